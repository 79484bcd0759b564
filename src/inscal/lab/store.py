"""Writing the calibration database: units, and calibration results, each in one transaction.

Write API (what ``inscal calibrate --db`` and a batch of calibrations use)::

    db = open_database(url)                                   # inscal.lab.opening
    add_unit(db, "FOG-0042", model="FOG-IMU")                 # once per unit
    if find_calibration(db, session.record_sha256, options, serial) is None:   # inscal.lab.queries
        rid = record_calibration(db, "FOG-0042", param_text, session, options=options,
                                 covariance=covariance_of(result))
    cal = get_calibration(db, rid)                            # inscal.lab.queries

A record (its sha256) is one session of a unit; a session may hold results of several methods
or options, but one result per (record, options) and per parameter file: the insert of the
result's key (``result_keys``, unique) is the check, in the result's own transaction, so two
writers racing on the same calibration record it once (the other gets :class:`AlreadyRecorded`).  A
result that replaces an earlier one (the same record recalibrated) names it in ``supersedes``: the
earlier one then leaves the history.  Recording a result makes it the unit's current calibration unless
``make_current=False``.  Reading it back is :mod:`inscal.lab.queries`.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json

import sqlalchemy as sa
from sqlalchemy.dialects import postgresql as pg_dialect
from sqlalchemy.dialects import sqlite as sqlite_dialect

from inscal.lab import schema as t
from inscal.lab.database import Database, DatabaseError, Staged, begin_write, write
from inscal.lab.model import (
    check_date,
    SessionInfo,
    Unit,
)
from inscal.lab.queries import current_id, unit_from_row, unit_id_of
from inscal.lab.record import (
    covariance_of,
    fit_of,
    options_hash,
    param_file_text,
    parameter_covariance,
    parameter_rows,
    parse_param_text,
    text_hash,
)


class AlreadyRecorded(DatabaseError):
    """The calibration is recorded already (same unit, record and options, or the same parameter file);
    nothing was written.

    Parameters
    ----------
    message : str
        The one line.
    result_id : int or None
        The result recorded already.

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one result, of the record "sha256:111..."
    >>> again = CalibrationResult.from_field({"gyro_bias": [0.010, 0, 0]}, {"gyro_bias": [0.001] * 3}, "six-position")
    >>> try:  # the same record, the same options
    ...     lab.record_result(db, "IMU-1", again, lab.SessionInfo(record_sha256="sha256:" + "1" * 64,
    ...                                                            date=dt.datetime(2025, 1, 31)))
    ... except lab.AlreadyRecorded as exc:
    ...     print(exc.result_id == first)
    True

    >>> db.close()
    """

    def __init__(self, message: str, result_id: int | None):
        super().__init__(message)
        self.result_id = result_id


def now() -> dt.datetime:
    """The current UTC time without a zone, to the second (how the database stores times)."""
    return dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0)


def _insert_ignore(db_or_conn, table: sa.Table, index: list[str] | None):
    """An INSERT that does nothing on a conflict with the unique ``index`` (None: with any unique key)."""
    name = db_or_conn.dialect.name
    ins = (pg_dialect.insert if name == "postgresql" else sqlite_dialect.insert)(table)
    return ins.on_conflict_do_nothing(index_elements=index)


def add_unit(db: Database, serial: str, model: str | None = None, notes: str | None = None) -> tuple[Unit, bool]:
    """Register a unit (an instrument the lab calibrates; its serial is its identity).

    Units are append-only: a unit that exists with the same model and notes (or without them given)
    is returned, one with others is refused.

    Parameters
    ----------
    db : Database
        The open database (written in one transaction).
    serial : str
        The serial (1 to 200 characters).
    model : str, optional
        The unit's model.
    notes : str, optional
        Free text.

    Returns
    -------
    tuple of (Unit, bool)
        The unit, and whether it was created.

    Raises
    ------
    DatabaseError
        A serial registered with another model or notes, or a serial or text too long.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> unit, created = lab.add_unit(db, "IMU-1", "nav-grade")
    >>> unit.serial, created
    ('IMU-1', True)
    >>> lab.add_unit(db, "IMU-1")[1]
    False

    >>> db.close()
    """
    serial = check_serial(serial)
    check_text(model, "--model")

    def run(conn):
        new = conn.execute(_insert_ignore(conn, t.units, ["serial"]).values(
            serial=serial, model=model, notes=notes, created_at=now()).returning(t.units.c.id)).first()
        return conn.execute(sa.select(t.units).where(t.units.c.serial == serial)).one(), new is not None

    row, created = write(db, run)
    unit = unit_from_row(row)
    for what, given, have in (("model", model, unit.model), ("notes", notes, unit.notes)):
        if given is not None and given != have:
            raise DatabaseError(f"unit {serial} is registered already with {what} {have!r} (units are append-only: "
                                f"not changed to {given!r})")
    return unit, created


def check_text(value: str | None, what: str, limit: int = 200) -> None:
    """Refuse (:class:`DatabaseError`) a text longer than its column holds (``limit`` characters, on every back-end)."""
    if value is not None and len(str(value)) > limit:
        raise DatabaseError(f"{what} {str(value)[:40]!r}...: {len(str(value))} characters, at most {limit}")


def check_serial(serial: str) -> str:
    """``serial`` stripped, when it is 1 to 200 printable characters; else a :class:`~inscal.lab.database.DatabaseError`."""
    s = str(serial).strip()
    if not s or len(s) > 200 or any(not c.isprintable() for c in s):
        raise DatabaseError(f"serial {str(serial)[:60]!r}{'...' if len(str(serial)) > 60 else ''}: give 1 to 200 "
                            "printable characters")
    return s


def record_calibration(db: Database, serial: str, param_text: str, session: SessionInfo, *,
                       options: dict | None = None, covariance: dict | None = None, supersedes: int | None = None,
                       make_current: bool | None = None, date_given: bool = False, new_file: bool = False,
                       budget: tuple[dict, dict] | None = None) -> int:
    """Record one calibration in one transaction (nothing is recorded on any error).

    Parameters
    ----------
    db : Database
        The open database (written in one transaction).
    serial : str
        The unit (registered with :func:`add_unit`).
    param_text : str
        The parameter file exactly as written (parsed for the parameters, fit and version).
    session : SessionInfo
        Its record (:func:`~inscal.lab.record.session_from_record`; one session per unit and record
        sha256: the first one recorded keeps its metadata).
    options : dict, optional
        The calibration's options (:func:`~inscal.lab.record.calibration_options`; by default the
        method alone).
    covariance : dict, optional
        :func:`~inscal.lab.record.covariance_of` (None: the diagonal of the reported 1 sigma).
    supersedes : int, optional
        A result of the same unit this one replaces.
    make_current : bool, optional
        Make it the unit's current calibration (None: if its record is not older than the current
        calibration's).
    date_given : bool
        The session's date was given by the operator: a session of the record stored already with
        another date is refused rather than kept silently.
    new_file : bool
        Refuse a parameter file already stored for the unit too.
    budget : tuple of (dict, dict), optional
        ``(station document, budget)``, stored with the result.

    Returns
    -------
    int
        The result's id.

    Raises
    ------
    DatabaseError
        An unknown unit, options of another method, a date out of range, a bad ``supersedes``.
    AlreadyRecorded
        The same unit, record and options (unless superseding), or the same file with ``new_file``.
    ParamFileError
        A parameter file that cannot be read.

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> jul = lab.SessionInfo(record_sha256="sha256:" + "3" * 64, date=dt.datetime(2025, 7, 1))
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # its January result
    >>> res = CalibrationResult.from_field({"gyro_bias": [0.011, 0, 0]}, {"gyro_bias": [0.001] * 3}, "six-position")
    >>> text = lab.param_file_text(res, data_hash=jul.record_sha256)
    >>> rid = lab.record_calibration(db, "IMU-1", text, jul, supersedes=first)
    >>> lab.get_calibration(db, first).superseded_by == (rid,)
    True

    >>> db.close()
    """
    return write(db, calibration_writer(serial, param_text, session, options=options, covariance=covariance,
                                        supersedes=supersedes, make_current=make_current, date_given=date_given,
                                        new_file=new_file, budget=budget))


def stage_calibration(db: Database, serial: str, param_text: str, session: SessionInfo, **kw) -> Staged:
    """The transaction of :func:`record_calibration`, run but not committed.

    ``staged.commit()`` makes it durable (commit it as a step of publishing the parameter file, with
    the interrupts held: ``before_publish`` of :func:`inscal.io.files.output_unit`), ``staged.close()``
    rolls it back unless committed.

    Parameters
    ----------
    db : Database
        The open database (written in one transaction).
    serial : str
        The unit, as for :func:`record_calibration`.
    param_text : str
        The parameter file exactly as written.
    session : SessionInfo
        Its record.
    **kw
        The keyword arguments of :func:`record_calibration`.

    Returns
    -------
    Staged
        ``staged.value`` is ``{"result_id", "current", "date"}`` (whether it becomes the unit's
        current calibration, the record's date as stored).

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> res = CalibrationResult.from_field({"gyro_bias": [0.012, 0, 0]}, {"gyro_bias": [0.001] * 3}, "six-position")
    >>> mar = lab.SessionInfo(record_sha256="sha256:" + "2" * 64, date=dt.datetime(2025, 3, 2))
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # its January result
    >>> staged = lab.stage_calibration(db, "IMU-1", lab.param_file_text(res), mar)
    >>> staged.value["current"]
    True
    >>> staged.close()  # rolled back
    >>> lab.table_counts(db)["results"]
    1

    >>> db.close()
    """
    staged = begin_write(db, calibration_writer(serial, param_text, session, **kw))
    try:
        rid = staged.value
        uid, date = staged.conn.execute(sa.select(t.results.c.unit_id, t.sessions.c.date).join(
            t.sessions, t.sessions.c.id == t.results.c.session_id).where(t.results.c.id == rid)).one()
        staged.value = {"result_id": rid, "current": current_id(staged.conn, uid) == rid, "date": date}
    except BaseException:
        staged.close()
        raise
    return staged


def calibration_writer(serial: str, param_text: str, session: SessionInfo, *,
                       options: dict | None = None, covariance: dict | None = None, supersedes: int | None = None,
                       make_current: bool | None = None, date_given: bool = False, new_file: bool = False,
                       budget: tuple[dict, dict] | None = None):
    """The transaction that records one calibration of unit ``serial`` (registered with :func:`add_unit`),
    ``fn(connection) -> result id`` for :func:`~inscal.lab.database.write`: ``param_text``, the parameter file exactly as written (parsed here for the
    parameters, fit and version); ``session``, its record (:func:`~inscal.lab.record.session_from_record`;
    one session per unit and record sha256: the first one recorded keeps its metadata); ``options``,
    the calibration's options (:func:`~inscal.lab.record.calibration_options`; by default the method
    alone); ``covariance`` (:func:`~inscal.lab.record.covariance_of`; None: the diagonal of the
    reported 1 sigma); ``supersedes``, the id of a result of the same unit this one replaces;
    ``make_current``: make it the unit's current calibration (None: if its record is not older than
    the current calibration's, so that recording an old calibration afterwards changes nothing).
    The session's date must lie between :data:`~inscal.lab.model.EARLIEST` and now (plus
    :data:`~inscal.lab.model.CLOCK_SKEW`); ``date_given``: it was given by the operator, so a session
    of the record stored already with another date is refused rather than kept silently.
    The same unit, record and options, unless superseding, is refused with :class:`AlreadyRecorded` by the
    unique key the insert itself takes (``result_keys``); ``new_file``: a parameter file already stored
    for the unit is refused too (``inscal db add`` of a file that ``inscal calibrate --serial`` recorded),
    checked inside the same transaction.  ``budget``: ``(station document, budget)`` (:meth:`Station.to_dict
    <inscal.uncertainty.station.Station.to_dict>`, :meth:`Budget.to_dict <inscal.uncertainty.budget.Budget.to_dict>`), stored
    with the result (:func:`write_budget`).
    Raises :class:`DatabaseError` or :class:`~inscal.io.paramfile.ParamFileError`; on any error
    nothing is recorded."""
    doc = parse_param_text(param_text)
    method = doc["method"]
    options = dict(options) if options is not None else {"method": method}
    if options.get("method", method) != method:
        raise DatabaseError(f"options are of method {options.get('method')!r} but the parameter file's is {method!r}")
    options.setdefault("method", method)
    rows = parameter_rows(doc)
    fit, chi2, dof, p = fit_of(doc)
    cov = covariance if covariance is not None else parameter_covariance(rows)
    state_set = (doc.get("metadata") or {}).get("states")
    stamp = now()
    sess = {k: getattr(session, k) for k in ("record_sha256", "record_path", "station", "operator", "latitude_deg",
                                             "longitude_deg", "height_m", "gravity_model", "g_site_m_s2",
                                             "temperature_c", "path_name")}
    try:
        sess["date"] = check_date(session.date, "the record's date")
    except ValueError as exc:
        raise DatabaseError(str(exc)) from None
    for name in ("station", "operator", "path_name"):  # VARCHAR(200) on PostgreSQL; the same bound on SQLite
        check_text(sess[name], f"--{name.replace('_', '-')}")
    ohash, phash = options_hash(options), text_hash(param_text)

    def run(conn):
        uid = unit_id_of(conn, serial)
        conn.execute(_insert_ignore(conn, t.sessions, ["unit_id", "record_sha256"]).values(
            unit_id=uid, recorded_at=stamp, **sess))
        sid, sdate = conn.execute(sa.select(t.sessions.c.id, t.sessions.c.date).where(
            t.sessions.c.unit_id == uid, t.sessions.c.record_sha256 == sess["record_sha256"])).one()
        if date_given and sdate != sess["date"]:
            raise DatabaseError(f"the record {sess['record_sha256'][:19]}... of {serial} is stored already with the date "
                                f"{sdate:%Y-%m-%d %H:%M:%S} UTC, not {sess['date']:%Y-%m-%d %H:%M:%S}: a record has one "
                                "date (leave --date out to use the stored one)")
        if supersedes is not None:
            if not 0 < supersedes < 2**63:
                raise DatabaseError(f"--supersedes {supersedes}: no such result")
            owner = conn.execute(sa.select(t.results.c.unit_id).where(t.results.c.id == supersedes)).scalar()
            if owner is None:
                raise DatabaseError(f"--supersedes {supersedes}: no such result")
            if owner != uid:
                raise DatabaseError(f"--supersedes {supersedes}: that result is of another unit, not {serial}")
        rid = conn.execute(sa.insert(t.results).values(
            unit_id=uid, session_id=sid, method=method, state_set=None if state_set is None else str(state_set),
            options=options, options_hash=options_hash(options), fit_chi2=chi2, fit_dof=dof, fit_p=p, fit=fit,
            notes=_notes(doc), covariance=cov, inscal_version=str(doc.get("inscal_version") or "unknown"),
            param_file=param_text, param_file_sha256=text_hash(param_text), supersedes=supersedes,
            recorded_at=stamp).returning(t.results.c.id)).scalar_one()
        k = t.result_keys.c
        if new_file and supersedes is None:
            old = conn.execute(sa.select(k.result_id).where(k.unit_id == uid, k.param_file_sha256 == phash)
                               .order_by(k.result_id).limit(1)).scalar()
            if old is not None:
                raise AlreadyRecorded(f"this parameter file is recorded already for {serial}, as result {old}", old)
        key = conn.execute(_insert_ignore(conn, t.result_keys, None).values(
            result_id=rid, unit_id=uid, record_sha256=sess["record_sha256"], options_hash=ohash,
            param_file_sha256=phash, supersedes=supersedes or 0).returning(t.result_keys.c.result_id)).first()
        if key is None:  # the unique key is taken: the same calibration, recorded already (perhaps a moment ago)
            old = conn.execute(sa.select(k.result_id).where(
                k.unit_id == uid, k.supersedes == (supersedes or 0), k.record_sha256 == sess["record_sha256"],
                k.options_hash == ohash)).scalar()
            raise AlreadyRecorded(
                f"this calibration of {serial} (the same record and options) is recorded already, as result {old}"
                + (f"; --supersedes {old} records a new one in its place" if supersedes is None
                   else f", also superseding {supersedes}"), old)
        write_parameters(conn, rid, rows)
        if budget is not None:
            write_budget(conn, rid, *budget, stamp)
        current = make_current
        if current is None:
            cid = current_id(conn, uid)
            cdate = None if cid is None else conn.execute(
                sa.select(t.sessions.c.date).join(t.results, t.results.c.session_id == t.sessions.c.id)
                .where(t.results.c.id == cid)).scalar()
            current = cdate is None or sess["date"] >= cdate
        if current:
            conn.execute(sa.insert(t.current).values(unit_id=uid, result_id=rid, set_at=stamp))
        return rid

    return run


def record_result(db: Database, serial: str, result, session: SessionInfo, *, data_file: str | None = None,
                  metadata: dict | None = None, options: dict | None = None, supersedes: int | None = None,
                  make_current: bool | None = None) -> tuple[int, str]:
    """Record a :class:`~inscal.calibrate.CalibrationResult` of a unit, as :func:`record_calibration`.

    Its parameter file's text is :func:`~inscal.lab.record.param_file_text` (with ``data_file``, the
    session's record hash and ``metadata``), its covariance :func:`~inscal.lab.record.covariance_of`.

    Parameters
    ----------
    db : Database
        The open database (written in one transaction).
    serial : str
        The unit's serial, registered with :func:`add_unit`.
    result : CalibrationResult
        The calibration, written as its parameter file's text and covariance.
    session : SessionInfo
        Its record.
    data_file : str, optional
        The record's file name, written in the parameter file.
    metadata : dict, optional
        More to write in the parameter file.
    options : dict, optional
        The calibration's options (by default the method alone).
    supersedes : int, optional
        A result of the same unit this one replaces.
    make_current : bool, optional
        Make it the unit's current calibration (None: if its record is not older).

    Returns
    -------
    tuple of (int, str)
        The result's id and the parameter file's text (write the text to publish the same file).

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> def result(bias_deg_h):  # a six-position result: the x gyro bias [deg/h], 1 sigma 0.001 deg/h
    ...     return CalibrationResult.from_field({"gyro_bias": [bias_deg_h, 0, 0]}, {"gyro_bias": [0.001] * 3}, "six-position")
    >>> db, created = lab.init_database("calib.sqlite")
    >>> unit, _ = lab.add_unit(db, "IMU-1", "nav-grade")
    >>> jan = lab.SessionInfo(record_sha256="sha256:" + "1" * 64, date=dt.datetime(2025, 1, 31))
    >>> first, text = lab.record_result(db, "IMU-1", result(0.010), jan)
    >>> first, text.splitlines()[0]
    (1, 'kind = "inscal-parameters"')

    >>> db.close()
    """
    text = param_file_text(result, data_file, session.record_sha256, metadata)
    rid = record_calibration(db, serial, text, session, options=options, covariance=covariance_of(result),
                             supersedes=supersedes, make_current=make_current)
    return rid, text


def _notes(doc: dict) -> list[str]:
    fit = doc.get("fit") or {}
    return [str(fit["note"])] if isinstance(fit, dict) and fit.get("note") else []


def write_parameters(conn, result_id: int, rows: list[dict]) -> None:
    """Insert the parameter rows of result ``result_id`` (inside the caller's transaction)."""
    conn.execute(sa.insert(t.parameters), [{"result_id": result_id, **r} for r in rows])


def write_budget(conn, result_id: int, station: dict, budget: dict, stamp: dt.datetime) -> None:
    """Store a result's uncertainty budget and its station (the station once per content, by its sha256)."""
    text = json.dumps(station, sort_keys=True, separators=(",", ":"))
    sha = "sha256:" + hashlib.sha256(text.encode()).hexdigest()
    name = str(station["station"]["name"])
    check_text(name, "the station's name")
    conn.execute(_insert_ignore(conn, t.stations, ["document_sha256"]).values(
        name=name, document=station, document_sha256=sha, recorded_at=stamp))
    sid = conn.execute(sa.select(t.stations.c.id).where(t.stations.c.document_sha256 == sha)).scalar_one()
    conn.execute(sa.insert(t.budgets).values(result_id=result_id, station_id=sid, coverage=float(budget["coverage"]),
                                             budget=budget, recorded_at=stamp))


def set_current(db: Database, serial: str, result_id: int) -> None:
    """Make a result the unit's current calibration.

    Parameters
    ----------
    db : Database
        The open database (written in one transaction).
    serial : str
        The unit whose current calibration it becomes.
    result_id : int
        One of its results.

    Raises
    ------
    DatabaseError
        A result of another unit, or none.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> lab.set_current(db, "IMU-1", first)
    >>> lab.current_calibration(db, "IMU-1").id == first
    True

    >>> db.close()
    """

    def run(conn):
        uid = unit_id_of(conn, serial)
        owner = conn.execute(sa.select(t.results.c.unit_id).where(t.results.c.id == result_id)).scalar()
        if owner != uid:
            raise DatabaseError(f"result {result_id} is not a calibration of {serial}")
        conn.execute(sa.insert(t.current).values(unit_id=uid, result_id=result_id, set_at=now()))

    write(db, run)
