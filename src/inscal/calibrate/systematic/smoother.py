"""The smoother of the systematic filter (inscal.core.kalman): backwards over the stores of a forward pass
(:mod:`inscal.calibrate.systematic.kernel`), the modified Bryson-Frazier adjoint recursion for the smoothed
states, and for their covariances a square-root information filter run backwards, combined with the forward
pass's predicted covariance in the two-filter form (:func:`inscal.core.kalman.sr_smoothed`), at the stored steps
and the start.

The MBF covariance ``P_{k|k-1} - P_{k|k-1} Lam P_{k|k-1}`` subtracts two information-sized terms: where the
predicted covariance is still the prior's (the first steps) and the rest of the record pins a state down by many
orders of magnitude, it cancels, and the first stored step's navigation covariance lost its positivity (an
unmeasured attitude variance below zero on the S16 record).  The square-root information ``Rb`` (``Rb^T Rb`` the
information of the measurements at and after a step) only ever has rows rotated into it, and the smoothed
covariance is a product ``W W^T``: positive semi-definite at every step by construction.  It needs each step's
``Q_d`` and ``R`` (stored by the pass) besides ``Phi``; the MBF state recursion needs only the gains.

Like the forward pass, each compiled kernel processes a range of steps and its Python driver calls it in
slices (:func:`inscal.core.slices.run_in_slices`), so an interrupt is honoured between two slices."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from inscal.calibrate.systematic.states import IDX_MEAS
from inscal.core import kalman as filters
from inscal.core.slices import run_in_slices


class SmootherData(NamedTuple):
    """What the smoother needs of a pass (the forward pass's :class:`PassStore` and
    :class:`EncoderRows` less what only the filter uses)."""

    K_st: np.ndarray
    Si_st: np.ndarray
    sz_st: np.ndarray
    phinn_st: np.ndarray
    phinp_st: np.ndarray
    hist_every: int
    att_used: np.ndarray
    Ka_st: np.ndarray
    Sia_st: np.ndarray
    sza_st: np.ndarray
    Ha_st: np.ndarray
    enc_floor: float
    qd_st: np.ndarray  # (M, nd, nd) the process noise of each step's prediction (scaled)
    r_meas: np.ndarray  # (6,) the zero-velocity/position measurement variances (scaled)
    rw_st: np.ndarray  # (M,) the factor on them each step ran with
    Ra_st: np.ndarray  # (Ma, 3, 3) the encoder rows' R


@njit(cache=True)
def dense_rows_adjoint(lam, K, sz, H, d):
    """The MBF adjoint step of three dense measurement rows (the encoder attitude): ``d = sz - K^T lam``,
    ``lam += H^T d``, in place (``d`` (3,) scratch)."""
    N = lam.shape[0]
    for a in range(3):
        s = sz[a]
        for i in range(N):
            s -= K[i, a] * lam[i]
        d[a] = s
    for i in range(N):
        lam[i] += H[0, i] * d[0] + H[1, i] * d[1] + H[2, i] * d[2]


@njit(cache=True)
def stored_before(k, M, hist_every):
    """How many of the steps ``0 .. k - 1`` store a history row (every ``hist_every``-th step and the
    last, ``M - 1``): the row index of the next stored step."""
    n = (k + hist_every - 1) // hist_every
    if k == M and (M - 1) % hist_every != 0:
        n += 1
    return n


@njit(cache=True)
def add_feedback(rem, K, Si, sz, n):
    """``rem += (K nu)[n:]``: the constants' part of one update's estimate (fed back by the closed loop), with the
    innovation ``nu`` recovered from the stored ``S^-1`` and ``S^-1 nu`` (a Cholesky solve of the SPD ``S^-1``)."""
    m = Si.shape[0]
    L = np.zeros((m, m))
    for j in range(m):
        d = Si[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        d = math.sqrt(d)
        L[j, j] = d
        for i in range(j + 1, m):
            v = 0.5 * (Si[i, j] + Si[j, i])
            for k in range(j):
                v -= L[i, k] * L[j, k]
            L[i, j] = v / d
    y = np.empty(m)
    for i in range(m):
        v = sz[i]
        for k in range(i):
            v -= L[i, k] * y[k]
        y[i] = v / L[i, i]
    for i in range(m - 1, -1, -1):
        v = y[i]
        for k in range(i + 1, m):
            v -= L[k, i] * y[k]
        y[i] = v / L[i, i]
    N = K.shape[0]
    for i in range(n, N):
        v = 0.0
        for a in range(m):
            v += K[i, a] * y[a]
        rem[i - n] += v


@njit(cache=True)
def smooth_steps(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, qd_st, r_meas, rw_st, hist_every, M, hist_Pm, hist_x,
                  hist_P, x0, Pc0, att_used, Ka_st, Sia_st, sza_st, Ha_st, Ra_st, lam, Rb, k0, k1, rem, Upp):
    """Steps ``k1 - 1`` down to ``k0`` of the backward pass (:func:`smooth_kernel` runs them all in slices):
    smoothed errors and covariances at the stored steps and, with ``k0 == 0``, at the start (``x0``, ``Pc0``).
    ``lam`` (the MBF adjoint vector) and ``Rb`` (the square-root information of the measurements from step ``k1``
    on, about the state after step ``k1 - 1``) are handed from step ``k1`` to step ``k0 - 1``, in place.  Steps with
    encoder attitude rows (``att_used``) undo that second, later update first.

    The smoothed errors are the MBF adjoint's (inscal.core.kalman): the dynamic states ``(P_{k|k-1} lam)_n``, the
    constants the feedback still to come (``rem``, accumulated from the last step back: with no process noise their
    smoothed estimate is the final filtered one).  The covariances: :func:`inscal.core.kalman.sr_smoothed` of the
    stored predicted covariance and ``Rb``, the constants' factor the final filtered ``Upp``."""
    nd = phinn_st.shape[1]
    ih = stored_before(k1, M, hist_every) - 1
    r = np.empty(r_meas.shape[0])
    d = np.empty(3)
    N = lam.shape[0]
    for k in range(k1 - 1, k0 - 1, -1):
        if att_used.shape[0] > 0 and att_used[k]:  # the encoder attitude rows (the later update)
            dense_rows_adjoint(lam, Ka_st[k], sza_st[k], Ha_st[k], d)
            filters.info_rows_dense(Rb, Ha_st[k], Ra_st[k])
            add_feedback(rem, Ka_st[k], Sia_st[k], sza_st[k], nd)
        K = K_st[k]
        ktl = K.T @ lam
        for a in range(IDX_MEAS.shape[0]):
            lam[IDX_MEAS[a]] += sz_st[k, a] - ktl[a]
            r[a] = r_meas[a] * rw_st[k]
        filters.info_rows(Rb, IDX_MEAS, r)
        add_feedback(rem, K, Si_st[k], sz_st[k], nd)
        if k % hist_every == 0 or k == M - 1:
            hist_x[ih, :nd] = hist_Pm[ih, :nd] @ lam
            hist_x[ih, nd:] = rem
            hist_P[ih] = filters.sr_smoothed(hist_Pm[ih], Rb, nd, Upp)
            ih -= 1
        ln = lam[:nd].copy()
        lam[nd:] = lam[nd:] + phinp_st[k].T @ ln
        lam[:nd] = phinn_st[k].T @ ln
        filters.info_back(Rb, nd, phinn_st[k], phinp_st[k], filters.noise_factor(qd_st[k]))
    if k0 == 0:
        x0[:nd] = P0[:nd, :] @ lam
        x0[nd:] = rem
        Pc0[:, :] = filters.sr_smoothed(P0, Rb, nd, Upp)


def backward(M: int, steps) -> None:
    """Run ``steps(k0, k1)`` over ``M - 1 .. 0`` backwards in slices (the last call has ``k0 == 0``; one
    call ``(0, 0)`` when ``M == 0``)."""
    if M == 0:
        steps(0, 0)
    run_in_slices(M, lambda j0, j1: steps(M - j1, M - j0), first=2048)


def smooth_kernel(P0, sm: SmootherData, M, hist_Pm, hist_x, hist_P, x0, Pc0, Upp) -> None:
    """The backward pass over all ``M`` steps of a pass's stores ``sm`` (:func:`smooth_steps`), in slices of steps so
    that an interrupt is honoured between two; the adjoint vector and the square-root information live here between
    slices.  ``P0``: the prior covariance (scaled); ``Upp``: the upper-triangular factor of the constants' final
    filtered covariance (scaled)."""
    N = P0.shape[0]
    lam = np.zeros(N)
    Rb = np.zeros((N, N))
    rem = np.zeros(N - sm.phinn_st.shape[1])
    Upp = np.ascontiguousarray(Upp, dtype=float)
    backward(M, lambda k0, k1: smooth_steps(P0, sm.K_st, sm.Si_st, sm.sz_st, sm.phinn_st, sm.phinp_st, sm.qd_st,
                                              sm.r_meas, sm.rw_st, sm.hist_every, M, hist_Pm, hist_x, hist_P, x0, Pc0,
                                              sm.att_used, sm.Ka_st, sm.Sia_st, sm.sza_st, sm.Ha_st, sm.Ra_st, lam, Rb,
                                              k0, k1, rem, Upp))


@njit(cache=True)
def smooth_vector_steps(K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, x0, att_used, Ka_st,
                         Sia_st, sza_st, Ha_st, lam, k0, k1, rem):
    """Steps ``k1 - 1`` down to ``k0`` of the adjoint recursion for the smoothed states alone (the vector half of
    :func:`smooth_steps`, the same arithmetic): the smoothed errors at the stored steps (``hist_x``: the navigation
    states ``(P_{k|k-1} lambda_k)_n``, the constants the feedback still to come) and, when ``k0 == 0``, at the start
    (``x0``: ``lambda_0`` with ``P_0 = I``, and the pass's whole feedback): what the passes need but the last (the
    initial attitude) and the history.
    ``lam``: the adjoint vector handed from step ``k1`` to ``k0 - 1``; ``rem``: the constants' feedback from step
    ``k1`` on (:func:`smooth_steps`), in place."""
    N = x0.shape[0]
    nd = phinn_st.shape[1]
    d = np.empty(3)
    ih = stored_before(k1, M, hist_every) - 1
    for k in range(k1 - 1, k0 - 1, -1):
        if att_used.shape[0] > 0 and att_used[k]:  # the encoder attitude rows (the later update)
            dense_rows_adjoint(lam, Ka_st[k], sza_st[k], Ha_st[k], d)
            add_feedback(rem, Ka_st[k], Sia_st[k], sza_st[k], nd)
        K = K_st[k]
        ktl = K.T @ lam
        for a in range(IDX_MEAS.shape[0]):
            lam[IDX_MEAS[a]] += sz_st[k, a] - ktl[a]
        add_feedback(rem, K, Si_st[k], sz_st[k], nd)
        if k % hist_every == 0 or k == M - 1:
            hist_x[ih, :nd] = hist_Pm[ih, :nd] @ lam  # as filters.smoothed_constant
            hist_x[ih, nd:] = rem
            ih -= 1
        ln = lam[:nd].copy()
        lam[nd:] = lam[nd:] + phinp_st[k].T @ ln
        lam[:nd] = phinn_st[k].T @ ln
    if k0 == 0:
        x0[:nd] = lam[:nd]
        x0[nd:] = rem


def smooth_vector_kernel(K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, x0, att_used, Ka_st,
                          Sia_st, sza_st, Ha_st) -> None:
    """The adjoint recursion for the smoothed states at the stored steps and the start over all ``M`` steps
    (:func:`smooth_vector_steps`), in slices of steps."""
    lam = np.zeros(x0.shape[0])
    rem = np.zeros(x0.shape[0] - phinn_st.shape[1])
    backward(M, lambda k0, k1: smooth_vector_steps(K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm,
                                                     hist_x, x0, att_used, Ka_st, Sia_st, sza_st, Ha_st, lam, k0, k1,
                                                     rem))
