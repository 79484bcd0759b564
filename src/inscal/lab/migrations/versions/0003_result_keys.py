"""v3: ``result_keys``, what makes a result unique: one row per result, unique on (unit, record sha256,
options hash, the result it supersedes or 0), with the parameter file's sha256 (indexed: ``db add`` of a
file stored already is refused in its transaction).  The "recorded already" check is then the insert
itself, one atomic step on every back-end, not a look-up before a write that a concurrent writer could
slip between.

The results recorded before (an older inscal could record the same calibration twice) are keyed in
the order they were recorded: the first of each key keeps it, a later duplicate stays in ``results``
(append-only) without a key, as it was."""

import sqlalchemy as sa
from alembic import op

from inscal.lab.migrations.ddl import append_only, create_table

revision = "0003_result_keys"
down_revision = "0002_session_temperature"


def upgrade() -> None:
    # supersedes: the result superseded, 0 for none
    create_table("result_keys", """
        result_id           Integer      PRIMARY KEY NO AUTOINCREMENT REFERENCES results.id
        unit_id             Integer      NOT NULL REFERENCES units.id
        record_sha256       String(80)   NOT NULL
        options_hash        String(80)   NOT NULL
        param_file_sha256   String(80)   NOT NULL
        supersedes          Integer      NOT NULL
    """, sa.UniqueConstraint("unit_id", "record_sha256", "options_hash", "supersedes", name="uq_result_keys_options"))
    op.create_index("ix_result_keys_param_file", "result_keys", ["unit_id", "param_file_sha256"])
    dialect = op.get_bind().dialect.name
    select = ("SELECT r.id, r.unit_id, s.record_sha256, r.options_hash, r.param_file_sha256, COALESCE(r.supersedes, 0) "
              "FROM results r JOIN sessions s ON s.id = r.session_id ORDER BY r.id")
    cols = "(result_id, unit_id, record_sha256, options_hash, param_file_sha256, supersedes)"
    if dialect == "sqlite":
        op.execute(f"INSERT OR IGNORE INTO result_keys {cols} {select}")
    else:
        conn = op.get_bind()
        for row in conn.execute(sa.text(select)).all():  # one by one, in order: the first of each key keeps it
            conn.execute(sa.text(f"INSERT INTO result_keys {cols} VALUES (:a, :b, :c, :d, :e, :f) "
                                 "ON CONFLICT DO NOTHING"), dict(zip("abcdef", row)))
    append_only(["result_keys"])


def downgrade() -> None:
    op.drop_table("result_keys")
