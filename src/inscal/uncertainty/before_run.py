"""The uncertainty budget a path promises before it runs: the Cramér-Rao bound of the systematic filter
(:mod:`inscal.plan.bound`) with the site and clock inputs carried through it (:mod:`inscal.plan.consider`),
combined with a station's uncertainties as the GUM budget of :mod:`inscal.uncertainty.budget` (``observability --crlb
--station``, ``design --station``); for a window-mean method, whose budget the bound does not give, the budget of
one simulated run (``observability --crlb --station --method n25``).  The planner and the simulator are layers
below the uncertainty package; this is where they meet."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from inscal.calibrate import calibrate
from inscal.calibrate.systematic.states import state_spec
from inscal.core.earth import Site
from inscal.uncertainty import budget as gum
from inscal.uncertainty.sensitivity import FILTER_TABLE_NOTE, STOP_INPUTS, calibration_budget
from inscal.uncertainty.station import Station
from inscal.plan.consider import CONSIDER_INPUTS, canonical
from inscal.sim.simulate import simulate

#: what a budget before the run says of itself
BOUND_NOTES = (
    "before the run: the estimator's line is the Cramér-Rao bound of the path (the systematic filter at the nominal "
    "unit, its noise model); the site and clock coefficients are the filter's first-order response to them (a "
    "consider analysis), the table's inputs enter with sensitivity 0 (the filter reads neither its angles nor its "
    "rates)",
    "height: the bound uses the station's gravity as a value (its own input), so the height moves nothing the filter "
    "uses",
)


def consider_u(station: Station) -> dict[str, float]:
    """The standard uncertainties (SI) of the station's site and clock inputs, by name."""
    return {k: float(station[k].u) for k in CONSIDER_INPUTS}


def station_site(site: Site, station: Station) -> Site:
    """``site`` moved to the station's latitude and height, with its gravity value."""
    s = Site(station["latitude"].value, site.longitude, station["height"].value)
    return s.with_gravity(station["gravity"].value)


def at_station(scenario, station: Station):
    """The scenario at the station's site."""
    return replace(scenario, site=station_site(scenario.site, station))


def scenario_temperature(scenario, names, duration_s: float) -> gum.TemperatureSensitivity | None:
    """How the chamber's temperature stability enters a budget before the run: through the scenario's own thermal
    model (the unit's, as the simulator has it) at the scenario's mean temperature over the path (its reference
    temperature without a profile); None (not propagated) for a unit without one."""
    model = getattr(scenario, "thermal", None)
    if model is None or model.is_zero:
        return None
    if scenario.temperature is not None:
        t_c = float(np.mean(scenario.temperature.at(np.linspace(0.0, duration_s, 2001))[0]))
        where = "the scenario's mean temperature over the path"
    else:
        t_c, where = float(model.t_ref), "the scenario's unit stays at its reference temperature"
    return gum.temperature_from_model(model, names, t_c, "the scenario's thermal model", where)


def bound_budget(bound, station: Station, coverage: float = gum.COVERAGE, scenario=None) -> gum.Budget:
    """The budget before the run of ``bound`` at ``station``.

    The bound (computed with ``consider``, e.g. :func:`consider_u`) is the Type-A line (infinite dof), the consider
    sensitivities enter for the site and clock, zero for the table; the chamber's temperature stability:
    sensitivity 0 with thermal states (the filter measures and models the temperature), else through the
    ``scenario``'s thermal model (:func:`scenario_temperature`).

    Parameters
    ----------
    bound : inscal.plan.bound.Bound
        The Cramér-Rao bound of a path, computed with ``consider``.
    station : inscal.uncertainty.station.Station
        The station.
    coverage : float, optional
        The coverage probability.
    scenario : optional
        The scenario the bound was computed on (its thermal model; None: not propagated).

    Returns
    -------
    inscal.uncertainty.budget.Budget
        The budget the path promises.

    Raises
    ------
    ValueError
        The bound carries no site and clock sensitivities.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from inscal.uncertainty.station import example_station
    >>> bound_budget(SimpleNamespace(setup=SimpleNamespace(consider=None)), example_station())
    Traceback (most recent call last):
    ...
    ValueError: the bound carries no site and clock sensitivities (crlb(..., consider=...))
    """
    if not bound.setup.consider:
        raise ValueError("the bound carries no site and clock sensitivities (crlb(..., consider=...))")
    cb = canonical(bound)
    n = cb.sigma.size
    glob = {k: np.zeros(n) for k in ("table_rate", "axis_nonorthogonality")}
    glob.update(cb.sensitivity)
    per_stop = {k: np.zeros((1, 2, n)) for k in STOP_INPUTS}
    method = f"Cramér-Rao bound of the systematic filter (states {state_spec(bound.setup.states)}) on {bound.path_name}"
    if bound.setup.states.thermal:
        temperature = gum.temperature_measured(cb.names, float(bound.setup.thermal["t_ref"]))
    else:
        temperature = scenario_temperature(scenario, cb.names, bound.duration_s)
    return gum.budget(method, cb.names, cb.values, cb.sigma, math.inf, station, glob, per_stop, None, coverage,
                      (*BOUND_NOTES, FILTER_TABLE_NOTE), temperature)


def simulated_budget(scenario, station: Station, method: str, seed: int = 0):
    """The budget a window-mean ``method`` (:data:`inscal.uncertainty.sensitivity.WINDOW_METHODS`) promises on
    ``scenario`` at ``station``: one run simulated at the station's site with the scenario's unit and noise
    (``seed``), calibrated, and its budget (:func:`inscal.uncertainty.sensitivity.calibration_budget`: the method's own
    sigma and its coefficients by differences through the method).  Returns ``(budget, result)``."""
    rec = simulate(at_station(scenario, station), np.random.default_rng(seed)).to_record()
    res = calibrate(rec, method)
    temperature = scenario_temperature(scenario, res.estimated, float(rec.time[-1] - rec.time[0]))
    return calibration_budget(res, station, temperature=temperature), res


def dominant_inputs(budget: gum.Budget) -> list[dict]:
    """Per input of ``budget``: the components whose largest contribution it is, its largest and median share (of
    ``u_c^2``), most dominant first; what an engineer improves first."""
    rows: dict[str, dict] = {}
    for c in budget.components:
        top = max(c.contributions, key=lambda x: x.share)
        for x in c.contributions:
            r = rows.setdefault(x.input, {"input": x.input, "largest_in": [], "shares": []})
            r["shares"].append(x.share)
            if x is top:
                r["largest_in"].append(c.label)
    out = [{"input": r["input"], "largest_in": r["largest_in"], "n_largest": len(r["largest_in"]),
            "max_share": float(max(r["shares"])), "median_share": float(np.median(r["shares"]))}
           for r in rows.values()]
    return sorted(out, key=lambda r: (-r["n_largest"], -r["max_share"]))
