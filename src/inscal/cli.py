"""The ``inscal`` command line: a thin layer over the library.

Subcommands live with their domain: ``cli_<name>.py`` modules each define
``register(app)``; this file assembles them.
"""

from __future__ import annotations

import importlib
import sys

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help="Calibrate high-accuracy IMUs and dual-axis rotational INS.")

def _version(value: bool) -> None:
    if value:
        from . import __version__

        typer.echo(f"inscal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="print the inscal version and exit"),
) -> None:
    """inscal: calibrate high-accuracy IMUs and dual-axis rotational INS (S16, N25)."""


#: modules contributing subcommands (each has ``register(app)``)
_SUBCOMMAND_MODULES = ["cli_simulate", "cli_calibrate", "cli_compensate", "cli_navigate", "cli_montecarlo", "cli_allan", "cli_demo", "cli_report", "cli_observability", "cli_import"]
_SUBCOMMAND_MODULES.append("cli_design")  # inscal design (issue 10): path design from the Cramér-Rao bound


def _register_all() -> None:
    for name in _SUBCOMMAND_MODULES:
        try:
            mod = importlib.import_module(f"inscal.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"inscal.{name}":
                continue  # not built yet
            raise
        mod.register(app)


_register_all()


class Interrupted(BaseException):
    """SIGINT or SIGTERM: raised in the main thread by :func:`main`'s handler so that it unwinds
    through the ``atomic_path`` context managers (whose cleanup removes the ``.part`` files).
    A ``BaseException``: no ``except Exception`` and no click handler swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _interrupt_handler(signum, frame):  # pragma: no cover - runs in a subprocess (tests/test_signals.py)
    import signal

    for s in (signal.SIGINT, signal.SIGTERM):  # a second signal must not cut the cleanup short
        signal.signal(s, signal.SIG_IGN)
    raise Interrupted(signum)


def _interrupted(signum: int) -> int:
    """Report an interrupt in one line (stderr) after the cleanup; return the exit code
    (128 + signal number: 130 for SIGINT, 143 for SIGTERM)."""
    import signal

    name = signal.Signals(signum).name
    removed = []
    io = sys.modules.get("inscal.io")
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
    try:
        app(prog_name="inscal")
    except (Interrupted, KeyboardInterrupt) as exc:
        sys.exit(_interrupted(getattr(exc, "signum", signal.SIGINT)))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
