"""v1: units, sessions, results, parameters and the current-calibration pointers (append-only).

Revision ID: 0001_initial
Revises: (none)
"""

import sqlalchemy as sa
from alembic import op

revision = "0001_initial"
down_revision = None
branch_labels = None
depends_on = None

#: the append-only tables: triggers refuse an UPDATE or a DELETE of their rows
APPEND_ONLY = ("units", "sessions", "results", "parameters", "current")


def upgrade() -> None:
    op.create_table(
        "units",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(200), nullable=False, unique=True),
        sa.Column("model", sa.String(200)),
        sa.Column("notes", sa.Text),
        sa.Column("created_at", sa.DateTime, nullable=False),
    )
    op.create_table(
        "sessions",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
        sa.Column("record_sha256", sa.String(80), nullable=False),
        sa.Column("record_path", sa.Text),
        sa.Column("station", sa.String(200)),
        sa.Column("operator", sa.String(200)),
        sa.Column("date", sa.DateTime, nullable=False),
        sa.Column("latitude_deg", sa.Float),
        sa.Column("longitude_deg", sa.Float),
        sa.Column("height_m", sa.Float),
        sa.Column("gravity_model", sa.Text),
        sa.Column("g_site_m_s2", sa.Float),
        sa.Column("path_name", sa.String(200)),
        sa.Column("recorded_at", sa.DateTime, nullable=False),
        sa.UniqueConstraint("unit_id", "record_sha256", name="uq_sessions_unit_record"),
    )
    op.create_table(
        "results",
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
        sa.Column("param_file", sa.Text, nullable=False),
        sa.Column("param_file_sha256", sa.String(80), nullable=False),
        sa.Column("supersedes", sa.Integer, sa.ForeignKey("results.id")),
        sa.Column("recorded_at", sa.DateTime, nullable=False),
    )
    op.create_index("ix_results_options_hash", "results", ["options_hash"])
    op.create_index("ix_results_unit", "results", ["unit_id"])
    op.create_table(
        "parameters",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
        sa.Column("name", sa.String(64), nullable=False),
        sa.Column("component", sa.Integer, nullable=False),
        sa.Column("label", sa.String(100), nullable=False),
        sa.Column("value", sa.Float),
        sa.Column("sigma", sa.Float),
        sa.Column("sigma_formal", sa.Float),
        sa.Column("unit", sa.String(32), nullable=False),
        sa.UniqueConstraint("result_id", "name", "component", name="uq_parameters_result_component"),
    )
    op.create_table(
        "current",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("unit_id", sa.Integer, sa.ForeignKey("units.id"), nullable=False),
        sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
        sa.Column("set_at", sa.DateTime, nullable=False),
    )
    op.create_index("ix_current_unit", "current", ["unit_id"])
    dialect = op.get_bind().dialect.name
    if dialect == "postgresql":
        op.execute("CREATE FUNCTION inscal_append_only() RETURNS trigger LANGUAGE plpgsql AS $$ "
                   "BEGIN RAISE EXCEPTION 'inscal: table % is append-only (no UPDATE or DELETE)', TG_TABLE_NAME; END $$")
    for table in APPEND_ONLY:
        if dialect == "sqlite":
            for event in ("UPDATE", "DELETE"):
                op.execute(f"CREATE TRIGGER {table}_no_{event.lower()} BEFORE {event} ON \"{table}\" BEGIN "
                           f"SELECT RAISE(ABORT, 'inscal: table {table} is append-only (no UPDATE or DELETE)'); END")
        elif dialect == "postgresql":
            op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON \"{table}\" "
                       "FOR EACH ROW EXECUTE FUNCTION inscal_append_only()")


def downgrade() -> None:
    for table in reversed(APPEND_ONLY):
        op.drop_table(table)
    if op.get_bind().dialect.name == "postgresql":
        op.execute("DROP FUNCTION IF EXISTS inscal_append_only()")
