"""Rates sampled at their own time stamps -> increments on a uniform grid, by a stated rule whose noise
is white.

A ROS ``sensor_msgs/Imu`` message, and many loggers, give the angular rate and the specific force *at*
an instant (the stamp), at a rate that jitters.  An inscal record holds increments over the intervals
of a uniform grid, and every estimator takes their noise as white (independent increments of equal
variance ``N^2 D``, ``N`` the noise density, ``D = 1/rate``).  The rule used here holds each sample over
its *cell*, the stretch of time nearer its stamp than any other's (the midpoint rule of quadrature,
what an averaging sensor reports)::

    cell i  = [m_(i-1), m_i],   m_i = (t_i + t_(i+1)) / 2   (the first and last cells symmetric about
                                                              their stamp)
    P(t)    = x_i on cell i     (the piecewise-constant interpolant of the samples)
    dX_j    = integral of P over [T_(j-1), T_j],   T_j = T_0 + j / rate

with the grid's origin ``T_0`` half a step before the stamps' best-fitting grid (``t_i ~ T_0 + (k_i +
1/2) / rate``), so that stamps on a grid sit at the centres of its intervals and every increment is one
sample times the step, ``dX_j = D x_j``.  Each increment is written as the cells wholly inside its
interval plus the two partial pieces at its ends (no running sum that grows with the record, so an
increment keeps its full relative precision).

Noise (:func:`rule_weights`, :class:`NoiseShape`).  The increments are linear in the samples,
``dX = W x`` with ``W_ji`` the overlap of cell i with grid interval j.  Samples with white noise of density
``N`` over their mean step ``h`` (variance ``N^2 / h``: an averaging sensor, or a band-limited white noise
sampled at its rate) give increments of covariance ``N^2 / h  W W^T``: exactly the white ``N^2 D I`` the
estimators assume when the stamps fall on the grid (every increment one sample), and close to it under
jitter (a cell straddling a grid edge shares its sample between two increments, in proportion to
the straddle).  The integral of the linear interpolant (the trapezoid rule on a grid of stamps), by
contrast, gives neighbouring increments a correlation of 1/2 and half the variance: a second difference
of the increments then reads the noise 1/sqrt(6) of its density, and fits over such a record are
inconsistent with sigma that do not cover.  :class:`RateIntegration` reports the extremes of the
diagonal of ``W W^T / (h D)`` and of the neighbours' correlation.

Error bound (per increment, from the Taylor expansion of ``x`` about each stamp on each piece ``[a, b]`` of
a cell that the increment covers)::

    |dX_j - integral of x over [T_(j-1), T_j]|  <=  max|x'| sum |((b - t_i)^2 - (a - t_i)^2) / 2|
                                                  + max|x''| sum ((b - t_i)^3 - (a - t_i)^3) / 6
                                                 =  D^3 / 24 * max|x''|          stamps on the grid

The first term (zero on a grid, where every piece is a whole cell centred on its stamp) is the price of
jitter: a stamp off the centre of its cell holds its rate over a stretch it does not represent to first
order.  It does not accumulate: over many increments the pieces telescope, so an integrated angle keeps
an error of the order of one term.  ``max|x'|`` and ``max|x''|`` are estimated from the samples: the
largest first and second divided differences (each is the derivative at some point of its samples'
span), widened by the largest change between neighbouring ones and, for the first, by ``max|x''|``
times the longest step; :class:`RateIntegration` reports the resulting bound per channel, in the
increments' units.  On noisy data the divided differences measure the noise (``~ sigma / h``, ``sigma /
h^2``), and the bound says the rule's error is below the noise's share of an increment.  The rule needs
no stamp on the grid and so absorbs a jittered rate; a duplicated stamp, a stamp going backwards and a
gap of more than :data:`GAP_FACTOR` median steps (dropped messages) are refused by :func:`check_stamps`,
each named with the message and its time.
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
class NoiseShape:
    """The covariance of the increments' noise relative to the white model (module docstring), for samples
    with white noise of density ``N`` over their mean step: ``variance`` (min, max) of the diagonal of
    ``W W^T / (h D)`` (1 for white increments) and ``correlation`` the largest correlation between
    neighbouring increments (0 for white)."""

    variance: tuple[float, float]
    correlation: float

    @property
    def white(self) -> bool:
        """True when the increments' noise is the white model to 1e-9 (stamps on the grid)."""
        return abs(self.variance[0] - 1.0) < 1e-9 and abs(self.variance[1] - 1.0) < 1e-9 and self.correlation < 1e-9


@dataclass(frozen=True)
class RateIntegration:
    """Increments from sampled rates: the grid's end times ``time`` (M,) [s], the increments ``gyro``,
    ``accel`` (M, 3) [rad, m/s], the grid's ``rate_hz``, the sample steps' largest ``h_max`` [s] and the
    rule's error bound per channel ``bound`` (6,) [rad, rad, rad, m/s, m/s, m/s] (see the module
    docstring); ``on_grid``: the stamps fell on the grid (each increment one sample, the midpoint rule's
    bound); ``noise``: the shape of the increments' noise covariance (:class:`NoiseShape`)."""

    time: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    rate_hz: float
    h_max: float
    bound: np.ndarray
    on_grid: bool
    noise: NoiseShape
    gaps: int = 0  # steps of over GAP_FACTOR median steps bridged by the interpolant (``max_gap``)


#: what a gap's refusal suggests by default (the mapping of a CSV / text import of sampled rates)
BRIDGE_REMEDY = "max_gap_s in the mapping bridges them"


def check_stamps(t: np.ndarray, where: str, what: str = "message", at=None, max_gap: float | None = None,
                 remedy: str = BRIDGE_REMEDY) -> float:
    """The median step [s] of the stamps ``t`` (N,), after refusing a duplicated stamp, one going
    backwards (out-of-order messages) and a gap of over :data:`GAP_FACTOR` median steps (dropped
    messages), each with one line naming the ``what`` (``at(i)``: how to name sample i; default
    "message i + 1").  ``max_gap`` [s]: a longer step up to it is accepted (a logger's gaps, bridged by
    the samples on either side, each held over half of it; the error bound takes the longest step); ``remedy``: what the
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


def cell_edges(t: np.ndarray) -> np.ndarray:
    """The edges ``m_(-1) .. m_(N-1)`` (N + 1,) of the cells of stamps ``t`` (N,): midway between stamps, the
    first and the last cell symmetric about their stamp (module docstring)."""
    t = np.asarray(t, dtype=float)
    mid = 0.5 * (t[:-1] + t[1:])
    return np.concatenate([[t[0] - 0.5 * (t[1] - t[0])], mid, [t[-1] + 0.5 * (t[-1] - t[-2])]])


def grid_origin(t: np.ndarray, rate: float) -> tuple[float, bool]:
    """``(T_0, on_grid)``: the grid's origin, half a step before the best-fitting grid of the stamps
    ``t`` (each stamp at the centre of its interval when they lie on a grid), moved on by whole steps
    until it lies inside the first cell; ``on_grid``: every stamp within 1e-9 steps of its centre."""
    t = np.asarray(t, dtype=float)
    d = 1.0 / rate
    k = np.round((t - t[0]) * rate)
    off = t - k * d  # the stamps' phase against the grid (a gap: k skips the missing indices)
    on_grid = bool(np.all(np.abs(off - t[0]) <= 1e-9 * d))
    t0 = (t[0] if on_grid else float(np.mean(off))) - 0.5 * d
    first = t[0] - 0.5 * (t[1] - t[0])
    if t0 < first - 1e-9 * d:
        t0 += np.ceil((first - t0) * rate - 1e-9) * d
    return float(t0), on_grid


def rule_weights(t: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The rule as a matrix: ``W`` (M, N) with ``W_ji`` the overlap [s] of cell i of stamps ``t`` (N,) with
    grid interval ``[grid_(j-1), grid_j]`` (``grid`` (M + 1,)); ``dX = W x``.  Dense: for checks and for
    the noise shape of a short stretch, not for a whole record."""
    return _overlap(cell_edges(t), np.asarray(grid, dtype=float))


def _overlap(e: np.ndarray, grid: np.ndarray) -> np.ndarray:
    lo = np.maximum(grid[:-1, None], e[None, :-1])
    hi = np.minimum(grid[1:, None], e[None, 1:])
    return np.clip(hi - lo, 0.0, None)


def _noise_shape(t: np.ndarray, e: np.ndarray, grid: np.ndarray, rate: float, on_grid: bool,
                 block: int = 2048) -> NoiseShape:
    """The extremes of the increments' noise covariance relative to white (module docstring), from the
    rule's overlaps, block by block of increments (each meets only the cells it overlaps)."""
    if on_grid:
        return NoiseShape((1.0, 1.0), 0.0)
    d = 1.0 / rate
    h = float((t[-1] - t[0]) / (t.shape[0] - 1))
    vmin, vmax, cmax = np.inf, 0.0, 0.0
    m = grid.shape[0] - 1
    for a in range(0, m, block):
        g = grid[a:min(m, a + block + 1) + 1]  # one increment more: the correlation across the blocks' edge
        i0 = max(0, int(np.searchsorted(e, g[0], side="right")) - 1)
        i1 = min(e.shape[0] - 1, int(np.searchsorted(e, g[-1], side="left")))
        W = _overlap(e[i0:i1 + 1], g)
        var = np.sum(W * W, axis=1) / (h * d)
        cov = np.sum(W[:-1] * W[1:], axis=1) / (h * d)
        vmin, vmax = min(vmin, float(var.min())), max(vmax, float(var.max()))
        if cov.size:
            cmax = max(cmax, float(np.max(cov / np.sqrt(var[:-1] * var[1:]))))
    return NoiseShape((float(vmin), float(vmax)), float(cmax))


def integrate_rates(t, gyro, accel, rate_hz: float | None = None) -> RateIntegration:
    """Integrate rates ``gyro`` [rad/s] and ``accel`` [m/s^2] (N, 3) sampled at stamps ``t`` (N,) [s]
    (increasing; :func:`check_stamps` first) onto the grid ``T_j = T_0 + j / rate``, ``j = 1 .. M``
    (``rate_hz`` default :func:`grid_rate`; ``T_0`` from :func:`grid_origin`) inside the stamps' cells,
    by the rule of the module docstring."""
    t = np.asarray(t, dtype=float)
    x = np.column_stack([np.asarray(gyro, dtype=float), np.asarray(accel, dtype=float)])
    n = t.shape[0]
    rate = grid_rate(t) if rate_hz is None else float(rate_hz)
    span = t[-1] - t[0]
    mean = (n - 1) / span
    if not (np.isfinite(rate) and abs(rate / mean - 1.0) <= RATE_TOL):
        raise ImportFileError(f"--rate-hz {rate:g} is inconsistent with the stamps: {mean:.9g} Hz on average "
                              f"(limit {RATE_TOL:g} relative; the grid would resample the rates)")
    e = cell_edges(t)
    t0, on_grid = grid_origin(t, rate)
    m = int(np.floor((e[-1] - t0) * rate * (1.0 + 1e-12) + 1e-9))
    if m < 2:
        raise ImportFileError(f"the stamps span {span:.6g} s: fewer than 2 intervals at {rate:g} Hz")
    grid = t0 + np.arange(m + 1) / rate
    grid[0], grid[-1] = max(grid[0], e[0]), min(grid[-1], e[-1])
    cell = np.diff(e)
    whole = x * cell[:, None]  # the integral of P over each cell
    k = np.clip(np.searchsorted(e, grid, side="right") - 1, 0, n - 1)  # the cell holding each T_j
    s = grid - e[k]
    part = x[k] * s[:, None]  # integral of P from the start of cell k to T_j
    seg = np.add.reduceat(np.vstack([whole, np.zeros((1, 6))]), k, axis=0)[:-1]
    seg = np.where((k[1:] > k[:-1])[:, None], seg, 0.0)
    inc = seg - part[:-1] + part[1:]
    if on_grid and m == n:  # every increment one whole cell of one step: D x_j, without the pieces' round-off
        inc = x / rate
    h = np.diff(t)
    h_max = float(np.max(h))
    # max |x'| and max |x''| from the divided differences
    d1 = np.diff(x, axis=0) / h[:, None]
    dd = np.diff(d1, axis=0) / (0.5 * (h[:-1] + h[1:]))[:, None]
    curv = np.max(np.abs(dd), axis=0) if dd.shape[0] else np.zeros(6)
    if dd.shape[0] > 1:
        curv = curv + 2.0 * np.max(np.abs(np.diff(dd, axis=0)), axis=0)
    slope = np.max(np.abs(d1), axis=0) + np.max(np.abs(np.diff(d1, axis=0)), axis=0) + curv * h_max
    dgrid = 1.0 / rate
    if on_grid:
        bound = dgrid ** 3 / 24.0 * curv
    else:
        c1, c2 = _piece_terms(t, e, grid)
        bound = slope * c1 + curv * c2
    noise = _noise_shape(t, e, grid, rate, on_grid)
    return RateIntegration(grid[1:], np.ascontiguousarray(inc[:, :3]), np.ascontiguousarray(inc[:, 3:]), rate, h_max,
                           bound, on_grid, noise)


def _piece_terms(t: np.ndarray, e: np.ndarray, grid: np.ndarray) -> tuple[float, float]:
    """The largest over the increments of ``sum |((b - t_i)^2 - (a - t_i)^2) / 2|`` and of ``sum ((b - t_i)^3 -
    (a - t_i)^3) / 6`` over their pieces ``[a, b]`` of cells (the error bound's geometry, module docstring)."""
    # every piece: the cells' edges and the grid's, merged; a piece lies in one cell and one grid interval
    pts = np.union1d(e, grid[(grid > e[0]) & (grid < e[-1])])
    pts = pts[(pts >= grid[0]) & (pts <= grid[-1])]
    a, b = pts[:-1], pts[1:]
    mid = 0.5 * (a + b)
    i = np.clip(np.searchsorted(e, mid, side="right") - 1, 0, t.shape[0] - 1)
    j = np.clip(np.searchsorted(grid, mid, side="right") - 1, 0, grid.shape[0] - 2)
    ua, ub = a - t[i], b - t[i]
    c1 = np.abs(ub * ub - ua * ua) / 2.0
    c2 = (ub ** 3 - ua ** 3) / 6.0
    m = grid.shape[0] - 1
    return float(np.bincount(j, c1, m).max()), float(np.bincount(j, c2, m).max())
