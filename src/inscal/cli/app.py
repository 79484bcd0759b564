"""The ``inscal`` command line: a thin layer over the library.

Subcommands live one per module: ``inscal.cli.<name>`` modules each define
``register(app)``; this file assembles them.
"""

from __future__ import annotations

import importlib
import sys

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Calibrate high-accuracy IMUs and dual-axis rotational INS.")

def _version(value: bool) -> None:
    if value:
        from inscal import __version__

        typer.echo(f"inscal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="print the inscal version and exit"),
) -> None:
    """inscal: calibrate high-accuracy IMUs and dual-axis rotational INS (S16, N25)."""


#: modules contributing subcommands (each has ``register(app)``)
_SUBCOMMAND_MODULES = ["simulate", "calibrate", "compensate", "navigate", "montecarlo", "allan", "demo", "report",
                       "observability", "import_export", "design"]


def _register_all() -> None:
    for name in _SUBCOMMAND_MODULES:
        importlib.import_module(f"inscal.cli.{name}").register(app)


_register_all()


class Interrupted(BaseException):
    """SIGINT or SIGTERM: raised in the main thread by :func:`main`'s handler so that it unwinds
    through the ``atomic_path`` context managers (whose cleanup removes the ``.part`` files).
    A ``BaseException``: no ``except Exception`` and no click handler swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


#: the signal being handled (None: not interrupted)
_PENDING: list[int] = []


def _interrupt_handler(signum, frame):  # pragma: no cover - runs in a subprocess (tests/cli/test_signals.py)
    """SIGINT/SIGTERM (and the SIGALRM re-arm): raise :class:`Interrupted` in the main thread.
    Python may have to drop it (a handler that runs inside a weakref or ``__del__`` callback), so
    the writers of :mod:`inscal.io` are told too (they stop at their next chunk), and SIGALRM
    repeats the raise every 0.2 s until :func:`main` has caught it."""
    import signal

    if _PENDING and isinstance(sys.exc_info()[1], Interrupted):
        return  # the interrupt is being handled (a cleanup runs): let it finish
    if not _PENDING:
        _PENDING.append(signum)
        try:
            signal.signal(signal.SIGALRM, _interrupt_handler)
            signal.setitimer(signal.ITIMER_REAL, 0.2, 0.2)
        except (ValueError, OSError, AttributeError):
            pass
    exc = Interrupted(_PENDING[0])
    io = sys.modules.get("inscal.io.files")
    if io is not None:
        io.cancel(exc)
    raise exc


def _quiet_unraisable(unraisable) -> None:
    """Drop the 'Exception ignored in ...' report of an interrupt Python could not propagate."""
    if isinstance(unraisable.exc_value, Interrupted):
        return
    sys.__unraisablehook__(unraisable)


def _interrupted(signum: int) -> int:
    """Report an interrupt in one line (stderr) after the cleanup; return the exit code
    (128 + signal number: 130 for SIGINT, 143 for SIGTERM)."""
    import signal

    try:
        signal.setitimer(signal.ITIMER_REAL, 0)
    except (ValueError, OSError, AttributeError):
        pass
    for s in (signal.SIGINT, signal.SIGTERM):  # a second signal must not cut the report short
        try:
            signal.signal(s, signal.SIG_IGN)
        except (ValueError, OSError):
            pass
    name = signal.Signals(signum).name
    removed = []
    io = sys.modules.get("inscal.io.files")
    if io is not None:  # no output is written without inscal.io
        io.remove_live_parts()
        removed = [f"{tmp} ({target} not written)" for tmp, target in io.REMOVED_PARTS]
    msg = f"inscal: interrupted ({name})"
    if removed:
        msg += "; removed partial output " + ", ".join(removed)
    sys.stderr.write(msg + "\n")
    sys.stderr.flush()
    return 128 + signum


def main() -> None:  # console-script entry point
    """Run the command line; SIGINT and SIGTERM remove the partial outputs, print one line
    and exit with 130 / 143."""
    import signal

    for s in (signal.SIGINT, signal.SIGTERM):
        try:
            signal.signal(s, _interrupt_handler)
        except (ValueError, OSError):  # not the main thread: leave the handlers alone
            pass
    sys.unraisablehook = _quiet_unraisable
    try:
        app(prog_name="inscal")
    except (Interrupted, KeyboardInterrupt) as exc:
        signum = _PENDING[0] if _PENDING else getattr(exc, "signum", signal.SIGINT)
        while True:
            try:
                code = _interrupted(signum)
                break
            except Interrupted:  # the SIGALRM re-arm fired before _interrupted disarmed it
                continue
        sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
