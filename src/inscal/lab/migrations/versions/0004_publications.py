"""v4: ``publications``, the journal of the files a committed result is publishing: one row per output
(target, temporary, sha256 of the temporary, whether it may replace a file, host and process), inserted
in the result's own transaction and deleted once the file is in place.  A row left by a process that
died between the commit and the rename is rolled forward by the next write (:mod:`inscal.lab.journal`).
Not append-only: its rows are deleted when done."""

from alembic import op

from inscal.lab.migrations.ddl import create_table

revision = "0004_publications"
down_revision = "0003_result_keys"


def upgrade() -> None:
    create_table("publications", """
        id                  Integer      PRIMARY KEY
        result_id           Integer      NOT NULL REFERENCES results.id
        target              Text         NOT NULL
        temporary           Text         NOT NULL
        sha256              String(80)   NOT NULL
        overwrite           Boolean      NOT NULL
        host                String(255)  NOT NULL
        pid                 Integer      NOT NULL
        created_at          DateTime     NOT NULL
    """)
    op.create_index("ix_publications_result", "publications", ["result_id"])


def downgrade() -> None:
    op.drop_table("publications")
