"""Opening the calibration database: its URL, the engine, the schema revision, and transactions
that lose nothing when several processes write at once.

``--db`` / ``INSCAL_DB`` is a file path (SQLite, the default: one file, nothing to set up) or a
URL: ``sqlite:///PATH`` or ``postgresql://USER[:PASSWORD]@HOST[:PORT]/NAME`` (a shared lab
database; the ``psycopg`` driver, ``pip install 'inscal[postgresql]'``).  Without either, the
file ``calib.sqlite`` in the current folder.

Schema revisions (Alembic scripts in ``inscal/lab/migrations/``: ``env.py`` and one file per revision in
``versions/``, loaded by path, not as modules): :func:`init_database` creates the tables
at the newest revision; :func:`open_database` refuses, in one line, a database whose revision
is newer than this inscal knows (made by a newer inscal) and one at an older revision (run
``inscal db upgrade``, or ``upgrade=True``), so no version ever writes rows the other cannot read.

Writes (:func:`write`) are single transactions: all of a result or none of it, whatever happens to
the process.  SQLite runs in WAL mode (readers do not block the writer) with a busy timeout, and
a write transaction starts with ``BEGIN IMMEDIATE`` (it takes the write lock up front, so two
writers never deadlock on a lock upgrade); a transaction that still meets a locked database, or a
PostgreSQL serialization failure or deadlock, is retried whole.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory

#: the file the commands use when neither ``--db`` nor ``INSCAL_DB`` names one
DEFAULT_FILE = "calib.sqlite"
ENV_VAR = "INSCAL_DB"
MIGRATIONS = Path(__file__).resolve().parent / "migrations"
#: how long a writer waits for a locked SQLite database, per attempt and in all [s]
BUSY_TIMEOUT_S = 30.0
LOCK_RETRY_S = 120.0
#: SQLSTATEs of a PostgreSQL transaction that lost a race and may be run again
PG_RETRY_STATES = ("40001", "40P01")


class DatabaseError(Exception):
    """A database that cannot be used, or a request it refuses: one line, with the reason."""


@dataclass
class Database:
    """An open calibration database: ``engine`` (SQLAlchemy), its ``url`` and ``where`` (the URL
    to print: no password).  Close it with :meth:`close` (or use it as a context manager).  One per
    process: a worker process opens its own (an engine's pooled connections do not cross a fork)."""

    engine: sa.Engine
    url: sa.URL
    where: str

    @property
    def dialect(self) -> str:
        """The SQL dialect of the database: ``sqlite`` or ``postgresql``."""
        return self.engine.dialect.name

    def close(self) -> None:
        """Release the database's connections (dispose of its engine)."""
        self.engine.dispose()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def database_url(text: str | os.PathLike | None = None) -> sa.URL:
    """The URL of ``--db`` (or ``INSCAL_DB``, or ``calib.sqlite``): a path becomes ``sqlite:///ABSOLUTE``,
    ``postgresql://`` takes the psycopg (3) driver.  Raises :class:`DatabaseError` for anything else."""
    if text is None or str(text) == "":
        text = os.environ.get(ENV_VAR) or DEFAULT_FILE
    text = str(text)
    if "://" not in text:
        return sa.URL.create("sqlite", database=str(Path(text).expanduser().absolute()))
    try:
        url = sa.make_url(text)
    except sa.exc.ArgumentError as exc:
        raise DatabaseError(f"--db {text!r}: not a database URL ({exc})") from None
    backend = url.get_backend_name()
    if backend == "sqlite":
        if not url.database or url.database == ":memory:":
            raise DatabaseError(f"--db {url.render_as_string(hide_password=True)}: an in-memory database keeps nothing; "
                                "give a file")
        return url
    if backend == "postgresql":
        driver = url.get_driver_name()
        if url.drivername == "postgresql" or driver == "psycopg2":
            url = url.set(drivername="postgresql+psycopg")
        elif driver != "psycopg":
            raise DatabaseError(f"--db: driver {driver!r} is not supported for PostgreSQL (use postgresql:// or "
                                "postgresql+psycopg://)")
        return url
    raise DatabaseError(f"--db {url.render_as_string(hide_password=True)}: unsupported database {backend!r} "
                        "(a file path or sqlite:///PATH, or postgresql://USER@HOST/NAME)")


def describe(url: sa.URL) -> str:
    """The URL to print: a SQLite file as its path, a server URL without its password."""
    if url.get_backend_name() == "sqlite":
        return str(url.database)
    return url.render_as_string(hide_password=True)


def _sqlite_connect(dbapi_connection, _record) -> None:
    dbapi_connection.isolation_level = None  # the transactions are begun by _sqlite_begin, not the driver
    cur = dbapi_connection.cursor()
    cur.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
    cur.execute("PRAGMA foreign_keys = ON")
    cur.execute("PRAGMA synchronous = FULL")  # a committed result survives a power cut, not only a crash
    try:  # persistent (kept by the file): readers no longer block the writer, nor the writer them
        cur.execute("PRAGMA journal_mode = WAL")
    except sqlite3.OperationalError:  # a read-only file or folder: it is read as it is
        pass
    cur.close()


def _sqlite_begin(conn) -> None:
    conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("inscal_write") else "BEGIN")


def make_engine(url: sa.URL) -> sa.Engine:
    """The SQLAlchemy engine of ``url`` (SQLite: WAL, busy timeout, foreign keys, explicit BEGIN)."""
    if url.get_backend_name() == "sqlite":
        engine = sa.create_engine(url)  # a pool: a connection kept open spares the WAL checkpoint of the last close
        sa.event.listen(engine, "connect", _sqlite_connect)
        sa.event.listen(engine, "begin", _sqlite_begin)
        return engine
    try:
        return sa.create_engine(url, pool_pre_ping=True, connect_args={"connect_timeout": 10})
    except ModuleNotFoundError:
        raise DatabaseError("PostgreSQL needs the psycopg driver: pip install 'inscal[postgresql]'") from None


def _alembic_config(connection=None) -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    cfg.attributes["connection"] = connection
    return cfg


@functools.cache
def script() -> ScriptDirectory:
    """The migrations this inscal ships (read once)."""
    return ScriptDirectory.from_config(_alembic_config())


def head_revision() -> str:
    """The newest schema revision the shipped Alembic scripts define."""
    return script().get_current_head()


def revision_number(rev: str | None) -> int | None:
    """The schema version of a revision id (``0002_session_temperature`` -> 2), None if unknown."""
    if rev is None:
        return None
    known = [r.revision for r in reversed(list(script().walk_revisions()))]  # oldest first
    return known.index(rev) + 1 if rev in known else None


def _state(engine: sa.Engine) -> tuple[str | None, list[str]]:
    """(the stored revision or None, the tables present)."""
    with engine.connect() as conn:
        tables = sa.inspect(conn).get_table_names()
        rev = MigrationContext.configure(conn).get_current_revision() if "alembic_version" in tables else None
    return rev, tables


def _connect_problem(exc: Exception, where: str) -> DatabaseError:
    msg = " ".join(str(getattr(exc, "orig", None) or exc).split())
    return DatabaseError(f"cannot open the database {where}: {msg[:300]}")


def _check_sqlite_file(url: sa.URL, create: bool) -> None:
    path = Path(url.database)
    if path.exists():
        if path.is_dir():
            raise DatabaseError(f"--db {path} is a folder, not a database file")
        with open(path, "rb") as fh:
            head = fh.read(16)
        if head and head != b"SQLite format 3\x00":
            raise DatabaseError(f"--db {path} is not an SQLite database (nor an inscal one)")
        return
    if not create:
        raise DatabaseError(f"no calibration database at {path}: create it with `inscal db init --db {path}` "
                            "(or `inscal db add SERIAL --model ...`)")
    if not path.parent.is_dir():
        raise DatabaseError(f"--db {path}: folder {path.parent} does not exist")


def open_database(text: str | os.PathLike | None = None, create: bool = False, upgrade: bool = False) -> Database:
    """Open the calibration database of ``text`` (see :func:`database_url`) at this inscal's schema.

    ``create``: a missing SQLite file, or a server database without tables, is created at the
    newest revision.  ``upgrade``: a database at an older revision is upgraded (else refused with
    the command that upgrades it).  A newer revision, or tables that are not an inscal database,
    are refused.  Raises :class:`DatabaseError` (one line)."""
    return _open(database_url(text), create, upgrade)[0]


def init_database(text: str | os.PathLike | None = None, revision: str = "head") -> tuple[Database, bool]:
    """Create the calibration database (a new SQLite file, or the tables of an empty server database)
    at ``revision`` (the newest by default: older ones are for testing migrations); ``(database,
    created)``, ``created`` False when it existed already (then it must be at this inscal's schema)."""
    return _open(database_url(text), True, False, revision)


def _open(url: sa.URL, create: bool, upgrade: bool, revision: str = "head") -> tuple[Database, bool]:
    where = describe(url)
    if url.get_backend_name() == "sqlite":
        _check_sqlite_file(url, create)
    db = Database(make_engine(url), url, where)
    created = False
    try:
        try:
            rev, tables = _state(db.engine)
        except sa.exc.DBAPIError as exc:
            raise _connect_problem(exc, where) from None
        head = head_revision()
        if rev is None:
            others = [t for t in tables if t != "alembic_version"]
            if others:
                raise DatabaseError(f"{where} is not an inscal calibration database (it has tables "
                                    f"{', '.join(sorted(others)[:5])}{' ...' if len(others) > 5 else ''})")
            if not create:
                raise DatabaseError(f"{where} has no calibration tables yet: run `inscal db init --db {where}`")
            _upgrade(db, revision)
            created = True
        elif rev != head:
            number = revision_number(rev)
            if number is None:
                raise DatabaseError(f"{where}: schema revision {rev!r} is newer than this inscal knows (v"
                                    f"{revision_number(head)}, {head}): it was written by a newer inscal; use that one")
            if not upgrade:
                raise DatabaseError(f"{where}: schema v{number} ({rev}) is older than this inscal's v"
                                    f"{revision_number(head)} ({head}): run `inscal db upgrade --db {where}` "
                                    "(back the database up first)")
            _upgrade(db, head)
    except BaseException:
        db.close()
        raise
    return db, created


def _upgrade(db: Database, revision: str) -> None:
    def run(conn):
        command.upgrade(_alembic_config(conn), revision)

    write(db, run)


def upgrade_database(text: str | os.PathLike | None = None, revision: str = "head") -> tuple[str, str]:
    """Upgrade an existing calibration database to ``revision`` (the newest); ``(from, to)`` revisions.
    A newer revision than this inscal knows, or a database without one, is refused (:class:`DatabaseError`)."""
    url = database_url(text)
    if url.get_backend_name() == "sqlite":
        _check_sqlite_file(url, create=False)
    db = Database(make_engine(url), url, describe(url))
    try:
        try:
            rev, _ = _state(db.engine)
        except sa.exc.DBAPIError as exc:
            raise _connect_problem(exc, db.where) from None
        if rev is None:
            raise DatabaseError(f"{db.where} is not an inscal calibration database (no schema revision): "
                                f"create one with `inscal db init --db {db.where}`")
        if revision_number(rev) is None:
            raise DatabaseError(f"{db.where}: schema revision {rev!r} is newer than this inscal knows; "
                                "use the inscal that wrote it")
        target = head_revision() if revision == "head" else revision
        if rev != target:
            _upgrade(db, target)
        return rev, target
    finally:
        db.close()


def revision_of(db: Database) -> str | None:
    """The schema revision stored in ``db``."""
    return _state(db.engine)[0]


def _retryable(exc: sa.exc.DBAPIError) -> bool:
    orig = getattr(exc, "orig", None)
    if getattr(orig, "sqlstate", None) in PG_RETRY_STATES:
        return True
    text = str(orig or exc).lower()
    return "database is locked" in text or "database is busy" in text or "database table is locked" in text


def write(db: Database, fn, retry_s: float = LOCK_RETRY_S):
    """Run ``fn(connection)`` in one write transaction and commit; return its value.  The whole
    transaction is run again while the database is locked by another writer (up to ``retry_s``), so
    concurrent writers all get through; any other error rolls everything back and propagates."""
    deadline = time.monotonic() + retry_s
    delay = 0.005
    while True:
        try:
            with db.engine.connect() as conn:
                conn = conn.execution_options(inscal_write=True)
                with conn.begin():
                    return fn(conn)
        except sa.exc.DBAPIError as exc:
            if not _retryable(exc) or time.monotonic() > deadline:
                raise
        time.sleep(delay)
        delay = min(2 * delay, 0.25)


@contextlib.contextmanager
def read(db: Database):
    """A read-only connection (one transaction: a consistent snapshot of the database)."""
    with db.engine.connect() as conn, conn.begin():
        yield conn

