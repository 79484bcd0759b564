"""Cancellation: an interrupt (SIGINT/SIGTERM) that must not cut a step in the middle.

The command line's signal handler (:mod:`inscal.cli.interrupts`) records its exception with
:func:`cancel`; the file writers and readers and the sliced kernels call :func:`check_cancel` between
steps and raise it there (Python may drop the handler's own exception inside a weakref or ``__del__``
callback).  A step that must finish once begun (a file made and registered, outputs renamed into place)
runs inside :func:`signals_held`: the signals are blocked in the main thread, the handler sees
:func:`holding` and only records the interrupt, and the outermost block raises it when it ends.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

#: a pending cancellation (the exception to raise), set by :func:`cancel`
_CANCEL: list[BaseException] = []
#: one entry per :func:`signals_held` block running in the main thread
_HOLDS: list[bool] = []


def cancel(exc: BaseException) -> None:
    """Ask the file writers and readers and the sliced kernels to stop.

    From now on :func:`check_cancel` (called per chunk and before an output is renamed into place)
    raises ``exc``.  Used by the SIGINT/SIGTERM handler of :func:`inscal.cli.main`, whose own exception
    may be swallowed where Python cannot propagate it (a weakref or ``__del__`` callback).  The first
    cancellation stays; later ones are ignored.

    Parameters
    ----------
    exc : BaseException
        The exception to raise (``KeyboardInterrupt()`` for SIGINT).

    Examples
    --------
    Not run here: a cancellation lasts for the rest of the process.

    >>> from inscal.core.cancel import cancel, check_cancel
    >>> cancel(KeyboardInterrupt())  # doctest: +SKIP
    >>> check_cancel()  # doctest: +SKIP
    Traceback (most recent call last):
    KeyboardInterrupt
    """
    if not _CANCEL:
        _CANCEL.append(exc)


def check_cancel() -> None:
    """Raise the pending cancellation, if any (see :func:`cancel`).

    Raises
    ------
    BaseException
        The exception given to :func:`cancel` (KeyboardInterrupt, the interrupt of a SIGTERM).

    Examples
    --------
    >>> from inscal.core.cancel import check_cancel
    >>> check_cancel()  # nothing pending: returns
    """
    if _CANCEL:
        raise _CANCEL[0]


def holding() -> bool:
    """Whether a step that an interrupt must not cut is running (a file made and registered, outputs
    renamed into place): the command line's SIGINT/SIGTERM handler then records the interrupt
    (:func:`cancel`) instead of raising it, and the step raises it when it ends."""
    return bool(_HOLDS)


@contextmanager
def signals_held():
    """SIGINT/SIGTERM held off in the main thread until the block ends (Python runs signal handlers there
    only; another thread's block holds nothing): blocked, and, for a signal another thread of the process
    received, deferred by the handler (:func:`holding`); an interrupt recorded meanwhile is raised when the
    outermost block ends (:func:`check_cancel`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sigs = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs) if hasattr(signal, "pthread_sigmask") else None
    _HOLDS.append(True)
    try:
        yield
    finally:
        _HOLDS.pop()
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
    if not _HOLDS:  # the outermost block: an inner one ends inside a step still running
        check_cancel()
