"""Strapdown inertial navigation (mechanization) in the local ENU frame on WGS-84.

Navigation runs in the IMU frame s: the kernel integrates ``C_s^n`` (a scalar-first
quaternion), the ENU velocity ``v^n`` and the geodetic position (latitude, longitude,
height) from the angular and velocity increments ``dtheta = int w_is^s dt``,
``dvel = int f^s dt`` of each sample interval.  The vehicle (turntable base)
attitude is obtained afterwards through the gimbal angles (N25 section 3.2,
eq. 34-36): ``C_b^n = C_s^n (C_s^b)^T`` with ``C_s^b`` from the gimbal model, so a
gimbal non-orthogonality that the model ignores shows up as N25 eq. 35-37 describe.

Algorithm (Savage, *Strapdown Analytics* ch. 7; Titterton & Weston (T&W) ch. 11):

* Attitude: ``q(k) = q(-zeta_k) * q(k-1) * q(phi_k)`` with the two-sample
  (current + previous) coning correction ``phi_k = dth_k + dth_{k-1} x dth_k / 12``
  (Savage ch. 7 / T&W ch. 11) and the navigation-frame rotation
  ``zeta_k = (w_ie^n + w_en^n) dt`` (exact rotation vectors, Rodrigues quaternions).
* Velocity: ``v(k) = v(k-1) + (I - [zeta x]/2) C_s^n(k-1) dv_sf + (g^n - (2 w_ie + w_en) x v) dt``
  with ``dv_sf = dv_k + dth_k x dv_k / 2`` (rotation correction) ``+ (dth_{k-1} x dv_k +
  dv_{k-1} x dth_k) / 12`` (two-sample sculling) (Savage ch. 7 / T&W ch. 11).
* Position: trapezoidal integration of ``dL/dt = v_N/(R_M+h)``, ``dlambda/dt = v_E/((R_N+h) cos L)``.
* The attitude update's ``zeta_k`` uses the transport rate of the *midpoint* velocity
  ``(v(k-1) + v(k)) / 2`` (mode "damped": also the midpoint velocity difference in the extra
  level rate).  With the velocity update's half rotation ``(I - [zeta x]/2)`` taken with the
  old velocity this makes the discrete Schuler loop neutral (its transition matrix has
  determinant 1).  Measured against a DOP853 (rtol 1e-13) integration of the continuous
  equations (``tests/nav/test_strapdown_reference.py``: static, 100 ug East accelerometer bias,
  34 deg N, 5 days, peak position error 1278 m): Schuler amplitude +1.3e-6 at 100 Hz
  (+5.4e-6 at 25 Hz), position within 0.052 m at 100 Hz (0.21 m at 25 Hz).  The *new*
  velocity would damp the amplitude by exp(-t w_s^2 dt / 4) (-1.65e-3 in 5 days at 100 Hz,
  -6.6e-3 at 25 Hz; 1.05 m / 4.2 m off the reference) and, under acceleration, leave a level
  tilt of about ``dv dt / (2 R)`` after a velocity change dv (analytic); the *old* velocity grows the
  amplitude by the same factor (+1.66e-3 / +6.6e-3).  The remaining position difference is
  first order in dt (5.2 m Hz / rate): the Coriolis term with the old velocity and the
  start-of-interval latitude in ``w_ie^n`` of ``zeta_k`` (both at the midpoint: 1e-4 m at 25 Hz).

Vertical channel (stated, not free: a free inertial vertical channel diverges with
the time constant ``sqrt(R/2g)`` ~ 9.5 min): ``"hold"`` (default) keeps ``v_U = 0`` and
``h = h_ref``; ``"damped"`` is a third-order loop on ``h - h_ref`` with three poles at
``-1/tau`` (the standard third-order vertical-channel loop, with the reference height in place of
a barometer: gains k1 = 3/tau, k2 = 3/tau^2 + 2 w_s^2 (cancelling the 2 g/R gravity-gradient
instability), k3 = 1/tau^3).

Horizontal damping (mode ``"damped"``, the S16 sailing test): an external velocity
reference ``v_ref`` (zero on a static base) feeds the velocity difference back into
the velocity (gain k1) and into the level-axis rotation rate (gain k2, as an extra
transport rate), giving the damped Schuler loop ``s^2 + k1 s + (1 + k2) w_s^2``
(the classical velocity-damped Schuler loop); k1 = 2 xi w_n, k2 = (w_n/w_s)^2 - 1.

Compensation on the fly (S16 eq. 3, 6, 7-8; the same model as
:meth:`inscal.core.error_model.ImuErrors.compensate`): each sample's increments are compensated
before integration, ``w~ = M_g^-1 (N_g - eps) - G f~``,
``f~ = M_a^-1 (N_a - nabla) - K2 f~^(2) - Kx f~^(x) - a_size(w~, w~-dot)`` with rates =
increments / dt (the fixed point is iterated three times, converged to ~1e-12 of
the nonlinear correction).

Everything runs in one ``@njit`` kernel that allocates nothing per sample; chunks
of any size are processed with the state carried between calls, so long records
never need to be in memory more than once.  Output is decimated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from inscal.core import earth
from inscal.core.attitude import (
    dcm_from_quat,
    euler_from_dcm,
    quat_from_dcm,
    quat_from_rotvec,
    quat_from_rotvec_xyz,
    quat_mul,
)
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.core.kinematics import true_attitude
from inscal.core.turntable import vehicle_attitude_from_imu

# layout of the kernel's state vector ``st`` (float64)
S_Q = 0  # 0..3 quaternion C_s^n (scalar first)
S_V = 4  # 4..6 ENU velocity [m/s]
S_LAT, S_LON, S_H = 7, 8, 9
S_PDTH = 10  # 10..12 previous compensated dtheta
S_PDV = 13  # 13..15 previous compensated dvel
S_HAVE_PREV = 16
S_VACC = 17  # vertical loop integrator state [m/s^2]
S_HREF = 18  # reference height [m]
S_PW = 19  # 19..21 previous compensated rate (for the size-effect w-dot)
S_LATC, S_LONC = 22, 23  # Kahan compensation of the latitude/longitude sums
N_STATE = 24

# layout of the configuration vector ``cfg`` (float64)
C_VERT = 0  # 0 hold, 1 damped
C_VK1, C_VK2, C_VK3 = 1, 2, 3
C_HDAMP = 4  # 0 free, 1 damped
C_HK1, C_HK2 = 5, 6
C_CONING = 7  # 1 apply coning/sculling corrections
C_COMP = 8  # 0 none, 1 linear (M, bias, G), 2 full (plus nonlinear and size effect)
C_FIXPOS = 9  # 1: position clamped to the reference (alignment)
C_GSCALE = 10  # gravity model / WGS-84 normal gravity at the site (1.0: WGS-84)
N_CFG = 11

# rows of the compensation parameter block ``cp`` (float64, (14, 3))
P_MGI = 0  # rows 0..2: M_g^-1
P_MAI = 3  # rows 3..5: M_a^-1
P_G = 6  # rows 6..8: G
P_LEV = 9  # rows 9..11: lever arms p_i (row i)
P_EPS = 12  # gyro bias eps (measurement form) [rad/s]
P_NAB = 13  # accel bias nabla [m/s^2]
P_K2 = 14  # K2 diagonal [1/(m/s^2)]
P_KX1 = 15  # Kx rows 15..17
P_XEPS = 18  # extra gyro bias subtracted after compensation (alignment estimates) [rad/s]
P_XNAB = 19  # extra accel bias subtracted after compensation [m/s^2]
N_CP = 20


@njit(cache=True, inline="always")
def qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product, scalar-first, on scalars (no allocation)."""
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )




@njit(cache=True, inline="always")
def two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, with_prev):
    """Rotation vector and velocity increment of one sample with the rotation compensation
    (a x b / 2 + a x (a x b) / 6, the series of Savage's exact form to third order) and, from the
    previous increments (p, u), the two-sample coning and sculling corrections (Savage ch. 7):
    r = a + p x a / 12, c = b + a x b / 2 + a x (a x b) / 6 + (p x b + u x a) / 12.

    The third-order term matters on a turntable: without it a constant rotation w in gravity
    leaves g (w dt)^2 / 6 along the rotation plane (12 ug at 5 deg/s and 10 Hz)."""
    r0, r1, r2 = a0, a1, a2
    x0 = a1 * b2 - a2 * b1
    x1 = a2 * b0 - a0 * b2
    x2 = a0 * b1 - a1 * b0
    c0 = b0 + 0.5 * x0 + (a1 * x2 - a2 * x1) / 6.0
    c1 = b1 + 0.5 * x1 + (a2 * x0 - a0 * x2) / 6.0
    c2 = b2 + 0.5 * x2 + (a0 * x1 - a1 * x0) / 6.0
    if with_prev:
        r0 += (p1 * a2 - p2 * a1) / 12.0
        r1 += (p2 * a0 - p0 * a2) / 12.0
        r2 += (p0 * a1 - p1 * a0) / 12.0
        c0 += ((p1 * b2 - p2 * b1) + (u1 * a2 - u2 * a1)) / 12.0
        c1 += ((p2 * b0 - p0 * b2) + (u2 * a0 - u0 * a2)) / 12.0
        c2 += ((p0 * b1 - p1 * b0) + (u0 * a1 - u1 * a0)) / 12.0
    return r0, r1, r2, c0, c1, c2


@njit(cache=True, inline="always")
def qrot(q0, q1, q2, q3, x, y, z):
    """Rotate (x, y, z) by the quaternion: C(q) v."""
    # t = 2 q_v x v ; v' = v + q0 t + q_v x t
    tx = 2.0 * (q2 * z - q3 * y)
    ty = 2.0 * (q3 * x - q1 * z)
    tz = 2.0 * (q1 * y - q2 * x)
    return (
        x + q0 * tx + (q2 * tz - q3 * ty),
        y + q0 * ty + (q3 * tx - q1 * tz),
        z + q0 * tz + (q1 * ty - q2 * tx),
    )


@njit(cache=True, inline="always")
def attitude_step(q0, q1, q2, q3, r0, r1, r2, z0, z1, z2):
    """``q(-zeta) * q * q(r)``, normalised: the body rotation vector ``r`` of the sample and the
    navigation-frame rotation ``zeta = (w_ie^n + w_en^n) dt`` (exact rotation-vector quaternions)."""
    e0, e1, e2, e3 = quat_from_rotvec_xyz(r0, r1, r2)
    q0, q1, q2, q3 = qmul(q0, q1, q2, q3, e0, e1, e2, e3)
    e0, e1, e2, e3 = quat_from_rotvec_xyz(-z0, -z1, -z2)
    q0, q1, q2, q3 = qmul(e0, e1, e2, e3, q0, q1, q2, q3)
    qn = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return q0 * qn, q1 * qn, q2 * qn, q3 * qn


@njit(cache=True, inline="always")
def velocity_step(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu, lat, h, dt, gscale):
    """ENU velocity after one sample (T&W ch. 11): ``v + (I - [zeta x]/2) C dv_sf + (g - (2 w_ie + w_en) x v) dt``
    with the Earth quantities at the start of the interval (WGS-84, T&W ch. 3); ``C`` = the quaternion
    ``q`` (C_s^n), ``c`` = the sample's velocity increment with its rotation and sculling terms.
    Returns the new velocity and ``sin L, cos L, R_M + h, R_N + h, w_ie north, w_ie up``."""
    sl = math.sin(lat)
    cl = math.cos(lat)
    w = math.sqrt(1.0 - earth.E2 * sl * sl)
    rn = earth.A / w
    rm = rn * (1.0 - earth.E2) / (w * w)
    grav = earth.normal_gravity(lat, h) * gscale
    rmh = rm + h
    rnh = rn + h
    wie = earth.OMEGA_IE
    wie_n, wie_u = wie * cl, wie * sl
    # transport rate w_en^n = [-vN/(RM+h), vE/(RN+h), vE tanL/(RN+h)]
    we0 = -vn / rmh
    we1 = ve / rnh
    we2 = ve * sl / (cl * rnh)
    z0 = we0 * dt
    z1 = (wie_n + we1) * dt
    z2 = (wie_u + we2) * dt
    s0, s1, s2 = qrot(q0, q1, q2, q3, c0, c1, c2)
    s0 -= 0.5 * (z1 * s2 - z2 * s1)
    s1 -= 0.5 * (z2 * s0 - z0 * s2)
    s2 -= 0.5 * (z0 * s1 - z1 * s0)
    o0 = we0
    o1 = 2.0 * wie_n + we1
    o2 = 2.0 * wie_u + we2
    nve = ve + s0 - (o1 * vu - o2 * vn) * dt
    nvn = vn + s1 - (o2 * ve - o0 * vu) * dt
    nvu = vu + s2 - (o0 * vn - o1 * ve) * dt - grav * dt
    return nve, nvn, nvu, sl, cl, rmh, rnh, wie_n, wie_u


@njit(cache=True)
def _compensate(dth, dv, dt, cp, level, pw, have_prev, out):
    """S16 compensation of one sample's increments into ``out[0:3]`` (dtheta) and ``out[3:6]`` (dv)."""
    a0 = dth[0] - cp[P_EPS, 0] * dt
    a1 = dth[1] - cp[P_EPS, 1] * dt
    a2 = dth[2] - cp[P_EPS, 2] * dt
    t0 = cp[P_MGI, 0] * a0 + cp[P_MGI, 1] * a1 + cp[P_MGI, 2] * a2  # S16 eq. 3 (linear part)
    t1 = cp[P_MGI + 1, 0] * a0 + cp[P_MGI + 1, 1] * a1 + cp[P_MGI + 1, 2] * a2
    t2 = cp[P_MGI + 2, 0] * a0 + cp[P_MGI + 2, 1] * a1 + cp[P_MGI + 2, 2] * a2
    b0 = dv[0] - cp[P_NAB, 0] * dt
    b1 = dv[1] - cp[P_NAB, 1] * dt
    b2 = dv[2] - cp[P_NAB, 2] * dt
    f0 = cp[P_MAI, 0] * b0 + cp[P_MAI, 1] * b1 + cp[P_MAI, 2] * b2  # S16 eq. 6 / 7 (f_0)
    f1 = cp[P_MAI + 1, 0] * b0 + cp[P_MAI + 1, 1] * b1 + cp[P_MAI + 1, 2] * b2
    f2 = cp[P_MAI + 2, 0] * b0 + cp[P_MAI + 2, 1] * b1 + cp[P_MAI + 2, 2] * b2
    g0, g1, g2 = f0, f1, f2
    w0 = t0 - (cp[P_G, 0] * g0 + cp[P_G, 1] * g1 + cp[P_G, 2] * g2)
    w1 = t1 - (cp[P_G + 1, 0] * g0 + cp[P_G + 1, 1] * g1 + cp[P_G + 1, 2] * g2)
    w2 = t2 - (cp[P_G + 2, 0] * g0 + cp[P_G + 2, 1] * g1 + cp[P_G + 2, 2] * g2)
    if level >= 2:
        idt = 1.0 / dt
        for _ in range(3):  # S16 eq. 8 as a fixed point (see core.error_model)
            # rates
            x0, x1, x2 = g0 * idt, g1 * idt, g2 * idt
            r0, r1, r2 = w0 * idt, w1 * idt, w2 * idt
            # K2 f^(2) + Kx f^(x) (S16 eq. 12)
            s0 = x0 * x0
            s1 = x1 * x1
            s2 = x2 * x2
            c0 = x0 * x1
            c1 = x0 * x2
            c2 = x1 * x2
            n0 = cp[P_K2, 0] * s0 + cp[P_KX1, 0] * c0 + cp[P_KX1, 1] * c1 + cp[P_KX1, 2] * c2
            n1 = cp[P_K2, 1] * s1 + cp[P_KX1 + 1, 0] * c0 + cp[P_KX1 + 1, 1] * c1 + cp[P_KX1 + 1, 2] * c2
            n2 = cp[P_K2, 2] * s2 + cp[P_KX1 + 2, 0] * c0 + cp[P_KX1 + 2, 1] * c1 + cp[P_KX1 + 2, 2] * c2
            # size effect a_i = e_i.(w x (w x p_i) + wdot x p_i) (S16 eq. 9-11)
            wp0 = r0 * cp[P_LEV, 0] + r1 * cp[P_LEV, 1] + r2 * cp[P_LEV, 2]
            wp1 = r0 * cp[P_LEV + 1, 0] + r1 * cp[P_LEV + 1, 1] + r2 * cp[P_LEV + 1, 2]
            wp2 = r0 * cp[P_LEV + 2, 0] + r1 * cp[P_LEV + 2, 1] + r2 * cp[P_LEV + 2, 2]
            ww = r0 * r0 + r1 * r1 + r2 * r2
            z0 = r0 * wp0 - cp[P_LEV, 0] * ww
            z1 = r1 * wp1 - cp[P_LEV + 1, 1] * ww
            z2 = r2 * wp2 - cp[P_LEV + 2, 2] * ww
            if have_prev:
                # w-dot integrated over the interval ~ difference of consecutive mean rates
                d0, d1, d2 = r0 - pw[0], r1 - pw[1], r2 - pw[2]
                z0 += (d1 * cp[P_LEV, 2] - d2 * cp[P_LEV, 1]) * idt
                z1 += (d2 * cp[P_LEV + 1, 0] - d0 * cp[P_LEV + 1, 2]) * idt
                z2 += (d0 * cp[P_LEV + 2, 1] - d1 * cp[P_LEV + 2, 0]) * idt
            g0 = f0 - (n0 + z0) * dt
            g1 = f1 - (n1 + z1) * dt
            g2 = f2 - (n2 + z2) * dt
            w0 = t0 - (cp[P_G, 0] * g0 + cp[P_G, 1] * g1 + cp[P_G, 2] * g2)
            w1 = t1 - (cp[P_G + 1, 0] * g0 + cp[P_G + 1, 1] * g1 + cp[P_G + 1, 2] * g2)
            w2 = t2 - (cp[P_G + 2, 0] * g0 + cp[P_G + 2, 1] * g1 + cp[P_G + 2, 2] * g2)
    out[0] = w0 - cp[P_XEPS, 0] * dt
    out[1] = w1 - cp[P_XEPS, 1] * dt
    out[2] = w2 - cp[P_XEPS, 2] * dt
    out[3] = g0 - cp[P_XNAB, 0] * dt
    out[4] = g1 - cp[P_XNAB, 1] * dt
    out[5] = g2 - cp[P_XNAB, 2] * dt


@njit(cache=True)
def mechanize(dth, dv, dt, st, cfg, cp, vref, k0, decim, o_idx, o_q, o_v, o_pos):
    """Integrate samples ``dth[j], dv[j]`` (global indices ``k0 + j``) from state ``st`` (updated in place).

    Writes one output row after every sample whose global index ``k`` has
    ``(k + 1) % decim == 0``: ``o_idx`` (the sample index), ``o_q`` (C_s^n quaternion),
    ``o_v`` (ENU velocity), ``o_pos`` (lat, lon, h).  ``vref`` is the reference velocity
    for horizontal damping: shape (n, 3) per sample or (1, 3) constant.
    Returns the number of output rows written.
    """
    n = dth.shape[0]
    comp_level = int(cfg[C_COMP])
    coning = cfg[C_CONING] != 0.0
    vert = int(cfg[C_VERT])
    hdamp = cfg[C_HDAMP] != 0.0
    fixpos = cfg[C_FIXPOS] != 0.0
    vk1, vk2, vk3 = cfg[C_VK1], cfg[C_VK2], cfg[C_VK3]
    hk1, hk2 = cfg[C_HK1], cfg[C_HK2]
    gscale = cfg[C_GSCALE]
    per_sample_ref = vref.shape[0] > 1
    buf = np.empty(6)
    pw = np.empty(3)

    q0, q1, q2, q3 = st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3]
    ve, vn, vu = st[S_V], st[S_V + 1], st[S_V + 2]
    lat, lon, h = st[S_LAT], st[S_LON], st[S_H]
    p0, p1, p2 = st[S_PDTH], st[S_PDTH + 1], st[S_PDTH + 2]
    u0, u1, u2 = st[S_PDV], st[S_PDV + 1], st[S_PDV + 2]
    have_prev = st[S_HAVE_PREV] != 0.0
    vacc = st[S_VACC]
    href = st[S_HREF]
    lat0, lon0 = lat, lon
    latc, lonc = st[S_LATC], st[S_LONC]
    pw[0], pw[1], pw[2] = st[S_PW], st[S_PW + 1], st[S_PW + 2]
    re, rn_ = vref[0, 0], vref[0, 1]
    nout = 0
    for j in range(n):
        # ---- compensation (S16 eq. 3, 6-8)
        if comp_level > 0:
            _compensate(dth[j], dv[j], dt, cp, comp_level, pw, have_prev, buf)
            a0, a1, a2 = buf[0], buf[1], buf[2]
            b0, b1, b2 = buf[3], buf[4], buf[5]
            pw[0], pw[1], pw[2] = a0 / dt, a1 / dt, a2 / dt
        else:
            a0, a1, a2 = dth[j, 0], dth[j, 1], dth[j, 2]
            b0, b1, b2 = dv[j, 0], dv[j, 1], dv[j, 2]
        # ---- two-sample coning, sculling and rotation corrections (Savage ch. 7)
        r0, r1, r2, c0, c1, c2 = two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, coning and have_prev)
        # ---- Earth quantities at the start of the interval, velocity update (T&W ch. 3, 11)
        nve, nvn, nvu, sl, cl, rmh, rnh, wie_n, wie_u = velocity_step(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu, lat, h,
                                                                        dt, gscale)
        if hdamp:
            if per_sample_ref:
                re, rn_ = vref[j, 0], vref[j, 1]
            nve -= hk1 * (ve - re) * dt
            nvn -= hk1 * (vn - rn_) * dt
        if vert == 0:
            nvu = 0.0
        else:
            dh = h - href  # third-order vertical loop (poles at -1/tau)
            nvu -= (vk2 * dh + vacc) * dt
            vacc += vk3 * dh * dt
        # ---- attitude: q = q(-zeta) q q(phi), zeta with the midpoint velocity (neutral Schuler loop)
        mve = 0.5 * (ve + nve)
        mvn = 0.5 * (vn + nvn)
        we0 = -mvn / rmh
        we1 = mve / rnh
        we2 = mve * sl / (cl * rnh)
        if hdamp:
            # extra level rotation rate from the (midpoint) velocity difference (damped Schuler loop)
            we0 += -hk2 * (mvn - rn_) / rmh
            we1 += hk2 * (mve - re) / rnh
        q0, q1, q2, q3 = attitude_step(q0, q1, q2, q3, r0, r1, r2, we0 * dt, (wie_n + we1) * dt, (wie_u + we2) * dt)
        # ---- position (trapezoidal)
        if fixpos:
            lat, lon = lat0, lon0
        else:
            # Kahan summation: steps of ~1e-12 rad must not be lost against lat ~ 1 rad
            y = 0.5 * (vn + nvn) / rmh * dt - latc
            tt = lat + y
            latc = (tt - lat) - y
            lat = tt
            y = 0.5 * (ve + nve) / (rnh * cl) * dt - lonc
            tt = lon + y
            lonc = (tt - lon) - y
            lon = tt
        if vert == 0:
            h = href
        else:
            h += (0.5 * (vu + nvu) - vk1 * (h - href)) * dt
        ve, vn, vu = nve, nvn, nvu
        p0, p1, p2 = a0, a1, a2
        u0, u1, u2 = b0, b1, b2
        have_prev = True
        k = k0 + j
        if (k + 1) % decim == 0:
            o_idx[nout] = k
            o_q[nout, 0] = q0
            o_q[nout, 1] = q1
            o_q[nout, 2] = q2
            o_q[nout, 3] = q3
            o_v[nout, 0] = ve
            o_v[nout, 1] = vn
            o_v[nout, 2] = vu
            o_pos[nout, 0] = lat
            o_pos[nout, 1] = lon
            o_pos[nout, 2] = h
            nout += 1
    st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3] = q0, q1, q2, q3
    st[S_V], st[S_V + 1], st[S_V + 2] = ve, vn, vu
    st[S_LAT], st[S_LON], st[S_H] = lat, lon, h
    st[S_PDTH], st[S_PDTH + 1], st[S_PDTH + 2] = p0, p1, p2
    st[S_PDV], st[S_PDV + 1], st[S_PDV + 2] = u0, u1, u2
    st[S_HAVE_PREV] = 1.0 if have_prev else 0.0
    st[S_VACC] = vacc
    st[S_LATC], st[S_LONC] = latc, lonc
    st[S_PW], st[S_PW + 1], st[S_PW + 2] = pw[0], pw[1], pw[2]
    return nout


# ----------------------------------------------------------------------------- Python layer
@dataclass
class NavState:
    """A navigation state (SI): IMU attitude ``C_s^n``, ENU velocity, geodetic position."""

    C_s_n: np.ndarray
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    latitude: float = 0.0
    longitude: float = 0.0
    height: float = 0.0

    def __post_init__(self):
        self.C_s_n = np.asarray(self.C_s_n, dtype=float).reshape(3, 3)
        self.velocity = np.asarray(self.velocity, dtype=float).reshape(3)
        if not (np.all(np.isfinite(self.C_s_n)) and np.all(np.isfinite(self.velocity))):
            raise ValueError("navigation state must be finite")
        if abs(np.linalg.det(self.C_s_n) - 1.0) > 1e-6:
            raise ValueError("C_s_n is not a rotation matrix")

    @classmethod
    def from_truth(cls, scenario, t: float = 0.0) -> "NavState":
        """The true state of a simulated static-site scenario at time ``t``."""

        site = scenario.site
        return cls(true_attitude(scenario, np.array([t]))[0], np.zeros(3), site.latitude, site.longitude, site.height)


@dataclass(frozen=True)
class NavConfig:
    """Mechanization options.

    ``mode``: "free" (pure inertial) or "damped" (horizontal damping against ``reference_velocity``);
    ``vertical``: "hold" (v_U = 0, h = h_ref), "damped" (third-order loop, time constant ``vertical_tau``)
    or "free" (pure inertial, no damping: diverges with the time constant sqrt(R/2g) ~ 9.5 min);
    ``damping_ratio`` / ``damping_frequency_ratio``: the damped Schuler loop's xi and w_n / w_s;
    ``output_rate_hz``: decimated output rate (the nearest whole divisor of the sample rate);
    ``coning``: apply the coning/sculling corrections (switch off only to study them).
    """

    mode: str = "free"
    vertical: str = "hold"
    vertical_tau: float = 100.0
    damping_ratio: float = 0.707
    damping_frequency_ratio: float = 1.0
    output_rate_hz: float = 1.0
    coning: bool = True

    def __post_init__(self):
        if self.mode not in ("free", "damped"):
            raise ValueError(f"mode must be 'free' or 'damped', got {self.mode!r}")
        if self.vertical not in ("hold", "damped", "free"):
            raise ValueError(f"vertical must be 'hold', 'damped' or 'free', got {self.vertical!r}")
        for n in ("vertical_tau", "damping_ratio", "damping_frequency_ratio", "output_rate_hz"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{n} must be a positive number, got {v}")

    def decimation(self, dt: float) -> int:
        """Samples per output row at the sample interval ``dt`` [s] (at least 1)."""
        return max(1, int(round(1.0 / (dt * self.output_rate_hz))))


def compensation_block(params: ImuErrors | None) -> tuple[np.ndarray, int]:
    """Kernel parameter block and compensation level (0 none, 1 linear, 2 full) for ``params``."""
    cp = np.zeros((N_CP, 3))
    cp[P_MGI:P_MGI + 3] = np.eye(3)
    cp[P_MAI:P_MAI + 3] = np.eye(3)
    if params is None:
        return cp, 0
    cp[P_MGI:P_MGI + 3] = np.linalg.inv(params.M_g)
    cp[P_MAI:P_MAI + 3] = np.linalg.inv(params.M_a)
    cp[P_G:P_G + 3] = params.gyro_g_sensitivity
    cp[P_LEV:P_LEV + 3] = params.accel_lever_arm
    cp[P_EPS] = params.gyro_bias
    cp[P_NAB] = params.accel_bias
    cp[P_K2] = params.accel_nonlinearity
    cp[P_KX1:P_KX1 + 3] = params.K_cross
    level = 2 if params.has_nonlinear else 1
    return cp, level


@dataclass
class NavOutput:
    """Decimated navigation output (SI).  ``index``: sample index k of each row (the state
    after sample k, time = (k + 1) dt + t0; -1 for the initial state)."""

    index: np.ndarray
    time: np.ndarray
    quaternion: np.ndarray  # C_s^n, scalar first (N, 4)
    velocity: np.ndarray  # ENU (N, 3)
    position: np.ndarray  # lat, lon, h (N, 3)
    gimbal: np.ndarray | None = None  # (theta_x, theta_z) at those samples (N, 2)

    @property
    def C_s_n(self) -> np.ndarray:
        return dcm_from_quat(self.quaternion)

    def vehicle_attitude(self, gimbal_model: GimbalErrors | None = None) -> np.ndarray:
        """Vehicle (base) ``[roll, pitch, yaw]`` through the gimbal angles (N25 eq. 34-36), using the
        gimbal model's non-orthogonality (0 if None).  Without gimbal angles, the IMU attitude."""
        Csn = self.C_s_n
        if self.gimbal is None:
            return euler_from_dcm(Csn)

        dth = 0.0 if gimbal_model is None else gimbal_model.nonorthogonality
        return vehicle_attitude_from_imu(Csn, self.gimbal[:, 0], self.gimbal[:, 1], dth)

    @staticmethod
    def concatenate(parts: list["NavOutput"]) -> "NavOutput":
        g = None
        if parts and all(p.gimbal is not None for p in parts):
            g = np.concatenate([p.gimbal for p in parts])
        return NavOutput(
            np.concatenate([p.index for p in parts]), np.concatenate([p.time for p in parts]),
            np.concatenate([p.quaternion for p in parts]), np.concatenate([p.velocity for p in parts]),
            np.concatenate([p.position for p in parts]), g,
        )


class Strapdown:
    """Chunked strapdown navigator.

    >>> nav = Strapdown(NavState.from_truth(scn), dt=1 / scn.rate_hz)
    >>> for ch in simulate_chunks(scn, None):
    ...     out = nav.run(ch.dtheta, ch.dvel, ch.gimbal)

    ``params``: an :class:`ImuErrors` calibration set applied to every sample before
    integration (S16 compensation form), or None.  ``k0``: global index of the next
    sample; ``t0``: the time at the start of sample k0 = 0 (time of sample k is
    ``t0 + (k + 1) dt``).  ``gravity``: the site's :class:`~inscal.core.earth.GravityModel` (WGS-84
    normal gravity when None); the kernel scales its normal gravity by the model's ratio to it
    at the initial position.
    """

    def __init__(self, init: NavState, dt: float, config: NavConfig | None = None,
                 params: ImuErrors | None = None, k0: int = 0, t0: float = 0.0, fix_position: bool = False,
                 gravity: earth.GravityModel | None = None):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError("sample interval must be > 0")
        self.dt = float(dt)
        self.config = config or NavConfig()
        self.params = params
        self.k = int(k0)
        self.t0 = float(t0)
        if self.config.output_rate_hz * self.dt > 1.0 + 1e-9:
            raise ValueError(f"output rate {self.config.output_rate_hz:g} Hz is above the sample rate "
                             f"{1.0 / self.dt:g} Hz")
        self.decim = self.config.decimation(self.dt)
        self.st = np.zeros(N_STATE)
        self.set_state(init)
        self.cp, level = compensation_block(params)
        c = self.config
        cfg = np.zeros(N_CFG)
        cfg[C_CONING] = 1.0 if c.coning else 0.0
        cfg[C_COMP] = level
        cfg[C_FIXPOS] = 1.0 if fix_position else 0.0
        # the kernel evaluates WGS-84 normal gravity along the track and scales it to the model
        self.gravity = gravity or earth.WGS84_GRAVITY
        cfg[C_GSCALE] = self.gravity.scale(init.latitude, init.height)
        g_site = earth.normal_gravity(init.latitude, init.height) * cfg[C_GSCALE]
        if c.vertical == "damped":
            tau = c.vertical_tau
            ws2 = g_site / earth.A
            cfg[C_VERT] = 1.0
            cfg[C_VK1], cfg[C_VK2], cfg[C_VK3] = 3.0 / tau, 3.0 / tau**2 + 2.0 * ws2, 1.0 / tau**3
        elif c.vertical == "free":  # the loop with zero gains: the pure inertial (unstable) vertical channel
            cfg[C_VERT] = 1.0
        if c.mode == "damped":
            ws = math.sqrt(g_site / earth.A)
            wn = c.damping_frequency_ratio * ws
            cfg[C_HDAMP] = 1.0
            cfg[C_HK1] = 2.0 * c.damping_ratio * wn  # s^2 + k1 s + (1 + k2) w_s^2
            cfg[C_HK2] = c.damping_frequency_ratio**2 - 1.0
        self.cfg = cfg
        self._vref0 = np.zeros((1, 3))

    # -- state access
    def set_state(self, s: NavState) -> None:
        q = quat_from_dcm(s.C_s_n)
        self.st[S_Q:S_Q + 4] = q / np.linalg.norm(q)
        self.st[S_V:S_V + 3] = s.velocity
        self.st[S_LAT], self.st[S_LON], self.st[S_H] = s.latitude, s.longitude, s.height
        self.st[S_HREF] = s.height
        self.st[S_LATC] = self.st[S_LONC] = 0.0

    @property
    def state(self) -> NavState:
        st = self.st
        return NavState(dcm_from_quat(st[S_Q:S_Q + 4]), st[S_V:S_V + 3].copy(), st[S_LAT], st[S_LON], st[S_H])

    @property
    def time(self) -> float:
        """Time at the end of the last processed sample."""
        return self.t0 + self.k * self.dt

    def set_extra_bias(self, gyro: np.ndarray, accel: np.ndarray) -> None:
        """Residual biases (after compensation) to subtract, e.g. alignment estimates [rad/s, m/s^2]."""
        self.cp[P_XEPS] = gyro
        self.cp[P_XNAB] = accel
        if self.cfg[C_COMP] == 0 and (np.any(gyro) or np.any(accel)):
            self.cfg[C_COMP] = 1.0

    def correct(self, phi: np.ndarray, dv: np.ndarray) -> None:
        """Feedback correction: remove attitude error ``phi`` (``C_est = exp([phi x]) C_true``)
        and velocity error ``dv`` from the state."""

        q = quat_mul(quat_from_rotvec(-np.asarray(phi, dtype=float)), self.st[S_Q:S_Q + 4].copy())
        self.st[S_Q:S_Q + 4] = q / np.linalg.norm(q)
        self.st[S_V:S_V + 3] -= dv

    # -- integration
    def run(self, dtheta, dvel, gimbal=None, vref=None) -> NavOutput:
        """Integrate one chunk; returns its decimated output rows.

        ``vref``: reference velocity for mode "damped", (n, 3) per sample or (3,) constant (default 0).
        """
        dth = np.ascontiguousarray(dtheta, dtype=np.float64)
        dv = np.ascontiguousarray(dvel, dtype=np.float64)
        if dth.ndim != 2 or dth.shape[1] != 3 or dv.shape != dth.shape:
            raise ValueError(f"increments must be (n, 3) arrays of equal shape, got {dth.shape} and {dv.shape}")
        n = dth.shape[0]
        if vref is None:
            vr = self._vref0
        else:
            vr = np.ascontiguousarray(np.atleast_2d(np.asarray(vref, dtype=np.float64)))
            if vr.shape not in ((1, 3), (n, 3)):
                raise ValueError(f"reference velocity must be (3,) or ({n}, 3), got {vr.shape}")
        m = n // self.decim + 1
        o_idx = np.empty(m, dtype=np.int64)
        o_q = np.empty((m, 4))
        o_v = np.empty((m, 3))
        o_p = np.empty((m, 3))
        nout = mechanize(dth, dv, self.dt, self.st, self.cfg, self.cp, vr, self.k, self.decim, o_idx, o_q, o_v, o_p)
        local = o_idx[:nout] - self.k
        self.k += n
        g = None
        if gimbal is not None:
            g = np.asarray(gimbal, dtype=float)[local]
        return NavOutput(o_idx[:nout], self.t0 + (o_idx[:nout] + 1) * self.dt, o_q[:nout], o_v[:nout], o_p[:nout], g)
