"""The canonical IMU and gimbal error model.

Frame: the N25 s-frame (z = inner gimbal axis, x = projection of the outer axis at
its zero position onto the plane normal to z).  All values SI.

Measurement (forward) model, exact and closed-form, used by the simulator::

    N_g = M_g (w + G f) + eps                                   # N25 eq. 1 + S16 eq. 1 g-sensitivity
    N_a = M_a (f + a_size + K2 f^(2) + Kx f^(x)) + nabla          # N25 eq. 2 + S16 eq. 4-6, 9-12
    M   = (I + K)(I + E),  K = diag(scale factor errors), E = zero-diagonal installation angles

with ``f^(2) = [fx^2, fy^2, fz^2]``, ``f^(x) = [fx fy, fx fz, fy fz]``,
``Kx = [[Kxy, Kxz, 0], [Kyx, 0, Kyz], [0, Kzx, Kzy]]`` (S16 eq. 12 row layout) and
the size effect of accelerometer i at position ``p_i`` (row i of ``lever_arm``)::

    a_size_i = e_i . (w x (w x p_i) + dw/dt x p_i)             # S16 eq. 9-11, plus w-dot terms

With ``p_i = r_i e_i`` (S16) the centripetal part is ``-(|w|^2 - w_i^2) r_i``.

Compensation model (S16 eq. 3, 6, 7-8; eq. 8 as printed subtracts the
correction again at every step, the model's intended form is the fixed point
``f_n = f_0 - K2 f_{n-1}^(2) - Kx f_{n-1}^(x)``),
used on data::

    f~ = M_a^-1 (N_a - nabla) - K2 f~^(2) - Kx f~^(x) - a_size(w~)     (iterated)
    w~ = M_g^-1 (N_g - eps) - G f~

Compensating the forward model's output with the same parameters returns the true
inputs to round-off (tests/core/test_error_model.py).

Gyro-accelerometer time asynchrony ``tau = time_asynchrony`` [s]: the accelerometer
triad has its own time base, lagging the gyros by ``tau`` (``tau < 0``: it leads).  The
velocity increment of sample k (gyro interval ``[t_{k-1}, t_k]``) is the accelerometer
output integrated over ``[t_{k-1} - tau, t_k - tau]``; every accelerometer term (scale,
misalignment, bias, nonlinearity, cross-coupling, size effect) acts on the delayed
specific force and rates, while the gyro g-sensitivity acts on the specific force at the
gyro time.  The simulator integrates the delayed window exactly; the compensation
removes it to first order in ``tau`` (:meth:`ImuErrors.compensate`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import rq

from inscal.core import units

MISALIGN_INDEX = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
MISALIGN_NAMES = ("xy", "xz", "yx", "yz", "zx", "zy")
CROSS_NAMES = ("xy", "xz", "yx", "yz", "zx", "zy")


def _arr(x, shape, name) -> np.ndarray:
    a = np.array(x, dtype=float)
    if a.shape == () and shape != ():
        a = np.full(shape, float(a))
    if a.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    a.setflags(write=False)
    return a


def off_diagonal(angles) -> np.ndarray:
    """Zero-diagonal installation matrix E from 6 angles [xy, xz, yx, yz, zx, zy] (N25 eq. 3-4)."""
    e = np.zeros((3, 3))
    for k, (i, j) in enumerate(MISALIGN_INDEX):
        e[i, j] = angles[k]
    return e


def off_diagonal_angles(e) -> np.ndarray:
    """The 6 angles ``[xy, xz, yx, yz, zx, zy]`` of a zero-diagonal installation matrix E: the inverse of :func:`off_diagonal`."""
    return np.array([e[i, j] for i, j in MISALIGN_INDEX])


def cross_matrix(kx) -> np.ndarray:
    """S16 eq. 12 cross-coupling matrix acting on f^(x) = [fx fy, fx fz, fy fz]."""
    return np.array([[kx[0], kx[1], 0.0], [kx[2], 0.0, kx[3]], [0.0, kx[4], kx[5]]])


def quad_terms(f):
    """(f^(2), f^(x)) for f of shape (..., 3)."""
    f = np.asarray(f)
    sq = f * f
    cr = np.stack([f[..., 0] * f[..., 1], f[..., 0] * f[..., 2], f[..., 1] * f[..., 2]], axis=-1)
    return sq, cr


def rows_times(m, x) -> np.ndarray:
    """``x @ m.T`` for x of shape (..., 3), each component summed left to right
    (``(m[i,0] x_0 + m[i,1] x_1) + m[i,2] x_2``) elementwise, so the result does not depend on the
    BLAS library and equals a scalar loop doing the same products."""
    x = np.asarray(x, dtype=float)
    return np.stack([m[i, 0] * x[..., 0] + m[i, 1] * x[..., 1] + m[i, 2] * x[..., 2] for i in range(3)], axis=-1)


def size_effect(lever_arm, w, wdot=None):
    """Size-effect specific force a_size (..., 3) for rates ``w`` (..., 3) (S16 eq. 9-11).

    ``a_size_i = e_i . (w x (w x p_i) + wdot x p_i)``, ``p_i = lever_arm[i]``.
    """
    w = np.asarray(w, dtype=float)
    p = np.asarray(lever_arm, dtype=float)
    w2 = np.sum(w * w, axis=-1, keepdims=True)
    # (w x (w x p_i))_i = w_i (w . p_i) - p_ii |w|^2
    wp = w @ p.T  # (..., i) = w . p_i
    out = w * wp - np.diag(p) * w2
    if wdot is not None:
        wd = np.asarray(wdot, dtype=float)
        # (wdot x p_i)_i = wdot_j p_ik - wdot_k p_ij for (i, j, k) cyclic
        out = out + np.stack(
            [
                wd[..., 1] * p[0, 2] - wd[..., 2] * p[0, 1],
                wd[..., 2] * p[1, 0] - wd[..., 0] * p[1, 2],
                wd[..., 0] * p[2, 1] - wd[..., 1] * p[2, 0],
            ],
            axis=-1,
        )
    return out


@dataclass(frozen=True)
class ImuErrors:
    """Deterministic IMU errors in the canonical (s-frame, measurement) form, SI units.

    The measurement model (N25 eq. 1-4; S16 eq. 1, 4-6, 9-12): ``measure`` maps true rates and specific force
    to the sensor outputs, ``compensate`` inverts it (S16 form).  Every field defaults to zero.

    Parameters
    ----------
    gyro_scale_factor : array_like
        K_g, the diagonal of (I + K_g) [-], (3,).
    gyro_misalignment : array_like
        E_g off-diagonals ``[xy, xz, yx, yz, zx, zy]`` [rad], (6,).
    gyro_bias : array_like
        epsilon [rad/s], (3,).
    gyro_g_sensitivity : array_like
        G [(rad/s)/(m/s^2)], (3, 3).
    accel_scale_factor : array_like
        K_a, the diagonal of (I + K_a) [-], (3,).
    accel_misalignment : array_like
        E_a off-diagonals [rad], (6,).
    accel_bias : array_like
        nabla [m/s^2], (3,).
    accel_nonlinearity : array_like
        K_a2 diagonal [1/(m/s^2)], (3,).
    accel_cross_coupling : array_like
        ``[xy, xz, yx, yz, zx, zy]`` [1/(m/s^2)], (6,).
    accel_lever_arm : array_like
        Row i = the position of accelerometer i [m], (3, 3) (S16 size effect).
    time_asynchrony : float
        tau [s]: the accelerometer samples lag the gyro samples by tau.

    Raises
    ------
    ValueError
        A field of the wrong shape, or values that are not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.error_model import ImuErrors
    >>> from inscal.core.units import DEG, HOUR
    >>> imu = ImuErrors(gyro_bias=np.array([0.01, 0.0, 0.0]) * DEG / HOUR, accel_scale_factor=np.full(3, 1e-4))
    >>> ng, na = imu.measure(np.zeros((1, 3)), np.array([[0.0, 0.0, 9.8]]))
    >>> round(float(ng[0, 0]) / (DEG / HOUR), 6), round(float(na[0, 2]), 5)
    (0.01, 9.80098)
    >>> w, f = imu.compensate(ng, na)
    >>> bool(np.allclose(f, [[0.0, 0.0, 9.8]]))
    True
    """

    gyro_scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))  # K_g diag [-]
    gyro_misalignment: np.ndarray = field(default_factory=lambda: np.zeros(6))  # E_g [rad]
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))  # eps [rad/s]
    gyro_g_sensitivity: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # G [(rad/s)/(m/s^2)]
    accel_scale_factor: np.ndarray = field(default_factory=lambda: np.zeros(3))  # K_a diag [-]
    accel_misalignment: np.ndarray = field(default_factory=lambda: np.zeros(6))  # E_a [rad]
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))  # nabla [m/s^2]
    accel_nonlinearity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # K2 diag [1/(m/s^2)]
    accel_cross_coupling: np.ndarray = field(default_factory=lambda: np.zeros(6))  # Kx [1/(m/s^2)]
    accel_lever_arm: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # rows p_i [m]
    time_asynchrony: float = 0.0  # tau [s]: accelerometer samples lag the gyro samples by tau

    def __post_init__(self):
        tau = self.time_asynchrony
        try:
            tau = float(np.asarray(tau, dtype=float).reshape(()))
        except (TypeError, ValueError):
            raise ValueError(f"time_asynchrony: expected a scalar number of seconds, got {self.time_asynchrony!r}") from None
        if not math.isfinite(tau):
            raise ValueError("time_asynchrony: must be finite")
        object.__setattr__(self, "time_asynchrony", tau)
        for f in dataclasses.fields(self):
            if f.name == "time_asynchrony":
                continue
            shape = (3, 3) if f.name in ("gyro_g_sensitivity", "accel_lever_arm") else (
                (6,) if f.name in ("gyro_misalignment", "accel_misalignment", "accel_cross_coupling") else (3,)
            )
            val = getattr(self, f.name)
            if f.name == "accel_lever_arm" and np.shape(val) == (3,):
                val = np.diag(np.asarray(val, dtype=float))  # S16: each lever arm along its own axis
            object.__setattr__(self, f.name, _arr(val, shape, f.name))

    def replace(self, **kw) -> "ImuErrors":
        """A copy with the fields given in ``kw`` replaced (:func:`dataclasses.replace`)."""
        return dataclasses.replace(self, **kw)

    # -- matrices
    @property
    def M_g(self) -> np.ndarray:
        """(I + K_g)(I + E_g) (N25 eq. 1)."""
        return (np.eye(3) + np.diag(self.gyro_scale_factor)) @ (np.eye(3) + off_diagonal(self.gyro_misalignment))

    @property
    def M_a(self) -> np.ndarray:
        """(I + K_a)(I + E_a) (N25 eq. 2)."""
        return (np.eye(3) + np.diag(self.accel_scale_factor)) @ (np.eye(3) + off_diagonal(self.accel_misalignment))

    @property
    def K_cross(self) -> np.ndarray:
        """The 3x3 cross-coupling matrix ``Kx`` of the S16 eq. 12 row layout, from ``accel_cross_coupling``."""
        return cross_matrix(self.accel_cross_coupling)

    @property
    def has_nonlinear(self) -> bool:
        """Whether any accelerometer nonlinearity, cross-coupling or lever arm is non-zero."""
        return bool(np.any(self.accel_nonlinearity) or np.any(self.accel_cross_coupling) or np.any(self.accel_lever_arm))

    @property
    def has_asynchrony(self) -> bool:
        """True when the accelerometers are not synchronous with the gyros (``time_asynchrony != 0``)."""
        return self.time_asynchrony != 0.0

    # -- forward model on rates (true -> measured)
    def measure(self, w, f, wdot=None, f_gyro=None):
        """Exact measured rates (N_g, N_a) for true w, f (..., 3) in the s-frame.

        With a time asynchrony the accelerometer inputs ``f`` and ``w``, ``wdot`` of its
        size effect are those at the accelerometer time ``t - tau`` (the caller evaluates
        them there; the gyro output then uses ``w`` at ``t``: call twice or use the
        increment form); ``f_gyro`` is the specific force at the gyro time for the
        g-sensitivity term (default ``f``).
        """
        w = np.asarray(w, dtype=float)
        f = np.asarray(f, dtype=float)
        fg = f if f_gyro is None else np.asarray(f_gyro, dtype=float)
        sq, cr = quad_terms(f)
        ng = (w + fg @ self.gyro_g_sensitivity.T) @ self.M_g.T + self.gyro_bias
        fa = f + size_effect(self.accel_lever_arm, w, wdot) + sq * self.accel_nonlinearity + cr @ self.K_cross.T
        na = fa @ self.M_a.T + self.accel_bias
        return ng, na

    def measure_increments(self, dt, dth, dv, f2=None, fx=None, wwT=None, dw=None, dv_gyro=None):
        """Measured increments from the exact integrals of one sample interval each.

        ``dth = int w``, ``dv = int f``; for the nonlinear terms ``f2 = int f^(2)``,
        ``fx = int f^(x)``, ``wwT = int [wx^2, wy^2, wz^2, wx wy, wx wz, wy wz]``,
        ``dw = w(t_k) - w(t_{k-1})`` (the integral of w-dot).  Everything is linear in
        these integrals, so the result is exact whatever the motion inside the interval.

        With a time asynchrony ``tau``, ``dv, f2, fx, wwT, dw`` are the integrals over the
        accelerometer window ``[t_{k-1} - tau, t_k - tau]`` and ``dv_gyro`` is ``int f``
        over the gyro window ``[t_{k-1}, t_k]`` (for the g-sensitivity; default ``dv``).
        """
        dth = np.asarray(dth, dtype=float)
        dv = np.asarray(dv, dtype=float)
        dvg = dv if dv_gyro is None else np.asarray(dv_gyro, dtype=float)
        dt = np.asarray(dt, dtype=float)[..., None] if np.ndim(dt) else dt
        # Every product is written out element by element in one fixed order (no BLAS), the order of
        # the simulator's compiled pass (inscal.sim.kernel.simulate_pass): both give the same bits.
        # A term whose parameters are all zero is skipped (adding it would add exact zeros).
        G = self.gyro_g_sensitivity
        ng = rows_times(self.M_g, dth + rows_times(G, dvg) if np.any(G) else dth) + self.gyro_bias * dt
        fa = dv
        if np.any(self.accel_nonlinearity) or np.any(self.accel_cross_coupling):
            fa = fa + f2 * self.accel_nonlinearity + rows_times(self.K_cross, fx)
        if np.any(self.accel_lever_arm):
            p = self.accel_lever_arm
            # int (w_i (w . p_i) - p_ii |w|^2) dt expressed with the integrated products (S16 eq. 9-11)
            wx2, wy2, wz2, wxy, wxz, wyz = (wwT[..., k] for k in range(6))
            w2 = wx2 + wy2 + wz2
            cen = np.stack(
                [
                    wx2 * p[0, 0] + wxy * p[0, 1] + wxz * p[0, 2] - p[0, 0] * w2,
                    wxy * p[1, 0] + wy2 * p[1, 1] + wyz * p[1, 2] - p[1, 1] * w2,
                    wxz * p[2, 0] + wyz * p[2, 1] + wz2 * p[2, 2] - p[2, 2] * w2,
                ],
                axis=-1,
            )
            # int (w-dot x p_i)_i dt = (delta w x p_i)_i: size_effect(p, 0, dw)
            dw = np.asarray(dw, dtype=float)
            rot = np.stack(
                [
                    dw[..., 1] * p[0, 2] - dw[..., 2] * p[0, 1],
                    dw[..., 2] * p[1, 0] - dw[..., 0] * p[1, 2],
                    dw[..., 0] * p[2, 1] - dw[..., 1] * p[2, 0],
                ],
                axis=-1,
            )
            fa = fa + cen + rot
        na = rows_times(self.M_a, fa) + self.accel_bias * dt
        return ng, na

    # -- compensation model (S16 form) on rates (measured -> true)
    def compensate(self, ng, na, wdot=None, tol=1e-15, max_iter=20, dt=None):
        """Compensated (w~, f~) from measured rates, by the S16 fixed-point iteration.

        With ``dt`` (the sample interval [s]) and rows of ``ng``, ``na`` (N, 3) that are
        consecutive samples, two sample-to-sample terms are taken from the data, exactly as the
        systematic calibration's kernel does (:mod:`inscal.calibrate.systematic`):

        * time asynchrony ``tau`` (accelerometer increments over ``[t_k-1 - tau, t_k - tau]``): the
          linearly compensated mean force ``fb`` is moved to the gyro time base by a quadratic
          interpolation of its integral, ``fb_k += tau (fb_k+1 - fb_k-1) / (2 dt) + tau^2 (fb_k+1 -
          2 fb_k + fb_k-1) / (2 dt^2)`` (error of order tau dt^2 times the third derivative of f;
          the first and last rows use themselves as the missing neighbour);
        * the size effect's w-dot, when ``wdot`` is None: the centred difference of the linearly
          compensated rates ``(wb_k+1 - wb_k-1) / (2 dt)``.
        """
        ng = np.asarray(ng, dtype=float)
        na = np.asarray(na, dtype=float)
        w0 = (ng - self.gyro_bias) @ np.linalg.inv(self.M_g).T  # S16 eq. 3
        f0 = (na - self.accel_bias) @ np.linalg.inv(self.M_a).T  # S16 eq. 6 / eq. 7
        if dt is not None and f0.ndim == 2 and f0.shape[0] > 1:
            dtc = np.asarray(dt, dtype=float)
            dtc = dtc[:, None] if dtc.ndim else dtc

            def nb(x):
                return np.vstack([x[:1], x[:-1]]), np.vstack([x[1:], x[-1:]])

            if self.has_asynchrony:
                fm, fp = nb(f0)
                tau = self.time_asynchrony
                f0 = f0 + tau * (fp - fm) / (2 * dtc) + tau * tau * (fp - 2 * f0 + fm) / (2 * dtc * dtc)
            if wdot is None and np.any(self.accel_lever_arm):
                wm, wp = nb(w0)
                wdot = (wp - wm) / (2 * dtc)
        w, f = w0 - f0 @ self.gyro_g_sensitivity.T, f0
        if self.has_nonlinear or np.any(self.gyro_g_sensitivity):
            scale = max(1.0, float(np.max(np.abs(f0)))) if f0.size else 1.0
            for _ in range(max_iter):  # S16 eq. 8 as the fixed point f_n = f_0 - K2 f_{n-1}^(2) - ...
                sq, cr = quad_terms(f)
                f_new = f0 - sq * self.accel_nonlinearity - cr @ self.K_cross.T - size_effect(self.accel_lever_arm, w, wdot)
                w = w0 - f_new @ self.gyro_g_sensitivity.T
                done = np.max(np.abs(f_new - f)) <= tol * scale if f.size else True
                f = f_new
                if done:
                    break
        return w, f

    def compensate_increments(self, dt, dth, dv, prev=None, next=None):
        """Compensate increments (rates = increments/dt, the S16 practice on sampled data), with
        the sample-to-sample terms of :meth:`compensate` (time asynchrony, size-effect w-dot).

        ``prev = (dth, dv)`` / ``next = (dth, dv)``: the raw measured increments of the samples
        just before ``dth[0]`` and just after ``dth[-1]``, so that data compensated in chunks gives
        the same result as in one piece.
        """
        dt = np.asarray(dt, dtype=float)
        dth = np.asarray(dth, dtype=float)
        dv = np.asarray(dv, dtype=float)
        seq = dv.ndim == 2 and (self.has_asynchrony or bool(np.any(self.accel_lever_arm)))
        lead = seq and prev is not None
        tail = seq and next is not None
        row = lambda x: np.reshape(np.asarray(x, dtype=float), (1, 3))  # noqa: E731
        if lead:
            dth, dv = np.vstack([row(prev[0]), dth]), np.vstack([row(prev[1]), dv])
        if tail:
            dth, dv = np.vstack([dth, row(next[0])]), np.vstack([dv, row(next[1])])
        if dt.ndim:
            dt = np.concatenate([dt[:1]] * lead + [dt] + [dt[-1:]] * tail)
        dtc = dt[..., None] if dt.ndim else dt
        w, f = self.compensate(dth / dtc, dv / dtc, dt=dt if seq else None)
        w, f = w * dtc, f * dtc
        if w.ndim == 2:
            n = w.shape[0]
            sl = slice(1 if lead else 0, n - 1 if tail else n)
            w, f = w[sl], f[sl]
        return w, f


@dataclass(frozen=True)
class GimbalErrors:
    """Dual-axis gimbal/turntable errors (N25 section 2.3)."""

    nonorthogonality: float = 0.0  # d theta [rad] (N25 eq. 5)
    mount_attitude: np.ndarray = field(default_factory=lambda: np.zeros(3))  # [alpha0, beta0, gamma0] [rad] (eq. 8)

    def __post_init__(self):
        if not np.isfinite(self.nonorthogonality):
            raise ValueError("nonorthogonality must be finite")
        object.__setattr__(self, "nonorthogonality", float(self.nonorthogonality))
        object.__setattr__(self, "mount_attitude", _arr(self.mount_attitude, (3,), "mount_attitude"))


@dataclass(frozen=True)
class ImuNoise:
    """Stochastic IMU errors (SI): white noise, bias instability, quantization, encoder noise.

    Parameters
    ----------
    arw : float or array_like
        Angle random walk [rad/sqrt(s)] (a scalar or per axis).
    vrw : float or array_like
        Velocity random walk [m/s/sqrt(s)].
    gyro_bias_instability : float or array_like
        The sigma of a first-order Gauss-Markov gyro bias [rad/s].
    gyro_bias_tau : float
        Its correlation time [s].
    accel_bias_instability : float or array_like
        The same for the accelerometers [m/s^2].
    accel_bias_tau : float
        Its correlation time [s].
    gyro_quantization : float
        The angle quantum [rad].
    accel_quantization : float
        The velocity quantum [m/s].
    encoder_noise : float
        White noise on the recorded gimbal angles [rad].

    Raises
    ------
    ValueError
        A negative or non-finite value, or a correlation time that is not positive.

    Examples
    --------
    >>> from inscal.core.error_model import ImuNoise
    >>> from inscal.core.units import DEG
    >>> noise = ImuNoise(arw=0.005 * DEG / 60.0)  # 0.005 deg/sqrt(h)
    >>> noise.arw.shape, noise.is_zero, ImuNoise().is_zero
    ((3,), False, True)
    """

    arw: Any = 0.0  # angle random walk [rad/sqrt(s)]
    vrw: Any = 0.0  # velocity random walk [m/s/sqrt(s)]
    gyro_bias_instability: Any = 0.0  # first-order Gauss-Markov sigma [rad/s]
    gyro_bias_tau: float = 3600.0  # its correlation time [s]
    accel_bias_instability: Any = 0.0  # [m/s^2]
    accel_bias_tau: float = 3600.0  # [s]
    gyro_quantization: float = 0.0  # angle quantum [rad]
    accel_quantization: float = 0.0  # velocity quantum [m/s]
    encoder_noise: float = 0.0  # white noise on recorded gimbal angles [rad]

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name in ("arw", "vrw", "gyro_bias_instability", "accel_bias_instability"):
                a = _arr(v, (3,), f.name)
                if np.any(a < 0):
                    raise ValueError(f"{f.name} must be >= 0")
                object.__setattr__(self, f.name, a)
            else:
                if not np.isfinite(v) or v < 0 or (f.name.endswith("tau") and v <= 0):
                    raise ValueError(f"{f.name} must be a finite {'positive' if 'tau' in f.name else 'non-negative'} number")
                object.__setattr__(self, f.name, float(v))

    @property
    def is_zero(self) -> bool:
        """Whether every noise term (white noise, bias instability, quantization, encoder noise) is zero."""
        return not any(np.any(getattr(self, n)) for n in (
            "arw", "vrw", "gyro_bias_instability", "accel_bias_instability",
            "gyro_quantization", "accel_quantization", "encoder_noise"))


# ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ParameterDef:
    """One parameter of the error model: its value is the attribute ``attribute`` of the ``group``'s errors
    (``"imu"``: :class:`ImuErrors`, ``"gimbal"``: :class:`GimbalErrors`), of unit kind ``kind``
    (:mod:`inscal.core.units`), written in the field unit ``unit`` (files, reports, the command line) and of
    shape ``shape`` (``()``: a scalar).  It unpacks as the tuple ``(group, attribute, kind, unit, shape)``."""

    group: str
    attribute: str
    kind: str
    unit: str
    shape: tuple

    @property
    def size(self) -> int:
        """The number of scalar components (1 for a scalar)."""
        return int(np.prod(self.shape)) if self.shape else 1

    def __iter__(self):
        return iter((self.group, self.attribute, self.kind, self.unit, self.shape))

    def __getitem__(self, index):
        return tuple(self)[index]


#: Parameter registry: name -> its :class:`ParameterDef` (group, attribute, unit kind, field unit, shape).
#: The field units are what files, reports and the CLI use; conversion is in units.py.
PARAMETERS: dict[str, ParameterDef] = {name: ParameterDef(*spec) for name, spec in {
    "gyro_scale_factor": ("imu", "gyro_scale_factor", "dimensionless", "ppm", (3,)),
    "gyro_misalignment": ("imu", "gyro_misalignment", "angle", "arcsec", (6,)),
    "gyro_bias": ("imu", "gyro_bias", "rate", "deg/h", (3,)),
    "gyro_g_sensitivity": ("imu", "gyro_g_sensitivity", "g-sensitivity", "deg/h/g", (3, 3)),
    "accel_scale_factor": ("imu", "accel_scale_factor", "dimensionless", "ppm", (3,)),
    "accel_misalignment": ("imu", "accel_misalignment", "angle", "arcsec", (6,)),
    "accel_bias": ("imu", "accel_bias", "accel", "ug", (3,)),
    "accel_nonlinearity": ("imu", "accel_nonlinearity", "nonlinearity", "ug/g^2", (3,)),
    "accel_cross_coupling": ("imu", "accel_cross_coupling", "nonlinearity", "ug/g^2", (6,)),
    "accel_lever_arm": ("imu", "accel_lever_arm", "length", "cm", (3, 3)),
    "time_asynchrony": ("imu", "time_asynchrony", "time", "ms", ()),
    "gimbal_nonorthogonality": ("gimbal", "nonorthogonality", "angle", "arcsec", ()),
    "mount_attitude": ("gimbal", "mount_attitude", "angle", "arcsec", (3,)),
}.items()}

#: the noise parameters of a ``[noise]`` table: name -> (attribute, unit kind, field unit)
NOISE_FIELDS: dict[str, tuple[str, str, str]] = {
    # name -> (attribute, kind, field unit)
    "arw": ("arw", "arw", "deg/sqrt(h)"),
    "vrw": ("vrw", "vrw", "ug/sqrt(Hz)"),
    "gyro_bias_instability": ("gyro_bias_instability", "rate", "deg/h"),
    "gyro_bias_tau": ("gyro_bias_tau", "time", "s"),
    "accel_bias_instability": ("accel_bias_instability", "accel", "ug"),
    "accel_bias_tau": ("accel_bias_tau", "time", "s"),
    "gyro_quantization": ("gyro_quantization", "angle", "arcsec"),
    "accel_quantization": ("accel_quantization", "velocity", "mm/s"),
    "encoder_noise": ("encoder_noise", "angle", "arcsec"),
}


def _parse_entry(name: str, entry, kind: str, default_unit: str):
    """``entry`` is a bare value (in the field unit) or ``{value = ..., unit = "..."}``."""
    if isinstance(entry, dict):
        unknown = set(entry) - {"value", "unit", "sigma", "error"}
        if unknown:
            raise ValueError(f"{name}: unknown keys {sorted(unknown)}")
        if "value" not in entry:
            raise ValueError(f"{name}: missing 'value'")
        unit = entry.get("unit", default_unit)
        value = entry["value"]
    else:
        unit, value = default_unit, entry
    try:
        return units.to_si(value, unit, kind)
    except units.UnitError as exc:
        raise ValueError(f"{name}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not a number or list of numbers ({exc})") from None


def errors_from_field(d: dict) -> tuple[ImuErrors, GimbalErrors]:
    """Build (ImuErrors, GimbalErrors) from a dict in field units (see PARAMETERS)."""
    unknown = set(d) - set(PARAMETERS)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)}; known: {', '.join(PARAMETERS)}")
    imu, gim = {}, {}
    for name, entry in d.items():
        p = PARAMETERS[name]
        val = _parse_entry(name, entry, p.kind, p.unit)
        if p.group == "imu":
            imu[p.attribute] = val
        else:
            gim[p.attribute] = val
    return ImuErrors(**imu), GimbalErrors(**gim)


def errors_to_field(imu: ImuErrors | None, gimbal: GimbalErrors | None = None) -> dict:
    """Inverse of :func:`errors_from_field`: ``{name: {"value": ..., "unit": ...}}``."""
    out = {}
    for name, p in PARAMETERS.items():
        src = imu if p.group == "imu" else gimbal
        if src is None:
            continue
        v = units.from_si(np.asarray(getattr(src, p.attribute), dtype=float), p.unit)
        out[name] = {"value": v.tolist(), "unit": p.unit}
    return out


def noise_from_field(d: dict) -> ImuNoise:
    """An :class:`ImuNoise` (SI) from a ``[noise]`` table in field units (names and units of
    :data:`NOISE_FIELDS`; a bare value is in the field unit, or ``{value = ..., unit = "..."}``).
    An unknown name is a ValueError.
    """
    unknown = set(d) - set(NOISE_FIELDS)
    if unknown:
        raise ValueError(f"unknown noise parameter(s) {sorted(unknown)}; known: {', '.join(NOISE_FIELDS)}")
    kw = {}
    for name, entry in d.items():
        attr, kind, unit = NOISE_FIELDS[name]
        kw[attr] = _parse_entry(name, entry, kind, unit)
    return ImuNoise(**kw)


# ----------------------------------------------------------------------------------
# S16 parameterisation (m-frame defined by the gyro input axes)
@dataclass(frozen=True)
class S16Parameters:
    """IMU parameters in the S16 compensation form (S16 eq. 3 and 6).

    ``w~^m = T_g K_g N_g - b_g - G f~^m``; ``f~^m = T_a K_a N_a - b_a - K_a2 f~^(2) - K_cross f~^(x) - a_size``.
    ``T_g = [[1,0,0],[-g_yz,1,0],[g_zy,-g_zx,1]]`` (3 angles ``gamma = [yz, zx, zy]``),
    ``T_a = [[1,a_xz,-a_xy],[-a_yz,1,a_yx],[a_zy,-a_zx,1]]`` (6 angles ``alpha = [xy, xz, yx, yz, zx, zy]``),
    K diagonal scale factors (output units -> SI, ~1).  Entries of T are used exactly
    (not only to first order), so the conversion is an identity on the linear part.
    """

    K_g: np.ndarray
    gamma: np.ndarray
    b_g: np.ndarray
    G: np.ndarray
    K_a: np.ndarray
    alpha: np.ndarray
    b_a: np.ndarray
    K_a2: np.ndarray
    K_cross: np.ndarray
    lever_arm: np.ndarray

    @property
    def T_g(self) -> np.ndarray:
        """S16's gyro misalignment matrix ``T_g`` (lower-triangular, the three angles ``gamma``)."""
        yz, zx, zy = self.gamma
        return np.array([[1.0, 0.0, 0.0], [-yz, 1.0, 0.0], [zy, -zx, 1.0]])

    @property
    def T_a(self) -> np.ndarray:
        """S16's accelerometer misalignment matrix ``T_a`` (the six angles ``alpha``)."""
        xy, xz, yx, yz, zx, zy = self.alpha
        return np.array([[1.0, xz, -xy], [-yz, 1.0, yx], [zy, -zx, 1.0]])


def to_s16(imu: ImuErrors) -> tuple[S16Parameters, np.ndarray]:
    """Canonical (s-frame) -> S16 (m-frame) parameters, and ``C_s^m`` (the rotation from the
    gimbal frame to the gyro-defined m-frame).

    ``C_s^m M_g^-1 = T_g K_g`` is lower triangular: an RQ decomposition of ``M_g^-1``
    (upper-triangular R' in the reversed order) gives the rotation exactly.
    """
    Mg_inv = np.linalg.inv(imu.M_g)
    # We need Mg_inv = C_m^s L with L lower triangular, i.e. a QL decomposition.
    # QL of A == reverse the rows/cols of the RQ of A reversed.  Use: A^T = L^T Q^T (RQ of A^T
    # gives upper-triangular R = L^T and orthogonal factor Q^T).
    R_, Q_ = rq(Mg_inv.T)  # Mg_inv.T = R_ Q_  ->  Mg_inv = Q_^T R_^T, R_^T lower triangular
    L = R_.T
    C_m_s = Q_.T
    # make the diagonal of L positive (sign ambiguity of the decomposition)
    S = np.diag(np.sign(np.diag(L)))
    L = S @ L
    C_m_s = C_m_s @ S
    if np.linalg.det(C_m_s) < 0:
        raise ValueError("gyro matrix has a reflection; cannot express in S16 form")
    C_s_m = C_m_s.T
    K_g = np.diag(L).copy()
    T_g = L @ np.diag(1.0 / K_g)
    gamma = np.array([-T_g[1, 0], -T_g[2, 1], T_g[2, 0]])
    b_g = C_s_m @ Mg_inv @ imu.gyro_bias
    G = C_s_m @ imu.gyro_g_sensitivity @ C_s_m.T
    Ca = C_s_m @ np.linalg.inv(imu.M_a)
    K_a = np.diag(Ca).copy()
    T_a = Ca @ np.diag(1.0 / K_a)
    alpha = np.array([-T_a[0, 2], T_a[0, 1], T_a[1, 2], -T_a[1, 0], -T_a[2, 1], T_a[2, 0]])
    b_a = C_s_m @ np.linalg.inv(imu.M_a) @ imu.accel_bias
    s16 = S16Parameters(
        K_g=K_g, gamma=gamma, b_g=b_g, G=G, K_a=K_a, alpha=alpha, b_a=b_a,
        # Nonlinear terms act on per-axis components; they are carried over unchanged
        # (exact to first order in the s->m rotation, error <= |K2| f^2 |angle|).
        K_a2=imu.accel_nonlinearity.copy(), K_cross=cross_matrix(imu.accel_cross_coupling),
        lever_arm=np.diag(imu.accel_lever_arm).copy(),
    )
    return s16, C_s_m


def from_s16(s16: S16Parameters, C_s_m: np.ndarray | None = None) -> ImuErrors:
    """S16 (m-frame) -> canonical (s-frame) parameters, given ``C_s^m`` (identity if None)."""
    C_s_m = np.eye(3) if C_s_m is None else np.asarray(C_s_m, dtype=float)
    C_m_s = C_s_m.T
    Mg = np.linalg.inv(C_m_s @ s16.T_g @ np.diag(s16.K_g))
    Ma = np.linalg.inv(C_m_s @ s16.T_a @ np.diag(s16.K_a))
    kg, eg = split_scale_misalignment(Mg)
    ka, ea = split_scale_misalignment(Ma)
    kc = s16.K_cross
    return ImuErrors(
        gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=Mg @ C_m_s @ s16.b_g,
        gyro_g_sensitivity=C_m_s @ s16.G @ C_s_m,
        accel_scale_factor=ka, accel_misalignment=ea, accel_bias=Ma @ C_m_s @ s16.b_a,
        accel_nonlinearity=s16.K_a2,
        accel_cross_coupling=[kc[0, 0], kc[0, 1], kc[1, 0], kc[1, 2], kc[2, 1], kc[2, 2]],
        accel_lever_arm=np.diag(s16.lever_arm),
    )


def split_scale_misalignment(M) -> tuple[np.ndarray, np.ndarray]:
    """Exact split of ``M = (I + K)(I + E)`` into K (3) and the 6 angles of E."""
    M = np.asarray(M, dtype=float)
    k = np.diag(M) - 1.0
    E = np.diag(1.0 / (1.0 + k)) @ M - np.eye(3)
    return k, off_diagonal_angles(E)


# --------------------------------------------------------------------------- parameters
def parameter_components(name: str) -> list[str]:
    """Component labels of a registry parameter (``accel_bias`` -> x, y, z ...)."""
    shape = PARAMETERS[name].shape
    if shape == ():
        return [""]
    if name.endswith("misalignment"):
        return list(MISALIGN_NAMES)
    if name == "accel_cross_coupling":
        return list(CROSS_NAMES)
    if name == "mount_attitude":
        return ["alpha0", "beta0", "gamma0"]
    if shape == (3,):
        return ["x", "y", "z"]
    return [f"{a}{b}" for a in "xyz" for b in "xyz"]
