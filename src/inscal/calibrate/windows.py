"""Segmenting a turntable record into static dwell windows and constant-rate windows.

A *window* is a run of whole samples ``[i0, i1)`` on which the gimbal is either at
rest (``kind == "static"``) or turning one axis at a constant rate (``kind == "rate"``).
Each window carries the mean measured rates ``gyro = sum(dtheta) / T`` and
``accel = sum(dvel) / T`` (output units per second), the standard deviation of these
means and the gimbal angles the calibration model needs.

Detection (from the recorded gimbal angles, or from the increments when a record has
no angle channel):

* the angle channels are unwrapped and checked for jumps (a one-sample change far
  above what the turntable's acceleration and the encoder noise allow);
* a centred finite-difference rate over ``2 * smooth`` seconds classifies every sample
  as static (both axes slower than ``static_tol``), single-axis constant rate, or moving;
* ``settle`` seconds are dropped at both ends of every window (turntable settling, and
  the smoothing half-width is already excluded by the centred difference);
* static windows shorter than ``min_static`` seconds are ignored;
* a constant-rate window is cut to the largest whole number of turns that fits inside
  the constant-rate part (centred), so the rotating Earth-rate and gravity components
  average out; the exact model (:mod:`.window_model`) uses the window's start and end angles,
  so a residual fraction of a turn is modelled, not neglected;
* a move of less than one turn (e.g. the +-90 deg moves of an S16 or PSINS path) gives a
  *turn* window (``kind == "turn"``): its whole constant-rate part, with the angles turned
  known from the encoders or the path (``partial_turns``; at least ``min_turn_s`` seconds
  and ``min_turn_deg`` degrees).  The same exact constant-rate model holds (the mean of a
  rotation over a partial turn, :func:`.window_model.mean_rot_T`), so these windows carry the
  gyro scale factors and installation angles for :mod:`.joint` on paths without full-turn
  rate tests.  The classical CW/CCW rate tests (N25 eq. 28) use whole-turn ``rate``
  windows only.

Noise of a window mean: the per-sample white-noise level is estimated from the second
differences of the per-sample rates (robust MAD, insensitive to the slow signal change
inside a rotating window), divided by ``sqrt(n)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

from inscal.core.earth import Site
from inscal.core.robust import exact_median
from inscal.core.units import ARCSEC, DEG


class CalibrationError(ValueError):
    """Data that cannot be calibrated with the requested method, with the reason (a ``ValueError``).

    Examples
    --------
    >>> from inscal.calibrate import CalibrationError, calibrate
    >>> try:
    ...     calibrate(None, "seven-position")
    ... except CalibrationError as exc:
    ...     print(str(exc)[:31])
    unknown method 'seven-position'
    """


@dataclass(frozen=True)
class Window:
    """One static or constant-rate window of a turntable record, averaged (SI).

    Parameters
    ----------
    kind : str
        ``"static"``, ``"rate"`` (whole turns) or ``"turn"`` (part of a turn).
    i0, i1 : int
        The first sample and one past the last.
    t0, t1 : float
        The start of the first sample interval and the end of the last [s].
    theta0, theta1 : numpy.ndarray
        The gimbal angles (theta_x, theta_z) at ``t0`` and ``t1`` [rad] (static: the window mean).
    axis : str
        The turning axis: ``"none"``, ``"outer"`` or ``"inner"``.
    rate : float
        The signed turntable rate of ``axis`` [rad/s] (0 for static).
    gyro, accel : numpy.ndarray
        (3,) mean gyro [rad/s] and accelerometer [m/s^2] outputs.
    gyro_sigma, accel_sigma : numpy.ndarray
        (3,) their 1 sigma.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import window_means
    >>> from inscal.sim.records import scenario_record
    >>> ws = window_means(scenario_record("n25", np.random.default_rng(0), rate_hz=10.0))
    >>> w = ws.static[0]
    >>> w.describe()
    'static (0.0, 0.0) deg, 1.5-98.5 s'
    >>> round(float(np.linalg.norm(w.accel)), 2)  # gravity, plus the accelerometer errors
    9.8
    """

    kind: str  # "static", "rate" (whole turns) or "turn" (part of a turn)
    i0: int  # first sample
    i1: int  # one past the last sample
    t0: float  # start of the first sample interval [s]
    t1: float  # end of the last sample interval [s]
    theta0: np.ndarray  # angles at t0 (static: the window mean)
    theta1: np.ndarray  # angles at t1 (static: the window mean)
    axis: str  # "none", "outer" or "inner"
    rate: float  # signed turntable rate of ``axis`` [rad/s] (0 for static)
    gyro: np.ndarray  # mean gyro output [rad/s]
    accel: np.ndarray  # mean accelerometer output [m/s^2]
    gyro_sigma: np.ndarray  # 1 sigma of ``gyro`` [rad/s]
    accel_sigma: np.ndarray  # 1 sigma of ``accel`` [m/s^2]

    @property
    def duration(self) -> float:
        return self.t1 - self.t0

    @property
    def theta(self) -> np.ndarray:
        """Mean angles (static windows) / mid-window angles (rate windows)."""
        return 0.5 * (self.theta0 + self.theta1)

    def describe(self) -> str:
        th = np.degrees(self.theta)
        if self.kind == "static":
            return f"static ({th[0]:.1f}, {th[1]:.1f}) deg, {self.t0:.1f}-{self.t1:.1f} s"
        turned = f" ({np.degrees(abs(self.theta1 - self.theta0)).max():.0f} deg)" if self.kind == "turn" else ""
        return f"{self.axis} {self.rate / DEG:+.2f} deg/s{turned}, {self.t0:.1f}-{self.t1:.1f} s"


@dataclass
class WindowSet:
    """The windows of one record (:func:`window_means`), with the site and rate they were recorded at.

    Parameters
    ----------
    windows : list of Window
        The static and constant-rate windows, in time order.
    site : Site
        The site of the record.
    rate_hz : float
        The record's sample rate [Hz].
    info : dict
        What the segmentation found and used (tolerances, rejected windows).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import window_means
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("n25", np.random.default_rng(0), rate_hz=10.0)  # N25 path, errors, noise
    >>> ws = window_means(rec)
    >>> len(ws.windows), len(ws.static), len(ws.rate)
    (42, 21, 6)
    """

    windows: list[Window]
    site: Site
    rate_hz: float
    info: dict = field(default_factory=dict)

    @property
    def static(self) -> list[Window]:
        return [w for w in self.windows if w.kind == "static"]

    @property
    def rate(self) -> list[Window]:
        return [w for w in self.windows if w.kind == "rate"]

    @property
    def turn(self) -> list[Window]:
        return [w for w in self.windows if w.kind == "turn"]

    def replace_means(self, gyro: np.ndarray, accel: np.ndarray) -> WindowSet:
        """A copy with the window means replaced (rows in window order); used for error propagation."""

        ws = [replace(w, gyro=np.asarray(gyro[k], float), accel=np.asarray(accel[k], float)) for k, w in enumerate(self.windows)]
        return WindowSet(ws, self.site, self.rate_hz, self.info)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open [start, stop) runs of True in a boolean array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _centred_rate(x: np.ndarray, h: int, dt: float) -> np.ndarray:
    """Centred difference rate over +-h samples (NaN at the edges); x is (N, k)."""
    r = np.full(x.shape, np.nan)
    if x.shape[0] > 2 * h:
        r[h:-h] = (x[2 * h:] - x[:-2 * h]) / (2 * h * dt)
    return r


@njit(cache=True)
def _second_difference_mad(x, dt):
    """Per column of ``x`` (n, k), n >= 3: the median absolute deviation of the second differences of
    ``x / dt`` (times 1.4826), value for value what ``1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)``
    gives for ``d = np.diff(x / dt, n=2, axis=0)`` (the
    same divisions and differences; a median is one value of the data whatever finds it), without the four
    temporaries and the strided, branch-bound partitions of NumPy's median per window."""
    n, k = x.shape
    m = n - 2
    out = np.empty(k)
    d = np.empty(m)
    pair = np.empty(2)
    for j in range(k):
        y0 = x[0, j] / dt
        y1 = x[1, j] / dt
        d1 = y1 - y0
        for i in range(m):
            y2 = x[i + 2, j] / dt
            d2 = y2 - y1
            d[i] = d2 - d1
            y1 = y2
            d1 = d2
        med = exact_median(d, pair)
        for i in range(m):
            d[i] = abs(d[i] - med)
        out[j] = 1.4826 * exact_median(d, pair)
    return out


@njit(cache=True)
def _largest_step(p):
    """The largest ``|p[i + 1, j] - p[i, j]|`` of an (n, k) array; infinite if it holds a NaN."""
    big = 0.0
    for j in range(p.shape[1]):
        for i in range(p.shape[0] - 1):
            s = abs(p[i + 1, j] - p[i, j])
            if not s <= big:
                if s != s:
                    return np.inf
                big = s
    return big


def unwrap_angles(p: np.ndarray) -> np.ndarray:
    """``np.unwrap(p, axis=0)`` value for value.  Angles recorded without wrap (every step below half a turn)
    need no correction, and NumPy then returns ``p + 0.0``: that case is found in one compiled pass instead of
    the five temporaries of the general one."""
    p = np.ascontiguousarray(p, dtype=float)
    if p.ndim != 2 or p.shape[0] < 2 or not _largest_step(p) < math.pi:
        return np.unwrap(p, axis=0)
    up = p.copy()
    up[1:] += 0.0
    return up


def all_columns(m: np.ndarray) -> np.ndarray:
    """``np.all(m, axis=1)`` for an (n, k) boolean array with few columns, as k column operations instead of a
    reduction along the short axis (ten times slower for k = 2)."""
    out = m[:, 0].copy()
    for j in range(1, m.shape[1]):
        out &= m[:, j]
    return out


def _get(rec, name, required=True):
    v = getattr(rec, name, None)
    if v is None and required:
        raise CalibrationError(f"record has no '{name}'")
    return v


def check_gimbal_jumps(theta: np.ndarray, dt: float, time: np.ndarray | None = None,
                       max_accel: float = 50.0 * DEG, jump_tol: float | None = None) -> None:
    """Raise :class:`CalibrationError` if an (unwrapped) angle channel jumps.

    The second difference of a real turntable angle is bounded by ``max_accel dt^2`` plus
    encoder noise; a glitch of size J gives a second difference of about J.
    """
    if theta.shape[0] < 3:
        return
    dd = np.diff(theta, n=2, axis=0)
    sig = _second_difference_mad(np.ascontiguousarray(theta, dtype=float), 1.0) / math.sqrt(6.0)
    for ax, name in enumerate(("outer (theta_x)", "inner (theta_z)")):
        tol = jump_tol if jump_tol is not None else max(60.0 * ARCSEC, 10.0 * math.sqrt(6.0) * sig[ax], 2.0 * max_accel * dt * dt)
        bad = np.flatnonzero(np.abs(dd[:, ax]) > tol)
        if bad.size:
            k = int(bad[0]) + 1
            step = theta[k + 1, ax] - theta[k, ax] - (theta[k, ax] - theta[k - 1, ax])
            when = f" at t = {time[k]:.3f} s" if time is not None else ""
            raise CalibrationError(
                f"gimbal angle channel {name} jumps by {step / ARCSEC:.1f} arcsec{when} (sample {k}); "
                f"the angle record is corrupt there (limit {tol / ARCSEC:.1f} arcsec per sample)")


def window_means(record_like, settle: float = 1.0, min_static: float = 20.0, smooth: float = 0.5,
                 static_tol: float = 0.01 * DEG, rate_min: float = 1.0 * DEG, rate_rel_tol: float = 1e-3,
                 min_turns: int = 1, increment_static_tol: float = 0.05 * DEG, jump_tol: float | None = None,
                 partial_turns: bool = True, min_turn_s: float = 2.0, min_turn_deg: float = 10.0) -> WindowSet:
    """Find the static and constant-rate windows of a turntable record and average each.

    Parameters
    ----------
    record_like : Record
        Anything with ``time``, ``dtheta``, ``dvel``, ``gimbal``, ``rate_hz`` and ``site``;
        ``gimbal`` may be None: the windows are then found from the gyro increments and the angles
        are taken from ``record_like.path``.
    settle : float
        Seconds dropped at each end of a window (the table settling) [s].
    min_static : float
        The shortest static window kept [s].
    smooth : float
        The span of the angle-rate estimate [s].
    static_tol : float
        The largest angle rate of a static window [rad/s].
    rate_min : float
        The smallest turntable rate of a rate window [rad/s].
    rate_rel_tol : float
        The largest relative change of the rate within a rate window.
    min_turns : int
        The fewest whole turns of a rate window.
    increment_static_tol : float
        The largest body rate of a static window from the increments, without angles [rad/s].
    jump_tol : float, optional
        The largest second difference of an angle channel [rad] (default: from the encoder noise
        and ``50 deg/s^2``).
    partial_turns : bool
        Keep the parts of turns (``"turn"`` windows) too.
    min_turn_s, min_turn_deg : float
        The shortest partial turn kept [s], [deg].

    Returns
    -------
    WindowSet
        The windows, in time order, with the site and rate.

    Raises
    ------
    CalibrationError
        A record without one of the fields, jumps in the gimbal angles, or no window found.

    Examples
    --------
    >>> from numpy.random import default_rng
    >>> from inscal.sim.records import scenario_record
    >>> from inscal.calibrate.windows import window_means
    >>> ws = window_means(scenario_record("n25", default_rng(0), rate_hz=10.0))
    >>> ws.rate_hz, ws.windows[0].kind, ws.rate[0].axis
    (10.0, 'static', 'inner')
    """
    time = np.asarray(_get(record_like, "time"), float)
    dth = np.asarray(_get(record_like, "dtheta"), float)
    dv = np.asarray(_get(record_like, "dvel"), float)
    rate_hz = float(_get(record_like, "rate_hz"))
    site = _get(record_like, "site")
    gim = getattr(record_like, "gimbal", None)
    n = time.shape[0]
    if dth.shape != (n, 3) or dv.shape != (n, 3):
        raise CalibrationError(f"dtheta/dvel must be ({n}, 3) arrays, got {dth.shape} and {dv.shape}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise CalibrationError(f"sample rate must be > 0 Hz, got {rate_hz}")
    dt = 1.0 / rate_hz
    if n < 10 * rate_hz:
        raise CalibrationError(f"record too short ({n} samples, {n * dt:.1f} s) to hold any calibration window")
    h = max(1, int(round(smooth * rate_hz)))
    ns = int(round(settle * rate_hz))
    info = {"source": "gimbal angles" if gim is not None else "increments"}
    theta, rate, static, moving_axis = _motion(record_like, gim, time, dth, dt, h, static_tol, rate_min,
                                               increment_static_tol, jump_tol)

    # white-noise level per sample from second differences of the per-sample rates
    def noise(x):  # of the per-sample rates x / dt
        if x.shape[0] < 8:
            return np.zeros(3)
        return _second_difference_mad(np.ascontiguousarray(x), dt) / math.sqrt(6.0)

    def make(kind, a, b, axis="none", rate_val=0.0, th0=None, th1=None):
        T = (b - a) * dt
        g = dth[a:b].sum(axis=0) / T
        f = dv[a:b].sum(axis=0) / T
        gs = noise(dth[a:b]) / math.sqrt(b - a)
        fs = noise(dv[a:b]) / math.sqrt(b - a)
        if th0 is None:
            th0 = th1 = theta[a:b].mean(axis=0)
        return Window(kind, int(a), int(b), float(time[a] - dt), float(time[b - 1]), np.asarray(th0, float),
                      np.asarray(th1, float), axis, float(rate_val), g, f, gs, fs)

    windows = []
    for a, b in _runs(static):
        a, b = a + ns, b - ns
        if (b - a) * dt >= min_static:
            windows.append(make("static", a, b))
    for span in _rate_spans(time, theta, rate, moving_axis, ns, dt, rate_hz, static_tol, rate_rel_tol, min_turns,
                            partial_turns, min_turn_s, min_turn_deg):
        windows.append(make(*span))
    windows.sort(key=lambda w: w.i0)
    if not windows:
        raise CalibrationError("no static dwell window and no constant-rate window found in the record "
                               f"(static: both axes slower than {static_tol / DEG:g} deg/s for at least {min_static:g} s)")
    info.update(n_static=sum(w.kind == "static" for w in windows), n_rate=sum(w.kind == "rate" for w in windows),
                n_turn=sum(w.kind == "turn" for w in windows),
                settle_s=settle, min_static_s=min_static)
    return WindowSet(windows, site, rate_hz, info)


def _motion(record_like, gim, time, dth, dt: float, h: int, static_tol: float, rate_min: float,
            increment_static_tol: float, jump_tol: float | None):
    """The table's angles (n, 2), their rate (centred over ``h`` samples), the static samples and, per axis
    (outer, inner), the samples turning about that axis alone: from the gimbal angles ``gim``, or without
    them from the gyro increments and the record's rotation path (:func:`window_means`)."""
    n = time.shape[0]
    if gim is not None:
        theta = unwrap_angles(np.asarray(gim, float))
        if theta.shape != (n, 2):
            raise CalibrationError(f"gimbal must be an ({n}, 2) array of (theta_x, theta_z), got {theta.shape}")
        check_gimbal_jumps(theta, dt, time, jump_tol=jump_tol)
        rate = _centred_rate(theta, h, dt)
        ok = all_columns(np.isfinite(rate))
        absr = np.abs(np.nan_to_num(rate, nan=np.inf))
        static = ok & all_columns(absr < static_tol)
        moving_axis = [ok & (absr[:, a] > rate_min) & (absr[:, 1 - a] < static_tol) for a in (0, 1)]
        return theta, rate, static, moving_axis
    path = getattr(record_like, "path", None)
    if path is None:
        raise CalibrationError("record has no gimbal angles and no rotation path: the attitude of each window is unknown")
    theta, _, _ = path.segments().angles(time)
    theta = unwrap_angles(theta)
    # windows from the increments: smoothed gyro rate
    cum = np.cumsum(dth, axis=0)
    wr = _centred_rate(cum, h, dt)
    ok = all_columns(np.isfinite(wr))
    wn = np.linalg.norm(np.nan_to_num(wr, nan=np.inf), axis=1)
    static = ok & (wn < increment_static_tol)
    rate = _centred_rate(theta, h, dt)  # axis/direction from the path
    absr = np.abs(np.nan_to_num(rate, nan=np.inf))
    moving_axis = [ok & (wn > rate_min) & (absr[:, a] > rate_min) & (absr[:, 1 - a] < static_tol) for a in (0, 1)]
    return theta, rate, static, moving_axis


def _rate_spans(time, theta, rate, moving_axis, ns: int, dt: float, rate_hz: float, static_tol: float,
                rate_rel_tol: float, min_turns: int, partial_turns: bool, min_turn_s: float, min_turn_deg: float):
    """The constant-rate windows of :func:`window_means` about each axis in turn (outer, inner), each as
    ``(kind, first, end, axis, rate, angles at its start, at its end)``: ``"rate"`` the whole turns at the
    middle of a constant-rate run, ``"turn"`` the whole run of a partial turn; the angles and rate from a
    straight line fitted to the window's angles."""
    spans = []
    for ax, axname in ((0, "outer"), (1, "inner")):
        for a, b in _runs(moving_axis[ax]):
            r = rate[a:b, ax]
            med = float(np.median(r))
            if np.any(np.sign(r) != np.sign(med)):
                continue
            const = np.abs(r - med) <= rate_rel_tol * abs(med) + 2.0 * static_tol
            runs = _runs(const)
            if not runs:
                continue
            ca, cb = max(runs, key=lambda q: q[1] - q[0])
            ca, cb = ca + a + ns, cb + a - ns
            if cb - ca < 2:
                continue
            # angle travelled by the intervals of samples ca..cb-1 (boundaries: ca-1 and cb-1)
            travel = abs(theta[cb - 1, ax] - theta[ca - 1, ax])
            turns = int(math.floor(travel / (2 * math.pi) + 1e-9))
            if turns < min_turns:
                if not (partial_turns and travel < 2 * math.pi and travel >= min_turn_deg * DEG
                        and (cb - ca) * dt >= min_turn_s):
                    continue
                kind, s0, s1 = "turn", ca, cb  # the whole constant-rate part of a partial turn
            else:
                kind = "rate"
                m = int(round(turns * 2 * math.pi / abs(med) * rate_hz))
                m = min(m, cb - ca)
                s0 = ca + (cb - ca - m) // 2
                s1 = s0 + m
            # straight-line fit of the angles on the window: boundary angles and rate
            tt = time[s0 - 1:s1]
            th = theta[s0 - 1:s1]
            A = np.vstack([np.ones_like(tt), tt - tt[0]]).T
            coef, *_ = np.linalg.lstsq(A, th, rcond=None)
            th0 = coef[0]
            th1 = coef[0] + coef[1] * (tt[-1] - tt[0])
            spans.append((kind, s0, s1, axname, float(coef[1, ax]), th0, th1))
    return spans
