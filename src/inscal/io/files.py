"""Writing files safely: atomic outputs (a temporary file renamed into place), the outputs of one
command published together or not at all, a lock beside every output being written (one writer
per output, across processes), the removal of partial outputs on an interrupt, and file hashes."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import os
import tempfile
from contextlib import contextmanager
from collections.abc import Callable
from pathlib import Path as FsPath

try:  # POSIX advisory locks: released by the kernel when the holder dies, even by SIGKILL
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: outputs are not locked
    fcntl = None

from inscal.core.cancel import cancel as cancel  # the command line's signal handler reaches it from here
from inscal.core.cancel import check_cancel, signals_held
from inscal.core.cancel import holding as holding  # likewise

#: the writers' block held against SIGINT/SIGTERM (:func:`inscal.core.cancel.signals_held`)
_signals_held = signals_held

#: temporaries of :func:`atomic_path` now being written (temporary -> final path), so that an
#: interrupt (SIGINT/SIGTERM, see :func:`inscal.cli.main`) can say what it removed
_LIVE_PARTS: dict[str, FsPath] = {}
#: ``(temporary, final path)`` of the temporaries removed after a failure, newest last
REMOVED_PARTS: list[tuple[str, FsPath]] = []


class OutputBusyError(FileExistsError):
    """The output is being written by another process (its lock is held)."""


#: outputs this process holds the lock of: resolved output path -> (lock file, its descriptor)
_CLAIMS: dict[str, tuple[str, int]] = {}
#: the open output units (:func:`output_unit`), innermost last
_UNITS: list["_Unit"] = []
#: outputs published by the last output unit (an interrupt after that point says they are complete)
PUBLISHED: list[FsPath] = []
#: where the lines saying that a dead writer's lock was taken over go (the CLI prints them as notes)
NOTES: list[Callable[[str], None]] = []


def _note(line: str) -> None:
    for sink in NOTES:
        sink(line)


#: the longest file name (bytes) of the usual file systems (ext4, XFS, btrfs, APFS, NTFS)
NAME_MAX = 255


def side_name(name: str, suffix: str, room: int = 0) -> str:
    """``.NAME`` + ``suffix``, the name of a file beside output ``NAME`` (its lock, its temporary), with
    ``room`` bytes to spare: when that would pass :data:`NAME_MAX`, NAME is cut and a hash of the whole
    name keeps it apart from any other (``.NAME[:n]~HASH12``), so every legal output name has its lock
    and its temporary."""
    full = f".{name}{suffix}"
    if len(os.fsencode(full)) + room <= NAME_MAX:
        return full
    tag = "~" + hashlib.sha256(os.fsencode(name)).hexdigest()[:12]
    keep = NAME_MAX - room - len(os.fsencode(f".{tag}{suffix}"))
    head = os.fsencode(name)[:max(0, keep)].decode(errors="ignore")
    return f".{head}{tag}{suffix}"


def lock_path(path) -> FsPath:
    """The lock file of an output: ``.NAME.lock`` beside it (NAME shortened when long, :func:`side_name`)."""
    path = FsPath(path)
    return path.parent / side_name(path.name, ".lock")


def _key(path) -> str:
    return str(FsPath(path).absolute().resolve())


def claim_output(path) -> bool:
    """Take the lock of output ``path`` for this process (a ``.NAME.lock`` file beside it, locked with
    ``flock``): True if taken now, False if this process already holds it.  Raises
    :class:`OutputBusyError` (one line) if another process holds it.  The kernel drops the lock
    of a process that dies however it dies, so a lock file left by a killed writer is taken over."""
    key = _key(path)
    if key in _CLAIMS or fcntl is None:
        return False
    lock = lock_path(path)
    with _signals_held():  # the lock file and its registration at once (an interrupt between them left the file)
        while True:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = os.read(fd, 64).decode(errors="replace").strip() or "?"
                os.close(fd)
                raise OutputBusyError(f"{path} is being written by another process (pid {holder}, lock "
                                      f"{lock.name}); wait for it to finish or choose another output") from None
            try:  # its releasing holder may have removed the file between our open and flock: retry on the new one
                same = os.stat(lock).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        previous = os.read(fd, 64).decode(errors="replace").strip()
        os.lseek(fd, 0, os.SEEK_SET)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        _CLAIMS[key] = (str(lock), fd)
    if previous and previous != str(os.getpid()):  # the file of a writer that died holding it (SIGKILL)
        _note(f"{lock.name}: the lock of process {previous}, which has ended, taken over")
    return True


def release_output(path) -> None:
    """Drop this process's lock of output ``path`` (and remove its lock file)."""
    entry = _CLAIMS.pop(_key(path), None)
    if entry is None:
        return
    lock, fd = entry
    with contextlib.suppress(OSError):
        os.unlink(lock)  # while still locked: a waiting process then retries on a fresh file
    with contextlib.suppress(OSError):
        os.close(fd)


def release_outputs() -> None:
    """Drop every output lock this process holds (the end of a command, or an interrupt)."""
    for key in list(_CLAIMS):
        release_output(key)


@contextmanager
def held_output(path):
    """Hold the lock of output ``path`` for the block (kept if the caller already held it)."""
    taken = claim_output(path)
    try:
        yield
    finally:
        if taken:
            release_output(path)


class _Unit:
    def __init__(self):
        self.pending: list[tuple[str, FsPath, bool]] = []  # (temporary, output, overwrite)
        self.made_dirs: list[FsPath] = []
        self.claimed: list[FsPath] = []
        #: steps run in the publication itself, with the interrupts held, after the outputs are checked
        #: and before the first is renamed into place (a database commit: the record and its files at once)
        self.before_publish: list = []
        #: steps run in the publication once every output is in place, before the locks are released (the
        #: entries of a publication journal cleared); they must not raise
        self.after_publish: list = []
        #: steps run when the outermost unit ends, published or not (:func:`after_unit`)
        self.finally_steps: list = []


@contextmanager
def output_unit():
    """The outputs of one command as one unit: every :func:`atomic_path` inside the block keeps its
    temporary until the block ends, then all of them are renamed into place together (SIGINT and
    SIGTERM held off for those renames); if the block raises, is interrupted or cancelled, no
    output is published and the folders made by :func:`make_output_dir` are removed again.  A unit
    inside another hands its outputs to the outer one.  ``unit.before_publish`` (callables) run in the
    same held step, after every target is checked and its temporary flushed to the disk, just before the
    renames: a commit there and the files' publication cannot be parted by SIGINT or SIGTERM; against
    SIGKILL or a power cut between the commit and the renames, the commit records what it publishes (a
    journal, :mod:`inscal.lab.journal`) and ``unit.after_publish`` (callables, which must not raise) clears
    it once every file is in place, before the output locks are released."""
    unit = _Unit()
    outer = _UNITS[-1] if _UNITS else None
    _UNITS.append(unit)
    if outer is None:
        PUBLISHED.clear()
    try:
        try:
            yield unit
        finally:
            _UNITS.remove(unit)
        if outer is not None:  # a unit inside another: its outputs are published with the outer's
            outer.pending += unit.pending
            outer.made_dirs += unit.made_dirs
            outer.claimed += unit.claimed
            outer.before_publish += unit.before_publish
            outer.after_publish += unit.after_publish
            outer.finally_steps += unit.finally_steps
            unit.claimed = []
            unit.finally_steps = []
            return
        with _signals_held():
            check_cancel()
            # every target checked before anything is committed or replaced (an early refusal: the rename
            # itself refuses a file that appears after this check, atomically, see rename_noreplace)
            for tmp, path, overwrite in unit.pending:
                if not overwrite and os.path.lexists(path):
                    raise FileExistsError(f"{path} appeared while this command ran; not replaced (use --force "
                                          "to overwrite it)")
            if unit.before_publish:  # a commit will vouch for the files: they are on the disk first
                for tmp, _, _ in unit.pending:
                    fsync_path(tmp)
            for step in unit.before_publish:
                step()
            for tmp, path, overwrite in unit.pending:
                publish(tmp, path, overwrite)
                PUBLISHED.append(path)
            if unit.before_publish:
                for folder in {FsPath(p).parent for _, p, _ in unit.pending}:
                    fsync_path(folder)
            for step in unit.after_publish:
                with contextlib.suppress(Exception):
                    step()
    except BaseException:
        for tmp, _, _ in unit.pending:
            remove_part(tmp)
        for path in unit.claimed:  # their lock files first: a folder made for the unit is empty then
            release_output(path)
        for tmp in [t for t in _LIVE_PARTS if FsPath(t).parent in unit.made_dirs]:
            remove_part(tmp)  # a write whose own cleanup never ran (an interrupt Python swallowed inside it)
        for d in reversed(unit.made_dirs):
            with contextlib.suppress(OSError):
                d.rmdir()  # only if empty: nothing of the user's is removed
        raise
    finally:
        for path in unit.claimed:
            release_output(path)
        for step in unit.finally_steps:
            with contextlib.suppress(Exception):
                step()


def after_unit(step) -> None:
    """Run ``step()`` when the outermost :func:`output_unit` now open ends, its outputs published or not (at
    once when none is open): the rollback of a database transaction its publication would have committed."""
    if _UNITS:
        _UNITS[-1].finally_steps.append(step)
    else:
        step()


def make_output_dir(path) -> FsPath:
    """Make output folder ``path`` (if missing); inside an :func:`output_unit` it is removed again
    (when empty) if the unit fails."""
    path = FsPath(path)
    if not path.is_dir():
        with _signals_held():  # the folder and its registration at once
            path.mkdir()
            if _UNITS:
                _UNITS[-1].made_dirs.append(path)
    return path


def publish(tmp, path, overwrite: bool) -> None:
    """Rename temporary ``tmp`` onto ``path`` (mode set from the umask); with ``overwrite`` an atomic replace,
    else :func:`rename_noreplace`: a file that is at ``path`` now (one that appeared after the command
    checked its outputs) is never replaced (FileExistsError), with no window between a check and the rename."""
    tmp, path = str(tmp), FsPath(path)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; outputs follow the umask like any file
    if overwrite:
        os.replace(tmp, path)
    else:
        try:
            rename_noreplace(tmp, path)
        except FileExistsError:
            raise FileExistsError(f"{path} appeared while this command ran; not replaced (use --force to "
                                  "overwrite it)") from None
    _LIVE_PARTS.pop(tmp, None)


#: ``renameat2`` flag: fail with EEXIST rather than replace the target (Linux >= 3.15, glibc >= 2.28)
RENAME_NOREPLACE = 1
_AT_FDCWD = -100


def _renameat2(src: str, dst: str) -> bool:
    """``renameat2(src, dst, RENAME_NOREPLACE)``: True if renamed, False where the C library or the file
    system lacks it; FileExistsError if ``dst`` exists."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        return False
    fn.argtypes = (ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint)
    if fn(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), RENAME_NOREPLACE) == 0:
        return True
    err = ctypes.get_errno()
    if err == errno.EEXIST:
        raise FileExistsError(err, os.strerror(err), dst)
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):  # the flag unsupported here
        return False
    raise OSError(err, os.strerror(err), dst)


def rename_noreplace(src, dst) -> None:
    """Rename ``src`` to ``dst`` unless ``dst`` exists (FileExistsError, ``src`` kept), atomically against a
    file that appears at ``dst`` at any moment: ``renameat2(RENAME_NOREPLACE)`` (Linux); where the C library
    or the file system lacks it, a hard link (which refuses an existing target) then the unlink of ``src``;
    on a file system without hard links (FAT, some network shares) ``dst`` is first created exclusively
    (``O_EXCL``: the same refusal) as a placeholder that ``src`` then replaces.  Never a check then an act."""
    src, dst = str(src), str(dst)
    if _renameat2(src, dst):
        return
    try:
        os.link(src, dst)
    except FileExistsError:
        raise
    except OSError:  # no hard links here: reserve the name exclusively, then replace the reservation
        os.close(os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.replace(src, dst)
    else:
        os.unlink(src)


def fsync_path(path) -> None:
    """Flush a file's (or a folder's: its entries) data to the disk, so it survives a power cut."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:  # a folder some file systems cannot fsync: nothing more can be done
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path, overwrite: bool = False):
    """A temporary path next to ``path``, renamed onto ``path`` when the block succeeds.

    Refuses if ``path`` exists and not ``overwrite``, and if another process holds the lock of
    ``path`` (:func:`claim_output`, taken here for the write unless held already).  Without
    ``overwrite``, a file that appears at ``path`` during the write is not replaced.  On any exception,
    ``BaseException`` included (KeyboardInterrupt, the interrupt of a SIGTERM), the temporary file is
    removed and ``path`` is untouched; a pending :func:`~inscal.core.cancel.cancel` is raised before the
    rename, so an interrupted write is never published.  Inside an :func:`output_unit` the rename waits
    for the end of the unit.  The temporaries of ``path`` that a killed writer left are removed once its
    lock is taken (:func:`remove_stale_parts`).

    Parameters
    ----------
    path : str or pathlib.Path
        The output file; its folder must exist.
    overwrite : bool
        Replace an existing file.

    Yields
    ------
    pathlib.Path
        The temporary file to write (same folder, ``.part`` suffix).

    Raises
    ------
    FileNotFoundError
        The folder of ``path`` does not exist.
    FileExistsError
        ``path`` exists and ``overwrite`` is false.
    OutputBusyError
        Another process is writing ``path``.

    Examples
    --------
    >>> from pathlib import Path
    >>> from inscal.io import atomic_path
    >>> with atomic_path("out.txt") as tmp:
    ...     _ = tmp.write_text("done")
    ...     Path("out.txt").exists()
    False
    >>> Path("out.txt").read_text()
    'done'
    """
    path = FsPath(path)
    if not path.parent.exists():
        raise FileNotFoundError(f"folder {path.parent} does not exist")
    unit = _UNITS[-1] if _UNITS else None
    with _signals_held():  # the unit knows of the lock before an interrupt can end it (it releases the lock)
        taken = claim_output(path)
        if taken and unit is not None:
            unit.claimed.append(path)
    if fcntl is not None:  # the lock held: no other writer of path is at work
        remove_stale_parts(path)
    try:
        if path.exists() and not overwrite:
            raise FileExistsError(f"{path} exists; refusing to overwrite it (use --force / overwrite=True)")
        tmp = None
        try:
            # the file and its registration at once: an interrupt between the two (mkstemp returns through
            # several bytecodes) left a temporary that neither this cleanup nor remove_live_parts knew of
            with _signals_held():
                fd, tmp = tempfile.mkstemp(prefix=part_prefix(path), suffix=".part", dir=path.parent)
                _LIVE_PARTS[tmp] = path
                os.close(fd)
            yield FsPath(tmp)
            check_cancel()
            if unit is not None:
                unit.pending.append((tmp, path, overwrite))
            else:
                publish(tmp, path, overwrite)
        except BaseException:
            if tmp is not None:
                remove_part(tmp)
            raise
    finally:
        if taken and unit is None:
            release_output(path)


#: the random part of a temporary's name (``tempfile.mkstemp``)
_RANDOM_CHARS = 8


def part_prefix(path) -> str:
    """The start of the name of every temporary of output ``path`` (:func:`atomic_path`)."""
    return side_name(FsPath(path).name, ".", room=_RANDOM_CHARS + len(".part"))


def remove_stale_parts(path) -> list[str]:
    """Remove the temporaries of output ``path`` that a killed writer left beside it (SIGKILL, a power cut);
    call it holding the output's lock (:func:`claim_output`), so that no writer of ``path`` is at work.  The
    names removed."""
    path = FsPath(path)
    prefix = part_prefix(path)
    try:
        names = os.listdir(path.parent)
    except OSError:
        return []
    gone = []
    for name in names:
        full = str(path.parent / name)
        if name.startswith(prefix) and name.endswith(".part") and len(name) == len(prefix) + _RANDOM_CHARS + 5 \
                and full not in _LIVE_PARTS:
            with contextlib.suppress(OSError):
                os.unlink(full)
                gone.append(name)
    return gone


def remove_part(tmp: str) -> bool:
    """Remove a temporary of :func:`atomic_path`, if still there.

    Parameters
    ----------
    tmp : str
        The temporary's path.

    Returns
    -------
    bool
        True if it is gone and was live (an earlier, interrupted removal counts); a removed one is
        listed in :data:`REMOVED_PARTS`.

    Examples
    --------
    >>> from inscal.io import remove_part
    >>> remove_part("never-written.part")
    False
    """
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
    """Remove every temporary of :func:`atomic_path` still being written (last resort of an interrupt).

    Examples
    --------
    >>> from pathlib import Path
    >>> from inscal.io import atomic_path, remove_live_parts
    >>> try:
    ...     with atomic_path("out.txt") as tmp:
    ...         remove_live_parts()  # as the interrupt handler does
    ...         raise KeyboardInterrupt
    ... except KeyboardInterrupt:
    ...     print(tmp.exists(), Path("out.txt").exists())
    False False
    """
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
    """The SHA-256 of a file's bytes (recorded in calibration parameter files).

    Parameters
    ----------
    path : str or pathlib.Path
        The file.

    Returns
    -------
    str
        ``"sha256:"`` and the hex digest.

    Examples
    --------
    >>> from pathlib import Path
    >>> from inscal.io import file_hash
    >>> _ = Path("empty.bin").write_bytes(b"")
    >>> file_hash("empty.bin")
    'sha256:e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855'
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return "sha256:" + h.hexdigest()
