"""The options of ``inscal calibrate`` as one object (:class:`CalibrateOptions`) and their checks before the
calibration runs: the station description of the budget, its thermal model, the thermal orders, the no-turntable
methods' options in their functions' units, and the calibration database that ``--serial`` records in."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from inscal.cli.common import CliError, normal_serial
from inscal.cli.guards import database_notes


@dataclass(frozen=True)
class CalibrateOptions:
    """Everything ``inscal calibrate`` is asked: calibrate ``data`` with ``method`` and write ``out``.

    ``states``/``plots``/``filter_rate``/``arw`` [deg/sqrt(h)]/``vrw`` [ug/sqrt(Hz)] apply to the systematic
    methods.  ``gravity`` (wgs84 | psins | m/s^2) overrides the record's gravity model.  ``encoder_sigma``
    [arcsec]: white noise of each encoder angle for the gimbal states (method ``unified``, or ``--states
    ...,gimbal``).  A record with encoder angles has them compared with the gyros first
    (:mod:`inscal.io.encoders`): a unit, sign, column or time-offset error stops the calibration with one line
    unless ``skip_encoder_check``; ``encoder_latency`` [s] shifts the angles before (encoders that lag: > 0).
    ``serial``: record the result in the calibration database ``db`` (:mod:`inscal.lab`; None: ``INSCAL_DB``,
    else calib.sqlite) as a calibration of that unit, with the session's ``station``, ``operator``, ``date`` and
    ``temperature_c``, committed together with the parameter file (a failure of either leaves neither);
    ``supersedes``: the id of an earlier result this one replaces; ``wait`` [s] for another writer.
    Method ``thermal-plateaus``: ``per_plateau`` (default n25) runs on each temperature plateau, then the
    thermal model is fitted with ``thermal_order`` (``("gyro_bias=2", ...)``), ``t_ref`` [degC] (default 20),
    ``plateau_tol`` [degC], ``temperature_sensor`` and ``chamber_label`` (:mod:`inscal.calibrate.thermal`).
    ``accept_unconverged``: a systematic run that does not converge keeps its last iterate, with a note,
    instead of ending with one line (:class:`inscal.calibrate.systematic.driver.NotConverged`).
    ``settle``, ``min_static`` [s]: None, the method's own default (:class:`~inscal.lab.calibration.CalibrationSetup`);
    ``quadratic``: ``multi-position`` estimates the quadratic accelerometer terms too; ``method_options``: the
    no-turntable method's keyword options given (:func:`method_options`); ``tremor_dps``: the hand tremor a
    still pose may hold [deg/s rms] (multi-position; None: its default).  ``noise``: a noise.toml (``inscal
    noise --out``) whose white terms weight the systematic filter and whose Gauss-Markov terms become bias
    states (:mod:`inscal.calibrate.systematic.gm_states`).  ``station`` a description FILE.toml: the GUM budget;
    its chamber temperature stability goes through ``thermal_model`` (a parameter file with a ``[thermal]``
    table) or else the unit's newest thermal result in the database, at ``temperature_c`` (allowed without
    ``serial`` then) or the record's mean temperature; ``mc`` trials at most of the budget's JCGM 101 Monte
    Carlo (:mod:`inscal.cli.budget_mc`; seed ``mc_seed``, ``mc_workers`` Dask workers).
    """

    data: Path
    method: str
    out: Path
    force: bool = False
    settle: float | None = None
    min_static: float | None = None
    states: str | None = None
    plots: Path | None = None
    filter_rate: float = 1.0
    arw: float | None = None
    vrw: float | None = None
    gravity: str | None = None
    encoder_sigma: float | None = None
    encoder_latency: float = 0.0
    skip_encoder_check: bool = False
    db: str | None = None
    serial: str | None = None
    station: str | None = None
    operator: str | None = None
    date: str | None = None
    temperature_c: float | None = None
    supersedes: int | None = None
    per_plateau: str | None = None
    thermal_order: tuple[str, ...] | None = None
    t_ref: float | None = None
    plateau_tol: float = 0.5
    temperature_sensor: str = ""
    chamber_label: str = "chamber"
    wait: float | None = None
    accept_unconverged: bool = False
    quadratic: bool = False
    noise: Path | None = None
    thermal_model: Path | None = None
    mc: int | None = None
    mc_seed: int = 0
    mc_workers: int = 1
    method_options: tuple[tuple[str, float], ...] = ()
    tremor_dps: float | None = None


def station_description(station: str | None, method: str):
    """The station description of ``--station FILE.toml`` (:mod:`inscal.lab.station`), None for a station's
    name; refused with one line when it cannot be read or the method has no budget."""
    if station is None or not station.lower().endswith(".toml"):
        return None
    from inscal.lab.sensitivity import BUDGET_METHODS
    from inscal.lab.station import StationError, read_station

    if method not in BUDGET_METHODS:
        raise CliError(f"--station {station}: an uncertainty budget needs one of the methods "
                       f"{', '.join(BUDGET_METHODS)}, not {method}")
    try:
        return read_station(station)
    except StationError as exc:
        raise CliError(str(exc)) from None


def budget_thermal_model(path: Path | None, desc, temperature_c: float | None):
    """``(path, ThermalModel)`` of ``--thermal-model PARAMS.toml`` (None without it), read before the calibration
    runs: refused with one line when there is no budget, the file cannot be read or carries no thermal model.
    ``temperature_c``: a ``--temperature-c`` given without ``--serial`` (the budget's stated temperature), checked."""
    if desc is None:
        if path is not None:
            raise CliError(f"--thermal-model {path}: it serves the uncertainty budget: give --station FILE.toml")
        return None
    if temperature_c is not None and not (math.isfinite(temperature_c) and -100.0 < temperature_c < 200.0):
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    if path is None:
        return None
    from inscal.io.paramfile import ParamFileError, load_params

    try:
        meta = load_params(path)[2]
    except ParamFileError as exc:
        raise CliError(f"--thermal-model: {exc}") from None
    model = meta.get("thermal")
    if model is None or model.is_zero:
        raise CliError(f"--thermal-model {path}: the parameter file has no thermal model (no [thermal] table with "
                       "coefficients; --method thermal-plateaus or --states ...,thermal write one)")
    return path, model


def parse_orders(items: list[str] | None) -> tuple[tuple[str, int], ...]:
    """``--thermal-order NAME=K`` (repeatable; NAME a thermal term, K its polynomial order) as pairs."""
    out = []
    for item in items or []:
        name, sep, k = str(item).partition("=")
        try:
            order = int(k)
        except ValueError:
            order = None
        if not sep or not name.strip() or order is None:
            raise CliError(f"--thermal-order {item!r}: expected NAME=ORDER, e.g. gyro_bias=2 (NAME a thermal term, "
                           "ORDER 0 .. 3; 0: constant)")
        out.append((name.strip(), order))
    return tuple(out)



def open_lab(db, serial, station, operator, date, temperature_c, supersedes, data: Path,
              options: dict, wait: float | None = None) -> dict | None:
    """The calibration database and what ``--serial`` records in it, checked before the calibration
    runs: the unit is registered, the record not yet calibrated with the same options (unless
    ``--supersedes``); None without ``--serial``."""
    if serial is None:
        extra = [n for n, v in (("--db", db), ("--station", station), ("--operator", operator), ("--date", date),
                                ("--temperature-c", temperature_c), ("--supersedes", supersedes), ("--wait", wait))
                 if v is not None]
        if extra:
            raise CliError(f"{', '.join(extra)}: the calibration is recorded in the database for a unit: give --serial")
        return None
    serial = normal_serial(serial)
    import sqlalchemy

    from inscal import lab
    from inscal.io.files import file_hash
    from inscal.io.paramfile import ParamFileError

    if temperature_c is not None and not (math.isfinite(temperature_c) and -100.0 < temperature_c < 200.0):
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    for name, text in (("--station", station), ("--operator", operator)):  # checked before the calibration runs
        if text is not None and len(text) > 200:
            raise CliError(f"{name} {text[:40]!r}...: {len(text)} characters, at most 200")
    try:
        when = lab.check_date(lab.parse_date(date), "--date") if date is not None else None
        d = lab.open_database(db, wait_s=wait)
    except (lab.DatabaseError, ValueError) as exc:
        raise CliError(str(exc)) from None
    database_notes(d)
    try:
        if lab.get_unit(d, serial) is None:
            raise CliError(f"unknown unit {serial!r} in {d.where}: register it first with `inscal db add {serial} "
                           "--model MODEL`")
        if supersedes is not None:
            old = lab.get_calibration(d, supersedes)
            if old.serial != serial:
                raise CliError(f"--supersedes {supersedes}: that result is a calibration of {old.serial}, not {serial}")
        h = file_hash(data)
        done = lab.find_calibration(d, h, options, serial)
        if done is not None and supersedes is None:
            raise CliError(f"{data} is recorded already for {serial} with these options (result {done}; `inscal db "
                           f"export {serial} --result {done} --out FILE` writes its parameter file); --supersedes {done} "
                           "records a new calibration in its place")
    except (lab.DatabaseError, ParamFileError, sqlalchemy.exc.SQLAlchemyError) as exc:
        d.close()
        raise CliError(str(getattr(exc, "orig", None) or exc).split("\n")[0]) from None
    except BaseException:
        d.close()
        raise
    return {"db": d, "serial": serial, "hash": h, "options": options, "date": when, "station": station,
            "operator": operator, "temperature_c": temperature_c, "supersedes": supersedes}



def method_options(alpha, gravity_tol, face_tilt, min_turn_end, turn_tol, turn_closure) -> tuple:
    """The no-turntable options given on the command line, in the method function's units, as sorted
    ``(name, value)`` pairs (:data:`~inscal.lab.calibration.NO_TABLE_OPTIONS`; ``face_tilt``, ``turn_closure``
    in rad)."""
    from inscal.core import units

    given = {"alpha": alpha, "gravity_tol": gravity_tol, "min_turn_end": min_turn_end, "turn_tol_deg": turn_tol,
             "face_tilt": None if face_tilt is None else units.to_si(face_tilt, "deg"),
             "turn_closure": None if turn_closure is None else units.to_si(turn_closure, "deg")}
    return tuple(sorted((k, float(v)) for k, v in given.items() if v is not None))
