"""``--format psins-imu``: the PSINS compact text SIMU log (``.imu``, as PSINS's ``imufile`` writes it),
a header (initial attitude and velocity, site, start time, interval, g, scale factors) and integer counts."""

from __future__ import annotations

import math

from io import StringIO
from pathlib import Path as FsPath

import numpy as np

from inscal.core import units
from inscal.io.formats.base import Raw, ReadOptions, text_lines
from inscal.io.mapping import MAX_RATE_HZ, MIN_RATE_HZ, ImportFileError


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
    lines = text_lines(p, ": a PSINS .imu log is text")
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



def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY` (a ``.imu`` log takes no option)."""
    return read_psins_imu(FsPath(src))
