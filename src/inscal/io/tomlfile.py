"""Reading small TOML input files (scenarios, mappings, paths) with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path

from inscal.io.files import check_input


def read_toml(path, error: type[Exception], what: str = "file") -> dict:
    """The parsed TOML document at ``path``; a missing file, malformed TOML or a non-text file
    raises ``error`` with one line naming the file (``what``: e.g. "scenario file")."""
    p = Path(path)
    check_input(p, what, error)
    try:
        return tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{p}: malformed TOML: {exc}") from None
    except UnicodeDecodeError:
        raise error(f"{p}: not a text file") from None
