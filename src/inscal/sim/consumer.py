"""A consumer-MEMS hand-held multi-position session as a logger writes it: int16 counts of a 6-axis chip
(+-250 deg/s, +-2 g) behind its on-chip low-pass filter, with turn-on biases of several deg/s, hand tremor in
the poses, a slow temperature drift and, in a fast turn, a gyro pinned at its range.

Motion (the body's attitude ``C_b^n``, n = East-North-Up at rest on the Earth).  A still start of
``start_s`` s on a table (no tremor), then ``poses`` poses of ``pose_s`` s held by hand; pose j has the
attitude ``C_j``; the move to pose j+1 turns about the fixed body axis ``e_j`` through ``Theta_j`` (the
rotation ``C_j^T C_{j+1}``) with the minimum-jerk profile ``theta = Theta (10 s^3 - 15 s^4 + 6 s^5)`` over
``T_j`` (Flash & Hogan 1985; peak rate ``1.875 Theta / T``).  In a hand-held pose the body trembles about
an axis ``k_j`` (Elble & Koller 1990: physiological tremor 4-12 Hz)::

    C_b^n(t) = C_j Rot(k_j, tau_j(t)),    tau_j = w(t) sum_i a_i sin(2 pi f_i t + phi_i),    w_nb^b = k_j tau_j'

with three components ``f_i`` in 4-11 Hz scaled so that ``tau'`` has the rms ``tremor_dps`` over the
pose, and ``w(t)`` a smooth ramp (``sin^2`` over 0.2 s) at both ends so the pose joins its moves at rest.

Sensor (each triad on its own; ``M = (I + K)(I + E)``, the canonical form of
:class:`inscal.core.error_model.ImuErrors`)::

    gyro  = M_g w_ib^b + b_g + c_g (T - T_mean) + n_g,      accel = M_a f^b + b_a + c_a (T - T_mean) + n_a

at ``internal_hz`` with white noise of density ``arw`` / ``vrw``; the temperature ``T`` rises by
``dT`` with a 300-s time constant; then the chip's second-order Butterworth low-pass filter at ``lpf_hz``
(started at rest on the first value), one sample in ``internal_hz / rate_hz`` kept, rounded to counts of
``range / 32768`` and clipped to -32768 .. 32767.  The truth is the model at the session's mean
temperature.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal
from scipy.spatial.transform import Rotation

from inscal.core.attitude import axis_angle_dcm_array
from inscal.core.earth import Site
from inscal.core.error_model import ImuErrors
from inscal.core.units import DEG, G0

#: int16 full scale
FULL = 32768


@dataclass(frozen=True)
class ConsumerSetup:
    """The session's layout and the chip's specification (field units as named); what is drawn per session
    (attitudes, durations, errors, tremor phases) comes from the generator given to :func:`consumer_session`."""

    tremor_dps: float | tuple[float, float] = (0.1, 2.0)  # tremor rate rms in the poses [deg/s] (a range: log-uniform)
    poses: tuple[int, int] = (9, 12)  # number of hand-held poses (inclusive range)
    start_s: tuple[float, float] = (30.0, 40.0)  # still start on a table
    pose_s: tuple[float, float] = (2.0, 7.0)
    move_s: tuple[float, float] = (0.8, 2.5)
    rate_hz: float = 100.0
    internal_hz: float = 1000.0
    lpf_hz: float = 20.0
    gyro_range_dps: float = 250.0
    accel_range_g: float = 2.0
    gyro_bias_dps: float = 3.0  # 1 sigma per axis, turn-on
    accel_bias_mg: float = 40.0
    scale_factor: float = 0.01  # 1 sigma, both triads (consumer parts: +-3 % at most)
    misalignment_deg: float = 0.5  # 1 sigma, both triads
    arw_dps_rthz: float = 0.005  # gyro white noise [deg/s/sqrt(Hz)]
    vrw_ug_rthz: float = 300.0  # accelerometer white noise [ug/sqrt(Hz)]
    temp_rise_c: tuple[float, float] = (0.2, 1.0)
    gyro_tempco_dps_c: float = 0.003  # 1 sigma per axis [deg/s/degC]
    accel_tempco_mg_c: float = 0.1  # [mg/degC]

    def __post_init__(self):
        tr = np.atleast_1d(np.asarray(self.tremor_dps, float))
        if np.any(tr < 0) or self.rate_hz <= 0 or self.internal_hz % self.rate_hz or self.lpf_hz >= self.rate_hz / 2:
            raise ValueError(f"consumer session: tremor >= 0, internal_hz a multiple of rate_hz, lpf_hz below "
                             f"rate_hz / 2; got {self}")


@dataclass(frozen=True)
class ConsumerSession:
    """One logged session: ``time`` [s] and ``counts`` (n, 6: gx gy gz ax ay az, int16 values) with the
    count scales; the truth at the mean temperature; the still intervals and the tremor of each pose."""

    time: np.ndarray
    counts: np.ndarray
    gyro_scale: float  # rad/s per count
    accel_scale: float  # m/s^2 per count
    truth: ImuErrors
    still: tuple[tuple[float, float], ...]  # (t0, t1) of the still start and every pose
    tremor_dps: tuple[float, ...]  # the tremor rate rms of each of ``still`` (0 for the still start)
    saturated: int  # samples with a gyro or accelerometer count at its limit
    setup: ConsumerSetup = field(default_factory=ConsumerSetup)
    attitudes: tuple[np.ndarray, ...] = ()  # C_b^n of every still stretch (the tremor's mean attitude)
    temperature: np.ndarray | None = None  # T - T_mean at every sample [degC]

    @property
    def rates(self) -> tuple[np.ndarray, np.ndarray]:
        """The readings in SI (rad/s, m/s^2): counts times their scales."""
        return self.counts[:, :3] * self.gyro_scale, self.counts[:, 3:] * self.accel_scale

    def csv_text(self) -> str:
        """The log as a logger writes it: ``time,gx,gy,gz,ax,ay,az`` (s, counts)."""
        rows = [f"{t:.4f}," + ",".join(str(int(c)) for c in row) for t, row in zip(self.time, self.counts)]
        return "time,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n"

    def mapping_text(self, site: Site) -> str:
        """The import mapping (TOML) of :meth:`csv_text`: rates in counts with their scales, the site."""
        return (f'kind = "rates"\nheader_rows = 1\n[columns]\ntime = "time"\ngx = "gx"\ngy = "gy"\ngz = "gz"\n'
                f'ax = "ax"\nay = "ay"\naz = "az"\n[units]\ntime = "s"\ngyro = "counts"\n'
                f'gyro_scale = {self.gyro_scale!r}\naccel = "counts"\naccel_scale = {self.accel_scale!r}\n'
                f"[site]\nlatitude_deg = {site.latitude / DEG!r}\nlongitude_deg = {site.longitude / DEG!r}\n"
                f"height_m = {site.height!r}\n")


def _directions(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Gravity directions (body frame, "up") of the hand-held poses: the six faces first, then random ones
    spread over the sphere, each tilted by up to 20 deg, in a random order."""
    faces = [np.eye(3)[i] * s for i in range(3) for s in (1.0, -1.0)]
    out = []
    for k in range(n):
        v = faces[k] if k < 6 else rng.normal(size=3)
        v = v / np.linalg.norm(v) + rng.normal(scale=0.2, size=3)
        out.append(v / np.linalg.norm(v))
    order = rng.permutation(n)
    return [out[i] for i in order]


def _attitude(up: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``C_b^n`` with the body vector ``up`` along n-up and a random heading."""
    a = rng.normal(size=3)
    x = a - up * (a @ up)
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    return np.array([x, y, up])  # rows: E, N, U in body components


def _rotation_of(R: np.ndarray) -> tuple[np.ndarray, float]:
    """Axis and angle of the rotation matrix ``R``."""
    v = Rotation.from_matrix(R).as_rotvec()
    ang = float(np.linalg.norm(v))
    return (v / ang if ang > 0 else np.array([0.0, 0.0, 1.0])), ang


def _ramp(t: np.ndarray, t0: float, t1: float, r: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """The window ``w`` that rises as ``sin^2`` over ``r`` s after t0 and falls before t1, and ``w'``."""
    r = min(r, 0.5 * (t1 - t0))
    w, wd = np.ones_like(t), np.zeros_like(t)
    for start, sign in ((t0, 1.0), (t1, -1.0)):
        u = sign * (t - start) / r
        m = (u >= 0) & (u < 1)
        w[m] *= np.sin(0.5 * math.pi * u[m]) ** 2
        wd[m] = sign * math.pi / r * np.sin(0.5 * math.pi * u[m]) * np.cos(0.5 * math.pi * u[m])
    return w, wd


def consumer_session(rng: np.random.Generator, site: Site, setup: ConsumerSetup = ConsumerSetup()) -> ConsumerSession:
    """Draw one session (module docstring) from ``rng``: its layout, the unit's errors, the tremor and the noise."""
    s = setup
    n_poses = int(rng.integers(s.poses[0], s.poses[1] + 1))
    ups = [np.array([0.0, 0.0, 1.0])] + _directions(rng, n_poses)  # the still start lies on the table, z up
    att = [_attitude(u, rng) for u in ups]
    if np.isscalar(s.tremor_dps) or np.ndim(s.tremor_dps) == 0:
        tremor = np.full(n_poses, float(s.tremor_dps))
    else:
        lo, hi = s.tremor_dps
        tremor = np.exp(rng.uniform(math.log(max(lo, 1e-6)), math.log(max(hi, 1e-6)), n_poses)) if hi > 0 else np.zeros(n_poses)
    # the layout: (t0, t1) of every still stretch and the moves between them
    dur = [rng.uniform(*s.start_s)] + list(rng.uniform(*s.pose_s, n_poses))
    mv = rng.uniform(*s.move_s, n_poses)
    still, moves, t = [], [], 0.0
    for j in range(n_poses + 1):
        still.append((t, t + dur[j]))
        t += dur[j]
        if j < n_poses:
            e, ang = _rotation_of(att[j].T @ att[j + 1])
            moves.append((t, mv[j], e, ang))
            t += mv[j]
    t_end = t
    # the tremor of each pose: axis, three components (f, amplitude, phase) with the stated rate rms
    trem = [None]
    for j in range(n_poses):
        k = rng.normal(size=3)
        f = rng.uniform(4.0, 11.0, 3)
        a = rng.uniform(0.5, 1.0, 3)
        ph = rng.uniform(0.0, 2 * math.pi, 3)
        rms = math.sqrt(0.5 * float(np.sum((2 * math.pi * f * a) ** 2)))
        trem.append((k / np.linalg.norm(k), f, a * math.radians(tremor[j]) / rms, ph))
    # kinematics at the internal rate
    ti = np.arange(int(round(t_end * s.internal_hz))) / s.internal_hz
    C = np.empty((ti.size, 3, 3))
    wnb = np.zeros((ti.size, 3))
    for j, (t0, t1) in enumerate(still):
        m = (ti >= t0) & (ti < t1)
        C[m] = att[j]
        if trem[j] is not None and tremor[j - 1] > 0:
            k, f, a, ph = trem[j]
            tt = ti[m]
            arg = 2 * math.pi * f[None] * tt[:, None] + ph[None]
            x, xd = np.sin(arg) @ a, (np.cos(arg) * (2 * math.pi * f)[None]) @ a
            w, wd = _ramp(tt, t0, t1)
            tau, taud = w * x, wd * x + w * xd
            C[m] = att[j] @ axis_angle_dcm_array(k, tau)
            wnb[m] = k[None] * taud[:, None]
    for j, (t0, T, e, Th) in enumerate(moves):
        m = (ti >= t0) & (ti < t0 + T)
        u = (ti[m] - t0) / T
        C[m] = att[j] @ axis_angle_dcm_array(e, Th * u**3 * (10.0 - 15.0 * u + 6.0 * u * u))
        wnb[m] = e[None] * (Th / T * 30.0 * u * u * (1.0 - u) ** 2)[:, None]
    Cnb = np.transpose(C, (0, 2, 1))
    w_ib = wnb + Cnb @ np.asarray(site.earth_rate_n, float)
    f_b = Cnb @ np.array([0.0, 0.0, float(site.gravity)])
    # the unit's errors and the temperature
    kg, ka = rng.normal(0.0, s.scale_factor, 3), rng.normal(0.0, s.scale_factor, 3)
    eg, ea = rng.normal(0.0, math.radians(s.misalignment_deg), 6), rng.normal(0.0, math.radians(s.misalignment_deg), 6)
    bg, ba = rng.normal(0.0, math.radians(s.gyro_bias_dps), 3), rng.normal(0.0, s.accel_bias_mg * 1e-3 * G0, 3)
    cg = rng.normal(0.0, math.radians(s.gyro_tempco_dps_c), 3)
    ca = rng.normal(0.0, s.accel_tempco_mg_c * 1e-3 * G0, 3)
    rise = rng.uniform(*s.temp_rise_c)
    temp = rise * (1.0 - np.exp(-ti / 300.0))
    temp -= temp.mean()
    truth = ImuErrors(gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=bg, accel_scale_factor=ka,
                      accel_misalignment=ea, accel_bias=ba)
    gyro = w_ib @ truth.M_g.T + bg + temp[:, None] * cg
    acc = f_b @ truth.M_a.T + ba + temp[:, None] * ca
    root = math.sqrt(s.internal_hz)
    gyro += math.radians(s.arw_dps_rthz) * root * rng.normal(size=gyro.shape)
    acc += s.vrw_ug_rthz * 1e-6 * G0 * root * rng.normal(size=acc.shape)
    # the chip: low-pass filter, decimation, counts
    b, a = signal.butter(2, s.lpf_hz, fs=s.internal_hz)
    zi = signal.lfilter_zi(b, a)
    x = np.column_stack([gyro, acc])
    y = signal.lfilter(b, a, x, axis=0, zi=zi[:, None] * x[0][None])[0]
    step = int(round(s.internal_hz / s.rate_hz))
    y = y[step - 1::step]
    gscale, ascale = math.radians(s.gyro_range_dps) / FULL, s.accel_range_g * G0 / FULL
    raw = np.rint(y / np.array([gscale] * 3 + [ascale] * 3))
    sat = int(np.count_nonzero(np.any((raw >= FULL - 1) | (raw <= -FULL), axis=1)))
    counts = np.clip(raw, -FULL, FULL - 1).astype(np.int64)
    time = ti[step - 1::step] + 1.0 / s.internal_hz
    return ConsumerSession(time, counts, gscale, ascale, truth, tuple((float(a0), float(a1)) for a0, a1 in still),
                           (0.0,) + tuple(float(x) for x in tremor), sat, s, tuple(att), temp[step - 1::step])
