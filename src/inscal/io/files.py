"""Writing files safely: atomic outputs (a temporary file renamed into place), the removal of
partial outputs on an interrupt, and file hashes."""

from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path as FsPath
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported on first use: they pull in scipy and numba (seconds), which reading a record does not need
    pass


#: temporaries of :func:`atomic_path` now being written (temporary -> final path), so that an
#: interrupt (SIGINT/SIGTERM, see :func:`inscal.cli.main`) can say what it removed
_LIVE_PARTS: dict[str, FsPath] = {}
#: ``(temporary, final path)`` of the temporaries removed after a failure, newest last
REMOVED_PARTS: list[tuple[str, FsPath]] = []
#: a pending cancellation (the exception to raise), set by :func:`cancel`
_CANCEL: list[BaseException] = []


def cancel(exc: BaseException) -> None:
    """Ask the writers and readers of this module to stop: :func:`check_cancel` (called per
    chunk and before an output is renamed into place) raises ``exc`` from now on.  Used by the
    SIGINT/SIGTERM handler of :func:`inscal.cli.main`, whose own exception may be swallowed
    where Python cannot propagate it (a weakref or ``__del__`` callback)."""
    if not _CANCEL:
        _CANCEL.append(exc)


def check_cancel() -> None:
    """Raise the pending cancellation, if any (see :func:`cancel`)."""
    if _CANCEL:
        raise _CANCEL[0]


@contextmanager
def atomic_path(path, overwrite: bool = False):
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    Refuses (FileExistsError) if ``path`` exists and not ``overwrite``.  On any
    exception, ``BaseException`` included (KeyboardInterrupt, the interrupt of a SIGTERM),
    the temporary file is removed and ``path`` is untouched; a pending :func:`cancel` is raised
    before the rename, so an interrupted write is never published.
    """
    path = FsPath(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists; refusing to overwrite it (use --force / overwrite=True)")
    if not path.parent.exists():
        raise FileNotFoundError(f"folder {path.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        _LIVE_PARTS[tmp] = path
        os.close(fd)
        yield FsPath(tmp)
        check_cancel()
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; outputs follow the umask like any file
        os.replace(tmp, path)
        _LIVE_PARTS.pop(tmp, None)
    except BaseException:
        remove_part(tmp)
        raise


def remove_part(tmp: str) -> bool:
    """Remove a temporary of :func:`atomic_path` (if still there); True if it is gone and was live
    (an earlier, interrupted removal counts)."""
    live = tmp in _LIVE_PARTS
    try:
        os.unlink(tmp)
        gone = True
    except FileNotFoundError:
        gone = live
    except OSError:
        gone = False
    if gone and all(t != tmp for t, _ in REMOVED_PARTS):
        REMOVED_PARTS.append((tmp, _LIVE_PARTS.get(tmp, FsPath(tmp))))
    _LIVE_PARTS.pop(tmp, None)
    return gone


def remove_live_parts() -> None:
    """Remove every temporary still being written (last resort of an interrupt)."""
    for tmp in list(_LIVE_PARTS):
        remove_part(tmp)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def input_problem(path, what: str = "file") -> str | None:
    """Why ``path`` cannot be read as an input ``what`` (one line), or None for a regular file: missing,
    a directory, or not a regular file (a FIFO, socket or device, which a reader would block on or
    read forever)."""
    p = FsPath(path)
    if not p.exists():
        return f"{p}: no such {what}"
    if p.is_dir():
        return f"{p}: is a directory, not a {what}"
    if not p.is_file():
        return f"{p}: not a regular file (a FIFO, socket or device), not a {what}"
    return None


def check_input(path, what: str, error: type[Exception]) -> None:
    """Raise ``error`` with :func:`input_problem`'s line when ``path`` is not a readable regular file."""
    msg = input_problem(path, what)
    if msg is not None:
        raise error(msg)


def file_hash(path) -> str:
    """SHA-256 of a file's bytes (recorded in calibration parameter files)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()
