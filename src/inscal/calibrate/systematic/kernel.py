"""The compiled forward pass of the systematic filter (strapdown navigation, compensation, Phi and the
velocity/position and encoder updates) with its driver; its modified Bryson-Frazier smoother is in
:mod:`inscal.calibrate.systematic.smoother`.

Each compiled kernel processes a range of filter steps and keeps what one step hands the next in arrays its
Python driver owns, which calls it in slices of about 50 ms (:func:`inscal.core.slices.run_in_slices`): a
SIGINT or SIGTERM is honoured between two slices instead of after a whole pass, with results bit-identical
to one call over all the steps.  :func:`pass_bytes` is what a pass keeps in memory."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from numba import njit

from inscal.calibrate.systematic.dynamics import (
    base_bias,
    compensate_sample,
    feedback_params,
    gimbal_attitude,
    linear,
    nav_F,
    thermal_linear,
)
from inscal.calibrate.systematic.gm_states import assemble, effective_biases, gm_step_arrays
from inscal.calibrate.systematic.jacobian import (
    N_BASIS,
    basis_values,
    column_layout,
    discretise,
    moment_weights,
    parameter_columns,
    step_moments,
    thermal_basis,
)
from inscal.calibrate.systematic.params import REF_SLICES, REF_WIDTH, CompParams
from inscal.calibrate.systematic.smoother import SmootherData, smooth_kernel, smooth_vector_kernel, stored_before
from inscal.calibrate.systematic.states import (
    ENCODER_SIGMA,
    IDX_MEAS,
    K_GIM,
    K_LEVT,
    StateSet,
)
from inscal.calibrate.windows import CalibrationError
from inscal.core import earth
from inscal.core import kalman as filters
from inscal.core.attitude import quat_from_dcm, quat_from_rotvec_xyz
from inscal.core.attitude import quat_mul_xyz as qmul
from inscal.core.attitude import quat_rotate_xyz as qrot
from inscal.core.slices import run_in_slices
from inscal.nav.strapdown import attitude_step, two_sample, velocity_step


# column ranges of the reference-history row (params.REF_SLICES), as compile-time constants
(_AG0, _AG1), (_BG0, _BG1), (_G0, _G1), (_AA0, _AA1), (_BA0, _BA1), (_K20, _K21), (_KX0, _KX1), (_LV0, _LV1), \
    (_TAU0, _), (_GIM0, _GIM1), (_TH0, _TH1), (_LT0, _LT1) = [REF_SLICES[k][:2] for k in (
        "Ag", "bg", "G", "Aa", "ba", "K2", "Kx", "lever", "tau", "gim", "th", "levt")]

# what one filter step hands the next besides U, the parameters and the stores, kept between two slices of
# a pass in the caller's carry array: the navigation [q(4), v(3), lat, lon, h], the linearly compensated
# specific force and rate of the previous and current samples, the previous sample's angle and velocity
# increments (two-sample coning and sculling) and whether there is one
_C_NAV, _C_F0M, _C_F0C, _C_WLM, _C_WLC, _C_PA, _C_PV, _C_HAVE, _CARRY = 0, 10, 13, 16, 19, 22, 25, 28, 29


class PassInputs(NamedTuple):
    """What a filter pass reads and never writes."""

    dth: np.ndarray  # (n, 3) gyro increments [rad]
    dv: np.ndarray  # (n, 3) velocity increments [m/s]
    dt: float  # sample interval [s]
    n_per: int  # samples per filter step
    nav0: np.ndarray  # [q(4), v(3), lat, lon, h] at the start
    site: np.ndarray  # [lat0, lon0, h0(, g_scale)]
    nl: bool  # evaluate the quadratic, cross-coupling, lever-arm and g-sensitivity terms
    est_tau: bool  # the asynchrony is a state
    kinds: np.ndarray  # per parameter state: its column kind (states.K_*)
    axes: np.ndarray  # ... the axis or matrix element it feeds
    js: np.ndarray  # ... its index into its parameter array
    sig: np.ndarray  # (N,) state scaling: the filter works on x / sig
    qg: np.ndarray  # (3,) gyro white-noise PSD
    qa: np.ndarray  # (3,) accelerometer white-noise PSD
    r: np.ndarray  # (6,) velocity/position measurement variances
    hist_every: int  # steps between stored history rows
    nis_cap: float  # bounded influence: the accelerometer noise raised where a step's NIS exceeds it (inf: none)
    q_factor: np.ndarray  # (M,) factor on the accelerometer white-noise PSD of each step (model-error term; 1: none)
    r_factor: np.ndarray  # (M,) factor on R of each step (a frozen outlier weight; 1: none)
    tdT: np.ndarray  # (n,) thermal states: T - T_ref of each sample [degC] (empty without them)
    trate: np.ndarray  # (n,) ... and dT/dt [degC/s]
    gm_sensor: np.ndarray  # (n_gm,) Gauss-Markov bias states (gm_states): 0 gyro, 1 accelerometer
    gm_axis: np.ndarray  # (n_gm,) ... the sensor axis
    gm_col: np.ndarray  # (n_gm,) ... the parameter column of that axis's constant bias
    gm_phi: np.ndarray  # (n_gm,) ... exp(-T / tc)
    gm_scale: np.ndarray  # (n_gm,) ... the scaled column factor exp(-T / (2 tc)) sig_gm / sig_bias
    gm_q: np.ndarray  # (n_gm,) ... the scaled discrete noise sigma^2 (1 - phi^2) / sig_gm^2
    sigp: np.ndarray  # (9 + npar,) the scaling of the navigation and the parameters (sig without the GM states)


class PassParams(NamedTuple):
    """The compensation parameters (:class:`~inscal.calibrate.systematic.params.CompParams`),
    updated in place by the feedback after every update."""

    Ag: np.ndarray
    bg: np.ndarray
    G: np.ndarray
    Aa: np.ndarray
    ba: np.ndarray
    K2: np.ndarray
    Kx: np.ndarray
    lev: np.ndarray
    tau: np.ndarray
    gim: np.ndarray  # [dth, alpha0, beta0, gamma0]
    th: np.ndarray  # (13, 3) thermal coefficients (params.CompParams.th)
    gmx: np.ndarray  # (n_gm,) the Gauss-Markov bias estimates [rad/s or m/s^2] (gm_states)
    levt: np.ndarray  # (3,) the lever-arm timing [s] (dynamics.lever_timing_rate; zero without levtime)


class PassStore(NamedTuple):
    """What the pass writes per step (M steps) for the smoother, and every ``hist_every`` steps."""

    K_st: np.ndarray  # (M, N, 6) gains
    Si_st: np.ndarray  # (M, 6, 6) S^-1
    sz_st: np.ndarray  # (M, 6) S^-1 nu
    phinn_st: np.ndarray  # (M, 9, 9) Phi_nn
    phinp_st: np.ndarray  # (M, 9, N - 9) Phi_np
    nis_st: np.ndarray  # (M,) NIS
    z_st: np.ndarray  # (M, 6) innovations
    hist_Pm: np.ndarray  # (nh, N, N) predicted covariance
    hist_ref: np.ndarray  # (nh, REF_WIDTH) pre-update reference parameters
    hist_Pf: np.ndarray  # (nh, N) filtered variances
    nav_out: np.ndarray  # (10,) the final navigation state
    rw_st: np.ndarray  # (M,) the factor on R of each step (1: the model fits; a frozen outlier weight)
    qw_st: np.ndarray  # (M,) the factor on the accelerometer noise of each step (q_factor, times the jump of
    # bounded influence where the NIS passed nis_cap: kalman.robust_jump)
    qd_st: np.ndarray  # (M, nd, nd) the process noise Q_d each step's prediction added (its jump included; scaled)


class EncoderRows(NamedTuple):
    """The encoder attitude update of the gimbal states (empty arrays without them)."""

    enc: np.ndarray  # (M, 2) encoder angles at the end of each step (NaN: no rows that step)
    enc_var: float  # encoder white-noise variance [rad^2]
    enc_floor: float  # variance of the isotropic floor [rad^2]
    att_used: np.ndarray  # (M,) 1 where the rows were used
    Ka_st: np.ndarray  # (M, N, 3) gains
    Sia_st: np.ndarray  # (M, 3, 3) S^-1
    sza_st: np.ndarray  # (M, 3) S^-1 nu
    Ha_st: np.ndarray  # (M, 3, N) scaled H
    nisa_st: np.ndarray  # (M,) NIS
    za_st: np.ndarray  # (M, 3) raw residuals
    Ra_st: np.ndarray  # (M, 3, 3) R


@njit(cache=True)
def _pass_steps(inp, par, U, st, er, cr, k0, k1):
    """Filter steps ``k0 .. k1 - 1`` of one closed-loop pass over the record (see the package docstring;
    :func:`_pass_kernel` runs the whole pass in slices): inputs ``inp``
    (:class:`PassInputs`), parameters ``par`` (:class:`PassParams`, updated in place), the
    covariance's upper-triangular square root ``U`` (``P = U U^T``, scaled states, updated in place: the
    square-root filter of :func:`inscal.core.kalman.sr_predict`/``sr_update``), per-step outputs ``st`` (:class:`PassStore`) and
    the encoder rows ``er`` (:class:`EncoderRows`).

    ``nav0`` = [q(4), v(3), lat, lon, h]; ``site`` = [lat0, lon0, h0(, g_scale)] (g_scale: site
    gravity model / WGS-84 normal gravity, 1 when absent); parameter arrays are
    updated in place by the feedback.  ``sig``: state scaling (the filter works on x / sig).
    Stores per step the smoother data; every ``hist_every`` steps the predicted covariance
    and the pre-update reference parameters.  ``cr`` (:data:`_CARRY`): what step ``k0 - 1`` handed on
    (set from ``nav0`` and the first sample when ``k0 == 0``), overwritten with what step ``k1 - 1``
    hands on; ``nav_out`` receives the navigation state after step ``k1 - 1``.  Every step does the
    same arithmetic whatever the slicing (tests/calibrate/test_kernel_slices.py).

    Gimbal states: ``gim = [dth, alpha0, beta0, gamma0]`` (updated in place by the feedback);
    ``enc`` (M, 2) the encoder angles at the end of each step (NaN: no attitude rows that step; shape
    (0, 2) without gimbal states), ``enc_var``/``enc_floor`` the encoder and floor variances; the
    attitude update's ``K``, ``S^-1``, ``S^-1 nu``, scaled ``H``, NIS, raw ``z`` and ``R`` are stored per
    step (``att_used[k] = 1`` where it ran).
    """
    dth, dv, dt, n_per, nav0, site, nl, est_tau, kinds, axes, js, sig, qg, qa, r, hist_every, nis_cap, qf, rf, tdT, trate, \
        gm_sensor, gm_axis, gm_col, gm_phi, gm_scale, gm_q, sigp = inp
    Ag, bg_const, G, Aa, ba_const, K2, Kx, lev, tau, gim, th, gmx, levt = par
    lt = bool(np.any(levt != 0.0) or np.any(kinds == K_LEVT))  # the lever-arm timing's rates are needed
    sd = np.zeros(3)
    ngm = gmx.shape[0]
    nd = 9 + ngm  # the dynamic states: navigation and Gauss-Markov biases (gm_states); the parameters follow
    bg = bg_const.copy()  # the biases the compensation subtracts: the constants plus the GM estimates
    ba = ba_const.copy()
    effective_biases(bg_const, ba_const, gmx, gm_sensor, gm_axis, bg, ba)
    thermal = tdT.shape[0] > 0
    K_st, Si_st, sz_st, phinn_st, phinp_st, nis_st, z_st, hist_Pm, hist_ref, hist_Pf, nav_out, rw_st, qw_st, qd_st = st
    enc, enc_var, enc_floor, att_used, Ka_st, Sia_st, sza_st, Ha_st, nisa_st, za_st, Ra_st = er
    N = sig.shape[0]
    npar = N - nd
    M = dth.shape[0] // n_per
    T = n_per * dt
    lat0, lon0, h0 = site[0], site[1], site[2]
    g_scale = site[3] if site.shape[0] > 3 else 1.0
    ug = np.empty(3)
    ua = np.empty(3)
    w = np.empty(3)
    f = np.empty(3)
    fdot = np.empty(3)
    ugn = np.empty(3)  # the next sample's u_g, u_a (with this step's parameters)
    uan = np.empty(3)
    f0m = np.empty(3)  # linear-compensated specific force / rate of the previous, this, next sample
    f0c = np.empty(3)
    f0n = np.empty(3)
    wlm = np.empty(3)
    wlc = np.empty(3)
    wln = np.empty(3)
    wd = np.zeros(3)
    idt = 1.0 / dt
    eg = np.zeros(3)  # thermal states: the base biases of the sensor axes, A^-1 b (after each feedback)
    ea = np.zeros(3)
    if thermal:
        base_bias(Ag, bg, eg)
        base_bias(Aa, ba, ea)
    if k0 == 0:  # the start of the pass
        cr[:] = 0.0
        cr[_C_NAV:_C_NAV + 10] = nav0
        if M > 0:
            if thermal:
                thermal_linear(Aa, dv[0], idt, ea, th, 6, tdT[0], trate[0], ua)
                thermal_linear(Ag, dth[0], idt, eg, th, 0, tdT[0], trate[0], ug)
            else:
                linear(Aa, dv[0], idt, ua)
                linear(Ag, dth[0], idt, ug)
            for i in range(3):
                f0c[i] = ua[i] - ba[i]
                wlc[i] = ug[i] - bg[i]
            cr[_C_F0M:_C_F0M + 3] = f0c
            cr[_C_F0C:_C_F0C + 3] = f0c
            cr[_C_WLM:_C_WLM + 3] = wlc
            cr[_C_WLC:_C_WLC + 3] = wlc
    q0, q1, q2, q3 = cr[_C_NAV], cr[_C_NAV + 1], cr[_C_NAV + 2], cr[_C_NAV + 3]
    ve, vn, vu = cr[_C_NAV + 4], cr[_C_NAV + 5], cr[_C_NAV + 6]
    lat, lon, h = cr[_C_NAV + 7], cr[_C_NAV + 8], cr[_C_NAV + 9]
    f0m[:] = cr[_C_F0M:_C_F0M + 3]
    f0c[:] = cr[_C_F0C:_C_F0C + 3]
    wlm[:] = cr[_C_WLM:_C_WLM + 3]
    wlc[:] = cr[_C_WLC:_C_WLC + 3]
    p0, p1, p2 = cr[_C_PA], cr[_C_PA + 1], cr[_C_PA + 2]
    u0, u1, u2 = cr[_C_PV], cr[_C_PV + 1], cr[_C_PV + 2]
    have_prev = cr[_C_HAVE] != 0.0
    start, src, col_sum, col_row, tau_pairs, lev9 = column_layout(kinds, axes, js, est_tau)
    Wm = moment_weights(n_per, dt)
    Cb = np.empty((9, n_per))  # the step's C_m^n and column values by sample (jacobian module docstring)
    Bb = np.empty((N_BASIS, n_per))
    CW = np.empty((3, 9, n_per))
    R = np.empty((src.shape[0], 3, 3))
    F = np.zeros((9, 9))
    F2 = np.empty((9, 9))
    Qd = np.empty((9, 9))
    fn = np.zeros(3)
    K = np.empty((N, 6))
    Si = np.empty((6, 6))
    xs = np.empty(N)
    z = np.empty(6)
    rs = np.empty(6)
    rsk = np.empty(6)
    Ft = np.empty((N, 6))
    Qa = np.empty((9, 9))
    F2s = np.empty((9, 9))
    phs = np.empty((9, 9))
    I9 = np.eye(9)
    Z9 = np.zeros((9, N - 9))
    phn9 = np.empty((9, 9))  # with GM states: the navigation's Phi_nn, Phi_np and Qd before the assembly
    php9 = np.empty((9, npar))
    Qd9 = np.empty((9, 9))
    Qdg = np.empty((nd, nd))
    gphis = np.exp(np.log(gm_phi) / n_per)  # exp(-dt / tc)
    nis0 = 0.0
    for a in range(6):
        rs[a] = r[a] / sig[3 + a] ** 2
    have_enc = enc.shape[0] > 0
    Cp = np.empty((3, 3))
    Ce = np.empty((3, 3))
    ga = np.empty(3)
    gc = np.empty(3)
    Hg = np.empty((3, 4))
    Ha = np.zeros((3, N))
    Ra = np.empty((3, 3))
    Ka = np.empty((N, 3))
    Sia = np.empty((3, 3))
    za = np.empty(3)
    nu = np.empty(3)
    xa = np.empty(N)
    qgm = (qg[0] + qg[1] + qg[2]) / 3.0
    qam = (qa[0] + qa[1] + qa[2]) / 3.0
    ih = stored_before(k0, M, hist_every)
    for k in range(k0, k1):
        fn[0] = 0.0
        fn[1] = 0.0
        fn[2] = 0.0
        s0 = k * n_per
        if thermal:
            thermal_linear(Ag, dth[s0], idt, eg, th, 0, tdT[s0], trate[s0], ug)
            thermal_linear(Aa, dv[s0], idt, ea, th, 6, tdT[s0], trate[s0], ua)
        else:
            linear(Ag, dth[s0], idt, ug)  # the step's first sample, with the parameters after the feedback
            linear(Aa, dv[s0], idt, ua)
        for jj in range(n_per):
            s = k * n_per + jj
            if s + 1 < dth.shape[0]:
                if thermal:
                    thermal_linear(Aa, dv[s + 1], idt, ea, th, 6, tdT[s + 1], trate[s + 1], uan)
                    thermal_linear(Ag, dth[s + 1], idt, eg, th, 0, tdT[s + 1], trate[s + 1], ugn)
                else:
                    linear(Aa, dv[s + 1], idt, uan)
                    linear(Ag, dth[s + 1], idt, ugn)
                for i in range(3):
                    f0n[i] = uan[i] - ba[i]
                    wln[i] = ugn[i] - bg[i]
            else:
                f0n[:] = f0c
                wln[:] = wlc
            compensate_sample(ug, ua, bg, G, ba, K2, Kx, lev, tau[0], nl, idt, f0m, f0n, wlm, wln, w, f, fdot, wd,
                              levt, lt, sd)
            if ngm > 0:  # the AR(1) mean of each GM estimate, sample by sample (gm_states)
                for g in range(ngm):
                    gmx[g] *= gphis[g]
                effective_biases(bg_const, ba_const, gmx, gm_sensor, gm_axis, bg, ba)
            f0m[:] = f0c
            f0c[:] = f0n
            wlm[:] = wlc
            wlc[:] = wln
            a0, a1, a2 = w[0] * dt, w[1] * dt, w[2] * dt
            b0, b1, b2 = f[0] * dt, f[1] * dt, f[2] * dt
            r0, r1, r2, c0, c1, c2 = two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, have_prev)
            nve, nvn, nvu, sl, cl, rmh, rnh, wie_n, wie_u = velocity_step(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu,
                                                                            lat, h, dt, g_scale)
            # attitude with the midpoint transport rate
            mve = 0.5 * (ve + nve)
            mvn = 0.5 * (vn + nvn)
            oq0, oq1, oq2, oq3 = q0, q1, q2, q3
            q0, q1, q2, q3 = attitude_step(q0, q1, q2, q3, r0, r1, r2, -mvn / rmh * dt, (wie_n + mve / rnh) * dt,
                                            (wie_u + mve * sl / (cl * rnh)) * dt)
            lat += 0.5 * (vn + nvn) / rmh * dt
            lon += 0.5 * (ve + nve) / (rnh * cl) * dt
            h += 0.5 * (vu + nvu) * dt
            ve, vn, vu = nve, nvn, nvu
            p0, p1, p2 = a0, a1, a2
            u0, u1, u2 = b0, b1, b2
            have_prev = True
            # ---- Jacobian accumulation with the mid-sample attitude (jacobian module docstring)
            m0, m1, m2, m3 = oq0 + q0, oq1 + q1, oq2 + q2, oq3 + q3
            mn = 1.0 / math.sqrt(m0 * m0 + m1 * m1 + m2 * m2 + m3 * m3)
            m0 *= mn
            m1 *= mn
            m2 *= mn
            m3 *= mn
            # C_m^n of the unit quaternion (the columns qrot gives for e_x, e_y, e_z), by rows
            Cb[0, jj] = 1.0 - 2.0 * (m2 * m2 + m3 * m3)
            Cb[1, jj] = 2.0 * (m1 * m2 - m0 * m3)
            Cb[2, jj] = 2.0 * (m1 * m3 + m0 * m2)
            Cb[3, jj] = 2.0 * (m1 * m2 + m0 * m3)
            Cb[4, jj] = 1.0 - 2.0 * (m1 * m1 + m3 * m3)
            Cb[5, jj] = 2.0 * (m2 * m3 - m0 * m1)
            Cb[6, jj] = 2.0 * (m1 * m3 - m0 * m2)
            Cb[7, jj] = 2.0 * (m2 * m3 + m0 * m1)
            Cb[8, jj] = 1.0 - 2.0 * (m1 * m1 + m2 * m2)
            fn[0] += (Cb[0, jj] * f[0] + Cb[1, jj] * f[1] + Cb[2, jj] * f[2]) * dt
            fn[1] += (Cb[3, jj] * f[0] + Cb[4, jj] * f[1] + Cb[5, jj] * f[2]) * dt
            fn[2] += (Cb[6, jj] * f[0] + Cb[7, jj] * f[1] + Cb[8, jj] * f[2]) * dt
            basis_values(ug, ua, w, f, wd, fdot, Bb, jj, lev9, sd, lt)
            if thermal:
                thermal_basis(ug, ua, bg, ba, tdT[s], trate[s], Bb, jj)
            ug[:] = ugn
            ua[:] = uan
        # ---- discretisation (package docstring; jacobian module)
        fn[0] /= T
        fn[1] /= T
        fn[2] /= T
        nav_F(lat0, h0, fn, F, g_scale)
        phinn = phinn_st[k]
        phinp = phinp_st[k]
        if ngm == 0:
            discretise(F, T, qgm, qam * qf[k], sig, F2, phinn, Qd)  # qf: the velocity model-error term (driver)
            step_moments(Cb, Bb, Wm, start, src, CW, R)
            parameter_columns(R, col_sum, col_row, tau_pairs, F, F2, sig, phinp)
            filters.sr_predict(U, 9, phinn, phinp, Qd)
            qd_st[k] = Qd
        else:  # the GM states' rows and columns (gm_states module docstring)
            discretise(F, T, qgm, qam * qf[k], sig, F2, phn9, Qd9)
            step_moments(Cb, Bb, Wm, start, src, CW, R)
            parameter_columns(R, col_sum, col_row, tau_pairs, F, F2, sigp, php9)
            assemble(phn9, Qd9, php9, gm_col, gm_phi, gm_scale, gm_q, phinn, phinp, Qdg)
            filters.sr_predict(U, nd, phinn, phinp, Qdg)
            qd_st[k] = Qdg
        # ---- measurement: zero velocity, known position
        rm0, rn0 = earth.radii(lat0)
        z[0], z[1], z[2] = ve, vn, vu
        z[3] = (lon - lon0) * (rn0 + h0) * math.cos(lat0)
        z[4] = (lat - lat0) * (rm0 + h0)
        z[5] = h - h0
        for a in range(6):
            z_st[k, a] = z[a]
            z[a] /= sig[3 + a]
        if k % hist_every == 0 or k == M - 1:
            if thermal:  # a compiled loop: BLAS would thread this N^3 product from N = 65 (idle threads spin)
                filters.upper_outer(U, hist_Pm[ih])
            else:
                hist_Pm[ih] = U @ U.T
            hist_ref[ih, _AG0:_AG1] = Ag.ravel()
            hist_ref[ih, _BG0:_BG1] = bg_const
            hist_ref[ih, _G0:_G1] = G.ravel()
            hist_ref[ih, _AA0:_AA1] = Aa.ravel()
            hist_ref[ih, _BA0:_BA1] = ba_const
            hist_ref[ih, _K20:_K21] = K2
            hist_ref[ih, _KX0:_KX1] = Kx.ravel()
            hist_ref[ih, _LV0:_LV1] = lev.ravel()
            hist_ref[ih, _TAU0] = tau[0]
            hist_ref[ih, _GIM0:_GIM1] = gim
            hist_ref[ih, _TH0:_TH1] = th.ravel()
            hist_ref[ih, _LT0:_LT1] = levt
        for a in range(6):
            rsk[a] = rs[a] * rf[k]  # a frozen outlier weight of the driver's robust scheme (1: none)
        jump = 1.0
        if nis_cap < np.inf:
            # bounded influence as a velocity jump (kalman.robust_jump): a step the model cannot fit (a misfit
            # during moves, an outlier) has its accelerometer noise raised until its NIS equals nis_cap, so the
            # velocity takes the misfit up instead of the constants, and the next step starts clean
            for a in range(6):
                for j in range(N):
                    Ft[j, a] = U[3 + a, j]
            Sm = Ft.T @ Ft
            for a in range(6):
                Sm[a, a] += rsk[a]
            nis0 = z @ np.linalg.solve(Sm, z)
            if nis0 > nis_cap:
                discretise(F, T, 0.0, qam * qf[k], sig, F2s, phs, Qa)
                jump = filters.robust_jump(Sm, np.ascontiguousarray(Qa[3:9, 3:9]), z, nis_cap)
                if jump > 1.0:
                    for i in range(9):
                        for j in range(9):
                            Qa[i, j] *= jump - 1.0
                    # with GM states the identity transition of the navigation block keeps them and the parameters
                    filters.sr_predict(U, 9, I9, Z9, Qa)
                    qd_st[k, :9, :9] += Qa
                    if k % hist_every == 0 or k == M - 1:  # the smoother's predicted covariance has the jump
                        if thermal:
                            filters.upper_outer(U, hist_Pm[ih])
                        else:
                            hist_Pm[ih] = U @ U.T
        nis_k, _ = filters.sr_update(U, IDX_MEAS, rsk, z, K, Si, xs, np.inf)
        nis_st[k] = nis0 if jump > 1.0 else nis_k  # the NIS of the nominal model
        rw_st[k] = rf[k]
        qw_st[k] = qf[k] * jump
        K_st[k] = K
        Si_st[k] = Si
        for a in range(6):
            v = 0.0
            for b in range(6):
                v += Si[a, b] * z[b]
            sz_st[k, a] = v
        if have_enc and enc[k, 0] == enc[k, 0] and enc[k, 1] == enc[k, 1]:
            # ---- encoder attitude rows (module docstring): z = vee(C_nav C_pred^T) ~ phi - psi
            gimbal_attitude(gim, enc[k, 0], enc[k, 1], Cp, ga, gc, Hg)
            e0, e1, e2 = qrot(q0, q1, q2, q3, 1.0, 0.0, 0.0)
            Ce[0, 0], Ce[1, 0], Ce[2, 0] = e0, e1, e2
            e0, e1, e2 = qrot(q0, q1, q2, q3, 0.0, 1.0, 0.0)
            Ce[0, 1], Ce[1, 1], Ce[2, 1] = e0, e1, e2
            e0, e1, e2 = qrot(q0, q1, q2, q3, 0.0, 0.0, 1.0)
            Ce[0, 2], Ce[1, 2], Ce[2, 2] = e0, e1, e2
            Em = Ce @ Cp.T
            za[0] = 0.5 * (Em[2, 1] - Em[1, 2])
            za[1] = 0.5 * (Em[0, 2] - Em[2, 0])
            za[2] = 0.5 * (Em[1, 0] - Em[0, 1])
            for i in range(3):
                for j in range(N):
                    Ha[i, j] = 0.0
                Ha[i, i] = sig[i]
            for c in range(npar):
                if kinds[c] == K_GIM:
                    for i in range(3):
                        Ha[i, nd + c] = -Hg[i, js[c]] * sig[nd + c]
            for i in range(3):
                for j in range(3):
                    Ra[i, j] = enc_var * (ga[i] * ga[j] + gc[i] * gc[j])
                Ra[i, i] += enc_floor
            # sequential update: innovation against the pending velocity/position estimate xs (scaled)
            for i in range(3):
                s_ = za[i]
                for j in range(N):
                    s_ -= Ha[i, j] * xs[j]
                nu[i] = s_
            nisa_st[k] = filters.sr_update_dense(U, Ha, Ra, nu, Ka, Sia, xa)
            for i in range(N):
                xs[i] += xa[i]
            Ka_st[k] = Ka
            Sia_st[k] = Sia
            sza_st[k] = Sia @ nu
            Ha_st[k] = Ha
            za_st[k] = za
            Ra_st[k] = Ra
            att_used[k] = 1
        if k % hist_every == 0 or k == M - 1:
            for i in range(N):
                hist_Pf[ih, i] = U[i, :] @ U[i, :]
            ih += 1
        # ---- feedback (S16 eq. 27)
        for i in range(N):
            xs[i] *= sig[i]
        e0, e1, e2, e3 = quat_from_rotvec_xyz(-xs[0], -xs[1], -xs[2])
        q0, q1, q2, q3 = qmul(e0, e1, e2, e3, q0, q1, q2, q3)
        ve -= xs[3]
        vn -= xs[4]
        vu -= xs[5]
        lon -= xs[6] / ((rn0 + h0) * math.cos(lat0))
        lat -= xs[7] / (rm0 + h0)
        h -= xs[8]
        feedback_params(xs, kinds, axes, js, Ag, bg_const, G, Aa, ba_const, K2, Kx, lev, tau, gim, th, levt, nd)
        for g in range(ngm):
            gmx[g] -= xs[9 + g]
        effective_biases(bg_const, ba_const, gmx, gm_sensor, gm_axis, bg, ba)
        if thermal:
            base_bias(Ag, bg, eg)
            base_bias(Aa, ba, ea)
    nav_out[0], nav_out[1], nav_out[2], nav_out[3] = q0, q1, q2, q3
    nav_out[4], nav_out[5], nav_out[6] = ve, vn, vu
    nav_out[7], nav_out[8], nav_out[9] = lat, lon, h
    cr[_C_NAV:_C_NAV + 10] = nav_out
    cr[_C_F0M:_C_F0M + 3] = f0m
    cr[_C_F0C:_C_F0C + 3] = f0c
    cr[_C_WLM:_C_WLM + 3] = wlm
    cr[_C_WLC:_C_WLC + 3] = wlc
    cr[_C_PA], cr[_C_PA + 1], cr[_C_PA + 2] = p0, p1, p2
    cr[_C_PV], cr[_C_PV + 1], cr[_C_PV + 2] = u0, u1, u2
    cr[_C_HAVE] = 1.0 if have_prev else 0.0


def _first_slice(n_per: int) -> int:
    """The first slice of a pass [steps]: about 30 ms at ~1.5 us per sample and ~0.1 ms per step's update."""
    return max(1, 30_000 // (n_per + 60))


def _pass_kernel(inp: PassInputs, par: PassParams, U: np.ndarray, st: PassStore, er: EncoderRows) -> int:
    """One closed-loop filter pass over the record (:func:`_pass_steps`), in slices of steps so that an
    interrupt is honoured between two (:func:`inscal.core.slices.run_in_slices`): what one step hands
    the next lives in ``U``, ``par``, the stores and a carry array owned here.  Returns the number of
    steps."""
    M = inp.dth.shape[0] // inp.n_per
    cr = np.empty(_CARRY)
    if M == 0:  # no step: the navigation state is the start
        _pass_steps(inp, par, U, st, er, cr, 0, 0)
    run_in_slices(M, lambda k0, k1: _pass_steps(inp, par, U, st, er, cr, k0, k1), first=_first_slice(inp.n_per))
    return M


@dataclass
class PassOutput:
    params: CompParams
    P0s: np.ndarray  # smoothed covariance at the start (scaled)
    x0s: np.ndarray  # smoothed error at the start (scaled)
    nis: np.ndarray
    z: np.ndarray
    steps: int
    hist_step: np.ndarray
    hist_ref: np.ndarray
    hist_x: np.ndarray
    hist_P: np.ndarray
    hist_Pm: np.ndarray
    Pf: np.ndarray | None = None  # filtered covariance after the last update (scaled)
    phinn: np.ndarray | None = None
    phinp: np.ndarray | None = None
    att_used: np.ndarray | None = None  # per step: 1 where the encoder attitude rows were used
    nis_att: np.ndarray | None = None  # their NIS (3 dof; NaN where unused)
    z_att: np.ndarray | None = None  # their raw residual vee(C_nav C_pred^T) [rad] (NaN where unused)
    # with keep_phi: the encoder rows' H (M, 3, N; scaled states, as Phi) and R (M, 3, 3; rad^2) per step,
    # for an observability matrix with the encoder rows (whitened by R^-1/2; zero where att_used is 0)
    H_att: np.ndarray | None = None
    R_att: np.ndarray | None = None
    smoother: SmootherData | None = None  # the stored data of the forward pass (run_pass sets it)
    r_factor: np.ndarray | None = None  # (M,) factor on R per step (frozen outlier weights; 1 elsewhere)
    q_used: np.ndarray | None = None  # (M,) factor on the accelerometer noise per step (model-error term and jumps)
    Uf: np.ndarray | None = None  # upper-triangular square root of Pf (Pf = Uf Uf^T; scaled)

    def without_stores(self) -> PassOutput:
        """A copy without the per-step stores of the smoother (its data, Phi, the encoder rows' H and R): a few
        numbers per step and the history rows stay (:func:`pass_bytes` with ``stores=False``)."""
        return replace(self, smoother=None, phinn=None, phinp=None, H_att=None, R_att=None)


def history_rows(M: int, hist_every: int) -> int:
    """The stored steps of a pass of ``M`` steps: every ``hist_every``-th and the last."""
    return (M - 1) // hist_every + 1 + (1 if (M - 1) % hist_every else 0) if M > 0 else 0


def pass_bytes(M: float, states: StateSet, hist_every: int = 1, stores: bool = True) -> float:
    """Memory [bytes] one pass (:func:`run_pass`, then :func:`smooth_pass`) keeps over ``M`` filter steps
    (``M`` may be a float: an estimate before the record is read).  Per step: the NIS, the innovation and
    the factor on R (8 floats) and, for the smoother (``stores``; :meth:`PassOutput.without_stores` drops
    them), the gains, ``S^-1``, ``S^-1 nu``, ``Phi_nn``, ``Phi_np`` and ``Q_d`` (15 N + 123 floats: 15 N + 131 in
    all, 7.1 kB with 51 states).  With gimbal states the encoder angles, rows' NIS and residual (6 floats and a
    flag) and their gains, ``S^-1``, ``S^-1 nu``, H and R (``stores``: 6 N + 21 floats).  Per stored step
    (every ``hist_every``-th and the last): the predicted and smoothed covariances, the filtered variances,
    the smoothed state and the reference parameters (2 N^2 + 2 N + REF_WIDTH floats).  ``Q_d`` (n_dyn^2 floats) is
    what the square-root information smoother needs besides ``Phi``."""
    N = states.n_states
    nd = states.n_dyn
    per_step = 8.0 * (8 + ((6 + nd) * N + 42 + nd * nd if stores else 0))  # 15 N + 123 without GM states
    if states.gimbal:
        per_step += 8.0 * (6 + (6 * N + 21 if stores else 0)) + 1.0
    rows = float(M) / max(1, int(hist_every)) + 2.0
    return per_step * float(M) + rows * 8.0 * (2 * N * N + 2 * N + REF_WIDTH)


def run_pass(dth, dv, dt, n_per, C0, site, params: CompParams, states: StateSet, sig, qg, qa, r, hist_every,
             keep_phi: bool = False, smooth: bool = True, enc=None, enc_sigma: float = ENCODER_SIGMA,
             nis_cap: float = np.inf, temperature=None, q_factor=None, r_factor=None) -> PassOutput:
    """One forward filter pass and its smoother (compiled kernels).  ``smooth=False`` runs only
    the adjoint recursion for the smoothed states, at the start and the stored steps (:func:`smooth_pass` adds
    their covariances).
    ``nis_cap``: bounded influence as a velocity jump (:func:`inscal.core.kalman.robust_jump`; inf: plain updates).
    ``q_factor`` (M,): a factor >= 1 on the accelerometer white-noise PSD of each step (the velocity model-error
    term of the driver's robust scheme; None: 1 everywhere, the plain noise model); ``r_factor`` (M,): a factor
    >= 1 on R of each step (frozen outlier weights; None: 1).  The stored NIS and ``S^-1`` are those of the
    weighted update; the output has the factors each step ran with (``r_factor`` on R, ``q_used`` on the
    accelerometer noise, the jumps of ``nis_cap`` included).
    Gimbal states: ``enc`` (>= M, 2) the encoder angles [outer, inner] at the end of each filter step
    (NaN rows: none), ``enc_sigma`` their white noise [rad] (module docstring).  Thermal states:
    ``temperature = (dT, rate)``, ``T - T_ref`` [degC] and dT/dt [degC/s] of every sample."""
    N = states.n_states
    nd = states.n_dyn
    npar = N - nd
    M = dth.shape[0] // n_per
    if M < 2:
        raise CalibrationError(f"record too short for the filter: {dth.shape[0] * dt:g} s at a {n_per * dt:g} s step")
    nh = history_rows(M, hist_every)
    p = params.copy()
    kinds, axes, js = states.columns()
    q = quat_from_dcm(C0)
    nav0 = np.concatenate([q / np.linalg.norm(q), np.zeros(3), [site[0], site[1], site[2]]])
    U = np.eye(N)
    K_st = np.empty((M, N, 6))
    Si_st = np.empty((M, 6, 6))
    sz_st = np.empty((M, 6))
    phinn_st = np.empty((M, nd, nd))
    phinp_st = np.empty((M, nd, npar))
    nis = np.empty(M)
    z_st = np.empty((M, 6))
    hist_Pm = np.empty((nh, N, N))
    hist_ref = np.empty((nh, REF_WIDTH))
    hist_Pf = np.empty((nh, N))
    nav_out = np.empty(10)
    if states.gimbal:
        if enc is None or np.shape(enc)[0] < M or np.shape(enc)[1:] != (2,):
            raise CalibrationError("the gimbal states need the encoder angles at every filter step")
        enc_a = np.ascontiguousarray(np.asarray(enc, float)[:M])
    else:
        enc_a = np.empty((0, 2))
    Ma = enc_a.shape[0]
    att_used = np.zeros(Ma, np.int8)
    Ka_st, Sia_st, sza_st = np.zeros((Ma, N, 3)), np.zeros((Ma, 3, 3)), np.zeros((Ma, 3))
    Ha_st, nisa_st, za_st = np.zeros((Ma, 3, N)), np.full(Ma, np.nan), np.full((Ma, 3), np.nan)
    Ra_st = np.zeros((Ma, 3, 3))
    nl = bool(states.extended or np.any(p.K2) or np.any(p.Kx) or np.any(p.lever) or np.any(p.G))
    tdT, trate = _temperature_inputs(states, temperature, dth.shape[0])
    inp = PassInputs(np.ascontiguousarray(dth, dtype=float), np.ascontiguousarray(dv, dtype=float), float(dt),
                     int(n_per), nav0, np.asarray(site, float), nl, bool(states.asynchrony), kinds, axes, js, sig, qg,
                     qa, r, int(hist_every), float(nis_cap), _step_factors(q_factor, M), _step_factors(r_factor, M), tdT, trate,
                     *_gm_inputs(states, sig, n_per * dt))
    par = PassParams(p.Ag, p.bg, p.G, p.Aa, p.ba, p.K2, p.Kx, p.lever, p.tau, p.gim, p.th, np.zeros(len(states.gm)),
                     p.levt)
    rw = np.ones(M)
    qw = np.ones(M)
    qd_st = np.empty((M, nd, nd))
    st = PassStore(K_st, Si_st, sz_st, phinn_st, phinp_st, nis, z_st, hist_Pm, hist_ref, hist_Pf, nav_out, rw, qw, qd_st)
    er = EncoderRows(enc_a, float(enc_sigma) ** 2, (0.1 * float(enc_sigma)) ** 2, att_used, Ka_st, Sia_st, sza_st,
                     Ha_st, nisa_st, za_st, Ra_st)
    Mk = _pass_kernel(inp, par, U, st, er)
    x0 = np.empty(N)
    hist_x = np.empty((nh, N))
    smooth_vector_kernel(K_st, Si_st, sz_st, phinn_st, phinp_st, int(hist_every), Mk, hist_Pm, hist_x, x0, att_used,
                          Ka_st, Sia_st, sza_st, Ha_st)
    steps = np.array(sorted(set(range(0, Mk, hist_every)) | {Mk - 1}))
    out = PassOutput(p, None, x0, nis, z_st, Mk, steps, hist_ref, hist_x, None, hist_Pm, U @ U.T)
    out.Uf = U
    out.r_factor = rw
    out.q_used = qw
    out.smoother = SmootherData(K_st, Si_st, sz_st, phinn_st, phinp_st, int(hist_every), att_used, Ka_st, Sia_st,
                                sza_st, Ha_st, er.enc_floor, qd_st, np.asarray(r, float) / sig[3:9] ** 2, rw, Ra_st)
    out.att_used, out.nis_att, out.z_att = att_used, nisa_st, za_st
    if keep_phi and Ma:
        out.H_att, out.R_att = Ha_st, Ra_st
    if keep_phi:
        out.phinn, out.phinp = phinn_st, phinp_st
    if smooth:
        smooth_pass(out)
    return out


def _gm_inputs(states: StateSet, sig, T: float) -> tuple:
    """The Gauss-Markov fields of :class:`PassInputs` (empty arrays without GM states)."""
    g = gm_step_arrays(states, np.asarray(sig, float), T)
    return g["sensor"], g["axis"], g["col"], g["phi"], g["scale"], g["q"], np.ascontiguousarray(g["sigp"])


def _step_factors(q_factor, M: int) -> np.ndarray:
    """The per-step factors on the accelerometer noise of a pass of ``M`` steps (ones when None)."""
    if q_factor is None:
        return np.ones(M)
    qf = np.ascontiguousarray(q_factor, dtype=float)
    if qf.shape[0] < M or not np.all(qf[:M] >= 1.0):
        raise CalibrationError(f"model-error factors: {M} factors >= 1 needed, got shape {qf.shape}")
    return qf[:M].copy()


def _temperature_inputs(states: StateSet, temperature, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The per-sample ``(dT, rate)`` arrays of a pass (empty without thermal states; any temperature is then
    ignored, so a pass without them is the same arithmetic as before thermal states existed)."""
    if not states.thermal:
        return np.empty(0), np.empty(0)
    if temperature is None:
        raise CalibrationError("the thermal states need the temperature of every sample")
    dT, rate = (np.ascontiguousarray(a, dtype=float) for a in temperature)
    if dT.shape != (n,) or rate.shape != (n,):
        raise CalibrationError(f"thermal states: temperature arrays of shape {dT.shape} and {rate.shape}, expected ({n},)")
    return dT, rate


def smooth_pass(out: PassOutput) -> PassOutput:
    """Run the full smoother (states and covariances at the stored steps and at the start) on a
    pass's stored data, in place."""
    sm = out.smoother
    N = sm.K_st.shape[1]
    nd = sm.phinn_st.shape[1]
    nh = out.hist_Pm.shape[0]
    out.hist_x = np.empty((nh, N))
    out.hist_P = np.empty((nh, N, N))
    x0 = np.empty(N)
    out.P0s = np.empty((N, N))
    smooth_kernel(np.eye(N), sm, out.steps, out.hist_Pm, out.hist_x, out.hist_P, x0, out.P0s, out.Uf[nd:, nd:])
    out.x0s = x0
    return out


# ----------------------------------------------------------------------------- for tests
def one_step(dth, dv, dt, nav0, site, params: CompParams, states: StateSet, temperature=None, gm_start=None):
    """Propagate the navigation over the samples given (one filter step, no update) from the
    navigation state ``nav0 = [q(4), v(3), lat, lon, h]``; returns the final state (10) and the
    step's physical ``(Phi_nn, Phi_np)`` (with GM states ``Phi_nn`` is that of the dynamic states, navigation
    and GM).  For tests of the F blocks against finite differences of this same nonlinear propagation.
    ``temperature``: ``(dT, rate)`` per sample (thermal states); ``gm_start``: the GM bias estimates over the
    step (default zero)."""
    N = states.n_states
    n = dth.shape[0]
    p = params.copy()
    kinds, axes, js = states.columns()
    P = np.eye(N)
    one = lambda *shape: np.empty((1,) + shape)  # noqa: E731  (storage for the one step)
    out = np.empty(10)
    tdT, trate = _temperature_inputs(states, temperature, n)
    inp = PassInputs(np.ascontiguousarray(dth, float), np.ascontiguousarray(dv, float), float(dt), n,
                     np.asarray(nav0, float), np.asarray(site, float), True, bool(states.asynchrony), kinds, axes, js,
                     np.ones(N), np.zeros(3), np.zeros(3), np.full(6, 1e30), 1, np.inf, np.ones(1), np.ones(1), tdT, trate,
                     *_gm_inputs(states, np.ones(N), n * dt))
    par = PassParams(p.Ag, p.bg, p.G, p.Aa, p.ba, p.K2, p.Kx, p.lever, p.tau, p.gim, p.th,
                     np.zeros(len(states.gm)) if gm_start is None else np.array(gm_start, float), p.levt)
    nd = states.n_dyn
    st = PassStore(one(N, 6), one(6, 6), one(6), one(nd, nd), one(nd, N - nd), np.empty(1), one(6), one(N, N),
                   one(REF_WIDTH), one(N), out, np.ones(1), np.ones(1), one(nd, nd))
    er = EncoderRows(np.empty((0, 2)), 0.0, 0.0, np.zeros(0, np.int8), np.empty((0, N, 3)), np.empty((0, 3, 3)),
                     np.empty((0, 3)), np.empty((0, 3, N)), np.empty(0), np.empty((0, 3)), np.empty((0, 3, 3)))
    _pass_kernel(inp, par, P, st, er)
    return out, st.phinn_st[0], st.phinp_st[0]
