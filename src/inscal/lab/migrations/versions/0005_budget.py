"""v5: ``stations`` (a station description: the turntable, site, clock and chamber as the Type-B inputs
of an uncertainty budget, as its file states them, stored once per content) and ``budgets`` (the GUM
uncertainty budget of a result at a station, one per result).  Both append-only like the others.

Revision ID: 0005_budget
Revises: 0004_publications
"""

import sqlalchemy as sa
from alembic import op

revision = "0005_budget"
down_revision = "0004_publications"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "stations",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("document", sa.JSON, nullable=False),
        sa.Column("document_sha256", sa.String(80), nullable=False, unique=True),
        sa.Column("recorded_at", sa.DateTime, nullable=False),
    )
    op.create_table(
        "budgets",
        sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), primary_key=True, autoincrement=False),
        sa.Column("station_id", sa.Integer, sa.ForeignKey("stations.id"), nullable=False),
        sa.Column("coverage", sa.Float, nullable=False),
        sa.Column("budget", sa.JSON, nullable=False),
        sa.Column("recorded_at", sa.DateTime, nullable=False),
    )
    dialect = op.get_bind().dialect.name
    for table in ("stations", "budgets"):
        if dialect == "sqlite":
            for event in ("UPDATE", "DELETE"):
                op.execute(f"CREATE TRIGGER {table}_no_{event.lower()} BEFORE {event} ON {table} BEGIN "
                           f"SELECT RAISE(ABORT, 'inscal: table {table} is append-only (no UPDATE or DELETE)'); END")
        elif dialect == "postgresql":
            op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                       "FOR EACH ROW EXECUTE FUNCTION inscal_append_only()")


def downgrade() -> None:
    op.drop_table("budgets")
    op.drop_table("stations")
