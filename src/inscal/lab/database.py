"""The calibration database's handle and its transactions: its URL, the engine, and transactions that
lose nothing when several processes write at once.

``--db`` / ``INSCAL_DB`` is a file path (SQLite, the default: one file, nothing to set up) or a
URL: ``sqlite:///PATH`` or ``postgresql://USER[:PASSWORD]@HOST[:PORT]/NAME`` (a shared lab
database; the ``psycopg`` driver, ``pip install 'inscal[postgresql]'``).  Without either, the
file ``calib.sqlite`` in the current folder.  Creating, opening and upgrading it at this inscal's
schema revision is :mod:`inscal.lab.opening`.

Writes (:func:`write`) are single transactions: all of a result or none of it, whatever happens to
the process.  SQLite runs in WAL mode (readers do not block the writer) with a busy timeout, and
a write transaction starts with ``BEGIN IMMEDIATE`` (it takes the write lock up front, so two
writers never deadlock on a lock upgrade); a transaction that still meets a locked database, or a
PostgreSQL serialization failure or deadlock, is retried whole.  A writer waits for another one
for :data:`GRACE_S` (inscal's own transactions take milliseconds), then is refused at once with who
holds the lock (:func:`lock_holders`), unless the caller asked to wait longer (``wait_s``, the
``--wait SECONDS`` of the commands).  The files of a command that records a result are published with
its commit through the journal of :mod:`inscal.lab.journal` (:func:`recover_publications`,
:func:`published`).

Read-only use: a database opened with ``readonly=True`` is read through a read-only SQLite
connection (``mode=ro``; ``immutable=1`` when nobody can write it: a read-only folder without a
write-ahead log), so a command that only reads never changes the file, its journal mode included,
and works on a read-only folder, file system or immutable file.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import sqlite3
import sys
import time
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import sqlalchemy as sa

from inscal.lab import journal

#: the file the commands use when neither ``--db`` nor ``INSCAL_DB`` names one
DEFAULT_FILE = "calib.sqlite"
ENV_VAR = "INSCAL_DB"
#: how long a writer waits for another writer's lock before it is refused (without ``wait_s``) [s]
GRACE_S = 2.0
#: the longest wait a caller may ask for [s] (a day)
MAX_WAIT_S = 86400.0
#: a waiting writer says so every this many seconds [s]
WAIT_REPORT_S = 10.0
#: the SQLite busy timeout of one attempt [s] (the attempts repeat until the wait is over)
BUSY_TIMEOUT_S = 0.5
#: SQLSTATEs of a PostgreSQL transaction that lost a race and may be run again
PG_RETRY_STATES = ("40001", "40P01")


class DatabaseError(Exception):
    """A database that cannot be used, or a request it refuses: one line, with the reason.

    Examples
    --------
    >>> from inscal import lab
    >>> try:
    ...     lab.open_database("missing.sqlite")
    ... except lab.DatabaseError as exc:
    ...     print("refused")
    refused
    """


@dataclass
class Database:
    """An open calibration database (:func:`~inscal.lab.opening.open_database`, :func:`~inscal.lab.opening.init_database`).

    Close it with :meth:`close` (or use it as a context manager).  One per process: a worker process
    opens its own (an engine's pooled connections do not cross a fork).

    Parameters
    ----------
    engine : sqlalchemy.Engine
        The SQLAlchemy engine.
    url : sqlalchemy.URL
        Its URL.
    where : str
        The URL to print (a SQLite file as its path, no password).
    readonly : bool
        Opened to read only (a write raises :class:`DatabaseError`).
    wait_s : float
        How long a write waits for another writer's lock [s].
    recovery : Recovery
        What opening it for writing rolled forward of the publication journal.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> with lab.open_database("calib.sqlite", readonly=True) as ro:
    ...     print(ro.dialect, ro.readonly)
    sqlite True

    >>> db.close()
    """

    engine: sa.Engine
    url: sa.URL
    where: str
    readonly: bool = False
    #: how long a write waits for another writer's lock [s] (:data:`GRACE_S` unless asked)
    wait_s: float = GRACE_S
    #: what opening it for writing rolled forward of the publication journal (:func:`recover_publications`)
    recovery: journal.Recovery = dataclasses.field(default_factory=journal.Recovery)

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
    """The URL of ``--db`` (or ``INSCAL_DB``, or ``calib.sqlite``).

    Parameters
    ----------
    text : str or os.PathLike, optional
        A file path (``sqlite:///ABSOLUTE``), ``sqlite:///PATH`` or ``postgresql://USER@HOST/NAME``
        (the psycopg 3 driver); None or "": ``INSCAL_DB``, else :data:`DEFAULT_FILE`.

    Returns
    -------
    sqlalchemy.URL
        The database's URL.

    Raises
    ------
    DatabaseError
        Not a URL, an in-memory SQLite database, another backend or driver.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.database_url("postgresql://lab@db.example/calib").drivername
    'postgresql+psycopg'
    >>> lab.database_url("calib.sqlite").get_backend_name()
    'sqlite'
    """
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


def _sqlite_connect_readonly(dbapi_connection, _record) -> None:
    dbapi_connection.isolation_level = None
    cur = dbapi_connection.cursor()
    cur.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
    cur.close()


def readonly_uri(path: str | os.PathLike) -> str:
    """The SQLite URI that reads ``path`` without ever writing it or leaving a file beside it: ``mode=ro``, and
    ``immutable=1`` while it has no write-ahead log (no writer is at work: a read-only connection would
    otherwise make the ``-wal`` and ``-shm`` files of a WAL database and, unable to remove them, leave them;
    and where the folder is read-only it could not make them at all).  With a write-ahead log present
    (a writer at work) the reader takes part in WAL's locking as any reader does.  What an immutable read
    does not see: a writer that starts during it (the read is a snapshot of the file as it was)."""
    p = Path(path)
    uri = "file:" + urllib.parse.quote(str(p)) + "?mode=ro"
    if not Path(f"{p}-wal").exists():
        uri += "&immutable=1"
    return uri


def _sqlite_begin(conn) -> None:
    conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.get_execution_options().get("inscal_write") else "BEGIN")


def make_engine(url: sa.URL, readonly: bool = False) -> sa.Engine:
    """The SQLAlchemy engine of ``url`` (SQLite: WAL, busy timeout, foreign keys, explicit BEGIN;
    ``readonly``: a connection that cannot write the file, see :func:`readonly_uri`)."""
    if url.get_backend_name() == "sqlite" and readonly:
        uri = readonly_uri(url.database)
        engine = sa.create_engine("sqlite://", creator=lambda: sqlite3.connect(uri, uri=True, check_same_thread=False))
        sa.event.listen(engine, "connect", _sqlite_connect_readonly)
        sa.event.listen(engine, "begin", _sqlite_begin)
        return engine
    if url.get_backend_name() == "sqlite":
        engine = sa.create_engine(url)  # a pool: a connection kept open spares the WAL checkpoint of the last close
        sa.event.listen(engine, "connect", _sqlite_connect)
        sa.event.listen(engine, "begin", _sqlite_begin)
        return engine
    try:
        return sa.create_engine(url, pool_pre_ping=True, connect_args={"connect_timeout": 10})
    except ModuleNotFoundError:
        raise DatabaseError("PostgreSQL needs the psycopg driver: pip install 'inscal[postgresql]'") from None


def check_wait(wait_s: float | None) -> float:
    """``--wait SECONDS``: how long a write waits for another writer's lock.

    Parameters
    ----------
    wait_s : float or None
        Seconds, 0 to a day (None: :data:`GRACE_S`).

    Returns
    -------
    float
        The wait [s].

    Raises
    ------
    DatabaseError
        A wait outside 0 .. 86400 s.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.check_wait(None), lab.check_wait(30)
    (2.0, 30.0)
    """
    if wait_s is None:
        return GRACE_S
    if not (math.isfinite(wait_s) and 0 <= wait_s <= MAX_WAIT_S):
        raise DatabaseError(f"--wait {wait_s}: give 0 .. {MAX_WAIT_S:.0f} seconds")
    return float(wait_s)


def recover_publications(db: Database, strict: bool = False) -> journal.Recovery:
    """Roll forward the publications that a writer killed between its commit and its renames left owed.

    The journal (:mod:`inscal.lab.journal`) is looked at first; a write transaction runs only when it
    has entries.  A database another writer holds beyond the wait is left as it is for a later write.

    Parameters
    ----------
    db : Database
        The open database (its journal of the files to publish).
    strict : bool
        Refuse (:class:`DatabaseError`) a database another writer holds (``inscal db recover``).

    Returns
    -------
    Recovery
        What was rolled forward (nothing, in a database without owed publications).

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> lab.recover_publications(db) == type(lab.recover_publications(db))()
    True

    >>> db.close()
    """
    with read(db) as conn:
        if not journal.pending_count(conn):
            return journal.Recovery()
    try:
        return write(db, journal.recover)
    except DatabaseError:
        if strict:
            raise
        return journal.Recovery()


def published(db: Database, ids: list[int]) -> None:
    """Clear the journal entries ``ids`` once their files are in place (step 4 of :mod:`inscal.lab.journal`).

    Never raises: an entry left is found in place by the next recovery.

    Parameters
    ----------
    db : Database
        The open database (its journal of the files to publish).
    ids : list of int
        The journal entries.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> lab.published(db, [])
    >>> lab.pending_publications(db)
    0

    >>> db.close()
    """
    with contextlib.suppress(Exception):
        write(db, lambda conn: journal.clear(conn, ids))


def pending_publications(db: Database) -> int:
    """How many files of committed results are not in place (a read: see :func:`recover_publications`).

    Parameters
    ----------
    db : Database
        The open database (its journal of the files to publish).

    Returns
    -------
    int
        The number of owed files.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> lab.pending_publications(db)
    0

    >>> db.close()
    """
    with read(db) as conn:
        return journal.owed(conn)


def _retryable(exc: sa.exc.DBAPIError) -> bool:
    orig = getattr(exc, "orig", None)
    if getattr(orig, "sqlstate", None) in PG_RETRY_STATES:
        return True
    return _locked(exc)


def _locked(exc: sa.exc.DBAPIError) -> bool:
    text = str(getattr(exc, "orig", None) or exc).lower()
    return "database is locked" in text or "database is busy" in text or "database table is locked" in text


def lock_holders(path: str | os.PathLike) -> list[tuple[int, str]]:
    """The processes holding a write lock of a SQLite database (its file or its shared-memory file).

    Read from Linux's ``/proc/locks``: empty elsewhere, or when the holder cannot be seen (another
    machine of a network file system).

    Parameters
    ----------
    path : str or os.PathLike
        The database file.

    Returns
    -------
    list of tuple of (int, str)
        ``[(pid, command line)]`` (this process left out).

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> lab.lock_holders("calib.sqlite")
    []

    >>> db.close()
    """
    inodes = set()
    for p in (Path(path), Path(f"{path}-shm")):
        with contextlib.suppress(OSError):
            inodes.add(os.stat(p).st_ino)
    pids: list[int] = []
    try:
        with open("/proc/locks", encoding="ascii", errors="replace") as fh:
            for line in fh:
                f = line.split()
                if "->" in f:  # a waiter, not a holder
                    continue
                if len(f) >= 6 and f[1] in ("POSIX", "OFDLCK", "FLOCK") and f[3] == "WRITE":
                    pid, ino = f[4], f[5].rsplit(":", 1)[-1]
                    if ino.isdigit() and int(ino) in inodes and pid.lstrip("-").isdigit() and int(pid) > 0 \
                            and int(pid) != os.getpid() and int(pid) not in pids:
                        pids.append(int(pid))
    except OSError:
        return []
    out = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as fh:
                cmd = " ".join(a.decode(errors="replace") for a in fh.read().split(b"\0") if a)
        except OSError:
            cmd = "?"
        out.append((pid, cmd[:120]))
    return out


def locked_message(db: Database) -> str:
    """The one line of a write refused because another writer holds the database."""
    who = ""
    if db.dialect == "sqlite":
        holders = lock_holders(db.url.database)
        who = " (" + "; ".join(f"pid {p}: {c}" for p, c in holders) + ")" if holders else \
            " (a process this one cannot see)"
    return (f"{db.where} is locked by another writer{who}; nothing was recorded: wait for it to finish, or give "
            f"--wait SECONDS to wait for it (waited {db.wait_s:g} s)")


@dataclass
class Staged:
    """A write transaction run but not committed (:func:`begin_write`): its ``value``; :meth:`commit`, or
    :meth:`close` (a rollback unless committed; the death of the process rolls it back too)."""

    conn: sa.Connection
    trans: sa.RootTransaction
    value: object
    committed: bool = False

    def commit(self) -> None:
        """Commit the transaction, then release its connection."""
        self.trans.commit()
        self.committed = True
        self.close()

    def close(self) -> None:
        """Roll the transaction back unless it was committed, and release its connection (never raises)."""
        if not self.committed:
            with contextlib.suppress(Exception):
                self.trans.rollback()
        with contextlib.suppress(Exception):
            self.conn.close()


def write(db: Database, fn, retry_s: float | None = None, progress=None):
    """Run ``fn(connection)`` in one write transaction and commit; return its value.  The whole
    transaction is run again while the database is locked by another writer, for up to ``retry_s``
    (default ``db.wait_s``: a short grace, :data:`GRACE_S`, unless the caller asked to wait), then
    refused at once with who holds the lock (:class:`DatabaseError`); ``progress(line)`` (default: a
    line on stderr) hears every :data:`WAIT_REPORT_S` of a wait longer than the grace.  A database
    opened read-only, or a file that cannot be written, is refused saying so; any other error rolls
    everything back and propagates."""
    staged = begin_write(db, fn, retry_s, progress)
    try:
        staged.commit()
    finally:
        staged.close()
    return staged.value


def begin_write(db: Database, fn, retry_s: float | None = None, progress=None) -> Staged:
    """:func:`write` without the commit: the transaction is left open, and the caller commits it
    (:meth:`Staged.commit`) when its other outputs are ready, so that the commit can be the last step
    of publishing them (or closes it: a rollback).  Hold it briefly: other writers wait meanwhile."""
    if db.readonly:
        raise DatabaseError(f"{db.where} was opened read-only: nothing can be recorded in it")
    retry_s = db.wait_s if retry_s is None else retry_s
    t0 = time.monotonic()
    deadline = t0 + retry_s
    said = t0 + max(GRACE_S, WAIT_REPORT_S / 2)
    delay = 0.005
    while True:
        conn = db.engine.connect().execution_options(inscal_write=True)
        try:
            trans = conn.begin()
            return Staged(conn, trans, fn(conn))
        except BaseException as exc:
            with contextlib.suppress(Exception):
                conn.rollback()
            conn.close()
            if not isinstance(exc, sa.exc.DBAPIError):
                raise
            text = str(getattr(exc, "orig", None) or exc).lower()
            if "readonly" in text or "read-only" in text:
                raise DatabaseError(f"{db.where} is read-only (the file, its folder or its file system cannot be "
                                    "written): nothing was recorded") from None
            if not _retryable(exc):
                raise
            if time.monotonic() > deadline:
                if _locked(exc):
                    raise DatabaseError(locked_message(db)) from None
                raise
        now = time.monotonic()
        if now >= said and now < deadline:
            line = f"inscal: waiting for {db.where}, locked by another writer ({now - t0:.0f} of {retry_s:g} s)"
            (progress or (lambda m: print(m, file=sys.stderr, flush=True)))(line)
            said = now + WAIT_REPORT_S
        time.sleep(delay)
        delay = min(2 * delay, 0.25)


@contextlib.contextmanager
def read(db: Database):
    """A read-only connection (one transaction: a consistent snapshot of the database)."""
    with db.engine.connect() as conn, conn.begin():
        yield conn
