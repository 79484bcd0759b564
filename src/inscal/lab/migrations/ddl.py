"""The frozen building blocks of the calibration database's migrations (the Alembic scripts in ``versions/``).

A migration keeps meaning what it meant when it was written: nothing here follows the live schema
(:mod:`inscal.lab.schema`), and a function here is never changed once a migration calls it (a migration that
needs another statement adds a function).

- :func:`create_table`: a table whose columns are written as a compact DDL text, one column a line,
  ``name  Type  [PRIMARY KEY] [NO AUTOINCREMENT] [NOT NULL] [UNIQUE] [REFERENCES table.column]``
  (``Type``: a name of :data:`TYPES`, or ``String(n)``);
- :func:`append_only`: the triggers that refuse an ``UPDATE`` or a ``DELETE`` of a table's rows (SQLite,
  PostgreSQL: its trigger function ``inscal_append_only()`` is made by the first migration).
"""

from __future__ import annotations

import re

import sqlalchemy as sa
from alembic import op

#: the column types a column line may name (besides ``String(n)``)
TYPES = {"Integer": sa.Integer, "Float": sa.Float, "Text": sa.Text, "JSON": sa.JSON, "DateTime": sa.DateTime,
         "Boolean": sa.Boolean}
#: the keywords of a column line, with the ``sa.Column`` keyword argument each one sets
FLAGS = {"PRIMARY KEY": ("primary_key", True), "NO AUTOINCREMENT": ("autoincrement", False),
         "NOT NULL": ("nullable", False), "UNIQUE": ("unique", True)}


def column(line: str) -> sa.Column:
    """The column of one line ``name Type [keywords]`` (the module's docstring); an unknown word is refused."""
    name, type_name, rest = (line.split(None, 2) + [""])[:3]
    size = re.fullmatch(r"String\((\d+)\)", type_name)
    args: list = [sa.String(int(size.group(1))) if size else TYPES[type_name]]
    ref = re.search(r"REFERENCES (\S+)", rest)
    if ref:
        args.append(sa.ForeignKey(ref.group(1)))
        rest = rest.replace(ref.group(0), "")
    kw = {}
    for flag, (key, value) in FLAGS.items():
        if flag in rest:
            kw[key] = value
            rest = rest.replace(flag, "")
    if rest.strip():
        raise ValueError(f"column {name}: unknown words {rest.split()}")
    return sa.Column(name, *args, **kw)


def create_table(name: str, columns: str, *constraints) -> None:
    """``op.create_table`` of the columns written one a line in ``columns``, then ``constraints``."""
    op.create_table(name, *(column(line) for line in columns.strip().splitlines()), *constraints)


def append_only(tables, quote_names: bool = False) -> None:
    """The triggers that refuse an UPDATE or a DELETE of the rows of each of ``tables`` (SQLite; PostgreSQL),
    the table named in double quotes in the trigger's ``ON`` where ``quote_names``."""
    dialect = op.get_bind().dialect.name
    for table in tables:
        on = f'"{table}"' if quote_names else table
        if dialect == "sqlite":
            for event in ("UPDATE", "DELETE"):
                op.execute(f"CREATE TRIGGER {table}_no_{event.lower()} BEFORE {event} ON {on} BEGIN "
                           f"SELECT RAISE(ABORT, 'inscal: table {table} is append-only (no UPDATE or DELETE)'); END")
        elif dialect == "postgresql":
            op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {on} "
                       "FOR EACH ROW EXECUTE FUNCTION inscal_append_only()")
