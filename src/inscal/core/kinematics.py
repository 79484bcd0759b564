"""Gimbal kinematics of a dual-axis turntable on a static base (N25 eq. 5-10): the gimbal angles of a
path segment, the true angular rate ``w_is^s`` and specific force ``f^s`` of the IMU, and its attitude.
One compiled kernel for the simulator and the Cramer-Rao bound."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.core.attitude import axis_angle_xyz, dcm_from_euler
from inscal.core.turntable import C_s_b, outer_axis


# ----------------------------------------------------------------------------- kernel
@njit(cache=True, inline="always")
def gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc):
    """Gimbal angles and rates ``(theta_x, theta_z, w_x, w_z)`` at time t on segment s (angles
    quadratic in time within a segment)."""
    tau = t - seg_t0[s]
    thx = seg_th0[s, 0] + seg_w0[s, 0] * tau + 0.5 * seg_acc[s, 0] * tau * tau
    thz = seg_th0[s, 1] + seg_w0[s, 1] * tau + 0.5 * seg_acc[s, 1] * tau * tau
    return thx, thz, seg_w0[s, 0] + seg_acc[s, 0] * tau, seg_w0[s, 1] + seg_acc[s, 1] * tau


@njit(cache=True)
def rates_at(t, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_out, f_out):
    """Evaluate w_is^s and f^s at time t on segment s (writes into w_out, f_out; no allocation).

    ``C_s^n = C_b^n Rot(u, theta_x) R_z(theta_z)`` (N25 eq. 7-8); ``w_is^s`` per N25 eq. 9 with the
    outer rate about the tilted axis u, ``f^s = C_n^s [0, 0, g]`` (eq. 10, static base).
    """
    thx, thz, wx, wz = gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc)
    w0, w1, w2, f0, f1, f2 = rates_from_trig(math.cos(thx), math.sin(thx), math.cos(thz), math.sin(thz), wx, wz,
                                             u, Cbn, wie_n, g)
    w_out[0] = w0
    w_out[1] = w1
    w_out[2] = w2
    f_out[0] = f0
    f_out[1] = f1
    f_out[2] = f2


@njit(cache=True, inline="always")
def rates_from_trig(c, sn, cz, sz, wx, wz, u, Cbn, wie_n, g):
    """``(w_is^s, f^s)`` as a 6-tuple from the cosines and sines of the gimbal angles
    ``(c, sn) = (cos, sin) theta_x``, ``(cz, sz) = (cos, sin) theta_z`` and the gimbal rates: the
    arithmetic of :func:`rates_at`, for callers that reuse the trigonometry of an axis at rest."""
    # Rodrigues rotation about the unit outer axis u (exact N25 eq. 5)
    ux, uy, uz = u[0], u[1], u[2]
    x00, x01, x02, x10, x11, x12, x20, x21, x22 = axis_angle_xyz(c, sn, ux, uy, uz)
    # columns of C_s^n = Cbn Cx Rz : x_s = Cbn (cz Cx[:,0] + sz Cx[:,1]), y_s = Cbn (-sz Cx[:,0] + cz Cx[:,1]), z_s = Cbn Cx[:,2]
    ax0 = cz * x00 + sz * x01
    ax1 = cz * x10 + sz * x11
    ax2 = cz * x20 + sz * x21
    ay0 = -sz * x00 + cz * x01
    ay1 = -sz * x10 + cz * x11
    ay2 = -sz * x20 + cz * x21
    w0_ = 0.0
    w1_ = 0.0
    w2_ = 0.0
    f0_ = 0.0
    f1_ = 0.0
    f2_ = 0.0
    for k in range(3):
        xs = Cbn[k, 0] * ax0 + Cbn[k, 1] * ax1 + Cbn[k, 2] * ax2
        ys = Cbn[k, 0] * ay0 + Cbn[k, 1] * ay1 + Cbn[k, 2] * ay2
        zs = Cbn[k, 0] * x02 + Cbn[k, 1] * x12 + Cbn[k, 2] * x22
        w0_ += xs * wie_n[k]
        w1_ += ys * wie_n[k]
        w2_ += zs * wie_n[k]
        if k == 2:
            f0_ = xs * g
            f1_ = ys * g
            f2_ = zs * g
    # outer rate about u, expressed in s: Rz^T u wx (u is fixed in the inner-gimbal frame); inner rate wz e_z
    return (w0_ + (cz * ux + sz * uy) * wx, w1_ + (-sz * ux + cz * uy) * wx, w2_ + uz * wx + wz, f0_, f1_, f2_)


@njit(cache=True)
def segment_at(t, seg_t1):
    """Smallest s with ``seg_t1[s] > t`` (clamped to the last segment)."""
    lo = 0
    hi = seg_t1.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if seg_t1[mid] > t:
            hi = mid
        else:
            lo = mid + 1
    return lo


def true_rates(scenario, t) -> tuple[np.ndarray, np.ndarray]:
    """True ``w_is^s`` and ``f^s`` (N, 3) at times ``t`` (N25 eq. 9-10 on a static base)."""
    seg = scenario.path.segments()
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k = np.clip(np.searchsorted(seg.t1, t, side="left"), 0, len(seg.t0) - 1)
    u = outer_axis(scenario.gimbal.nonorthogonality)
    Cbn = dcm_from_euler(scenario.gimbal.mount_attitude)
    w = np.empty((t.size, 3))
    f = np.empty((t.size, 3))
    for i in range(t.size):
        rates_at(t[i], k[i], seg.t0, seg.th0, seg.w0, seg.acc, u, Cbn, scenario.site.earth_rate_n, scenario.site.gravity, w[i], f[i])
    return w, f


def true_attitude(scenario, t) -> np.ndarray:
    """True ``C_s^n`` (N, 3, 3) at times ``t``."""
    th, _, _ = scenario.path.segments().angles(np.atleast_1d(t))
    Cbn = dcm_from_euler(scenario.gimbal.mount_attitude)
    return Cbn @ C_s_b(th[:, 0], th[:, 1], scenario.gimbal.nonorthogonality)


# ----------------------------------------------------------------------------- kinematics
@njit(cache=True)
def kinematics(t, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, C, w, f):
    """``C_s^n`` (3 x 3), ``w_is^s`` and ``f^s`` at time ``t`` on segment ``s`` (static base, ideal
    IMU): ``C_s^n = C_b^n Rot(u, theta_x) R_z(theta_z)`` (N25 eq. 7-8, exact Rodrigues rotation),
    ``w_is^s = C_n^s w_ie^n + R_z^T u w_x + e_z w_z`` (N25 eq. 9), ``f^s = C_n^s [0, 0, g]`` (eq. 10);
    the formulas of :func:`inscal.core.kinematics.rates_at`."""
    thx, thz, wx, wz = gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc)
    c, sn = math.cos(thx), math.sin(thx)
    ux, uy, uz = u[0], u[1], u[2]
    R = np.empty((3, 3))
    (R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1],
     R[2, 2]) = axis_angle_xyz(c, sn, ux, uy, uz)
    cz, sz = math.cos(thz), math.sin(thz)
    for i in range(3):  # C_s^b = R Rz
        a0 = cz * R[i, 0] + sz * R[i, 1]
        a1 = -sz * R[i, 0] + cz * R[i, 1]
        R[i, 0] = a0
        R[i, 1] = a1
    for i in range(3):
        for j in range(3):
            C[i, j] = Cbn[i, 0] * R[0, j] + Cbn[i, 1] * R[1, j] + Cbn[i, 2] * R[2, j]
    for j in range(3):
        w[j] = C[0, j] * wie_n[0] + C[1, j] * wie_n[1] + C[2, j] * wie_n[2]
        f[j] = C[2, j] * g
    w[0] += (cz * ux + sz * uy) * wx
    w[1] += (-sz * ux + cz * uy) * wx
    w[2] += uz * wx + wz
