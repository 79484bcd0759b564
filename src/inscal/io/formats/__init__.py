"""Readers of the raw formats of other tools (PSINS binary, MATLAB ``.mat``, CSV and text tables, gimbal
angle files): each returns a :class:`Raw` block of increments in the source's own units."""

from __future__ import annotations

import math
import re

from dataclasses import dataclass, replace
from io import StringIO
from pathlib import Path as FsPath

import h5py
import numpy as np

from inscal.core import units
from inscal.core.units import DEG
from inscal.io.files import check_input
from inscal.io.formats.rates import GAP_FACTOR, check_stamps, integrate_rates
from inscal.io.mapping import (
    CHANNELS,
    EXPORT_HEADER,
    MAX_ANGLE,
    MAX_RATE,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    ImportFileError,
    Mapping,
    decode_counts,
    default_mapping,
    export_layout,
)


# ----------------------------------------------------------------------------- raw sources
@dataclass
class RawTemperature:
    """Temperature readings as read, in degC, not yet checked: ``values`` (M, S) with NaN where a cell is
    empty (that sensor has no reading there), at ``time`` (M,) s, or at the rows of the IMU samples
    they came with (``time`` None)."""

    time: np.ndarray | None
    values: np.ndarray
    names: tuple  # sensor names
    labels: tuple  # each sensor's column, for messages
    lines: np.ndarray | None = None  # file line of each row
    units: tuple = ()  # the unit each sensor's values were declared in (degC, K, degF)
    fix: str = ""  # how to declare a sensor's unit ("{unit}": the unit, "{name}": the sensor)
    where: str = ""  # the file

    def at(self, i: int) -> str:
        """Where reading ``i`` came from, for messages: ``line N`` of a text file, else ``row N`` (1-based)."""
        return f"line {int(self.lines[i])}" if self.lines is not None else f"row {i + 1}"


@dataclass
class Raw:
    """Columns read from a source, converted to SI but not yet checked."""

    time: np.ndarray | None  # (N,) s, or None (then a rate is required)
    gyro: np.ndarray  # (N, 3) rad (increments) or rad/s (rates), IMU axes
    accel: np.ndarray  # (N, 3) m/s or m/s^2
    kind: str  # "increments" | "rates"
    gimbal: np.ndarray | None  # (N, 2) rad, from columns of the same file
    labels: tuple  # names of the 6 channels (for messages)
    lines: np.ndarray | None = None  # file line of each row (text); None: rows counted from 1
    hint: str = ""  # appended to time-base messages (e.g. a dtype hint)
    raw_channels: np.ndarray | None = None  # (N, 6) as read (before scaling), for the plausibility checks
    counts: tuple = (False, False)  # gyro / accel given in counts (whole numbers expected)
    time_label: str = "time"
    header_site: tuple | None = None  # (latitude deg, longitude deg, height m) the file's own header gives
    axes: tuple = (0, 1, 2)  # IMU axis of each file channel (1st, 2nd, 3rd of the gyros and of the accelerometers)
    time_unit: str = "s"  # the unit the time column was read in
    time_fix: str = ""  # how to declare the time column's unit here ("{unit}": the unit, "{factor}": the factor)
    temperature: RawTemperature | None = None  # temperature columns of the same file
    integration: object | None = None  # rates integrated onto a grid (inscal.io.formats.rates.RateIntegration)
    source_info: dict | None = None  # what a reader adds to the record's ``source`` attribute (JSON-ready)

    def at(self, i: int) -> str:
        """Where sample ``i`` came from, for messages: ``line N`` of a text file, else ``row N`` (1-based)."""
        return f"line {int(self.lines[i])}" if self.lines is not None else f"row {i + 1}"


def check_angles(angles: np.ndarray, dt, where: str, at, names=("outer angle", "inner angle")) -> None:
    """Gimbal angles [rad] (N, 2) within :data:`~inscal.io.mapping.MAX_ANGLE`, and no jump between two
    readings beyond a wrap (2 pi) plus :data:`~inscal.io.mapping.MAX_RATE` times the interval ``dt`` (a
    scalar or the (N - 1,) steps [s]): a value no encoder reads, named with ``at(i)`` (its row)."""
    for c in range(2):
        x = angles[:, c]
        with np.errstate(all="ignore"):
            big = np.abs(x) > MAX_ANGLE
        if big.any():
            i = int(np.argmax(big))
            raise ImportFileError(f"{where}: {names[c]} is {x[i]:.6g} rad ({x[i] / DEG:.6g} deg) at {at(i)}: beyond "
                                  f"any turntable (limit {MAX_ANGLE:.3g} rad, 1.6 million turns)")
        with np.errstate(all="ignore"):
            jump = np.abs(np.diff(x)) > 2.0 * math.pi + MAX_RATE * np.asarray(dt)
        if jump.any():
            j = int(np.argmax(jump))
            i = j if abs(x[j]) > abs(x[j + 1]) else j + 1  # the reading that does not belong: the larger one
            around = " and ".join(f"{x[m]:.6g}" for m in (i - 1, i + 1) if 0 <= m < x.size)
            raise ImportFileError(
                f"{where}: {names[c]} is {x[i]:.6g} rad ({x[i] / DEG:.6g} deg) at {at(i)}, {around} rad on the rows "
                f"around it: a jump of {abs(x[j + 1] - x[j]):.3g} rad in one interval, beyond a wrap (2 pi) and any "
                f"turntable's rate (limit {MAX_RATE:.0f} rad/s = 100 rev/s)")


def _file_bytes(p: FsPath) -> bytes:
    check_input(p, "file", ImportFileError)
    b = p.read_bytes()
    if not b:
        raise ImportFileError(f"{p}: file is empty")
    return b


def _rows7(a: np.ndarray, where: str, rates: bool, hint: str = "") -> Raw:
    """A (N, 7) PSINS array ``[gyro(3) accel(3) t]`` as a :class:`Raw`."""
    if a.shape[0] < 2:
        raise ImportFileError(f"{where}: {a.shape[0]} row(s); at least 2 samples are needed")
    a = np.asarray(a, dtype=float)
    kind = "rates" if rates else "increments"
    labels = (("wx", "wy", "wz", "fx", "fy", "fz") if rates else ("dthx", "dthy", "dthz", "dvx", "dvy", "dvz"))
    labels = tuple(f"{n} (column {k + 1})" for k, n in enumerate(labels))
    return Raw(a[:, 6].copy(), a[:, 0:3].copy(), a[:, 3:6].copy(), kind, None, labels, None, hint, a[:, :6],
               time_fix="the format holds seconds: divide its time column by {factor} before importing (or read the "
                        "rows as csv through a mapping with [units] time = \"{unit}\")")


def read_psins_bin(path, dtype: str = "float64", rates: bool = False) -> Raw:
    """PSINS raw binary: little-endian rows of 7 float64 (or float32) values."""
    p = FsPath(path)
    if dtype not in ("float64", "float32"):
        raise ImportFileError(f"--dtype must be float64 or float32, got {dtype!r}")
    b = _file_bytes(p)
    item = 8 if dtype == "float64" else 4
    row = 7 * item
    if len(b) % row:
        other = "float32" if dtype == "float64" else "float64"
        raise ImportFileError(f"{p}: {len(b)} bytes is not a whole number of 7-value {dtype} rows ({row} bytes each; "
                              f"truncated, or {other}?)")
    a = np.frombuffer(b, dtype="<f8" if item == 8 else "<f4").reshape(-1, 7)
    hint = ""
    if _plausible_rows(b, 12 - item):  # the other width reads as a clean time base: say so on time errors
        hint = " (is the file float32? try --dtype float32)" if dtype == "float64" else " (is the file float64? drop --dtype float32)"
    return _rows7(a, str(p), rates, hint)


def _numbers(p, line: str, n_line: int, what: str) -> list[float]:
    try:
        v = [float(x) for x in line.split()]
    except ValueError:
        raise ImportFileError(f"{p}: line {n_line} ({what}) is not numbers: {line.strip()[:60]!r}") from None
    if len(v) not in (6, 7) or not all(math.isfinite(x) for x in v):
        raise ImportFileError(f"{p}: line {n_line} ({what}) needs 6 (or 7) finite numbers, got {line.strip()[:60]!r}")
    return v


def read_psins_imu(path) -> Raw:
    """PSINS compact text SIMU log (``.imu``, as PSINS's ``imufile`` writes it): ``%`` comment lines,
    the first naming ``PSINS`` and ``SIMU``; three header rows, ``[pitch0 roll0 yaw0 (deg) VE0 VN0 VU0]``,
    ``[lat0 lon0 (deg) h0 (m) t0 (s) interval (ms) g (m/s^2)]`` and the scale factors
    ``[gyro x3 (arcsec per count), accel x3 (ug*s per count, ug = 1e-6 of the header's g)]``; then
    integer count rows ``[gx gy gz ax ay az (dither)]``.  Sample k (1-based) ends at
    ``t0 + k interval``, plus the running sum of the dither column (microseconds) when present.
    The header's site becomes the record's site unless one is given."""
    p = FsPath(path)
    b = _file_bytes(p)
    try:
        text = b.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8): a PSINS .imu log is text") from None
    lines = text.splitlines()
    first = next((ln for ln in lines if ln.strip()), "")
    if not (first.lstrip().startswith("%") and "PSINS" in first and "SIMU" in first):
        raise ImportFileError(f"{p}: not a PSINS .imu log (its first line must be the '% PSINS-format SIMU' comment)")
    rows = [(k + 1, ln) for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("%")]
    if len(rows) < 5:
        raise ImportFileError(f"{p}: a PSINS .imu log needs 3 header rows and at least 2 samples, "
                              f"found {len(rows)} non-comment rows (truncated?)")
    _numbers(p, rows[0][1], rows[0][0], "initial attitude and velocity")
    lat, lon, h, t0, ts_ms, g = _numbers(p, rows[1][1], rows[1][0], "site, t0, interval, g")[:6]
    scales = np.array(_numbers(p, rows[2][1], rows[2][0], "scale factors")[:6])
    if not (abs(lat) <= 90.0 and abs(lon) <= 360.0):
        raise ImportFileError(f"{p}: header latitude {lat:g} / longitude {lon:g} deg out of range")
    if not (ts_ms > 0):
        raise ImportFileError(f"{p}: header sampling interval {ts_ms:g} ms must be positive")
    lo, hi = 1e3 / MAX_RATE_HZ, 1e3 / MIN_RATE_HZ
    if not lo <= ts_ms <= hi:
        why = (f"it looks like seconds: write {ts_ms * 1e3:g} (ms)" if lo <= ts_ms * 1e3 <= hi else
               f"it looks like microseconds: write {ts_ms * 1e-3:g} (ms)" if lo <= ts_ms * 1e-3 <= hi else
               "wrong header row?")
        raise ImportFileError(f"{p}: line {rows[1][0]}: header sampling interval {ts_ms:g} ms ({1e3 / ts_ms:.6g} Hz) "
                              f"is no IMU's ({lo:g} .. {hi:g} ms; PSINS writes it in milliseconds): {why}")
    if not (9.7 < g < 9.9):
        raise ImportFileError(f"{p}: header gravity {g:g} m/s^2 is not a gravity value (9.7 .. 9.9)")
    like_sample = len(rows[2][1].split()) == len(rows[3][1].split()) and len(rows[2][1].split()) in (6, 7)
    if not np.all(scales > 0) or (like_sample and len(rows[2][1].split()) == 7):  # 7 values: a dithered sample
        raise ImportFileError(
            f"{p}: line {rows[2][0]}: " + ("the header's scale-factor row (the 3rd) is missing: this line is a sample "
                                           "row like the ones after it (6 or 7 counts); add the scale factors"
                                           if like_sample else
                                           f"header scale factors must be positive, got {scales.tolist()}"))
    body = rows[3:]
    ncol = len(body[0][1].split())
    if ncol not in (6, 7):
        raise ImportFileError(f"{p}: line {body[0][0]}: a sample row needs 6 counts (or 7 with the time dither), "
                              f"got {ncol}")
    try:
        a = np.loadtxt(StringIO("\n".join(ln for _, ln in body)), dtype=float, ndmin=2)
    except ValueError as exc:
        for n_line, ln in body:
            if len(ln.split()) != ncol:
                raise ImportFileError(f"{p}: line {n_line} has {len(ln.split())} values, the rows before {ncol} "
                                      "(truncated or edited file?)") from None
        raise ImportFileError(f"{p}: sample rows must be whole numbers of counts ({exc})") from None
    line_no = np.array([n for n, _ in body])
    if not np.all(np.isfinite(a)):
        k = int(np.argmax(~np.isfinite(a).all(axis=1)))
        raise ImportFileError(f"{p}: line {line_no[k]}: NaN/Inf in the counts")
    if np.any(a[:, :6] != np.round(a[:, :6])):
        k = int(np.argmax(np.any(a[:, :6] != np.round(a[:, :6]), axis=1)))
        raise ImportFileError(f"{p}: line {line_no[k]}: counts must be whole numbers (is it a PSINS .imu log?)")
    ts = ts_ms * 1e-3
    k = np.arange(1, a.shape[0] + 1)
    t = t0 + k * ts + (np.cumsum(a[:, 6]) * 1e-6 if ncol == 7 else 0.0)
    gyro = a[:, :3] * (scales[:3] * units.ARCSEC)
    accel = a[:, 3:6] * (scales[3:6] * 1e-6 * g)
    labels = tuple(f"{n} (counts)" for n in ("gx", "gy", "gz", "ax", "ay", "az"))
    return Raw(t, gyro, accel, "increments", None, labels, line_no, "", a[:, :6].copy(), (True, True),
               header_site=(lat, lon, h))


def _plausible_rows(b: bytes, item: int) -> bool:
    """Whether ``b`` read as 7-value rows of ``item``-byte floats has a finite, increasing, uniform time column."""
    if len(b) % (7 * item) or len(b) < 3 * 7 * item:
        return False
    with np.errstate(all="ignore"):
        t = np.frombuffer(b, dtype="<f8" if item == 8 else "<f4").reshape(-1, 7)[:, 6].astype(float)
        st = np.diff(t)
        med = np.median(st) if st.size else 0.0
        return bool(np.all(np.isfinite(t)) and med > 0 and np.all(np.abs(st - med) < 0.01 * med))


def _mat_variables(p: FsPath) -> list[tuple[str, np.ndarray]]:
    import scipy.io

    try:
        d = scipy.io.loadmat(str(p))
    except NotImplementedError:  # MATLAB v7.3 = HDF5, arrays stored transposed

        out = []
        with h5py.File(p, "r") as h5:
            for k, v in h5.items():
                if isinstance(v, h5py.Dataset) and not k.startswith("#"):
                    a = v[()]
                    out.append((k, a.T if np.ndim(a) == 2 else a))
        return out
    except Exception as exc:  # scipy raises assorted errors (ValueError, struct.error, ...) on files that are not MAT
        raise ImportFileError(f"{p}: not a readable MAT file ({type(exc).__name__}: {exc})") from None
    return [(k, v) for k, v in d.items() if not k.startswith("__")]


def _describe(a) -> str:
    a = np.asarray(a)
    return f"{'x'.join(map(str, a.shape))} {a.dtype}"


def read_mat(path, variable: str | None = None, rates: bool = False) -> Raw:
    """A MAT file: the first 2-D numeric variable with 7 columns, or ``variable``."""
    p = FsPath(path)
    _file_bytes(p)
    vars_ = _mat_variables(p)

    def usable(a) -> bool:
        return isinstance(a, np.ndarray) and a.ndim == 2 and a.shape[1] == 7 and a.dtype.kind in "fiu"

    if variable is not None:
        found = dict(vars_)
        if variable not in found:
            raise ImportFileError(f"{p}: no variable {variable!r}; variables: {', '.join(found) or 'none'}")
        a = found[variable]
        if not usable(a):
            raise ImportFileError(f"{p}: variable {variable!r} is {_describe(a)}; expected an N x 7 floating-point array")
        name = variable
    else:
        cand = [(k, v) for k, v in vars_ if usable(v)]
        if not cand:
            listing = ", ".join(f"{k} ({_describe(v)})" for k, v in vars_) or "none"
            raise ImportFileError(f"{p}: no 2-D numeric variable with 7 columns [dθ dv t]; variables: {listing}")
        name, a = cand[0]
    if a.dtype.kind in "iu":
        raise ImportFileError(f"{p}: variable {name!r} holds integers ({a.dtype}): PSINS rows are floating-point "
                              "rad, m/s and s (raw counts: export them as csv and import with a mapping)")
    return _rows7(a, f"{p} variable {name!r}", rates)


def _split(line: str, delim: str | None) -> list[str]:
    return line.split() if delim is None else [f.strip() for f in line.split(delim)]


def _column(p, names: list[str] | None, col, key: str) -> int:
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


def _parse_table(p: FsPath, m: Mapping, blank: dict | None = None,
                 names: list[str] | None = None) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """Data rows as floats, the file line of each row, and the header names (last header row, unless
    ``names`` gives them).  ``blank``: ``{column (index or header name): what it is for}`` of temperature
    columns, whose cells may be empty (NaN: no reading) and must otherwise be finite."""
    b = _file_bytes(p)
    if b"\x00" in b[:4096]:
        raise ImportFileError(f"{p}: not a text file (binary data)")
    try:
        text = b.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
    lines = text.splitlines()
    if len(lines) < m.header_rows:
        raise ImportFileError(f"{p}: {len(lines)} line(s), fewer than header_rows = {m.header_rows}")
    if names is None:
        names = _split(lines[m.header_rows - 1], m.delimiter) if m.header_rows else None
        if names is not None:
            names = [n.strip().strip('"').strip("'").strip() for n in names]
    body = [(k + 1, ln) for k, ln in enumerate(lines[m.header_rows:], start=m.header_rows)
            if ln.strip() and not ln.lstrip().startswith(m.comment)]
    if not body:
        raise ImportFileError(f"{p}: no data rows after the {m.header_rows} header row(s)")
    opt = {_column(p, names, c, key) for c, key in (blank or {}).items()}
    line_no = np.fromiter((k for k, _ in body), dtype=np.int64, count=len(body))
    first = _split(body[0][1], m.delimiter)
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
                tok = _split(body[k][1], m.delimiter)[c]
                raise ImportFileError(f"{p}: line {line_no[k]}, {col_name(c)}: {tok!r} is not a temperature "
                                      "reading (leave the cell empty where there is no reading)")
        return data, line_no, names
    if opt and (data := load({c: _reading for c in opt if c < ncol})) is not None:
        return data, line_no, names
    # slow path: find the first bad row and say what is wrong with it
    for k, ln in body:
        fields = _split(ln, m.delimiter)
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


def read_text(path, mapping: Mapping | None, fmt: str = "csv", rate_hz: float | None = None) -> Raw:
    """A delimited text file read through ``mapping`` (None: the inscal export layout); ``rate_hz``: the
    grid of ``kind = "sampled-rates"`` (default their mean rate)."""
    p = FsPath(path)
    given = mapping is not None
    if mapping is None:
        if fmt != "csv":
            raise ImportFileError(f"--format {fmt} needs --mapping M.toml (the columns and their units)")
        b = _file_bytes(p)
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
    data, line_no, names = _parse_table(p, m, {c: f"temperature sensor {n!r}" for n, c in m.temperature})
    ncol = data.shape[1]
    idx = {}
    keyed = [*m.columns.items(), *((f"temperature sensor {n!r}", c) for n, c in m.temperature)]
    for key, col in keyed:
        col = _column(p, names, col, key)
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
    b = _file_bytes(p)
    try:
        text = b.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
    lines = text.splitlines()
    k_head = next((k for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")), None)
    if k_head is None:
        raise ImportFileError(f"{p}: no temperature rows")
    head = lines[k_head]
    delim = "," if "," in head else None
    cells = []
    for tok in _split(head, delim):  # whitespace separated: "imu [degC]" is one cell
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
    data, line_no, _ = _parse_table(p, m, {c: f"temperature sensor {names[c - 1]!r}" for c in range(1, len(cells))},
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
    b = _file_bytes(p)
    try:
        text = b.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ImportFileError(f"{p}: no gimbal rows")
    delim = "," if "," in lines[0] else None
    try:
        float(_split(lines[0], delim)[0])
        header = 0
    except ValueError:
        header = 1
    in_file = header_angle_unit(p, lines[0]) if header else None
    t_unit = header_time_unit(p, lines[0]) if header else "s"
    if in_file is not None and unit is not None and units.to_si(1.0, in_file, "angle") != units.to_si(1.0, unit, "angle"):
        raise ImportFileError(f"{p}: the header says the angles are in {in_file}, --gimbal-unit says {unit}")
    u = in_file or unit or "deg"
    m = Mapping({}, delimiter=delim, header_rows=header)
    data, line_no, _ = _parse_table(p, m)
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


# ----------------------------------------------------------------------------- export
def write_rows(fh, a: np.ndarray, blanks: bool = False) -> None:
    """Rows of 17 significant digits; ``blanks``: NaN cells (no temperature reading) are left empty."""
    if not blanks:
        np.savetxt(fh, a, fmt="%.17g", delimiter=",")
        return
    buf = StringIO()
    np.savetxt(buf, a, fmt="%.17g", delimiter=",")
    fh.write(buf.getvalue().replace("nan", ""))  # "%.17g" writes no other "nan" than NaN's
