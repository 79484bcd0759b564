"""Reading small TOML input files (scenarios, mappings, paths) with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path


def read_toml(path, error: type[Exception], what: str = "file") -> dict:
    """The parsed TOML document at ``path``; a missing file, malformed TOML or a non-text file
    raises ``error`` with one line naming the file (``what``: e.g. "scenario file")."""
    p = Path(path)
    if not p.is_file():
        raise error(f"{p}: no such {what}")
    try:
        return tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{p}: malformed TOML: {exc}") from None
    except UnicodeDecodeError:
        raise error(f"{p}: not a text file") from None
