"""v2: the temperature of a session (the IMU's, when the record or the operator gives it) [deg C].

Revision ID: 0002_session_temperature
Revises: 0001_initial
"""

import sqlalchemy as sa
from alembic import op

revision = "0002_session_temperature"
down_revision = "0001_initial"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # ALTER TABLE ... ADD COLUMN on both SQLite and PostgreSQL: the rows stay, the new column is NULL
    # (not known) for the sessions recorded before
    op.add_column("sessions", sa.Column("temperature_c", sa.Float, nullable=True))


def downgrade() -> None:
    op.drop_column("sessions", "temperature_c")
