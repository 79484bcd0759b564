"""The publication journal: a result recorded in the calibration database and the files of the command
that computed it (its parameter file, its plots) are published together or not at all, whatever ends
the process when (SIGKILL, a power cut, not only SIGINT and SIGTERM).

The database and a file system are two stores with no common transaction, so one of them must carry
the other's intent, as a database's own write-ahead log does for its pages (Gray & Reuter,
*Transaction Processing*, 1993, ch. 9-10: redo logging; the "intent, apply, clear" of a journal).  The
database is the one with a commit, so it records what the files are to become:

1. every output is written to a temporary beside its target (:func:`inscal.io.files.atomic_path`) and
   flushed to the disk, the lock of each target held (``flock``: the kernel drops it when its holder dies);
2. in the transaction that inserts the result, one row of ``publications`` per output (:func:`add`):
   target, temporary, sha256 of the temporary, whether it may replace a file (``--force``), host and
   process; then the commit: from here on the result *is* recorded, its files owed;
3. each temporary is renamed into place, never over a file that is there unless ``--force``
   (:func:`inscal.io.files.publish`: ``renameat2(RENAME_NOREPLACE)``, atomic against a file that appears);
4. the rows are deleted (:func:`clear`), then the locks released.

A process that dies before 2 commits nothing and publishes nothing (its transaction rolls back; the
renames come after the commit).  One that dies between 2 and 4 leaves rows, which the next write to
the database (any :func:`inscal.lab.opening.open_database` for writing, or ``inscal db recover``)
rolls *forward* (:func:`recover`): a temporary still there with its hash is renamed into place; a
parameter file whose temporary is gone is written again from the database, which stores it byte for
byte; a file in place with its hash needs nothing.  Forward, never back: the result tables are
append-only (no row is ever deleted), and the file can always be rebuilt from the row, while the row
could not be rebuilt from the file.  A row whose target's lock is held belongs to a writer at work
(between its steps 2 and 4) and is left to it; a row of another host (a shared PostgreSQL database)
is left to that host, whose file system holds the paths.  Read-only commands never write: they may
only say that results await their files (:func:`waiting_line`).

An empty file at a target is the placeholder that :func:`inscal.io.files.rename_noreplace` makes on a file
system without hard links, cut before its replace: it is replaced.  What cannot be rolled forward is
said and the row cleared: a target whose folder is gone, a plot
whose temporary is gone (the database keeps only the parameter file), and a target where another
program put a file between the command's last check and its rename (not replaced without ``--force``;
the result's parameter file is then exported from the database with ``inscal db export``).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import socket
from dataclasses import dataclass, field
from pathlib import Path

import sqlalchemy as sa

from inscal.io.files import (
    OutputBusyError,
    claim_output,
    file_hash,
    publish,
    release_output,
)
from inscal.lab import schema as t


@dataclass
class Recovery:
    """What :func:`recover` did: ``done`` (one line per journal entry settled) and ``waiting`` (entries
    left: a writer at work, or another host's)."""

    done: list[str] = field(default_factory=list)
    waiting: list[str] = field(default_factory=list)


def host() -> str:
    """This machine's name, as the journal stores it (the file system the paths belong to)."""
    return socket.gethostname()[:255]


def add(conn: sa.Connection, result_id: int, outputs) -> list[int]:
    """In the open transaction ``conn`` that records result ``result_id``: one journal row per output
    ``(temporary, target, overwrite)`` (the temporaries complete and flushed), the ids of the rows."""
    ids = []
    for tmp, target, overwrite in outputs:
        ids.append(conn.execute(sa.insert(t.publications).values(
            result_id=result_id, target=str(Path(target).absolute()), temporary=str(Path(tmp).absolute()),
            sha256=file_hash(tmp), overwrite=bool(overwrite), host=host(), pid=os.getpid(),
            created_at=dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0))).inserted_primary_key[0])
    return ids


def clear(conn: sa.Connection, ids: list[int]) -> None:
    """Delete the journal rows ``ids`` (their files are in place)."""
    if ids:
        conn.execute(sa.delete(t.publications).where(t.publications.c.id.in_(ids)))


def pending_count(conn: sa.Connection) -> int:
    """How many journal entries there are (owed files, and files in place whose entry was not yet cleared)."""
    return int(conn.execute(sa.select(sa.func.count()).select_from(t.publications)).scalar_one())


def owed(conn: sa.Connection) -> int:
    """How many files of committed results are not in place, reading only: the entries whose target does not
    hold the journal's sha256 (an entry of another host counts: its files cannot be seen from here)."""
    rows = conn.execute(sa.select(t.publications.c.target, t.publications.c.sha256, t.publications.c.host)).all()
    me = host()
    return sum(r.host != me or _sha(Path(r.target)) != r.sha256 for r in rows)


def waiting_line(n: int, where: str) -> str:
    """The line a read-only command says when ``n`` files of committed results are not yet in place."""
    return (f"{n} file{'s' if n != 1 else ''} of results recorded in {where} await{'s' if n == 1 else ''} "
            f"publication (a writer at work, or one that was killed): run `inscal db recover --db {where}`")


def _sha(path: Path) -> str | None:
    try:
        return file_hash(path) if path.is_file() else None
    except OSError:
        return None


def _settle(conn: sa.Connection, row) -> str:
    """Roll one journal entry forward (its target's lock held); the line that says what was done."""
    target, tmp = Path(row.target), Path(row.temporary)
    what = f"result {row.result_id}: {target}"
    have = _sha(target)
    if have == row.sha256:
        with contextlib.suppress(OSError):
            tmp.unlink()  # a hard link left between the link and the unlink of a publication
        return f"{what} was in place"
    placeholder = have is not None and target.stat().st_size == 0  # rename_noreplace's, cut before its replace
    if have is not None and not row.overwrite and not placeholder:
        with contextlib.suppress(OSError):
            tmp.unlink()
        return (f"{what} is another file (it appeared while the result was published; not replaced): `inscal db "
                f"export` writes the result's parameter file elsewhere")
    overwrite = row.overwrite or placeholder
    if _sha(tmp) == row.sha256:
        publish(tmp, target, overwrite)
        return f"{what} published from its temporary"
    text = conn.execute(sa.select(t.results.c.param_file).where(
        t.results.c.id == row.result_id, t.results.c.param_file_sha256 == row.sha256)).scalar()
    with contextlib.suppress(OSError):
        tmp.unlink()
    if text is None:
        return f"{what} lost (its temporary is gone and the database keeps only the parameter file)"
    with open(tmp, "xb") as fh:  # its own name again (exclusive): nothing else has it
        fh.write(text.encode("utf-8"))
        fh.flush()
        os.fsync(fh.fileno())
    publish(tmp, target, overwrite)
    return f"{what} written again from the database"


def recover(conn: sa.Connection) -> Recovery:
    """Roll forward every journal entry of this host whose writer is gone (its target's lock free), in the
    open write transaction ``conn``, deleting each row settled (see the module docstring)."""
    rep = Recovery()
    rows = conn.execute(sa.select(t.publications).order_by(t.publications.c.id)).all()
    me = host()
    for row in rows:
        target = Path(row.target)
        if row.host != me:
            rep.waiting.append(f"result {row.result_id}: {target} (on host {row.host})")
            continue
        if not target.parent.is_dir():
            rep.done.append(f"result {row.result_id}: {target} not written (its folder is gone)")
            clear(conn, [row.id])
            continue
        try:
            taken = claim_output(target)
        except OutputBusyError:  # its writer is at work between its commit and its renames
            rep.waiting.append(f"result {row.result_id}: {target} (being published by pid {row.pid})")
            continue
        except OSError as exc:  # a folder that cannot be written now: left for a later recovery
            rep.waiting.append(f"result {row.result_id}: {target} ({exc.strerror or exc})")
            continue
        if not taken and row.pid == os.getpid():  # this process's own publication, at work (never during an open)
            rep.waiting.append(f"result {row.result_id}: {target} (being published by pid {row.pid})")
            continue
        # taken, or held by this process for its own output (the command's lock, taken before it opened the
        # database): in both cases no other process holds it, so the entry's writer is gone
        try:
            rep.done.append(_settle(conn, row))
        except OSError as exc:
            rep.waiting.append(f"result {row.result_id}: {target} ({exc.strerror or exc})")
            continue
        finally:
            if taken:
                release_output(target)
        clear(conn, [row.id])
    return rep
