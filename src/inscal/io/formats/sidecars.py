"""The files that come beside a source, whatever its format: temperature readings at their own times
(``--temperature``) and encoder angles (``--gimbal``), each a header row that may give the units, then
rows, comma or whitespace separated."""

from __future__ import annotations

import re

from pathlib import Path as FsPath

import numpy as np

from inscal.core import units
from inscal.io.formats.base import RawTemperature, check_angles, text_lines
from inscal.io.formats.table import parse_table, split_fields
from inscal.io.mapping import ImportFileError, Mapping


def _header_cell(p, cell: str, what: str) -> tuple[str, str | None]:
    """``NAME [unit]`` -> ``(NAME, unit or None)``."""
    found = re.fullmatch(r"\s*(.*?)\s*\[\s*([^\]]+?)\s*\]\s*", cell)
    if found is None:
        if "[" in cell or "]" in cell:
            raise ImportFileError(f"{p}: header cell {cell!r} ({what}): expected 'NAME [unit]' or 'NAME'")
        return cell.strip(), None
    return found.group(1), found.group(2)


def read_temperature_file(path) -> RawTemperature:
    """Temperature readings at their own times: a header row ``time [s],NAME [degC],...`` (one column per
    sensor, named by its header cell; the units in brackets: time s | ms | min | h, default s;
    temperature degC | K | degF, default degC), then rows; comma or whitespace separated, ``#`` comment
    lines.  A comma-separated row may leave a sensor's cell empty (no reading of that sensor then).
    Times must increase; values are returned in degC."""
    p = FsPath(path)
    lines = text_lines(p)
    k_head = next((k for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")), None)
    if k_head is None:
        raise ImportFileError(f"{p}: no temperature rows")
    head = lines[k_head]
    delim = "," if "," in head else None
    cells = []
    for tok in split_fields(head, delim):  # whitespace separated: "imu [degC]" is one cell
        if delim is None and tok.startswith("[") and cells:
            cells[-1] += " " + tok
        else:
            cells.append(tok)
    try:
        float(cells[0])
        numeric = True
    except ValueError:
        numeric = False
    if numeric:
        raise ImportFileError(f"{p}: line {k_head + 1}: a temperature file starts with a header row naming its "
                              "columns, as 'time [s],imu [degC]' (a sensor per column after the time)")
    if len(cells) < 2:
        raise ImportFileError(f"{p}: the header {head.strip()!r} names no temperature column after the time")
    tname, t_unit = _header_cell(p, cells[0], "time")
    try:
        t_unit = units.check_kind(t_unit or "s", "time")
    except units.UnitError as exc:
        raise ImportFileError(f"{p}: header unit of the time column: {exc}") from None
    names, tunits = [], []
    for c in cells[1:]:
        name, unit = _header_cell(p, c, "a temperature column")
        if not name:
            raise ImportFileError(f"{p}: a temperature column has no name in the header ({head.strip()!r})")
        try:
            tunits.append(units.temperature_unit(unit or "degC"))
        except units.UnitError as exc:
            raise ImportFileError(f"{p}: header cell {c.strip()!r}: {exc}") from None
        names.append(name)
    if len(set(names)) != len(names):
        raise ImportFileError(f"{p}: temperature sensor names repeat in the header ({', '.join(names)})")
    m = Mapping({}, delimiter=delim, header_rows=k_head + 1)
    data, line_no, _ = parse_table(p, m, {c: f"temperature sensor {names[c - 1]!r}" for c in range(1, len(cells))},
                                    [c.strip() for c in cells])
    if data.shape[1] != len(cells):
        raise ImportFileError(f"{p}: rows have {data.shape[1]} columns, the header names {len(cells)}")
    t = data[:, 0]
    bad = ~np.isfinite(t)
    if bad.any():
        k = int(np.argmax(bad))
        raise ImportFileError(f"{p}: line {line_no[k]}: the time is {t[k]!r}")
    t = units.to_si(t, t_unit, "time")
    st = np.diff(t)
    if np.any(st <= 0):
        k = int(np.argmax(st <= 0))
        raise ImportFileError(f"{p}: the time does not increase at line {line_no[k + 1]} "
                              f"(t = {t[k + 1]:.9g} s after {t[k]:.9g} s)")
    vals = np.column_stack([units.to_celsius(data[:, k + 1], u) for k, u in enumerate(tunits)])
    return RawTemperature(t, vals, tuple(names), tuple(f"temperature {n!r} (column {k + 1})" for k, n in enumerate(names)),
                          line_no, tuple(tunits), "give the column's unit in the header, as '{name} [{unit}]'", str(p))


def header_angle_unit(p, header: str) -> str | None:
    """The angle unit a gimbal file's header gives its outer and inner columns (``outer [rad]``, as
    ``inscal export --gimbal-out`` writes), or None when it gives none; both must agree."""
    cells = [c.strip() for c in (header.split(",") if "," in header else header.split())]
    found = [re.search(r"\[\s*([^\]]+?)\s*\]", c) for c in cells[1:3]]
    names = {m.group(1) for m in found if m}
    if not names:
        return None
    if len(names) > 1 or len(cells) < 3 or not all(found):
        raise ImportFileError(f"{p}: the header gives the angle columns different or missing units ({header.strip()!r})")
    try:
        units.check_kind(names.pop(), "angle")
    except units.UnitError as exc:
        raise ImportFileError(f"{p}: header unit: {exc}") from None
    return found[0].group(1)


def header_time_unit(p, header: str) -> str:
    """The time unit a gimbal file's header gives its first column (``time [ms]``), else seconds."""
    cells = [c.strip() for c in (header.split(",") if "," in header else header.split())]
    found = re.search(r"\[\s*([^\]]+?)\s*\]", cells[0]) if cells else None
    if found is None:
        return "s"
    try:
        return units.check_kind(found.group(1), "time")
    except units.UnitError as exc:
        raise ImportFileError(f"{p}: header unit of the time column: {exc}") from None


def read_gimbal_file(path, unit: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Encoder angles: rows ``time [s], outer, inner`` -> ``(t [s], angles [rad] (M, 2))``, unwrapped.
    The unit is the one the header gives (``outer [rad]``), else ``unit``, else degrees; a header
    unit that contradicts an explicit ``unit`` is an error (one of them is wrong).  The header may
    give the time column's unit too (``time [ms]``; default seconds).  Angles beyond the physical
    limits (:func:`check_angles`) are refused with their line."""
    p = FsPath(path)
    if unit is not None:
        try:
            units.check_kind(unit, "angle")
        except units.UnitError as exc:
            raise ImportFileError(f"--gimbal-unit: {exc}") from None
    lines = [ln for ln in text_lines(p) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ImportFileError(f"{p}: no gimbal rows")
    delim = "," if "," in lines[0] else None
    try:
        float(split_fields(lines[0], delim)[0])
        header = 0
    except ValueError:
        header = 1
    in_file = header_angle_unit(p, lines[0]) if header else None
    t_unit = header_time_unit(p, lines[0]) if header else "s"
    if in_file is not None and unit is not None and units.to_si(1.0, in_file, "angle") != units.to_si(1.0, unit, "angle"):
        raise ImportFileError(f"{p}: the header says the angles are in {in_file}, --gimbal-unit says {unit}")
    u = in_file or unit or "deg"
    m = Mapping({}, delimiter=delim, header_rows=header)
    data, line_no, _ = parse_table(p, m)
    if data.shape[1] != 3:
        raise ImportFileError(f"{p}: gimbal rows need 3 columns (time, outer, inner), got {data.shape[1]}")
    if data.shape[0] < 2:
        raise ImportFileError(f"{p}: fewer than 2 gimbal rows")
    bad = ~np.isfinite(data)
    if bad.any():
        k = int(np.argmax(bad.any(axis=1)))
        raise ImportFileError(f"{p}: NaN/Inf in the gimbal angles at line {line_no[k]}")
    t = units.to_si(data[:, 0], t_unit, "time")
    st = np.diff(t)
    if np.any(st <= 0):
        k = int(np.argmax(st <= 0))
        raise ImportFileError(f"{p}: gimbal time does not increase at line {line_no[k + 1]} "
                              f"(t = {t[k + 1]:.9g} s after {t[k]:.9g} s)")
    med = float(np.median(st))
    if st.max() > 10 * med:
        k = int(np.argmax(st))
        raise ImportFileError(f"{p}: gimbal time has a gap of {st[k]:.6g} s at line {line_no[k + 1]} "
                              f"(t = {t[k]:.9g} -> {t[k + 1]:.9g} s; usual step {med:.6g} s)")
    ang = units.to_si(data[:, 1:3], u, "angle")
    check_angles(ang, st, str(p), lambda i: f"line {line_no[i]}")
    return t, np.unwrap(ang, axis=0)

