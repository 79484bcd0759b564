"""IMU-on-a-dual-axis-turntable simulator.

Produces angular and velocity increments (``dtheta = int w_is^s dt``, ``dv = int f^s dt``)
at a fixed rate for a static site, through the gimbal motion of a :class:`~inscal.core.turntable.Path`.

Exactness: inside each sample interval the gimbal angles are piecewise quadratic in
time; the interval is split at every segment boundary and each piece is integrated
with 4-point Gauss-Legendre quadrature (exact to ~(w h)^8, i.e. far below 1e-15
relative for turntable rates).  The integrals the error model needs (``int f``,
``int f^(2)``, ``int f^(x)``, ``int w w^T``, ``delta w``) are produced once; every
error term is linear in them, so measured increments are exact too.

Time asynchrony (``ImuErrors.time_asynchrony = tau``): the accelerometer integrals are
taken over ``[t_{k-1} - tau, t_k - tau]`` as ``gyro-window integral - I_k + I_{k-1}`` with
``I_k = int_{t_k - tau}^{t_k}`` computed by the same quadrature (split at breakpoints;
the base is static at the initial angles before t = 0 and at the final ones after the
end), and ``delta w = w(t_k - tau) - w(t_{k-1} - tau)``; the gyro increments (and the
g-sensitivity's specific force) stay on the gyro time base.  ``I_k`` depends only on k, so
the result does not depend on the chunk size; with ``tau == 0`` none of this runs.

Random draws: each noise source has its own child generator spawned from the
generator passed in, so results do not depend on the chunk size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np
from numba import njit
from scipy.signal import lfilter

from inscal.core.attitude import dcm_from_euler
from inscal.core.earth import Site
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
from inscal.core.kinematics import rates_at, segment_at
from inscal.core.turntable import RotationPath, Segments, outer_axis
from inscal.io.records import DataFileError, Record, RecordInfo, Truth, write_stream

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class Scenario:
    """Everything a simulation needs (all SI)."""

    name: str
    path: RotationPath
    site: Site
    imu: ImuErrors = field(default_factory=ImuErrors)
    gimbal: GimbalErrors = field(default_factory=GimbalErrors)
    noise: ImuNoise = field(default_factory=ImuNoise)
    rate_hz: float = 100.0

    def __post_init__(self):
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"rate must be a positive number of Hz, got {self.rate_hz}")

    @property
    def n_samples(self) -> int:
        return int(math.floor(self.path.duration * self.rate_hz + 1e-9))


@njit(cache=True)
def _simulate_kernel(k0, n, dt, seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, glx, glw,
                     want_nl, dth, dv, f2, fx, ww, dw):
    S = seg_t0.shape[0]
    w = np.empty(3)
    f = np.empty(3)
    w_prev = np.empty(3)
    w_end = np.empty(3)
    a0 = k0 * dt
    s = 0
    while s < S - 1 and seg_t1[s] <= a0:
        s += 1
    static_seg = -1
    ws = np.zeros(3)
    fs = np.zeros(3)
    if want_nl:
        rates_at(a0, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_prev, f)
    for j in range(n):
        a = (k0 + j) * dt
        b = (k0 + j + 1) * dt
        for c in range(3):
            dth[j, c] = 0.0
            dv[j, c] = 0.0
            if want_nl:
                f2[j, c] = 0.0
                fx[j, c] = 0.0
                ww[j, c] = 0.0
                ww[j, c + 3] = 0.0
        sa = a
        end_static = False
        while True:
            sb = seg_t1[s] if (seg_t1[s] < b and s < S - 1) else b
            h = sb - sa
            is_static = seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0
            if h > 0.0:
                if is_static:
                    if static_seg != s:
                        rates_at(seg_t0[s], s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, ws, fs)
                        static_seg = s
                    nq = 1
                else:
                    nq = glx.shape[0]
                for q in range(nq):
                    if is_static:
                        wq = h
                        for c in range(3):
                            w[c] = ws[c]
                            f[c] = fs[c]
                    else:
                        tq = 0.5 * (sa + sb) + 0.5 * h * glx[q]
                        wq = 0.5 * h * glw[q]
                        rates_at(tq, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                    for c in range(3):
                        dth[j, c] += wq * w[c]
                        dv[j, c] += wq * f[c]
                    if want_nl:
                        f2[j, 0] += wq * f[0] * f[0]
                        f2[j, 1] += wq * f[1] * f[1]
                        f2[j, 2] += wq * f[2] * f[2]
                        fx[j, 0] += wq * f[0] * f[1]
                        fx[j, 1] += wq * f[0] * f[2]
                        fx[j, 2] += wq * f[1] * f[2]
                        ww[j, 0] += wq * w[0] * w[0]
                        ww[j, 1] += wq * w[1] * w[1]
                        ww[j, 2] += wq * w[2] * w[2]
                        ww[j, 3] += wq * w[0] * w[1]
                        ww[j, 4] += wq * w[0] * w[2]
                        ww[j, 5] += wq * w[1] * w[2]
            if sb >= b:
                end_static = is_static and static_seg == s
                break
            s += 1
            sa = sb
        if want_nl:
            # delta w = w(b) - w(a) (the integral of w-dot); w is continuous across segments
            if end_static:
                for c in range(3):
                    w_end[c] = ws[c]
            else:
                rates_at(b, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_end, f)
            for c in range(3):
                dw[j, c] = w_end[c] - w_prev[c]
                w_prev[c] = w_end[c]
        # the next sample starts in segment s (or the one after, if s ends exactly at b)
        if s < S - 1 and seg_t1[s] <= b:
            s += 1


@njit(cache=True)
def _accumulate(wq, w, f, want_nl, j, sgn, iv, if2, ifx, iww):
    c = sgn * wq
    for i in range(3):
        iv[j, i] += c * f[i]
    if want_nl:
        if2[j, 0] += c * f[0] * f[0]
        if2[j, 1] += c * f[1] * f[1]
        if2[j, 2] += c * f[2] * f[2]
        ifx[j, 0] += c * f[0] * f[1]
        ifx[j, 1] += c * f[0] * f[2]
        ifx[j, 2] += c * f[1] * f[2]
        iww[j, 0] += c * w[0] * w[0]
        iww[j, 1] += c * w[1] * w[1]
        iww[j, 2] += c * w[2] * w[2]
        iww[j, 3] += c * w[0] * w[1]
        iww[j, 4] += c * w[0] * w[2]
        iww[j, 5] += c * w[1] * w[2]


@njit(cache=True)
def _asynchrony_kernel(k0, n1, dt, tau, seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, glx, glw,
                       want_nl, iv, if2, ifx, iww, wdel):
    """Boundary integrals for a time asynchrony ``tau``: for the sample boundaries
    ``t_j = (k0 + j) dt``, j = 0 .. n1-1, ``I_j = int_{t_j - tau}^{t_j} (f, f^(2), f^(x), w w^T)``
    (signed: negative for ``tau < 0``) and ``wdel_j = w(t_j - tau)``.  Before t = 0 and after
    the end of the path the base is static at the first / last gimbal angles.  Each piece
    between segment breakpoints is integrated with Gauss-Legendre (pieces longer than dt
    are split into <= dt parts), static segments exactly."""
    S = seg_t0.shape[0]
    T = seg_t1[S - 1]
    w = np.empty(3)
    f = np.empty(3)
    w_beg = np.empty(3)
    f_beg = np.empty(3)
    w_fin = np.empty(3)
    f_fin = np.empty(3)
    rates_at(0.0, 0, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_beg, f_beg)
    rates_at(T, S - 1, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_fin, f_fin)
    nq = glx.shape[0]
    for j in range(n1):
        tb = (k0 + j) * dt
        ta = tb - tau
        for c in range(3):
            iv[j, c] = 0.0
            if want_nl:
                if2[j, c] = 0.0
                ifx[j, c] = 0.0
                iww[j, c] = 0.0
                iww[j, c + 3] = 0.0
        if tau > 0.0:
            lo, hi, sgn = ta, tb, 1.0
        else:
            lo, hi, sgn = tb, ta, -1.0
        x = lo
        if x < 0.0:  # static base before the path starts
            xe = hi if hi < 0.0 else 0.0
            _accumulate(xe - x, w_beg, f_beg, want_nl, j, sgn, iv, if2, ifx, iww)
            x = xe
        if x < hi and x < T:
            s = segment_at(x, seg_t1)
            while x < hi and s < S:
                xe = seg_t1[s] if seg_t1[s] < hi else hi
                h = xe - x
                if h > 0.0:
                    if seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0:
                        rates_at(seg_t0[s], s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                        _accumulate(h, w, f, want_nl, j, sgn, iv, if2, ifx, iww)
                    else:
                        m = int(math.ceil(h / dt)) if h > dt else 1
                        hp = h / m
                        for p in range(m):
                            pa = x + p * hp
                            pb = xe if p == m - 1 else pa + hp
                            hh = pb - pa
                            for q in range(nq):
                                tq = 0.5 * (pa + pb) + 0.5 * hh * glx[q]
                                rates_at(tq, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                                _accumulate(0.5 * hh * glw[q], w, f, want_nl, j, sgn, iv, if2, ifx, iww)
                x = xe
                s += 1
        if x < hi:  # static base after the path ends
            _accumulate(hi - x, w_fin, f_fin, want_nl, j, sgn, iv, if2, ifx, iww)
        if want_nl:
            if ta <= 0.0:
                for c in range(3):
                    wdel[j, c] = w_beg[c]
            elif ta >= T:
                for c in range(3):
                    wdel[j, c] = w_fin[c]
            else:
                s = segment_at(ta, seg_t1)
                rates_at(ta, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                for c in range(3):
                    wdel[j, c] = w[c]


@dataclass
class Chunk:
    """Samples k0 .. k0+n-1 of a simulation (all SI).  ``time`` is the end of each interval."""

    k0: int
    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    gimbal: np.ndarray  # recorded (theta_x, theta_z) at ``time`` [rad]
    true_dtheta: np.ndarray | None = None
    true_dvel: np.ndarray | None = None


class NoiseState:
    """Stateful, chunk-size-independent noise generator."""

    def __init__(self, noise: ImuNoise, rng: np.random.Generator, dt: float):
        self.noise = noise
        self.dt = dt
        self.g_arw, self.g_vrw, self.g_gbi, self.g_abi, self.g_enc = rng.spawn(5)
        self.zi_g = None
        self.zi_a = None
        self.q_g = (np.zeros(3), np.zeros(3))
        self.q_a = (np.zeros(3), np.zeros(3))

    def _gm(self, gen, sigma, tau, n, zi_name):
        if not np.any(sigma):
            return 0.0
        phi = math.exp(-self.dt / tau)
        zi = getattr(self, zi_name)
        if zi is None:  # stationary start (drawn first, so results do not depend on chunking)
            zi = (gen.standard_normal(3) * sigma * phi)[None, :]
        drive = gen.standard_normal((n, 3)) * sigma * math.sqrt(1 - phi * phi)
        out, zf = lfilter([1.0], [1.0, -phi], drive, axis=0, zi=zi)
        setattr(self, zi_name, zf)
        return out

    @staticmethod
    def _quantize(x, q, state):
        """Quantize increments of an accumulating output: emit whole quanta of the running
        total, the remainder carries to the next sample.  ``state = (total, emitted_counts)``;
        the running total is summed in the same order whatever the chunking."""
        if q <= 0:
            return x, state
        total, emitted = state
        acc = np.cumsum(np.vstack([total[None, :], x]), axis=0)[1:]
        counts = np.floor(acc / q)
        out = np.diff(np.vstack([emitted[None, :], counts]), axis=0) * q
        return out, (acc[-1], counts[-1])

    def apply(self, dth, dv, gimbal):
        n, nz, dt = dth.shape[0], self.noise, self.dt
        if np.any(nz.arw):
            dth = dth + self.g_arw.standard_normal((n, 3)) * nz.arw * math.sqrt(dt)
        if np.any(nz.vrw):
            dv = dv + self.g_vrw.standard_normal((n, 3)) * nz.vrw * math.sqrt(dt)
        dth = dth + self._gm(self.g_gbi, nz.gyro_bias_instability, nz.gyro_bias_tau, n, "zi_g") * dt
        dv = dv + self._gm(self.g_abi, nz.accel_bias_instability, nz.accel_bias_tau, n, "zi_a") * dt
        dth, self.q_g = self._quantize(dth, nz.gyro_quantization, self.q_g)
        dv, self.q_a = self._quantize(dv, nz.accel_quantization, self.q_a)
        if nz.encoder_noise > 0:
            gimbal = gimbal + self.g_enc.standard_normal(gimbal.shape) * nz.encoder_noise
        return dth, dv, gimbal


def simulate_chunks(scenario: Scenario, rng: np.random.Generator | None, chunk_size: int = 1 << 19,
                    keep_truth: bool = False, progress: Callable[[int, int], None] | None = None) -> Iterator[Chunk]:
    """Yield the simulation in chunks.  ``rng`` may be None only when the noise is zero."""
    if rng is None and not scenario.noise.is_zero:
        raise ValueError("a seeded numpy Generator is required when the scenario has noise")
    seg: Segments = scenario.path.segments()
    dt = 1.0 / scenario.rate_hz
    N = scenario.n_samples
    u = outer_axis(scenario.gimbal.nonorthogonality)
    Cbn = np.ascontiguousarray(dcm_from_euler(scenario.gimbal.mount_attitude))
    wie_n = scenario.site.earth_rate_n
    g = scenario.site.gravity
    imu = scenario.imu
    want_nl = imu.has_nonlinear
    noise = None if scenario.noise.is_zero else NoiseState(scenario.noise, rng, dt)
    for k0 in range(0, N, chunk_size):
        n = min(chunk_size, N - k0)
        dth = np.empty((n, 3))
        dv = np.empty((n, 3))
        m = n if want_nl else 1
        f2, fx, dw = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        ww = np.empty((m, 6))
        _simulate_kernel(k0, n, dt, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie_n, g, _GL_X, _GL_W,
                         want_nl, dth, dv, f2, fx, ww, dw)
        t = (k0 + 1 + np.arange(n)) * dt
        th, _, _ = seg.angles(t)
        if imu.has_asynchrony:
            # accelerometer window [t_{k-1} - tau, t_k - tau] = gyro window - I_k + I_{k-1}
            iv, if2, ifx, wdel = np.empty((n + 1, 3)), np.empty((m + 1, 3)), np.empty((m + 1, 3)), np.empty((m + 1, 3))
            iww = np.empty((m + 1, 6))
            _asynchrony_kernel(k0, n + 1, dt, imu.time_asynchrony, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn,
                               wie_n, g, _GL_X, _GL_W, want_nl, iv, if2, ifx, iww, wdel)
            dva = dv - iv[1:] + iv[:-1]
            if want_nl:
                f2, fx, ww = f2 - if2[1:] + if2[:-1], fx - ifx[1:] + ifx[:-1], ww - iww[1:] + iww[:-1]
                dw = wdel[1:] - wdel[:-1]
            mdth, mdv = imu.measure_increments(dt, dth, dva, f2, fx, ww, dw, dv_gyro=dv)
        else:
            mdth, mdv = imu.measure_increments(dt, dth, dv, f2, fx, ww, dw)
        gimbal = th
        if noise is not None:
            mdth, mdv, gimbal = noise.apply(mdth, mdv, gimbal)
        yield Chunk(k0, t, mdth, mdv, gimbal, dth if keep_truth else None, dv if keep_truth else None)
        if progress is not None:
            progress(k0 + n, N)


@dataclass
class SimData:
    """A whole simulation in memory."""

    scenario: Scenario
    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    gimbal: np.ndarray
    true_dtheta: np.ndarray | None = None
    true_dvel: np.ndarray | None = None


def simulate(scenario: Scenario, rng: np.random.Generator | None = None, keep_truth: bool = False,
             chunk_size: int = 1 << 19) -> SimData:
    """Simulate the whole scenario in memory (see :func:`simulate_chunks` for long runs)."""
    parts = list(simulate_chunks(scenario, rng, chunk_size, keep_truth))
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts]) if parts and getattr(parts[0], name) is not None else None  # noqa: E731
    return SimData(scenario, cat("time"), cat("dtheta"), cat("dvel"), cat("gimbal"), cat("true_dtheta"), cat("true_dvel"))


def write_simulation(path, scenario: Scenario, rng: np.random.Generator | None, overwrite: bool = False,
                     progress: Callable[[int, int], None] | None = None, chunk_size: int = 1 << 19) -> int:
    """Simulate ``scenario`` straight into an HDF5 record (chunk by chunk, atomic).  Returns N."""

    n = scenario.n_samples
    if n < 1:
        raise ValueError("scenario is shorter than one sample")
    info = RecordInfo(n, scenario.rate_hz, scenario.site, scenario.path,
                      Truth(scenario.imu, scenario.gimbal, scenario.noise), scenario.name, True)
    chunks = ((c.time, c.dtheta, c.dvel, c.gimbal)
              for c in simulate_chunks(scenario, rng, chunk_size=chunk_size, progress=progress))
    return write_stream(path, info, chunks, overwrite)


def scenario_from_record(rec: Record | RecordInfo) -> Scenario:
    """Rebuild the simulation scenario of a simulated record (for truth trajectories)."""

    if rec.truth is None or rec.path is None:
        raise DataFileError("record has no truth/path: it is not a simulated record")
    return Scenario(rec.scenario or "record", rec.path, rec.site, rec.truth.imu, rec.truth.gimbal, rec.truth.noise, rec.rate_hz)
