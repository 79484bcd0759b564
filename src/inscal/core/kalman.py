"""Kalman filter and Rauch-Tung-Striebel smoother for error states whose tail is constant.

The engine knows nothing about IMUs.  It serves state vectors ``x = [n | p]`` made of ``n``
*dynamic* states and ``p`` *parameter* states that are constants, except for an optional
random walk on the diagonal (``q_p``).  The transition and noise then have the block form::

    Phi = [[Phi_nn, Phi_np],        Q = [[Q_nn, 0      ],
           [0,      I     ]]             [0,    diag q_p]]

and the measurements see the dynamic states only: ``z = H x + v`` with ``H = [H_n, 0]``
selecting ``m`` dynamic states (``idx``), ``v ~ N(0, diag R)``.

Prediction (structure only: the parameter block ``P_pp`` moves only by ``q_p``)::

    P_np' = Phi_nn P_np + Phi_np P_pp
    P_nn' = (Phi_nn P_nn + Phi_np P_pn) Phi_nn^T + P_np' Phi_np^T + Q_nn
    P_pp' = P_pp + diag(q_p)

Update in Joseph form, written with ``K = P H^T S^-1``::

    P+ = (I - K H) P (I - K H)^T + K R K^T = P - K (P H^T)^T - (P H^T) K^T + K S K^T

(each term computed separately, then symmetrised), which keeps ``P`` symmetric and
positive to round-off even when ``R`` is tiny.

Smoother.  The fixed-interval RTS smoother of S16 eq. 13-16,
``A_{j-1} = P_{j-1} Phi^T P_{j|j-1}^-1``, ``x_{j-1|M} = x_{j-1} + A (x_{j|M} - x_{j|j-1})``,
``P_{j-1|M} = P_{j-1} + A (P_{j|M} - P_{j|j-1}) A^T``, is evaluated in its algebraically
identical *modified Bryson-Frazier* form (Bierman 1977, ch. X), which needs no inverse of
``P`` and stores per step only ``Phi_nn``, ``Phi_np``, ``K``, ``S^-1`` and ``S^-1 nu``:
with the adjoint ``lambda``, ``Lambda`` (zero after the last update), backwards::

    lt_k = H^T S_k^-1 nu_k + (I - K_k H)^T l_k
    Lt_k = H^T S_k^-1 H    + (I - K_k H)^T L_k (I - K_k H)
    x_{k|M} = x_{k|k-1} + P_{k|k-1} lt_k,     P_{k|M} = P_{k|k-1} - P_{k|k-1} Lt_k P_{k|k-1}
    l_{k-1} = Phi_k^T lt_k,                   L_{k-1} = Phi_k^T Lt_k Phi_k

so ``P_{k|k-1}`` is only needed at the steps where a smoothed estimate is wanted
(``tests/core/test_kalman.py`` checks the equality with the dense eq. 13-16 form).  With constant
parameters (``q_p = 0``) their smoothed estimate and covariance are the final filtered ones at every
step; :func:`smoothed_constant` takes them from the filter and conditions the dynamic states on them,
because ``P - P L P`` cancels catastrophically in the parameter directions when the data dwarf the
prior (checked against a batch least-squares smoother in the tests).

Square-root information smoother.  For the covariances the MBF form ``P - P Lam P`` subtracts two
information-sized terms and still loses positivity on the first steps of such a record; the functions at the
end of this module give them as a product instead: a square-root information filter run backwards (``Rb``,
``Rb^T Rb`` the information of the measurements at and after a step; :func:`info_rows` adds a step's rows,
:func:`info_back` carries it back through ``Phi`` and ``Q``) and the two-filter combination with the forward
predicted covariance (:func:`sr_smoothed`, Fraser and Potter 1969; checked against a 50-digit RTS smoother).

Feedback.  A closed-loop filter removes its estimate from the reference after every
update (S16 eq. 27), so ``x_{k|k-1} = 0`` always and the innovation is the raw measurement.
A known input does not change the innovations, the gains or the adjoint recursion, so
the smoothed error of the *pre-update reference at step k* is simply ``P_{k|k-1} lt_k``; the
caller keeps the references it needs.  At the start (``k = 0``), ``x_{0|M} = x_0 + P_0 l_0``
and ``P_{0|M} = P_0 - P_0 L_0 P_0``.

All functions are ``@njit`` and work in place on float64 arrays; they are meant to be
called from the model's compiled loop.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def predict(P, n, phi_nn, phi_np, q_nn, q_p):
    """Structured prediction ``P <- Phi P Phi^T + Q`` in place (see the module docstring)."""
    N = P.shape[0]
    Pnn = np.ascontiguousarray(P[:n, :n])
    Pnp = np.ascontiguousarray(P[:n, n:])
    Ppp = np.ascontiguousarray(P[n:, n:])
    new_np = phi_nn @ Pnp + phi_np @ Ppp
    t1 = phi_nn @ Pnn + phi_np @ Pnp.T
    new_nn = t1 @ phi_nn.T + new_np @ phi_np.T + q_nn
    store_predicted(P, n, new_nn, new_np)
    for j in range(n, N):
        P[j, j] += q_p[j - n]


@njit(cache=True, inline="always")
def store_predicted(P, n, new_nn, new_np):
    """Write a prediction's new blocks into ``P``: ``P_nn`` symmetrised (the mean of ``new_nn`` and its transpose),
    ``P_np = new_np`` and ``P_pn`` its transpose; ``P_pp`` is left alone."""
    p = P.shape[0] - n
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (new_nn[i, j] + new_nn[j, i])
            P[i, j] = v
            P[j, i] = v
        for c in range(p):
            P[i, n + c] = new_np[i, c]
            P[n + c, i] = new_np[i, c]


@njit(cache=True)
def update(P, idx, r, z, K, Sinv, x):
    """Joseph-form update with ``H`` selecting states ``idx`` (m), noise variances ``r`` (m) and
    measurement ``z`` (m).  Writes the gain ``K`` (N, m), ``S^-1`` (m, m) and the estimate
    ``x = K z`` (N); returns the normalised innovation squared ``z^T S^-1 z``."""
    N = P.shape[0]
    m = idx.shape[0]
    PHt = np.empty((N, m))
    for i in range(N):
        for a in range(m):
            PHt[i, a] = P[i, idx[a]]
    S = np.empty((m, m))
    for a in range(m):
        for b in range(m):
            S[a, b] = PHt[idx[a], b]
        S[a, a] += r[a]
    return gain_and_joseph(P, PHt, S, z, K, Sinv, x)


@njit(cache=True)
def gain(PHt, S, z, K, Sinv, x):
    """The gain of an update, given ``P H^T`` (N, m) and ``S = H P H^T + R`` (m, m): symmetrise ``S`` (in
    place), write ``S^-1``, ``K = P H^T S^-1`` and ``x = K z``; returns ``z^T S^-1 z``."""
    m = S.shape[0]
    for a in range(m):
        for b in range(a + 1, m):
            v = 0.5 * (S[a, b] + S[b, a])
            S[a, b] = v
            S[b, a] = v
    Si = np.linalg.inv(S)
    Sinv[:, :] = Si
    K[:, :] = PHt @ Si
    x[:] = K @ z
    return z @ (Si @ z)


@njit(cache=True)
def gain_and_joseph(P, PHt, S, z, K, Sinv, x):
    """The common part of every update in covariance form: :func:`gain`, then ``P`` updated in Joseph
    form (``P - K H P - (K H P)^T + K S K^T``, symmetric); returns ``z^T S^-1 z``."""
    N = P.shape[0]
    nis = gain(PHt, S, z, K, Sinv, x)
    KPH = K @ PHt.T
    KSK = (K @ S) @ K.T
    for i in range(N):
        for j in range(i, N):
            v = P[i, j] - KPH[i, j] - KPH[j, i] + 0.5 * (KSK[i, j] + KSK[j, i])
            P[i, j] = v
            P[j, i] = v
    return nis


@njit(cache=True)
def robust_inflation(hph, r, z, cap, max_iter=30):
    """Huber-type bounded influence of one update: the factor ``alpha >= 1`` on ``R`` that brings the
    normalised innovation squared down to ``cap`` when it exceeds it, and the NIS with the nominal ``R``.

    ``hph = H P H^T`` (m x m); ``S(alpha) = H P H^T + alpha R``; ``alpha NIS(alpha) = nu^T (S(alpha) /
    alpha)^-1 nu`` never decreases with ``alpha``, so the multiplicative iteration ``alpha <- alpha
    NIS(alpha) / cap`` rises monotonically to the root (one step when ``R`` dominates ``S``).  Steps
    within ``cap`` keep ``alpha = 1``: on data the model fits, the update is the plain Kalman update.
    Returns ``(alpha, nis_nominal)``."""
    m = hph.shape[0]
    nis0 = 0.0
    alpha = 1.0
    for it in range(max_iter + 1):
        Sa = np.empty((m, m))
        for a in range(m):
            for b in range(m):
                Sa[a, b] = 0.5 * (hph[a, b] + hph[b, a])
            Sa[a, a] += alpha * r[a]
        nis = z @ np.linalg.solve(Sa, z)
        if it == 0:
            nis0 = nis
        if not (nis > cap * (1.0 + 1e-3)) or not (nis == nis):
            break
        alpha *= nis / cap
    return alpha, nis0


@njit(cache=True)
def robust_jump(S, hqh, z, cap, iters=60):
    """Bounded influence in the form of a state jump: the factor ``lam >= 1`` with
    ``nu^T (S + (lam - 1) H Q H^T)^-1 nu = cap`` (``S`` the innovation covariance, ``hqh = H Q H^T`` of a unit
    process noise, ``z`` the innovation), by bisection on ``log lam`` (the NIS never increases with ``lam``);
    1 when the NIS is within the cap, at most ``1e12``.  Unlike an inflated ``R`` (:func:`robust_inflation`), the
    misfit is then taken up by the states the noise drives (a velocity jump), so the next step starts clean."""
    Sl = np.empty(S.shape)
    lo = 0.0
    hi = math.log(1e12)
    if not _nis_jump(S, hqh, z, lo, Sl) > cap:
        return 1.0
    if _nis_jump(S, hqh, z, hi, Sl) > cap:
        return math.exp(hi)
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if _nis_jump(S, hqh, z, mid, Sl) > cap:
            lo = mid
        else:
            hi = mid
    return math.exp(hi)


@njit(cache=True)
def _nis_jump(S, hqh, z, log_lam, Sl):
    """``z^T (S + (exp(log_lam) - 1) hqh)^-1 z`` (symmetrised; ``Sl`` work)."""
    lam = math.exp(log_lam)
    m = S.shape[0]
    for a in range(m):
        for b in range(m):
            Sl[a, b] = 0.5 * (S[a, b] + S[b, a]) + (lam - 1.0) * 0.5 * (hqh[a, b] + hqh[b, a])
    return z @ np.linalg.solve(Sl, z)


# ----------------------------------------------------------------------------- square-root form
@njit(cache=True)
def sr_predict(U, n, phi_nn, phi_np, q_nn):
    """Square-root form of :func:`predict` (no parameter noise): ``P = U U^T`` with ``U`` upper
    triangular and the states ordered ``[n dynamic | p constants]``, so ``U = [[U_nn, U_np], [0, U_pp]]``
    and ``Phi U = [[Phi_nn U_nn, Phi_nn U_np + Phi_np U_pp], [0, U_pp]]``: ``U_pp`` never changes (the
    parameters' covariance is never formed, so it stays positive whatever its range), the new ``U_np``
    is that product, and the new ``U_nn`` is the upper-triangular factor of the dynamic block
    ``(Phi_nn U_nn)(Phi_nn U_nn)^T + Q_nn`` (n x n, a reversed Cholesky: ``J chol(J M J) J``, ``J`` the
    exchange matrix)."""
    N = U.shape[0]
    Unn = np.ascontiguousarray(U[:n, :n])
    new_np = phi_nn @ np.ascontiguousarray(U[:n, n:]) + phi_np @ np.ascontiguousarray(U[n:, n:])
    A = phi_nn @ Unn
    M = A @ A.T + q_nn
    Mr = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            Mr[i, j] = 0.5 * (M[n - 1 - i, n - 1 - j] + M[n - 1 - j, n - 1 - i])
    L = np.linalg.cholesky(Mr)
    for i in range(n):
        for j in range(n):
            U[i, j] = L[n - 1 - i, n - 1 - j] if i <= j else 0.0
        for j in range(n, N):
            U[i, j] = new_np[i, j - n]


@njit(cache=True, inline="always")
def carlson_column(U, j, sigma, alpha, w):
    """One column ``j`` of Carlson's update (``sigma = (U^T h)_j``, ``alpha`` the running ``h^T P h + r`` so
    far, ``w`` the unscaled gain), in place; returns the new ``alpha``."""
    beta = alpha
    alpha = alpha + sigma * sigma
    gamma = np.sqrt(alpha * beta)
    eta = beta / gamma
    zeta = sigma / gamma
    for i in range(j + 1):
        tau = U[i, j]
        U[i, j] = eta * tau - zeta * w[i]
        w[i] += tau * sigma
    return alpha


@njit(cache=True)
def carlson(U, h, r):
    """Carlson's triangular square-root update (Grewal and Andrews, Kalman Filtering, sec. 6.5) of
    ``P = U U^T`` for one scalar measurement ``h^T x + v``, ``var v = r``, in place: afterwards
    ``U U^T = P - P h h^T P / (h^T P h + r)``, ``U`` still upper triangular.  (``w[j]`` is zero until
    column ``j``: the columns before it touch rows ``i < j`` only.)"""
    N = U.shape[0]
    w = np.zeros(N)
    alpha = r
    for j in range(N):
        sigma = 0.0
        for i in range(j + 1):
            sigma += U[i, j] * h[i]
        if sigma != 0.0:
            alpha = carlson_column(U, j, sigma, alpha, w)


@njit(cache=True)
def carlson_unit(U, i0, r):
    """:func:`carlson` for ``h = e_i0`` (a measurement of one state): ``sigma_j = U[i0, j]``, zero for
    ``j < i0``."""
    N = U.shape[0]
    w = np.zeros(N)
    alpha = r
    for j in range(i0, N):
        sigma = U[i0, j]
        if sigma != 0.0:
            alpha = carlson_column(U, j, sigma, alpha, w)


@njit(cache=True)
def sr_gain(U, Ht, R, nu, K, Sinv, x):
    """The vector update's gain in square-root form, given ``F = U^T H^T`` (N x m, ``Ht``): ``P H^T = U F``,
    ``S = F^T F + R``; :func:`gain` of those; returns ``nu^T S^-1 nu``."""
    return gain(U @ Ht, Ht.T @ Ht + R, nu, K, Sinv, x)


@njit(cache=True)
def sr_update(U, idx, r, z, K, Sinv, x, cap=np.inf):
    """Square-root form of :func:`update`: the same ``K``, ``S^-1``, ``x`` and NIS (from ``U``), and ``U``
    updated by one Carlson step per measurement (``R`` diagonal: the rows are independent).  With a
    finite ``cap``, a step whose NIS exceeds it is updated with ``alpha R`` (:func:`robust_inflation`).
    Returns ``(NIS with the nominal R, alpha)``."""
    N = U.shape[0]
    m = idx.shape[0]
    F = np.empty((N, m))
    for a in range(m):
        for j in range(N):
            F[j, a] = U[idx[a], j]
    Rm = np.zeros((m, m))
    for a in range(m):
        Rm[a, a] = r[a]
    nis = sr_gain(U, F, Rm, z, K, Sinv, x)
    alpha = 1.0
    if nis > cap:
        alpha, _ = robust_inflation(F.T @ F, r, z, cap)
        for a in range(m):
            Rm[a, a] = alpha * r[a]
        sr_gain(U, F, Rm, z, K, Sinv, x)
    for a in range(m):
        carlson_unit(U, idx[a], alpha * r[a])
    return nis, alpha


@njit(cache=True)
def sr_update_dense(U, H, R, nu, K, Sinv, x):
    """Square-root form of :func:`update_dense` (``H`` m x N, ``R`` full): the gain from ``U``, then the rows
    decorrelated by ``R = L L^T`` (``L^-1 H``, unit variances) and one Carlson step each."""
    N = U.shape[0]
    m = H.shape[0]
    F = U.T @ H.T
    nis = sr_gain(U, np.ascontiguousarray(F), R, nu, K, Sinv, x)
    L = np.linalg.cholesky(0.5 * (R + R.T))
    Hw = np.linalg.solve(L, H)
    for a in range(m):
        carlson(U, np.ascontiguousarray(Hw[a]), 1.0)
    return nis


@njit(cache=True)
def smoother_step(lam, Lam, idx, K, Sinv, sz):
    """Adjoint at the predicted time of one step (``lt``, ``Lt`` of the module docstring),
    in place: ``lam <- H^T S^-1 nu + (I - K H)^T lam``, ``Lam <- H^T S^-1 H + (I-KH)^T Lam (I-KH)``."""
    N = lam.shape[0]
    m = idx.shape[0]
    # (I - K H)^T lam = lam - H^T (K^T lam)
    ktl = K.T @ lam
    for a in range(m):
        lam[idx[a]] += sz[a] - ktl[a]
    LK = Lam @ K  # (N, m)
    KtLK = K.T @ LK  # (m, m)
    # Lam - H^T (K^T Lam) - (Lam K) H + H^T (K^T Lam K) H + H^T S^-1 H
    for i in range(N):
        for a in range(m):
            Lam[i, idx[a]] -= LK[i, a]
    for a in range(m):
        for j in range(N):
            Lam[idx[a], j] -= LK[j, a]
    for a in range(m):
        for b in range(m):
            Lam[idx[a], idx[b]] += KtLK[a, b] + Sinv[a, b]
    for i in range(N):
        for j in range(i + 1, N):
            v = 0.5 * (Lam[i, j] + Lam[j, i])
            Lam[i, j] = v
            Lam[j, i] = v


@njit(cache=True)
def adjoint_back(lam, Lam, n, phi_nn, phi_np):
    """``lam <- Phi^T lam``, ``Lam <- Phi^T Lam Phi`` for the block transition, in place."""
    N = lam.shape[0]
    ln = lam[:n].copy()
    lp = lam[n:]
    lam[:n] = phi_nn.T @ ln
    lam[n:] = lp + phi_np.T @ ln
    Lnn = Lam[:n, :n].copy()
    Lnp = Lam[:n, n:].copy()
    a = Lnn @ phi_np + Lnp  # (n, p)
    new_nn = phi_nn.T @ Lnn @ phi_nn
    new_np = phi_nn.T @ a
    new_pp = phi_np.T @ a + Lnp.T @ phi_np
    for i in range(n):
        for j in range(n):
            Lam[i, j] = new_nn[i, j]
    for i in range(n):
        for j in range(n, N):
            Lam[i, j] = new_np[i, j - n]
            Lam[j, i] = new_np[i, j - n]
    p = N - n
    for i in range(p):
        for j in range(i, p):
            v = Lam[n + i, n + j] + 0.5 * (new_pp[i, j] + new_pp[j, i])
            Lam[n + i, n + j] = v
            Lam[n + j, n + i] = v


@njit(cache=True)
def smoothed(Pm, lam, Lam):
    """Smoothed error and covariance from the predicted covariance ``Pm`` and the adjoint:
    ``(Pm lam, Pm - Pm Lam Pm)``."""
    x = Pm @ lam
    PL = Pm @ Lam
    Ps = Pm - PL @ Pm
    return x, 0.5 * (Ps + Ps.T)


@njit(cache=True)
def smoothed_constant(Pm, lam, Lam, n, xp, Ppp):
    """:func:`smoothed` for states ``[n dynamic | p constants]`` given the constants' smoothed estimate ``xp``
    and covariance ``Ppp`` (with no parameter noise: the final filtered ones, at every step).

    ``Pm - Pm Lam Pm`` cancels catastrophically in the constants' directions: early in a record ``P_pp`` is the
    prior while the adjoint ``Lam`` carries the information of the whole rest of it, so ``Lam_pp`` is ``P_pp^-1``
    less a part ~1e-8 of it, accumulated from terms ``H^T S^-1 H`` many orders larger (smoothed variances off by
    a factor 60, some negative, on a 1-hour record).  Split ``x_n = V x_p + y`` at the predicted time,
    ``V = P_np P_pp^-1``: ``y`` and ``x_p`` are uncorrelated with covariances ``C = P_nn - V P_pn`` and ``P_pp``; in
    ``(y, x_p)`` the adjoint's blocks are ``Lam'_yy = Lam_nn``, ``Lam'_yp = Lam_nn V + Lam_np``, so (MBF in those
    coordinates, the ``pp`` block replaced by the given ``Ppp``)::

        C_yy = C - C Lam_nn C,     C_yp = -C (Lam_nn P_np + Lam_np P_pp)
        P_nn = C_yy + V C_yp^T + C_yp V^T + V Ppp V^T,     P_np = C_yp + V Ppp,     P_pp = Ppp

    (the same as :func:`smoothed` in exact arithmetic when ``xp``, ``Ppp`` are its own values): no information-sized
    term of the constants is subtracted.  The dynamic states keep :func:`smoothed`'s ``(Pm lam)_n`` (as accurate
    as the split form's ``C lam_n + V xp`` or more on the measured states); ``x_p = xp``.  Where the predicted
    covariance is still the prior's (the first steps), an unmeasured dynamic state that the rest of the record
    pins down keeps a cancellation of its own in ``C - C Lam_nn C`` (orders of magnitude smaller than the plain
    form's).  Returns ``(x, P)``."""
    N = Pm.shape[0]
    Ppp = np.ascontiguousarray(Ppp)
    Pnn = np.ascontiguousarray(Pm[:n, :n])
    Pnp = np.ascontiguousarray(Pm[:n, n:])
    Pp = np.ascontiguousarray(Pm[n:, n:])
    Lc = np.linalg.cholesky(0.5 * (Pp + Pp.T))
    V = np.ascontiguousarray(np.linalg.solve(Lc.T, np.linalg.solve(Lc, np.ascontiguousarray(Pnp.T))).T)  # P_np P_pp^-1
    C = Pnn - V @ Pnp.T
    C = 0.5 * (C + C.T)
    x = np.empty(N)
    x[:n] = np.ascontiguousarray(Pm[:n, :]) @ lam
    x[n:] = xp
    Lnn = np.ascontiguousarray(Lam[:n, :n])
    Lnp = np.ascontiguousarray(Lam[:n, n:])
    Cyy = C - C @ Lnn @ C
    Cyp = -(C @ (Lnn @ Pnp + Lnp @ Pp))
    VP = V @ Ppp
    CV = Cyp @ V.T
    Snn = Cyy + CV + CV.T + VP @ V.T
    P = np.empty((N, N))
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (Snn[i, j] + Snn[j, i])
            P[i, j] = v
            P[j, i] = v
        for j in range(n, N):
            v = Cyp[i, j - n] + VP[i, j - n]
            P[i, j] = v
            P[j, i] = v
    for i in range(n, N):
        for j in range(n, N):
            P[i, j] = 0.5 * (Ppp[i - n, j - n] + Ppp[j - n, i - n])
    return x, P


def dense_rts(xf, Pf, xp, Pp, Phis):
    """Textbook RTS smoother (S16 eq. 13-16), dense, for checks: ``xf[k], Pf[k]`` filtered,
    ``xp[k], Pp[k]`` predicted (from k-1), ``Phis[k]`` the transition k-1 -> k (k = 1..M;
    index 0 is the prior).  Returns the smoothed ``(x, P)`` for k = 0..M."""
    M = len(xf) - 1
    xs = [None] * (M + 1)
    Ps = [None] * (M + 1)
    xs[M], Ps[M] = xf[M], Pf[M]  # S16 eq. 16
    for j in range(M, 0, -1):
        A = Pf[j - 1] @ Phis[j].T @ np.linalg.inv(Pp[j])  # S16 eq. 14
        xs[j - 1] = xf[j - 1] + A @ (xs[j] - xp[j])  # S16 eq. 13
        Ps[j - 1] = Pf[j - 1] + A @ (Ps[j] - Pp[j]) @ A.T  # S16 eq. 15
    return xs, Ps


@njit(cache=True)
def update_dense(P, H, R, nu, K, Sinv, x):
    """:func:`inscal.core.kalman.update` for a dense ``H`` (m x N) and a full ``R`` (m x m): Joseph-form
    update, writes ``K``, ``S^-1`` and ``x = K nu``; returns ``nu^T S^-1 nu``."""
    N = P.shape[0]
    m = H.shape[0]
    PHt = np.zeros((N, m))
    for i in range(N):
        for a in range(m):
            s = 0.0
            for j in range(N):
                s += P[i, j] * H[a, j]
            PHt[i, a] = s
    S = np.empty((m, m))
    for a in range(m):
        for b in range(m):
            s = R[a, b]
            for j in range(N):
                s += H[a, j] * PHt[j, b]
            S[a, b] = s
    return gain_and_joseph(P, PHt, S, nu, K, Sinv, x)


@njit(cache=True)
def upper_outer(U, P):
    """``P = U U^T`` of an upper-triangular ``U`` (``P_ij = sum_{k >= max(i, j)} U_ik U_jk``), in place."""
    N = U.shape[0]
    for i in range(N):
        for j in range(i, N):
            s = 0.0
            for k in range(j, N):
                s += U[i, k] * U[j, k]
            P[i, j] = s
            P[j, i] = s


# ----------------------------------------------------------------------------- square-root information smoother
@njit(cache=True)
def givens_row(R, v, j0):
    """Rotate the row ``v`` (zero before column ``j0``) into the upper-triangular ``R`` by Givens rotations, in
    place: afterwards ``R^T R`` is the old ``R^T R + v v^T`` (information added), ``R`` still upper triangular with
    a non-negative diagonal, and ``v`` is zero (Golub and Van Loan, Matrix Computations, sec. 5.1.8, 6.5)."""
    N = R.shape[0]
    for j in range(j0, N):
        b = v[j]
        if b == 0.0:
            continue
        a = R[j, j]
        r = math.hypot(a, b)
        c = a / r
        s = b / r
        R[j, j] = r
        v[j] = 0.0
        for i in range(j + 1, N):
            t = R[j, i]
            u = v[i]
            R[j, i] = c * t + s * u
            v[i] = c * u - s * t


@njit(cache=True)
def info_rows(Rb, idx, r):
    """The information of measurements of the states ``idx`` (variances ``r``) added to the square-root
    information ``Rb`` (``I_b = Rb^T Rb``), in place: one row ``e_i / sqrt(r)`` each (:func:`givens_row`)."""
    N = Rb.shape[0]
    v = np.empty(N)
    for a in range(idx.shape[0]):
        v[:] = 0.0
        v[idx[a]] = 1.0 / math.sqrt(r[a])
        givens_row(Rb, v, idx[a])


@njit(cache=True)
def info_rows_dense(Rb, H, R):
    """:func:`info_rows` for a dense ``H`` (m x N) and a full ``R`` (m x m): the rows ``L^-1 H`` (``R = L L^T``)."""
    L = np.linalg.cholesky(0.5 * (R + R.T))
    W = np.linalg.solve(L, np.ascontiguousarray(H))
    for a in range(W.shape[0]):
        givens_row(Rb, np.ascontiguousarray(W[a]), 0)


@njit(cache=True)
def noise_factor(Q):
    """``G`` with ``G G^T = Q`` for a symmetric positive semi-definite ``Q`` (eigenvalues below zero, round-off,
    taken as zero): the columns ``v_i sqrt(lambda_i)``."""
    w, V = np.linalg.eigh(0.5 * (Q + Q.T))
    G = np.empty(V.shape)
    for j in range(w.shape[0]):
        s = math.sqrt(w[j]) if w[j] > 0.0 else 0.0
        for i in range(V.shape[0]):
            G[i, j] = V[i, j] * s
    return G


@njit(cache=True)
def info_back(Rb, n, phi_nn, phi_np, G):
    """The square-root information ``Rb`` about ``x_k`` (from the measurements at ``k`` and after) carried back to
    ``x_{k-1}`` through ``x_k = Phi x_{k-1} + [G u; 0]``, ``u ~ N(0, I)`` (``Q_nn = G G^T``; ``Phi`` in the block
    form of the module docstring), in place (Bierman 1977, ch. VI, the square-root information filter's time update
    run backwards).  The data equations ``u = 0 - e_u`` and ``Rb (Phi x_{k-1} + G u) = z - e`` are triangularised
    with ``u`` first; the trailing block is the new ``Rb``.  The rows ``n ..`` of ``Rb`` see neither ``u`` nor the
    dynamic states (``Rb[n:, :n] = 0``, ``Phi_pp = I``): they stay as they are, and only the ``q + n`` rows of ``u``
    and the dynamic states are triangularised (one QR of ``(q + n) x (q + N)``)."""
    N = Rb.shape[0]
    q = G.shape[1]
    T = np.zeros((q + n, q + N))
    for i in range(q):
        T[i, i] = 1.0
    top = np.ascontiguousarray(Rb[:n, :n])
    T[q:, :q] = top @ G
    T[q:, q:q + n] = top @ phi_nn
    T[q:, q + n:] = top @ phi_np + Rb[:n, n:]
    _, R = np.linalg.qr(T)
    for i in range(n):
        sgn = 1.0 if R[q + i, q + i] >= 0.0 else -1.0
        for j in range(i):
            Rb[i, j] = 0.0
        for j in range(i, N):
            Rb[i, j] = sgn * R[q + i, q + j]


@njit(cache=True)
def upper_factor(P):
    """The upper-triangular ``U`` with ``U U^T = P`` (the reversed Cholesky ``J chol(J P J) J``)."""
    N = P.shape[0]
    Pr = np.empty((N, N))
    for i in range(N):
        for j in range(N):
            Pr[i, j] = 0.5 * (P[N - 1 - i, N - 1 - j] + P[N - 1 - j, N - 1 - i])
    L = np.linalg.cholesky(Pr)
    U = np.zeros((N, N))
    for i in range(N):
        for j in range(i, N):
            U[i, j] = L[N - 1 - i, N - 1 - j]
    return U


@njit(cache=True)
def upper_solve_right(B, R):
    """``X`` with ``X R = B`` for an upper-triangular ``R`` (column by column, forward)."""
    m, N = B.shape
    X = np.empty((m, N))
    for j in range(N):
        for i in range(m):
            s = B[i, j]
            for k in range(j):
                s -= X[i, k] * R[k, j]
            X[i, j] = s / R[j, j]
    return X


@njit(cache=True)
def sr_smoothed(Pm, Rb, n, Upp):
    """The smoothed covariance from the predicted one ``Pm`` and the square-root information ``Rb`` of the
    measurements at and after the step (the two-filter form, Fraser and Potter 1969): ``P = (Pm^-1 + Rb^T Rb)^-1
    = U (I + F^T F)^-1 U^T``, ``Pm = U U^T`` (upper triangular), ``F = Rb U``, with ``I + F^T F = Rs^T Rs`` from
    rotating the rows of ``F`` into ``I`` (:func:`givens_row`): ``P = W W^T``, ``W = U Rs^-1`` upper triangular, so
    positive semi-definite by construction (no difference of information-sized terms, unlike ``Pm - Pm Lam Pm``).

    States ``[n dynamic | p constants]``: in ``W = [[W_nn, W_np], [0, W_pp]]`` the constants are ``W_pp u_p`` and
    the dynamic states ``W_nn u_n + W_np u_p``; the constants' factor is replaced by ``Upp`` (the final filtered
    one: with no parameter noise their smoothed covariance at every step) and ``W_np`` by ``W_np W_pp^-1 Upp``, which
    keeps the dynamic states' covariance given the constants (:func:`smoothed_constant`'s split, as a factor).
    Returns ``P``."""
    N = Pm.shape[0]
    U = upper_factor(Pm)
    F = np.zeros((N, N))  # Rb U, both upper triangular (compiled loops: BLAS threads spin on a busy machine)
    for i in range(N):
        for k in range(i, N):
            a = Rb[i, k]
            if a != 0.0:
                for j in range(k, N):
                    F[i, j] += a * U[k, j]
    Rs = np.eye(N)
    v = np.empty(N)
    for i in range(N):
        v[:] = F[i]
        givens_row(Rs, v, i)
    W = upper_solve_right(U, Rs)
    if n < N:
        Wnp = upper_solve_right(np.ascontiguousarray(W[:n, n:]), np.ascontiguousarray(W[n:, n:])) @ Upp
        for i in range(n):
            for j in range(n, N):
                W[i, j] = Wnp[i, j - n]
        for i in range(n, N):
            for j in range(n, N):
                W[i, j] = Upp[i - n, j - n]
    P = np.empty((N, N))  # W W^T of the upper-triangular W
    upper_outer(W, P)
    return P


# ------------------------------------------------------------------ allocation-free covariance-only forms
# For a covariance-only pass (the Cramér-Rao bound of a path, inscal.plan.bound): no estimate, no allocation per
# step, the zeros of Phi skipped.  Compiled with fastmath (reassociated sums): the bound is a design figure, so
# its covariance may differ from the filter's in the last bits.


@njit(cache=True, fastmath=True)
def predict_into(P, n, phi_nn, phi_np, new_np, q_nn, t1, new_nn):
    """:func:`predict` with ``q_p = 0`` for a caller that has already put ``Phi_np P_pp`` into ``new_np`` (n, p)
    (it knows the sparsity of ``Phi_np``): adds ``Phi_nn P_np`` to it (zero entries of ``Phi_nn`` skipped), then
    ``P_nn' = (Phi_nn P_nn + Phi_np P_pn) Phi_nn^T + P_np' Phi_np^T + Q_nn``; ``t1``, ``new_nn`` (n, n) work."""
    N = P.shape[0]
    p = N - n
    for i in range(n):
        for l in range(n):
            al = phi_nn[i, l]
            if al != 0.0:
                for c in range(p):
                    new_np[i, c] += al * P[l, n + c]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for l in range(n):
                acc += phi_nn[i, l] * P[l, j]
            for l in range(p):
                acc += phi_np[i, l] * P[j, n + l]
            t1[i, j] = acc
    for i in range(n):
        for j in range(n):
            acc = q_nn[i, j]
            for l in range(n):
                acc += t1[i, l] * phi_nn[j, l]
            for l in range(p):
                acc += new_np[i, l] * phi_np[j, l]
            new_nn[i, j] = acc
    store_predicted(P, n, new_nn, new_np)


@njit(cache=True, fastmath=True)
def predict_params(P, n, phi_p, q_p):
    """The parameters' own transition after :func:`predict_into`: first-order Gauss-Markov states
    ``x_p <- diag(phi_p) x_p + w``, ``w ~ N(0, diag q_p)``, applied to the rows and columns of ``P`` in place."""
    p = P.shape[0] - n
    for c in range(p):
        for i in range(n):
            P[i, n + c] *= phi_p[c]
            P[n + c, i] = P[i, n + c]
        for d in range(p):
            P[n + c, n + d] *= phi_p[c] * phi_p[d]
        P[n + c, n + c] += q_p[c]


@njit(cache=True, fastmath=True)
def update_block(P, i0, r, PHt, S, K):
    """Covariance-only update by a measurement of the consecutive states ``i0 .. i0 + m - 1`` with noise variances
    ``r`` (m,), in the form ``P <- P - K^T (H P)`` (row layout: ``PHt`` (m, N) receives ``H P``, ``K`` (m, N) the
    gain rows ``S^-1 H P``; ``S`` (m, m) work); ``P`` stays symmetric."""
    N = P.shape[0]
    m = r.shape[0]
    for a in range(m):
        for i in range(N):
            PHt[a, i] = P[i0 + a, i]
    for a in range(m):
        for b in range(m):
            S[a, b] = 0.5 * (PHt[a, i0 + b] + PHt[b, i0 + a])
        S[a, a] += r[a]
    Si = np.linalg.inv(S)
    for a in range(m):
        for i in range(N):
            K[a, i] = 0.0
        for b in range(m):
            sab = Si[a, b]
            for i in range(N):
                K[a, i] += sab * PHt[b, i]
    for i in range(N):
        for a in range(m):
            ki = K[a, i]
            for j in range(i, N):
                P[i, j] -= ki * PHt[a, j]
    for i in range(N):
        for j in range(i + 1, N):
            P[j, i] = P[i, j]


@njit(cache=True, fastmath=True)
def update_row(P, h, r, ph, k):
    """Covariance-only update by one scalar measurement ``h^T x`` (``h`` (N,), noise variance ``r``): ``ph = P h``
    and the gain ``k = ph / (h^T P h + r)`` written, ``P <- P - k ph^T`` (symmetric)."""
    N = P.shape[0]
    for i in range(N):
        acc = 0.0
        for j in range(N):
            acc += P[i, j] * h[j]
        ph[i] = acc
    sv = r
    for i in range(N):
        sv += h[i] * ph[i]
    for i in range(N):
        k[i] = ph[i] / sv
    for i in range(N):
        for j in range(i, N):
            v = P[i, j] - k[i] * ph[j]
            P[i, j] = v
            P[j, i] = v
