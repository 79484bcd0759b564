"""v2: the temperature of a session (the IMU's, when the record or the operator gives it) [deg C]."""

from alembic import op

from inscal.lab.migrations.ddl import column

revision = "0002_session_temperature"
down_revision = "0001_initial"


def upgrade() -> None:
    # ALTER TABLE ... ADD COLUMN on both SQLite and PostgreSQL: the rows stay, the new column is NULL
    # (not known) for the sessions recorded before
    op.add_column("sessions", column("temperature_c  Float"))


def downgrade() -> None:
    op.drop_column("sessions", "temperature_c")
