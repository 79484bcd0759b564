"""Samples of a hand-held logger (instantaneous rates and specific forces at their own, jittered
timestamps, possibly raw integer counts) turned into the increments every inscal estimator reads.

Units: time in ``s``, ``ms`` or ``us``; gyros in a rate unit (``rad/s``, ``deg/s``) or ``counts`` with a
scale (one count, in a rate unit) and an offset (counts at zero rate); accelerometers in an acceleration
unit (``m/s^2``, ``g``) or ``counts`` likewise.  Converted in :mod:`inscal.core.units` only.

Increments by the midpoint rule on the logger's own time base (the rule of :mod:`inscal.io.formats.rates`
without its uniform grid): each sample held over its cell, the times nearer its stamp than any other's::

    dtheta_k = w_k (m_k - m_(k-1)),   m_k = (t_k + t_(k+1)) / 2 (the first and last cells symmetric),   dvel_k likewise

one increment per sample, ending at ``m_k``, so the increments' noise is independent from one to the next
(the trapezoid rule's neighbours would correlate by 1/2, and the estimators take it as white), a
jittered clock costs nothing to second order in a still pose, and a gap stays a long interval (which
:mod:`inscal.calibrate.static_detect` names and keeps out of the still poses).  A gyro at its clip level
(``gyro_range`` in the gyro's unit) is reported as the samples it holds; the calibration drops the rotation
it falls in (with a note).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from inscal.core import units
from inscal.core.samples import triad_series
from inscal.io.formats.rates import cell_edges
from inscal.io.records import DataFileError


@dataclass(frozen=True)
class LoggerIncrements:
    """Increments on the logger's time base (SI): ``time`` the end of each interval."""

    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    gyro_clipped: np.ndarray  # bool per interval: its sample's gyro at its clip level
    notes: tuple[str, ...] = ()


def _to_si(x: np.ndarray, unit: str, kind: str, counts: tuple[float, float] | None, what: str) -> np.ndarray:
    if unit == "counts":
        if counts is None:
            raise DataFileError(f"{what} in counts needs its scale and offset (scale in a {kind} unit)")
        scale, offset = counts
        return (x - offset) * float(scale)
    try:
        return np.asarray(units.to_si(x, unit, kind), float)
    except ValueError as exc:
        raise DataFileError(f"{what}: {exc}") from None


def increments_from_samples(time, gyro, accel, *, time_unit: str = "s", gyro_unit: str = "rad/s",
                            accel_unit: str = "m/s^2", gyro_counts: tuple[float, float] | None = None,
                            accel_counts: tuple[float, float] | None = None,
                            gyro_range: float | None = None) -> LoggerIncrements:
    """The increments of logger samples (module docstring).  ``gyro_counts`` / ``accel_counts``:
    ``(scale, offset)`` with the scale in SI (rad/s, m/s^2 per count), for the ``counts`` unit;
    ``gyro_range``: the clip level in ``gyro_unit`` (counts: in counts)."""
    t_raw, g_raw, a_raw = triad_series(time, gyro, accel, DataFileError,
                                       "logger samples: time (n,), gyro (n, 3), accel (n, 3); got {}, {}, {}")
    n = t_raw.shape[0]
    if n < 3:
        raise DataFileError(f"logger samples: {n} samples, too few")
    for name, x in (("time", t_raw), ("gyro", g_raw), ("accel", a_raw)):
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.argmax(bad.reshape(n, -1).any(axis=1)))
            raise DataFileError(f"logger samples: {name} is not a number at sample {k}")
    try:
        t = np.asarray(units.to_si(t_raw, time_unit, "time"), float)
    except ValueError as exc:
        raise DataFileError(f"time: {exc}") from None
    st = np.diff(t)
    if np.any(st <= 0):
        k = int(np.argmax(st <= 0))
        raise DataFileError(f"logger samples: time does not increase at sample {k + 1} ({t_raw[k]:.9g} then "
                            f"{t_raw[k + 1]:.9g} {time_unit})")
    w = _to_si(g_raw, gyro_unit, "rate", gyro_counts, "gyro")
    f = _to_si(a_raw, accel_unit, "accel", accel_counts, "accel")
    clip = np.zeros(n, bool) if gyro_range is None else np.any(np.abs(g_raw) >= gyro_range, axis=1)
    e = cell_edges(t)
    cell = np.diff(e)[:, None]  # midpoint rule: one sample per increment, second order on any time base
    dth, dv = w * cell, f * cell
    notes = []
    if clip.any():
        notes.append(f"{int(clip.sum())} gyro sample(s) at the clip level {gyro_range:g} {gyro_unit}")
    return LoggerIncrements(e[1:], dth, dv, clip, tuple(notes))
