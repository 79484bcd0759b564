"""The calibration database: a lab's memory of its units, calibration runs and results
(SQLAlchemy 2, Alembic migrations; SQLite by default, PostgreSQL for a shared lab).

Public API (what ``inscal db``, ``inscal calibrate --db`` and batch calibrations use)::

    from inscal import lab

    db = lab.open_database("calib.sqlite", create=True)      # or a postgresql:// URL; INSCAL_DB
    lab.add_unit(db, "FOG-0042", model="FOG-IMU")
    session = lab.session_from_record("run.h5", station="T1", operator="ana")
    options = lab.calibration_options("n25")                 # what decides the result
    if lab.find_calibration(db, session.record_sha256, options, "FOG-0042") is None:
        rid, text = lab.record_result(db, "FOG-0042", result, session, data_file="run.h5",
                                      metadata=metadata, options=options)   # text: the parameter file
    # or, from a parameter file's text: lab.record_calibration(db, serial, text, session, options=...)
    cal = lab.get_calibration(db, rid)       # parameters (value, sigma, unit), covariance, fit, provenance
    lab.current_calibration(db, "FOG-0042")
    h = lab.unit_history(db, "FOG-0042", k=3)   # repeatability, drift rate +- sigma, flags
    lab.fleet(db, flagged_only=True)

Values are stored in the field units of :data:`inscal.core.error_model.PARAMETERS` (those of the
parameter file); see :mod:`inscal.lab.schema` for the tables, :mod:`inscal.lab.drift` for the
statistics and :mod:`inscal.lab.database` for migrations and concurrent writers.

Calibrating records into the database (these load the estimators, so they are imported on their own):
:mod:`inscal.lab.calibration` (one record, as ``inscal calibrate`` does it) and :mod:`inscal.lab.batch`
(many records on Dask, resumable: ``inscal batch``).
"""

from inscal.lab.database import (
    DEFAULT_FILE,
    ENV_VAR,
    Database,
    DatabaseError,
    database_url,
    head_revision,
    init_database,
    open_database,
    revision_number,
    revision_of,
    upgrade_database,
)
from inscal.lab.drift import (
    DEFAULT_K,
    MONTH_DAYS,
    ComponentDrift,
    History,
    component_drift,
    history,
    tail,
)
from inscal.lab.fleet import FleetEntry, fleet, unit_history
from inscal.lab.model import (
    Calibration,
    Parameter,
    Session,
    SessionInfo,
    Unit,
    parse_date,
)
from inscal.lab.record import (
    calibration_options,
    covariance_of,
    options_hash,
    param_file_text,
    session_from_record,
    text_hash,
)
from inscal.lab.store import (
    add_unit,
    calibrations,
    current_calibration,
    find_calibration,
    find_param_file,
    get_calibration,
    get_unit,
    list_units,
    record_calibration,
    record_result,
    set_current,
    table_counts,
)

__all__ = [
    "DEFAULT_FILE",
    "DEFAULT_K",
    "ENV_VAR",
    "MONTH_DAYS",
    "Calibration",
    "ComponentDrift",
    "Database",
    "DatabaseError",
    "FleetEntry",
    "History",
    "Parameter",
    "Session",
    "SessionInfo",
    "Unit",
    "add_unit",
    "calibration_options",
    "calibrations",
    "component_drift",
    "covariance_of",
    "current_calibration",
    "database_url",
    "find_calibration",
    "find_param_file",
    "fleet",
    "get_calibration",
    "get_unit",
    "head_revision",
    "history",
    "init_database",
    "list_units",
    "open_database",
    "options_hash",
    "param_file_text",
    "parse_date",
    "record_calibration",
    "record_result",
    "revision_number",
    "revision_of",
    "session_from_record",
    "set_current",
    "table_counts",
    "tail",
    "text_hash",
    "unit_history",
    "upgrade_database",
]
