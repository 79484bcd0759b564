"""Compiled building blocks of the systematic filter: compensation of one sample (S16 eq. 1-12), the
per-sample parameter Jacobian columns (S16 eq. 17-27), the navigation error dynamics F_nn and the
encoder attitude of the gimbal model (N25 eq. 5-8)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.calibrate.systematic.states import K_GIM, K_LEVT, K_TH
from inscal.core import earth
from inscal.core.attitude import axis_angle_dcm, rot_x, rot_y, rot_z, skew_entry


# ----------------------------------------------------------------------------- the kernel
@njit(cache=True, inline="always")
def linear(A, x, idt, out):
    """``out = A x / dt`` (the matrix part of the compensation, a rate: ``u_g``, ``u_a`` of S16 eq. 3, 6)."""
    for i in range(3):
        out[i] = (A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]) * idt


@njit(cache=True, inline="always")
def thermal_linear(A, x, idt, eps, th, r0, dT, rate, out):
    """``out = A y`` with the thermal states applied to the raw output ``x`` (one sample's increments) before the
    compensation matrix (states module docstring): ``y_i = (x_i / dt - eps_i - beta_i) / (1 + s_i) + eps_i``,
    ``beta_i = sum_k th[r0 + k - 1, i] dT^k`` (+ ``th[12, i] dT/dt`` for the gyros, ``r0 == 0``), ``s_i = sum_k
    th[r0 + 2 + k, i] dT^k``; ``eps = A^-1 b`` the base bias of the sensor axes.  The exact inverse of the
    canonical model (:meth:`inscal.core.thermal.ThermalModel.to_reference`)."""
    d2 = dT * dT
    d3 = d2 * dT
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    for i in range(3):
        b = th[r0, i] * dT + th[r0 + 1, i] * d2 + th[r0 + 2, i] * d3
        if r0 == 0:
            b += th[12, i] * rate
        sc = 1.0 + th[r0 + 3, i] * dT + th[r0 + 4, i] * d2 + th[r0 + 5, i] * d3
        y = (x[i] * idt - eps[i] - b) / sc + eps[i]
        if i == 0:
            y0 = y
        elif i == 1:
            y1 = y
        else:
            y2 = y
    for i in range(3):
        out[i] = A[i, 0] * y0 + A[i, 1] * y1 + A[i, 2] * y2


@njit(cache=True)
def base_bias(A, b, eps):
    """``eps = A^-1 b``: the base bias of the sensor axes (rate or specific force) of a compensation matrix and
    bias (Cramer's rule)."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    c10 = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    c11 = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    c12 = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    c20 = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    c21 = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    c22 = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    eps[0] = (c00 * b[0] + c10 * b[1] + c20 * b[2]) / det
    eps[1] = (c01 * b[0] + c11 * b[1] + c21 * b[2]) / det
    eps[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det


@njit(cache=True)
def thermal_values(kinds, axes, js, wl, fl, dT, rate, vals):
    """Per-sample value of each thermal column (kind ``K_TH``; the others are left as they are): ``-dT^k`` for a
    bias coefficient, ``-(u - b)_i dT^k`` for a scale-factor coefficient (``wl`` = ``u_g - b_g``, ``fl`` =
    ``u_a - b_a``, the linearly compensated rate and specific force), ``-dT/dt`` for the dT/dt term; the column
    is ``C[:, axes[c]] * vals[c]`` in the rows of the state's triad (states module docstring)."""
    for c in range(kinds.shape[0]):
        if kinds[c] != 11:
            continue
        j = js[c]
        if j == 12:
            vals[c] = -rate
            continue
        p = dT ** (j % 3 + 1)
        t = j // 3
        if t == 0 or t == 2:
            vals[c] = -p
        elif t == 1:
            vals[c] = -wl[axes[c]] * p
        else:
            vals[c] = -fl[axes[c]] * p


@njit(cache=True)
def lever_timing_rate(lev, w, wd, wdd, sd):
    """Per accelerometer ``i`` (lever arm ``p = lev[i]``), the rate in navigation axes of the lever-arm terms it
    senses, ``sd_i = e_i . (L-dot + w x L)``, ``L = w-dot x p + w x (w x p)`` (body axes), ``L-dot = w-ddot x p
    + w-dot x (w x p) + w x (w-dot x p)``: a lever-arm acceleration evaluated ``delta`` earlier in navigation axes
    and sensed along the accelerometer's axis now is ``e_i . L - delta sd_i`` to first order
    (``d/dt (C_n^b a^n) = L-dot``, ``C_n^b a-dot^n = L-dot + w x L``).  The lever-arm timing state
    (``levtime``) is the coefficient of this column: the PSINS first-order asynchrony ``f - tau w x f`` leaves the
    lever-arm terms where an accelerometer sampled ``tau`` early has them, ``delta = tau``."""
    for i in range(3):
        p0, p1, p2 = lev[i, 0], lev[i, 1], lev[i, 2]
        a0 = w[1] * p2 - w[2] * p1  # w x p
        a1 = w[2] * p0 - w[0] * p2
        a2 = w[0] * p1 - w[1] * p0
        b0 = wd[1] * p2 - wd[2] * p1  # w-dot x p
        b1 = wd[2] * p0 - wd[0] * p2
        b2 = wd[0] * p1 - wd[1] * p0
        L0 = b0 + w[1] * a2 - w[2] * a1
        L1 = b1 + w[2] * a0 - w[0] * a2
        L2 = b2 + w[0] * a1 - w[1] * a0
        D0 = (wdd[1] * p2 - wdd[2] * p1) + (wd[1] * a2 - wd[2] * a1) + (w[1] * b2 - w[2] * b1)
        D1 = (wdd[2] * p0 - wdd[0] * p2) + (wd[2] * a0 - wd[0] * a2) + (w[2] * b0 - w[0] * b2)
        D2 = (wdd[0] * p1 - wdd[1] * p0) + (wd[0] * a1 - wd[1] * a0) + (w[0] * b1 - w[1] * b0)
        if i == 0:
            sd[0] = D0 + w[1] * L2 - w[2] * L1
        elif i == 1:
            sd[1] = D1 + w[2] * L0 - w[0] * L2
        else:
            sd[2] = D2 + w[0] * L1 - w[1] * L0


@njit(cache=True)
def lever_timing_step(ug, bg, wlm, wlp, wdot, lev, idt, sd):
    """:func:`lever_timing_rate` of one sample from its linearly compensated rate ``ug - bg``, the centred
    ``wdot`` and the second difference of the neighbours' rates ``wlm``, ``wlp`` (``w-ddot``)."""
    i2 = idt * idt
    w0, w1, w2 = ug[0] - bg[0], ug[1] - bg[1], ug[2] - bg[2]
    lever_timing_rate(lev, (w0, w1, w2), wdot, ((wlp[0] - 2.0 * w0 + wlm[0]) * i2, (wlp[1] - 2.0 * w1 + wlm[1]) * i2,
                                               (wlp[2] - 2.0 * w2 + wlm[2]) * i2), sd)


@njit(cache=True, inline="always")
def compensate_sample(ug, ua, bg, G, ba, K2, Kx, lev, tau, nl, idt, f0m, f0p, wlm, wlp, w, f, fdot, wdot, levt, lt,
                      sd):
    """S16 compensation of one sample (module docstring) from its matrix parts ``ug = A_g dtheta / dt``,
    ``ua = A_a dv / dt`` (:func:`linear`); fills w, f (rates), the centred derivatives ``fdot`` (of the
    accelerometer output) and ``wdot``; ``idt = 1 / dt``.

    ``f0m``/``f0p`` and ``wlm``/``wlp``: the linearly compensated specific force and rate of the
    previous and next samples (equal to this sample's at the ends of the record).  Time asynchrony:
    the accelerometer increment over [t_k-1 - tau, t_k - tau] is moved to [t_k-1, t_k] by a quadratic
    interpolation of the integrated output, ``fb_k += tau (fb_k+1 - fb_k-1) / (2 dt)
    + tau^2 (fb_k+1 - 2 fb_k + fb_k-1) / (2 dt^2)`` (error of order tau dt^2 times the third
    derivative of f).  The size effect's w-dot is the centred difference ``(wb_k+1 - wb_k-1) / (2 dt)``.
    ``lt``: the lever-arm timing (``levt`` (3), s; :func:`lever_timing_rate` with the linearly compensated rates,
    ``w-ddot`` their centred second difference, into ``sd``): ``f_i += levt_i sd_i``."""
    f0x = ua[0] - ba[0]
    f0y = ua[1] - ba[1]
    f0z = ua[2] - ba[2]
    fdot[0] = (f0p[0] - f0m[0]) * 0.5 * idt
    fdot[1] = (f0p[1] - f0m[1]) * 0.5 * idt
    fdot[2] = (f0p[2] - f0m[2]) * 0.5 * idt
    for i in range(3):
        wdot[i] = (wlp[i] - wlm[i]) * 0.5 * idt
    if tau != 0.0:
        c2 = 0.5 * tau * tau * idt * idt
        f0x += tau * fdot[0] + c2 * (f0p[0] - 2.0 * f0x + f0m[0])
        f0y += tau * fdot[1] + c2 * (f0p[1] - 2.0 * f0y + f0m[1])
        f0z += tau * fdot[2] + c2 * (f0p[2] - 2.0 * f0z + f0m[2])
    if lt:  # a call, not inlined: the hot loop of a pass without the lever-arm timing stays as small as it was
        lever_timing_step(ug, bg, wlm, wlp, wdot, lev, idt, sd)
        f0x += levt[0] * sd[0]
        f0y += levt[1] * sd[1]
        f0z += levt[2] * sd[2]
    fx, fy, fz = f0x, f0y, f0z
    for i in range(3):
        w[i] = ug[i] - bg[i] - (G[i, 0] * fx + G[i, 1] * fy + G[i, 2] * fz)
    if nl:
        d0, d1, d2 = wdot[0], wdot[1], wdot[2]
        for _ in range(3):  # S16 eq. 8 (fixed point)
            c0, c1, c2_ = fx * fy, fx * fz, fy * fz
            w0, w1, w2 = w[0], w[1], w[2]
            ww = w0 * w0 + w1 * w1 + w2 * w2
            wp0 = w0 * lev[0, 0] + w1 * lev[0, 1] + w2 * lev[0, 2]
            wp1 = w0 * lev[1, 0] + w1 * lev[1, 1] + w2 * lev[1, 2]
            wp2 = w0 * lev[2, 0] + w1 * lev[2, 1] + w2 * lev[2, 2]
            s0 = w0 * wp0 - lev[0, 0] * ww + (d1 * lev[0, 2] - d2 * lev[0, 1])  # S16 eq. 9-11 (+ w-dot)
            s1 = w1 * wp1 - lev[1, 1] * ww + (d2 * lev[1, 0] - d0 * lev[1, 2])
            s2 = w2 * wp2 - lev[2, 2] * ww + (d0 * lev[2, 1] - d1 * lev[2, 0])
            nx = f0x - (K2[0] * fx * fx + Kx[0, 0] * c0 + Kx[0, 1] * c1 + Kx[0, 2] * c2_) - s0  # S16 eq. 12
            ny = f0y - (K2[1] * fy * fy + Kx[1, 0] * c0 + Kx[1, 1] * c1 + Kx[1, 2] * c2_) - s1
            nz = f0z - (K2[2] * fz * fz + Kx[2, 0] * c0 + Kx[2, 1] * c1 + Kx[2, 2] * c2_) - s2
            fx, fy, fz = nx, ny, nz
            for i in range(3):
                w[i] = ug[i] - bg[i] - (G[i, 0] * fx + G[i, 1] * fy + G[i, 2] * fz)
    f[0], f[1], f[2] = fx, fy, fz


@njit(cache=True)
def column_values(kinds, axes, js, ug, ua, w, f, wd, fdot, vals):
    """Per-sample value of each parameter column of dw (kinds 0-2) or df (kinds 3-9): the column
    is ``C[:, axes[c]] * vals[c]`` except for the asynchrony (``C fdot``, handled by the caller)."""
    ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    for c in range(kinds.shape[0]):
        k = kinds[c]
        i = axes[c]
        j = js[c]
        if k == 0:  # dKG u_g
            vals[c] = ug[j]
        elif k == 1 or k == 4:  # -db
            vals[c] = -1.0
        elif k == 2:  # -dG f
            vals[c] = -f[j]
        elif k == 3:  # dKA u_a
            vals[c] = ua[j]
        elif k == 5:  # -dK2 f_i^2
            vals[c] = -f[i] * f[i]
        elif k == 6:  # -dKx f_a f_b
            if j == 0 or j == 2:
                vals[c] = -f[0] * f[1]
            elif j == 1 or j == 4:
                vals[c] = -f[0] * f[2]
            else:
                vals[c] = -f[1] * f[2]
        elif k == 7:  # diagonal lever arm: -d a_size_i / d r_i = |w|^2 - w_i^2
            vals[c] = ww - w[i] * w[i]
        elif k == 8:  # full lever arm p_ij: -(w_i w_j - delta_ij |w|^2 + (wdot x e_j)_i)
            vals[c] = -(w[i] * w[j] - (ww if i == j else 0.0) + skew_entry(wd, i, j))
        else:  # the asynchrony (the caller's C f-dot) and the lever-arm timing: its column is the lever-arm terms'
            # rate (lever_timing_rate), zero at lever arms of zero, the nominal unit the bound linearises about
            vals[c] = 0.0


@njit(cache=True)
def nav_F(lat, h, fn, F, g_scale=1.0):
    """Continuous F_nn (9 x 9) of the static-base error model (module docstring); ``g_scale``:
    site gravity model / WGS-84 normal gravity."""
    for i in range(9):
        for j in range(9):
            F[i, j] = 0.0
    W = earth.OMEGA_IE
    sl, cl = math.sin(lat), math.cos(lat)
    rm, rn = earth.radii(lat)
    rm += h
    rn += h
    wn, wu = W * cl, W * sl
    # phi' = phi x w_ie  = -[w_ie x] phi
    F[0, 1] = wu
    F[0, 2] = -wn
    F[1, 0] = -wu
    F[2, 0] = wn
    # - dw_en(dv):  dw_en = [-dvN/RM, dvE/RN, dvE tanL/RN]
    F[0, 4] = 1.0 / rm
    F[1, 3] = -1.0 / rn
    F[2, 3] = -sl / cl / rn
    # - dw_ie(dL), dL = dpN / RM: dw_ie = W [0, -sinL, cosL] dL
    F[1, 7] = W * sl / rm
    F[2, 7] = -W * cl / rm
    # dv' = phi x f^n = -[f x] phi
    F[3, 1] = fn[2]
    F[3, 2] = -fn[1]
    F[4, 0] = -fn[2]
    F[4, 2] = fn[0]
    F[5, 0] = fn[1]
    F[5, 1] = -fn[0]
    # - 2 w_ie x dv
    F[3, 4] = 2.0 * wu
    F[3, 5] = -2.0 * wn
    F[4, 3] = -2.0 * wu
    F[5, 3] = 2.0 * wn
    # gravity gradient: g_U = -gamma(h), d(dv_U)/d(h) = +2 gamma / R
    F[5, 8] = 2.0 * earth.normal_gravity(lat, h) * g_scale / math.sqrt(rm * rn)
    # dp' = dv
    F[6, 3] = 1.0
    F[7, 4] = 1.0
    F[8, 5] = 1.0


@njit(cache=True)
def gimbal_attitude(gim, tx, tz, C, a, c, Hg):
    """The gimbal model's IMU attitude ``C = C_b^n Rot(u, tx) R_z(tz)`` (N25 eq. 5-8, 34; exact
    Rodrigues rotation about ``u = [cos dth, 0, sin dth]``), the outer and inner axes in n (``a``,
    ``c``: the directions of the encoder noise) and ``Hg = d psi / d[dth, alpha0, beta0, gamma0]``
    (3 x 4), ``psi`` the n-frame rotation of ``C`` for a change of the gimbal parameters (module
    docstring); ``gim = [dth, alpha0, beta0, gamma0]``."""
    dth = gim[0]
    u = np.array([math.cos(dth), 0.0, math.sin(dth)])
    du = np.array([-math.sin(dth), 0.0, math.cos(dth)])
    Rzg = rot_z(gim[3])
    RzRy = Rzg @ rot_y(gim[2])
    Cbn = RzRy @ rot_x(gim[1])  # N25 eq. 8
    Rx = axis_angle_dcm(u, tx)  # N25 eq. 5 (exact)
    C[:, :] = Cbn @ (Rx @ rot_z(tz))  # N25 eq. 7
    s1, c1 = math.sin(tx), 1.0 - math.cos(tx)
    # left Jacobian of Rot(u, tx) for a change du of the unit axis (du perpendicular to u)
    w0 = s1 * du[0] + c1 * (u[1] * du[2] - u[2] * du[1])
    w1 = s1 * du[1] + c1 * (u[2] * du[0] - u[0] * du[2])
    w2 = s1 * du[2] + c1 * (u[0] * du[1] - u[1] * du[0])
    for i in range(3):
        a[i] = Cbn[i, 0] * u[0] + Cbn[i, 1] * u[1] + Cbn[i, 2] * u[2]
        c[i] = Cbn[i, 0] * Rx[0, 2] + Cbn[i, 1] * Rx[1, 2] + Cbn[i, 2] * Rx[2, 2]
        Hg[i, 0] = Cbn[i, 0] * w0 + Cbn[i, 1] * w1 + Cbn[i, 2] * w2  # N25 eq. 35-36 (d dth)
        Hg[i, 1] = RzRy[i, 0]  # d alpha0: R_z R_y e_x
        Hg[i, 2] = Rzg[i, 1]  # d beta0: R_z e_y
        Hg[i, 3] = 1.0 if i == 2 else 0.0  # d gamma0: e_z


@njit(cache=True)
def feedback_params(xs, kinds, axes, js, Ag, bg, G, Aa, ba, K2, Kx, lev, tau, gim, th, levt, nd=9):
    """Remove the parameter estimates (physical, ``xs[nd:]``, ``nd`` the dynamic states) from the compensation
    (in place)."""
    npar = kinds.shape[0]
    Dg = np.zeros((3, 3))
    Da = np.zeros((3, 3))
    for c in range(npar):
        v = xs[nd + c]
        k = kinds[c]
        i = axes[c]
        j = js[c]
        if k == 0:
            Dg[i, j] = v
        elif k == 1:
            bg[i] -= v
        elif k == 2:
            G[i, j] -= v
        elif k == 3:
            Da[i, j] = v
        elif k == 4:
            ba[i] -= v
        elif k == 5:
            K2[i] -= v
        elif k == 6:
            col = 0 if (j == 0 or j == 2) else (1 if (j == 1 or j == 4) else 2)
            Kx[i, col] -= v
        elif k == 7:
            lev[i, i] -= v
        elif k == 8:
            lev[i, j] -= v
        elif k == K_GIM:
            gim[j] -= v
        elif k == K_TH:
            th[j, i] -= v
        elif k == K_LEVT:
            levt[i] -= v
        else:
            tau[0] -= v
    left_correct(Dg, Ag)
    left_correct(Da, Aa)


@njit(cache=True, inline="always")
def left_correct(D, A):
    """``A <- (I - D) A`` in place (S16 eq. 27 for a compensation matrix)."""
    for j in range(3):
        a0, a1, a2 = A[0, j], A[1, j], A[2, j]
        for i in range(3):
            A[i, j] = A[i, j] - (D[i, 0] * a0 + D[i, 1] * a1 + D[i, 2] * a2)
