"""SIGINT and SIGTERM for the command line and the warm-up: the handler raises :class:`Interrupted`
in the main thread so that the command unwinds through its ``atomic_path`` / ``output_unit``
context managers (whose cleanup removes the ``.part`` files), and tells the writers of
:mod:`inscal.io.files` to stop at their next chunk.

Python may have to drop an exception raised by a handler (one that runs inside a weakref or
``__del__`` callback, or a numba compilation inside a ctypes callback), so the handler re-arms
itself with SIGALRM every 0.2 s until the command has caught the interrupt; an interrupt caught
while another is being handled (the cleanup runs) is not raised again."""

from __future__ import annotations

import signal
import sys
import threading

#: the repeat of the raise while the interrupt has not been caught [s]
REARM_S = 0.2


class Interrupted(BaseException):
    """SIGINT or SIGTERM.  A ``BaseException``: no ``except Exception`` and no click handler
    swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


#: the signal being handled (empty: not interrupted)
_PENDING: list[int] = []
#: not empty once :func:`release_interrupts` ran: the handler no longer raises
_RELEASED: list[bool] = []


def pending_signal() -> int | None:
    """The signal that interrupted the command (None: not interrupted)."""
    return _PENDING[0] if _PENDING else None


def _handler(signum, frame):  # pragma: no cover - runs in a subprocess (tests/cli/test_signals.py)
    if _RELEASED or (_PENDING and isinstance(sys.exc_info()[1], Interrupted)):
        return  # released, or the interrupt is being handled (a cleanup runs): let it finish
    if not _PENDING:
        _PENDING.append(signum)
        try:
            signal.signal(signal.SIGALRM, _handler)
            signal.setitimer(signal.ITIMER_REAL, REARM_S, REARM_S)
        except (ValueError, OSError, AttributeError):
            pass
    exc = Interrupted(_PENDING[0])
    files = sys.modules.get("inscal.io.files")
    if files is not None:  # no output is written without inscal.io.files
        files.cancel(exc)
        if files.holding():  # a file being made and registered: the step raises it when it ends
            return
    raise exc


def _quiet_unraisable(unraisable) -> None:
    """Drop the 'Exception ignored in ...' report of an interrupt Python could not propagate."""
    if isinstance(unraisable.exc_value, (Interrupted, KeyboardInterrupt)):
        return
    sys.__unraisablehook__(unraisable)


def catch_interrupts() -> dict:
    """Route SIGINT and SIGTERM to the handler (main thread only; a signal ignored by the parent stays
    ignored); returns the previous handlers for :func:`release_interrupts`."""
    _PENDING.clear()
    _RELEASED.clear()
    old: dict = {}
    if threading.current_thread() is not threading.main_thread():
        return old
    sys.unraisablehook = _quiet_unraisable
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            if signal.getsignal(sig) is not signal.SIG_IGN:
                old[sig] = signal.signal(sig, _handler)
        except (ValueError, OSError):
            pass
    if old and hasattr(signal, "SIGALRM"):
        old[signal.SIGALRM] = signal.getsignal(signal.SIGALRM)
    return old


def release_interrupts(old: dict, ignore: bool = False) -> None:
    """Stop the re-arm and restore the handlers :func:`catch_interrupts` replaced (``ignore``: ignore SIGINT
    and SIGTERM instead, so that a second signal cannot cut the report of the first short)."""
    _RELEASED.append(True)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0)
    except (ValueError, OSError, AttributeError):
        pass
    for sig, handler in old.items():
        try:
            if ignore and sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, signal.SIG_IGN)
            else:
                signal.signal(sig, handler)
        except (ValueError, OSError):
            pass
    sys.unraisablehook = sys.__unraisablehook__
