"""``--format csv`` and ``--format txt``: delimited text read through a mapping (which column is which
channel, in which unit and sign; :mod:`inscal.io.mapping`), or a csv that starts with the header
``inscal export`` writes; ``kind = "sampled-rates"`` integrates rates at their own stamps onto a grid
(:mod:`inscal.io.formats.rates`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path as FsPath

import numpy as np

from inscal.core import units
from inscal.io.formats.base import Raw, RawTemperature, ReadOptions, file_bytes, write_rows
from inscal.io.formats.rates import GAP_FACTOR, check_stamps, integrate_rates
from inscal.io.formats.table import column_index, parse_table
from inscal.io.mapping import (
    CHANNELS,
    EXPORT_HEADER,
    EXPORT_HEADER_GIMBAL,
    EXPORT_TEMPERATURE,
    ImportFileError,
    Mapping,
    decode_counts,
    default_mapping,
    export_layout,
)
from inscal.io.records import RecordInfo, Temperature


def read_text(path, mapping: Mapping | None, fmt: str = "csv", rate_hz: float | None = None) -> Raw:
    """A delimited text file read through ``mapping`` (None: the inscal export layout); ``rate_hz``: the
    grid of ``kind = "sampled-rates"`` (default their mean rate)."""
    p = FsPath(path)
    given = mapping is not None
    if mapping is None:
        if fmt != "csv":
            raise ImportFileError(f"--format {fmt} needs --mapping M.toml (the columns and their units)")
        b = file_bytes(p)
        try:
            head = b.decode("utf-8-sig").splitlines()[0] if b else ""
        except UnicodeDecodeError:
            raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
        layout = export_layout([n.strip() for n in head.split(",")])
        if layout is None:
            raise ImportFileError(f"{p}: the first line is not the inscal export header ({','.join(EXPORT_HEADER)}); "
                                  "give --mapping M.toml")
        mapping = default_mapping(*layout)
    m = mapping
    data, line_no, names = parse_table(p, m, {c: f"temperature sensor {n!r}" for n, c in m.temperature})
    ncol = data.shape[1]
    idx = {}
    keyed = [*m.columns.items(), *((f"temperature sensor {n!r}", c) for n, c in m.temperature)]
    for key, col in keyed:
        col = column_index(p, names, col, key)
        if col >= ncol:
            raise ImportFileError(f"{p}: column index {col} (for {key}) is out of range: rows have {ncol} columns "
                                  f"(indexes 0-{ncol - 1})")
        idx[key] = col
    if data.shape[0] < 2:
        raise ImportFileError(f"{p}: {data.shape[0]} data row(s); at least 2 samples are needed")
    raw6 = data[:, [idx[c] for c in CHANNELS]]
    inc = m.kind == "increments"

    def label(key: str, c: int) -> str:
        return f"{key} (column {c}" + (f" {names[c]!r})" if names and c < len(names) else ")")

    labels = tuple(label(c, idx[c]) for c in CHANNELS)

    def at(i: int) -> str:
        return f"line {int(line_no[i])}" if line_no is not None else f"row {i + 1}"

    def conv(x, unit, scale, kind, spec, lab):
        if unit == "counts":
            return decode_counts(x, spec, str(p), lab, at) * scale
        return units.to_si(x, unit, kind)

    g = conv(raw6[:, 0:3], m.gyro_unit, m.gyro_scale, "angle" if inc else "rate", m.gyro_counts, labels[0:3])
    a = conv(raw6[:, 3:6], m.accel_unit, m.accel_scale, "velocity" if inc else "accel", m.accel_counts, labels[3:6])
    gyro = np.empty_like(g)
    accel = np.empty_like(a)
    for i in range(3):
        gyro[:, m.axes[i]] = m.signs[i] * g[:, i]
        accel[:, m.axes[i]] = m.signs[i] * a[:, i]
    t = units.to_si(data[:, idx["time"]], m.time_unit, "time") if "time" in idx else None
    gim = units.to_si(data[:, [idx["outer"], idx["inner"]]], m.gimbal_unit, "angle") if "outer" in idx else None

    counts = (m.gyro_unit == "counts", m.accel_unit == "counts")
    tl = f"time (column {idx['time']})" if "time" in idx else "time"
    fix = ("set [units] time = \"{unit}\" in the mapping" if given else
           "import it with --mapping M.toml that sets [units] time = \"{unit}\" (without a mapping a csv is read as "
           "inscal's export, in seconds)")
    temp = None
    if m.temperature:
        cols = [idx[f"temperature sensor {n!r}"] for n, _ in m.temperature]
        temp = RawTemperature(None, units.to_celsius(data[:, cols], m.temperature_unit),
                              tuple(n for n, _ in m.temperature),
                              tuple(label(f"temperature {n!r}", c) for (n, _), c in zip(m.temperature, cols)),
                              line_no, (m.temperature_unit,) * len(cols),
                              "set [units] temperature = \"{unit}\" in the mapping" if given else "", str(p))
    if m.kind == "sampled-rates":
        return _sampled_rates(p, t, gyro, accel, gim, temp, labels, at, rate_hz, m.max_gap)
    return Raw(t, gyro, accel, m.kind, gim, labels, line_no, "", raw6, counts, tl, axes=m.axes, time_unit=m.time_unit,
               time_fix=fix, temperature=temp)


def _sampled_rates(p: FsPath, t, gyro, accel, gim, temp, labels, at, rate_hz: float | None,
                   max_gap: float | None = None) -> Raw:
    """Rates sampled at their own stamps (``kind = "sampled-rates"``) -> increments on a uniform grid
    (:mod:`inscal.io.formats.rates`; the stamps checked first, steps up to ``max_gap`` [s] bridged)."""
    if gim is not None or temp is not None:
        raise ImportFileError(f"{p}: kind = \"sampled-rates\" takes no gimbal or temperature columns (import them "
                              "with --gimbal / --temperature at their own times)")
    step = check_stamps(t, str(p), "sample", at, max_gap)
    integ = integrate_rates(t, gyro, accel, rate_hz)
    integ = replace(integ, gaps=int(np.count_nonzero(np.diff(t) > GAP_FACTOR * step)))
    inc_labels = tuple(lab.replace("gx", "dthx").replace("gy", "dthy").replace("gz", "dthz") for lab in labels)
    return Raw(integ.time, integ.gyro, integ.accel, "increments", None, inc_labels, None, "",
               np.column_stack([integ.gyro, integ.accel]), integration=integ)



def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY` (csv and txt)."""
    return read_text(FsPath(src), opts.mapping, opts.fmt, opts.rate_hz)


def temperature_block(temp: Temperature, rows: np.ndarray | None, k0: int, t: np.ndarray) -> np.ndarray:
    """The csv temperature cells of the samples ``k0 ..`` at times ``t``: the readings on their rows (NaN:
    an empty cell), or interpolated (``rows`` None)."""
    if rows is None:
        return np.column_stack([np.interp(t, temp.time, temp.values[:, s]) for s in range(temp.values.shape[1])])
    block = np.full((t.shape[0], temp.values.shape[1]), np.nan)
    a, b = np.searchsorted(rows, [k0, k0 + t.shape[0]])
    block[rows[a:b] - k0] = temp.values[a:b]
    return block


def write(tmp, chunks, info: RecordInfo, rows: np.ndarray | None = None) -> None:
    """The export writer of :data:`~inscal.io.formats.REGISTRY` (csv): the header with units, then per chunk
    ``(t, dtheta, dvel, gimbal)`` the rows of 17 digits, with the gimbal columns when recorded and the
    temperature sensors' columns (``rows``: each reading's sample, None: interpolated onto every sample,
    said on a comment line under the header)."""
    temp = info.temperature
    with open(tmp, "w") as fh:
        head = EXPORT_HEADER + (EXPORT_HEADER_GIMBAL if info.has_gimbal else [])
        head += [EXPORT_TEMPERATURE.format(n) for n in (temp.sensors if temp is not None else ())]
        fh.write(",".join(head) + "\n")
        if temp is not None and rows is None:
            fh.write(f"# temperature: interpolated linearly onto the sample times from the {temp.time.shape[0]} "
                     f"readings at their own times (t = {temp.time[0]:.9g} .. {temp.time[-1]:.9g} s; held "
                     "before the first and after the last)\n")
        elif temp is not None and temp.time.shape[0] < info.n_samples:
            fh.write(f"# temperature: the {temp.time.shape[0]} readings on the rows of their sample times; "
                     "an empty cell: no reading at that sample\n")
        blanks = temp is not None and rows is not None and temp.time.shape[0] < info.n_samples
        k0 = 0
        for t, dth, dv, g in chunks:
            cols = [t, dth, dv] + ([g] if g is not None else [])
            if temp is not None:
                cols.append(temperature_block(temp, rows, k0, t))
            write_rows(fh, np.column_stack(cols), blanks=blanks)
            k0 += t.shape[0]
