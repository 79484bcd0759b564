"""v5: ``stations`` (a station description: the turntable, site, clock and chamber as the Type-B inputs
of an uncertainty budget, as its file states them, stored once per content) and ``budgets`` (the GUM
uncertainty budget of a result at a station, one per result).  Both append-only like the others."""

from alembic import op

from inscal.lab.migrations.ddl import append_only, create_table

revision = "0005_budget"
down_revision = "0004_publications"


def upgrade() -> None:
    create_table("stations", """
        id                  Integer      PRIMARY KEY
        name                String(200)  NOT NULL
        document            JSON         NOT NULL
        document_sha256     String(80)   NOT NULL UNIQUE
        recorded_at         DateTime     NOT NULL
    """)
    create_table("budgets", """
        result_id           Integer      PRIMARY KEY NO AUTOINCREMENT REFERENCES results.id
        station_id          Integer      NOT NULL REFERENCES stations.id
        coverage            Float        NOT NULL
        budget              JSON         NOT NULL
        recorded_at         DateTime     NOT NULL
    """)
    append_only(("stations", "budgets"))


def downgrade() -> None:
    op.drop_table("budgets")
    op.drop_table("stations")
