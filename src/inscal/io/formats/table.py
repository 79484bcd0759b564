"""Delimited text tables as the text formats read them (csv / txt through a mapping, the temperature
and gimbal files): the data rows as floats with the file line of each, the header names, columns given
by index or by header name, and temperature cells that may be empty (no reading)."""

from __future__ import annotations

import math

from io import StringIO
from pathlib import Path as FsPath

import numpy as np

from inscal.io.formats.base import text_lines
from inscal.io.mapping import ImportFileError, Mapping


def split_fields(line: str, delim: str | None) -> list[str]:
    """The fields of ``line``: split at ``delim`` and stripped, or at whitespace (``delim`` None)."""
    return line.split() if delim is None else [f.strip() for f in line.split(delim)]


def column_index(p, names: list[str] | None, col, key: str) -> int:
    """The index of a column given by index or by header name (exact, else the one case-insensitive match)."""
    if not isinstance(col, str):
        return int(col)
    if names is None:
        raise ImportFileError(f"{p}: column {col!r} (for {key}) is named, but the file is read without a header row")
    hits = [k for k, n in enumerate(names) if n == col] or [k for k, n in enumerate(names) if n.lower() == col.lower()]
    if len(hits) != 1:
        what = "no column" if not hits else f"{len(hits)} columns"
        raise ImportFileError(f"{p}: {what} named {col!r} (for {key}); header: {names}")
    return hits[0]


def _reading(tok: str) -> float:
    """A temperature cell: a finite number, or empty (no reading: NaN)."""
    if not tok.strip():
        return math.nan
    v = float(tok)
    if not math.isfinite(v):
        raise ValueError(f"{tok!r} is not finite")
    return v


def parse_table(p: FsPath, m: Mapping, blank: dict | None = None,
                 names: list[str] | None = None) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """Data rows as floats, the file line of each row, and the header names (last header row, unless
    ``names`` gives them).  ``blank``: ``{column (index or header name): what it is for}`` of temperature
    columns, whose cells may be empty (NaN: no reading) and must otherwise be finite."""
    lines = text_lines(p, binary_check=True)
    if len(lines) < m.header_rows:
        raise ImportFileError(f"{p}: {len(lines)} line(s), fewer than header_rows = {m.header_rows}")
    if names is None:
        names = split_fields(lines[m.header_rows - 1], m.delimiter) if m.header_rows else None
        if names is not None:
            names = [n.strip().strip('"').strip("'").strip() for n in names]
    body = [(k + 1, ln) for k, ln in enumerate(lines[m.header_rows:], start=m.header_rows)
            if ln.strip() and not ln.lstrip().startswith(m.comment)]
    if not body:
        raise ImportFileError(f"{p}: no data rows after the {m.header_rows} header row(s)")
    opt = {column_index(p, names, c, key) for c, key in (blank or {}).items()}
    line_no = np.fromiter((k for k, _ in body), dtype=np.int64, count=len(body))
    first = split_fields(body[0][1], m.delimiter)
    ncol = len(first)

    def col_name(c: int) -> str:
        return f"column {c}" + (f" ({names[c]!r})" if names and c < len(names) else "")

    def load(converters):
        try:
            data = np.loadtxt(StringIO("\n".join(ln for _, ln in body)), delimiter=m.delimiter, comments=None,
                              dtype=float, ndmin=2, converters=converters)
        except ValueError:
            return None
        return data if data.shape[0] == len(body) else None

    data = load(None)
    if data is not None:
        for c in opt:
            bad = ~np.isfinite(data[:, c]) if c < data.shape[1] else np.zeros(0, bool)
            if bad.any():  # no cell was empty (the fast parse took them all): a NaN / Inf written in the file
                k = int(np.argmax(bad))
                tok = split_fields(body[k][1], m.delimiter)[c]
                raise ImportFileError(f"{p}: line {line_no[k]}, {col_name(c)}: {tok!r} is not a temperature "
                                      "reading (leave the cell empty where there is no reading)")
        return data, line_no, names
    if opt and (data := load({c: _reading for c in opt if c < ncol})) is not None:
        return data, line_no, names
    # slow path: find the first bad row and say what is wrong with it
    for k, ln in body:
        fields = split_fields(ln, m.delimiter)
        if len(fields) != ncol:
            raise ImportFileError(f"{p}: line {k} has {len(fields)} field(s), expected {ncol} (as on line {body[0][0]})")
        for c, tok in enumerate(fields):
            try:
                v = float(tok) if tok or c not in opt else 0.0
            except ValueError:
                what = f"{tok!r} is not a number" if tok else "empty field"
                hint = ("; a header line? set header_rows" if m.columns and k == body[0][0] and m.header_rows == 0
                        else "")
                raise ImportFileError(f"{p}: line {k}, {col_name(c)}: {what}{hint}") from None
            if c in opt and not math.isfinite(v):
                raise ImportFileError(f"{p}: line {k}, {col_name(c)}: {tok!r} is not a temperature reading (leave the "
                                      "cell empty where there is no reading)")
    raise ImportFileError(f"{p}: cannot parse the data rows")  # pragma: no cover - loadtxt and the scan disagree

