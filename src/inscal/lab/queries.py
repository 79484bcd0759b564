"""Reading the calibration database: a unit, the "already recorded" queries, one calibration with all
it has (parameters, sigma, covariance, fit, provenance), a unit's calibrations and its current one, the
uncertainty budget stored with a result, and the units with their counts.

Read API (what ``inscal db``, the drift statistics and the fleet's status use)::

    db = open_database(url, readonly=True)                    # inscal.lab.opening
    if find_calibration(db, session.record_sha256, options, serial) is None:
        ...                                                   # calibrate, then record (inscal.lab.store)
    cal = get_calibration(db, rid)                            # parameters, sigma, covariance, fit, provenance
    current_calibration(db, "FOG-0042")
    calibrations(db, "FOG-0042")                              # by their records' dates

Each query runs in one read transaction (:func:`~inscal.lab.database.read`: a consistent snapshot); a
result another one supersedes leaves a unit's history (:func:`calibrations`) but stays readable by its
id.  Writing is :mod:`inscal.lab.store`.
"""

from __future__ import annotations

import json

import numpy as np
import sqlalchemy as sa

from inscal.core.error_model import PARAMETERS, parameter_components
from inscal.core.thermal import ThermalModel, thermal_from_field
from inscal.io.paramfile import ParamFileError
from inscal.lab import schema as t
from inscal.lab.database import Database, DatabaseError, read
from inscal.lab.model import (
    Calibration,
    Parameter,
    Session,
    Unit,
)
from inscal.lab.record import options_hash, parse_param_text


def unit_from_row(row) -> Unit:
    """The :class:`~inscal.lab.model.Unit` of a row of ``units``."""
    return Unit(row.id, row.serial, row.model, row.notes, row.created_at)


def unit_id_of(conn, serial: str) -> int:
    """The id of the unit registered under ``serial`` (read on ``conn``, inside the caller's transaction); an
    unknown unit is refused (:class:`~inscal.lab.database.DatabaseError`) with the command that registers it."""
    uid = conn.execute(sa.select(t.units.c.id).where(t.units.c.serial == serial)).scalar()
    if uid is None:
        raise DatabaseError(f"unknown unit {serial!r}: register it first with `inscal db add {serial} --model MODEL`")
    return uid


def get_unit(db: Database, serial: str) -> Unit | None:
    """The unit registered under a serial.

    Parameters
    ----------
    db : Database
        The open database (read only).
    serial : str
        The serial.

    Returns
    -------
    Unit or None
        The unit, None if none is registered.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> _ = lab.add_unit(db, "IMU-1", "nav-grade")
    >>> lab.get_unit(db, "IMU-1").model, lab.get_unit(db, "IMU-2")
    ('nav-grade', None)

    >>> db.close()
    """
    with read(db) as conn:
        row = conn.execute(sa.select(t.units).where(t.units.c.serial == serial)).first()
    return None if row is None else unit_from_row(row)


def find_calibration(db: Database, record_sha256: str, options: dict, serial: str | None = None) -> int | None:
    """The newest result already recorded from a record with the same options.

    Parameters
    ----------
    db : Database
        The open database (read only).
    record_sha256 : str
        The record's hash (:func:`inscal.io.file_hash`).
    options : dict
        The calibration's options (:func:`~inscal.lab.record.calibration_options`).
    serial : str, optional
        Only this unit's.

    Returns
    -------
    int or None
        Its id; None if none.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # its record: "sha256:111..."
    >>> lab.find_calibration(db, "sha256:" + "1" * 64, {"method": "six-position"}) == first
    True

    >>> db.close()
    """
    q = (sa.select(t.results.c.id).join(t.sessions, t.sessions.c.id == t.results.c.session_id)
         .where(t.sessions.c.record_sha256 == record_sha256, t.results.c.options_hash == options_hash(options))
         .order_by(t.results.c.id.desc()).limit(1))
    if serial is not None:
        q = q.join(t.units, t.units.c.id == t.results.c.unit_id).where(t.units.c.serial == serial)
    with read(db) as conn:
        return conn.execute(q).scalar()


def find_param_file(db: Database, serial: str, param_file_sha256: str) -> int | None:
    """The result of a unit recorded from the very same parameter file.

    Parameters
    ----------
    db : Database
        The open database (read only).
    serial : str
        The unit.
    param_file_sha256 : str
        The file's hash (:func:`~inscal.lab.record.text_hash` of its text).

    Returns
    -------
    int or None
        Its id; None if none.

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> res = CalibrationResult.from_field({"gyro_bias": [0.010, 0, 0]}, {"gyro_bias": [0.001] * 3}, "six-position")
    >>> text = lab.param_file_text(res)  # a parameter file, as ``inscal calibrate`` writes it
    >>> db, created = lab.init_database("calib.sqlite")
    >>> _ = lab.add_unit(db, "IMU-1")
    >>> jan = lab.SessionInfo(record_sha256="sha256:" + "1" * 64, date=dt.datetime(2025, 1, 31))
    >>> first = lab.record_calibration(db, "IMU-1", text, jan)
    >>> lab.find_param_file(db, "IMU-1", lab.text_hash(text)) == first
    True

    >>> db.close()
    """
    with read(db) as conn:
        return conn.execute(sa.select(t.results.c.id).join(t.units, t.units.c.id == t.results.c.unit_id).where(
            t.units.c.serial == serial, t.results.c.param_file_sha256 == param_file_sha256)
            .order_by(t.results.c.id).limit(1)).scalar()


def current_id(conn, unit_id: int) -> int | None:
    """The id of the unit's current result (its newest ``current`` row), or None."""
    return conn.execute(sa.select(t.current.c.result_id).where(t.current.c.unit_id == unit_id)
                        .order_by(t.current.c.id.desc()).limit(1)).scalar()


def _arrays(name: str, rows: list) -> Parameter:
    shape = PARAMETERS[name].shape
    n = len(parameter_components(name))

    def arr(key):
        a = np.full(n, np.nan)
        for r in rows:
            v = getattr(r, key)
            a[r.component] = np.nan if v is None else v
        return a.reshape(shape) if shape else a.reshape(())

    formal = arr("sigma_formal") if any(r.sigma_formal is not None for r in rows) else None
    return Parameter(name, rows[0].unit, arr("value"), arr("sigma"), formal,
                     tuple(r.label for r in sorted(rows, key=lambda r: r.component)))


def _load(conn, result_rows: list) -> list[Calibration]:
    """The calibrations of ``result_rows`` (a few queries for all of them)."""
    if not result_rows:
        return []
    ids = [r.id for r in result_rows]
    params: dict[int, dict[str, list]] = {i: {} for i in ids}
    for p in conn.execute(sa.select(t.parameters).where(t.parameters.c.result_id.in_(ids))
                          .order_by(t.parameters.c.id)):
        params[p.result_id].setdefault(p.name, []).append(p)
    sess = {s.id: s for s in conn.execute(sa.select(t.sessions).where(
        t.sessions.c.id.in_({r.session_id for r in result_rows})))}
    unit_rows = {u.id: u for u in conn.execute(sa.select(t.units).where(
        t.units.c.id.in_({r.unit_id for r in result_rows})))}
    later: dict[int, list[int]] = {i: [] for i in ids}
    for r in conn.execute(sa.select(t.results.c.id, t.results.c.supersedes).where(t.results.c.supersedes.in_(ids))):
        later[r.supersedes].append(r.id)
    cur = {uid: current_id(conn, uid) for uid in unit_rows}
    out = []
    for r in result_rows:
        s = sess[r.session_id]
        session = Session(id=s.id, record_sha256=s.record_sha256, date=s.date, record_path=s.record_path,
                          station=s.station, operator=s.operator, latitude_deg=s.latitude_deg,
                          longitude_deg=s.longitude_deg, height_m=s.height_m, gravity_model=s.gravity_model,
                          g_site_m_s2=s.g_site_m_s2, temperature_c=s.temperature_c, path_name=s.path_name,
                          recorded_at=s.recorded_at)
        u = unit_rows[r.unit_id]
        out.append(Calibration(
            id=r.id, serial=u.serial, method=r.method, state_set=r.state_set, options=r.options,
            options_hash=r.options_hash, parameters={n: _arrays(n, rows) for n, rows in params[r.id].items()},
            covariance=r.covariance, fit=r.fit, fit_chi2=r.fit_chi2, fit_dof=r.fit_dof, fit_p=r.fit_p,
            notes=tuple(r.notes or ()), inscal_version=r.inscal_version, param_text=r.param_file,
            param_file_sha256=r.param_file_sha256, supersedes=r.supersedes, superseded_by=tuple(sorted(later[r.id])),
            current=cur[r.unit_id] == r.id, recorded_at=r.recorded_at, session=session, unit_model=u.model))
    return out


def get_calibration(db: Database, result_id: int) -> Calibration:
    """A result with all its parameters, sigma, covariance, fit and provenance.

    Parameters
    ----------
    db : Database
        The open database (read only).
    result_id : int
        The result.

    Returns
    -------
    Calibration
        The result.

    Raises
    ------
    DatabaseError
        No such result.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> cal = lab.get_calibration(db, first)
    >>> cal.serial, cal.method, cal.parameters["gyro_bias"].unit
    ('IMU-1', 'six-position', 'deg/h')

    >>> db.close()
    """
    if not 0 < int(result_id) < 2**63:  # beyond any id (and SQLite's 64-bit integers)
        raise DatabaseError(f"no calibration result {result_id} in {db.where}")
    with read(db) as conn:
        row = conn.execute(sa.select(t.results).where(t.results.c.id == int(result_id))).first()
        if row is None:
            raise DatabaseError(f"no calibration result {result_id} in {db.where}")
        return _load(conn, [row])[0]


def current_calibration(db: Database, serial: str) -> Calibration | None:
    """The current calibration of a unit.

    Parameters
    ----------
    db : Database
        The open database (read only).
    serial : str
        The unit.

    Returns
    -------
    Calibration or None
        Its current calibration, None if it has none.

    Raises
    ------
    DatabaseError
        An unknown unit.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> lab.current_calibration(db, "IMU-1").id == second  # the newest record's
    True

    >>> db.close()
    """
    with read(db) as conn:
        rid = current_id(conn, unit_id_of(conn, serial))
        if rid is None:
            return None
        return _load(conn, [conn.execute(sa.select(t.results).where(t.results.c.id == rid)).one()])[0]


def calibrations(db: Database, serial: str, method: str | None = None, superseded: bool = False) -> list[Calibration]:
    """The calibrations of a unit, in the order of their records' dates (then of recording).

    Parameters
    ----------
    db : Database
        The open database (read only).
    serial : str
        The unit.
    method : str, optional
        Only this method's.
    superseded : bool
        Keep the results another one supersedes too.

    Returns
    -------
    list of Calibration
        The calibrations.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> [c.parameters["gyro_bias"].value[0].item() for c in lab.calibrations(db, "IMU-1")]
    [0.01, 0.012]

    >>> db.close()
    """
    with read(db) as conn:
        uid = unit_id_of(conn, serial)
        q = (sa.select(t.results).join(t.sessions, t.sessions.c.id == t.results.c.session_id)
             .where(t.results.c.unit_id == uid).order_by(t.sessions.c.date, t.results.c.id))
        if method is not None:
            q = q.where(t.results.c.method == method)
        if not superseded:
            later = sa.select(t.results.c.supersedes).where(t.results.c.supersedes.is_not(None))
            q = q.where(t.results.c.id.not_in(later))
        return _load(conn, list(conn.execute(q)))


def thermal_of(cal: Calibration) -> ThermalModel | None:
    """The thermal model the parameter file of ``cal`` carries (its ``[thermal]`` table), None when it has none
    or one that cannot be read."""
    try:
        doc = parse_param_text(cal.param_text)
    except ParamFileError:
        return None
    tdoc = doc.get("thermal")
    if not isinstance(tdoc, dict):
        return None
    try:
        return thermal_from_field({k: v for k, v in tdoc.items() if k != "fit"})[0]
    except (ValueError, TypeError, KeyError):
        return None


def newest_thermal(db: Database, serial: str) -> tuple[Calibration, ThermalModel] | None:
    """The unit's newest result (by its record's date, then by recording) whose parameter file carries a thermal
    model (``thermal-plateaus``, thermal states), with that model; None when none does.  Superseded results
    are left out."""
    for cal in reversed(calibrations(db, serial)):
        model = thermal_of(cal)
        if model is not None and not model.is_zero:
            return cal, model
    return None


def list_units(db: Database) -> list[tuple[Unit, int, int | None]]:
    """Every unit with its number of (not superseded) results and its current result id, by serial.

    Parameters
    ----------
    db : Database
        The open database (read only).

    Returns
    -------
    list of tuple of (Unit, int, int or None)
        ``(unit, results, current result id)``.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> [(u.serial, n, cur == first) for u, n, cur in lab.list_units(db)]
    [('IMU-1', 1, True)]

    >>> db.close()
    """
    with read(db) as conn:
        later = sa.select(t.results.c.supersedes).where(t.results.c.supersedes.is_not(None))
        counts = dict(conn.execute(sa.select(t.results.c.unit_id, sa.func.count()).where(
            t.results.c.id.not_in(later)).group_by(t.results.c.unit_id)).all())
        out = []
        for row in conn.execute(sa.select(t.units).order_by(t.units.c.serial)):
            out.append((unit_from_row(row), int(counts.get(row.id, 0)), current_id(conn, row.id)))
        return out


def table_counts(db: Database) -> dict[str, int]:
    """Rows per table.

    Parameters
    ----------
    db : Database
        The open database (read only).

    Returns
    -------
    dict of str to int
        ``{table: rows}``.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> counts = lab.table_counts(db)
    >>> counts["units"], counts["results"], counts["parameters"]
    (1, 1, 3)

    >>> db.close()
    """
    with read(db) as conn:
        return {tab.name: int(conn.execute(sa.select(sa.func.count()).select_from(tab)).scalar_one())
                for tab in t.TABLES}


def get_budget(db: Database, result_id: int) -> dict | None:
    """The uncertainty budget stored with a result (field units).

    Parameters
    ----------
    db : Database
        The open database (read only).
    result_id : int
        The result whose budget is wanted.

    Returns
    -------
    dict or None
        ``{"result_id", "station", "budget"}`` (the station's document and the budget as stored),
        None when it was recorded without a station.

    Raises
    ------
    DatabaseError
        A stored budget that is not one.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> lab.get_budget(db, first) is None  # recorded without a station
    True

    >>> db.close()
    """
    with read(db) as conn:
        row = conn.execute(sa.select(t.budgets.c.budget, t.stations.c.document).join(
            t.stations, t.stations.c.id == t.budgets.c.station_id).where(t.budgets.c.result_id == int(result_id))).first()
    if row is None:
        return None
    if not budget_well_formed(row.budget):
        raise DatabaseError(f"the uncertainty budget stored with result {result_id} is not a budget "
                            f"({short_json(row.budget)}): the database was edited; record the result again with "
                            "inscal calibrate ... --station FILE.toml --serial ... --supersedes "
                            f"{result_id}")
    return {"result_id": int(result_id), "station": row.document, "budget": row.budget}


#: the keys of a stored budget and of each of its components and contributions (inscal.uncertainty.budget.Budget)
BUDGET_KEYS = ("station", "method", "coverage", "components")
COMPONENT_KEYS = ("parameter", "label", "unit", "value", "u_c", "k", "U", "contributions")
CONTRIBUTION_KEYS = ("input", "value", "distribution", "u", "unit", "sensitivity", "contribution", "share", "stops")


def budget_well_formed(b) -> bool:
    """Whether ``b`` (a stored budget's JSON) has what the budget's readers use."""
    if not (isinstance(b, dict) and all(k in b for k in BUDGET_KEYS) and isinstance(b["components"], list)):
        return False
    for c in b["components"]:
        if not (isinstance(c, dict) and all(k in c for k in COMPONENT_KEYS) and isinstance(c["contributions"], list)):
            return False
        if not all(isinstance(x, dict) and all(k in x for k in CONTRIBUTION_KEYS) for x in c["contributions"]):
            return False
    return True


def short_json(v, limit: int = 40) -> str:
    """``v`` as JSON text, cut to ``limit`` characters."""
    text = json.dumps(v, default=str)
    return text if len(text) <= limit else text[:limit - 1] + "…"
