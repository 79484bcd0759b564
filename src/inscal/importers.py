"""Importing IMU data from other tools into an inscal record, and exporting records.

``inscal import`` converts once; every other command reads the HDF5 record (:mod:`inscal.io`).

Sources
-------
``psins``  raw binary (PSINS ``.bin``): little-endian float64 (default) or float32 rows of 7
           values ``[dθx dθy dθz dvx dvy dvz t]`` (rad, m/s, s), or with ``rates=True`` the
           rate form ``[wx wy wz fx fy fz t]`` (rad/s, m/s^2, s), multiplied by the sample
           interval.  ``t`` is the END time of each sample interval (PSINS convention and the
           record's).
``mat``    MATLAB ``.mat`` (v4-v7 via scipy.io, v7.3 via h5py) with the same 7-column rows:
           the first 2-D numeric variable with 7 columns, or the named ``variable``.
``csv``    delimited text described by a mapping TOML (below); without a mapping, the file
``txt``    must start with the header line that :func:`export_record` writes.  ``txt``
           defaults to whitespace-separated columns.

Mapping TOML (csv / txt; every key is checked, unknown keys are errors)::

    kind = "increments"            # default; or "rates" (then multiplied by the sample interval)
    delimiter = ","                # one character, or "whitespace"; default "," (csv), whitespace (txt)
    header_rows = 1                # default 0; lines before the data (names are read from the last one)
    comment = "#"                  # default; lines starting with it (and blank lines) are skipped
    axes = ["x", "y", "z"]         # IMU axis each file channel (1st, 2nd, 3rd) measures
    signs = [1, 1, 1]              # and its sign: imu[axes[i]] = signs[i] * file[i]
    [columns]                      # 0-based index or header name; time optional (then --rate-hz)
    time = 0
    gx = 1
    gy = 2
    gz = 3
    ax = 4
    ay = 5
    az = 6
    outer = 7                      # optional gimbal angle columns (both or neither)
    inner = 8
    [units]
    time = "s"                     # default; s | ms
    gyro = "deg"                   # required; increments: rad | deg | arcsec | urad; rates: rad/s | deg/s | deg/h
    accel = "m/s"                  # required; increments: m/s | mm/s; rates: m/s^2 | g | mg | ug
    # gyro = "counts"              # raw counts need a scale: "VALUE UNIT" (an angle unit for increments,
    # gyro_scale = "0.1 arcsec"    #   a rate unit for rates) or a number in SI (rad, rad/s per count)
    # accel = "counts"             #   likewise for the accelerometers (m/s or m/s^2 per count)
    # accel_scale = 1e-6
    gimbal = "deg"                 # deg | rad; required with the outer/inner columns
    [site]                         # optional; --lat/--lon/--height override it
    latitude_deg = 34.2
    longitude_deg = 108.9
    height_m = 400.0

For ``psins``/``mat`` a mapping may only hold ``[site]``.

Gimbal angles from encoders at another rate (``gimbal_file``: columns time, outer, inner;
an optional header line; comma or whitespace separated) are unwrapped and interpolated
linearly to the sample end times; they must cover the record.  Without encoders a rotation
path (a ``[path]`` table as in scenario files) is stored in the record; the record's time is
then shifted so that the path starts at 0 (``path_start``: the source time at which the path
starts, default the start of the first sample interval).

Checks (each refusal is one line): empty or header-only files, wrong column counts, text in
numbers, integer data, NaN/Inf, the time base (backwards steps, repeats, gaps, jitter, a rate
inconsistent with the timestamps), and the plausibility checks that ``skip`` may name:
``constant`` (a channel that never changes), ``saturation`` (a channel pinned at its extreme
while the others move), ``magnitudes`` (gravity and Earth rate judged from magnitudes: g vs
m/s^2, degrees vs radians, rates vs increments) and ``motion`` (the gyros must turn when the
gimbal angles / path say so, and only then).

Exports (:func:`export_record`): ``csv`` (one header line with units; time, dtheta, dvel and
the gimbal angles if recorded, ``%.17g`` so that importing gives back the same doubles),
``psins`` (float64 ``.bin`` rows ``[dθ dv t]``) and ``mat`` (variable ``imu``, N x 7); the
gimbal angles of a psins/mat export can go to a separate CSV that ``gimbal_file`` reads, and
the rotation path to a TOML that ``path_file`` reads.  The site is not exported: give it again
on import.

An imported record has no ``/truth``; its root attribute ``source`` (JSON) names the file, its
SHA-256, the format, the mapping / gimbal / path files, the checks skipped, whether the time
was regridded and the time offset subtracted (the path start).
"""

from __future__ import annotations

import json
import math
from .tomlfile import read_toml
from contextlib import ExitStack
from dataclasses import dataclass
from io import StringIO
from pathlib import Path as FsPath

import numpy as np

from . import earth, units
from .io import (DataFileError, Record, RecordInfo, atomic_path, file_hash, iter_chunks, record_info, validate_arrays,
                 write_stream)
from .simulate import Site
from .turntable import BUILTIN_PATHS, Path, PathError

FORMATS = ("psins", "csv", "txt", "mat")
EXPORT_FORMATS = ("csv", "psins", "mat")
CHECKS = ("constant", "saturation", "magnitudes", "motion")
CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")
DEG = math.pi / 180.0

#: the header line :func:`export_record` writes (csv); a csv without a mapping must start with it
EXPORT_HEADER = ["time [s]", "dtheta_x [rad]", "dtheta_y [rad]", "dtheta_z [rad]",
                 "dvel_x [m/s]", "dvel_y [m/s]", "dvel_z [m/s]"]
EXPORT_HEADER_GIMBAL = ["outer [rad]", "inner [rad]"]
GIMBAL_HEADER = ["time [s]", "outer [rad]", "inner [rad]"]

#: timestamps must be uniform to this fraction of the step unless a rate is given
JITTER_TOL = 1e-6
#: with a given rate, steps may deviate by this fraction of the interval (they are regridded)
REGRID_TOL = 0.1


class ImportFileError(DataFileError):
    """A source file that cannot be imported, with the reason (one line)."""


# ----------------------------------------------------------------------------- mapping
@dataclass(frozen=True)
class Mapping:
    """How to read a delimited text file (SI conversions come from :mod:`inscal.units`)."""

    columns: dict
    kind: str = "increments"
    time_unit: str = "s"
    gyro_unit: str = "rad"
    accel_unit: str = "m/s"
    gyro_scale: float | None = None
    accel_scale: float | None = None
    gimbal_unit: str = "rad"
    axes: tuple = (0, 1, 2)
    signs: tuple = (1.0, 1.0, 1.0)
    delimiter: str | None = ","
    header_rows: int = 0
    comment: str = "#"


_TOP = {"kind", "delimiter", "header_rows", "comment", "axes", "signs", "columns", "units", "site"}
_COLS = {"time", "gx", "gy", "gz", "ax", "ay", "az", "outer", "inner"}
_UNITS = {"time", "gyro", "accel", "gyro_scale", "accel_scale", "gimbal"}
_SITE = {"latitude_deg", "longitude_deg", "height_m"}


def _keys(where: str, d, allowed: set) -> None:
    if not isinstance(d, dict):
        raise ImportFileError(f"{where} must be a table")
    unknown = set(d) - allowed
    if unknown:
        raise ImportFileError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")


def _scale(value, unit_kind: str, name: str) -> float:
    """A counts scale: a number in SI, or "VALUE UNIT" in a unit of ``unit_kind``."""
    if isinstance(value, bool):
        raise ImportFileError(f"[units] {name} must be a number or \"VALUE UNIT\", got {value!r}")
    if isinstance(value, (int, float)):
        s = float(value)
    elif isinstance(value, str):
        parts = value.split(None, 1)
        try:
            s = float(units.to_si(float(parts[0]), parts[1], unit_kind))
        except (IndexError, ValueError) as exc:  # UnitError is a ValueError
            raise ImportFileError(f"[units] {name} = {value!r}: expected \"VALUE UNIT\" with a {unit_kind} unit ({exc})") from None
    else:
        raise ImportFileError(f"[units] {name} must be a number or \"VALUE UNIT\", got {value!r}")
    if not (math.isfinite(s) and s != 0):
        raise ImportFileError(f"[units] {name} must be finite and non-zero, got {value!r}")
    return s


def parse_mapping(d: dict, fmt: str) -> tuple[Mapping | None, Site | None]:
    """Check a mapping document; returns ``(mapping or None, site or None)``."""
    _keys("mapping", d, _TOP)
    site = None
    if "site" in d:
        s = d["site"]
        _keys("[site]", s, _SITE)
        missing = _SITE - set(s)
        if missing:
            raise ImportFileError(f"[site] needs {sorted(_SITE)}; missing {sorted(missing)}")
        try:
            site = Site(float(s["latitude_deg"]) * DEG, float(s["longitude_deg"]) * DEG, float(s["height_m"]))
        except (TypeError, ValueError) as exc:
            raise ImportFileError(f"[site]: {exc}") from None
    rest = set(d) - {"site"}
    if fmt in ("psins", "mat"):
        if rest:
            raise ImportFileError(f"mapping key(s) {sorted(rest)} apply to --format csv|txt; a {fmt} mapping may only hold [site]")
        return None, site
    if "columns" not in d:
        raise ImportFileError("mapping needs a [columns] table (gx, gy, gz, ax, ay, az, and time)")
    kind = d.get("kind", "increments")
    if kind not in ("increments", "rates"):
        raise ImportFileError(f"kind must be \"increments\" or \"rates\", got {kind!r}")
    cols = d["columns"]
    _keys("[columns]", cols, _COLS)
    missing = [c for c in CHANNELS if c not in cols]
    if missing:
        raise ImportFileError(f"[columns] needs {list(CHANNELS)}; missing {missing}")
    if ("outer" in cols) != ("inner" in cols):
        raise ImportFileError("[columns] outer and inner go together (both or neither)")
    for k, v in cols.items():
        if isinstance(v, bool) or not isinstance(v, (int, str)) or (isinstance(v, int) and v < 0):
            raise ImportFileError(f"[columns] {k} must be a 0-based column index or a header name, got {v!r}")
    seen = {}
    for k, v in cols.items():
        if v in seen:
            raise ImportFileError(f"[columns] {seen[v]} and {k} both read column {v!r}")
        seen[v] = k
    u = d.get("units", {})
    _keys("[units]", u, _UNITS)
    for k in ("gyro", "accel"):
        if k not in u:
            raise ImportFileError(f"[units] needs {k} (e.g. gyro = \"deg\", accel = \"m/s\" for increments)")
    inc = kind == "increments"
    gk, ak = ("angle", "velocity") if inc else ("rate", "accel")
    conv = {}
    for k, uk in (("gyro", gk), ("accel", ak)):
        unit = u[k]
        if not isinstance(unit, str):
            raise ImportFileError(f"[units] {k} must be a string, got {unit!r}")
        if unit == "counts":
            if f"{k}_scale" not in u:
                raise ImportFileError(f"[units] {k} = \"counts\" needs {k}_scale (value of one count)")
            conv[k] = ("counts", _scale(u[f"{k}_scale"], uk, f"{k}_scale"))
        else:
            if f"{k}_scale" in u:
                raise ImportFileError(f"[units] {k}_scale applies to {k} = \"counts\" only")
            try:
                conv[k] = (units.check_kind(unit, uk), None)
            except units.UnitError as exc:
                raise ImportFileError(f"[units] {k}: {exc} (kind = {kind!r})") from None
    try:
        tu = units.check_kind(str(u.get("time", "s")), "time")
        gu = units.check_kind(str(u.get("gimbal", "rad")), "angle")
    except units.UnitError as exc:
        raise ImportFileError(f"[units]: {exc}") from None
    if "outer" in cols and "gimbal" not in u:
        raise ImportFileError("[units] needs gimbal = \"deg\" or \"rad\" with the outer/inner columns")
    axes = d.get("axes", ["x", "y", "z"])
    if not (isinstance(axes, list) and sorted(map(str, axes)) == ["x", "y", "z"]):
        raise ImportFileError(f"axes must be a permutation of [\"x\", \"y\", \"z\"], got {axes!r}")
    signs = d.get("signs", [1, 1, 1])
    if not (isinstance(signs, list) and len(signs) == 3 and all(s in (1, -1) and not isinstance(s, bool) for s in signs)):
        raise ImportFileError(f"signs must be three of 1 / -1, got {signs!r}")
    delim = d.get("delimiter", "," if fmt == "csv" else "whitespace")
    if not isinstance(delim, str) or not (delim == "whitespace" or len(delim) == 1):
        raise ImportFileError(f"delimiter must be one character or \"whitespace\", got {delim!r}")
    hr = d.get("header_rows", 0)
    if isinstance(hr, bool) or not isinstance(hr, int) or hr < 0:
        raise ImportFileError(f"header_rows must be an integer >= 0, got {hr!r}")
    if hr == 0 and any(isinstance(v, str) for v in cols.values()):
        raise ImportFileError("columns given by name need header_rows >= 1")
    comment = d.get("comment", "#")
    if not isinstance(comment, str) or len(comment) != 1:
        raise ImportFileError(f"comment must be one character, got {comment!r}")
    m = Mapping(dict(cols), kind, tu, conv["gyro"][0], conv["accel"][0], conv["gyro"][1], conv["accel"][1], gu,
                tuple("xyz".index(a) for a in axes), tuple(float(s) for s in signs),
                None if delim == "whitespace" else delim, hr, comment)
    return m, site


def load_mapping(path, fmt: str) -> tuple[Mapping | None, Site | None]:
    p = FsPath(path)
    d = read_toml(p, ImportFileError, "mapping file")
    try:
        return parse_mapping(d, fmt)
    except ImportFileError as exc:
        raise ImportFileError(f"{p}: {exc}") from None


def default_mapping(gimbal: bool) -> Mapping:
    """The mapping of a csv written by :func:`export_record`."""
    cols = {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6}
    if gimbal:
        cols.update(outer=7, inner=8)
    return Mapping(cols, "increments", "s", "rad", "m/s", None, None, "rad", (0, 1, 2), (1.0, 1.0, 1.0), ",", 1, "#")


def load_path(path) -> Path:
    """A rotation path from a TOML file holding one ``[path]`` table (as in scenario files)."""
    p = FsPath(path)
    d = read_toml(p, ImportFileError, "path file")
    if set(d) - {"path"} or "path" not in d:
        raise ImportFileError(f"{p}: a path file holds one [path] table, got key(s) {sorted(d)}")
    pd = dict(d["path"]) if isinstance(d["path"], dict) else None
    if pd is None:
        raise ImportFileError(f"{p}: [path] must be a table")
    try:
        if "builtin" in pd:
            name = pd.pop("builtin")
            if name not in BUILTIN_PATHS or name in ("static", "rotmod16"):
                known = sorted(set(BUILTIN_PATHS) - {"static", "rotmod16"})
                raise ImportFileError(f"{p}: [path] builtin {name!r} is not a fixed path; known: {known}")
            if pd:
                raise ImportFileError(f"{p}: [path] with builtin takes no other keys, got {sorted(pd)}")
            return BUILTIN_PATHS[name]()
        return Path.from_dict(pd)
    except (PathError, TypeError, ValueError) as exc:
        if isinstance(exc, ImportFileError):
            raise
        raise ImportFileError(f"{p}: [path]: {exc}") from None


# ----------------------------------------------------------------------------- raw sources
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

    def at(self, i: int) -> str:
        return f"line {int(self.lines[i])}" if self.lines is not None else f"row {i + 1}"


def _file_bytes(p: FsPath) -> bytes:
    if not p.is_file():
        raise ImportFileError(f"{p}: no such file")
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
    return Raw(a[:, 6].copy(), a[:, 0:3].copy(), a[:, 3:6].copy(), kind, None, labels, None, hint, a[:, :6])


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
        import h5py

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


def _parse_table(p: FsPath, m: Mapping) -> tuple[np.ndarray, np.ndarray, list[str] | None]:
    """Data rows as floats, the file line of each row, and the header names (last header row)."""
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
    names = _split(lines[m.header_rows - 1], m.delimiter) if m.header_rows else None
    if names is not None:
        names = [n.strip().strip('"').strip("'").strip() for n in names]
    body = [(k + 1, ln) for k, ln in enumerate(lines[m.header_rows:], start=m.header_rows)
            if ln.strip() and not ln.lstrip().startswith(m.comment)]
    if not body:
        raise ImportFileError(f"{p}: no data rows after the {m.header_rows} header row(s)")
    line_no = np.fromiter((k for k, _ in body), dtype=np.int64, count=len(body))
    try:
        data = np.loadtxt(StringIO("\n".join(ln for _, ln in body)), delimiter=m.delimiter, comments=None,
                          dtype=float, ndmin=2)
        if data.shape[0] == len(body):
            return data, line_no, names
    except ValueError:
        pass
    # slow path: find the first bad row and say what is wrong with it
    first = _split(body[0][1], m.delimiter)
    ncol = len(first)
    for k, ln in body:
        fields = _split(ln, m.delimiter)
        if len(fields) != ncol:
            raise ImportFileError(f"{p}: line {k} has {len(fields)} field(s), expected {ncol} (as on line {body[0][0]})")
        for c, tok in enumerate(fields):
            try:
                float(tok)
            except ValueError:
                what = f"{tok!r} is not a number" if tok else "empty field"
                col = f"column {c}" + (f" ({names[c]!r})" if names and c < len(names) else "")
                hint = ("; a header line? set header_rows" if m.columns and k == body[0][0] and m.header_rows == 0
                        else "")
                raise ImportFileError(f"{p}: line {k}, {col}: {what}{hint}") from None
    raise ImportFileError(f"{p}: cannot parse the data rows")  # pragma: no cover - loadtxt and the scan disagree


def read_text(path, mapping: Mapping | None, fmt: str = "csv") -> Raw:
    """A delimited text file read through ``mapping`` (None: the inscal export layout)."""
    p = FsPath(path)
    if mapping is None:
        if fmt != "csv":
            raise ImportFileError(f"--format {fmt} needs --mapping M.toml (the columns and their units)")
        b = _file_bytes(p)
        try:
            head = b.decode("utf-8-sig").splitlines()[0] if b else ""
        except UnicodeDecodeError:
            raise ImportFileError(f"{p}: not a text file (not UTF-8)") from None
        names = [n.strip() for n in head.split(",")]
        if names == EXPORT_HEADER:
            mapping = default_mapping(False)
        elif names == EXPORT_HEADER + EXPORT_HEADER_GIMBAL:
            mapping = default_mapping(True)
        else:
            raise ImportFileError(f"{p}: the first line is not the inscal export header ({','.join(EXPORT_HEADER)}); "
                                  "give --mapping M.toml")
    m = mapping
    data, line_no, names = _parse_table(p, m)
    ncol = data.shape[1]
    idx = {}
    for key, col in m.columns.items():
        if isinstance(col, str):
            hits = [k for k, n in enumerate(names) if n == col] or [k for k, n in enumerate(names) if n.lower() == col.lower()]
            if len(hits) != 1:
                what = "no column" if not hits else f"{len(hits)} columns"
                raise ImportFileError(f"{p}: {what} named {col!r} (for {key}); header: {names}")
            col = hits[0]
        if col >= ncol:
            raise ImportFileError(f"{p}: column index {col} (for {key}) is out of range: rows have {ncol} columns "
                                  f"(indexes 0-{ncol - 1})")
        idx[key] = col
    if data.shape[0] < 2:
        raise ImportFileError(f"{p}: {data.shape[0]} data row(s); at least 2 samples are needed")
    raw6 = data[:, [idx[c] for c in CHANNELS]]
    inc = m.kind == "increments"

    def conv(x, unit, scale, kind):
        return x * scale if unit == "counts" else units.to_si(x, unit, kind)

    g = conv(raw6[:, 0:3], m.gyro_unit, m.gyro_scale, "angle" if inc else "rate")
    a = conv(raw6[:, 3:6], m.accel_unit, m.accel_scale, "velocity" if inc else "accel")
    gyro = np.empty_like(g)
    accel = np.empty_like(a)
    for i in range(3):
        gyro[:, m.axes[i]] = m.signs[i] * g[:, i]
        accel[:, m.axes[i]] = m.signs[i] * a[:, i]
    t = units.to_si(data[:, idx["time"]], m.time_unit, "time") if "time" in idx else None
    gim = units.to_si(data[:, [idx["outer"], idx["inner"]]], m.gimbal_unit, "angle") if "outer" in idx else None
    labels = tuple(f"{c} (column {idx[c]}" + (f" {names[idx[c]]!r})" if names and idx[c] < len(names) else ")")
                   for c in CHANNELS)
    counts = (m.gyro_unit == "counts", m.accel_unit == "counts")
    tl = f"time (column {idx['time']})" if "time" in idx else "time"
    return Raw(t, gyro, accel, m.kind, gim, labels, line_no, "", raw6, counts, tl)


def read_gimbal_file(path, unit: str = "deg") -> tuple[np.ndarray, np.ndarray]:
    """Encoder angles: rows ``time [s], outer, inner`` in ``unit`` -> ``(t, angles [rad] (M, 2))``, unwrapped."""
    p = FsPath(path)
    try:
        u = units.check_kind(unit, "angle")
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
    t = data[:, 0]
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
    ang = np.unwrap(units.to_si(data[:, 1:3], u, "angle"), axis=0)
    return t, ang


# ----------------------------------------------------------------------------- checks
def _check_finite(raw: Raw, where: str) -> None:
    chans = [(raw.time_label, raw.time)] if raw.time is not None else []
    chans += [(raw.labels[k], raw.raw_channels[:, k]) for k in range(6)]
    if raw.gimbal is not None:
        chans += [("outer angle", raw.gimbal[:, 0]), ("inner angle", raw.gimbal[:, 1])]
    for name, x in chans:
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.argmax(bad))
            raise ImportFileError(f"{where}: {name} has {int(bad.sum())} NaN/Inf value(s), first at {raw.at(k)}{raw.hint}")


def _check_integers(raw: Raw, where: str) -> None:
    for k in range(6):
        if raw.counts[k // 3]:
            continue
        x = raw.raw_channels[:, k]
        if np.ptp(x) > 0 and np.all(x == np.round(x)):
            which = "gyro" if k < 3 else "accel"
            raise ImportFileError(f"{where}: {raw.labels[k]} holds only whole numbers (e.g. {x[np.argmax(x != 0)]:g}): "
                                  f"integer data (raw counts? import them as csv/txt with {which} = \"counts\" and "
                                  f"{which}_scale in the mapping)")


def time_base(raw: Raw, n: int, rate_hz: float | None, where: str) -> tuple[np.ndarray, float, dict]:
    """Check the timestamps and return ``(time [s], rate [Hz], info)``."""
    info: dict = {"regridded": False}
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ImportFileError(f"--rate-hz must be positive, got {rate_hz:g}")
    if raw.time is None:
        if rate_hz is None:
            raise ImportFileError(f"{where}: no time column; give --rate-hz (samples are then taken as uniform)")
        info["time_column"] = False
        return (np.arange(n) + 1.0) / rate_hz, float(rate_hz), info
    t = raw.time
    name = raw.time_label
    st = np.diff(t)
    back = np.flatnonzero(st < 0)
    if back.size:
        k = int(back[0])
        raise ImportFileError(f"{where}: {name} goes backwards at {raw.at(k + 1)} (t = {t[k + 1]:.9g} s after "
                              f"{t[k]:.9g} s; {back.size} backward step(s)){raw.hint}")
    rep = np.flatnonzero(st == 0)
    if rep.size:
        k = int(rep[0])
        raise ImportFileError(f"{where}: {name} repeats at {raw.at(k + 1)} (t = {t[k]:.9g} s twice; "
                              f"{rep.size} repeated timestamp(s)){raw.hint}")
    med = float(np.median(st))
    gaps = np.flatnonzero(st > 1.5 * med)
    if gaps.size:
        k = int(gaps[np.argmax(st[gaps])])
        raise ImportFileError(
            f"{where}: {name} has {gaps.size} gap(s) over 1.5 sample intervals; the largest is {st[k]:.6g} s "
            f"(about {int(round(st[k] / med)) - 1} missing sample(s)) at {raw.at(k + 1)} (t = {t[k]:.9g} -> "
            f"{t[k + 1]:.9g} s){raw.hint}")
    dt_est = float((t[-1] - t[0]) / (n - 1))
    info["largest_step_s"] = float(st.max())
    jitter = float(np.max(np.abs(st - dt_est)) / dt_est)
    info["jitter"] = jitter
    if rate_hz is None:
        if jitter > JITTER_TOL:
            k = int(np.argmax(np.abs(st - dt_est)))
            raise ImportFileError(
                f"{where}: {name} is not uniform: steps vary by up to {jitter:.3g} of the {dt_est:.6g} s interval "
                f"(limit {JITTER_TOL:g}; worst at {raw.at(k + 1)}, t = {t[k + 1]:.9g} s); if the timestamps are "
                f"only quantised, give --rate-hz to rebuild a uniform time base{raw.hint}")
        r = 1.0 / dt_est
        for d in range(0, 7):  # a rate written with few digits (e.g. 100, 200.5) is taken as exact
            rr = round(r, d)
            if abs(rr - r) <= 1e-9 * r:
                r = rr
                break
        return t, float(r), info
    nominal = 1.0 / rate_hz
    if abs(med / nominal - 1.0) > 1e-3 or abs(dt_est / nominal - 1.0) > 1e-4:
        raise ImportFileError(
            f"{where}: --rate-hz {rate_hz:g} is inconsistent with the timestamps: {1.0 / dt_est:.9g} Hz from the first "
            f"to the last sample (median step {med:.6g} s){raw.hint}")
    if jitter <= JITTER_TOL:
        return t, float(rate_hz), info
    if jitter > REGRID_TOL:
        k = int(np.argmax(np.abs(st - dt_est)))
        raise ImportFileError(f"{where}: {name} is irregular: steps vary by up to {jitter:.3g} of the sample interval "
                              f"(limit {REGRID_TOL:g} with --rate-hz; worst at {raw.at(k + 1)}){raw.hint}")
    k = np.arange(n)
    t0 = float(np.mean(t - k * nominal))
    info["regridded"] = True
    return t0 + k * nominal, float(rate_hz), info


def _check_constant(raw: Raw, where: str) -> None:
    for k in range(6):
        x = raw.raw_channels[:, k]
        if np.ptp(x) == 0:
            raise ImportFileError(f"{where}: {raw.labels[k]} is constant ({x[0]:g}) over all {x.size} samples: "
                                  "a dead or disconnected channel (--skip-check constant to import anyway)")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _check_saturation(raw: Raw, where: str, min_run: int = 5, rel: float = 1e-7, noisy: float = 0.9) -> None:
    """A noisy channel pinned at its maximum or minimum for ``min_run`` samples while another channel moves.

    Only channels that change on at least ``noisy`` of their other samples are judged: in
    noise-free or coarsely quantised data repeated values are normal (a constant-rate turn
    reads the same on every sample)."""
    x6 = raw.raw_channels
    span = np.ptp(x6, axis=0)
    for k in range(6):
        x = x6[:, k]
        if span[k] == 0:  # constant: the constant check's business
            continue
        for lim, word in ((x.max(), "maximum"), (x.min(), "minimum")):
            at = x == lim
            if at.sum() < min_run:
                continue
            for a, b in _runs(at):
                if b - a < min_run:
                    continue
                same = np.delete(np.diff(x) == 0, np.arange(a, b - 1))
                if same.size == 0 or np.mean(same) > 1 - noisy:
                    continue
                others = np.delete(x6[a:b], k, axis=1)
                if np.any(np.ptp(others, axis=0) > rel * np.delete(span, k)):
                    raise ImportFileError(
                        f"{where}: {raw.labels[k]} looks saturated: pinned at its {word} {lim:g} for {b - a} samples from "
                        f"{raw.at(a)} while the other channels change (--skip-check saturation to import anyway)")


def _blocks(x: np.ndarray, m: int) -> np.ndarray:
    nb = x.shape[0] // m
    return x[: nb * m].reshape(nb, m, -1).sum(axis=1)


def _check_magnitudes(dth: np.ndarray, dv: np.ndarray, rate_hz: float, site: Site, where: str, kind: str,
                      gyro_unit: str, accel_unit: str) -> None:
    """Gravity and Earth rate judged from magnitudes (unit mix-ups give factors far from 1)."""
    dt = 1.0 / rate_hz
    m = max(1, min(dth.shape[0], int(round(rate_hz))))
    T = m * dt
    f = np.linalg.norm(_blocks(dv, m), axis=1) / T
    w = np.linalg.norm(_blocks(dth, m), axis=1) / T
    g = site.gravity
    ratio = float(np.median(f)) / g
    if not 0.8 < ratio < 1.2:
        guesses = [("g, not m/s^2 (accel unit)", 1.0 / units.G0), ("m/s^2, not g (accel unit)", units.G0),
                   ("rates, not increments", rate_hz), ("increments, not rates", 1.0 / rate_hz),
                   ("mg, not m/s^2", 1e3 / units.G0)]
        why = [s for s, fac in guesses if 0.8 < ratio / fac < 1.2]
        hint = f": the values look like {' or '.join(why)}" if why else ": wrong unit or scale?"
        raise ImportFileError(
            f"{where}: accelerometers read {ratio * g:.6g} m/s^2 (median magnitude, as {kind} in {accel_unit}), "
            f"not gravity {g:.4g} m/s^2{hint} (--skip-check magnitudes to import anyway)")
    p5 = float(np.percentile(w, 5))
    om = earth.OMEGA_IE
    if om * 57.29577951 / 3 < p5 < om * 57.29577951 * 3:
        look = "degrees, not radians"
    elif om / 57.29577951 / 3 < p5 < om / 57.29577951 * 3:
        look = "radians, not degrees"
    elif om * 206264.8 / 3 < p5 < om * 206264.8 * 3:
        look = "arcsec, not radians"
    else:
        return
    raise ImportFileError(
        f"{where}: gyros read at least {p5:.4g} rad/s ({p5 / DEG * 3600:.4g} deg/h, 5th percentile of 1-s means, "
        f"as {kind} in {gyro_unit}) where the Earth rate is {om / DEG * 3600:.4g} deg/h: the values look like {look} "
        "(--skip-check magnitudes to import anyway)")


def check_motion(dtheta: np.ndarray, theta: np.ndarray, dt: float, what: str, time: np.ndarray,
                 block_s: float = 0.5, max_fraction: float = 0.005) -> None:
    """The gyros must turn where the gimbal angles ``theta`` (N, 2) turn, and rest where they rest.

    Half-second blocks are compared where the gimbal is clearly static (< 0.02 deg/s) or clearly
    turning at a steady rate (> 1 deg/s) in the block and both neighbours; more than
    ``max_fraction`` of such blocks disagreeing (gyro > 0.5 deg/s at rest, or a turn rate off
    by 20 %) means the angles are not aligned with the increments.
    """
    n = dtheta.shape[0]
    m = max(1, int(round(block_s / dt)))
    nb = n // m
    if nb < 4:
        return
    T = m * dt
    ends = theta[np.arange(nb) * m + m - 1]  # angle at the end of each block
    wg = np.full(nb, np.nan)
    wg[1:] = np.linalg.norm(np.diff(ends, axis=0), axis=1) / T
    wm = np.linalg.norm(_blocks(dtheta, m), axis=1) / T
    static = wg < 0.02 * DEG
    moving = wg > 1.0 * DEG
    cs = static[1:-1] & static[:-2] & static[2:]
    steady = (np.abs(wg[:-2] - wg[1:-1]) < 0.1 * wg[1:-1]) & (np.abs(wg[2:] - wg[1:-1]) < 0.1 * wg[1:-1])
    cm = moving[1:-1] & moving[:-2] & moving[2:] & steady
    bad_s = cs & (wm[1:-1] > 0.5 * DEG)
    bad_m = cm & (np.abs(wm[1:-1] - wg[1:-1]) > 0.2 * wg[1:-1])
    bad = bad_s | bad_m
    clean = int(cs.sum() + cm.sum())
    if clean and bad.sum() > max(2, max_fraction * clean):
        b = int(np.argmax(bad)) + 1
        t = time[b * m + m - 1]
        state = "at rest" if static[b] else f"turning at {wg[b] / DEG:.3g} deg/s"
        raise ImportFileError(
            f"the increments do not follow the {what}: {int(bad.sum())} of {clean} half-second blocks disagree "
            f"(first ending at t = {t:.3f} s: {what} {state}, gyros {wm[b] / DEG:.3g} deg/s) "
            "(--skip-check motion to import anyway)")


# ----------------------------------------------------------------------------- import
def read_source(src, fmt: str, mapping: Mapping | None = None, dtype: str = "float64", variable: str | None = None,
                rates: bool = False) -> Raw:
    """Read ``src`` in ``fmt`` (see the module docstring) into a :class:`Raw`."""
    if fmt not in FORMATS:
        raise ImportFileError(f"unknown format {fmt!r}; choose one of: {', '.join(FORMATS)}")
    p = FsPath(src)
    if fmt == "psins":
        return read_mat(p, variable, rates) if p.suffix.lower() == ".mat" else read_psins_bin(p, dtype, rates)
    if fmt == "mat":
        return read_mat(p, variable, rates)
    return read_text(p, mapping, fmt)


def build_record(raw: Raw, site: Site, where: str, rate_hz: float | None = None, path: Path | None = None,
                 path_start: float | None = None, gimbal: tuple[np.ndarray, np.ndarray] | None = None,
                 skip=(), units_desc: tuple[str, str] = ("rad", "m/s"),
                 gimbal_name: str = "gimbal angles") -> tuple[Record, dict]:
    """Check ``raw`` and turn it into a :class:`~inscal.io.Record` (SI increments).  Returns
    ``(record, info)``; raises :class:`ImportFileError` with one line on any problem."""
    unknown = set(skip) - set(CHECKS)
    if unknown:
        raise ImportFileError(f"unknown check(s) {sorted(unknown)} to skip; known: {', '.join(CHECKS)}")
    n = raw.gyro.shape[0]
    _check_finite(raw, where)
    _check_integers(raw, where)
    time, rate, info = time_base(raw, n, rate_hz, where)
    dt = 1.0 / rate
    if "constant" not in skip:
        _check_constant(raw, where)
    if "saturation" not in skip:
        _check_saturation(raw, where)
    if raw.kind == "rates":
        dth, dv = raw.gyro * dt, raw.accel * dt
    else:
        dth, dv = raw.gyro, raw.accel
    if "magnitudes" not in skip:
        _check_magnitudes(dth, dv, rate, site, where, raw.kind, *units_desc)
    gim = raw.gimbal
    if gimbal is not None:
        if gim is not None:
            raise ImportFileError(f"{where} has gimbal angle columns; --gimbal would give them twice")
        tg, ag = gimbal
        if tg[0] > time[0] + 1e-9 * dt or tg[-1] < time[-1] - 1e-9 * dt:
            raise ImportFileError(f"{gimbal_name}: the angles cover t = {tg[0]:.9g} .. {tg[-1]:.9g} s; the record needs "
                                  f"t = {time[0]:.9g} .. {time[-1]:.9g} s (the sample end times)")
        gim = np.column_stack([np.interp(time, tg, ag[:, 0]), np.interp(time, tg, ag[:, 1])])
        info["gimbal"] = "file"
    elif gim is not None:
        gim = np.unwrap(gim, axis=0)
        info["gimbal"] = "columns"
    else:
        info["gimbal"] = None
    if gim is not None and "motion" not in skip:
        check_motion(dth, gim, dt, "gimbal angles", time)
    if path is not None:
        start = time[0] - dt if path_start is None else float(path_start)
        if not math.isfinite(start):
            raise ImportFileError(f"--path-start-s must be finite, got {start}")
        if time[0] - dt < start - 1e-6 * dt:
            raise ImportFileError(f"the record starts at t = {time[0] - dt:.9g} s, before the path start {start:.9g} s")
        span = time[-1] - start
        if span > path.duration + 1e-6 * dt:
            raise ImportFileError(f"path {path.name!r} lasts {path.duration:.6g} s, but the record runs {span:.6g} s "
                                  f"from the path start (t = {start:.9g} s): wrong path or --path-start-s?")
        time = time - start if start != 0.0 else time
        info["path_start_s"] = float(start)
        if gim is None and "motion" not in skip:
            theta, _, _ = path.segments().angles(time)
            check_motion(dth, theta, dt, f"path {path.name!r}", time)
    rec = Record(np.ascontiguousarray(time, float), np.ascontiguousarray(dth, float), np.ascontiguousarray(dv, float),
                 None if gim is None else np.ascontiguousarray(gim, float), rate, site, path, None, "", where)
    try:
        validate_arrays(rec.time, rec.dtheta, rec.dvel, rec.gimbal, rec.rate_hz, where=where)
    except DataFileError as exc:
        raise ImportFileError(str(exc)) from None
    return rec, info


def write_imported(out, rec: Record, source_attrs: dict, overwrite: bool = False) -> int:
    """Write an imported record atomically (the source is kept as a JSON attribute ``source``)."""
    info = RecordInfo(rec.n_samples, rec.rate_hz, rec.site, rec.path, None, rec.scenario, rec.gimbal is not None)
    return write_stream(out, info, [(rec.time, rec.dtheta, rec.dvel, rec.gimbal)], overwrite,
                        extra_attrs={"source": json.dumps(source_attrs)})


def import_file(src, out, fmt: str, site: Site | None = None, mapping_file=None, path_file=None,
                path_start: float | None = None, gimbal_file=None, gimbal_unit: str = "deg",
                rate_hz: float | None = None, dtype: str = "float64", variable: str | None = None,
                rates: bool = False, skip=(), overwrite: bool = False) -> dict:
    """Convert ``src`` into the record ``out`` (see the module docstring); returns a summary."""
    src = FsPath(src)
    if fmt not in FORMATS:
        raise ImportFileError(f"unknown format {fmt!r}; choose one of: {', '.join(FORMATS)}")
    if dtype != "float64" and fmt != "psins":
        raise ImportFileError("--dtype applies to --format psins (.bin)")
    if variable is not None and fmt not in ("psins", "mat"):
        raise ImportFileError("--variable applies to .mat files")
    if rates and fmt in ("csv", "txt"):
        raise ImportFileError("--rates applies to psins/mat; for csv/txt set kind = \"rates\" in the mapping")
    if path_start is not None and path_file is None:
        raise ImportFileError("--path-start-s applies with --path")
    mapping, msite = load_mapping(mapping_file, fmt) if mapping_file is not None else (None, None)
    site = site if site is not None else msite
    if site is None:
        raise ImportFileError("no site: give --lat, --lon and --height (or a [site] table in the mapping)")
    path = load_path(path_file) if path_file is not None else None
    gim = read_gimbal_file(gimbal_file, gimbal_unit) if gimbal_file is not None else None
    raw = read_source(src, fmt, mapping, dtype, variable, rates)
    if mapping is not None:
        ud = (mapping.gyro_unit, mapping.accel_unit)
    else:
        ud = ("rad/s", "m/s^2") if raw.kind == "rates" else ("rad", "m/s")
    rec, info = build_record(raw, site, str(src), rate_hz, path, path_start, gim, skip, ud, str(gimbal_file))
    attrs = {"file": src.name, "hash": file_hash(src), "format": fmt,
             "mapping": None if mapping_file is None else str(mapping_file),
             "gimbal_file": None if gimbal_file is None else str(gimbal_file),
             "path_file": None if path_file is None else str(path_file),
             "skipped_checks": sorted(skip), "time_regridded": info["regridded"],
             "time_offset_s": info.get("path_start_s", 0.0)}
    n = write_imported(out, rec, attrs, overwrite)
    return {"source": str(src), "format": fmt, "out": str(out), "samples": n, "rate_hz": rec.rate_hz,
            "duration_s": n / rec.rate_hz, "kind": raw.kind, "gimbal": info["gimbal"],
            "path": None if path is None else path.name, "time_regridded": info["regridded"],
            "time_offset_s": info.get("path_start_s", 0.0),
            "site": {"latitude_deg": site.latitude / DEG, "longitude_deg": site.longitude / DEG, "height_m": site.height},
            "skipped_checks": sorted(skip)}


# ----------------------------------------------------------------------------- export
def _fmt_rows(fh, a: np.ndarray) -> None:
    np.savetxt(fh, a, fmt="%.17g", delimiter=",")


def export_record(data, out, fmt: str, overwrite: bool = False, gimbal_out=None, path_out=None,
                  chunk_size: int = 1 << 18) -> dict:
    """Export the record ``data`` as ``csv``, ``psins`` (.bin float64) or ``mat`` (atomic writes).

    ``gimbal_out``: a CSV of ``time, outer, inner`` [s, rad, rad] (psins / mat only; the csv
    export carries the angles in its own columns).  ``path_out``: the record's rotation path
    as a TOML ``[path]`` table (what ``--path`` reads).  All outputs are written, or none."""
    import tomli_w

    if fmt not in EXPORT_FORMATS:
        raise ImportFileError(f"unknown export format {fmt!r}; choose one of: {', '.join(EXPORT_FORMATS)}")
    info = record_info(data)
    if gimbal_out is not None:
        if fmt == "csv":
            raise ImportFileError("--gimbal-out applies to psins/mat (a csv export has the gimbal columns)")
        if not info.has_gimbal:
            raise ImportFileError(f"{data}: the record has no gimbal angles for --gimbal-out")
    if path_out is not None and info.path is None:
        raise ImportFileError(f"{data}: the record has no rotation path for --path-out")
    out = FsPath(out)
    with ExitStack() as stack:
        tmp = stack.enter_context(atomic_path(out, overwrite))
        gtmp = stack.enter_context(atomic_path(gimbal_out, overwrite)) if gimbal_out is not None else None
        if path_out is not None:
            ptmp = stack.enter_context(atomic_path(path_out, overwrite))
            ptmp.write_text(tomli_w.dumps({"path": info.path.to_dict()}))
        _export_main(data, tmp, fmt, info, chunk_size, gtmp)
    res = {"data": str(data), "format": fmt, "out": str(out), "samples": info.n_samples, "rate_hz": info.rate_hz,
           "gimbal": "columns" if fmt == "csv" and info.has_gimbal else (str(gimbal_out) if gimbal_out else None),
           "site": {"latitude_deg": info.site.latitude / DEG, "longitude_deg": info.site.longitude / DEG,
                    "height_m": info.site.height},
           "path": None if info.path is None else info.path.name,
           "path_out": None if path_out is None else str(path_out)}
    return res


def _export_main(data, tmp: FsPath, fmt: str, info: RecordInfo, chunk_size: int, gtmp: FsPath | None) -> None:
    gfh = open(gtmp, "w") if gtmp is not None else None
    try:
        if gfh is not None:
            gfh.write(",".join(GIMBAL_HEADER) + "\n")
        if fmt == "mat":
            import scipy.io

            parts = []
            for t, dth, dv, g in iter_chunks(data, chunk_size):
                parts.append(np.column_stack([dth, dv, t]))
                if gfh is not None:
                    _fmt_rows(gfh, np.column_stack([t, g]))
            with open(tmp, "wb") as fh:
                scipy.io.savemat(fh, {"imu": np.concatenate(parts)})
            return
        with open(tmp, "w" if fmt == "csv" else "wb") as fh:
            if fmt == "csv":
                fh.write(",".join(EXPORT_HEADER + (EXPORT_HEADER_GIMBAL if info.has_gimbal else [])) + "\n")
            for t, dth, dv, g in iter_chunks(data, chunk_size):
                if fmt == "csv":
                    _fmt_rows(fh, np.column_stack([t, dth, dv] + ([g] if g is not None else [])))
                else:
                    np.ascontiguousarray(np.column_stack([dth, dv, t]), dtype="<f8").tofile(fh)
                if gfh is not None:
                    _fmt_rows(gfh, np.column_stack([t, g]))
    finally:
        if gfh is not None:
            gfh.close()

