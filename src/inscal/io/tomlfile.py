"""Reading small TOML input files (scenarios, mappings, paths) with one-line errors."""

from __future__ import annotations

import tomllib
from pathlib import Path

from inscal.io.files import check_input


#: the largest TOML input file read [bytes]: a scenario, mapping, path or station file is a few kB (a path
#: table of ten thousand stops some hundred kB)
MAX_TOML_BYTES = 4_000_000
#: the deepest nesting of arrays and tables read (tomllib recurses: deeper input would exhaust the stack)
MAX_TOML_DEPTH = 64


def read_toml(path, error: type[Exception], what: str = "file") -> dict:
    """The parsed TOML document at ``path``; a missing file, malformed TOML, a non-text file, one over
    :data:`MAX_TOML_BYTES` or nested deeper than :data:`MAX_TOML_DEPTH` raises ``error`` with one line
    naming the file (``what``: e.g. "scenario file")."""
    p = Path(path)
    check_input(p, what, error)
    size = p.stat().st_size
    if size > MAX_TOML_BYTES:
        raise error(f"{p}: {size} bytes, more than a {what} holds (at most {MAX_TOML_BYTES})")
    try:
        text = p.read_text()
        if _depth(text) > MAX_TOML_DEPTH:
            raise error(f"{p}: arrays or tables nested more than {MAX_TOML_DEPTH} deep: not a {what}")
        return tomllib.loads(text)
    except RecursionError:
        raise error(f"{p}: nested too deeply to be a {what}") from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{p}: malformed TOML: {exc}") from None
    except UnicodeDecodeError:
        raise error(f"{p}: not a text file") from None


def _depth(text: str) -> int:
    """An upper bound of the nesting of ``[`` and ``{`` in ``text`` (brackets inside strings counted too)."""
    depth = worst = 0
    for ch in text:
        if ch in "[{":
            depth += 1
            worst = max(worst, depth)
        elif ch in "]}":
            depth = max(depth - 1, 0)
    return worst
