"""HTML building blocks of the reports: escaping, tables, numbers and field units."""

from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np


def fmt_value(v) -> str:
    a = np.atleast_1d(np.asarray(v, dtype=float)).ravel()
    return ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a)


# ------------------------------------------------------------------------------ demo report
#: display spellings of the field units (the files keep the ASCII ones)
DISPLAY_UNIT = {"deg/h": "°/h", "ug": "µg", "ug/g^2": "µg/g²", "deg/h/g": "°/h/g", "deg/sqrt(h)": "°/√h",
                "ug/sqrt(Hz)": "µg/√Hz", "arcsec": "arcsec", "ppm": "ppm", "cm": "cm", "ms": "ms", "deg": "°"}


def display_unit(unit: str) -> str:
    return DISPLAY_UNIT.get(unit, unit)


def fmt_num(x, digits: int = 4) -> str:
    """A number for a table: ``digits`` significant digits, no exponent between 1e-4 and 10**digits."""
    if x is None:
        return "—"
    x = float(x)
    if not np.isfinite(x):
        return "—"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 10 ** digits:
        return f"{x:.0f}"
    if a >= 1e-4:
        s = f"{x:.{digits}g}"
        return s if "e" not in s else f"{x:.0f}"
    return f"{x:.{digits - 1}e}"


def escape(s) -> str:

    return html.escape(str(s))


def png_file_base64(path) -> str:

    return base64.b64encode(Path(path).read_bytes()).decode("ascii")


def html_table(head: list[str], rows: list[list[str]], cls: str = "", head2: list[tuple[str, int]] | None = None) -> str:
    """An HTML table; cells are escaped unless given as ``("html", text)``."""
    def cell(c, tag="td"):
        if isinstance(c, tuple):
            kind, text = c[0], c[1]
            attrs = c[2] if len(c) > 2 else ""
            return f"<{tag}{attrs}>{text if kind == 'html' else escape(text)}</{tag}>"
        return f"<{tag}>{escape(c)}</{tag}>"

    h = ""
    if head2:
        h += "<tr>" + "".join(f"<th colspan='{n}'>{escape(t)}</th>" for t, n in head2) + "</tr>"
    h += "<tr>" + "".join(cell(c, "th") for c in head) + "</tr>"
    body = "".join("<tr>" + "".join(cell(c) for c in r) + "</tr>" for r in rows)
    return f"<table class='{cls}'>{h}{body}</table>"


def z_cell(err, sig):
    if err is None or sig is None or not np.isfinite(err) or not np.isfinite(sig) or sig <= 0:
        return "—"
    z = err / sig
    return ("html", fmt_num(z, 2), " class='bad'" if abs(z) > 3 else "")
