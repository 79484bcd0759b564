"""Small helpers shared by the ``cli_*`` modules (no domain logic here)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from .jsonutil import to_jsonable


class CliError(Exception):
    """An error to report to the user as one line (exit code 2)."""


def fail(msg: str, code: int = 2) -> typer.Exit:
    """Print a one-line error to stderr and return an Exit to raise: ``raise fail("...")``."""
    typer.echo(f"inscal: error: {msg}", err=True)
    return typer.Exit(code)


def check_output(path: Path, force: bool) -> None:
    """Refuse to overwrite an existing output unless ``force``; the parent folder must exist."""
    if path.exists() and not force:
        raise CliError(f"{path} exists; use --force to overwrite it")
    if not path.parent.exists():
        raise CliError(f"folder {path.parent} does not exist")


def print_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (NumPy types converted, NaN/inf -> null)."""
    typer.echo(json.dumps(to_jsonable(obj), indent=2))
