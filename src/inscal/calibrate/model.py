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

import numpy as np

from ..attitude import axis_angle_dcm, dcm_from_euler
from ..errors import GimbalErrors, ImuErrors
from .segment import WindowSet

E3 = np.array([0.0, 0.0, 1.0])


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def mean_rot_T(k, a0: float, a1: float) -> np.ndarray:
    """Mean of ``Rot(k, a)^T`` for a linear in time from a0 to a1 (exact)."""
    d = a1 - a0
    if abs(d) < 1e-9:
        c, s = math.cos(0.5 * (a0 + a1)), math.sin(0.5 * (a0 + a1))
    else:
        c = (math.sin(a1) - math.sin(a0)) / d
        s = (math.cos(a0) - math.cos(a1)) / d
    k = np.asarray(k, float)
    return c * np.eye(3) - s * _skew(k) + (1.0 - c) * np.outer(k, k)


def outer_axis(dth: float) -> np.ndarray:
    return np.array([math.cos(dth), 0.0, math.sin(dth)])


def C_n_s(theta_x: float, theta_z: float, dth: float, mount) -> np.ndarray:
    """``C_n^s`` of a static position (N25 eq. 7-8, exact Rodrigues rotation)."""
    Cbn = dcm_from_euler(mount)
    return _rz(theta_z).T @ axis_angle_dcm(outer_axis(dth), theta_x).T @ Cbn.T


def C_b_s(theta_x: float, theta_z: float, dth: float) -> np.ndarray:
    return _rz(theta_z).T @ axis_angle_dcm(outer_axis(dth), theta_x).T


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
            C = _rz(tz).T @ axis_angle_dcm(u, tx).T
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
            Rz = _rz(tz).T
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
    return _rz(theta_z).T @ axis_angle_dcm(np.array([1.0, 0.0, 0.0]), theta_x).T @ E3
