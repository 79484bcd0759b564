"""v4: ``publications``, the journal of the files a committed result is publishing: one row per output
(target, temporary, sha256 of the temporary, whether it may replace a file, host and process), inserted
in the result's own transaction and deleted once the file is in place.  A row left by a process that
died between the commit and the rename is rolled forward by the next write (:mod:`inscal.lab.journal`).
Not append-only: its rows are deleted when done.

Revision ID: 0004_publications
Revises: 0003_result_keys
"""

import sqlalchemy as sa
from alembic import op

revision = "0004_publications"
down_revision = "0003_result_keys"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "publications",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("result_id", sa.Integer, sa.ForeignKey("results.id"), nullable=False),
        sa.Column("target", sa.Text, nullable=False),
        sa.Column("temporary", sa.Text, nullable=False),
        sa.Column("sha256", sa.String(80), nullable=False),
        sa.Column("overwrite", sa.Boolean, nullable=False),
        sa.Column("host", sa.String(255), nullable=False),
        sa.Column("pid", sa.Integer, nullable=False),
        sa.Column("created_at", sa.DateTime, nullable=False),
    )
    op.create_index("ix_publications_result", "publications", ["result_id"])


def downgrade() -> None:
    op.drop_table("publications")
