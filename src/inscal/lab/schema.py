"""The tables of the calibration database (SQLAlchemy Core), at the newest schema revision.

Every table but ``publications`` is append-only: rows are inserted, never updated nor deleted (database
triggers refuse an ``UPDATE`` or ``DELETE``, see the first migration).  ``publications`` is a journal: the
files a result's transaction is about to publish, each row deleted once its file is in place
(:mod:`inscal.lab.journal`).  A result that replaces an earlier one
names it in ``results.supersedes``; the unit's current calibration is the newest row of
``current`` for the unit.

Units: parameter values and 1 sigma are stored in the field units of
:data:`inscal.core.error_model.PARAMETERS` (ppm, arcsec, deg/h, ug ...), the units of the parameter
file, with the unit's name in ``parameters.unit``; a covariance over the parameter components is
in the same field units, a covariance over an estimator's own states (the systematic filter's)
in SI (``results.covariance["units"]`` says which).  Times are UTC, stored without a zone.

The schema's history is in ``inscal/lab/migrations/`` (Alembic scripts): revision ``0001_initial``
(v1) made every table below without ``sessions.temperature_c``; ``0002_session_temperature`` (v2)
added it; ``0003_result_keys`` (v3) added ``result_keys``, the unique keys of the results;
``0004_publications`` (v4) added ``publications``, the journal of the files being published.
``0005_budget`` (v5) added ``stations`` (a station description, :mod:`inscal.uncertainty.station`) and
``budgets`` (a result's uncertainty budget at a station, :mod:`inscal.uncertainty.budget`).
"""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

units = sa.Table(
    "units", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(200), nullable=False, unique=True),
    sa.Column("model", sa.String(200)),
    sa.Column("notes", sa.Text),
    sa.Column("created_at", sa.DateTime, nullable=False),
)

sessions = sa.Table(
    "sessions", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
    sa.Column("record_sha256", sa.String(80), nullable=False),  # io.file_hash: "sha256:<hex>"
    sa.Column("record_path", sa.Text),
    sa.Column("station", sa.String(200)),
    sa.Column("operator", sa.String(200)),
    sa.Column("date", sa.DateTime, nullable=False),  # when the record was taken (UTC)
    sa.Column("latitude_deg", sa.Float),
    sa.Column("longitude_deg", sa.Float),
    sa.Column("height_m", sa.Float),
    sa.Column("gravity_model", sa.Text),  # GravityModel.to_json(), as JSON text
    sa.Column("g_site_m_s2", sa.Float),
    sa.Column("path_name", sa.String(200)),
    sa.Column("recorded_at", sa.DateTime, nullable=False),
    sa.Column("temperature_c", sa.Float),  # v2
    sa.UniqueConstraint("unit_id", "record_sha256", name="uq_sessions_unit_record"),
)

results = sa.Table(
    "results", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
    sa.Column("session_id", sa.Integer, sa.ForeignKey("sessions.id"), nullable=False),
    sa.Column("method", sa.String(64), nullable=False),
    sa.Column("state_set", sa.String(200)),
    sa.Column("options", sa.JSON, nullable=False),
    sa.Column("options_hash", sa.String(80), nullable=False),
    sa.Column("fit_chi2", sa.Float),
    sa.Column("fit_dof", sa.Float),
    sa.Column("fit_p", sa.Float),
    sa.Column("fit", sa.JSON),
    sa.Column("notes", sa.JSON),
    sa.Column("covariance", sa.JSON),
    sa.Column("inscal_version", sa.String(64), nullable=False),
    sa.Column("param_file", sa.Text, nullable=False),  # the parameter file as written, byte for byte (UTF-8)
    sa.Column("param_file_sha256", sa.String(80), nullable=False),
    sa.Column("supersedes", sa.Integer, sa.ForeignKey("results.id")),
    sa.Column("recorded_at", sa.DateTime, nullable=False),
    sa.Index("ix_results_options_hash", "options_hash"),
    sa.Index("ix_results_unit", "unit_id"),
)

parameters = sa.Table(
    "parameters", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
    sa.Column("name", sa.String(64), nullable=False),
    sa.Column("component", sa.Integer, nullable=False),  # index in the flattened (row-major) parameter
    sa.Column("label", sa.String(100), nullable=False),  # e.g. accel_scale_factor[x]
    sa.Column("value", sa.Float),  # field unit; NULL: not a finite number
    sa.Column("sigma", sa.Float),  # reported 1 sigma, field unit; NULL: held fixed (not estimated)
    sa.Column("sigma_formal", sa.Float),  # formal 1 sigma where the reported one was scaled
    sa.Column("unit", sa.String(32), nullable=False),
    sa.UniqueConstraint("result_id", "name", "component", name="uq_parameters_result_component"),
)

current = sa.Table(
    "current", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
    sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
    sa.Column("set_at", sa.DateTime, nullable=False),
    sa.Index("ix_current_unit", "unit_id"),
)

result_keys = sa.Table(  # v3: what makes a result unique (the insert is the "recorded already" check)
    "result_keys", metadata,
    sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), primary_key=True, autoincrement=False),
    sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
    sa.Column("record_sha256", sa.String(80), nullable=False),
    sa.Column("options_hash", sa.String(80), nullable=False),
    sa.Column("param_file_sha256", sa.String(80), nullable=False),
    sa.Column("supersedes", sa.Integer, nullable=False),  # the result superseded, 0 for none
    sa.UniqueConstraint("unit_id", "record_sha256", "options_hash", "supersedes", name="uq_result_keys_options"),
    sa.Index("ix_result_keys_param_file", "unit_id", "param_file_sha256"),
)

publications = sa.Table(  # v4: the journal of the files a committed result is publishing (rows deleted when done)
    "publications", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
    sa.Column("target", sa.Text, nullable=False),  # the output's absolute path
    sa.Column("temporary", sa.Text, nullable=False),  # its temporary beside it, complete and fsynced
    sa.Column("sha256", sa.String(80), nullable=False),  # io.file_hash of the temporary: "sha256:<hex>"
    sa.Column("overwrite", sa.Boolean, nullable=False),  # --force: the output may replace a file there
    sa.Column("host", sa.String(255), nullable=False),  # the machine whose file system holds the paths
    sa.Column("pid", sa.Integer, nullable=False),
    sa.Column("created_at", sa.DateTime, nullable=False),
    sa.Index("ix_publications_result", "result_id"),
)

stations = sa.Table(  # v5: a station description as its file states it (field units), once per content
    "stations", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("name", sa.String(200), nullable=False),
    sa.Column("document", sa.JSON, nullable=False),  # Station.to_dict()
    sa.Column("document_sha256", sa.String(80), nullable=False, unique=True),
    sa.Column("recorded_at", sa.DateTime, nullable=False),
)

budgets = sa.Table(  # v5: the uncertainty budget of a result at a station (Budget.to_dict(), field units)
    "budgets", metadata,
    sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), primary_key=True, autoincrement=False),
    sa.Column("station_id", sa.Integer, sa.ForeignKey("stations.id"), nullable=False),
    sa.Column("coverage", sa.Float, nullable=False),
    sa.Column("budget", sa.JSON, nullable=False),
    sa.Column("recorded_at", sa.DateTime, nullable=False),
)

#: the tables, parents first (the order rows are copied or counted in)
TABLES = (units, sessions, results, parameters, current, result_keys, publications, stations, budgets)
