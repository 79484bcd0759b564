"""The parameter columns of the systematic filter's transition (S16 eq. 17-27), accumulated sample by sample
over a filter step, and the step's discretisation (``Phi_nn``, ``Phi_np``, ``Q_d``; the package docstring's
"Discretisation").

Columns.  Every parameter column of ``F_np`` at a sample is ``C_m^n e_i v`` (rows of ``phi`` for the gyro
kinds, of ``dv`` for the accelerometer kinds): the column ``i`` of the mid-sample attitude times one value
``v`` of the sample's compensated output (S16 eq. 18-19), or ``C_m^n f-dot = sum_i C_m^n e_i f-dot_i`` for the
time asynchrony.  The kernel keeps each sample's ``C_m^n`` and a short basis of its values (:data:`N_BASIS`:
``u_g``, ``-1``, ``-f``, ``u_a``, the quadratic and cross products, the size-effect terms, ``f-dot``; with
thermal states ``-dT^k``, ``-dT/dt`` and ``-(u - b)_i dT^k`` of both triads) in
per-step buffers, one row per entry; a column is a pair (axis ``i``, basis entry), and the columns that share
a pair (the gyro and accelerometer biases, both ``-C e_i``) share its sums.

Moments.  ``Phi_np = M0 + F M1 + F^2 M2`` with ``M_i = sum_j (T - t_j)^i / i! G_j dt`` over the step's
samples ``j = 0 .. n - 1`` (``T - t_j = (n - j - 1/2) dt`` at the sample's middle, ``G_j`` the sample's
columns): per pair, row and moment one dot product over the step's samples of the weighted attitude row
``(T - t_j)^i / i! dt C_j[r, i]`` with the basis row, evaluated at the step's end in vector lanes
(reassociated sums: the same for every slicing of a pass, as each step's arithmetic is its own).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.calibrate.systematic.states import (
    K_F2,
    K_FX,
    K_LEVD,
    K_LEVF,
    K_LEVT,
    K_M1A,
    K_M1G,
    K_MF,
    K_TAU,
    K_TH,
    K_UA,
    K_UG,
    TH_RATE_ROW,
)
from inscal.core.attitude import skew_entry
from inscal.core.dense import product_entry

# the basis of one sample's column values: u_g (3), -1, -f (3), u_a (3), -f_i^2 (3), -f_x f_y, -f_x f_z, -f_y f_z,
# |w|^2 - w_i^2 (3), the full lever arm's -(w_i w_j - delta_ij |w|^2 + (w-dot x e_j)_i) (9, at 3 i + j), f-dot (3);
# thermal states: -dT^k (3, k = 1 .. 3), -dT/dt, -(u_g - b_g)_i dT^k (9, at 3 (k - 1) + i), -(u_a - b_a)_i dT^k (9)
# the lever-arm timing's rate of the lever-arm terms in navigation axes (3, dynamics.lever_timing_rate)
B_UG, B_ONE, B_MF, B_UA, B_F2, B_FX, B_LEVD, B_LEVF, B_FDOT = 0, 3, 4, 7, 10, 13, 16, 19, 28
B_TDT, B_TRATE, B_TSG, B_TSA, B_LEVT, N_BASIS = 31, 34, 35, 44, 53, 56
#: a column without a pair (a gimbal state: no column in Phi_np), the asynchrony (the sum of three pairs, C f-dot)
NO_SUMS, TAU_SUMS = -1, -2
#: 3-point Gauss-Legendre nodes and weights on [0, 1]
GL3_NODES = (0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6))
GL3_WEIGHTS = (5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0)


@njit(cache=True)
def _basis_index(k, i, j):
    """The basis entry of a column of kind ``k``, axis ``i`` and second index ``j`` (dynamics.column_values)."""
    if k == K_UG:
        return B_UG + j
    if k == K_M1G or k == K_M1A:
        return B_ONE
    if k == K_MF:
        return B_MF + j
    if k == K_UA:
        return B_UA + j
    if k == K_F2:
        return B_F2 + i
    if k == K_FX:
        return B_FX + (0 if (j == 0 or j == 2) else (1 if (j == 1 or j == 4) else 2))
    if k == K_LEVD:
        return B_LEVD + i
    if k == K_LEVF:
        return B_LEVF + 3 * i + j
    if k == K_LEVT:
        return B_LEVT + i
    if k == K_TH:  # j: the row of the thermal array (states.THERMAL_ROWS)
        if j == TH_RATE_ROW:
            return B_TRATE
        t = j // 3
        if t == 0 or t == 2:
            return B_TDT + j % 3
        return (B_TSG if t == 1 else B_TSA) + 3 * (j % 3) + i
    return -1


@njit(cache=True, inline="always")
def is_gyro_column(k, j):
    """Whether a column of kind ``k`` (second index ``j``) feeds the attitude rows (gyro kinds) rather than the
    velocity rows."""
    if k == K_TH:
        return j < 6 or j == TH_RATE_ROW
    return k <= K_MF


@njit(cache=True)
def column_layout(kinds, axes, js, est_tau):
    """The pairs of the parameter columns (module docstring): ``start`` (4,) the first pair of each axis,
    ``src`` the basis entry of each pair, ``col_sum`` per column its pair (:data:`NO_SUMS`; :data:`TAU_SUMS`:
    the asynchrony, the sum of the pairs ``tau_pairs`` (3,)), ``col_row`` its first row in ``Phi_np`` (0:
    attitude, gyro kinds; 3: velocity, accelerometer kinds); ``lev9`` whether the full lever arm's basis
    entries are needed."""
    npar = kinds.shape[0]
    src = np.empty(npar + 3, np.int64)
    col_sum = np.full(npar, NO_SUMS, np.int64)
    col_row = np.zeros(npar, np.int64)
    tau_pairs = np.full(3, -1, np.int64)
    start = np.zeros(4, np.int64)
    lev9 = False
    n = 0
    for c in range(npar):
        col_row[c] = 0 if is_gyro_column(kinds[c], js[c]) else 3
        if kinds[c] == K_TAU and est_tau:
            col_sum[c] = TAU_SUMS
    for g in range(3):
        start[g] = n
        for c in range(npar + 1):
            if c == npar:  # the asynchrony's pair of this axis
                if not np.any(col_sum == TAU_SUMS):
                    continue
                b, k = B_FDOT + g, K_TAU
            else:
                k = kinds[c]
                b = _basis_index(k, axes[c], js[c])
                if b < 0 or axes[c] != g:
                    continue
            lev9 = lev9 or k == K_LEVF
            found = -1
            for a in range(start[g], n):
                if src[a] == b:
                    found = a
            if found < 0:
                src[n] = b
                found = n
                n += 1
            if c == npar:
                tau_pairs[g] = found
            else:
                col_sum[c] = found
    start[3] = n
    return start, src[:n].copy(), col_sum, col_row, tau_pairs, lev9


@njit(cache=True, inline="always")
def basis_values(ug, ua, w, f, wd, fdot, B, j, lev9, sd, lt):
    """One sample's column values into column ``j`` of the step's basis buffer ``B`` (:data:`N_BASIS`, n);
    the expressions of dynamics.column_values; ``lt``: the lever-arm timing's rates ``sd`` (3) too."""
    if lt:
        for i in range(3):
            B[B_LEVT + i, j] = sd[i]
    for i in range(3):
        B[B_UG + i, j] = ug[i]
        B[B_MF + i, j] = -f[i]
        B[B_UA + i, j] = ua[i]
        B[B_F2 + i, j] = -f[i] * f[i]
        B[B_FDOT + i, j] = fdot[i]
    B[B_ONE, j] = -1.0
    B[B_FX, j] = -f[0] * f[1]
    B[B_FX + 1, j] = -f[0] * f[2]
    B[B_FX + 2, j] = -f[1] * f[2]
    ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    for i in range(3):
        B[B_LEVD + i, j] = ww - w[i] * w[i]
    if lev9:
        for i in range(3):
            for k in range(3):
                B[B_LEVF + 3 * i + k, j] = -(w[i] * w[k] - (ww if i == k else 0.0) + skew_entry(wd, i, k))


@njit(cache=True, inline="always")
def thermal_basis(ug, ua, bg, ba, dT, rate, B, j):
    """One sample's thermal column values (temperature difference ``dT`` from T_ref, rate ``rate``) into column
    ``j`` of the basis buffer ``B``; the expressions of dynamics.thermal_values."""
    p = -dT
    for k in range(3):
        B[B_TDT + k, j] = p
        for i in range(3):
            B[B_TSG + 3 * k + i, j] = (ug[i] - bg[i]) * p
            B[B_TSA + 3 * k + i, j] = (ua[i] - ba[i]) * p
        p *= dT
    B[B_TRATE, j] = -rate


@njit(cache=True)
def moment_weights(n, dt):
    """``(T - t_j)^i / i! dt`` (3, n) of the moments ``M0``, ``M1``, ``M2`` (module docstring)."""
    W = np.empty((3, n))
    for j in range(n):
        sw = (n - j - 0.5) * dt
        W[0, j] = dt
        W[1, j] = sw * dt
        W[2, j] = 0.5 * sw * sw * dt
    return W


@njit(cache=True, fastmath={"reassoc"})
def step_moments(Cb, B, W, start, src, CW, R):
    """The step's moments of every pair (module docstring) into ``R`` (pairs, 3 moments, 3 rows): ``Cb``
    (9, n) the samples' ``C_m^n`` by rows (``3 r + i``), ``B`` the basis buffer, ``W`` :func:`moment_weights`,
    ``CW`` (3, 9, n) work.  Reassociated sums (vector lanes)."""
    n = Cb.shape[1]
    for m in range(3):
        for e in range(9):
            for j in range(n):
                CW[m, e, j] = W[m, j] * Cb[e, j]
    for g in range(3):  # the pairs of one axis four at a time: each weighted attitude row read once for four
        a = start[g]
        while a < start[g + 1]:
            nb = min(4, start[g + 1] - a)
            b0 = src[a]
            b1 = src[a + 1] if nb > 1 else b0
            b2 = src[a + 2] if nb > 2 else b0
            b3 = src[a + 3] if nb > 3 else b0
            for m in range(3):
                for r in range(3):
                    e = 3 * r + g
                    s0 = 0.0
                    s1 = 0.0
                    s2 = 0.0
                    s3 = 0.0
                    for j in range(n):
                        c = CW[m, e, j]
                        s0 += c * B[b0, j]
                        s1 += c * B[b1, j]
                        s2 += c * B[b2, j]
                        s3 += c * B[b3, j]
                    R[a, m, r] = s0
                    if nb > 1:
                        R[a + 1, m, r] = s1
                    if nb > 2:
                        R[a + 2, m, r] = s2
                    if nb > 3:
                        R[a + 3, m, r] = s3
            a += nb


@njit(cache=True)
def discretise(F, T, qgm, qam, sig, F2, phinn, Qd):
    """The step's scaled ``Phi_nn = I + F T + F^2 T^2/2 + F^3 T^3/6`` (into ``phinn``), ``F^2`` (into ``F2``, for
    :func:`parameter_columns`) and the scaled ``Q_d = int_0^T Phi(s) Q_c Phi(s)^T ds`` (into ``Qd``) by 3-point
    Gauss-Legendre quadrature, ``Q_c = diag(qgm I, qam I, 0)``: a positive-weight sum of PSD terms, so ``Q_d``
    is PSD by construction (the third-order series in T had position-attitude terms of order T^3 without the
    T^5 position variance that balances them: with a large gyro noise, e.g. --arw 1 deg/sqrt(h), it went
    indefinite and the Cholesky of the square-root prediction failed).  ``sig``: the state scaling."""
    F3 = np.empty((9, 9))
    for i in range(9):
        for j in range(9):
            F2[i, j] = product_entry(0.0, F, i, F, j, 9)
    for i in range(9):
        for j in range(9):
            F3[i, j] = product_entry(0.0, F2, i, F, j, 9)
    T2, T3 = T * T / 2.0, T * T * T / 6.0
    for i in range(9):
        for j in range(9):
            phinn[i, j] = ((1.0 if i == j else 0.0) + F[i, j] * T + F2[i, j] * T2 + F3[i, j] * T3) * (sig[j] / sig[i])
    # Phi(s) Q_c Phi(s)^T = sum_k q_k Phi[:, k] Phi[:, k]^T over the six noisy states k
    Ph = np.empty((9, 6))
    for i in range(9):
        for j in range(9):
            Qd[i, j] = 0.0
    for gq in range(3):
        sq = T * GL3_NODES[gq]
        s2, s3 = sq * sq / 2.0, sq * sq * sq / 6.0
        wq = T * GL3_WEIGHTS[gq]
        for i in range(9):
            for k in range(6):
                Ph[i, k] = (1.0 if i == k else 0.0) + F[i, k] * sq + F2[i, k] * s2 + F3[i, k] * s3
        for i in range(9):
            for j in range(i, 9):
                sg = 0.0
                for k in range(3):
                    sg += Ph[i, k] * Ph[j, k]
                sa = 0.0
                for k in range(3, 6):
                    sa += Ph[i, k] * Ph[j, k]
                Qd[i, j] += wq * (qgm * sg + qam * sa)
    for i in range(9):
        for j in range(i, 9):
            v = Qd[i, j] / (sig[i] * sig[j])
            Qd[i, j] = v
            Qd[j, i] = v


@njit(cache=True)
def parameter_columns(R, col_sum, col_row, tau_pairs, F, F2, sig, phinp):
    """The step's scaled ``Phi_np = M0 + F M1 + F^2 M2`` from the moments ``R`` of :func:`step_moments`, into
    ``phinp`` (9, npar)."""
    npar = col_sum.shape[0]
    mo = np.empty((3, 3))
    for c in range(npar):
        a = col_sum[c]
        if a == NO_SUMS:
            for i in range(9):
                phinp[i, c] = 0.0
            continue
        for m in range(3):
            for r in range(3):
                if a == TAU_SUMS:
                    mo[m, r] = R[tau_pairs[0], m, r] + R[tau_pairs[1], m, r] + R[tau_pairs[2], m, r]
                else:
                    mo[m, r] = R[a, m, r]
        rb = col_row[c]
        sc = sig[9 + c]
        for i in range(9):
            s = mo[0, i - rb] if rb <= i < rb + 3 else 0.0
            for r in range(3):
                s += F[i, rb + r] * mo[1, r] + F2[i, rb + r] * mo[2, r]
            phinp[i, c] = s * (sc / sig[i])
