"""The ``inscal`` command line: a thin layer over the library.

Subcommands live one per module: ``inscal.cli.<name>`` modules each define
``register(app)``; this file assembles them.
"""

from __future__ import annotations

import functools
import importlib
import sys

import click
import typer

from inscal.cli.common import CliError, fail
from inscal.cli.examples import epilog
from inscal.cli.interrupts import (
    Interrupted,
    catch_interrupts,
    pending_signal,
    release_interrupts,
)
from inscal.cli.options import Command, Group

app = typer.Typer(add_completion=False, no_args_is_help=True, cls=Group, help="Calibrate high-accuracy IMUs and dual-axis rotational INS.")

def _version(value: bool) -> None:
    if value:
        from inscal import __version__

        typer.echo(f"inscal {__version__}")
        raise typer.Exit()


def _release_outputs() -> None:
    files = sys.modules.get("inscal.io.files")
    if files is not None:
        files.release_outputs()


@app.callback()
def _root(
    ctx: typer.Context,
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="print the inscal version and exit"),
) -> None:
    """inscal: calibrate high-accuracy IMUs and dual-axis rotational INS (S16, N25)."""
    ctx.call_on_close(_release_outputs)  # the locks of the command's outputs (inscal.io.files.claim_output)
    files = importlib.import_module("inscal.io.files")
    if _stale_lock_note not in files.NOTES:  # a dead writer's lock taken over: said
        files.NOTES.append(_stale_lock_note)


def _stale_lock_note(line: str) -> None:
    typer.echo(f"inscal: note: {line}", err=True)


#: modules contributing subcommands (each has ``register(app)``)
_SUBCOMMAND_MODULES = ["simulate", "calibrate", "compensate", "navigate", "montecarlo", "allan", "demo", "report",
                       "observability", "import_export", "design", "db", "batch", "noise"]


#: commands whose outputs are not one unit: the demo is a pipeline whose later steps read the
#: records and parameter files of the earlier ones (each output is still written atomically)
_PIPELINES = ("demo",)


def _one_unit(command):
    """``command`` with all its outputs published together at its end, or none of them (an error,
    an interrupt): :func:`inscal.io.files.output_unit` around the whole command."""

    @functools.wraps(command)
    def run(*args, **kwargs):
        files = importlib.import_module("inscal.io.files")
        try:
            with files.output_unit():
                try:
                    return command(*args, **kwargs)
                except click.exceptions.Exit as exc:
                    if exc.exit_code:
                        raise
                    return None  # a command that ends early with success: its outputs stand
        except (FileExistsError, CliError) as exc:  # an output that appeared meanwhile is not replaced; a step
            raise fail(str(exc)) from None          # of the publication (a database commit) failed: nothing published

    return run


def _register_all() -> None:
    for name in _SUBCOMMAND_MODULES:
        importlib.import_module(f"inscal.cli.{name}").register(app)
    for info in app.registered_commands:
        if info.callback.__name__ not in _PIPELINES:
            info.callback = _one_unit(info.callback)
    # every command's help: the values named (inscal.cli.options.Command) and its examples (inscal.cli.examples)
    commands = [("", info) for info in app.registered_commands]
    for group in app.registered_groups:
        commands += [(group.name + " ", info) for info in group.typer_instance.registered_commands]
    for prefix, info in commands:
        info.cls = Command
        info.epilog = epilog(prefix + (info.name or info.callback.__name__))


_register_all()


def _interrupted(signum: int, old: dict) -> int:
    """Report an interrupt in one line (stderr) after the cleanup; return the exit code
    (128 + signal number: 130 for SIGINT, 143 for SIGTERM)."""
    import signal

    release_interrupts(old, ignore=True)  # a second signal must not cut the report short
    name = signal.Signals(signum).name
    removed, published = [], []
    files = sys.modules.get("inscal.io.files")
    if files is not None:  # no output is written without inscal.io.files
        files.remove_live_parts()
        files.release_outputs()
        removed = [f"{tmp} ({target} not written)" for tmp, target in files.REMOVED_PARTS]
        published = [str(p) for p in files.PUBLISHED]
    msg = f"inscal: interrupted ({name})"
    if removed:
        msg += "; removed partial output " + ", ".join(removed)
    elif published:  # the signal came after the outputs were renamed into place: they are whole
        msg += " after its outputs were complete: " + ", ".join(published)
    sys.stderr.write(msg + "\n")
    sys.stderr.flush()
    return 128 + signum


def main() -> None:  # console-script entry point
    """Run the command line; SIGINT and SIGTERM remove the partial outputs, print one line
    and exit with 130 / 143."""
    import signal

    old = catch_interrupts()
    try:
        try:
            app(prog_name="inscal")
        except SystemExit:
            # the command is over (its outputs published or removed): a signal during the interpreter's
            # teardown, whose finalisation restores the default handlers, would kill it with an exit
            # status that says nothing of the work done
            release_interrupts(old, ignore=True)
            raise
    except SystemExit:
        raise
    except BaseException as exc:
        # the interrupt itself, or an error it caused: raised in a class body while a module is imported,
        # Python reports it as a RuntimeError of __set_name__; an import may wrap it likewise
        signum = pending_signal() or getattr(exc, "signum", None)
        if signum is None and isinstance(exc, KeyboardInterrupt):
            signum = signal.SIGINT
        if signum is None:
            raise
        while True:
            try:
                code = _interrupted(signum, old)
                break
            except Interrupted:  # the SIGALRM re-arm fired before _interrupted disarmed it
                continue
        sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
