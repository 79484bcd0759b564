"""The structured closed-loop filter and its MBF smoother against the textbook dense Kalman
filter and RTS smoother (S16 eq. 13-16) on a small random linear system."""

from __future__ import annotations

import numpy as np
import pytest

from inscal.core import kalman as filters


def _system(rng, n=3, p=2, m=2, M=40, qp=0.0):
    phinn = [np.eye(n) + 0.2 * rng.standard_normal((n, n)) for _ in range(M + 1)]
    phinp = [0.5 * rng.standard_normal((n, p)) for _ in range(M + 1)]
    A = rng.standard_normal((n, n))
    qnn = 0.05 * (A @ A.T) + 0.01 * np.eye(n)
    q_p = np.full(p, qp)
    idx = np.array([0, n - 1][:m], dtype=np.int64)
    r = np.array([0.3, 0.02][:m])
    return phinn, phinp, qnn, q_p, idx, r


def _dense_phi(pn, pp):
    n, p = pp.shape
    F = np.eye(n + p)
    F[:n, :n] = pn
    F[:n, n:] = pp
    return F


@pytest.mark.parametrize("qp", [0.0, 1e-3])
def test_structured_closed_loop_filter_and_mbf_equal_dense_rts(qp):
    rng = np.random.default_rng(7)
    n, p, M = 3, 2, 40
    phinn, phinp, qnn, q_p, idx, r = _system(rng, n, p, 2, M, qp)
    N = n + p
    H = np.zeros((len(idx), N))
    H[np.arange(len(idx)), idx] = 1.0
    Q = np.zeros((N, N))
    Q[:n, :n] = qnn
    Q[n:, n:] = np.diag(q_p)
    P0 = np.diag(rng.uniform(0.5, 2.0, N))
    x_true = rng.standard_normal(N) * np.sqrt(np.diag(P0))
    zs = []
    for k in range(1, M + 1):
        x_true = _dense_phi(phinn[k], phinp[k]) @ x_true + rng.multivariate_normal(np.zeros(N), Q)
        zs.append(H @ x_true + rng.standard_normal(len(idx)) * np.sqrt(r))
    # --- dense, open loop (textbook)
    xf, Pf, xp, Pp, Phis = [np.zeros(N)], [P0.copy()], [None], [None], [None]
    for k in range(1, M + 1):
        F = _dense_phi(phinn[k], phinp[k])
        x_ = F @ xf[-1]
        P_ = F @ Pf[-1] @ F.T + Q
        S = H @ P_ @ H.T + np.diag(r)
        K = P_ @ H.T @ np.linalg.inv(S)
        xf.append(x_ + K @ (zs[k - 1] - H @ x_))
        Pf.append((np.eye(N) - K @ H) @ P_)
        xp.append(x_)
        Pp.append(P_)
        Phis.append(F)
    xs, Ps = filters.dense_rts(xf, Pf, xp, Pp, Phis)
    # --- structured, closed loop: reference y, error e = y - x; estimate fed back every step
    P = P0.copy()
    y = np.zeros(N)
    K_st = np.empty((M, N, len(idx)))
    Si_st = np.empty((M, len(idx), len(idx)))
    sz_st = np.empty((M, len(idx)))
    Pm = np.empty((M, N, N))
    yref = np.empty((M, N))
    Kk = np.empty((N, len(idx)))
    Si = np.empty((len(idx), len(idx)))
    xh = np.empty(N)
    for k in range(1, M + 1):
        filters.predict(P, n, phinn[k], np.ascontiguousarray(phinp[k]), qnn, q_p)
        y = _dense_phi(phinn[k], phinp[k]) @ y
        np.testing.assert_allclose(P, Pp[k], rtol=1e-11, atol=1e-13)
        Pm[k - 1] = P
        yref[k - 1] = y
        z = H @ y - zs[k - 1]
        filters.update(P, idx, r, z, Kk, Si, xh)
        K_st[k - 1], Si_st[k - 1], sz_st[k - 1] = Kk, Si, Si @ z
        y = y - xh  # feedback (S16 eq. 27)
        np.testing.assert_allclose(y, xf[k], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(P, Pf[k], rtol=1e-10, atol=1e-12)
    # --- MBF backwards: smoothed error of the pre-update reference
    lam = np.zeros(N)
    Lam = np.zeros((N, N))
    for k in range(M, 0, -1):
        filters.smoother_step(lam, Lam, idx, K_st[k - 1], Si_st[k - 1], sz_st[k - 1])
        e, Pk = filters.smoothed(Pm[k - 1], lam, Lam)
        np.testing.assert_allclose(yref[k - 1] - e, xs[k], rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(Pk, Ps[k], rtol=1e-9, atol=1e-11)
        filters.adjoint_back(lam, Lam, n, phinn[k], np.ascontiguousarray(phinp[k]))
    e0, P0s = filters.smoothed(P0, lam, Lam)
    np.testing.assert_allclose(-e0, xs[0], rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(P0s, Ps[0], rtol=1e-9, atol=1e-11)
    if qp == 0.0:  # constant parameters: smoothed = final filtered at every step
        for k in range(M + 1):
            np.testing.assert_allclose(xs[k][n:], xf[M][n:], rtol=1e-9, atol=1e-11)


def test_joseph_update_keeps_covariance_symmetric_positive_with_tiny_noise():
    rng = np.random.default_rng(3)
    N = 12
    A = rng.standard_normal((N, N))
    P = A @ A.T + np.eye(N)
    idx = np.array([1, 4, 7], dtype=np.int64)
    K = np.empty((N, 3))
    Si = np.empty((3, 3))
    x = np.empty(N)
    for _ in range(50):
        filters.update(P, idx, np.full(3, 1e-14), rng.standard_normal(3), K, Si, x)
        assert np.array_equal(P, P.T)
        assert np.min(np.linalg.eigvalsh(P)) > -1e-12 * np.max(np.diag(P))


# ----------------------------------------------------------------------------- square-root form
def _upper_factor(P):
    """An upper-triangular U with U U^T = P (the reversed Cholesky)."""
    J = np.eye(P.shape[0])[::-1]
    return J @ np.linalg.cholesky(J @ P @ J) @ J


def _spd(rng, N, spread=0.0):
    A = rng.normal(size=(N, N))
    D = np.diag(10.0 ** rng.uniform(-spread, spread, N))
    return D @ (A @ A.T + N * np.eye(N)) @ D


@pytest.mark.parametrize("spread", [0.0, 3.0])
def test_sr_predict_and_updates_equal_the_covariance_forms(spread):
    rng = np.random.default_rng(7)
    N, n = 20, 9
    P = _spd(rng, N, spread)
    U = _upper_factor(P)
    assert np.allclose(np.triu(U), U) and np.allclose(U @ U.T, P, rtol=1e-12, atol=1e-12 * np.abs(P).max())
    phi_nn = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    phi_np = 0.1 * rng.normal(size=(n, N - n))
    B = rng.normal(size=(n, 4))
    q = B @ B.T  # rank 4: semi-definite, as the navigation noise of the position rows
    Pp = P.copy()
    filters.predict(Pp, n, phi_nn, phi_np, q, np.zeros(N - n))
    filters.sr_predict(U, n, phi_nn, phi_np, q)
    assert np.allclose(np.triu(U), U)
    assert np.allclose(U @ U.T, Pp, rtol=1e-10, atol=1e-10 * np.abs(Pp).max())
    idx = np.array([3, 4, 5, 6, 7, 8])
    r = rng.uniform(0.1, 2.0, 6)
    z = rng.normal(size=6)
    K1, S1, x1 = np.empty((N, 6)), np.empty((6, 6)), np.empty(N)
    K2, S2, x2 = np.empty((N, 6)), np.empty((6, 6)), np.empty(N)
    nis1 = filters.update(Pp, idx, r, z, K1, S1, x1)
    nis2, alpha = filters.sr_update(U, idx, r, z, K2, S2, x2)
    assert nis2 == pytest.approx(nis1, rel=1e-10) and alpha == 1.0
    assert np.allclose(K2, K1, rtol=1e-9, atol=1e-12) and np.allclose(x2, x1, rtol=1e-9, atol=1e-12)
    assert np.allclose(np.triu(U), U) and np.allclose(U @ U.T, Pp, rtol=1e-9, atol=1e-10 * np.abs(Pp).max())
    H = rng.normal(size=(3, N))
    C = rng.normal(size=(3, 3))
    R = C @ C.T + np.eye(3)
    nu = rng.normal(size=3)
    K1, S1, x1 = np.empty((N, 3)), np.empty((3, 3)), np.empty(N)
    K2, S2, x2 = np.empty((N, 3)), np.empty((3, 3)), np.empty(N)
    nis1 = filters.update_dense(Pp, H, R, nu, K1, S1, x1)
    nis2 = filters.sr_update_dense(U, H, R, nu, K2, S2, x2)
    assert nis2 == pytest.approx(nis1, rel=1e-10) and np.allclose(K2, K1, rtol=1e-9, atol=1e-12)
    assert np.allclose(U @ U.T, Pp, rtol=1e-9, atol=1e-10 * np.abs(Pp).max())


def test_sr_update_stays_positive_semidefinite():
    """Measurements 1e8 times more precise than the prior, repeated 50 times on a covariance spanning 1e8:
    the factor stays finite and U U^T positive semi-definite to round-off, by construction."""
    rng = np.random.default_rng(1)
    N = 12
    P = _spd(rng, N, 4.0)
    U = _upper_factor(P)
    idx = np.arange(6)
    r = np.full(6, 1e-16) * np.diag(P)[:6]
    K, S, x = np.empty((N, 6)), np.empty((6, 6)), np.empty(N)
    for _ in range(50):
        filters.sr_update(U, idx, r, rng.normal(size=6) * 1e-8, K, S, x)
    ev = np.linalg.eigvalsh(U @ U.T)
    assert ev.min() >= -1e-14 * ev.max() and np.all(np.isfinite(U))


# ----------------------------------------------------------------------------- constant parameters, informative data
def _batch_smoother(P0, phis, qnn, H, r, zs, n):
    """Independent reference: the fixed-interval smoother as one batch least-squares problem in the unknowns
    ``theta = [x_0, w_1 .. w_M]`` (``x_k = Phi_k x_{k-1} + [w_k; 0]``), whitened and solved by QR (no Kalman
    recursion, no inverse of an ill-conditioned covariance).  Returns the smoothed states and covariances at
    k = 0..M."""
    N = P0.shape[0]
    M = len(zs)
    nt = N + n * M
    Lq = np.linalg.cholesky(qnn)
    A = [np.zeros((N, nt))]
    A[0][:, :N] = np.eye(N)
    rows, rhs = [np.linalg.solve(np.linalg.cholesky(P0), A[0])], [np.zeros(N)]
    for k in range(1, M + 1):
        Ak = phis[k] @ A[-1]
        Ak[:n, N + n * (k - 1):N + n * k] += Lq  # w_k = Lq u_k, u_k ~ N(0, I)
        A.append(Ak)
        prior = np.zeros((n, nt))
        prior[:, N + n * (k - 1):N + n * k] = np.eye(n)
        rows.append(prior)
        rhs.append(np.zeros(n))
        rows.append((H @ Ak) / np.sqrt(r)[:, None])
        rhs.append(zs[k - 1] / np.sqrt(r))
    Q_, R_ = np.linalg.qr(np.vstack(rows))
    theta = np.linalg.solve(R_, Q_.T @ np.concatenate(rhs))
    Ri = np.linalg.solve(R_, np.eye(nt))  # Cov(theta) = Ri Ri^T
    return [Ak @ theta for Ak in A], [(Ak @ Ri) @ (Ak @ Ri).T for Ak in A]


def test_smoothed_constant_keeps_the_constants_when_the_data_dwarf_the_prior():
    """Zero-velocity-like updates ~1e10 times more informative than the prior: ``Pm - Pm Lam Pm`` of the plain MBF
    form cancels catastrophically in the constants' directions (their variances far off, negative); the split form
    (:func:`inscal.core.kalman.smoothed_constant`) gives the final filtered constants at every step, and the batch
    least-squares smoother's covariances once the predicted covariance is no longer the prior's (the first steps'
    unmeasured dynamic state keeps a cancellation of its own, orders of magnitude smaller than the plain form's)."""
    rng = np.random.default_rng(11)
    n, p, M = 3, 4, 60
    N = n + p
    idx = np.array([1, 2], dtype=np.int64)
    r = np.array([1e-10, 1e-10])
    H = np.zeros((2, N))
    H[[0, 1], idx] = 1.0
    qnn = 1e-10 * np.eye(n)
    phinn = [np.eye(n) + 0.1 * rng.standard_normal((n, n)) for _ in range(M + 1)]
    phinp = [np.ascontiguousarray(rng.standard_normal((n, p))) for _ in range(M + 1)]
    phis = [None] + [_dense_phi(phinn[k], phinp[k]) for k in range(1, M + 1)]
    x = rng.standard_normal(N)
    zs = []
    for k in range(1, M + 1):
        x = phis[k] @ x
        x[:n] += rng.standard_normal(n) * 1e-5
        zs.append(H @ x + rng.standard_normal(2) * 1e-5)
    xs_ref, Ps_ref = _batch_smoother(np.eye(N), phis, qnn, H, r, zs, n)
    # closed-loop square-root filter (as the systematic kernel): reference y, error e = y - x, fed back
    U = np.eye(N)
    y = np.zeros(N)
    K_st, Si_st, sz_st = np.empty((M, N, 2)), np.empty((M, 2, 2)), np.empty((M, 2))
    Pm, yref, xh_st = np.empty((M, N, N)), np.empty((M, N)), np.empty((M, N))
    Kk, Si, xh = np.empty((N, 2)), np.empty((2, 2)), np.empty(N)
    for k in range(1, M + 1):
        filters.sr_predict(U, n, phinn[k], phinp[k], qnn)
        y = phis[k] @ y
        Pm[k - 1], yref[k - 1] = U @ U.T, y
        z = H @ y - zs[k - 1]
        filters.sr_update(U, idx, r, z, Kk, Si, xh)
        K_st[k - 1], Si_st[k - 1], sz_st[k - 1], xh_st[k - 1] = Kk, Si, Si @ z, xh
        y = y - xh
    Pf = U @ U.T
    np.testing.assert_allclose(y, xs_ref[M], atol=1e-6 * np.sqrt(np.diag(Pf)).min())
    rem = np.cumsum(xh_st[::-1, n:], axis=0)[::-1]  # the constants' feedback from step k on
    lam, Lam = np.zeros(N), np.zeros((N, N))
    worst_plain = 0.0
    for k in range(M, -1, -1):
        if k > 0:
            filters.smoother_step(lam, Lam, idx, K_st[k - 1], Si_st[k - 1], sz_st[k - 1])
        Pk_m, ref = (Pm[k - 1], yref[k - 1]) if k > 0 else (np.eye(N), np.zeros(N))
        e, Pk = filters.smoothed_constant(Pk_m, lam, Lam, n, rem[max(k - 1, 0)], np.ascontiguousarray(Pf[n:, n:]))
        e_plain, P_plain = filters.smoothed(Pk_m, lam, Lam)
        s = np.sqrt(np.diag(Ps_ref[k]))
        o = np.outer(s, s)
        # the constants: the final filtered ones, at every step
        np.testing.assert_allclose((ref - e)[n:] / s[n:], xs_ref[k][n:] / s[n:], rtol=0, atol=1e-4)
        np.testing.assert_allclose(Pk[n:, n:] / o[n:, n:], Ps_ref[k][n:, n:] / o[n:, n:], rtol=0, atol=1e-6)
        worst_plain = max(worst_plain, np.max(np.abs(np.diag(P_plain)[n:] / np.diag(Ps_ref[k])[n:] - 1.0)))
        assert np.array_equal(e[:n], e_plain[:n])  # the dynamic states: the plain form's (Pm lam)_n
        for b in (np.s_[:n, :n], np.s_[:n, n:]):  # their covariance: never worse than the plain form's
            assert np.max(np.abs(Pk - Ps_ref[k])[b] / o[b]) <= np.max(np.abs(P_plain - Ps_ref[k])[b] / o[b]) + 1e-6
        if k >= 5:  # the data dominate the predicted covariance: everything agrees
            assert np.max(np.abs(ref - e - xs_ref[k]) / s) < 1e-4
            np.testing.assert_allclose(Pk / o, Ps_ref[k] / o, rtol=0, atol=1e-6)
        if k > 0:
            filters.adjoint_back(lam, Lam, n, phinn[k], phinp[k])
    assert worst_plain > 1.0  # the case is hard: the plain form's constant variances are off by more than 100 %


def _decimal_rts_covariances(P0, phis, qnn, H, r, n, digits=50):
    """Independent reference: the textbook dense Kalman filter (Joseph update) and RTS smoother (S16 eq. 13-16)
    in ``digits``-digit decimal arithmetic (numpy object arrays of :class:`decimal.Decimal`; Gauss-Jordan inverse),
    so the RTS form's own cancellation (``P_f + A (P_s - P_p) A^T``, data 1e10 times the prior) costs nothing at
    double precision.  Returns the smoothed covariances at k = 0..M as floats."""
    import decimal

    decimal.getcontext().prec = digits

    def dec(A):
        return np.array([[decimal.Decimal(repr(float(x))) for x in row] for row in np.atleast_2d(A)], dtype=object)

    def inv(A):
        m = A.shape[0]
        G = np.concatenate([A, dec(np.eye(m))], axis=1)
        for c in range(m):
            piv = max(range(c, m), key=lambda i: abs(G[i, c]))
            G[[c, piv]] = G[[piv, c]]
            G[c] = G[c] / G[c, c]
            for i in range(m):
                if i != c:
                    G[i] = G[i] - G[i, c] * G[c]
        return G[:, m:]

    N = P0.shape[0]
    M = len(phis) - 1
    Q = np.zeros((N, N))
    Q[:n, :n] = qnn
    Qd, Hd, Rd, I = dec(Q), dec(H), dec(np.diag(r)), dec(np.eye(N))
    Pf, Pp, Fd = [dec(P0)], [None], [None]
    for k in range(1, M + 1):
        F = dec(phis[k])
        P_ = F @ Pf[-1] @ F.T + Qd
        K = P_ @ Hd.T @ inv(Hd @ P_ @ Hd.T + Rd)
        IKH = I - K @ Hd
        Pf.append(IKH @ P_ @ IKH.T + K @ Rd @ K.T)
        Pp.append(P_)
        Fd.append(F)
    Ps = [None] * (M + 1)
    Ps[M] = Pf[M]
    for j in range(M, 0, -1):
        A = Pf[j - 1] @ Fd[j].T @ inv(Pp[j])
        Ps[j - 1] = Pf[j - 1] + A @ (Ps[j] - Pp[j]) @ A.T
    return [np.array(P, dtype=float) for P in Ps]


def test_square_root_information_smoother_against_a_50_digit_reference():
    """Data 1e10 times more informative than the prior: the smoothed covariance of the square-root information
    smoother (:func:`inscal.core.kalman.sr_smoothed`, the backward information carried by :func:`info_rows` and
    :func:`info_back`) is positive definite at every step and within 2e-6 of a 50-digit dense RTS smoother (in units
    of the reference's sigma_i sigma_j; 1e-8 once the data dominate the predicted covariance: the floor of a
    predicted covariance handed over formed, eps / smallest smoothed variance), where the MBF forms, plain and split,
    lose positivity on the first steps and are off by orders of magnitude."""
    rng = np.random.default_rng(11)
    n, p, M = 3, 4, 40
    N = n + p
    idx = np.array([1, 2], dtype=np.int64)
    r = np.array([1e-10, 1e-10])
    H = np.zeros((2, N))
    H[[0, 1], idx] = 1.0
    qnn = 1e-10 * np.eye(n)
    phinn = [np.eye(n) + 0.1 * rng.standard_normal((n, n)) for _ in range(M + 1)]
    phinp = [np.ascontiguousarray(rng.standard_normal((n, p))) for _ in range(M + 1)]
    phis = [None] + [_dense_phi(phinn[k], phinp[k]) for k in range(1, M + 1)]
    ref = _decimal_rts_covariances(np.eye(N), phis, qnn, H, r, n)
    # the closed-loop square-root filter (as the systematic kernel); the covariances do not depend on the data
    U = np.eye(N)
    K_st, Si_st, Pm = np.empty((M, N, 2)), np.empty((M, 2, 2)), np.empty((M, N, N))
    Kk, Si, xh = np.empty((N, 2)), np.empty((2, 2)), np.empty(N)
    for k in range(1, M + 1):
        filters.sr_predict(U, n, phinn[k], phinp[k], qnn)
        Pm[k - 1] = U @ U.T
        filters.sr_update(U, idx, r, np.zeros(2), Kk, Si, xh)
        K_st[k - 1], Si_st[k - 1] = Kk, Si
    Upp = np.ascontiguousarray(U[n:, n:])
    Ppp = np.ascontiguousarray((U @ U.T)[n:, n:])
    G = filters.noise_factor(qnn)
    assert np.allclose(G @ G.T, qnn, rtol=1e-12, atol=0)
    Rb = np.zeros((N, N))
    lam, Lam = np.zeros(N), np.zeros((N, N))
    mbf_fails = 0
    for k in range(M, -1, -1):
        if k > 0:
            filters.info_rows(Rb, idx, r)
            filters.smoother_step(lam, Lam, idx, K_st[k - 1], Si_st[k - 1], np.zeros(2))
        Pk = np.ascontiguousarray(Pm[k - 1]) if k > 0 else np.eye(N)
        P = filters.sr_smoothed(Pk, Rb, n, Upp)
        s = np.sqrt(np.diag(ref[k]))
        err = np.max(np.abs(P - ref[k]) / np.outer(s, s))
        np.linalg.cholesky(P)  # positive definite at every step
        assert err < (2e-6 if k < 5 else 1e-8), (k, err)
        np.testing.assert_allclose(P[n:, n:], Ppp, rtol=1e-13, atol=1e-13 * np.max(np.abs(Ppp)))
        _, P_split = filters.smoothed_constant(Pk, lam, Lam, n, np.zeros(p), Ppp)
        _, P_plain = filters.smoothed(Pk, lam, Lam)
        if k < 3:  # the MBF forms on the first steps: far off and indefinite
            assert np.max(np.abs(P_split - ref[k]) / np.outer(s, s)) > 1.0
            assert np.max(np.abs(P_plain - ref[k]) / np.outer(s, s)) > 1e3
            mbf_fails += int(np.linalg.eigvalsh(P_split)[0] < 0) + int(np.linalg.eigvalsh(P_plain)[0] < 0)
        if k > 0:
            filters.info_back(Rb, n, phinn[k], phinp[k], G)
            filters.adjoint_back(lam, Lam, n, phinn[k], phinp[k])
    assert mbf_fails == 6


def test_information_steps_equal_their_covariance_forms():
    """:func:`info_rows`, :func:`info_rows_dense` and :func:`info_back` against the information they stand for,
    formed directly: rows add ``H^T R^-1 H``; the step back gives ``Phi^T (I_b^-1 + Q)^-1 Phi`` (a full-rank case)."""
    rng = np.random.default_rng(4)
    n, p = 3, 2
    N = n + p
    A = rng.standard_normal((N, N))
    Rb = np.linalg.cholesky(A @ A.T + np.eye(N)).T  # upper triangular
    Ib = Rb.T @ Rb
    R1 = Rb.copy()
    filters.info_rows(R1, np.array([0, 2], dtype=np.int64), np.array([0.5, 2.0]))
    Hs = np.eye(N)[[0, 2]]
    np.testing.assert_allclose(R1.T @ R1, Ib + Hs.T @ np.diag([2.0, 0.5]) @ Hs, rtol=1e-12)
    assert np.allclose(R1, np.triu(R1)) and np.all(np.diag(R1) >= 0)
    Hd = rng.standard_normal((2, N))
    B = rng.standard_normal((2, 2))
    Rm = B @ B.T + np.eye(2)
    R2 = Rb.copy()
    filters.info_rows_dense(R2, Hd, Rm)
    np.testing.assert_allclose(R2.T @ R2, Ib + Hd.T @ np.linalg.solve(Rm, Hd), rtol=1e-11)
    pn, pp = np.eye(n) + 0.3 * rng.standard_normal((n, n)), rng.standard_normal((n, p))
    C = rng.standard_normal((n, n))
    qnn = C @ C.T + 0.1 * np.eye(n)
    R3 = Rb.copy()
    filters.info_back(R3, n, pn, pp, filters.noise_factor(qnn))
    Phi = _dense_phi(pn, pp)
    Q = np.zeros((N, N))
    Q[:n, :n] = qnn
    np.testing.assert_allclose(R3.T @ R3, Phi.T @ np.linalg.inv(np.linalg.inv(Ib) + Q) @ Phi, rtol=1e-10)
    assert np.allclose(R3, np.triu(R3))


def test_covariance_only_forms_equal_the_filter_forms():
    """The bound's allocation-free forms against the filter's: predict_into (with Phi_np P_pp given) and
    predict_params against the dense Phi P Phi^T + Q, update_block against the Joseph update of the same states,
    update_row against the dense update by one row."""
    rng = np.random.default_rng(3)
    N, n = 14, 9
    P = _spd(rng, N)
    phi_nn = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    phi_nn[0, 5] = 0.0  # a zero the form skips
    phi_np = 0.1 * rng.normal(size=(n, N - n))
    B = rng.normal(size=(n, n))
    q = B @ B.T
    phi_p = rng.uniform(0.9, 1.0, N - n)
    q_p = rng.uniform(0.0, 0.1, N - n)
    F = _dense_phi(phi_nn, phi_np)
    F[n:, n:] = np.diag(phi_p)
    Q = np.zeros((N, N))
    Q[:n, :n] = q
    Q[n:, n:] = np.diag(q_p)
    ref = F @ P @ F.T + Q
    got = P.copy()
    new_np = phi_np @ P[n:, n:]
    filters.predict_into(got, n, phi_nn, phi_np, new_np, q, np.empty((n, n)), np.empty((n, n)))
    filters.predict_params(got, n, phi_p, q_p)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    r = rng.uniform(0.1, 2.0, 6)
    joseph = ref.copy()
    filters.update(joseph, np.arange(3, 9), r, np.zeros(6), np.empty((N, 6)), np.empty((6, 6)), np.empty(N))
    K = np.empty((6, N))
    filters.update_block(got, 3, r, np.empty((6, N)), np.empty((6, 6)), K)
    np.testing.assert_allclose(got, joseph, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    assert np.array_equal(got, got.T)
    h = rng.normal(size=N)
    dense = got.copy()
    Kd = np.empty((N, 1))
    filters.update_dense(dense, h[None, :], np.array([[0.5]]), np.zeros(1), Kd, np.empty((1, 1)), np.empty(N))
    k = np.empty(N)
    filters.update_row(got, h, 0.5, np.empty(N), k)
    np.testing.assert_allclose(k, Kd[:, 0], rtol=1e-12)
    np.testing.assert_allclose(got, dense, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
