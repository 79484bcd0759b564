"""Creating, opening and upgrading the calibration database at this inscal's schema revision.

Schema revisions (Alembic scripts in ``inscal/lab/migrations/``: ``env.py`` and one file per revision in
``versions/``, loaded by path, not as modules; ``ddl.py``, the frozen statements they share):
:func:`init_database` creates the tables
at the newest revision; :func:`open_database` refuses, in one line, a database whose revision
is newer than this inscal knows (made by a newer inscal) and one at an older revision (run
``inscal db upgrade``, or ``upgrade=True``), so no version ever writes rows the other cannot read.

Opening for writing checks first, over a read-only connection
(:func:`~inscal.lab.database.readonly_uri`), that the file is an inscal database (a foreign or empty
file is refused untouched), then that it can be written ("read-only" in one line otherwise); it then
rolls forward the publications a killed writer left owed
(:func:`~inscal.lab.database.recover_publications`).  The handle it returns, its URL and its
transactions are :mod:`inscal.lab.database`.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory

from inscal.lab.database import (
    Database,
    DatabaseError,
    check_wait,
    database_url,
    describe,
    make_engine,
    recover_publications,
    write,
)

MIGRATIONS = Path(__file__).resolve().parent / "migrations"


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
    """The newest schema revision the shipped Alembic scripts define.

    Returns
    -------
    str
        Its revision id (``NNNN_name``).

    Examples
    --------
    >>> from inscal import lab
    >>> lab.head_revision()[:4].isdigit()
    True
    """
    return script().get_current_head()


def revision_number(rev: str | None) -> int | None:
    """The schema version of a revision id (``0002_session_temperature`` -> 2).

    Parameters
    ----------
    rev : str or None
        A revision id.

    Returns
    -------
    int or None
        Its place among the shipped revisions, oldest first from 1; None if unknown.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.revision_number("0001_initial"), lab.revision_number("9999_future")
    (1, None)
    """
    if rev is None:
        return None
    known = [r.revision for r in reversed(list(script().walk_revisions()))]  # oldest first
    return known.index(rev) + 1 if rev in known else None


def revision_of(db: Database) -> str | None:
    """The schema revision stored in a database.

    Parameters
    ----------
    db : Database
        The open database (its schema revision read).

    Returns
    -------
    str or None
        The Alembic revision id, None for a database without one.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> lab.revision_of(db) == lab.head_revision()
    True

    >>> db.close()
    """
    return _state(db.engine)[0]


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
    try:
        os.stat(path)
    except FileNotFoundError:
        pass
    except OSError as exc:  # a name too long, a folder that is a file ...
        raise DatabaseError(f"--db {str(path)[:200]}{'...' if len(str(path)) > 200 else ''}: "
                            f"{exc.strerror or exc}") from None
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
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise DatabaseError(f"--db {path}: folder {path.parent} is read-only: no database can be created there")


def check_writable(url: sa.URL) -> None:
    """Refuse (:class:`~inscal.lab.database.DatabaseError`, saying "read-only") a SQLite database that this
    process cannot write: the file, or its folder (where SQLite keeps its write-ahead log), read-only or on a
    read-only file system, or an immutable file."""
    if url.get_backend_name() != "sqlite":
        return
    path = Path(url.database)
    for what, p in (("file", path), ("folder", path.parent)):
        if p.exists() and not os.access(p, os.W_OK):
            raise DatabaseError(f"--db {path} is read-only (its {what} cannot be written by this user, or the file "
                                "system is read-only): it can be read (inscal db list/show/export/history) but "
                                "nothing can be recorded in it")


def init_database(text: str | os.PathLike | None = None, revision: str = "head") -> tuple[Database, bool]:
    """Create the calibration database (a new SQLite file, or the tables of an empty server database).

    Parameters
    ----------
    text : str or os.PathLike, optional
        The database (see :func:`~inscal.lab.database.database_url`).
    revision : str
        The schema revision (the newest by default: older ones are for testing migrations).

    Returns
    -------
    tuple of (Database, bool)
        The open database, and whether it was created (False when it existed already: it must then be
        at this inscal's schema).

    Raises
    ------
    DatabaseError
        A database at another revision, not an inscal database, or one that cannot be written.

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> created, lab.table_counts(db)["units"]
    (True, 0)
    >>> db.close()
    >>> db, created = lab.init_database("calib.sqlite")
    >>> created
    False

    >>> db.close()
    """
    return _open(database_url(text), True, False, revision)


def open_database(text: str | os.PathLike | None = None, create: bool = False, upgrade: bool = False,
                  readonly: bool = False, wait_s: float | None = None) -> Database:
    """Open the calibration database of ``text`` at this inscal's schema.

    A newer revision, or tables that are not an inscal database, are refused.  Opening it for writing
    rolls forward the publications a killed writer left owed (:func:`~inscal.lab.database.recover_publications`).

    Parameters
    ----------
    text : str or os.PathLike, optional
        The database (see :func:`~inscal.lab.database.database_url`).
    create : bool
        Create a missing SQLite file, or the tables of an empty server database, at the newest revision.
    upgrade : bool
        Upgrade a database at an older revision (else it is refused with the command that upgrades it).
    readonly : bool
        Only read: the file is never written; a write raises :class:`~inscal.lab.database.DatabaseError`.
    wait_s : float, optional
        How long a write waits for another writer [s] (default :data:`~inscal.lab.database.GRACE_S`).

    Returns
    -------
    Database
        The open database.

    Raises
    ------
    ValueError
        ``readonly`` with ``create`` or ``upgrade``.
    DatabaseError
        A database that is missing (without ``create``), not an inscal database, at another revision,
        unreachable or read-only (one line).

    Examples
    --------
    >>> from inscal import lab
    >>> db = lab.open_database("calib.sqlite", create=True)
    >>> lab.revision_number(lab.revision_of(db)) == lab.revision_number(lab.head_revision())
    True

    >>> db.close()
    """
    if readonly and (create or upgrade):
        raise ValueError("a database opened read-only is neither created nor upgraded")
    db = _open(database_url(text), create, upgrade, readonly=readonly)[0]
    try:
        db.wait_s = check_wait(wait_s)
        if not readonly:
            db.recovery = recover_publications(db)
    except BaseException:
        db.close()
        raise
    return db


def _open(url: sa.URL, create: bool, upgrade: bool, revision: str = "head",
          readonly: bool = False) -> tuple[Database, bool]:
    where = describe(url)
    sqlite = url.get_backend_name() == "sqlite"
    if sqlite:
        _check_sqlite_file(url, create)
    exists = sqlite and Path(url.database).exists()
    # a SQLite file is looked at read-only first: a foreign or empty file is refused as it is (no WAL switch)
    db = Database(make_engine(url, readonly=readonly or exists), url, where, readonly=readonly)
    created = False
    try:
        try:
            rev, tables = _state(db.engine)
        except sa.exc.DBAPIError as exc:
            raise _connect_problem(exc, where) from None
        if exists and not readonly:
            if rev is None and (not create or [t for t in tables if t != "alembic_version"]):
                pass  # refused below, untouched
            else:
                check_writable(url)
                db.engine.dispose()
                db.engine = make_engine(url)
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
    """Upgrade an existing calibration database to ``revision`` (the newest by default).

    Parameters
    ----------
    text : str or os.PathLike, optional
        The database (see :func:`~inscal.lab.database.database_url`).
    revision : str
        The revision to upgrade to.

    Returns
    -------
    tuple of (str, str)
        The revisions before and after.

    Raises
    ------
    DatabaseError
        A missing database, one without a revision (not an inscal database), or a newer revision than
        this inscal knows.

    Examples
    --------
    >>> from inscal import lab
    >>> db, _ = lab.init_database("calib.sqlite", revision="0001_initial")
    >>> db.close()
    >>> lab.upgrade_database("calib.sqlite") == ("0001_initial", lab.head_revision())
    True
    """
    url = database_url(text)
    sqlite = url.get_backend_name() == "sqlite"
    if sqlite:
        _check_sqlite_file(url, create=False)
    db = Database(make_engine(url, readonly=sqlite), url, describe(url))  # looked at read-only first
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
            if sqlite:
                check_writable(url)
                db.engine.dispose()
                db.engine = make_engine(url)
            _upgrade(db, target)
        return rev, target
    finally:
        db.close()
