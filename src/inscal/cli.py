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


def main() -> None:  # console-script entry point
    app(prog_name="inscal")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
