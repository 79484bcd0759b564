"""v1: units, sessions, results, parameters and the current-calibration pointers (append-only)."""

import sqlalchemy as sa
from alembic import op

from inscal.lab.migrations.ddl import append_only, create_table

revision = "0001_initial"
down_revision = None

#: the append-only tables: triggers refuse an UPDATE or a DELETE of their rows
APPEND_ONLY = ("units", "sessions", "results", "parameters", "current")


def upgrade() -> None:
    create_table("units", """
        id                  Integer      PRIMARY KEY
        serial              String(200)  NOT NULL UNIQUE
        model               String(200)
        notes               Text
        created_at          DateTime     NOT NULL
    """)
    create_table("sessions", """
        id                  Integer      PRIMARY KEY
        unit_id             Integer      NOT NULL REFERENCES units.id
        record_sha256       String(80)   NOT NULL
        record_path         Text
        station             String(200)
        operator            String(200)
        date                DateTime     NOT NULL
        latitude_deg        Float
        longitude_deg       Float
        height_m            Float
        gravity_model       Text
        g_site_m_s2         Float
        path_name           String(200)
        recorded_at         DateTime     NOT NULL
    """, sa.UniqueConstraint("unit_id", "record_sha256", name="uq_sessions_unit_record"))
    create_table("results", """
        id                  Integer      PRIMARY KEY
        unit_id             Integer      NOT NULL REFERENCES units.id
        session_id          Integer      NOT NULL REFERENCES sessions.id
        method              String(64)   NOT NULL
        state_set           String(200)
        options             JSON         NOT NULL
        options_hash        String(80)   NOT NULL
        fit_chi2            Float
        fit_dof             Float
        fit_p               Float
        fit                 JSON
        notes               JSON
        covariance          JSON
        inscal_version      String(64)   NOT NULL
        param_file          Text         NOT NULL
        param_file_sha256   String(80)   NOT NULL
        supersedes          Integer      REFERENCES results.id
        recorded_at         DateTime     NOT NULL
    """)
    op.create_index("ix_results_options_hash", "results", ["options_hash"])
    op.create_index("ix_results_unit", "results", ["unit_id"])
    create_table("parameters", """
        id                  Integer      PRIMARY KEY
        result_id           Integer      NOT NULL REFERENCES results.id
        name                String(64)   NOT NULL
        component           Integer      NOT NULL
        label               String(100)  NOT NULL
        value               Float
        sigma               Float
        sigma_formal        Float
        unit                String(32)   NOT NULL
    """, sa.UniqueConstraint("result_id", "name", "component", name="uq_parameters_result_component"))
    create_table("current", """
        id                  Integer      PRIMARY KEY
        unit_id             Integer      NOT NULL REFERENCES units.id
        result_id           Integer      NOT NULL REFERENCES results.id
        set_at              DateTime     NOT NULL
    """)
    op.create_index("ix_current_unit", "current", ["unit_id"])
    if op.get_bind().dialect.name == "postgresql":
        op.execute("CREATE FUNCTION inscal_append_only() RETURNS trigger LANGUAGE plpgsql AS $$ "
                   "BEGIN RAISE EXCEPTION 'inscal: table % is append-only (no UPDATE or DELETE)', TG_TABLE_NAME; END $$")
    append_only(APPEND_ONLY, quote_names=True)


def downgrade() -> None:
    for table in reversed(APPEND_ONLY):
        op.drop_table(table)
    if op.get_bind().dialect.name == "postgresql":
        op.execute("DROP FUNCTION IF EXISTS inscal_append_only()")
