"""Importing IMU data from other tools into an inscal record, and exporting records.

``inscal import`` converts once; every other command reads the HDF5 record (:mod:`inscal.io`).

Sources
-------
The formats of :data:`inscal.io.formats.REGISTRY`, each read by its own module into a
:class:`~inscal.io.formats.base.Raw` block that this module checks and writes: ``psins``
(:mod:`~inscal.io.formats.psins`, PSINS ``.bin`` rows ``[dθ dv t]``, or rates with ``rates=True``;
``t`` is the END time of each sample interval, the PSINS convention and the record's), ``psins-imu``
(:mod:`~inscal.io.formats.psins_imu`, the compact ``.imu`` log; its header gives the site unless one
is given), ``mat`` (:mod:`~inscal.io.formats.mat`), ``csv`` and ``txt`` (:mod:`~inscal.io.formats.text`:
delimited text through a mapping, below; a csv without one must start with the header that
:func:`export_record` writes; ``txt`` defaults to whitespace-separated columns), ``rosbag``
(:mod:`~inscal.io.formats.rosbag`: ``sensor_msgs/Imu`` rates integrated onto a uniform grid by
:mod:`~inscal.io.formats.rates`; time 0 is the first message's stamp) and ``kf-gins``
(:mod:`~inscal.io.formats.kfgins`, with its configuration's ``imunoise`` block kept in the record's
``source``).

Mapping TOML (csv / txt; every key is checked, unknown keys are errors)::

    kind = "increments"            # default; or "rates" (then multiplied by the sample interval), or
                                   #   "sampled-rates": rates at their own (jittered) time stamps, integrated
                                   #   onto a uniform grid (--rate-hz; default their mean rate) by the rule
                                   #   of inscal.io.formats.rates
    max_gap_s = 0.05               # sampled-rates: a logger's gaps up to this long [s] are bridged by that rule
                                   #   (its error bound takes the longest step); default: a step over 1.5
                                   #   median steps is refused as dropped samples
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
    temperature = "T_imu"          # optional temperature sensor(s): a column (by header name: the sensor's
                                   #   name; by index k: sensor "T0"), a list ["T_gyro", "T_acc"] (index k of
                                   #   the list: "T<k>"), or a table {gyro = 9, accel = "T_acc"} naming them
    [units]
    time = "s"                     # default; s | ms | min | h (a column in another unit is named)
    gyro = "deg"                   # required; increments: rad | deg | arcsec | urad; rates: rad/s | deg/s | deg/h
    accel = "m/s"                  # required; increments: m/s | mm/s; rates: m/s^2 | g | mg | ug
    # gyro = "counts"              # raw counts need a scale: "VALUE UNIT" (an angle unit for increments,
    # gyro_scale = "0.1 arcsec"    #   a rate unit for rates) or a number in SI (rad, rad/s per count)
    # accel = "counts"             #   likewise for the accelerometers (m/s or m/s^2 per count)
    # accel_scale = 1e-6
    # gyro_bits = 24               # raw words: their width (a count beyond it is refused), read as
    # gyro_twos_complement = true  #   unsigned 0 .. 2^bits - 1 two's complement words when true;
    # gyro_offset = 0              #   value = scale * (count - offset) (likewise accel_*)
    gimbal = "deg"                 # deg | rad; required with the outer/inner columns
    temperature = "degC"           # degC (default) | K | degF, converted to degC
    [site]                         # optional; --lat/--lon/--height override it
    latitude_deg = 34.2
    longitude_deg = 108.9
    height_m = 400.0

For ``psins``/``mat`` a mapping may only hold ``[site]``.

Temperature (the record's ``/temperature``, degC).  A temperature column of a delimited file (csv) may
leave a cell empty where that sensor has no reading (a sensor slower than the IMU): the readings then
keep their own times, those of their rows, and the record stores them with ``/temperature_time``;
a column with a reading on every row is on the record's time grid.  Several sensors with readings on
different rows share the rows where any has one: each is interpolated linearly between its own
readings on the others' rows (held before its first and after its last).  A NaN / Inf written in a
temperature cell, text, a column with no reading at all, readings outside -100 .. 200 degC once
converted (kelvin declared as degC: the message names the unit that fits) and an unknown unit are
refused with one line.  Whitespace text has no empty cells: every row needs its readings.
Readings at their own times may also come from a separate file (``temperature_file``, ``inscal
import --temperature``): a header row ``time [s],NAME [degC],...`` naming each sensor's column with its
unit (time s | ms | min | h; degC | K | degF), then increasing times, comma or whitespace separated
(:func:`~inscal.io.formats.sidecars.read_temperature_file`); they are shifted with the samples to the path
start and must overlap the record.

Gimbal angles from encoders at another rate (``gimbal_file``: columns time, outer, inner;
an optional header line, which may give the units as ``time [ms],outer [deg],inner [deg]``;
comma or whitespace separated) are unwrapped and interpolated
linearly to the sample end times; they must cover the record.  Without encoders a rotation
path (a ``[path]`` table as in scenario files) is stored in the record; the record's time is
then shifted so that the path starts at 0 (``path_start``: the source time at which the path
starts, default the start of the first sample interval).

Checks (each refusal is one line): empty or header-only files, wrong column counts, text in
numbers, integer data, NaN/Inf, the time base (a corrupt timestamp, backwards steps, repeats, a
time column in another unit than declared -- milliseconds read as seconds --, gaps, jitter, a
rate inconsistent with the timestamps), values beyond the physical limits (a rate of 100 rev/s,
1,000 g, a gimbal angle or encoder jump no turntable makes; :mod:`inscal.io.checks`, with the
file, column, line and value), and the plausibility checks that ``skip`` may name:
``constant`` (a channel that never changes), ``saturation`` (a channel pinned at its extreme
while the others move: a run of up to 2 s, a sensor at its range in a fast turn, is marked in the record's
``source`` attribute, key ``saturated``, and the calibrations leave those samples out; a channel pinned
longer is refused as stuck), ``magnitudes`` (gravity and Earth rate judged from magnitudes: g vs
m/s^2, degrees vs radians, rates vs increments), ``motion`` (the gyros must turn when the
gimbal angles / path say so, and only then) and ``encoders`` (the encoder angles must give the
gyros' rotation through every move, and no latency over a sample:
:mod:`inscal.io.encoders`, which names a unit mix-up, a flipped sign, swapped columns or the
latency to give as ``encoder_latency``, the shift applied to the angles before the checks).

Exports (:func:`export_record`): ``csv`` (one header line with units; time, dtheta, dvel, the
gimbal angles if recorded and the temperature sensors if any, ``%.17g`` so that importing gives back
the same doubles; the temperature on the rows of its readings, or interpolated onto the sample times
when the readings are not at sample times, said on a comment line under the header),
``psins`` (float64 ``.bin`` rows ``[dθ dv t]``) and ``mat`` (variable ``imu``, N x 7); the
gimbal angles of a psins/mat export can go to a separate CSV that ``gimbal_file`` reads, and
the rotation path to a TOML that ``path_file`` reads, and the temperature readings at their own
times to a CSV that ``temperature_file`` reads (any format).  The site is not exported: give it again
on import.

An imported record has no ``/truth``; its root attribute ``source`` (JSON) names the file, its
SHA-256, the format, the mapping / gimbal / path / temperature files, the checks skipped, whether the
time was regridded and the time offset subtracted (the path start).
"""

from __future__ import annotations

import datetime as _dt

import json
import math
import os
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

import numpy as np
import tomli_w

from inscal.core.earth import Site
from inscal.core.turntable import RotationPath
from inscal.core.units import DEG
from inscal.io.checks import (
    SKIPPABLE,
    check_constant,
    check_temperature,
    check_encoders,
    check_finite,
    check_integers,
    check_magnitudes,
    check_motion,
    check_saturation,
    check_values,
    saturated_spans,
    time_base,
)
from inscal.io.encoders import apply_latency, small_latency
from inscal.io.files import atomic_path, file_hash
from inscal.io.formats import Format, UnknownFormat, format_spec, reader, taking, with_mapping
from inscal.io.formats.base import Raw, RawTemperature, ReadOptions, write_rows
from inscal.io.formats.kfgins import read_kfgins_noise
from inscal.io.formats.rosbag import STAMPS, read_bag_temperature
from inscal.io.formats.sidecars import read_gimbal_file, read_temperature_file
from inscal.io.mapping import (  # noqa: F401  (EXPORT_HEADER*: the export's header, named here for its readers)
    EXPORT_HEADER,
    EXPORT_HEADER_GIMBAL,
    GIMBAL_HEADER,
    TEMPERATURE_TIME_HEADER,
    ImportFileError,
    Mapping,
    load_mapping,
    load_path,
)
from inscal.io.recordfile import record_info, write_stream
from inscal.io.records import DataFileError, Record, RecordInfo, Temperature, validate_arrays
from inscal.io.streaming import iter_chunks, iter_window


# ----------------------------------------------------------------------------- import
def read_source(src, fmt: str | Format, mapping: Mapping | None = None, dtype: str = "float64",
                variable: str | None = None, rates: bool = False, topic: str | None = None, stamps: str = "header",
                rate_hz: float | None = None) -> Raw:
    """Read ``src`` in ``fmt`` (a name or a row of :data:`~inscal.io.formats.REGISTRY`; see the module
    docstring) into a :class:`Raw`, by the format's own reader."""
    spec = fmt if isinstance(fmt, Format) else known_format(fmt)
    opts = ReadOptions(spec.name, mapping, dtype, variable, rates, topic, stamps, rate_hz)
    return reader(spec).read(Path(src), opts)


def known_format(fmt: str, export: bool = False) -> Format:
    """The row of ``fmt`` in :data:`~inscal.io.formats.REGISTRY`; an unknown one is an :class:`ImportFileError`
    that lists the choices."""
    try:
        return format_spec(fmt, export)
    except UnknownFormat as exc:
        raise ImportFileError(str(exc)) from None


def site_from_options(lat: float | None, lon: float | None, height: float | None, base: Site | None) -> Site | None:
    """The site of ``--lat``, ``--lon`` and ``--height`` [deg, deg, m], those not given taken from ``base`` (a
    mapping's ``[site]``); None when none is given.  Missing parts without a base, a value that is not
    finite, a latitude out of range: an :class:`ImportFileError` in one line."""
    given = {"--lat": lat, "--lon": lon, "--height": height}
    if all(v is None for v in given.values()):
        return None
    if base is None and any(v is None for v in given.values()):
        missing = [k for k, v in given.items() if v is None]
        raise ImportFileError(f"give --lat, --lon and --height together (missing {', '.join(missing)}), "
                              "or a [site] table in the mapping")
    for k, v in given.items():
        if v is not None and not math.isfinite(v):
            raise ImportFileError(f"{k} must be finite, got {v}")
    try:
        return Site((lat if lat is not None else base.latitude / DEG) * DEG,
                    (lon if lon is not None else base.longitude / DEG) * DEG,
                    height if height is not None else base.height)
    except ValueError as exc:
        raise ImportFileError(str(exc)) from None


def build_record(raw: Raw, site: Site, where: str, rate_hz: float | None = None, path: RotationPath | None = None,
                 path_start: float | None = None, gimbal: tuple[np.ndarray, np.ndarray] | None = None,
                 skip=(), units_desc: tuple[str, str] = ("rad", "m/s"),
                 gimbal_name: str = "gimbal angles", encoder_latency: float = 0.0,
                 temperature: RawTemperature | None = None, declared: str | None = None) -> tuple[Record, dict]:
    """Check ``raw`` and turn it into a :class:`~inscal.io.Record` (SI increments).  Returns
    ``(record, info)``; raises :class:`ImportFileError` with one line on any problem.
    ``encoder_latency`` [s]: the encoder angles are shifted to ``theta(t + encoder_latency)``
    (:func:`~inscal.io.encoders.apply_latency`) before the checks.  ``temperature``: readings at their
    own times from a separate file (:func:`~inscal.io.formats.sidecars.read_temperature_file`), on the source's
    clock as the samples' (shifted with them to the path start); temperature columns of the source
    itself come with ``raw``.  ``declared``: the gyro unit as declared (by a mapping, or by a format whose
    messages fix it; None: assumed), so a gyro magnitude that contradicts it is a warning (``info["warnings"]``), not a
    refusal (:func:`~inscal.io.checks.check_magnitudes`)."""
    unknown = set(skip) - set(SKIPPABLE)
    if unknown:
        raise ImportFileError(f"unknown check(s) {sorted(unknown)} to skip; known: {', '.join(SKIPPABLE)}")
    if not math.isfinite(encoder_latency):
        raise ImportFileError(f"--encoder-latency must be finite, got {encoder_latency}")
    n = raw.gyro.shape[0]
    check_finite(raw, where)
    time, rate, info = time_base(raw, n, rate_hz, where)
    check_integers(raw, where)
    check_values(raw, rate, where, *units_desc)
    dt = 1.0 / rate
    if "constant" not in skip:
        check_constant(raw, where)
    marks = check_saturation(raw, where, rate_hz=rate) if "saturation" not in skip else []
    if raw.kind == "rates":
        dth, dv = raw.gyro * dt, raw.accel * dt
    else:
        dth, dv = raw.gyro, raw.accel
    info["warnings"] = []
    if "magnitudes" not in skip:
        info["warnings"] += check_magnitudes(dth, dv, rate, site, where, raw.kind, *units_desc, raw=raw,
                                             declared=declared)
    gim = raw.gimbal
    if gimbal is not None:
        if gim is not None:
            raise ImportFileError(f"{where} has gimbal angle columns; --gimbal would give them twice")
        tg, ag = gimbal
        if tg[0] > time[0] + 1e-9 * dt or tg[-1] < time[-1] - 1e-9 * dt:
            hint = _bag_epoch_hint(tg, time, dt, raw) or _gimbal_time_hint(tg, time, dt)
            raise ImportFileError(f"{gimbal_name}: the angles cover t = {tg[0]:.9g} .. {tg[-1]:.9g} s; the record needs "
                                  f"t = {time[0]:.9g} .. {time[-1]:.9g} s (the sample end times)"
                                  + (f": {hint}" if hint else ""))
        if tg[-1] - tg[0] > 100.0 * (time[-1] - time[0] + dt) and (hint := _gimbal_time_hint(tg, time, dt, close=True)):
            raise ImportFileError(f"{gimbal_name}: the angles span t = {tg[0]:.9g} .. {tg[-1]:.9g} s, the record "
                                  f"t = {time[0]:.9g} .. {time[-1]:.9g} s: {hint}")
        gim = np.column_stack([np.interp(time, tg, ag[:, 0]), np.interp(time, tg, ag[:, 1])])
        info["gimbal"] = "file"
    elif gim is not None:
        gim = np.unwrap(gim, axis=0)
        info["gimbal"] = "columns"
    else:
        info["gimbal"] = None
    if encoder_latency != 0.0:
        if gim is None:
            raise ImportFileError("--encoder-latency applies to encoder angles (--gimbal, or gimbal columns)")
        gim = apply_latency(time, gim, encoder_latency)
    info["encoder_latency_s"] = float(encoder_latency) if gim is not None else None
    if gim is not None and "motion" not in skip:
        check_motion(dth, gim, dt, "gimbal angles", time)
    info["encoders"] = None
    if gim is not None and "encoders" not in skip:
        info["encoders"] = check_encoders(dth, gim, rate, time).summary()
        e = info["encoders"]
        if (words := small_latency(e["latency_s"], e["latency_sigma_s"], rate)) is not None:
            info["warnings"].append(f"{gimbal_name if gimbal is not None else where}: {words}: a calibration misfits "
                                    f"through the turns unless the angles are shifted (--encoder-latency "
                                    f"{e['latency_s']:.6g})")
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
    temp = _temperature(raw, temperature, time, dt, info.get("path_start_s", 0.0), where)
    info["temperature"] = None if temp is None else {
        "sensors": list(temp.sensors), "readings": int(temp.time.shape[0]),
        "grid": "record" if np.array_equal(temp.time, time) else "own",
        "source": "columns" if raw.temperature is not None else "file",
        "span_s": [float(temp.time[0]), float(temp.time[-1])]}
    info["saturated"] = saturated_spans(marks, time, dt)
    rec = Record(np.ascontiguousarray(time, float), np.ascontiguousarray(dth, float), np.ascontiguousarray(dv, float),
                 None if gim is None else np.ascontiguousarray(gim, float), rate, site, path, None, "", where,
                 temp)
    try:
        validate_arrays(rec.time, rec.dtheta, rec.dvel, rec.gimbal, rec.rate_hz, where=where)
    except DataFileError as exc:
        raise ImportFileError(str(exc)) from None
    return rec, info


def _identity(path) -> tuple:
    """What changes when a file is replaced or written to: its inode, size and modification time."""
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


#: the longest stretch at either end of a record that a temperature file's first or last reading is held
#: over, at least [s] (also 10 % of the record, and 1.5 of the file's own reading interval)
TEMPERATURE_HOLD_S = 60.0


def _temperature(raw: Raw, file: RawTemperature | None, time: np.ndarray, dt: float, offset: float,
                 where: str) -> Temperature | None:
    """The record's temperature from the source's columns (at the rows' sample times) or from a file of
    readings at their own times (shifted by ``offset``, the path start), checked
    (:func:`~inscal.io.checks.check_temperature`); a file must overlap the record."""
    if raw.temperature is not None and file is not None:
        raise ImportFileError(f"{where} has temperature columns; --temperature would give the temperature twice")
    if raw.temperature is not None:
        return check_temperature(raw.temperature, time)
    if file is None:
        return None
    if offset != 0.0:
        file = replace(file, time=file.time - offset)
    temp = check_temperature(file)
    a, b = float(temp.time[0]), float(temp.time[-1])
    if b < time[0] - dt or a > time[-1]:
        shift = f" (after the shift of {offset:.9g} s to the path start)" if offset else ""
        raise ImportFileError(f"{file.where}: the temperature readings cover t = {a:.9g} .. {b:.9g} s{shift}; the record "
                              f"runs t = {time[0] - dt:.9g} .. {time[-1]:.9g} s: no overlap (another clock, or a time "
                              "unit: give it in the header, as 'time [ms]')")
    # the readings are held beyond the first and the last: a file must not leave a long stretch of the record
    # without any (one reading held over a 30-min warm-up is not the warm-up's temperature)
    start, end = float(time[0] - dt), float(time[-1])
    step = float(np.median(np.diff(temp.time))) if temp.time.size > 1 else 0.0
    tol = max(TEMPERATURE_HOLD_S, 0.1 * (end - start), 1.5 * step)
    head, tail = a - start, end - b
    if head > tol or tail > tol:
        where_ = "before its first" if head >= tail else "after its last"
        raise ImportFileError(f"{file.where}: {temp.time.size} reading{'s' if temp.time.size != 1 else ''} at t = {a:.9g} "
                              f".. {b:.9g} s leave {max(head, tail):.6g} s of the record (t = {start:.9g} .. {end:.9g} s) "
                              f"{where_} reading (at most {tol:.3g} s is held): a temperature file must cover the record")
    return temp


def _bag_epoch_hint(tg: np.ndarray, time: np.ndarray, dt: float, raw: Raw) -> str:
    """Why encoder times miss a bag's record: they are Unix times (in s, ms, us or ns) while the bag's time counts
    from its first stamp; "" when the source is no bag or that does not explain them."""
    bag = (raw.source_info or {}).get("bag")
    if not bag or "epoch_ns" not in bag:
        return ""
    epoch = bag["epoch_ns"] * 1e-9
    span = time[-1] - time[0] + dt
    for f, unit in ((1.0, "seconds"), (1e-3, "milliseconds"), (1e-6, "microseconds"), (1e-9, "nanoseconds")):
        a, b = tg[0] * f - epoch, tg[-1] * f - epoch
        if a <= time[0] + 0.1 * span and b >= time[-1] - 0.1 * span and b - a < 2.0 * span:
            return (f"they look like Unix times in {unit}, while a bag's time counts from its first stamp ({epoch:.9f} "
                    f"s, Unix): subtract it from the encoder file's times (they then run {a:.6g} .. {b:.6g} s)")
    return ""


def _gimbal_time_hint(tg: np.ndarray, time: np.ndarray, dt: float, close: bool = False) -> str:
    """Why encoder times miss the record by a unit: scaled by 1e-3 (1e-6) they would cover the record
    (``close``: and start and end within a tenth of its span of its ends) -- a time column in
    milliseconds (microseconds) read as seconds -- or scaled by 1e3 (seconds under a header that says
    milliseconds).  "" when no scale explains them."""
    span = time[-1] - time[0] + dt
    for f, what, unit in ((1e-3, "milliseconds", "ms"), (1e-6, "microseconds", None), (1e3, "seconds", "s")):
        a, b = tg[0] * f, tg[-1] * f
        if close:
            fits = abs(a - (time[0] - dt)) <= 0.1 * span and abs(b - time[-1]) <= 0.1 * span
        else:
            fits = a <= time[0] + 0.1 * span and b >= time[-1] - 0.1 * span and b - a < 2.0 * span
        if fits:
            how = (f"give its header the unit, as 'time [{unit}],outer [deg],inner [deg]'" if unit is not None
                   else "convert its time column to seconds or milliseconds")
            return (f"its time column looks like {what}, not {'seconds' if f < 1 else 'milliseconds'} "
                    f"(t = {a:.9g} .. {b:.9g} s as {what}); {how}")
    return ""


def write_imported(out, rec: Record, source_attrs: dict, overwrite: bool = False, created: str | None = None) -> int:
    """Write an imported record atomically (the source is kept as a JSON attribute ``source``); ``created``:
    the record's ``created`` time (ISO, UTC) in place of the time of writing (:func:`source_time`), so that
    the same unchanged source imported twice gives the same file, byte for byte, and the same hash."""
    info = RecordInfo(rec.n_samples, rec.rate_hz, rec.site, rec.path, None, rec.scenario, rec.gimbal is not None,
                      rec.temperature)
    extra = {"source": json.dumps(source_attrs)} | ({} if created is None else {"created": created})
    return write_stream(out, info, [(rec.time, rec.dtheta, rec.dvel, rec.gimbal)], overwrite, extra_attrs=extra)


def source_time(src: Path, epoch_ns: int | None = None) -> str:
    """When an imported source was taken (ISO, UTC, seconds): a bag's first stamp (``epoch_ns``, when it is a
    Unix time), else the source's modification time (a folder's newest file)."""
    if epoch_ns is not None and 946684800 <= epoch_ns / 1e9 <= 4102444800:  # 2000 .. 2100
        ts = epoch_ns / 1e9
    else:
        files = [src] if src.is_file() else [f for f in src.iterdir() if f.is_file()] or [src]
        ts = max(f.stat().st_mtime for f in files)
    return _dt.datetime.fromtimestamp(int(ts), _dt.timezone.utc).isoformat(timespec="seconds")


def import_file(src, out, fmt: str | Format, site: Site | None = None, mapping_file=None, path_file=None,
                path_start: float | None = None, gimbal_file=None, gimbal_unit: str | None = None,
                rate_hz: float | None = None, dtype: str = "float64", variable: str | None = None,
                rates: bool = False, skip=(), overwrite: bool = False, encoder_latency: float = 0.0,
                gravity=None, temperature_file=None, topic: str | None = None, stamps: str = "header",
                config_file=None, temperature_topic: str | None = None,
                site_parts: tuple[float | None, float | None, float | None] | None = None) -> dict:
    """Convert ``src`` into the record ``out`` (see the module docstring); returns a summary.
    ``fmt``: a format's name, or its row of :data:`~inscal.io.formats.REGISTRY` (looked up once).
    ``site_parts``: ``--lat``, ``--lon``, ``--height`` [deg, deg, m] as given (None each where not), in
    place of ``site``: those not given come from the mapping's ``[site]`` (:func:`site_from_options`).
    ``gravity`` (a :class:`~inscal.core.earth.GravityModel`) replaces the gravity model of the site,
    wherever the site comes from (the options, the mapping's ``[site]`` or a PSINS ``.imu`` header)
    (``encoders``: the encoder check's summary, its ``latency_s`` what remains after the applied
    ``encoder_latency_s``).  ``temperature_file``: temperature readings at their own times
    (:func:`~inscal.io.formats.sidecars.read_temperature_file`); ``temperature`` in the summary: the sensors, the
    number of readings, whether they are on the record's grid, their source and time span.
    ``topic``, ``stamps``: a ROS bag's IMU topic and its time (``header`` stamps or ``receive`` times);
    ``temperature_topic``: its ``sensor_msgs/Temperature`` topic, the record's temperature;
    ``config_file``: a KF-GINS configuration whose ``imunoise`` block (and ``imudatarate``) come with a
    ``kf-gins`` import (kept in the record's ``source`` attribute, SI).  ``integration`` in the summary:
    for rates sampled at their stamps (a bag, ``kind = "sampled-rates"``), the grid and the rule's
    error bound (:mod:`inscal.io.formats.rates`)."""
    src = Path(src)
    spec = fmt if isinstance(fmt, Format) else known_format(fmt)
    fmt = spec.name
    if not spec.takes("topic") and (topic is not None or stamps != "header" or temperature_topic is not None):
        raise ImportFileError(f"--topic, --stamps and --temperature-topic apply to --format {' or '.join(taking('topic'))}")
    if temperature_topic is not None and temperature_file is not None:
        raise ImportFileError("--temperature-topic and --temperature would give the temperature twice")
    if stamps not in STAMPS:
        raise ImportFileError(f"--stamps must be one of {', '.join(STAMPS)}, got {stamps!r}")
    if config_file is not None and not spec.takes("config"):
        raise ImportFileError(f"--config applies to --format {' or '.join(taking('config'))} (its imunoise block)")
    noise = read_kfgins_noise(config_file) if config_file is not None else None
    if noise is not None and rate_hz is None:
        rate_hz = noise.rate_hz
    if dtype != "float64" and not spec.takes("dtype"):
        raise ImportFileError(f"--dtype applies to --format {' or '.join(taking('dtype'))} (.bin)")
    if variable is not None and not spec.takes("variable"):
        raise ImportFileError("--variable applies to .mat files")
    if rates and not spec.takes("rates"):
        raise ImportFileError(f"--rates applies to {'/'.join(taking('rates'))}; for {'/'.join(with_mapping('columns'))} "
                              "set kind = \"rates\" in the mapping")
    if path_start is not None and path_file is None:
        raise ImportFileError("--path-start-s applies with --path")
    mapping, msite = load_mapping(mapping_file, fmt) if mapping_file is not None else (None, None)
    if site_parts is not None and site is None:
        site = site_from_options(*site_parts, msite)
    site = site if site is not None else msite
    if site is None and not spec.site_in_file:
        raise ImportFileError("no site: give --lat, --lon and --height (or a [site] table in the mapping)")
    path = load_path(path_file) if path_file is not None else None
    gim = read_gimbal_file(gimbal_file, gimbal_unit) if gimbal_file is not None else None
    tfile = read_temperature_file(temperature_file) if temperature_file is not None else None
    # the hash of the bytes about to be read (a bag folder: its files)
    before, src_hash = _identity(src), getattr(reader(spec), "source_hash", file_hash)(src)
    raw = read_source(src, spec, mapping, dtype, variable, rates, topic, stamps, rate_hz)
    if _identity(src) != before:  # replaced or written to while read: the hash is not the data's
        raise ImportFileError(f"{src} changed while it was imported (replaced or written to): nothing written; "
                              "import it again once it is complete")
    if temperature_topic is not None:
        tfile = read_bag_temperature(src, temperature_topic, raw.source_info["bag"]["epoch_ns"], stamps)
    if mapping_file is not None and spec.mapping == "columns":
        safe = str(mapping_file).replace("{", "{{").replace("}", "}}")
        raw = replace(raw, time_fix=f"set [units] time = \"{{unit}}\" in {safe}")
        if raw.temperature is not None:
            raw = replace(raw, temperature=replace(raw.temperature,
                                                   fix=f"set [units] temperature = \"{{unit}}\" in {safe}"))
    if site is None:  # a PSINS .imu log names its site in its header
        lat, lon, h = raw.header_site
        site = Site(lat * DEG, lon * DEG, h)
    if gravity is not None:
        site = site.with_gravity(gravity)
    if mapping is not None:
        ud = (mapping.gyro_unit, mapping.accel_unit)
    elif spec.units is not None:  # the format's own (sensor_msgs/Imu: rad/s and m/s^2, REP 145)
        ud = spec.units
    else:
        ud = ("rad/s", "m/s^2") if raw.kind == "rates" else ("rad", "m/s")
    if raw.integration is not None:  # rates integrated to increments in SI by the reader
        ud = (f"rad (rates in {ud[0]} integrated)", f"m/s (rates in {ud[1]} integrated)")
    # the gyro unit is declared by a csv/txt mapping, and by a bag's message type; psins, mat and kf-gins files
    # carry none (their format's unit is assumed)
    declared = (spec.declared if spec.declared is not None else
                mapping.gyro_unit if mapping is not None and spec.mapping == "columns" else None)
    rec, info = build_record(raw, site, str(src), rate_hz, path, path_start, gim, skip, ud, str(gimbal_file),
                             encoder_latency, tfile, declared)
    integ = None
    if raw.integration is not None:
        ri = raw.integration
        integ = {"rule": "each rate held over the times nearer its stamp than any other's (midpoint rule; one "
                         "sample per increment when the stamps sit at the centres of the grid's intervals)",
                 "grid_rate_hz": ri.rate_hz,
                 "stamps_on_grid": ri.on_grid, "largest_step_s": ri.h_max, "gaps_bridged": ri.gaps,
                 "error_bound": {"dtheta_rad": ri.bound[:3].tolist(), "dvel_m_s": ri.bound[3:].tolist()},
                 "noise": {"white": ri.noise.white, "variance_ratio": list(ri.noise.variance),
                           "neighbour_correlation": ri.noise.correlation}}
    attrs = {"file": src.name, "hash": src_hash, "format": fmt,
             "mapping": None if mapping_file is None else str(mapping_file),
             "gimbal_file": None if gimbal_file is None else str(gimbal_file),
             "path_file": None if path_file is None else str(path_file),
             "skipped_checks": sorted(skip), "time_regridded": info["regridded"],
             "time_offset_s": info.get("path_start_s", 0.0), "encoder_latency_s": info["encoder_latency_s"],
             "temperature_file": None if temperature_file is None else str(temperature_file),
             "warnings": info["warnings"]}
    if raw.source_info is not None:
        attrs.update(raw.source_info)
    if temperature_topic is not None:
        attrs["bag"] = {**attrs["bag"], "temperature_topic": temperature_topic}
    if integ is not None:
        attrs["integration"] = integ
    if info["saturated"]:  # a sensor at its range: the calibrations leave these samples out
        attrs["saturated"] = info["saturated"]
    if noise is not None:
        attrs["imunoise"] = {"config": str(config_file), "arw_rad_sqrt_s": noise.noise.arw.tolist(),
                             "vrw_m_s_sqrt_s": noise.noise.vrw.tolist(),
                             "gyro_bias_sigma_rad_s": noise.noise.gyro_bias_instability.tolist(),
                             "accel_bias_sigma_m_s2": noise.noise.accel_bias_instability.tolist(),
                             "gyro_scale_sigma": noise.scale_sigma[0].tolist(),
                             "accel_scale_sigma": noise.scale_sigma[1].tolist(),
                             "correlation_time_s": noise.noise.gyro_bias_tau}
    n = write_imported(out, rec, attrs, overwrite, created=source_time(src, (attrs.get("bag") or {}).get("epoch_ns")))
    return {"source": str(src), "format": fmt, "out": str(out), "samples": n, "rate_hz": rec.rate_hz,
            "duration_s": n / rec.rate_hz, "kind": raw.kind, "gimbal": info["gimbal"],
            "path": None if path is None else path.name, "time_regridded": info["regridded"],
            "time_offset_s": info.get("path_start_s", 0.0),
            "site": {"latitude_deg": site.latitude / DEG, "longitude_deg": site.longitude / DEG, "height_m": site.height},
            "skipped_checks": sorted(skip), "encoder_latency_s": info["encoder_latency_s"],
            "encoders": info["encoders"], "temperature": info["temperature"], "warnings": info["warnings"],
            **({k: attrs[k] for k in ("bag", "integration", "imunoise", "saturated") if k in attrs})}


def export_record(data, out, fmt: str, overwrite: bool = False, gimbal_out=None, path_out=None,
                  chunk_size: int = 1 << 18, temperature_out=None) -> dict:
    """Export the record ``data`` as ``csv``, ``psins`` (.bin float64), ``mat`` or ``kf-gins`` (KF-GINS IMU text:
    rows ``t dtheta dvel`` [s, rad, m/s], 17 digits) (atomic writes).

    ``gimbal_out``: a CSV of ``time, outer, inner`` [s, rad, rad] (psins / mat only; the csv
    export carries the angles in its own columns).  ``path_out``: the record's rotation path
    as a TOML ``[path]`` table (what ``--path`` reads).  ``temperature_out``: the record's
    temperature readings at their own times, ``time [s],NAME [degC],...`` (what ``--temperature``
    reads; any format).  All outputs are written, or none.

    A csv export carries the temperature too, one column per sensor (``temperature NAME [degC]``):
    when every reading falls on a sample time (to 1e-6 of the interval) each goes on its sample's row
    and the other rows leave the cell empty (imported back, the readings and their times are the
    same); otherwise the readings are interpolated linearly onto every sample time (held before the
    first and after the last), and a comment line under the header says so."""

    known_format(fmt, export=True)
    info = record_info(data)
    if gimbal_out is not None:
        if fmt == "csv":
            raise ImportFileError("--gimbal-out applies to psins/mat (a csv export has the gimbal columns)")
        if not info.has_gimbal:
            raise ImportFileError(f"{data}: the record has no gimbal angles for --gimbal-out")
    if path_out is not None and info.path is None:
        raise ImportFileError(f"{data}: the record has no rotation path for --path-out")
    temp = info.temperature
    if temperature_out is not None and temp is None:
        raise ImportFileError(f"{data}: the record has no temperature for --temperature-out")
    if temp is not None and (fmt == "csv" or temperature_out is not None):
        bad = [n for n in temp.sensors if not n or n != n.strip() or any(c in n for c in ',[]"#')]
        if bad:
            raise ImportFileError(f"{data}: temperature sensor {bad[0]!r} cannot name a column of a csv "
                                  "(a comma, bracket, quote or '#' in it, or spaces around it)")
    rows = None
    if temp is not None and fmt == "csv":
        rows = _reading_rows(data, temp, info.rate_hz, info.n_samples, chunk_size)
    out = Path(out)
    with ExitStack() as stack:
        tmp = stack.enter_context(atomic_path(out, overwrite))
        gtmp = stack.enter_context(atomic_path(gimbal_out, overwrite)) if gimbal_out is not None else None
        if path_out is not None:
            ptmp = stack.enter_context(atomic_path(path_out, overwrite))
            ptmp.write_text(tomli_w.dumps({"path": info.path.to_dict()}))
        if temperature_out is not None:
            ttmp = stack.enter_context(atomic_path(temperature_out, overwrite))
            with open(ttmp, "w") as fh:
                fh.write(",".join([TEMPERATURE_TIME_HEADER] + [f"{n} [degC]" for n in temp.sensors]) + "\n")
                write_rows(fh, np.column_stack([temp.time, temp.values]))
        _export_main(data, tmp, fmt, info, chunk_size, gtmp, rows)
    res = {"data": str(data), "format": fmt, "out": str(out), "samples": info.n_samples, "rate_hz": info.rate_hz,
           "gimbal": "columns" if fmt == "csv" and info.has_gimbal else (str(gimbal_out) if gimbal_out else None),
           "site": {"latitude_deg": info.site.latitude / DEG, "longitude_deg": info.site.longitude / DEG,
                    "height_m": info.site.height},
           "path": None if info.path is None else info.path.name,
           "path_out": None if path_out is None else str(path_out),
           "temperature": None if temp is None else ("not exported" if fmt != "csv" else
                                                     "interpolated" if rows is None else "columns"),
           "temperature_out": None if temperature_out is None else str(temperature_out)}
    return res


def _reading_rows(data, temp: Temperature, rate_hz: float, n: int, chunk_size: int) -> np.ndarray | None:
    """The sample index of each temperature reading when every reading lies on a sample time (to 1e-6 of
    the interval), else None; the record's time is read chunk by chunk."""
    tol = 1e-6 / rate_hz
    tr = temp.time
    rows = np.full(tr.shape[0], -1, dtype=np.int64)
    k0 = 0
    for (t,) in iter_window(data, ("time",), 0, n, chunk_size):
        a = int(np.searchsorted(tr, t[0] - tol))
        b = int(np.searchsorted(tr, t[-1] + tol, side="right"))
        if b > a:
            x = tr[a:b]
            j = np.searchsorted(t, x)
            lo, hi = np.clip(j - 1, 0, t.shape[0] - 1), np.clip(j, 0, t.shape[0] - 1)
            near = np.where(np.abs(t[lo] - x) <= np.abs(t[hi] - x), lo, hi)
            ok = np.abs(t[near] - x) <= tol
            rows[a:b] = np.where(ok, k0 + near, rows[a:b])
        k0 += t.shape[0]
    return rows if np.all(rows >= 0) else None


def _export_main(data, tmp: Path, fmt: str, info: RecordInfo, chunk_size: int, gtmp: Path | None,
                 rows: np.ndarray | None = None) -> None:
    """The record ``data`` written to ``tmp`` by the writer of ``fmt``'s module (``write(tmp, chunks, info,
    rows)``), its gimbal angles to ``gtmp`` (``time, outer, inner``) chunk by chunk as the writer reads them."""
    gfh = open(gtmp, "w") if gtmp is not None else None
    try:
        if gfh is not None:
            gfh.write(",".join(GIMBAL_HEADER) + "\n")

        def chunks():
            for t, dth, dv, g in iter_chunks(data, chunk_size):
                yield t, dth, dv, g
                if gfh is not None:
                    write_rows(gfh, np.column_stack([t, g]))

        reader(known_format(fmt, export=True)).write(tmp, chunks(), info, rows)
    finally:
        if gfh is not None:
            gfh.close()
