"""Navigation runs: initialisation (truth or static alignment), orchestration over
chunked records, error analysis against the truth, oscillation components, and the
linear error model / closed forms used to check the mechanization.

Error conventions (SI, ENU):

* attitude error ``phi`` with ``C_est = exp([phi x]) C_true`` (the rotation vector of
  :func:`inscal.attitude.small_angle_error`), so a level error of the computed
  frame about North is ``phi_N``; with this sign an East accelerometer bias ``b``
  settles at ``phi_N = -b/g`` (T&W ch. 12, tilt = -bias/g);
* velocity error ``v_est - v_true``; position error in metres East/North/Up
  ``[(lambda_est - lambda) (R_N + h) cos L, (L_est - L)(R_M + h), h_est - h]``.

Linear error model (phi-angle form, ENU, vertical channel held; T&W ch. 12, S16 eq. 17
without the vertical terms), derived for ``C_est = (I + [phi x]) C``::

    phi'  = -w_ie x phi - dw_en(dv) - dw_ie(dL) + C_s^n eps          dw_ie = W [0, -sin L, cos L] dL
    dv'   =  phi x f^n + C_s^n nabla - 2 w_ie x dv      (horizontal)   dw_en = [-dv_N/R_M, dv_E/R_N, dv_E tan L/R_N]
    dL'   =  dv_N / R_M,        dlambda' = dv_E / (R_N cos L)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

import numpy as np
from numba import njit
from scipy.linalg import expm
from scipy.optimize import least_squares

from . import earth
from .attitude import dcm_from_euler, euler_from_dcm, quat_to_dcm, small_angle_error
from .errors import GimbalErrors, ImuErrors
from .strapdown import S_HREF, S_Q, S_V, NavConfig, NavOutput, NavState, Strapdown, _qmul, _qrot, _qrv, _two_sample

DAY = 86400.0


# =============================================================================== streams
class SampleStream:
    """Consumes an iterable of ``(time, dtheta, dvel, gimbal)`` chunks; ``take(n)`` returns the
    next n samples (concatenated), ``chunks()`` the rest, chunk by chunk."""

    def __init__(self, chunks: Iterable):
        self._it = iter(chunks)
        self._pending = None

    def _next(self):
        if self._pending is not None:
            p, self._pending = self._pending, None
            return p
        c = next(self._it)
        if hasattr(c, "dtheta"):  # simulate.Chunk
            c = (c.time, c.dtheta, c.dvel, c.gimbal)
        return c

    def peek(self):
        """The next chunk without consuming it (None at the end)."""
        if self._pending is None:
            try:
                self._pending = self._next()
            except StopIteration:
                return None
        return self._pending

    def take(self, n: int):
        parts, have = [], 0
        while have < n:
            try:
                t, dth, dv, g = self._next()
            except StopIteration:
                break
            need = n - have
            if t.shape[0] > need:
                self._pending = (t[need:], dth[need:], dv[need:], None if g is None else g[need:])
                t, dth, dv, g = t[:need], dth[:need], dv[:need], None if g is None else g[:need]
            parts.append((t, dth, dv, g))
            have += t.shape[0]
        if not parts:
            return None
        g = None if any(p[3] is None for p in parts) else np.concatenate([p[3] for p in parts])
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]), g)

    def chunks(self) -> Iterator:
        while True:
            try:
                yield self._next()
            except StopIteration:
                return


def chunks_of(data, chunk_size: int = 1 << 19) -> Iterator:
    """Chunk tuples from an in-memory record (SimData or io.Record: .time .dtheta .dvel .gimbal)."""
    n = data.time.shape[0]
    for k in range(0, n, chunk_size):
        sl = slice(k, k + chunk_size)
        yield data.time[sl], data.dtheta[sl], data.dvel[sl], None if data.gimbal is None else data.gimbal[sl]


# ============================================================================ alignment
@dataclass(frozen=True)
class AlignConfig:
    """Static alignment: analytic coarse alignment over ``coarse_time``, then a Kalman fine
    alignment over ``fine_time`` (seconds; 0 skips it).

    Noise densities (SI) tune the fine-alignment filter: ``arw`` [rad/sqrt(s)],
    ``vrw`` [m/s/sqrt(s)], ``velocity_sigma`` [m/s] (zero-velocity measurement),
    initial sigmas of level/heading error [rad] and gyro/accel residual biases.
    ``apply_bias_estimates``: keep the filter's residual-bias estimates in the
    compensation for the navigation that follows (keeps the Schuler loop in the
    equilibrium the filter reached)."""

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


@dataclass
class AlignResult:
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
        r0, r1, r2, c0, c1, c2 = _two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, j > 0)
        x, y, z = _qrot(q0, q1, q2, q3, c0, c1, c2)  # C_s^{s0}(k-1) dv_sf
        vx += x
        vy += y
        vz += z
        e0, e1, e2, e3 = _qrv(r0, r1, r2)
        q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, e0, e1, e2, e3)
        nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 * nq, q1 * nq, q2 * nq, q3 * nq
        p0, p1, p2, u0, u1, u2 = a0, a1, a2, b0, b1, b2
        if (j + 1) % every == 0 and m < out_v.shape[0]:
            out_v[m, 0], out_v[m, 1], out_v[m, 2] = vx, vy, vz
            m += 1
    return np.array([q0, q1, q2, q3])


def _earth_rotation(w_n: np.ndarray, t) -> np.ndarray:
    """C_{n(t)}^{n0} = exp(t [w x]) for the constant Earth rate w_n of a static site, (N, 3, 3)."""
    from scipy.spatial.transform import Rotation

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

    Inertial-frame (two-vector / Wahba) method: the gyros give ``C_s^{s0}(t)`` (s0 = the
    IMU frame at the start, fixed in inertial space); the specific force integrated in s0
    must equal the closed-form integral of ``f^n = [0, 0, g]`` in the inertial frame n0
    (= n at the start), ``v^{n0} = C_{s0}^{n0} v^{s0}``.  ``C_{s0}^{n0}`` follows from an SVD
    (Wahba) fit over one vector per second; then
    ``C_s^n(T) = C_{n0}^{n(T)} C_{s0}^{n0} C_{s(T)}^{s0}``.  Returns ``C_s^n`` at the end of the window
    (``at_start``: ``C_{s0}^{n0}``, the attitude at the start of the window).  ``gravity``: the
    site's gravity model (WGS-84 normal gravity when None).
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

    Fine alignment (zero-velocity Kalman filter, T&W ch. 10; S16 eq. 25-27 with a zero
    reference velocity): the mechanization runs with the position clamped to the known
    site and the vertical channel held; every ``kf_interval`` the 11-state filter
    [attitude, horizontal velocity, gyro and accelerometer residual biases] is propagated
    and updated with the computed horizontal velocity, and its estimates are fed back
    (attitude and velocity into the state, biases into the compensation).
    """
    cfg = cfg or AlignConfig()
    nc = int(round(cfg.coarse_time / dt))
    first = stream.take(nc)
    if first is None or first[0].shape[0] < nc:
        raise ValueError(f"record shorter than the coarse alignment time ({cfg.coarse_time:g} s)")
    C0 = coarse_align(first[1], first[2], dt, latitude, height, params, gravity=gravity)
    state = NavState(C0, np.zeros(3), latitude, longitude, height)
    nf = int(round(cfg.fine_time / dt))
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
    Qc = np.zeros(11)
    Qc[0:3] = cfg.arw**2
    Qc[3:5] = cfg.vrw**2
    H = np.zeros((2, 11))
    H[0, 3] = H[1, 4] = 1.0
    R = np.eye(2) * cfg.velocity_sigma**2
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
        Phi = I11 + FT + FT2 / 2.0 + FT2 @ FT / 6.0  # |F T| << 1 (T <= a few s)
        P = Phi @ P @ Phi.T + np.diag(Qc) * Tb  # isotropic white noise: its rotation into n changes nothing
        P = 0.5 * (P + P.T)
        z = nav.st[S_V:S_V + 2]
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x = K @ z
        IKH = I11 - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T  # Joseph form
        # feedback (S16 eq. 27): attitude, velocity, residual biases
        nav.correct(x[0:3], np.r_[x[3:5], 0.0])
        gb = gb + x[5:8]
        ab = ab + x[8:11]
        nav.set_extra_bias(gb, ab)
        C_prev = quat_to_dcm(nav.st[S_Q:S_Q + 4])
    final = nav.state
    final = NavState(final.C_s_n, np.zeros(3), latitude, longitude, height)
    return AlignResult(final, nc + nf, t0 + (nc + nf) * dt, C0, gb, ab, np.sqrt(np.diag(P)[0:3]))


# ============================================================================ truth and errors
@dataclass
class NavErrors:
    """Errors of a navigation output against a static-site truth (SI).  Without a simulation
    truth (recorded data) only the position and velocity errors are known (the site is
    static and surveyed); ``attitude`` and ``vehicle`` are then None."""

    time: np.ndarray
    attitude: np.ndarray | None  # IMU attitude error phi, n-frame (N, 3) [rad]
    vehicle: np.ndarray | None  # vehicle [roll, pitch, yaw] error (N, 3) [rad]
    velocity: np.ndarray  # (N, 3) [m/s]
    position: np.ndarray  # East, North, Up (N, 3) [m]

    @property
    def horizontal(self) -> np.ndarray:
        return np.hypot(self.position[:, 0], self.position[:, 1])


def _wrap(a):
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def navigation_errors(out: NavOutput, scenario=None, gimbal_model: GimbalErrors | None = None,
                      site=None) -> NavErrors:
    """Errors of ``out`` against the truth of a simulated static-site ``scenario``: the site
    position, zero velocity, the true IMU attitude (:func:`inscal.simulate.true_attitude`)
    and the true vehicle attitude (the gimbal mount attitude, N25 eq. 8).  With only a
    ``site`` (recorded data on a static base), position and velocity errors."""
    from .simulate import true_attitude

    if scenario is not None:
        site = scenario.site
        C_true = true_attitude(scenario, out.time)
        phi = small_angle_error(out.C_s_n, C_true)
        if out.gimbal is not None:
            veh_true = euler_from_dcm(dcm_from_euler(scenario.gimbal.mount_attitude))
        else:  # no gimbal angles recorded: compare the IMU attitude's Euler angles
            veh_true = euler_from_dcm(C_true)
        veh = _wrap(out.vehicle_attitude(gimbal_model) - veh_true)
    elif site is None:
        raise ValueError("navigation errors need a scenario (truth) or at least the static site")
    else:
        phi = veh = None
    rm, rn = earth.radii(site.latitude)
    pos = np.stack([
        _wrap(out.position[:, 1] - site.longitude) * (rn + site.height) * math.cos(site.latitude),
        (out.position[:, 0] - site.latitude) * (rm + site.height),
        out.position[:, 2] - site.height,
    ], axis=-1)
    return NavErrors(out.time.copy(), phi, veh, out.velocity.copy(), pos)


# ----------------------------------------------------------------------- oscillations
def schuler_frequency(lat: float, h: float = 0.0) -> float:
    """w_s = sqrt(g / R) with R the geometric mean radius (T&W ch. 12)."""
    return 2.0 * math.pi / earth.schuler_period(lat, h)


def foucault_frequency(lat: float) -> float:
    return earth.OMEGA_IE * abs(math.sin(lat))


def fit_oscillation(t: np.ndarray, x: np.ndarray, period_guess: float, trend: bool = True) -> dict:
    """Least-squares fit of ``x = c0 [+ c1 t] + A cos(2 pi t / P + p)`` with the period P free
    (variable projection: the linear coefficients are solved for each P).
    Returns period, amplitude, phase, offset, slope and the rms residual."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    tc = t - t[0]
    tn = tc / max(tc[-1], 1.0)

    def design(P):
        w = 2 * math.pi / P
        cols = [np.ones_like(tc)] + ([tn] if trend else []) + [np.cos(w * tc), np.sin(w * tc)]
        return np.stack(cols, axis=-1)

    def resid(p):
        A = design(p[0])
        c, *_ = np.linalg.lstsq(A, x, rcond=None)
        return A @ c - x

    r = least_squares(resid, [period_guess], x_scale=[period_guess * 0.01], xtol=1e-14, ftol=1e-14, gtol=1e-14)
    P = float(r.x[0])
    A = design(P)
    c, *_ = np.linalg.lstsq(A, x, rcond=None)
    a, b = c[-2], c[-1]
    return {"period": P, "amplitude": float(math.hypot(a, b)), "phase": float(math.atan2(-b, a)),
            "offset": float(c[0]), "slope": float(c[1] / max(tc[-1], 1.0)) if trend else 0.0,
            "rms_residual": float(np.sqrt(np.mean((A @ c - x) ** 2)))}


def oscillation_components(t: np.ndarray, x: np.ndarray, lat: float) -> dict:
    """Amplitudes of the Schuler (84.4 min), Earth (24 h) and Foucault components of an error
    time series, by linear least squares on fixed frequencies with an offset and a trend.

    * Schuler: the Schuler-band oscillation.  When the record resolves the Foucault
      splitting (duration >= one Foucault period 2 pi/(W sin L)), the band is modelled as
      the two lines ``w_s +- w_F`` with amplitudes A+ and A-; ``schuler`` = A+ + A- (the
      peak of the envelope) and ``foucault`` = min(A+, A-) (half the envelope's
      peak-to-peak modulation over a Foucault period).  Otherwise one line at w_s and
      ``foucault`` = None.  Needs at least one Schuler period.
    * Earth: the line at W (needs >= 24 h, else None).
    Amplitudes in the unit of ``x``; ``trend`` per second.
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    tc = t - t[0]
    T = float(tc[-1]) if tc.size else 0.0
    ws = schuler_frequency(lat)
    wf = foucault_frequency(lat)
    W = earth.OMEGA_IE
    res: dict = {"schuler": None, "foucault": None, "earth": None, "trend": None, "duration": T}
    if T <= 0:
        return res
    cols = [np.ones_like(tc), tc / T]
    names = []
    if T >= 2 * math.pi / ws:
        freqs = [ws - wf, ws + wf] if (wf > 0 and T >= 2 * math.pi / wf) else [ws]
        for f in freqs:
            cols += [np.cos(f * tc), np.sin(f * tc)]
            names.append(("schuler", f))
    if T >= 2 * math.pi / W:
        cols += [np.cos(W * tc), np.sin(W * tc)]
        names.append(("earth", W))
    A = np.stack(cols, axis=-1)
    c, *_ = np.linalg.lstsq(A, x, rcond=None)
    res["trend"] = float(c[1] / T)
    amps: dict = {}
    for i, (name, f) in enumerate(names):
        amps.setdefault(name, []).append(float(math.hypot(c[2 + 2 * i], c[3 + 2 * i])))
    if "schuler" in amps:
        a = amps["schuler"]
        res["schuler"] = float(sum(a))
        res["foucault"] = float(min(a)) if len(a) == 2 else None
    if "earth" in amps:
        res["earth"] = amps["earth"][0]
    return res


def summarize(err: NavErrors, lat: float) -> dict:
    """Summary figures (SI): maxima, final values, oscillation components."""
    hor = err.horizontal
    out = {
        "duration_s": float(err.time[-1] - err.time[0]) if err.time.size else 0.0,
        "max_position_error_m": float(np.max(hor)),
        "final_position_error_m": float(hor[-1]),
        "max_velocity_error_mps": float(np.max(np.linalg.norm(err.velocity[:, 0:2], axis=-1))),
        "max_velocity_error_enu_mps": np.max(np.abs(err.velocity), axis=0),
        "final_position_error_en_m": err.position[-1, 0:2],
        "max_attitude_error_rad": None,
        "max_imu_attitude_error_rad": None,
    }
    series = [("position_east", err.position[:, 0]), ("position_north", err.position[:, 1]),
              ("velocity_east", err.velocity[:, 0]), ("velocity_north", err.velocity[:, 1])]
    if err.vehicle is not None:
        out["max_attitude_error_rad"] = np.max(np.abs(err.vehicle), axis=0)  # roll, pitch, yaw
        out["max_imu_attitude_error_rad"] = np.max(np.abs(err.attitude), axis=0)  # phi E, N, U
        series += [("roll", err.vehicle[:, 0]), ("pitch", err.vehicle[:, 1]), ("yaw", err.vehicle[:, 2])]
    comps = {}
    for name, x in series:
        comps[name] = oscillation_components(err.time, x, lat)
    out["components"] = comps
    return out


# ============================================================================ height reference
class HeightReference:
    """External height for the vertical channel (a barometer, a survey, a depth gauge): a
    constant ``height_m`` or a profile ``time_s``, ``height_m`` (linearly interpolated, held at
    its end values outside its span).  The damped vertical loop ("damped") tracks it, "hold"
    follows it; the navigator updates the reference once per ``UPDATE_S`` seconds."""

    #: how often the navigator reads the reference [s] (the third-order loop's tau is ~100 s)
    UPDATE_S = 1.0

    def __init__(self, height_m=None, time_s=None):
        if time_s is None:
            h = float(height_m)
            if not math.isfinite(h):
                raise ValueError(f"reference height must be finite, got {height_m!r}")
            self.time = None
            self.height = np.array([h])
            return
        t = np.asarray(time_s, dtype=float).ravel()
        h = np.asarray(height_m, dtype=float).ravel()
        if t.size != h.size or t.size == 0:
            raise ValueError(f"height reference needs as many heights as times (got {t.size} and {h.size}), at least one")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(h))):
            raise ValueError("height reference: times and heights must be finite numbers")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise ValueError(f"height reference: times must increase (row {k + 2}: {t[k + 1]:g} s after {t[k]:g} s)")
        self.time, self.height = t, h

    @property
    def constant(self) -> bool:
        return self.time is None

    def __call__(self, t):
        if self.time is None:
            return np.full(np.shape(t), self.height[0]) if np.ndim(t) else float(self.height[0])
        return np.interp(t, self.time, self.height)

    def span(self) -> tuple[float, float] | None:
        return None if self.time is None else (float(self.time[0]), float(self.time[-1]))

    @classmethod
    def read_csv(cls, path) -> "HeightReference":
        """A CSV file with a header row naming the columns ``time_s`` and ``height_m`` (any order,
        other columns ignored; ``#`` comments allowed)."""
        import csv

        with open(path, newline="", encoding="utf-8") as fh:
            rows = [r for r in csv.reader(line for line in fh if line.strip() and not line.lstrip().startswith("#"))]
        if not rows:
            raise ValueError(f"{path}: empty height reference (expected a header time_s,height_m and rows)")
        head = [c.strip() for c in rows[0]]
        if "time_s" not in head or "height_m" not in head:
            raise ValueError(f"{path}: the header must name the columns time_s and height_m, got {','.join(head)[:80]!r}")
        it, ih = head.index("time_s"), head.index("height_m")
        t, h = [], []
        for n, r in enumerate(rows[1:], start=2):
            try:
                t.append(float(r[it]))
                h.append(float(r[ih]))
            except (IndexError, ValueError):
                raise ValueError(f"{path}: row {n} is not two numbers time_s, height_m: {','.join(r)[:80]!r}") from None
        if not t:
            raise ValueError(f"{path}: no rows after the header")
        try:
            return cls(h, t)
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


# ============================================================================ orchestration
@dataclass
class NavResult:
    output: NavOutput
    errors: NavErrors | None
    summary: dict | None
    alignment: AlignResult | None
    config: NavConfig
    init: str


def compensated_chunks(chunks, params: ImuErrors, dt: float):
    """``(t, dtheta, dvel, gimbal)`` chunks compensated with ``params`` (one chunk of look-ahead)."""
    prev = None
    it = iter(chunks)
    cur = next(it, None)
    while cur is not None:
        nxt = next(it, None)
        t, dth, dv, g = cur
        after = (nxt[1][0], nxt[2][0]) if nxt is not None and len(nxt[1]) else None
        cdth, cdv = params.compensate_increments(dt, dth, dv, prev=prev, next=after)
        if len(dth):
            prev = (dth[-1], dv[-1])
        yield t, cdth, cdv, g
        cur = nxt


def navigate(chunks: Iterable, rate_hz: float, site, *, init="truth", scenario=None,
             params: ImuErrors | None = None, gimbal_model: GimbalErrors | None = None,
             config: NavConfig | None = None, align_config: AlignConfig | None = None,
             vref=None, progress: Callable[[float], None] | None = None,
             height_ref: "HeightReference | float | None" = None) -> NavResult:
    """Navigate a chunked record.

    ``chunks``: iterable of ``(time, dtheta, dvel, gimbal)`` (e.g. :func:`inscal.io.iter_chunks`,
    :func:`chunks_of`) or :class:`inscal.simulate.Chunk` objects.  ``site``: the known static site
    (latitude, longitude, height; its ``gravity_model``, when it has one, is used throughout).
    ``init``: "truth" (needs ``scenario``), "align" (static coarse +
    fine alignment, navigation continues from its end), or a :class:`NavState` at the start.
    ``params``: calibration set applied on the fly (S16 compensation form); ``gimbal_model``: the
    gimbal non-orthogonality used to map the IMU attitude to the vehicle.  With a ``scenario``,
    errors against its truth and a summary are computed.  ``height_ref``: an external height
    (:class:`HeightReference`, or a constant in metres) for the vertical channel's reference in
    place of the initial height ("damped" tracks it, "hold" follows it; "free" refuses it).
    """
    config = config or NavConfig()
    dt = 1.0 / rate_hz
    gravity = getattr(site, "gravity_model", None)
    stream = SampleStream(chunks)
    if params is not None and (params.has_asynchrony or np.any(params.accel_lever_arm - np.diag(np.diag(params.accel_lever_arm)))):
        # sample-to-sample terms (time asynchrony, tangential size effect) need the next sample:
        # compensate ahead of the kernel exactly as the systematic calibration does
        stream = SampleStream(compensated_chunks(stream.chunks(), params, dt))
        params = None
    head = stream.peek()
    if head is None or head[0].shape[0] == 0:
        raise ValueError("record has no samples")
    t0 = float(head[0][0]) - dt  # time of the start of the first sample
    alignment = None
    if isinstance(init, NavState):
        state, k0, label = init, 0, "given"
    elif init == "truth":
        if scenario is None:
            raise ValueError("initialisation from truth needs the simulation scenario (record has no truth)")
        state, k0, label = NavState.from_truth(scenario, t0), 0, "truth"
    elif init == "align":
        alignment = align(stream, dt, site.latitude, site.longitude, site.height, align_config, params, t0=t0,
                          gravity=gravity)
        state, k0, label = alignment.state, alignment.k_end, "align"
    else:
        raise ValueError(f"init must be 'truth', 'align' or a NavState, got {init!r}")
    nav = Strapdown(state, dt, config, params, k0=k0, t0=t0, gravity=gravity)
    if alignment is not None and (align_config or AlignConfig()).apply_bias_estimates:
        nav.set_extra_bias(alignment.gyro_bias, alignment.accel_bias)
    if height_ref is not None and not isinstance(height_ref, HeightReference):
        height_ref = HeightReference(height_ref)
    if height_ref is not None and config.vertical == "free":
        raise ValueError("a height reference needs a damped (or held) vertical channel, not vertical 'free'")
    profile = height_ref is not None and not height_ref.constant
    if height_ref is not None and not profile:
        nav.st[S_HREF] = height_ref.height[0]
    blk = max(1, int(round(HeightReference.UPDATE_S * rate_hz)))
    parts = []
    for t, dth, dv, g in stream.chunks():
        vr = None
        if vref is not None:
            vr = vref(t) if callable(vref) else vref
        if profile:  # the reference once per UPDATE_S, at the middle of each block of samples
            per = vr is not None and np.ndim(vr) == 2 and np.shape(vr)[0] == t.shape[0]
            for a in range(0, t.shape[0], blk):
                b = min(a + blk, t.shape[0])
                nav.st[S_HREF] = height_ref(0.5 * (t[a] + t[b - 1]))
                parts.append(nav.run(dth[a:b], dv[a:b], None if g is None else g[a:b], vr[a:b] if per else vr))
        else:
            parts.append(nav.run(dth, dv, g, vr))
        if progress is not None:
            progress(float(t[-1]))
    if not parts:
        raise ValueError("no samples left to navigate after the alignment")
    out = NavOutput.concatenate(parts)
    # static base: position and velocity are known even without a simulation truth
    errors = navigation_errors(out, scenario, gimbal_model, site=site)
    summary = summarize(errors, site.latitude)
    return NavResult(out, errors, summary, alignment, config, label)


def write_nav(path, res: NavResult, meta: dict | None = None, overwrite: bool = False) -> None:
    """Write a navigation result to HDF5 (SI datasets, atomic; see ``inscal navigate``)::

        /time (N,) s; /quaternion (N,4) C_s^n scalar-first; /velocity (N,3) m/s ENU;
        /position (N,3) lat rad, lon rad, h m; /vehicle_attitude (N,3) rad roll/pitch/yaw;
        /gimbal (N,2) rad (if recorded); /errors/{position,velocity[,attitude,vehicle]};
        attrs: kind="inscal-navigation", schema_version, mode, vertical, init, meta (JSON), summary (JSON).
    """
    import json

    import h5py

    from . import SCHEMA_VERSION, __version__
    from .io import atomic_path

    def _js(o):
        return json.dumps(o, default=lambda v: v.tolist() if hasattr(v, "tolist") else str(v))

    out = res.output
    with atomic_path(path, overwrite=overwrite) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["kind"] = "inscal-navigation"
            h5.attrs["schema_version"] = SCHEMA_VERSION
            h5.attrs["inscal_version"] = __version__
            h5.attrs["mode"] = res.config.mode
            h5.attrs["vertical"] = res.config.vertical
            h5.attrs["init"] = res.init
            h5.attrs["meta"] = _js(meta or {})
            h5.attrs["summary"] = _js(res.summary or {})
            h5.attrs["units"] = json.dumps({"time": "s", "quaternion": "1", "velocity": "m/s", "position": "rad,rad,m",
                                            "vehicle_attitude": "rad", "gimbal": "rad", "errors/position": "m",
                                            "errors/velocity": "m/s", "errors/attitude": "rad", "errors/vehicle": "rad"})
            h5["time"] = out.time
            h5["quaternion"] = out.quaternion
            h5["velocity"] = out.velocity
            h5["position"] = out.position
            gm = None
            if meta and meta.get("gimbal_nonorthogonality_rad"):
                gm = GimbalErrors(meta["gimbal_nonorthogonality_rad"])
            h5["vehicle_attitude"] = out.vehicle_attitude(gm)
            if out.gimbal is not None:
                h5["gimbal"] = out.gimbal
            if res.errors is not None:
                g = h5.create_group("errors")
                g["position"] = res.errors.position
                g["velocity"] = res.errors.velocity
                if res.errors.attitude is not None:
                    g["attitude"] = res.errors.attitude
                    g["vehicle"] = res.errors.vehicle


# ============================================================================ error model / closed forms
def linear_error_model(C_s_n: np.ndarray, lat: float, t: np.ndarray, gyro_bias=(0, 0, 0), accel_bias=(0, 0, 0),
                       height: float = 0.0, phi0=(0, 0, 0)) -> dict:
    """Propagate the linear phi-angle error model (module docstring) for a static IMU
    attitude ``C_s_n`` and constant biases (s-frame, SI), exactly (matrix exponential),
    at uniformly spaced times ``t`` (t[0] = 0).  Returns phi (N, 3), dv (N, 2),
    position East/North [m] (N, 2)."""
    rm, rn = earth.radii(lat)
    rm, rn = rm + height, rn + height
    g = earth.normal_gravity(lat, height)
    W = earth.OMEGA_IE
    sl, cl = math.sin(lat), math.cos(lat)
    wn, wu = W * cl, W * sl
    C = np.asarray(C_s_n, dtype=float)
    eps = C @ np.asarray(gyro_bias, dtype=float)
    nab = C @ np.asarray(accel_bias, dtype=float)
    # x = [phiE, phiN, phiU, dvE, dvN, dL, dlam]
    F = np.zeros((8, 8))
    F[0:3, 0:3] = -np.array([[0.0, -wu, wn], [wu, 0.0, 0.0], [-wn, 0.0, 0.0]])
    F[0, 4] = 1.0 / rm  # -dw_en
    F[1, 3] = -1.0 / rn
    F[2, 3] = -math.tan(lat) / rn
    F[1, 5] = W * sl  # -dw_ie = -W [0, -sinL, cosL] dL
    F[2, 5] = -W * cl
    F[3, 1] = g  # phi x f
    F[4, 0] = -g
    F[3, 4] = 2 * wu  # -2 w_ie x dv
    F[4, 3] = -2 * wu
    F[5, 4] = 1.0 / rm
    F[6, 3] = 1.0 / (rn * cl)
    F[0:3, 7] = eps  # constant forcing as an augmented state
    F[3:5, 7] = nab[0:2]
    t = np.asarray(t, dtype=float)
    x = np.zeros(8)
    x[0:3] = phi0
    x[7] = 1.0
    out = np.empty((t.size, 8))
    h = t[1] - t[0] if t.size > 1 else 0.0
    Phi = expm(F * h)
    for i in range(t.size):
        out[i] = x
        x = Phi @ x
    return {"phi": out[:, 0:3], "dv": out[:, 3:5],
            "position": np.stack([out[:, 6] * rn * cl, out[:, 5] * rm], axis=-1)}


def gyro_bias_closed_form(eps_n, lat: float, t) -> dict:
    """Schuler-averaged (24-hour) closed-form errors for a constant gyro bias ``eps_n``
    = [E, N, U] in the n-frame on a static base (T&W ch. 12; Britting), with the level
    tilts in equilibrium and terms of order (W/w_s)^2 dropped::

        p      = eps_U cos L - eps_N sin L
        dL     = (p/W)(1 - cos Wt) - (eps_E/W) sin Wt
        dlam cos L = eps_N t + sin L [p (t - sin(Wt)/W) - (eps_E/W)(1 - cos Wt)]
        phi_U  = [p sin Wt + eps_E (1 - cos Wt)] / (W cos L)

    (derived from the phi-angle model of the module docstring with phi' = 0 on the level
    axes).  Returns position East/North [m] (R = the Gaussian mean radius) and phi_U."""
    eE, eN, eU = (float(v) for v in eps_n)
    W = earth.OMEGA_IE
    t = np.asarray(t, dtype=float)
    sl, cl = math.sin(lat), math.cos(lat)
    rm, rn = earth.radii(lat)
    p = eU * cl - eN * sl
    dL = p / W * (1 - np.cos(W * t)) - eE / W * np.sin(W * t)
    dlc = eN * t + sl * (p * (t - np.sin(W * t) / W) - eE / W * (1 - np.cos(W * t)))
    phiU = (p * np.sin(W * t) + eE * (1 - np.cos(W * t))) / (W * cl)
    return {"position": np.stack([dlc * rn, dL * rm], axis=-1), "phi_up": phiU}


def accel_bias_closed_form(b_east: float, lat: float, t) -> dict:
    """Single-channel Schuler solution for an East accelerometer bias (T&W ch. 12): exact for
    the phi-angle model at the equator (no Foucault or Earth-rate coupling of the channel)::

        phi_N = -(b/g)(1 - cos w_s t),  dv_E = (b/w_s) sin w_s t,  dx_E = (b/w_s^2)(1 - cos w_s t)

    with w_s = sqrt(g/R_N) (the East channel's transport rate uses R_N)."""
    t = np.asarray(t, dtype=float)
    g = earth.normal_gravity(lat)
    _, rn = earth.radii(lat)
    ws = math.sqrt(g / rn)
    return {"omega": ws, "phi_north": -(b_east / g) * (1 - np.cos(ws * t)),
            "dv_east": b_east / ws * np.sin(ws * t), "position_east": b_east / ws**2 * (1 - np.cos(ws * t))}
