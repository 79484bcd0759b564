"""The uncertainty budget of one calibration run, as ``inscal calibrate --station FILE.toml`` states it: the GUM
budget of the result at the station (:func:`inscal.uncertainty.sensitivity.calibration_budget`), with

- the method rerun in its differences with the options the run used (a filter method: the state set of the run,
  its noise figures and the noise model it read, :func:`rerun_options`);
- the repeatability between the unit's earlier results of the method when the database holds two or more
  (GUM 4.2, :func:`inscal.uncertainty.budget.repeatability_of`);
- the chamber's temperature stability through a thermal model (:func:`session_temperature`: the result's own,
  a ``--thermal-model`` file's, or the unit's newest in the database, at the session's temperature or the
  record's mean temperature);
- the JCGM 101 Monte Carlo of the budget when asked (:func:`inscal.uncertainty.montecarlo.budget_monte_carlo`).

The command only calls :func:`session_budget` and stores what it returns with the result.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import sqlalchemy

from inscal import lab
from inscal.lab.model import iso
from inscal.lab.queries import newest_thermal
from inscal.core import units
from inscal.uncertainty import budget as gum
from inscal.uncertainty.montecarlo import budget_monte_carlo
from inscal.uncertainty.sensitivity import FILTER_METHODS, NO_TABLE_METHODS, calibration_budget
from inscal.uncertainty.station import Station

__all__ = ["BudgetError", "SessionBudget", "rerun_options", "session_budget", "session_temperature"]


class BudgetError(ValueError):
    """A run's budget that cannot be stated, with the reason in one line.

    Parameters
    ----------
    message : str
        The reason.
    part : str, optional
        Which part: ``"budget"`` (the linear budget) or ``"monte_carlo"`` (its JCGM 101 Monte Carlo).

    Examples
    --------
    >>> e = BudgetError("no trials", "monte_carlo")
    >>> str(e), e.part
    ('no trials', 'monte_carlo')
    """

    def __init__(self, message: str, part: str = "budget"):
        super().__init__(message)
        self.part = part


@dataclass(frozen=True)
class SessionBudget:
    """A run's budget: ``budget`` (:class:`inscal.uncertainty.budget.Budget`) at ``station``, and ``document``, the
    budget as JSON (what ``--json`` prints and the database stores) with its Monte Carlo under ``monte_carlo``."""

    station: Station
    budget: gum.Budget
    document: dict

    def stored(self) -> tuple[dict, dict]:
        """``(station document, budget document)``: what ``record_calibration(..., budget=...)`` stores."""
        return self.station.to_dict(), self.document


def rerun_options(result, setup) -> dict:
    """The options the method reruns with in the budget's differences.

    Parameters
    ----------
    result : inscal.calibrate.result.CalibrationResult
        The run's result (a filter method's carries its state set and noise figures in ``diagnostics``).
    setup : inscal.runs.calibration.CalibrationSetup
        The run's options (``window_options``, ``filter_rate_hz``, ``noise`` and ``noise_model()`` are read).

    Returns
    -------
    dict
        The table-free methods' window options; a filter method's rate, state set (without its Gauss-Markov
        states, which come back from the noise model), white noise (SI) and noise model; else empty.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> rerun_options(SimpleNamespace(method="n25"), SimpleNamespace(window_options={"settle": 1.0}))
    {}
    """
    if result.method in NO_TABLE_METHODS:
        return setup.window_options
    if result.method not in FILTER_METHODS:
        return {}
    d = result.diagnostics
    # the state set the run used (its option string: "51,thermal=11110", not the count of states); the
    # Gauss-Markov states come back from the noise model
    spec = ",".join(p for p in str(d.get("state_options", d["states"])).split(",") if not p.startswith("gm("))
    opts = {"filter_rate_hz": setup.filter_rate_hz, "states": spec,
            "arw": units.to_si(d["noise"]["arw_deg_sqrt_h"], "deg/sqrt(h)"),
            "vrw": units.to_si(d["noise"]["vrw_ug_sqrt_hz"], "ug/sqrt(Hz)")}
    if setup.noise is not None:
        opts["noise"] = setup.noise_model()
    return opts


def session_temperature(result, record, station: Station, temperature_c: float | None = None, thermal=None,
                        db=None, serial: str | None = None) -> gum.TemperatureSensitivity | None:
    """How the chamber's temperature stability enters a run's budget.

    A result with its own thermal model (thermal states) has sensitivity 0
    (:func:`inscal.uncertainty.budget.temperature_measured`); otherwise the slope of ``thermal`` or of the unit's
    newest result in the database that carries a thermal model, at ``temperature_c`` or else the record's mean
    temperature (:func:`inscal.uncertainty.budget.temperature_from_model`).

    Parameters
    ----------
    result : inscal.calibrate.result.CalibrationResult
        The run's result.
    record : inscal.io.records.Record
        The calibrated record (its temperatures, if any, give the mean temperature).
    station : inscal.uncertainty.station.Station
        The station (its ``temperature_stability`` is checked against the record's mean temperature).
    temperature_c : float, optional
        The temperature [degC] the result is stated at (the session's).
    thermal : tuple, optional
        ``(path, ThermalModel)`` of a parameter file with a thermal model (``--thermal-model``).
    db : inscal.lab.database.Database, optional
        The calibration database holding the unit's results.
    serial : str, optional
        The unit, with ``db``.

    Returns
    -------
    inscal.uncertainty.budget.TemperatureSensitivity or None
        The coefficients and the note; None (not propagated, the budget's own note) when neither a thermal model
        nor a database is given.

    Raises
    ------
    BudgetError
        The database cannot be read.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> print(session_temperature(SimpleNamespace(thermal=None), None, None))
    None
    """
    if result.thermal is not None:
        t = gum.temperature_measured(result.estimated, result.thermal.t_ref)
        return t if thermal is None else replace(t, note=t.note + f"; --thermal-model {Path(thermal[0]).name} not used")
    if thermal is not None:
        path, model = thermal
        source = f"the thermal model of {Path(path).name} (--thermal-model)"
    elif db is not None:
        try:
            found = newest_thermal(db, serial)
        except (lab.DatabaseError, sqlalchemy.exc.SQLAlchemyError) as exc:
            raise BudgetError(str(getattr(exc, "orig", None) or exc).splitlines()[0]) from None
        if found is None:
            return gum.TemperatureSensitivity(None, f"no thermal model of {serial}: none of its results in "
                                                    f"{db.where} carries one and no --thermal-model was given: "
                                                    "not propagated")
        cal, model = found
        source = f"the thermal model of result {cal.id} of {cal.serial} ({cal.method}, {iso(cal.date)[:10]})"
    else:
        return None
    t_c, where = temperature_c, "the session's --temperature-c"
    measured = None if record.temperature is None else gum.mean_temperature(record.temperature, model.sensor)
    if t_c is None and measured is not None:
        t_c, where = measured, "the record's mean temperature"
    return gum.temperature_from_model(model, result.estimated, t_c, source, where, measured,
                                      station[gum.TEMPERATURE].u)


def session_budget(result, station: Station, record, setup, db=None, serial: str | None = None,
                   temperature_c: float | None = None, thermal=None, mc: int | None = None, mc_seed: int = 0,
                   mc_workers: int = 1) -> SessionBudget:
    """The uncertainty budget of one calibration run (module docstring).

    Parameters
    ----------
    result : inscal.calibrate.result.CalibrationResult
        The run's result (a window-mean method's keeps its windows).
    station : inscal.uncertainty.station.Station
        The station's description (:func:`inscal.uncertainty.station.read_station`).
    record : inscal.io.records.Record
        The calibrated record (a filter or table-free method's differences rerun it).
    setup : inscal.runs.calibration.CalibrationSetup
        The run's options (:func:`rerun_options`).
    db : inscal.lab.database.Database, optional
        The calibration database: the repeatability of the unit's earlier results of the method, and its newest
        thermal model.
    serial : str, optional
        The unit, with ``db``.
    temperature_c : float, optional
        The temperature [degC] the result is stated at.
    thermal : tuple, optional
        ``(path, ThermalModel)`` of ``--thermal-model``.
    mc : int, optional
        At most this many trials of the budget's JCGM 101 Monte Carlo (None: none).
    mc_seed : int, optional
        The Monte Carlo's seed.
    mc_workers : int, optional
        The Monte Carlo's Dask workers (1: this process).

    Returns
    -------
    SessionBudget
        The budget, its JSON document (with ``monte_carlo``) and what the database stores.

    Raises
    ------
    BudgetError
        No budget for this result (another method, another site, an unreadable database: ``part`` "budget"), or no
        Monte Carlo of it (``part`` "monte_carlo").

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from inscal.uncertainty.station import example_station
    >>> res = SimpleNamespace(method="unified", thermal=None, estimated=[], windows=None)
    >>> session_budget(res, example_station(), None, None)
    Traceback (most recent call last):
    ...
    inscal.uncertainty.session.BudgetError: an uncertainty budget needs a window-mean method (n25, six-position, \
twelve-position, joint) or the record of a filter or table-free method (systematic51, systematic30, multi-position, \
ferraris), not unified
    """
    opts = rerun_options(result, setup)
    rep = None
    if db is not None:
        rep = gum.repeatability_of(lab.calibrations(db, serial, method=result.method), result.estimated)
    temperature = session_temperature(result, record, station, temperature_c, thermal, db, serial)
    try:
        bud = calibration_budget(result, station, rep, record=record, temperature=temperature, **opts)
    except ValueError as exc:
        raise BudgetError(str(exc)) from None
    doc = bud.to_dict()
    if mc:
        try:
            doc["monte_carlo"] = budget_monte_carlo(result, station, bud, mc, mc_seed, mc_workers, opts).to_dict()
        except ValueError as exc:
            raise BudgetError(str(exc), "monte_carlo") from None
    return SessionBudget(station, bud, doc)
