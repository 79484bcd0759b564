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
* Earth quantities (Savage ch. 7's lower-rate navigation-frame terms): the latitude's functions
  (Earth rate, ``tan L`` and ``1/cos L``, the radii of curvature, normal gravity on the ellipsoid)
  change with the position, by ``v_N dt / R`` per sample (1e-9 rad at 1 m/s and 100 Hz), and are
  computed once per update interval (:attr:`NavConfig.earth_update_hz`, 1 Hz) at the mean of the
  start-of-sample latitudes an update at every sample would use (the latitude extrapolated with
  ``v_N``: the same to second order in the interval).  The velocity terms of the transport rate
  and of Coriolis, ``1/(R + h)`` and gravity's height term stay per sample (the vertical channel's
  2 g / R gradient).  Against the update at every sample: 3e-4 m on the 1278 m of the 5-day
  reference run at 100 Hz, 1e-5 m on 10 km in 24 h (``tests/nav/test_strapdown_rates.py``).

Arithmetic of a sample (no trigonometry, no division, no allocation): the quaternion of a
rotation vector by its series (exact to round-off up to 10 deg per sample, trigonometric beyond),
the constant divisions of the two-sample terms as products, the quaternion normalised once per
Earth update (a Newton step: ``|q| - 1`` stays ~1e-15 in between), the output rows decimated in
the kernel by a countdown, products contracted to fused multiply-adds.  Against the per-sample step
functions (trigonometric quaternions normalised every sample) the kernel agrees to round-off
(``tests/nav/test_strapdown_rates.py``; the 5-day reference run moves by 2e-7 m).

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
:meth:`inscal.core.error_model.ImuErrors.compensate`, :mod:`inscal.nav.compensation`): each
sample's increments are compensated before integration, ``w~ = M_g^-1 (N_g - eps) - G f~``,
``f~ = M_a^-1 (N_a - nabla) - K2 f~^(2) - Kx f~^(x) - a_size(w~, w~-dot)`` with rates =
increments / dt (the fixed point is iterated three times, converged to ~1e-12 of
the nonlinear correction).

Everything runs in one ``@njit`` kernel that allocates nothing per sample; chunks
of any size are processed with the state carried between calls (the Earth updates, the output
rows and the reference-height blocks on the grid of the global sample index, so the chunking
changes no bit), and long records never need to be in memory more than once.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from inscal.core import earth
from inscal.core.attitude import (
    dcm_from_quat,
    quat_from_dcm,
    quat_from_rotvec,
    quat_from_rotvec_xyz,
    quat_mul,
)
# the kernels' scalar faces under their short names (the systematic filter's kernel imports them from here)
from inscal.core.attitude import quat_from_rotvec_poly_xyz as rotvec_quat
from inscal.core.attitude import quat_mul_xyz as qmul
from inscal.core.attitude import quat_rotate_xyz as qrot
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.core.kinematics import true_attitude
from inscal.core.turntable import C_s_b
from inscal.nav.compensation import (
    P_XEPS,
    P_XNAB,
    compensate_sample,
    compensation_block,
)
from inscal.nav.frames import euler_of_products

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
# the Earth quantities of the current update interval (:func:`earth_update`)
S_E_OK = 24  # 1: valid (0 after set_state: computed at the next sample)
S_E_TL, S_E_SECL = 25, 26  # tan L, 1 / cos L
S_E_WN, S_E_WU = 27, 28  # Earth rate north, up [rad/s]
S_E_RM, S_E_RN = 29, 30  # radii of curvature R_M, R_N [m]
S_E_G0, S_E_GH = 31, 32  # normal gravity on the ellipsoid (scaled) [m/s^2], its height coefficient [1/m]
N_STATE = 33

# layout of the configuration vector ``cfg`` (float64)
C_VERT = 0  # 0 hold, 1 damped
C_VK1, C_VK2, C_VK3 = 1, 2, 3
C_HDAMP = 4  # 0 free, 1 damped
C_HK1, C_HK2 = 5, 6
C_CONING = 7  # 1 apply coning/sculling corrections
C_COMP = 8  # 0 none, 1 linear (M, bias, G), 2 full (plus nonlinear and size effect)
C_FIXPOS = 9  # 1: position clamped to the reference (alignment)
C_GSCALE = 10  # gravity model / WGS-84 normal gravity at the site (1.0: WGS-84)
C_EARTH_N = 11  # samples per update of the Earth quantities (1: every sample)
C_HBLK = 12  # samples per block of the reference height profile
N_CFG = 13



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
    nve, nvn, nvu = velocity_increment(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu, we0, we1, we2, wie_n, wie_u, grav, dt)
    return nve, nvn, nvu, sl, cl, rmh, rnh, wie_n, wie_u


@njit(cache=True, inline="always")
def velocity_increment(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu, we0, we1, we2, wie_n, wie_u, grav, dt):
    """The ENU velocity equation of one sample (T&W ch. 11) given the transport rate ``w_en^n`` = (we0, we1, we2),
    the Earth rate's north and up components and gravity at the start of the interval:
    ``v + (I - [zeta x]/2) C(q) c + (g - (2 w_ie + w_en) x v) dt``, ``zeta = (w_ie^n + w_en^n) dt``."""
    z0 = we0 * dt
    z1 = (wie_n + we1) * dt
    z2 = (wie_u + we2) * dt
    s0, s1, s2 = qrot(q0, q1, q2, q3, c0, c1, c2)
    s0 -= 0.5 * (z1 * s2 - z2 * s1)
    s1 -= 0.5 * (z2 * s0 - z0 * s2)
    s2 -= 0.5 * (z0 * s1 - z1 * s0)
    o1 = 2.0 * wie_n + we1
    o2 = 2.0 * wie_u + we2
    nve = ve + s0 - (o1 * vu - o2 * vn) * dt
    nvn = vn + s1 - (o2 * ve - we0 * vu) * dt
    nvu = vu + s2 - (we0 * vn - o1 * ve) * dt - grav * dt
    return nve, nvn, nvu



@njit(cache=True, inline="always")
def two_sample_mul(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, with_prev):
    """:func:`two_sample` with the divisions by 6 and 12 as products with 1/6 and 1/12 (the same
    terms to round-off, without the division latency: the navigation kernel's; :func:`two_sample`
    keeps its rounding for the systematic filter's navigation)."""
    r0, r1, r2 = a0, a1, a2
    x0 = a1 * b2 - a2 * b1
    x1 = a2 * b0 - a0 * b2
    x2 = a0 * b1 - a1 * b0
    c0 = b0 + 0.5 * x0 + (a1 * x2 - a2 * x1) * (1.0 / 6.0)
    c1 = b1 + 0.5 * x1 + (a2 * x0 - a0 * x2) * (1.0 / 6.0)
    c2 = b2 + 0.5 * x2 + (a0 * x1 - a1 * x0) * (1.0 / 6.0)
    if with_prev:
        r0 += (p1 * a2 - p2 * a1) * (1.0 / 12.0)
        r1 += (p2 * a0 - p0 * a2) * (1.0 / 12.0)
        r2 += (p0 * a1 - p1 * a0) * (1.0 / 12.0)
        c0 += ((p1 * b2 - p2 * b1) + (u1 * a2 - u2 * a1)) * (1.0 / 12.0)
        c1 += ((p2 * b0 - p0 * b2) + (u2 * a0 - u0 * a2)) * (1.0 / 12.0)
        c2 += ((p0 * b1 - p1 * b0) + (u0 * a1 - u1 * a0)) * (1.0 / 12.0)
    return r0, r1, r2, c0, c1, c2

@njit(cache=True)
def earth_update(st, lat, h, vn, ahead, gscale):
    """The Earth quantities of the next update interval into ``st[S_E_*]`` (WGS-84, T&W ch. 3):
    ``tan L``, ``1 / cos L``, the Earth rate ``W cos L``, ``W sin L``, the radii ``R_M``, ``R_N`` and
    normal gravity's latitude terms, ``g_0(L)`` (times the model's scale ``gscale``) and its height
    coefficient (TR8350.2 eq. 4-1, 4-3; the height term is applied per sample), at the latitude
    ``L + v_N ahead / (R_M + h)`` extrapolated with the current North velocity by ``ahead`` =
    (samples in the interval - 1) dt / 2: the mean of the start-of-sample latitudes that an update
    at every sample would use (the midpoint rule: the same to second order in the interval)."""
    rm0, _ = earth.radii(lat)
    lm = lat + ahead * vn / (rm0 + h)
    sl = math.sin(lm)
    cl = math.cos(lm)
    s2 = sl * sl
    w = math.sqrt(1.0 - earth.E2 * s2)
    rn = earth.A / w
    st[S_E_TL] = sl / cl
    st[S_E_SECL] = 1.0 / cl
    st[S_E_WN] = earth.OMEGA_IE * cl
    st[S_E_WU] = earth.OMEGA_IE * sl
    st[S_E_RM] = rn * (1.0 - earth.E2) / (w * w)
    st[S_E_RN] = rn
    st[S_E_G0] = earth.GAMMA_E * (1.0 + earth.K_SOMIGLIANA * s2) / w * gscale
    st[S_E_GH] = 2.0 / earth.A * (1.0 + earth.F + earth.M_RATIO - 2.0 * earth.F * s2)
    st[S_E_OK] = 1.0


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def mechanize(dth, dv, dt, st, cfg, cp, vref, href, k0, t0, decim, o_idx, o_t, o_q, o_v, o_pos):
    """Integrate samples ``dth[j], dv[j]`` (global indices ``k0 + j``) from state ``st`` (updated in place).

    Writes one output row after every sample whose global index ``k`` has
    ``(k + 1) % decim == 0``: ``o_idx`` (the sample index), ``o_t`` (its time ``t0 + (k + 1) dt``),
    ``o_q`` (C_s^n quaternion), ``o_v`` (ENU velocity), ``o_pos`` (lat, lon, h).  ``vref`` is the
    reference velocity for horizontal damping: shape (n, 3) per sample or (1, 3) constant.  ``href``: the reference
    heights of the blocks of ``cfg[C_HBLK]`` samples (global block index ``k // blk``) from the
    block of ``k0`` on, or empty (the reference ``st[S_HREF]`` held).  The Earth quantities are
    updated before every sample with ``k % cfg[C_EARTH_N] == 0`` (:func:`earth_update`).
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
    n_earth = max(1, int(cfg[C_EARTH_N]))
    per_sample_ref = vref.shape[0] > 1
    hprof = href.shape[0] > 0
    hblk = max(1, int(cfg[C_HBLK]))
    gh2 = 3.0 / (earth.A * earth.A)

    q0, q1, q2, q3 = st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3]
    ve, vn, vu = st[S_V], st[S_V + 1], st[S_V + 2]
    lat, lon, h = st[S_LAT], st[S_LON], st[S_H]
    p0, p1, p2 = st[S_PDTH], st[S_PDTH + 1], st[S_PDTH + 2]
    u0, u1, u2 = st[S_PDV], st[S_PDV + 1], st[S_PDV + 2]
    have_prev = st[S_HAVE_PREV] != 0.0
    vacc = st[S_VACC]
    href_now = st[S_HREF]
    lat0, lon0 = lat, lon
    latc, lonc = st[S_LATC], st[S_LONC]
    pw0, pw1, pw2 = st[S_PW], st[S_PW + 1], st[S_PW + 2]
    re, rn_ = vref[0, 0], vref[0, 1]
    # countdowns (global indices, so that the chunking changes nothing): to the next Earth update,
    # the next output row, the next reference-height block
    ce = (n_earth - k0 % n_earth) % n_earth
    if st[S_E_OK] == 0.0:
        earth_update(st, lat, h, 0.0 if fixpos else vn, 0.5 * ((ce if ce > 0 else n_earth) - 1) * dt, gscale)
        ce = ce if ce > 0 else n_earth
    co = (decim - (k0 + 1) % decim) % decim
    ch = hblk - k0 % hblk
    ih = 0
    if hprof:
        href_now = href[0]
    tl, secl = st[S_E_TL], st[S_E_SECL]
    wie_n, wie_u = st[S_E_WN], st[S_E_WU]
    rm, rn = st[S_E_RM], st[S_E_RN]
    g0, gh = st[S_E_G0], st[S_E_GH]
    nout = 0
    for j in range(n):
        if ce == 0:  # a new update interval: normalise q (one Newton step, |q| - 1 ~ 1e-15), Earth quantities
            qn = 1.5 - 0.5 * (q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            q0, q1, q2, q3 = q0 * qn, q1 * qn, q2 * qn, q3 * qn
            earth_update(st, lat, h, 0.0 if fixpos else vn, 0.5 * (n_earth - 1) * dt, gscale)
            tl, secl = st[S_E_TL], st[S_E_SECL]
            wie_n, wie_u = st[S_E_WN], st[S_E_WU]
            rm, rn = st[S_E_RM], st[S_E_RN]
            g0, gh = st[S_E_G0], st[S_E_GH]
            ce = n_earth
        ce -= 1
        if hprof:
            if ch == 0:
                ih = min(ih + 1, href.shape[0] - 1)
                href_now = href[ih]
                ch = hblk
            ch -= 1
        # ---- compensation (S16 eq. 3, 6-8)
        if comp_level > 0:
            a0, a1, a2, b0, b1, b2 = compensate_sample(dth[j, 0], dth[j, 1], dth[j, 2], dv[j, 0], dv[j, 1], dv[j, 2],
                                                        dt, cp, comp_level, pw0, pw1, pw2, have_prev)
            pw0, pw1, pw2 = a0 / dt, a1 / dt, a2 / dt
        else:
            a0, a1, a2 = dth[j, 0], dth[j, 1], dth[j, 2]
            b0, b1, b2 = dv[j, 0], dv[j, 1], dv[j, 2]
        # ---- two-sample coning, sculling and rotation corrections (Savage ch. 7)
        r0, r1, r2, c0, c1, c2 = two_sample_mul(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, coning and have_prev)
        # ---- velocity (T&W ch. 11): v + (I - [zeta x]/2) C dv_sf + (g - (2 w_ie + w_en) x v) dt
        irm = 1.0 / (rm + h)
        irn = 1.0 / (rn + h)
        grav = g0 * (1.0 - gh * h + gh2 * h * h)  # TR8350.2 eq. 4-3 (g0 carries the model's scale)
        we0 = -vn * irm  # transport rate w_en^n = [-vN/(RM+h), vE/(RN+h), vE tanL/(RN+h)]
        we1 = ve * irn
        we2 = we1 * tl
        nve, nvn, nvu = velocity_increment(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu, we0, we1, we2, wie_n, wie_u, grav,
                                           dt)
        if hdamp:
            if per_sample_ref:
                re, rn_ = vref[j, 0], vref[j, 1]
            nve -= hk1 * (ve - re) * dt
            nvn -= hk1 * (vn - rn_) * dt
        if vert == 0:
            nvu = 0.0
        else:
            dh = h - href_now  # third-order vertical loop (poles at -1/tau)
            nvu -= (vk2 * dh + vacc) * dt
            vacc += vk3 * dh * dt
        # ---- attitude: q = q(-zeta) q q(phi), zeta with the midpoint velocity (neutral Schuler loop)
        mve = 0.5 * (ve + nve)
        mvn = 0.5 * (vn + nvn)
        we0 = -mvn * irm
        we1 = mve * irn
        we2 = we1 * tl
        if hdamp:
            # extra level rotation rate from the (midpoint) velocity difference (damped Schuler loop)
            we0 += -hk2 * (mvn - rn_) * irm
            we1 += hk2 * (mve - re) * irn
        e0, e1, e2, e3 = rotvec_quat(r0, r1, r2)
        q0, q1, q2, q3 = qmul(q0, q1, q2, q3, e0, e1, e2, e3)
        e0, e1, e2, e3 = rotvec_quat(-we0 * dt, -(wie_n + we1) * dt, -(wie_u + we2) * dt)
        q0, q1, q2, q3 = qmul(e0, e1, e2, e3, q0, q1, q2, q3)
        # ---- position (trapezoidal)
        if fixpos:
            lat, lon = lat0, lon0
        else:
            # Kahan summation: steps of ~1e-12 rad must not be lost against lat ~ 1 rad
            y = 0.5 * (vn + nvn) * irm * dt - latc
            tt = lat + y
            latc = (tt - lat) - y
            lat = tt
            y = 0.5 * (ve + nve) * irn * secl * dt - lonc
            tt = lon + y
            lonc = (tt - lon) - y
            lon = tt
        if vert == 0:
            h = href_now
        else:
            h += (0.5 * (vu + nvu) - vk1 * (h - href_now)) * dt
        ve, vn, vu = nve, nvn, nvu
        p0, p1, p2 = a0, a1, a2
        u0, u1, u2 = b0, b1, b2
        have_prev = True
        if co == 0:
            o_idx[nout] = k0 + j
            o_t[nout] = t0 + (k0 + j + 1) * dt
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
            co = decim
        co -= 1
    st[S_Q], st[S_Q + 1], st[S_Q + 2], st[S_Q + 3] = q0, q1, q2, q3
    st[S_V], st[S_V + 1], st[S_V + 2] = ve, vn, vu
    st[S_LAT], st[S_LON], st[S_H] = lat, lon, h
    st[S_PDTH], st[S_PDTH + 1], st[S_PDTH + 2] = p0, p1, p2
    st[S_PDV], st[S_PDV + 1], st[S_PDV + 2] = u0, u1, u2
    st[S_HAVE_PREV] = 1.0 if have_prev else 0.0
    st[S_VACC] = vacc
    st[S_HREF] = href_now
    st[S_LATC], st[S_LONC] = latc, lonc
    st[S_PW], st[S_PW + 1], st[S_PW + 2] = pw0, pw1, pw2
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
    ``coning``: apply the coning/sculling corrections (switch off only to study them);
    ``earth_update_hz``: rate of the update of the latitude's Earth quantities (Earth rate, the
    radii of curvature in the transport rate, normal gravity on the ellipsoid; the nearest whole
    divisor of the sample rate, every sample at or above it), at the latitude extrapolated to the
    middle of each update interval; the velocity terms of the transport rate and of Coriolis and
    the height terms stay per sample.  On a static site the latitude moves by the navigation
    error's v_N / R (1.6e-7 rad/s at 1 m/s): 1 Hz is indistinguishable from every sample (2.7e-7 of
    the position error after 5 days at 100 Hz, 1e-9 after 24 h at 10 Hz; the difference is second
    order in the interval; ``tests/nav/test_strapdown_rates.py``).
    """

    mode: str = "free"
    vertical: str = "hold"
    vertical_tau: float = 100.0
    damping_ratio: float = 0.707
    damping_frequency_ratio: float = 1.0
    output_rate_hz: float = 1.0
    coning: bool = True
    earth_update_hz: float = 1.0

    def __post_init__(self):
        if self.mode not in ("free", "damped"):
            raise ValueError(f"mode must be 'free' or 'damped', got {self.mode!r}")
        if self.vertical not in ("hold", "damped", "free"):
            raise ValueError(f"vertical must be 'hold', 'damped' or 'free', got {self.vertical!r}")
        for n in ("vertical_tau", "damping_ratio", "damping_frequency_ratio", "output_rate_hz", "earth_update_hz"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{n} must be a positive number, got {v}")

    def decimation(self, dt: float) -> int:
        """Samples per output row at the sample interval ``dt`` [s] (at least 1)."""
        return max(1, int(round(1.0 / (dt * self.output_rate_hz))))

    def earth_samples(self, dt: float) -> int:
        """Samples per update of the Earth quantities at the sample interval ``dt`` [s] (at least 1)."""
        return max(1, round(1.0 / (dt * self.earth_update_hz)))


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
        """The attitude ``C_s^n`` at each output time, from the stored quaternions."""
        return dcm_from_quat(self.quaternion)

    def vehicle_attitude(self, gimbal_model: GimbalErrors | None = None) -> np.ndarray:
        """Vehicle (base) ``[roll, pitch, yaw]`` through the gimbal angles (N25 eq. 34-36), using the
        gimbal model's non-orthogonality (0 if None).  Without gimbal angles, the IMU attitude."""
        q = np.ascontiguousarray(self.quaternion, dtype=np.float64)
        if self.gimbal is None:
            return euler_of_products(q, np.eye(3)[None])
        dth = 0.0 if gimbal_model is None else gimbal_model.nonorthogonality
        # C_b^n = C_s^n (C_s^b)^T (N25 eq. 34; :func:`inscal.core.turntable.vehicle_attitude_from_imu`)
        return euler_of_products(q, C_s_b(self.gimbal[:, 0], self.gimbal[:, 1], dth))

    @staticmethod
    def concatenate(parts: list["NavOutput"], release: bool = False) -> "NavOutput":
        """The rows of ``parts`` in one output.  ``release``: drop each field of the parts once it is
        copied (the parts are emptied), so that the peak holds the result and one field of the parts,
        not two copies of everything."""
        fields = {}
        for name in ("index", "time", "quaternion", "velocity", "position", "gimbal"):
            cols = [getattr(p, name) for p in parts]
            if name == "gimbal" and not (parts and all(c is not None for c in cols)):
                fields[name] = None
            else:
                fields[name] = np.concatenate(cols)
            if release:
                del cols
                for p in parts:
                    setattr(p, name, None)
        return NavOutput(**fields)


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
        cfg[C_EARTH_N] = c.earth_samples(self.dt)
        cfg[C_HBLK] = 1.0
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
        self._href0 = np.zeros(0)
        self._height_at = None

    # -- state access
    def set_state(self, s: NavState) -> None:
        """Start (or restart) the navigation from state ``s``; the Earth quantities are recomputed at its position."""
        q = quat_from_dcm(s.C_s_n)
        self.st[S_Q:S_Q + 4] = q / np.linalg.norm(q)
        self.st[S_V:S_V + 3] = s.velocity
        self.st[S_LAT], self.st[S_LON], self.st[S_H] = s.latitude, s.longitude, s.height
        self.st[S_HREF] = s.height
        self.st[S_LATC] = self.st[S_LONC] = 0.0
        self.st[S_E_OK] = 0.0  # Earth quantities recomputed at the new position

    @property
    def state(self) -> NavState:
        """The current navigation state (attitude, velocity, position)."""
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
    def set_height_reference(self, height_at: Callable[[np.ndarray], np.ndarray] | None, block: int = 1) -> None:
        """Reference height of the vertical channel from ``height_at(times)`` [s -> m], read once per block of
        ``block`` samples (global blocks ``k // block``) at the middle of the block's sample times; None: the
        reference ``st[S_HREF]`` is held."""
        self._height_at = height_at
        self.cfg[C_HBLK] = max(1, int(block))

    def _height_blocks(self, n: int) -> np.ndarray:
        if self._height_at is None or n == 0:
            return self._href0
        blk = int(self.cfg[C_HBLK])
        kb = np.arange(self.k // blk, (self.k + n - 1) // blk + 1)
        mid = self.t0 + (kb * blk + 0.5 * (blk + 1)) * self.dt  # sample k ends at t0 + (k + 1) dt
        return np.ascontiguousarray(self._height_at(mid), dtype=np.float64).reshape(kb.shape[0])

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
        m = (self.k + n) // self.decim - self.k // self.decim  # rows after the samples k with (k + 1) % decim == 0
        o_idx = np.empty(m, dtype=np.int64)
        o_t = np.empty(m)
        o_q = np.empty((m, 4))
        o_v = np.empty((m, 3))
        o_p = np.empty((m, 3))
        nout = mechanize(dth, dv, self.dt, self.st, self.cfg, self.cp, vr, self._height_blocks(n), self.k, self.t0,
                         self.decim, o_idx, o_t, o_q, o_v, o_p)
        g = None
        if gimbal is not None:
            g = np.asarray(gimbal, dtype=float)[o_idx[:nout] - self.k]
        self.k += n
        return NavOutput(o_idx[:nout], o_t[:nout], o_q[:nout], o_v[:nout], o_p[:nout], g)
