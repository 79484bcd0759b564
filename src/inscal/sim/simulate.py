"""IMU-on-a-dual-axis-turntable simulator.

Produces angular and velocity increments (``dtheta = int w_is^s dt``, ``dv = int f^s dt``)
at a fixed rate for a static site, through the gimbal motion of a :class:`~inscal.core.turntable.RotationPath`.

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

Speed: the per-sample arithmetic (integrals, gimbal angles, error model, noise) is one compiled pass
over each chunk (:func:`inscal.sim.kernel.simulate_pass`); only the normal draws are made in NumPy, in
bulk (:meth:`NoiseState.draw`), and the asynchrony's boundary integrals in their own kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable, Iterator

import numpy as np
from numba import njit

from inscal.core.attitude import dcm_from_euler
from inscal.core.earth import Site
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
from inscal.core.kinematics import rates_at, segment_at
from inscal.core.thermal import ThermalModel
from inscal.core.turntable import RotationPath, Segments, outer_axis
from inscal.io.recordfile import write_stream
from inscal.io.records import DataFileError, Record, RecordInfo, Temperature, Truth, record_attrs
from inscal.sim.kernel import (
    O_ARW,
    O_ASYNC,
    O_ENCODER,
    O_GM_A,
    O_GM_G,
    O_GSENS,
    O_LEVER,
    O_MEASURE,
    O_QUAD,
    O_QUANT_A,
    O_QUANT_G,
    O_RAW,
    O_RECORD,
    O_TRUTH,
    O_VRW,
    gauss_markov_filter,
    simulate_pass,
)
from inscal.sim.handheld import HandheldMotion, true_increments
from inscal.sim.thermal import TemperatureProfile, TemperatureSensor

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)
#: samples per compiled pass (a chunk is done in passes of this many; the numbers do not depend on it)
PASS_ROWS = 1 << 14


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
    #: the IMU errors follow the temperature (``imu``: the errors at ``thermal.t_ref``)
    thermal: ThermalModel | None = None
    #: the temperature of the IMU over time (None: no temperature, the IMU stays at its reference)
    temperature: TemperatureProfile | None = None
    #: how the record's /temperature readings are taken from ``temperature``
    temperature_sensor: TemperatureSensor = field(default_factory=TemperatureSensor)
    #: a hand-held session without a turntable (:mod:`inscal.sim.handheld`; ``path`` is then a static path
    #: of its duration, and the record has no gimbal angles nor path)
    motion: HandheldMotion | None = None

    def __post_init__(self):
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"rate must be a positive number of Hz, got {self.rate_hz}")
        if self.thermal is not None and not self.thermal.is_zero and self.temperature is None:
            raise ValueError("a scenario with a thermal model needs a temperature profile")
        if self.motion is not None and (self.has_thermal or self.imu.has_asynchrony or np.any(self.imu.accel_lever_arm)
                                        or np.any(self.imu.gyro_g_sensitivity)):
            raise ValueError("a hand-held scenario takes no thermal model, time asynchrony, size effect nor "
                             "g-sensitivity")

    @property
    def has_thermal(self) -> bool:
        """True when the IMU errors change with the temperature in this scenario."""
        return self.thermal is not None and not self.thermal.is_zero and self.temperature is not None

    def temperature_readings(self, rng: np.random.Generator | None) -> Temperature | None:
        """The record's /temperature (None without a profile); the sensor's noise draws come from
        ``rng`` (a child of the simulation's generator)."""
        if self.temperature is None:
            return None
        return self.temperature_sensor.read(self.temperature, self.path.duration, rng)

    @property
    def n_samples(self) -> int:
        return int(math.floor(self.path.duration * self.rate_hz + 1e-9))


def _rows(n: int, width: int) -> np.ndarray:
    return np.zeros((n, width))


@dataclass(frozen=True)
class ModelArrays:
    """The error model as the compiled pass takes it: option bits and contiguous writable arrays."""

    opts: int
    mg: np.ndarray
    bg: np.ndarray
    gs: np.ndarray
    ma: np.ndarray
    ba: np.ndarray
    k2: np.ndarray
    kc: np.ndarray
    p: np.ndarray

    @property
    def arrays(self) -> tuple:
        """``(mg, bg, gs, ma, ba, k2, kc, p)``: the ``model`` tuple of :func:`inscal.sim.kernel.simulate_pass`."""
        return (self.mg, self.bg, self.gs, self.ma, self.ba, self.k2, self.kc, self.p)

    @classmethod
    def of(cls, imu: ImuErrors | None) -> ModelArrays:
        """The arrays of ``imu`` (copies: writable and C-ordered, as numba compiles read-only arrays
        apart) and the terms it has: a term whose parameters are all zero is left out, and a perfect
        IMU (or None) has no error model at all."""
        imu = ImuErrors() if imu is None else imu
        m = cls(0, *(np.array(x, dtype=float) for x in (
            imu.M_g, imu.gyro_bias, imu.gyro_g_sensitivity, imu.M_a, imu.accel_bias, imu.accel_nonlinearity,
            imu.K_cross, imu.accel_lever_arm)))
        eye = np.eye(3)
        opts = ((O_QUAD if np.any(m.k2) or np.any(m.kc) else 0) | (O_LEVER if np.any(m.p) else 0)
                | (O_GSENS if np.any(m.gs) else 0))
        if opts or np.any(m.mg != eye) or np.any(m.ma != eye) or np.any(m.bg) or np.any(m.ba):
            opts |= O_MEASURE
        return replace(m, opts=opts)


def _simulate_kernel(k0, n, dt, seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, glx, glw,
                     want_nl, dth, dv, f2, fx, ww, dw):
    """The true integrals of samples ``k0 .. k0 + n - 1``: ``dth = int w``, ``dv = int f`` and, with
    ``want_nl``, ``f2 = int f^(2)``, ``fx = int f^(x)``, ``ww = int w w^T`` (6 products), ``dw = delta w``
    (the inputs of :meth:`~inscal.core.error_model.ImuErrors.measure_increments`): the first step of
    the compiled pass alone."""
    model = ModelArrays.of(None)
    opts = O_TRUTH | O_RAW | ((O_QUAD | O_LEVER) if want_nl else 0)
    simulate_pass(k0, n, dt, (seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g), glx, glw, opts,
                  model.arrays, (_rows(1, 3), _rows(1, 3), _rows(1, 3), _rows(1, 6), _rows(1, 3)), _no_noise(),
                  np.zeros(4), (np.zeros(1), _rows(1, 3), _rows(1, 3), _rows(1, 2), dth, dv, f2, fx, ww, dw))


#: the axis pairs of the cross products f^(x) = (f_x f_y, f_x f_z, f_y f_z) (and of w w^T's off-diagonal)
_PAIRS = np.array([[0, 1], [0, 2], [1, 2]])


@njit(cache=True)
def _accumulate(wq, w, f, want_nl, j, sgn, iv, if2, ifx, iww):
    c = sgn * wq
    for i in range(3):
        iv[j, i] += c * f[i]
    if want_nl:
        for i in range(3):
            a, b = _PAIRS[i, 0], _PAIRS[i, 1]
            if2[j, i] += c * f[i] * f[i]
            ifx[j, i] += c * f[a] * f[b]
            iww[j, i] += c * w[i] * w[i]
            iww[j, 3 + i] += c * w[a] * w[b]


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
    w, f, w_beg, f_beg, w_fin, f_fin = np.empty((6, 3))  # rates: at a node; before the path; after it
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


@dataclass(frozen=True)
class NoiseDraws:
    """The standard normal draws of the noise sources for n samples (None: a source that is off):
    ``arw``, ``vrw``, ``gyro_bias``, ``accel_bias`` (n, 3) and ``encoder`` (n, 2)."""

    arw: np.ndarray | None
    vrw: np.ndarray | None
    gyro_bias: np.ndarray | None
    accel_bias: np.ndarray | None
    encoder: np.ndarray | None


class NoiseState:
    """Stateful, chunk-size-independent noise generator.

    Each source draws from its own child generator.  :meth:`draw` makes the standard normal draws of
    the next samples and :meth:`apply` adds the noise to increments in NumPy; the simulator adds it in
    its compiled pass from the same draws, with the same arithmetic, and updates the same state
    (``zi_g``, ``zi_a``: Gauss-Markov filter states (1, 3); ``q_g``, ``q_a``: running totals and
    emitted quanta)."""

    def __init__(self, noise: ImuNoise, rng: np.random.Generator, dt: float):
        self.noise = noise
        self.dt = dt
        self.g_arw, self.g_vrw, self.g_gbi, self.g_abi, self.g_enc = rng.spawn(5)
        self.zi_g = None
        self.zi_a = None
        self.q_g = (np.zeros(3), np.zeros(3))
        self.q_a = (np.zeros(3), np.zeros(3))
        self._buffers: dict[str, np.ndarray] = {}
        # the coefficients as the compiled pass takes them (writable copies: numba types read-only arrays apart)
        self._coef = {name: np.array(getattr(noise, name), dtype=float)
                      for name in ("arw", "vrw", "gyro_bias_instability", "accel_bias_instability")}
        self._unused = _no_noise()

    def _normal(self, gen, name, n, width):
        """n x width standard normals from ``gen`` (the numbers of ``gen.standard_normal((n, width))``)
        into a buffer kept for the next chunk."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape[0] < n:
            buf = self._buffers[name] = np.empty((n, width))
        out = buf[:n]
        gen.standard_normal(out=out)
        return out

    def gauss_markov(self, tau) -> tuple[float, float]:
        """``(phi, sqrt(1 - phi^2))`` of the first-order Gauss-Markov process of correlation time tau."""
        phi = math.exp(-self.dt / tau)
        return phi, math.sqrt(1 - phi * phi)

    def _gm_draws(self, gen, sigma, tau, n, zi_name):
        if not np.any(sigma):
            return None
        if getattr(self, zi_name) is None:  # stationary start (drawn first, so results do not depend on chunking)
            setattr(self, zi_name, (gen.standard_normal(3) * sigma * self.gauss_markov(tau)[0])[None, :])
        return self._normal(gen, zi_name, n, 3)

    def draw(self, n: int) -> NoiseDraws:
        """The draws of the next n samples.  The arrays are overwritten by the next call."""
        nz = self.noise
        return NoiseDraws(
            self._normal(self.g_arw, "arw", n, 3) if np.any(nz.arw) else None,
            self._normal(self.g_vrw, "vrw", n, 3) if np.any(nz.vrw) else None,
            self._gm_draws(self.g_gbi, nz.gyro_bias_instability, nz.gyro_bias_tau, n, "zi_g"),
            self._gm_draws(self.g_abi, nz.accel_bias_instability, nz.accel_bias_tau, n, "zi_a"),
            self._normal(self.g_enc, "encoder", n, 2) if nz.encoder_noise > 0 else None,
        )

    def _gm(self, z, sigma, tau, zi_name):
        if z is None:
            return 0.0
        phi, drive = self.gauss_markov(tau)
        zf = np.array(getattr(self, zi_name), dtype=float).reshape(-1)
        out = gauss_markov_filter(np.ascontiguousarray(z * sigma * drive), phi, zf)
        setattr(self, zi_name, zf[None, :])
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
        return out, (acc[-1].copy(), counts[-1].copy())

    def apply(self, dth, dv, gimbal):
        """Noisy ``(dth, dv, gimbal)`` of the next ``dth.shape[0]`` samples (gimbal (n, 2))."""
        n, nz, dt = dth.shape[0], self.noise, self.dt
        d = self.draw(n)
        if d.arw is not None:
            dth = dth + d.arw * nz.arw * math.sqrt(dt)
        if d.vrw is not None:
            dv = dv + d.vrw * nz.vrw * math.sqrt(dt)
        dth = dth + self._gm(d.gyro_bias, nz.gyro_bias_instability, nz.gyro_bias_tau, "zi_g") * dt
        dv = dv + self._gm(d.accel_bias, nz.accel_bias_instability, nz.accel_bias_tau, "zi_a") * dt
        dth, self.q_g = self._quantize(dth, nz.gyro_quantization, self.q_g)
        dv, self.q_a = self._quantize(dv, nz.accel_quantization, self.q_a)
        if d.encoder is not None:
            gimbal = gimbal + d.encoder * nz.encoder_noise
        return dth, dv, gimbal

    def pass_arguments(self, n: int) -> tuple[int, tuple]:
        """Option bits and the ``noise`` tuple of :func:`inscal.sim.kernel.simulate_pass` for the next
        n samples (draws made; the pass updates the Gauss-Markov and quantization states in place)."""
        nz, d, c, off = self.noise, self.draw(n), self._coef, self._unused
        opts = ((O_ARW if d.arw is not None else 0) | (O_VRW if d.vrw is not None else 0)
                | (O_ENCODER if d.encoder is not None else 0))
        gm = []
        for z, sigma, tau, zi_name, bit in ((d.gyro_bias, "gyro_bias_instability", nz.gyro_bias_tau, "zi_g", O_GM_G),
                                            (d.accel_bias, "accel_bias_instability", nz.accel_bias_tau, "zi_a", O_GM_A)):
            if z is None:
                gm += off[5:10]
                continue
            opts |= bit
            phi, drive = self.gauss_markov(tau)
            zi = getattr(self, zi_name)
            if not (zi.dtype == np.float64 and zi.flags.c_contiguous and zi.flags.writeable):
                zi = np.array(zi, dtype=float)
                setattr(self, zi_name, zi)
            gm += [z, c[sigma], drive, phi, zi[0]]
        quant = []
        for q, name, bit in ((nz.gyro_quantization, "q_g", O_QUANT_G), (nz.accel_quantization, "q_a", O_QUANT_A)):
            state = getattr(self, name)
            if q > 0:
                opts |= bit
                if not all(x.dtype == np.float64 and x.flags.c_contiguous and x.flags.writeable for x in state):
                    state = tuple(np.array(x, dtype=float) for x in state)
                    setattr(self, name, state)
            quant += [float(q), state[0], state[1]]
        args = (math.sqrt(self.dt), off[1] if d.arw is None else d.arw, c["arw"], off[3] if d.vrw is None else d.vrw,
                c["vrw"], *gm, *quant, off[21] if d.encoder is None else d.encoder, float(nz.encoder_noise))
        return opts, args


def _no_noise() -> tuple:
    """The ``noise`` tuple of :func:`~inscal.sim.kernel.simulate_pass` with no noise (never read)."""
    r3 = _rows(1, 3)
    return (0.0, r3, np.zeros(3), r3, np.zeros(3), r3, np.zeros(3), 0.0, 0.0, np.zeros(3), r3, np.zeros(3), 0.0, 0.0,
            np.zeros(3), 0.0, np.zeros(3), np.zeros(3), 0.0, np.zeros(3), np.zeros(3), _rows(1, 2), 0.0)


def simulate_chunks(scenario: Scenario, rng: np.random.Generator | None, chunk_size: int = 1 << 19,
                    keep_truth: bool = False, progress: Callable[[int, int], None] | None = None) -> Iterator[Chunk]:
    """Yield the simulation in chunks.  ``rng`` may be None only when the noise is zero."""
    return _chunks(scenario, rng, chunk_size, keep_truth, progress, None, None)


def _n_samples(scenario: Scenario, seg: Segments) -> int:
    """:attr:`Scenario.n_samples` from the compiled path (which ``path.duration`` compiles again)."""
    return int(math.floor(float(seg.t1[-1]) * scenario.rate_hz + 1e-9))


def _chunks(scenario, rng, chunk_size, keep_truth, progress, seg, whole) -> Iterator[Chunk]:
    """:func:`simulate_chunks` (``seg``: the compiled path, or None); with ``whole`` = (time, dtheta, dvel,
    gimbal, true_dtheta, true_dvel) arrays of all the samples, the chunks are written into them (their
    arrays are views of ``whole``)."""
    if rng is None and not scenario.noise.is_zero:
        raise ValueError("a seeded numpy Generator is required when the scenario has noise")
    seg = scenario.path.segments() if seg is None else seg
    dt = 1.0 / scenario.rate_hz
    N = _n_samples(scenario, seg)
    u = outer_axis(scenario.gimbal.nonorthogonality)
    Cbn = np.ascontiguousarray(dcm_from_euler(scenario.gimbal.mount_attitude))
    wie_n = np.array(scenario.site.earth_rate_n, dtype=float)
    g = float(scenario.site.gravity)
    imu = scenario.imu
    model = ModelArrays.of(imu)
    want_nl = bool(model.opts & (O_QUAD | O_LEVER))
    noise = None if scenario.noise.is_zero else NoiseState(scenario.noise, rng, dt)
    # thermal errors: the pass measures at T_ref, the thermal model moves each sample to its temperature, then
    # the noise is added in NumPy from the same draws (NoiseState.apply)
    thermal = scenario.thermal if scenario.has_thermal else None
    # the arrays of what a run does not use (never written: their option bits are off)
    unused3 = _rows(1, 3)
    unused_boundary = (unused3, unused3, unused3, _rows(1, 6), unused3)
    unused_noise = _no_noise()
    unused_raw = (unused3, unused3, _rows(1, 6), unused3)
    path = (seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie_n, g)
    for k0 in range(0, N, chunk_size):
        n = min(chunk_size, N - k0)
        if whole is None:
            t, mdth, mdv, gimbal = np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2))
            dth, dv = (np.empty((n, 3)), np.empty((n, 3))) if keep_truth else (None, None)
        else:
            t, mdth, mdv, gimbal, dth, dv = (None if x is None else x[k0:k0 + n] for x in whole)
        carry = np.zeros(4)  # each chunk starts afresh (the rates at its start evaluated), as it always did
        # the chunk in passes of PASS_ROWS samples: the noise draws of a pass stay small and in cache
        for j0 in range(0, n, PASS_ROWS):
            j1 = min(n, j0 + PASS_ROWS)
            k, m = k0 + j0, j1 - j0
            opts = model.opts | O_RECORD | (O_TRUTH if keep_truth else 0)
            boundary = unused_boundary
            if imu.has_asynchrony:
                # accelerometer window [t_{k-1} - tau, t_k - tau] = gyro window - I_k + I_{k-1}
                mm = m if want_nl else 1
                boundary = (np.empty((m + 1, 3)), np.empty((mm + 1, 3)), np.empty((mm + 1, 3)), np.empty((mm + 1, 6)),
                            np.empty((mm + 1, 3)))
                _asynchrony_kernel(k, m + 1, dt, imu.time_asynchrony, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn,
                                   wie_n, g, _GL_X, _GL_W, want_nl, *boundary)
                opts |= O_ASYNC
            noise_args = unused_noise
            if noise is not None and thermal is None:
                noise_opts, noise_args = noise.pass_arguments(m)
                opts |= noise_opts
            simulate_pass(k, m, dt, path, _GL_X, _GL_W, opts, model.arrays, boundary, noise_args, carry,
                          (t[j0:j1], mdth[j0:j1], mdv[j0:j1], gimbal[j0:j1], unused3 if dth is None else dth[j0:j1],
                           unused3 if dv is None else dv[j0:j1], *unused_raw))
            if thermal is not None:
                T, rate = scenario.temperature.at(t[j0:j1] - 0.5 * dt)  # the middle of each sample interval
                a, b = thermal.to_temperature(imu, dt, mdth[j0:j1], mdv[j0:j1], T, rate)
                if noise is not None:
                    a, b, gimbal[j0:j1] = noise.apply(a, b, gimbal[j0:j1])
                mdth[j0:j1], mdv[j0:j1] = a, b
        yield Chunk(k0, t, mdth, mdv, gimbal, dth, dv)
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
    temperature: Temperature | None = None

    def to_record(self) -> Record:
        """The simulation as an in-memory :class:`~inscal.io.records.Record` with its truth."""
        sc = self.scenario
        return Record(self.time, self.dtheta, self.dvel, self.gimbal, sc.rate_hz, sc.site,
                      path=sc.path if sc.motion is None else None,
                      truth=Truth(sc.imu, sc.gimbal, sc.noise, sc.thermal), scenario=sc.name,
                      temperature=self.temperature)


def _temperature_rng(scenario: Scenario, rng: np.random.Generator | None) -> np.random.Generator | None:
    """The generator of the temperature sensor's noise: a child spawned from ``rng`` only when that noise is
    on (so the IMU noise draws of every other scenario are unchanged)."""
    if scenario.temperature is None or scenario.temperature_sensor.noise_c <= 0:
        return None
    if rng is None:
        raise ValueError("a seeded numpy Generator is required for temperature sensor noise")
    return rng.spawn(1)[0]


def _handheld(scenario: Scenario, rng: np.random.Generator | None, keep_truth: bool) -> SimData:
    """A hand-held session (:mod:`inscal.sim.handheld`): exact increments, the error model, the noise."""
    if rng is None and not scenario.noise.is_zero:
        raise ValueError("a seeded numpy Generator is required when the scenario has noise")
    imu = scenario.imu
    quad = bool(np.any(imu.accel_nonlinearity) or np.any(imu.accel_cross_coupling))
    t, dth, dv, f2, fx = true_increments(scenario.motion, scenario.site, scenario.rate_hz, quad)
    mdth, mdv = imu.measure_increments(1.0 / scenario.rate_hz, dth, dv, f2, fx)
    if not scenario.noise.is_zero:
        mdth, mdv, _ = NoiseState(scenario.noise, rng, 1.0 / scenario.rate_hz).apply(mdth, mdv, np.zeros((t.size, 2)))
    return SimData(scenario, t, mdth, mdv, None, dth if keep_truth else None, dv if keep_truth else None)


def simulate(scenario: Scenario, rng: np.random.Generator | None = None, keep_truth: bool = False,
             chunk_size: int = 1 << 19) -> SimData:
    """Simulate a whole scenario in memory (:func:`simulate_chunks` for long runs).

    The chunks are written into the arrays of the result: no copy, no more memory than the result.

    Parameters
    ----------
    scenario : Scenario
        What to simulate (:func:`inscal.sim.scenarios.build`).
    rng : numpy.random.Generator, optional
        The generator of the noise (None: no noise drawn).
    keep_truth : bool
        Keep the true rates and specific force too.
    chunk_size : int
        Samples per chunk of the simulation.

    Returns
    -------
    SimData
        ``time``, ``dtheta``, ``dvel``, ``gimbal`` (SI), the true rates and specific force with
        ``keep_truth``, and the temperature readings of a thermal scenario.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=10.0, rate_hz=100.0)
    >>> data = simulate(sc, np.random.default_rng(0))
    >>> data.dtheta.shape, float(data.time[-1])
    ((1000, 3), 10.0)
    """
    if scenario.motion is not None:
        return _handheld(scenario, rng, keep_truth)
    seg = scenario.path.segments()
    n = _n_samples(scenario, seg)
    temp_rng = _temperature_rng(scenario, rng)
    if n < 1:
        for _ in _chunks(scenario, rng, chunk_size, keep_truth, None, seg, None):
            pass
        return SimData(scenario, None, None, None, None)
    whole = (np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2)),
             np.empty((n, 3)) if keep_truth else None, np.empty((n, 3)) if keep_truth else None)
    for _ in _chunks(scenario, rng, chunk_size, keep_truth, None, seg, whole):
        pass
    return SimData(scenario, *whole, temperature=scenario.temperature_readings(temp_rng))


def write_simulation(path, scenario: Scenario, rng: np.random.Generator | None, overwrite: bool = False,
                     progress: Callable[[int, int], None] | None = None, chunk_size: int = 1 << 19) -> int:
    """Simulate a scenario straight into an HDF5 record (chunk by chunk, atomic).

    The record carries the scenario's truth (``/truth``) and, for a thermal scenario, its
    temperature readings.

    Parameters
    ----------
    path : str or pathlib.Path
        The record to write.
    scenario : Scenario
        What to simulate.
    rng : numpy.random.Generator or None
        The generator of the noise.
    overwrite : bool
        Replace an existing file.
    progress : callable, optional
        Called with ``(samples done, samples)``.
    chunk_size : int
        Samples per chunk.

    Returns
    -------
    int
        The number of samples N.

    Raises
    ------
    ValueError
        A scenario shorter than one sample.
    FileExistsError
        ``path`` exists and ``overwrite`` is false.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.io import read_record
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import write_simulation
    >>> write_simulation("static.h5", build("static", duration_s=10.0, rate_hz=10.0), np.random.default_rng(0))
    100
    >>> rec = read_record("static.h5")
    >>> rec.scenario, rec.truth is not None
    ('static', True)
    """

    n = scenario.n_samples
    if n < 1:
        raise ValueError("scenario is shorter than one sample")
    if scenario.motion is not None:  # a hand-held session: in memory (minutes of data), no gimbal, no path
        d = _handheld(scenario, rng, False)
        info = RecordInfo(n, scenario.rate_hz, scenario.site, None, Truth(scenario.imu, scenario.gimbal, scenario.noise,
                                                                          None), scenario.name, False, None)
        return write_stream(path, info, [(d.time, d.dtheta, d.dvel, None)], overwrite)
    temp_rng = _temperature_rng(scenario, rng)
    info = RecordInfo(n, scenario.rate_hz, scenario.site, scenario.path,
                      Truth(scenario.imu, scenario.gimbal, scenario.noise, scenario.thermal), scenario.name, True,
                      scenario.temperature_readings(temp_rng))
    chunks = ((c.time, c.dtheta, c.dvel, c.gimbal)
              for c in simulate_chunks(scenario, rng, chunk_size=chunk_size, progress=progress))
    extra = {"temperature_profile": scenario.temperature.to_json()} if scenario.temperature is not None else None
    return write_stream(path, info, chunks, overwrite, extra_attrs=extra)


def scenario_from_record(rec: Record | RecordInfo) -> Scenario:
    """Rebuild the simulation scenario of a simulated record (for truth trajectories)."""

    if rec.truth is None or rec.path is None:
        raise DataFileError("record has no truth/path: it is not a simulated record")
    return Scenario(rec.scenario or "record", rec.path, rec.site, rec.truth.imu, rec.truth.gimbal, rec.truth.noise, rec.rate_hz,
                    rec.truth.thermal, _profile_of(rec))


def _profile_of(rec: Record | RecordInfo) -> TemperatureProfile | None:
    """The temperature profile of a simulated record (its ``temperature_profile`` attribute), if any."""
    src = getattr(rec, "source", "")
    if rec.truth is None or rec.truth.thermal is None or not src:
        return None
    text = record_attrs(src, ("temperature_profile",)).get("temperature_profile")
    return TemperatureProfile.from_json(text) if text else None
