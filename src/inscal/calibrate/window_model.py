"""Exact forward model of the window means (static base, N25 eq. 9-12).

Static window at gimbal angles (theta_x, theta_z)::

    C_n^s = R_z(theta_z)^T Rot(u, theta_x)^T C_n^b,    u = [cos dth, 0, sin dth]   # N25 eq. 5-8
    mean N_g = M_g C_n^s w_ie^n + eps                                              # N25 eq. 11
    mean N_a = M_a C_n^s g^n_up + nabla,   g^n_up = [0, 0, g]                       # N25 eq. 12

Constant-rate window (one axis turning at rate w from angle a0 to a1): the mean of a
rotation ``Rot(k, a)^T = cos a I - sin a [k x] + (1 - cos a) k k^T`` over the window is
the same expression with ``cos a``, ``sin a`` replaced by their means
``(sin a1 - sin a0) / (a1 - a0)`` and ``(cos a0 - cos a1) / (a1 - a0)`` (exact for a
constant rate; both vanish over whole turns).  Inner axis: ``mean w^s = Rbar_z^T
Rot(u, theta_x)^T C_n^b w_ie + w e_z``; outer axis: ``mean w^s = R_z(theta_z)^T (Rbar_u^T
C_n^b w_ie + w u)`` (N25 eq. 9); the specific force likewise without the turntable rate.
"""

from __future__ import annotations

import math
import re

import numpy as np

from inscal.calibrate.result import GIMBAL, IMU_LINEAR
from inscal.calibrate.windows import CalibrationError, WindowSet
from inscal.core import units
from inscal.core.attitude import axis_angle_dcm, dcm_from_euler, rot_z, skew
from inscal.core.error_model import (
    MISALIGN_INDEX,
    MISALIGN_NAMES,
    GimbalErrors,
    ImuErrors,
    off_diagonal,
)
from inscal.core.turntable import outer_axis

E3 = np.array([0.0, 0.0, 1.0])


def mean_rot_T(k, a0: float, a1: float) -> np.ndarray:
    """Mean of ``Rot(k, a)^T`` for a linear in time from a0 to a1 (exact)."""
    d = a1 - a0
    if abs(d) < 1e-9:
        c, s = math.cos(0.5 * (a0 + a1)), math.sin(0.5 * (a0 + a1))
    else:
        c = (math.sin(a1) - math.sin(a0)) / d
        s = (math.cos(a0) - math.cos(a1)) / d
    k = np.asarray(k, float)
    return c * np.eye(3) - s * skew(k) + (1.0 - c) * np.outer(k, k)


def C_n_s(theta_x: float, theta_z: float, dth: float, mount) -> np.ndarray:
    """``C_n^s`` of a static position (N25 eq. 7-8, exact Rodrigues rotation)."""
    Cbn = dcm_from_euler(mount)
    return rot_z(theta_z).T @ axis_angle_dcm(outer_axis(dth), theta_x).T @ Cbn.T


def C_b_s(theta_x: float, theta_z: float, dth: float) -> np.ndarray:
    return rot_z(theta_z).T @ axis_angle_dcm(outer_axis(dth), theta_x).T


def window_inputs(ws: WindowSet, dth: float, mount, windows=None) -> tuple[np.ndarray, np.ndarray]:
    """True mean ``(w^s, f^s)`` (n, 3) of every window for gimbal errors (dth, mount)."""
    windows = ws.windows if windows is None else windows
    wie = ws.site.earth_rate_n
    gup = np.array([0.0, 0.0, ws.site.gravity])
    Cnb = dcm_from_euler(mount).T
    wb, gb = Cnb @ wie, Cnb @ gup
    u = outer_axis(dth)
    W = np.empty((len(windows), 3))
    F = np.empty((len(windows), 3))
    for k, w in enumerate(windows):
        if w.kind == "static":
            tx, tz = w.theta
            C = rot_z(tz).T @ axis_angle_dcm(u, tx).T
            W[k], F[k] = C @ wb, C @ gb
        elif w.axis == "inner":
            tx = 0.5 * (w.theta0[0] + w.theta1[0])
            R = mean_rot_T(E3, w.theta0[1], w.theta1[1])
            Cx = axis_angle_dcm(u, tx).T
            W[k] = R @ (Cx @ wb) + w.rate * E3
            F[k] = R @ (Cx @ gb)
        else:
            tz = 0.5 * (w.theta0[1] + w.theta1[1])
            R = mean_rot_T(u, w.theta0[0], w.theta1[0])
            Rz = rot_z(tz).T
            W[k] = Rz @ (R @ wb + w.rate * u)
            F[k] = Rz @ (R @ gb)
    return W, F


def predict(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, windows=None) -> tuple[np.ndarray, np.ndarray]:
    """Predicted mean outputs ``(N_g, N_a)`` (n, 3) of the windows (N25 eq. 1-2, 11-12)."""
    W, F = window_inputs(ws, gimbal.nonorthogonality, gimbal.mount_attitude, windows)
    return W @ imu.M_g.T + imu.gyro_bias, F @ imu.M_a.T + imu.accel_bias


def ideal_up(theta_x: float, theta_z: float) -> np.ndarray:
    """Unit up vector in the s-frame for a level, orthogonal turntable (the ideal input of
    the classical schemes, N25 eq. 17)."""
    return rot_z(theta_z).T @ axis_angle_dcm(np.array([1.0, 0.0, 0.0]), theta_x).T @ E3


NAMES = IMU_LINEAR + GIMBAL
#: (parameter name, component label) of each internal parameter
COMPONENTS = (
    [("gyro_scale_factor", a) for a in "xyz"] + [("gyro_misalignment", m) for m in MISALIGN_NAMES]
    + [("gyro_bias", a) for a in "xyz"] + [("accel_scale_factor", a) for a in "xyz"]
    + [("accel_misalignment", m) for m in MISALIGN_NAMES] + [("accel_bias", a) for a in "xyz"]
    + [("gimbal_nonorthogonality", "")] + [("mount_attitude", a) for a in ("alpha0", "beta0", "gamma0")]
)
NP = len(COMPONENTS)


def component_label(i: int) -> str:
    n, c = COMPONENTS[i]
    return f"{n}[{c}]" if c else n


def parse_component(key: str) -> list[int]:
    m = re.fullmatch(r"([a-z_]+)(?:\[([a-z0-9]+)\])?", key.strip())
    if not m or m.group(1) not in NAMES:
        raise CalibrationError(f"cannot fix {key!r}: expected NAME or NAME[component] with NAME in {', '.join(NAMES)}")
    idx = [i for i, (n, c) in enumerate(COMPONENTS) if n == m.group(1) and (m.group(2) is None or c == m.group(2))]
    if not idx:
        raise CalibrationError(f"cannot fix {key!r}: unknown component")
    return idx


class WindowModel:
    def __init__(self, ws: WindowSet):
        self.ws = ws
        self.Om = float(np.linalg.norm(ws.site.earth_rate_n))
        self.g = ws.site.gravity
        self.G = np.array([w.gyro for w in ws.windows])
        self.A = np.array([w.accel for w in ws.windows])
        self.sg = np.maximum(np.array([w.gyro_sigma for w in ws.windows]), GYRO_FLOOR)
        self.sa = np.maximum(np.array([w.accel_sigma for w in ws.windows]), ACCEL_FLOOR)
        # internal scaling: eps / w_ie, nabla / g; other parameters in rad or dimensionless
        self.scale = np.ones(NP)
        self.scale[9:12] = self.Om
        self.scale[21:24] = self.g

    def to_si(self, p):
        return p * self.scale

    def from_si(self, x):
        return x / self.scale

    @staticmethod
    def unpack(x):
        return x[0:3], x[3:9], x[9:12], x[12:15], x[15:21], x[21:24], x[24], x[25:28]

    def inputs(self, x):
        return window_inputs(self.ws, x[24], x[25:28])

    def residual(self, p):
        x = self.to_si(p)
        kg, eg, eps, ka, ea, nab, dth, mount = self.unpack(x)
        W, F = window_inputs(self.ws, dth, mount)
        Mg = (np.eye(3) + np.diag(kg)) @ (np.eye(3) + off_diagonal(eg))
        Ma = (np.eye(3) + np.diag(ka)) @ (np.eye(3) + off_diagonal(ea))
        rg = (W @ Mg.T + eps - self.G) / self.sg
        ra = (F @ Ma.T + nab - self.A) / self.sa
        return np.concatenate([rg.ravel(), ra.ravel()])

    def jacobian(self, p, h: float = 1e-6):
        x = self.to_si(p)
        kg, eg, eps, ka, ea, nab, dth, mount = self.unpack(x)
        n = len(self.ws.windows)
        W, F = window_inputs(self.ws, dth, mount)
        Eg, Ea = np.eye(3) + off_diagonal(eg), np.eye(3) + off_diagonal(ea)
        Mg, Ma = (np.eye(3) + np.diag(kg)) @ Eg, (np.eye(3) + np.diag(ka)) @ Ea
        Jg = np.zeros((n, 3, NP))
        Ja = np.zeros((n, 3, NP))
        for blk, (J, V, E, k, off_k, off_e, off_b) in enumerate(((Jg, W, Eg, kg, 0, 3, 9), (Ja, F, Ea, ka, 12, 15, 21))):
            EV = V @ E.T
            for i in range(3):
                J[:, i, off_k + i] = EV[:, i]  # d/dK_i
                J[:, i, off_b + i] = 1.0  # d/d bias_i
            for m, (i, j) in enumerate(MISALIGN_INDEX):
                J[:, i, off_e + m] = (1.0 + k[i]) * V[:, j]  # d/dE_ij
        for q in range(4):
            xp, xm = x.copy(), x.copy()
            xp[24 + q] += h
            xm[24 + q] -= h
            Wp, Fp = self.inputs(xp)
            Wm, Fm = self.inputs(xm)
            Jg[:, :, 24 + q] = (Wp - Wm) @ Mg.T / (2 * h)
            Ja[:, :, 24 + q] = (Fp - Fm) @ Ma.T / (2 * h)
        Jg /= self.sg[:, :, None]
        Ja /= self.sa[:, :, None]
        J = np.concatenate([Jg.reshape(3 * n, NP), Ja.reshape(3 * n, NP)])
        return J * self.scale[None, :]


GYRO_FLOOR = units.to_si(1e-6, "deg/h")


ACCEL_FLOOR = units.to_si(1e-6, "ug")
