"""Import mappings: which column of a text file is which channel, in which unit and sign, and the
formats, channels and checks the importers know (see :mod:`inscal.io.importers`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.core import units
from inscal.core.earth import Site
from inscal.core.turntable import BUILTIN_PATHS, PathError, RotationPath
from inscal.core.units import DEG
from inscal.io.formats import REGISTRY, export_formats, with_mapping
from inscal.io.records import DataFileError
from inscal.io.tomlfile import read_toml

#: the formats ``inscal import`` reads and ``inscal export`` writes (the names of :data:`inscal.io.formats.REGISTRY`)
FORMATS = tuple(REGISTRY)
EXPORT_FORMATS = export_formats()
CHECKS = ("constant", "saturation", "magnitudes", "motion")
CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")

#: the header line :func:`export_record` writes (csv); a csv without a mapping must start with it
EXPORT_HEADER = ["time [s]", "dtheta_x [rad]", "dtheta_y [rad]", "dtheta_z [rad]",
                 "dvel_x [m/s]", "dvel_y [m/s]", "dvel_z [m/s]"]
EXPORT_HEADER_GIMBAL = ["outer [rad]", "inner [rad]"]
GIMBAL_HEADER = ["time [s]", "outer [rad]", "inner [rad]"]
#: the header cell of a temperature sensor's column in a csv export (``temperature imu [degC]``)
EXPORT_TEMPERATURE = "temperature {} [degC]"
#: the header cell of a temperature file's time column (``inscal export --temperature-out``)
TEMPERATURE_TIME_HEADER = "time [s]"

#: timestamps must be uniform to this fraction of the step unless a rate is given
JITTER_TOL = 1e-6
#: with a given rate, steps may deviate by this fraction of the interval (they are regridded)
REGRID_TOL = 0.1

#: physical limits of imported values (:mod:`inscal.io.checks`): angular rate [rad/s] (100 rev/s),
#: specific force [m/s^2] (1,000 g), gimbal angle [rad] (1.6 million turns), timestamp [s] (31,700 years)
MAX_RATE = 2.0 * math.pi * 100.0
MAX_ACCEL = 1000.0 * units.G0
#: the largest plausible angle of an import [rad] (1.6 million turns)
MAX_ANGLE = 2.0 * math.pi * 1.6e6
MAX_TIME = 1e12
#: sample rates an IMU record can have [Hz]: a slower log (over 1.5 s between samples) or a faster one
#: (under 20 us) is a time column in another unit
MIN_RATE_HZ = 1.0 / 1.5
MAX_RATE_HZ = 5e4
#: factors by which a time column's unit can be off, and the unit each makes of seconds
TIME_FACTORS = ((1e3, "milliseconds"), (1e6, "microseconds"), (1e9, "nanoseconds"))


class ImportFileError(DataFileError):
    """A source file that cannot be imported, with the reason (one line)."""


# ----------------------------------------------------------------------------- mapping
@dataclass(frozen=True)
class Mapping:
    """How to read a delimited text file (SI conversions come from :mod:`inscal.core.units`)."""

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
    #: temperature sensors: ``((name, column), ...)``, a column being a 0-based index or a header name
    temperature: tuple = ()
    temperature_unit: str = "degC"
    #: raw counts of a triad: ``(offset, bits, twos_complement)`` (None: not counts, or no width given);
    #: the SI value is ``scale * (decoded - offset)`` (:func:`decode_counts`)
    gyro_counts: tuple | None = None
    accel_counts: tuple | None = None
    #: ``kind = "sampled-rates"``: the longest step between stamps bridged by the rule [s] (None: a step
    #: over :data:`inscal.io.formats.rates.GAP_FACTOR` median steps is refused)
    max_gap: float | None = None


_TOP = {"max_gap_s", "kind", "delimiter", "header_rows", "comment", "axes", "signs", "columns", "units", "site"}
_COLS = {"time", "gx", "gy", "gz", "ax", "ay", "az", "outer", "inner", "temperature"}
_UNITS = {"time", "gyro", "accel", "gyro_scale", "accel_scale", "gimbal", "temperature",
          "gyro_offset", "accel_offset", "gyro_bits", "accel_bits", "gyro_twos_complement", "accel_twos_complement"}
_COUNTS_KEYS = ("offset", "bits", "twos_complement")
#: ``kind``: increments, rates held over each sample interval (multiplied by it), or rates sampled at
#: their time stamps (integrated onto a uniform grid by :mod:`inscal.io.formats.rates`)
KINDS = ("increments", "rates", "sampled-rates")
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


def _column_ok(v) -> bool:
    return not isinstance(v, bool) and (isinstance(v, str) or (isinstance(v, int) and v >= 0))


def temperature_columns(spec) -> tuple[tuple[str, int | str], ...]:
    """``[columns] temperature``: one column, a list of columns or a table ``{sensor = column, ...}``
    -> ``((sensor, column), ...)``.  A column given by header name names its sensor; one given by
    index is sensor ``T<k>`` (``k``: its place in the list, from 0), as a record's unnamed sensors."""
    if isinstance(spec, dict):
        pairs = [(str(k), v) for k, v in spec.items()]
    elif isinstance(spec, list):
        pairs = [(v if isinstance(v, str) else f"T{k}", v) for k, v in enumerate(spec)]
    else:
        pairs = [(spec if isinstance(spec, str) else "T0", spec)]
    if not pairs:
        raise ImportFileError("[columns] temperature names no column")
    for name, v in pairs:
        if not _column_ok(v):
            raise ImportFileError(f"[columns] temperature: the column of sensor {name!r} must be a 0-based index or a "
                                  f"header name, got {v!r}")
        if not name.strip():
            raise ImportFileError("[columns] temperature: a sensor name is empty")
    names = [n for n, _ in pairs]
    if len(set(names)) != len(names):
        raise ImportFileError(f"[columns] temperature: sensor names repeat ({', '.join(names)})")
    return tuple(pairs)


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
    spec = REGISTRY.get(fmt)
    if spec is not None and spec.mapping == "site":  # their columns and units are fixed (a .imu header gives its scales)
        if rest:
            raise ImportFileError(f"mapping key(s) {sorted(rest)} apply to --format {'|'.join(with_mapping('columns'))}; "
                                  f"a {fmt} mapping may only hold [site]")
        return None, site
    if "columns" not in d:
        raise ImportFileError("mapping needs a [columns] table (gx, gy, gz, ax, ay, az, and time)")
    kind = d.get("kind", "increments")
    if kind not in KINDS:
        raise ImportFileError(f"kind must be one of {', '.join(repr(k) for k in KINDS)}, got {kind!r}")
    if kind == "sampled-rates" and "time" not in d["columns"]:
        raise ImportFileError("kind = \"sampled-rates\" needs a [columns] time (a stamp per sample)")
    max_gap = d.get("max_gap_s")
    if max_gap is not None:
        if kind != "sampled-rates":
            raise ImportFileError(f"max_gap_s applies to kind = \"sampled-rates\", not {kind!r}")
        if isinstance(max_gap, bool) or not isinstance(max_gap, (int, float)) or not (0 < max_gap < math.inf):
            raise ImportFileError(f"max_gap_s must be a duration > 0 s, got {max_gap!r}")
        max_gap = float(max_gap)
    cols = d["columns"]
    _keys("[columns]", cols, _COLS)
    cols = dict(cols)
    temps = temperature_columns(cols.pop("temperature")) if "temperature" in cols else ()
    missing = [c for c in CHANNELS if c not in cols]
    if missing:
        raise ImportFileError(f"[columns] needs {list(CHANNELS)}; missing {missing}")
    if ("outer" in cols) != ("inner" in cols):
        raise ImportFileError("[columns] outer and inner go together (both or neither)")
    for k, v in cols.items():
        if not _column_ok(v):
            raise ImportFileError(f"[columns] {k} must be a 0-based column index or a header name, got {v!r}")
    seen = {}
    for k, v in [*cols.items(), *((f"temperature sensor {n!r}", v) for n, v in temps)]:
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
    conv, counts = {}, {"gyro": None, "accel": None}
    for k, uk in (("gyro", gk), ("accel", ak)):
        unit = u[k]
        if not isinstance(unit, str):
            raise ImportFileError(f"[units] {k} must be a string, got {unit!r}")
        if unit == "counts":
            if f"{k}_scale" not in u:
                raise ImportFileError(f"[units] {k} = \"counts\" needs {k}_scale (value of one count)")
            conv[k] = ("counts", _scale(u[f"{k}_scale"], uk, f"{k}_scale"))
            counts[k] = _counts(u, k)
        else:
            extra = [f"{k}_{c}" for c in ("scale", *_COUNTS_KEYS) if f"{k}_{c}" in u]
            if extra:
                raise ImportFileError(f"[units] {extra[0]} applies to {k} = \"counts\" only")
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
    tu_c = "degC"
    if "temperature" in u:
        if not temps:
            raise ImportFileError("[units] temperature applies with a [columns] temperature")
        try:
            tu_c = units.temperature_unit(str(u["temperature"]))
        except units.UnitError as exc:
            raise ImportFileError(f"[units] temperature: {exc}") from None
    axes = d.get("axes", ["x", "y", "z"])
    if not (isinstance(axes, list) and sorted(map(str, axes)) == ["x", "y", "z"]):
        raise ImportFileError(f"axes must be a permutation of [\"x\", \"y\", \"z\"], got {axes!r}")
    signs = d.get("signs", [1, 1, 1])
    if not (isinstance(signs, list) and len(signs) == 3 and all(s in (1, -1) and not isinstance(s, bool) for s in signs)):
        raise ImportFileError(f"signs must be three of 1 / -1, got {signs!r}")
    delim = d.get("delimiter", (spec.delimiter if spec is not None else None) or "whitespace")
    if not isinstance(delim, str) or not (delim == "whitespace" or len(delim) == 1):
        raise ImportFileError(f"delimiter must be one character or \"whitespace\", got {delim!r}")
    hr = d.get("header_rows", 0)
    if isinstance(hr, bool) or not isinstance(hr, int) or hr < 0:
        raise ImportFileError(f"header_rows must be an integer >= 0, got {hr!r}")
    if hr == 0 and any(isinstance(v, str) for v in [*cols.values(), *(v for _, v in temps)]):
        raise ImportFileError("columns given by name need header_rows >= 1")
    comment = d.get("comment", "#")
    if not isinstance(comment, str) or len(comment) != 1:
        raise ImportFileError(f"comment must be one character, got {comment!r}")
    m = Mapping(dict(cols), kind, tu, conv["gyro"][0], conv["accel"][0], conv["gyro"][1], conv["accel"][1], gu,
                tuple("xyz".index(a) for a in axes), tuple(float(s) for s in signs),
                None if delim == "whitespace" else delim, hr, comment, temps, tu_c, counts["gyro"], counts["accel"],
                max_gap)
    return m, site


def _counts(u: dict, k: str) -> tuple | None:
    """``(offset, bits, twos_complement)`` of raw counts from ``[units] {k}_offset`` (counts subtracted
    before scaling, default 0), ``{k}_bits`` (the word width, 2 .. 64) and ``{k}_twos_complement``
    (the file holds the words as unsigned numbers 0 .. 2^bits - 1, read as two's complement;
    needs ``{k}_bits``); None when neither a width nor an offset is given."""
    off = u.get(f"{k}_offset", 0)
    if isinstance(off, bool) or not isinstance(off, (int, float)) or not math.isfinite(off):
        raise ImportFileError(f"[units] {k}_offset must be a number of counts, got {off!r}")
    bits = u.get(f"{k}_bits")
    if bits is not None and (isinstance(bits, bool) or not isinstance(bits, int) or not 2 <= bits <= 64):
        raise ImportFileError(f"[units] {k}_bits must be a whole number of bits 2 .. 64, got {bits!r}")
    twos = u.get(f"{k}_twos_complement", False)
    if not isinstance(twos, bool):
        raise ImportFileError(f"[units] {k}_twos_complement must be true or false, got {twos!r}")
    if twos and bits is None:
        raise ImportFileError(f"[units] {k}_twos_complement needs {k}_bits (the word width)")
    if bits is None and off == 0:
        return None
    return float(off), bits, twos


def decode_counts(x, spec: tuple | None, where: str, labels, at) -> np.ndarray:
    """Raw counts ``x`` (N, 3) of one triad decoded by ``spec = (offset, bits, twos_complement)`` and the
    offset removed: words beyond the width (``0 .. 2^bits - 1`` read as two's complement, else
    ``-2^(bits-1) .. 2^(bits-1) - 1``) are refused with one line naming the channel and the row
    (``labels[i]``, ``at(row)``)."""
    x = np.asarray(x, dtype=float)
    if spec is None:
        return x
    off, bits, twos = spec
    if bits is not None:
        lo, hi = (0.0, 2.0 ** bits - 1) if twos else (-(2.0 ** (bits - 1)), 2.0 ** (bits - 1) - 1)
        with np.errstate(invalid="ignore"):
            out = (x < lo) | (x > hi)
        if np.any(out):
            r, c = map(int, np.argwhere(out)[0])
            form = f"{bits}-bit two's complement words {lo:.0f} .. {hi:.0f}" if twos else \
                f"{bits}-bit signed counts {lo:.0f} .. {hi:.0f}"
            raise ImportFileError(f"{where}: {labels[c]} is {x[r, c]:.17g} at {at(r)}: beyond its bit width "
                                  f"({form}; {int(np.count_nonzero(out))} value(s) out of range)")
        if twos:
            x = np.where(x >= 2.0 ** (bits - 1), x - 2.0 ** bits, x)
    return x - off


def load_mapping(path, fmt: str) -> tuple[Mapping | None, Site | None]:
    """Read and check a mapping TOML for format ``fmt``: ``(Mapping or None, Site or None)`` (a psins/mat
    mapping may hold only ``[site]``); every malformed key is an :class:`ImportFileError` naming the file.
    """
    p = Path(path)
    d = read_toml(p, ImportFileError, "mapping file")
    try:
        return parse_mapping(d, fmt)
    except ImportFileError as exc:
        raise ImportFileError(f"{p}: {exc}") from None


def default_mapping(gimbal: bool, sensors: tuple[str, ...] = ()) -> Mapping:
    """The mapping of a csv written by :func:`export_record` (``sensors``: its temperature columns)."""
    cols = {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6}
    if gimbal:
        cols.update(outer=7, inner=8)
    temps = tuple((name, len(cols) + k) for k, name in enumerate(sensors))
    return Mapping(cols, "increments", "s", "rad", "m/s", None, None, "rad", (0, 1, 2), (1.0, 1.0, 1.0), ",", 1, "#",
                   temps, "degC")


def export_layout(names: list[str]) -> tuple[bool, tuple[str, ...]] | None:
    """``(gimbal columns, temperature sensors)`` of a csv header written by :func:`export_record`, or
    None when ``names`` is not such a header."""
    if names[:len(EXPORT_HEADER)] != EXPORT_HEADER:
        return None
    rest = names[len(EXPORT_HEADER):]
    gimbal = rest[:2] == EXPORT_HEADER_GIMBAL
    rest = rest[2:] if gimbal else rest
    head, tail = EXPORT_TEMPERATURE.split("{}")
    sensors = []
    for cell in rest:
        if not (cell.startswith(head) and cell.endswith(tail) and len(cell) > len(head) + len(tail)):
            return None
        sensors.append(cell[len(head):-len(tail)])
    return gimbal, tuple(sensors)


def load_path(path) -> RotationPath:
    """A rotation path from a TOML file holding one ``[path]`` table (as in scenario files)."""
    p = Path(path)
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
        return RotationPath.from_dict(pd)
    except (PathError, TypeError, ValueError) as exc:
        if isinstance(exc, ImportFileError):
            raise
        raise ImportFileError(f"{p}: [path]: {exc}") from None
