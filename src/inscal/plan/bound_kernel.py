"""The compiled covariance-only pass of the Cramér-Rao bound (:mod:`inscal.plan.bound`): per filter step the
parameter columns of ``Phi_np`` from the path kinematics (one evaluation on a dwell, mid-point sub-samples
with motion or with thermal states), the structured prediction and the zero-velocity / known-position
update (the covariance-only forms of :mod:`inscal.core.kalman`), in the scaled state.

Thermal states (the systematic filter's option ``thermal``): their columns are the base columns times a
known scalar of the sample (``-dT^k``, ``-(w or f)_i dT^k``, ``-dT/dt``;
:func:`inscal.calibrate.systematic.dynamics.thermal_values`), ``dT`` and ``dT/dt`` given per sub-sample
(the temperature profile at the sub-sample times).  They change along a dwell while the temperature
moves, so with thermal states every step takes the sub-sample moments.

Sensitivity to the site and clock (a consider analysis, :mod:`inscal.plan.consider`).  Inputs the filter takes as
exact enter the true navigation error through constant columns ``Vc`` (6, m) in the navigation frame, in the rows
where a parameter column acts (``[dphi'; dv']``); the filter, which does not know them, carries the error
``e = x^ - x`` with ``E = de/ds``::

    E^- = Phi E - Gamma,   Gamma = G6 Vc = int_0^T Phi_nn(T - t) [Vc; 0] dt
    E^+ = (I - K H) E^-                          (the gain K of the covariance update)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from inscal.calibrate.systematic.dynamics import column_values, lever_timing_rate, thermal_values
from inscal.calibrate.systematic.states import K_LEVT, K_TH, TH_RATE_ROW
from inscal.core.kalman import predict_into, predict_params, update_block, update_row
from inscal.core.kinematics import (  # segment_at: smallest s with seg_t1[s] > t
    kinematics,
    segment_at,
)


@njit(cache=True)
def is_static(s, seg_w0, seg_acc):
    """Whether segment ``s`` of the path holds both gimbal axes still: zero rate and zero angular acceleration."""
    return seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0



@njit(cache=True)
def triad_row(kind, j):
    """First row of a column's block in ``V``: 0 for the gyro kinds (phi rows), 3 for the accelerometer kinds
    (dv rows); a thermal column by its thermal row ``j`` (gyro bias, gyro scale factor, the dT/dt term: 0)."""
    if kind == K_TH:
        return 0 if (j < 6 or j == TH_RATE_ROW) else 3
    return 0 if kind <= 2 else 3


@njit(cache=True)
def step_columns(t, path, need_rates, kinds, axes, js, C, w, f, wd, fd, vals, V, thermal, dT, rate, lev, sd):
    """The parameter columns of ``[dphi'; dv']`` at ``t``: ``V`` (6, p) = ``C[:, axis] * value``
    (rows 0-2 gyro kinds, 3-5 accelerometer kinds; the asynchrony column is ``C fdot``); with ``thermal`` the
    thermal columns at the temperature difference ``dT`` [degC] and rate ``rate`` [degC/s] (module docstring);
    the lever-arm timing's column of accelerometer i is ``C[:, i] sd_i`` (``lever_timing_rate`` at the nominal
    lever arms ``lev``, w-ddot a centred second difference; ``sd`` (3) scratch).
    ``path``: the tuple ``(seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g)`` of :func:`bound_kernel`."""
    seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g = path
    s = segment_at(t, seg_t1)
    kinematics(t, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, C, w, f)
    if need_rates:  # centred differences (the filter's own w-dot and f-dot are centred differences too)
        h = 1e-3
        Ct = np.empty((3, 3))
        wp = np.empty(3)
        fp = np.empty(3)
        wm = np.empty(3)
        fm = np.empty(3)
        sp = segment_at(t + h, seg_t1)
        kinematics(t + h, sp, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, Ct, wp, fp)
        sm = segment_at(t - h, seg_t1)
        kinematics(t - h, sm, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, Ct, wm, fm)
        for i in range(3):
            wd[i] = (wp[i] - wm[i]) / (2 * h)
            fd[i] = (fp[i] - fm[i]) / (2 * h)
            wp[i] = (wp[i] - 2.0 * w[i] + wm[i]) / (h * h)  # w-ddot
    else:
        wp = np.zeros(3)
        for i in range(3):
            wd[i] = 0.0
            fd[i] = 0.0
    column_values(kinds, axes, js, w, f, w, f, wd, fd, vals)
    lever_timing_rate(lev, w, wd, wp, sd)
    if thermal:  # the ideal IMU: u_g - b_g = w, u_a - b_a = f
        thermal_values(kinds, axes, js, w, f, dT, rate, vals)
    p = kinds.shape[0]
    for c in range(p):
        k = kinds[c]
        rb = triad_row(k, js[c])
        for a in range(6):
            V[a, c] = 0.0
        if k == 9:
            for r in range(3):
                V[rb + r, c] = C[r, 0] * fd[0] + C[r, 1] * fd[1] + C[r, 2] * fd[2]
        elif k < 9 or k == K_TH:
            i = axes[c]
            for r in range(3):
                V[rb + r, c] = C[r, i] * vals[c]
        elif k == K_LEVT:
            i = axes[c]
            for r in range(3):
                V[3 + r, c] = C[r, i] * sd[i]
        # other kinds: states outside the navigation dynamics (e.g. gimbal geometry): zero columns


@njit(cache=True, fastmath=True, inline="always")
def g6_times(G6, X, out):
    """``out`` (9, p) = ``G6 X`` for the step's ``G6`` (9, 6) and ``X`` (6, p), the zeros of ``G6`` skipped."""
    for i in range(9):
        for c in range(X.shape[1]):
            out[i, c] = 0.0
        for r in range(6):
            gi = G6[i, r]
            if gi != 0.0:
                for c in range(X.shape[1]):
                    out[i, c] += gi * X[r, c]


# ----------------------------------------------------------------------------- the kernel
@njit(cache=True, fastmath=True)
def bound_kernel(k0, k1, T, n_sub, path, need_rates, kinds, axes, js, sig, phinn, F, F2, qd, rs, phi_p, q_p, xH, xr,
                 P, hist, last, phinp, Vs, th_dT, th_rate, Vc, E, lev):
    """Covariance-only pass (module docstring) in the scaled state over the filter steps ``k0 .. k1 - 1``
    (:mod:`inscal.plan.slices`); ``path`` the tuple ``(seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g)``
    (the :class:`~inscal.core.turntable.Segments` arrays, the outer axis, the mount attitude, the site's Earth
    rate and gravity); ``P`` (N, N) in/out, ``hist`` (k1 - k0, N) receives diag(P) after each
    update (``(0, N)``: not kept).  ``phinn``, ``F``, ``F2``, ``qd``: physical; ``phi_p``/``q_p``: scaled
    parameter transition (diagonal) and process noise; ``xH`` (k1 - k0, m, N) scaled extra rows, ``xr``
    (k1 - k0, m) their scaled variances.  Thermal states: ``th_dT``, ``th_rate`` (k1 - k0, n_sub) the
    temperature difference from T_ref [degC] and its rate [degC/s] at every sub-sample (``(0, n_sub)``: none;
    every step then takes the sub-sample moments).  Carried from one call to the next: ``last`` (1,) the dwell
    whose ``Phi_np`` is in ``phinp`` (9, p) (-1: none), and its scaled columns ``Vs`` (6, p).  Consider inputs
    (module docstring): ``Vc`` (6, m) their columns (SI), ``E`` (N, m) in/out the sensitivity of the error in the
    scaled state; ``m = 0``: none.  ``lev`` (3, 3): the nominal lever arms of the lever-arm timing's columns."""
    seg_t1, seg_w0, seg_acc = path[1], path[3], path[4]
    N = P.shape[0]
    p = N - 9
    C = np.empty((3, 3))
    w = np.empty(3)
    f = np.empty(3)
    wd = np.empty(3)
    fd = np.empty(3)
    sd = np.zeros(3)
    vals = np.empty(p)
    V = np.empty((6, p))
    M0 = np.empty((6, p))
    M1 = np.empty((6, p))
    M2 = np.empty((6, p))
    # scaled Phi_nn, Q_d, and G6 = T [I6; 0] + T^2/2 F[:, :6] + T^3/6 F^2[:, :6] (row-scaled): on a dwell
    # Phi_np = G6 V with V constant over the step
    Pn = np.empty((9, 9))
    Qs = np.empty((9, 9))
    G6 = np.empty((9, 6))
    for i in range(9):
        for j in range(9):
            Pn[i, j] = phinn[i, j] * sig[j] / sig[i]
            Qs[i, j] = qd[i, j] / (sig[i] * sig[j])
        for r in range(6):
            G6[i, r] = (F[i, r] * (T * T / 2.0) + F2[i, r] * (T * T * T / 6.0) + (T if i == r else 0.0)) / sig[i]
    rbase = np.empty(p, np.int64)  # first row of each column's non-zero block in V (0: gyro, 3: accelerometer)
    for c in range(p):
        rbase[c] = triad_row(kinds[c], js[c])
    thermal = th_dT.shape[0] > 0
    W = np.empty((6, p))  # Vs P_pp
    new_np = np.empty((9, p))
    t1 = np.empty((9, 9))
    new_nn = np.empty((9, 9))
    PHt = np.empty((6, N))
    S = np.empty((6, 6))
    K = np.empty((6, N))
    dyn_p = False
    for c in range(p):
        if phi_p[c] != 1.0 or q_p[c] != 0.0:
            dyn_p = True
    mx = xH.shape[1]
    ph = np.empty(N)
    kg = np.empty(N)
    h = T / n_sub
    last_seg = last[0]
    keep = hist.shape[0] > 0
    m_c = Vc.shape[1]
    gam = np.zeros((9, m_c))  # the step's Gamma (scaled rows): the same on every step (Vc is constant)
    for i in range(9):
        for c in range(m_c):
            for r in range(6):
                gam[i, c] += G6[i, r] * Vc[r, c]
    En = np.empty((9, m_c))
    Eh = np.empty((6, m_c))
    he = np.empty(m_c)
    for k in range(k0, k1):
        a = k * T
        b = a + T
        # ---- is the whole step on a dwell?
        s = segment_at(a + 1e-9 * T, seg_t1)
        s_first = s
        static = not thermal
        while static:
            if not is_static(s, seg_w0, seg_acc):
                static = False
                break
            if seg_t1[s] >= b or s == seg_t1.shape[0] - 1:
                break
            s += 1
        if static:
            if s_first != last_seg:  # a new dwell: new V (the same on every step of a dwell)
                step_columns(a + 0.5 * T, path, False, kinds, axes, js, C, w, f, wd, fd, vals, V, False, 0.0, 0.0, lev,
                             sd)
                for r in range(6):
                    for c in range(p):
                        Vs[r, c] = V[r, c] * sig[9 + c]
                g6_times(G6, Vs, phinp)
                last_seg = s_first
            # W = Vs P_pp (three non-zero rows per column of Vs)
            for r in range(6):
                for c in range(p):
                    W[r, c] = 0.0
            for l in range(p):
                r0 = rbase[l]
                for r in range(r0, r0 + 3):
                    v = Vs[r, l]
                    if v != 0.0:
                        for c in range(p):
                            W[r, c] += v * P[9 + l, 9 + c]
            g6_times(G6, W, new_np)
        else:
            last_seg = -1
            for r in range(6):
                for c in range(p):
                    M0[r, c] = 0.0
                    M1[r, c] = 0.0
                    M2[r, c] = 0.0
            for jj in range(n_sub):
                tj = a + (jj + 0.5) * h
                if thermal:
                    tdT = th_dT[k - k0, jj]
                    trt = th_rate[k - k0, jj]
                else:
                    tdT = 0.0
                    trt = 0.0
                step_columns(tj, path, need_rates, kinds, axes, js, C, w, f, wd, fd, vals, V, thermal, tdT, trt, lev, sd)
                sw = b - tj
                w1 = sw * h
                w2 = 0.5 * sw * sw * h
                for r in range(6):
                    for c in range(p):
                        v = V[r, c]
                        M0[r, c] += v * h
                        M1[r, c] += v * w1
                        M2[r, c] += v * w2
            # Phi_np = [M0; 0] + F[:, :6] M1 + F^2[:, :6] M2, scaled
            for i in range(9):
                for c in range(p):
                    phinp[i, c] = M0[i, c] if i < 6 else 0.0
                for r in range(6):
                    f1 = F[i, r]
                    f2 = F2[i, r]
                    for c in range(p):
                        phinp[i, c] += f1 * M1[r, c] + f2 * M2[r, c]
                si = sig[i]
                for c in range(p):
                    phinp[i, c] *= sig[9 + c] / si
            for i in range(9):
                for c in range(p):
                    new_np[i, c] = 0.0
                for l in range(p):
                    al = phinp[i, l]
                    if al != 0.0:
                        for c in range(p):
                            new_np[i, c] += al * P[9 + l, 9 + c]
        # ---- predict: P_np' = Pn P_np + Phi_np P_pp;  P_nn' = (Pn P_nn + Phi_np P_pn) Pn^T + P_np' Phi_np^T + Q
        predict_into(P, 9, Pn, phinp, new_np, Qs, t1, new_nn)
        if dyn_p:
            predict_params(P, 9, phi_p, q_p)
        # ---- the consider sensitivity: E_n <- Pn E_n + Phi_np E_p - Gamma, E_p <- phi_p E_p
        if m_c:
            for i in range(9):
                for c in range(m_c):
                    acc = -gam[i, c]
                    for l in range(9):
                        acc += Pn[i, l] * E[l, c]
                    for l in range(p):
                        acc += phinp[i, l] * E[9 + l, c]
                    En[i, c] = acc
            for i in range(9):
                for c in range(m_c):
                    E[i, c] = En[i, c]
            if dyn_p:
                for l in range(p):
                    for c in range(m_c):
                        E[9 + l, c] *= phi_p[l]
        # ---- update: zero velocity, known position (states 3..8); P <- P - K^T PHt (row layout)
        update_block(P, 3, rs, PHt, S, K)
        if m_c:  # E <- E - K^T (H E)
            for a_ in range(6):
                for c in range(m_c):
                    Eh[a_, c] = E[3 + a_, c]
            for i in range(N):
                for a_ in range(6):
                    ki = K[a_, i]
                    for c in range(m_c):
                        E[i, c] -= ki * Eh[a_, c]
        # ---- extra rows (scalar sequential updates)
        for m in range(mx):
            hr = xH[k - k0, m]
            update_row(P, hr, xr[k - k0, m], ph, kg)
            for c in range(m_c):
                acc = 0.0
                for j in range(N):
                    acc += hr[j] * E[j, c]
                he[c] = acc
            for i in range(N):
                for c in range(m_c):
                    E[i, c] -= kg[i] * he[c]
        if keep:
            for i in range(N):
                hist[k - k0, i] = P[i, i]
    last[0] = last_seg

