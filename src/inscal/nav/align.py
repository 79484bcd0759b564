"""Initial alignment on a static base: inertial-frame coarse alignment and a Kalman fine alignment."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

from inscal.core import earth
from inscal.core.attitude import quat_from_rotvec_xyz, quat_mul_xyz, quat_rotate_xyz, quat_to_dcm
from inscal.core.error_model import ImuErrors
from inscal.core.kalman import predict, update
from inscal.nav.strapdown import (
    S_Q,
    S_V,
    NavConfig,
    NavState,
    Strapdown,
    two_sample,
)
from inscal.nav.stream import SampleStream


# ============================================================================ alignment
@dataclass(frozen=True)
class AlignConfig:
    """Static alignment: analytic coarse alignment over ``coarse_time``, then a Kalman fine alignment
    over ``fine_time``.

    Parameters
    ----------
    coarse_time : float
        The coarse window [s].
    fine_time : float
        The fine window [s] (0 skips it).
    kf_interval : float
        The fine filter's update interval [s].
    arw : float
        Angle random walk of the filter's model [rad/sqrt(s)].
    vrw : float
        Velocity random walk [m/s/sqrt(s)].
    velocity_sigma : float
        The zero-velocity measurement's sigma [m/s].
    level_sigma, heading_sigma : float
        Initial sigmas of the level and heading errors [rad].
    gyro_bias_sigma, accel_bias_sigma : float
        Initial sigmas of the residual biases [rad/s], [m/s^2].
    apply_bias_estimates : bool
        Keep the filter's residual-bias estimates in the compensation for the navigation that follows
        (keeps the Schuler loop in the equilibrium the filter reached).

    Examples
    --------
    >>> from inscal.nav import AlignConfig
    >>> AlignConfig(coarse_time=10.0, fine_time=20.0).samples(0.1)
    (100, 200)
    """

    coarse_time: float = 60.0
    fine_time: float = 600.0
    kf_interval: float = 0.1
    arw: float = 0.005 * math.pi / 180 / 60.0  # 0.005 deg/sqrt(h)
    vrw: float = 20e-6 * 9.80665  # 20 ug/sqrt(Hz)
    velocity_sigma: float = 1e-3
    level_sigma: float = 1e-3
    heading_sigma: float = 1e-2
    gyro_bias_sigma: float = 0.01 * math.pi / 180 / 3600.0
    accel_bias_sigma: float = 100e-6 * 9.80665
    apply_bias_estimates: bool = True

    def __post_init__(self):
        if not (math.isfinite(self.coarse_time) and self.coarse_time > 0):
            raise ValueError("coarse alignment time must be > 0 s")
        if not (math.isfinite(self.fine_time) and self.fine_time >= 0):
            raise ValueError("fine alignment time must be >= 0 s")
        for n in ("kf_interval", "arw", "vrw", "velocity_sigma", "level_sigma", "heading_sigma",
                  "gyro_bias_sigma", "accel_bias_sigma"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"alignment {n} must be > 0")

    def samples(self, dt: float) -> tuple[int, int]:
        """Samples of the coarse and of the fine alignment at the sample interval ``dt`` [s]."""
        return int(round(self.coarse_time / dt)), int(round(self.fine_time / dt))


@dataclass
class AlignResult:
    """The outcome of an alignment (:func:`align`).

    Parameters
    ----------
    state : NavState
        The navigation state at the end of the alignment.
    k_end : int
        The number of samples used.
    time_end : float
        The time at its end [s].
    coarse_C_s_n : numpy.ndarray
        (3, 3) the coarse attitude at the end of the coarse window.
    gyro_bias, accel_bias : numpy.ndarray
        (3,) residual bias estimates in the s-frame [rad/s], [m/s^2].
    sigma_phi : numpy.ndarray
        (3,) the final 1 sigma of the attitude error [rad].

    Examples
    --------
    >>> from numpy.random import default_rng
    >>> from inscal.nav import AlignConfig, SampleStream, align, chunks_of
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("static", default_rng(0), duration_s=30.0, rate_hz=10.0)
    >>> lat, lon, h = rec.site.latitude, rec.site.longitude, rec.site.height
    >>> res = align(SampleStream(chunks_of(rec)), 0.1, lat, lon, h, AlignConfig(coarse_time=10.0, fine_time=20.0))
    >>> res.k_end, res.time_end
    (300, 30.0)
    """
    state: NavState  # at the end of the alignment
    k_end: int  # number of samples used
    time_end: float
    coarse_C_s_n: np.ndarray  # at the end of the coarse window
    gyro_bias: np.ndarray  # residual bias estimates (s-frame) [rad/s]
    accel_bias: np.ndarray  # [m/s^2]
    sigma_phi: np.ndarray  # final 1-sigma of the attitude error [rad]


@njit(cache=True)
def _inertial_integrals(dth, dv, every, out_v):
    """Integrate the attitude of s relative to its initial (inertial) orientation s0 and
    the specific-force velocity in s0, writing v^{s0} after every ``every`` samples.
    Returns the final quaternion C_s^{s0}."""
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    vx = vy = vz = 0.0
    p0 = p1 = p2 = u0 = u1 = u2 = 0.0
    m = 0
    for j in range(dth.shape[0]):
        a0, a1, a2 = dth[j, 0], dth[j, 1], dth[j, 2]
        b0, b1, b2 = dv[j, 0], dv[j, 1], dv[j, 2]
        r0, r1, r2, c0, c1, c2 = two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, j > 0)
        x, y, z = quat_rotate_xyz(q0, q1, q2, q3, c0, c1, c2)  # C_s^{s0}(k-1) dv_sf
        vx += x
        vy += y
        vz += z
        e0, e1, e2, e3 = quat_from_rotvec_xyz(r0, r1, r2)
        q0, q1, q2, q3 = quat_mul_xyz(q0, q1, q2, q3, e0, e1, e2, e3)
        nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 * nq, q1 * nq, q2 * nq, q3 * nq
        p0, p1, p2, u0, u1, u2 = a0, a1, a2, b0, b1, b2
        if (j + 1) % every == 0 and m < out_v.shape[0]:
            out_v[m, 0], out_v[m, 1], out_v[m, 2] = vx, vy, vz
            m += 1
    return np.array([q0, q1, q2, q3])


def _earth_rotation(w_n: np.ndarray, t) -> np.ndarray:
    """C_{n(t)}^{n0} = exp(t [w x]) for the constant Earth rate w_n of a static site, (N, 3, 3)."""

    t = np.atleast_1d(t)
    return Rotation.from_rotvec(t[:, None] * w_n[None, :]).as_matrix()


def _integrated_gravity_n0(w_n: np.ndarray, f_n: np.ndarray, t: np.ndarray) -> np.ndarray:
    """v^{n0}(t) = int_0^t C_{n(tau)}^{n0} f^n dtau for a static site (closed form)."""
    W = np.linalg.norm(w_n)
    wh = w_n / W
    par = wh * (wh @ f_n)
    perp = f_n - par
    x = np.cross(wh, perp)
    t = np.asarray(t, dtype=float)[:, None]
    return par * t + perp * np.sin(W * t) / W + x * (1.0 - np.cos(W * t)) / W


def coarse_align(dtheta: np.ndarray, dvel: np.ndarray, dt: float, latitude: float, height: float = 0.0,
                 params: ImuErrors | None = None, at_start: bool = False,
                 gravity: earth.GravityModel | None = None) -> np.ndarray:
    """Analytic coarse alignment on a static site, valid also while the turntable turns.

    Inertial-frame (two-vector / Wahba) method: the gyros give ``C_s^{s0}(t)`` (s0 = the IMU frame at
    the start, fixed in inertial space); the specific force integrated in s0 must equal the closed-form
    integral of ``f^n = [0, 0, g]`` in the inertial frame n0 (= n at the start),
    ``v^{n0} = C_{s0}^{n0} v^{s0}``.  ``C_{s0}^{n0}`` follows from an SVD (Wahba) fit over one vector
    per second; then ``C_s^n(T) = C_{n0}^{n(T)} C_{s0}^{n0} C_{s(T)}^{s0}``.

    Parameters
    ----------
    dtheta, dvel : numpy.ndarray
        (N, 3) angular [rad] and velocity [m/s] increments, at least 5 s of them.
    dt : float
        The sample interval [s].
    latitude : float
        The site's latitude [rad].
    height : float
        Its height [m].
    params : ImuErrors, optional
        A calibration to compensate the increments with first.
    at_start : bool
        Return the attitude at the start of the window (``C_{s0}^{n0}``) instead of its end.
    gravity : GravityModel, optional
        The site's gravity model (WGS-84 normal gravity when None).

    Returns
    -------
    numpy.ndarray
        (3, 3) ``C_s^n`` at the end of the window (or at its start).

    Raises
    ------
    ValueError
        Less than 5 s of data.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.attitude import euler_from_dcm
    >>> from inscal.nav import coarse_align
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=10.0, rate_hz=10.0)
    >>> data = simulate(sc, np.random.default_rng(0))
    >>> C = coarse_align(data.dtheta, data.dvel, 0.1, sc.site.latitude)
    >>> np.allclose(np.degrees(euler_from_dcm(C)), 0.0, atol=1e-9)  # the level, North-pointing IMU
    True
    """
    if params is not None:
        dtheta, dvel = params.compensate_increments(dt, dtheta, dvel)
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dvel = np.ascontiguousarray(dvel, dtype=float)
    n = dtheta.shape[0]
    every = max(1, int(round(1.0 / dt)))
    m = n // every
    if m < 5:
        raise ValueError(f"coarse alignment needs at least 5 s of data, got {n * dt:g} s")
    v_s0 = np.zeros((m, 3))
    q_end = _inertial_integrals(dtheta, dvel, every, v_s0)
    t = (np.arange(m) + 1) * every * dt
    w_n = earth.earth_rate_n(latitude)
    f_n = np.array([0.0, 0.0, (gravity or earth.WGS84_GRAVITY).g(latitude, height)])
    v_n0 = _integrated_gravity_n0(w_n, f_n, t)
    # Wahba: maximise sum a_k . C b_k (SVD of B = sum a b^T)
    B = v_n0.T @ v_s0
    U, _, Vt = np.linalg.svd(B)
    D = np.diag([1.0, 1.0, np.linalg.det(U @ Vt)])
    C_s0_n0 = U @ D @ Vt
    if at_start:
        return C_s0_n0
    T = n * dt
    C_n_n0 = _earth_rotation(w_n, np.array([T]))[0]
    return C_n_n0.T @ C_s0_n0 @ quat_to_dcm(q_end)


def _fine_F(C: np.ndarray, lat: float, h: float, gravity: earth.GravityModel | None = None) -> np.ndarray:
    """Error-state matrix of the fine alignment, x = [phi(3), dv_E, dv_N, eps(3), nabla(3)]."""
    rm, rn = earth.radii(lat)
    g = (gravity or earth.WGS84_GRAVITY).g(lat, h)
    W = earth.OMEGA_IE
    wn, wu = W * math.cos(lat), W * math.sin(lat)
    F = np.zeros((11, 11))
    wx = np.array([[0.0, -wu, wn], [wu, 0.0, 0.0], [-wn, 0.0, 0.0]])  # [w_ie x]
    F[0:3, 0:3] = -wx
    # - dw_en(dv): dw_en = [-dv_N/R_M, dv_E/R_N, dv_E tanL/R_N]
    F[0, 4] = 1.0 / (rm + h)
    F[1, 3] = -1.0 / (rn + h)
    F[2, 3] = -math.tan(lat) / (rn + h)
    F[0:3, 5:8] = C
    # dv' = phi x f + C nabla - 2 w_ie x dv (horizontal)
    F[3, 1] = g
    F[4, 0] = -g
    F[3, 4] = 2.0 * wu
    F[4, 3] = -2.0 * wu
    F[3:5, 8:11] = C[0:2, :]
    return F


def align(stream: SampleStream, dt: float, latitude: float, longitude: float, height: float,
          cfg: AlignConfig | None = None, params: ImuErrors | None = None, t0: float = 0.0,
          gravity: earth.GravityModel | None = None) -> AlignResult:
    """Coarse + Kalman fine alignment on the first ``coarse_time + fine_time`` seconds of ``stream``.

    Fine alignment (zero-velocity Kalman filter, T&W ch. 10; S16 eq. 25-27 with a zero reference
    velocity): the mechanization runs with the position clamped to the known site and the vertical
    channel held; every ``kf_interval`` the 11-state filter [attitude, horizontal velocity, gyro and
    accelerometer residual biases] is propagated and updated with the computed horizontal velocity,
    and its estimates are fed back (attitude and velocity into the state, biases into the
    compensation).

    Parameters
    ----------
    stream : SampleStream
        The record's samples; the alignment consumes its first samples.
    dt : float
        The sample interval [s].
    latitude, longitude : float
        The site [rad].
    height : float
        Its height [m].
    cfg : AlignConfig, optional
        The windows and the filter's tuning.
    params : ImuErrors, optional
        A calibration applied on the fly.
    t0 : float
        The time of the start of the first sample [s].
    gravity : GravityModel, optional
        The site's gravity model (WGS-84 normal gravity when None).

    Returns
    -------
    AlignResult
        The state at the end, the samples used, the bias estimates and the attitude's 1 sigma.

    Raises
    ------
    ValueError
        A record shorter than the alignment time.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import AlignConfig, SampleStream, align, chunks_of
    >>> from inscal.sim.scenarios import build
    >>> from inscal.sim.simulate import simulate
    >>> sc = build("static", duration_s=30.0, rate_hz=10.0)
    >>> stream = SampleStream(chunks_of(simulate(sc, np.random.default_rng(0))))
    >>> res = align(stream, 0.1, sc.site.latitude, sc.site.longitude, sc.site.height,
    ...             AlignConfig(coarse_time=10.0, fine_time=20.0))
    >>> bool(res.sigma_phi[2] > res.sigma_phi[0])  # heading is the least observable
    True
    """
    cfg = cfg or AlignConfig()
    nc, nf = cfg.samples(dt)
    first = stream.take(nc)
    if first is None or first[0].shape[0] < nc:
        raise ValueError(f"record shorter than the coarse alignment time ({cfg.coarse_time:g} s)")
    C0 = coarse_align(first[1], first[2], dt, latitude, height, params, gravity=gravity)
    state = NavState(C0, np.zeros(3), latitude, longitude, height)
    gb = np.zeros(3)
    ab = np.zeros(3)
    sig = np.full(3, np.nan)
    if nf == 0:
        return AlignResult(state, nc, t0 + nc * dt, C0, gb, ab, sig)
    nav = Strapdown(state, dt, NavConfig(vertical="hold", output_rate_hz=1.0 / dt), params, k0=nc, t0=t0,
                    fix_position=True, gravity=gravity)
    nblk = max(1, int(round(cfg.kf_interval / dt)))
    T = nblk * dt
    P = np.diag(np.r_[[cfg.level_sigma**2] * 2, cfg.heading_sigma**2, [cfg.velocity_sigma**2] * 2,
                      [cfg.gyro_bias_sigma**2] * 3, [cfg.accel_bias_sigma**2] * 3])
    # the filter [phi, dv_EN | b_g, b_a]: five dynamic states and six constants (core.kalman's block form)
    Qc = np.diag(np.r_[[cfg.arw**2] * 3, [cfg.vrw**2] * 2])
    q_p = np.zeros(6)
    idx = np.array([3, 4])  # the measured states: the horizontal velocity
    r = np.full(2, cfg.velocity_sigma**2)
    K = np.empty((11, 2))
    Sinv = np.empty((2, 2))
    x = np.empty(11)
    done = 0
    C_prev = C0
    I11 = np.eye(11)
    while done < nf:
        blk = stream.take(min(nblk, nf - done))
        if blk is None:
            raise ValueError(f"record shorter than the alignment time ({cfg.coarse_time + cfg.fine_time:g} s)")
        n = blk[0].shape[0]
        nav.run(blk[1], blk[2])
        done += n
        C_now = quat_to_dcm(nav.st[S_Q:S_Q + 4])
        Cm = 0.5 * (C_prev + C_now)  # mean attitude over the block (the turntable may turn)
        Tb = n * dt
        FT = _fine_F(Cm, latitude, height, gravity) * Tb
        FT2 = FT @ FT
        Phi = I11 + FT + FT2 / 2.0 + FT2 @ FT / 6.0  # |F T| << 1 (T <= a few s); the bias rows are I
        # isotropic white noise: its rotation into n changes nothing
        predict(P, 5, np.ascontiguousarray(Phi[:5, :5]), np.ascontiguousarray(Phi[:5, 5:]), Qc * Tb, q_p)
        update(P, idx, r, np.ascontiguousarray(nav.st[S_V:S_V + 2]), K, Sinv, x)  # Joseph form
        # feedback (S16 eq. 27): attitude, velocity, residual biases
        nav.correct(x[0:3], np.r_[x[3:5], 0.0])
        gb = gb + x[5:8]
        ab = ab + x[8:11]
        nav.set_extra_bias(gb, ab)
        C_prev = quat_to_dcm(nav.st[S_Q:S_Q + 4])
    final = nav.state
    final = NavState(final.C_s_n, np.zeros(3), latitude, longitude, height)
    return AlignResult(final, nc + nf, t0 + (nc + nf) * dt, C0, gb, ab, np.sqrt(np.diag(P)[0:3]))
