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
    db, ids = lab.example_history("try.sqlite")   # a small database to try these on (one unit, two results)

Values are stored in the field units of :data:`inscal.core.error_model.PARAMETERS` (those of the
parameter file); see :mod:`inscal.lab.schema` for the tables, :mod:`inscal.lab.drift` for the
statistics, :mod:`inscal.lab.opening` for migrations, :mod:`inscal.lab.database` for concurrent writers,
:mod:`inscal.lab.store` for the writes and :mod:`inscal.lab.queries` for the reads.

Calibrating records into the database is :mod:`inscal.runs` (one record as ``inscal calibrate`` does it, a
batch on Dask); the uncertainty budget of a calibration (GUM) is :mod:`inscal.uncertainty`, stored with the
result here (``record_calibration(..., budget=...)``, :func:`get_budget`).

The names above load their module on first use (PEP 562): a command that imports
:mod:`inscal.runs.calibration` or :mod:`inscal.lab.record` to calibrate without a database does not pay
for SQLAlchemy and Alembic (0.3 s of every ``inscal calibrate``'s start).  No public name is also the name of
a submodule (``lab.fleet`` is the function; its module is :mod:`inscal.lab.fleet_status`), so importing a
submodule never hides a name.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

#: public name -> the module that defines it
EXPORTS = {
    "DEFAULT_FILE": "inscal.lab.database",
    "Database": "inscal.lab.database",
    "DatabaseError": "inscal.lab.database",
    "ENV_VAR": "inscal.lab.database",
    "database_url": "inscal.lab.database",
    "head_revision": "inscal.lab.opening",
    "init_database": "inscal.lab.opening",
    "open_database": "inscal.lab.opening",
    "revision_number": "inscal.lab.opening",
    "revision_of": "inscal.lab.opening",
    "upgrade_database": "inscal.lab.opening",
    "check_wait": "inscal.lab.database",
    "lock_holders": "inscal.lab.database",
    "ComponentDrift": "inscal.lab.drift",
    "DEFAULT_K": "inscal.lab.drift",
    "History": "inscal.lab.drift",
    "MONTH_DAYS": "inscal.lab.drift",
    "component_drift": "inscal.lab.drift",
    "history": "inscal.lab.drift",
    "tail": "inscal.lab.drift",
    "FleetEntry": "inscal.lab.fleet_status",
    "fleet": "inscal.lab.fleet_status",
    "unit_history": "inscal.lab.fleet_status",
    "Calibration": "inscal.lab.model",
    "Parameter": "inscal.lab.model",
    "Session": "inscal.lab.model",
    "SessionInfo": "inscal.lab.model",
    "Unit": "inscal.lab.model",
    "parse_date": "inscal.lab.model",
    "check_date": "inscal.lab.model",
    "CLOCK_SKEW": "inscal.lab.model",
    "EARLIEST": "inscal.lab.model",
    "calibration_options": "inscal.lab.record",
    "covariance_of": "inscal.lab.record",
    "options_hash": "inscal.lab.record",
    "param_file_text": "inscal.lab.record",
    "session_from_record": "inscal.lab.record",
    "text_hash": "inscal.lab.record",
    "add_unit": "inscal.lab.store",
    "AlreadyRecorded": "inscal.lab.store",
    "calibrations": "inscal.lab.queries",
    "current_calibration": "inscal.lab.queries",
    "find_calibration": "inscal.lab.queries",
    "find_param_file": "inscal.lab.queries",
    "get_budget": "inscal.lab.queries",
    "get_calibration": "inscal.lab.queries",
    "get_unit": "inscal.lab.queries",
    "list_units": "inscal.lab.queries",
    "record_calibration": "inscal.lab.store",
    "record_result": "inscal.lab.store",
    "set_current": "inscal.lab.store",
    "stage_calibration": "inscal.lab.store",
    "pending_publications": "inscal.lab.database",
    "published": "inscal.lab.database",
    "recover_publications": "inscal.lab.database",
    "table_counts": "inscal.lab.queries",
    "example_history": "inscal.lab.example",
}
__all__ = [
    "CLOCK_SKEW",
    "EARLIEST",
    "AlreadyRecorded",
    "check_date",
    "check_wait",
    "lock_holders",
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
    "get_budget",
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
    "pending_publications",
    "published",
    "record_calibration",
    "recover_publications",
    "record_result",
    "revision_number",
    "revision_of",
    "session_from_record",
    "example_history",
    "set_current",
    "stage_calibration",
    "table_counts",
    "tail",
    "text_hash",
    "unit_history",
    "upgrade_database",
]

if TYPE_CHECKING:  # the names for type checkers and IDEs; at run time they load on first use
    from inscal.lab.database import (
        DEFAULT_FILE,
        ENV_VAR,
        Database,
        DatabaseError,
        database_url,
        check_wait,
        pending_publications,
        published,
        recover_publications,
        lock_holders,
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
    from inscal.lab.fleet_status import (
        FleetEntry,
        fleet,
        unit_history,
    )
    from inscal.lab.model import (
        Calibration,
        Parameter,
        Session,
        SessionInfo,
        Unit,
        parse_date,
        check_date,
        CLOCK_SKEW,
        EARLIEST,
    )
    from inscal.lab.opening import (
        head_revision,
        init_database,
        open_database,
        revision_number,
        revision_of,
        upgrade_database,
    )
    from inscal.lab.record import (
        calibration_options,
        covariance_of,
        options_hash,
        param_file_text,
        session_from_record,
        text_hash,
    )
    from inscal.lab.example import example_history
    from inscal.lab.queries import (
        calibrations,
        current_calibration,
        find_calibration,
        find_param_file,
        get_budget,
        get_calibration,
        get_unit,
        list_units,
        table_counts,
    )
    from inscal.lab.store import (
        AlreadyRecorded,
        add_unit,
        record_calibration,
        record_result,
        set_current,
        stage_calibration,
    )


def __getattr__(name: str):
    """``lab.NAME``: the public name, its module imported now; every public name of that module is then
    kept as an attribute of the package."""
    try:
        module = importlib.import_module(EXPORTS[name])
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    for public, where in EXPORTS.items():
        if where == module.__name__:
            globals()[public] = getattr(module, public)
    return globals()[name]


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(EXPORTS))

