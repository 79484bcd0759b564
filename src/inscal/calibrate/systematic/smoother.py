"""The modified Bryson-Frazier smoother of the systematic filter (inscal.core.kalman): the backward adjoint
recursion over the stores of a forward pass (:mod:`inscal.calibrate.systematic.kernel`), for the smoothed
states and covariances, or the states alone, at the stored steps and the start.

Like the forward pass, each compiled kernel processes a range of steps and its Python driver calls it in
slices (:func:`inscal.core.slices.run_in_slices`), so an interrupt is honoured between two slices."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from inscal.calibrate.systematic.states import IDX_MEAS
from inscal.core import kalman as filters
from inscal.core.kalman import smoother_step_dense
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
def smooth_steps(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, hist_P, x0, Pc0,
                  att_used, Ka_st, Sia_st, sza_st, Ha_st, lam, Lam, k0, k1, rem, Ppp):
    """Steps ``k1 - 1`` down to ``k0`` of the backward MBF pass (inscal.core.kalman; :func:`smooth_kernel`
    runs them all in slices): smoothed errors and covariances at the stored steps and, with ``k0 == 0``,
    at the start (``x0``, ``Pc0``).  ``lam``/``Lam``: the adjoint variables handed from step ``k1`` (zero
    for ``k1 == M``) to step ``k0 - 1``, in place.  Steps with encoder attitude rows (``att_used``) undo
    that second, later update first.

    The constants' smoothed estimate and covariance are the final filtered ones at every step (no process
    noise): ``rem`` accumulates, from the last step back, the constants' part of every update's estimate (the
    final filtered constants less the reference of the step reached), ``Ppp`` is their final filtered
    covariance, and :func:`inscal.core.kalman.smoothed_constant` conditions the navigation states on them (the
    plain ``Pm - Pm Lam Pm`` cancels catastrophically in the constants' directions)."""
    nd = phinn_st.shape[1]  # the dynamic states (navigation, and Gauss-Markov biases when there are some)
    ih = stored_before(k1, M, hist_every) - 1
    for k in range(k1 - 1, k0 - 1, -1):
        if att_used.shape[0] > 0 and att_used[k]:
            smoother_step_dense(lam, Lam, Ha_st[k], Ka_st[k], Sia_st[k], sza_st[k])
            add_feedback(rem, Ka_st[k], Sia_st[k], sza_st[k], nd)
        filters.smoother_step(lam, Lam, IDX_MEAS, K_st[k], Si_st[k], sz_st[k])
        add_feedback(rem, K_st[k], Si_st[k], sz_st[k], nd)
        if k % hist_every == 0 or k == M - 1:
            x, Ps = filters.smoothed_constant(hist_Pm[ih], lam, Lam, nd, rem, Ppp)
            hist_x[ih] = x
            hist_P[ih] = Ps
            ih -= 1
        filters.adjoint_back(lam, Lam, nd, phinn_st[k], phinp_st[k])
    if k0 == 0:
        x, Ps = filters.smoothed_constant(P0, lam, Lam, nd, rem, Ppp)
        x0[:] = x
        Pc0[:, :] = Ps


def backward(M: int, steps) -> None:
    """Run ``steps(k0, k1)`` over ``M - 1 .. 0`` backwards in slices (the last call has ``k0 == 0``; one
    call ``(0, 0)`` when ``M == 0``)."""
    if M == 0:
        steps(0, 0)
    run_in_slices(M, lambda j0, j1: steps(M - j1, M - j0), first=2048)


def smooth_kernel(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, hist_P, x0, Pc0,
                   att_used, Ka_st, Sia_st, sza_st, Ha_st, Ppp) -> None:
    """The backward MBF pass over all ``M`` steps (:func:`smooth_steps`), in slices of steps so that an
    interrupt is honoured between two; the adjoint variables live here between slices.  ``Ppp``: the
    constants' final filtered covariance (scaled)."""
    N = P0.shape[0]
    lam = np.zeros(N)
    Lam = np.zeros((N, N))
    rem = np.zeros(N - phinn_st.shape[1])
    Ppp = np.ascontiguousarray(Ppp, dtype=float)
    backward(M, lambda k0, k1: smooth_steps(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm,
                                              hist_x, hist_P, x0, Pc0, att_used, Ka_st, Sia_st, sza_st, Ha_st, lam,
                                              Lam, k0, k1, rem, Ppp))


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
            for a in range(3):
                s = sza_st[k, a]
                for i in range(N):
                    s -= Ka_st[k, i, a] * lam[i]
                d[a] = s
            for i in range(N):
                lam[i] += Ha_st[k, 0, i] * d[0] + Ha_st[k, 1, i] * d[1] + Ha_st[k, 2, i] * d[2]
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
