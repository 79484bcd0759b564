"""Rates sampled at their own time stamps -> increments on a uniform grid, by a stated second-order rule.

A ROS ``sensor_msgs/Imu`` message, and many loggers, give the angular rate and the specific force *at*
an instant (the stamp), at a rate that jitters.  An inscal record holds increments over the intervals
of a uniform grid.  The rule used here:

    x(t) ~ L(t), the piecewise-linear interpolant of the samples (t_i, x_i)
    dX_j  = integral of L over [T_(j-1), T_j],   T_j = t_0 + j / rate           (exact for that L)

written per grid interval as the sum of the trapezoids of the sample intervals wholly inside it plus
the two partial pieces at its ends (the quadratic ``x_k s + (x_(k+1) - x_k) s^2 / (2 h_k)`` of the
interpolant's integral from ``t_k`` to ``t_k + s``), summed per interval (no running sum that
grows with the record, so an increment keeps its full relative precision).  When the stamps fall on
the grid it is the trapezoid rule ``dX = h (x_(k-1) + x_k) / 2``.

Error bound (the interpolation error of a linear interpolant, ``|x - L| <= h^2/8 max|x''|``, integrated;
the trapezoid rule's ``h^3/12 max|x''|``)::

    |dX_j - integral of x over [T_(j-1), T_j]|  <=  D h_max^2 / 8 * max|x''|      (D = 1/rate)
                                                 <=  D^3 / 12 * max|x''|           stamps on the grid

``max|x''|`` is estimated from the samples: the largest second divided difference (each is ``x''`` at
some point of its three samples' span), widened by twice the largest change between neighbouring
ones (``x''`` between the points it was sampled at, to first order); :class:`RateIntegration` reports
the resulting bound per channel, in the increments' units.  On noisy data the divided differences
measure the noise (``~ sigma / h^2``), and the bound says the rule's error is below the noise's share
of an increment.  The rule needs no stamp on the
grid and so absorbs a jittered rate; a duplicated stamp, a stamp going backwards and a gap of more
than :data:`GAP_FACTOR` median steps (dropped messages) are refused by :func:`check_stamps`, each named
with the message and its time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from inscal.io.mapping import ImportFileError

#: a step longer than this many median steps is a gap: messages were dropped
GAP_FACTOR = 1.5
#: a given grid rate may differ from the stamps' mean rate by this fraction (a clock's drift)
RATE_TOL = 1e-3


@dataclass(frozen=True)
class RateIntegration:
    """Increments from sampled rates: the grid's end times ``time`` (M,) [s], the increments ``gyro``,
    ``accel`` (M, 3) [rad, m/s], the grid's ``rate_hz``, the sample steps' largest ``h_max`` [s] and the
    rule's error bound per channel ``bound`` (6,) [rad, rad, rad, m/s, m/s, m/s] (see the module
    docstring); ``on_grid``: the stamps fell on the grid (the trapezoid rule's bound)."""

    time: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    rate_hz: float
    h_max: float
    bound: np.ndarray
    on_grid: bool
    gaps: int = 0  # steps of over GAP_FACTOR median steps bridged by the interpolant (``max_gap``)


#: what a gap's refusal suggests by default (the mapping of a CSV / text import of sampled rates)
BRIDGE_REMEDY = "max_gap_s in the mapping bridges them"


def check_stamps(t: np.ndarray, where: str, what: str = "message", at=None, max_gap: float | None = None,
                 remedy: str = BRIDGE_REMEDY) -> float:
    """The median step [s] of the stamps ``t`` (N,), after refusing a duplicated stamp, one going
    backwards (out-of-order messages) and a gap of over :data:`GAP_FACTOR` median steps (dropped
    messages), each with one line naming the ``what`` (``at(i)``: how to name sample i; default
    "message i + 1").  ``max_gap`` [s]: a longer step up to it is accepted (a logger's gaps, bridged by
    the linear interpolant; the error bound takes the longest step, ``h_max``); ``remedy``: what the
    refusal of a gap suggests (an import without a mapping has no ``max_gap_s``)."""
    t = np.asarray(t, dtype=float)
    name = at if at is not None else (lambda i: f"{what} {i + 1}")
    if t.shape[0] < 3:
        raise ImportFileError(f"{where}: {t.shape[0]} {what}(s); at least 3 are needed")
    if not np.all(np.isfinite(t)):
        i = int(np.argmax(~np.isfinite(t)))
        raise ImportFileError(f"{where}: the stamp of {name(i)} is {t[i]}")
    d = np.diff(t)
    if np.any(d < 0):
        i = int(np.argmax(d < 0)) + 1
        raise ImportFileError(f"{where}: stamps go backwards at {name(i)}: t = {t[i]:.9f} s after {t[i - 1]:.9f} s "
                              f"({-d[i - 1]:.3g} s earlier; out-of-order messages)")
    if np.any(d == 0):
        i = int(np.argmax(d == 0)) + 1
        raise ImportFileError(f"{where}: duplicated stamp at {name(i)}: t = {t[i]:.9f} s, the same as {name(i - 1)}")
    step = float(np.median(d))
    big = d > max(GAP_FACTOR * step, max_gap or 0.0)
    if np.any(big):
        i = int(np.argmax(big)) + 1
        lost = int(round(d[i - 1] / step)) - 1
        raise ImportFileError(f"{where}: {max(lost, 1)} {what}(s) dropped before {name(i)}: a gap of {d[i - 1]:.6g} s "
                              f"from t = {t[i - 1]:.9f} s to {t[i]:.9f} s, the median step being {step:.6g} s "
                              f"({int(np.count_nonzero(big))} gap(s) in all"
                              + (f" over max_gap_s = {max_gap:g}" if max_gap else f"; {remedy}") + ")")
    return step


def grid_rate(t: np.ndarray) -> float:
    """The grid rate of stamps ``t`` [Hz]: their mean rate ``(N - 1) / (t_N - t_1)``, to 10 digits."""
    return float(f"{(t.shape[0] - 1) / (t[-1] - t[0]):.10g}")


def integrate_rates(t, gyro, accel, rate_hz: float | None = None) -> RateIntegration:
    """Integrate rates ``gyro`` [rad/s] and ``accel`` [m/s^2] (N, 3) sampled at stamps ``t`` (N,) [s]
    (increasing; :func:`check_stamps` first) onto the grid ``T_j = t_0 + j / rate``, ``j = 1 .. M``
    (``rate_hz`` default :func:`grid_rate`) inside the stamps, by the rule of the module docstring."""
    t = np.asarray(t, dtype=float)
    x = np.column_stack([np.asarray(gyro, dtype=float), np.asarray(accel, dtype=float)])
    n = t.shape[0]
    rate = grid_rate(t) if rate_hz is None else float(rate_hz)
    span = t[-1] - t[0]
    mean = (n - 1) / span
    if not (np.isfinite(rate) and abs(rate / mean - 1.0) <= RATE_TOL):
        raise ImportFileError(f"--rate-hz {rate:g} is inconsistent with the stamps: {mean:.9g} Hz on average "
                              f"(limit {RATE_TOL:g} relative; the grid would resample the rates)")
    m = int(np.floor(span * rate * (1.0 + 1e-12)))
    if m < 2:
        raise ImportFileError(f"the stamps span {span:.6g} s: fewer than 2 intervals at {rate:g} Hz")
    grid = t[0] + np.arange(m + 1) / rate
    grid[-1] = min(grid[-1], t[-1])
    h = np.diff(t)
    trap = 0.5 * (x[:-1] + x[1:]) * h[:, None]  # S: trapezoid of each sample interval
    k = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, n - 2)  # sample interval holding each T_j
    s = (grid - t[k])[:, None]
    part = x[k] * s + (x[k + 1] - x[k]) * (s * s) / (2.0 * h[k][:, None])  # integral of L from t_k to T_j
    # whole sample intervals k_(j-1) .. k_j - 1 inside grid interval j, summed per interval
    seg = np.add.reduceat(np.vstack([trap, np.zeros((1, 6))]), k, axis=0)[:-1]
    seg = np.where((k[1:] > k[:-1])[:, None], seg, 0.0)
    inc = seg - part[:-1] + part[1:]
    h_max = float(np.max(h))
    # max |x''| from the second divided differences
    dd = np.diff(np.diff(x, axis=0) / h[:, None], axis=0) / (0.5 * (h[:-1] + h[1:]))[:, None]
    curv = np.max(np.abs(dd), axis=0) if dd.shape[0] else np.zeros(6)
    if dd.shape[0] > 1:
        curv = curv + 2.0 * np.max(np.abs(np.diff(dd, axis=0)), axis=0)
    on_grid = bool(np.allclose(t[1:m + 1] - t[0], np.arange(1, m + 1) / rate, rtol=0, atol=1e-9 / rate))
    dgrid = 1.0 / rate
    bound = (dgrid ** 3 / 12.0 if on_grid else dgrid * h_max ** 2 / 8.0) * curv
    return RateIntegration(grid[1:], np.ascontiguousarray(inc[:, :3]), np.ascontiguousarray(inc[:, 3:]), rate, h_max,
                           bound, on_grid)
