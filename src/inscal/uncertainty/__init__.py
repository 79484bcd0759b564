"""The measurement uncertainty of a calibration (JCGM 100:2008, the GUM; JCGM 101:2008, its Monte Carlo): one
package for the budget, above the estimators it differentiates, the bound it reads before a run, the Monte Carlo
engine it runs on and the database it takes a unit's history from.

Where each part lives:

- :mod:`inscal.uncertainty.station`: a station file (turntable, site, clock, chamber) as the budget's Type-B
  inputs, :func:`read_station`;
- :mod:`inscal.uncertainty.distributions`: the inputs' distributions: half-width factors, CDFs, the sampler;
- :mod:`inscal.uncertainty.sensitivity`: the sensitivity coefficients by differences through the estimators,
  :func:`calibration_budget`;
- :mod:`inscal.uncertainty.budget`: the combination (GUM eq. 10), Welch-Satterthwaite, the coverage factor of the
  linear model, the temperature's sensitivity through a thermal model, the repeatability between runs;
- :mod:`inscal.uncertainty.montecarlo`: the JCGM 101 Monte Carlo of a budget and its validation,
  :func:`budget_monte_carlo`, on the shared engine (:func:`inscal.analysis.montecarlo.ordered_map`);
- :mod:`inscal.uncertainty.before_run`: the budget a path promises before it runs (the Cramér-Rao bound with the
  site and clock carried through it, or one simulated run), :func:`bound_budget`;
- :mod:`inscal.uncertainty.session`: the budget of one calibration run as ``inscal calibrate --station`` states
  it (the unit's repeatability and thermal model from the database, the Monte Carlo), :func:`session_budget`.

Usage::

    from inscal import uncertainty

    station = uncertainty.read_station("station.toml")
    budget = uncertainty.calibration_budget(result, station)          # a Budget: u_c, nu_eff, k, U per component
    mc = uncertainty.budget_monte_carlo(result, station, budget, 10000)  # JCGM 101: validated or not

The names load their module on first use (PEP 562): reading a station file does not load the estimators.  No
public name is also the name of a submodule.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

#: public name -> the module that defines it
EXPORTS = {
    "Budget": "inscal.uncertainty.budget",
    "BudgetError": "inscal.uncertainty.session",
    "Station": "inscal.uncertainty.station",
    "StationError": "inscal.uncertainty.station",
    "bound_budget": "inscal.uncertainty.before_run",
    "budget_monte_carlo": "inscal.uncertainty.montecarlo",
    "calibration_budget": "inscal.uncertainty.sensitivity",
    "read_station": "inscal.uncertainty.station",
    "session_budget": "inscal.uncertainty.session",
}
__all__ = sorted(EXPORTS)

if TYPE_CHECKING:  # the names for type checkers and IDEs; at run time they load on first use
    from inscal.uncertainty.before_run import bound_budget
    from inscal.uncertainty.budget import Budget
    from inscal.uncertainty.montecarlo import budget_monte_carlo
    from inscal.uncertainty.sensitivity import calibration_budget
    from inscal.uncertainty.session import BudgetError, session_budget
    from inscal.uncertainty.station import Station, StationError, read_station


def __getattr__(name: str):
    """``uncertainty.NAME``: the public name, its module imported now."""
    try:
        module = importlib.import_module(EXPORTS[name])
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    globals()[name] = getattr(module, name)
    return globals()[name]


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(EXPORTS))
