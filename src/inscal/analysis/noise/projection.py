"""Variable projection for a sum of noise processes: the global optimum over the correlation times,
the amplitudes solved exactly.

Every process's wavelet variance is its squared scale parameter times a unit curve (q^2, n^2, b^2,
k^2, r^2, sigma^2: :mod:`inscal.core.noise_models`), so for fixed Gauss-Markov correlation times the
model is linear in the amplitudes ``a >= 0``::

    nu(a, tc) = G(tc) a,     min_{a >= 0} || W (nu_hat - G(tc) a) ||^2      (a non-negative least squares)

with ``W`` the square root of the weight matrix (``diag(sqrt(Omega))`` for GMWM's weights,
``V^-1/2`` for the efficient ones).  The remaining search runs over the correlation times alone: a
logarithmic grid (every pair for two GMs), each point an exact NNLS (Lawson & Hanson 1974), then the
best point polished (:func:`inscal.analysis.noise.fit.solve`).  This is the variable projection of
Golub & Pereyra (SIAM J. Numer. Anal. 10, 1973) with the inequality kept: an amplitude at zero says
the term is not seen in the curve (the smaller model fits as well).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.optimize import nnls

from inscal.core import noise_models as nm

#: correlation times per octave on the grid
PER_OCTAVE = 3
#: floor of a zero amplitude, relative to the largest one, when it becomes a log-parameter
ZERO_FLOOR = 1e-12
#: the shortest Gauss-Markov correlation time, as a share of dt: the AR(1) coefficient
#: phi = exp(-dt / T_c) runs down to exp(-8) = 3e-4, i.e. practically 0, as GMWM parametrises it
#: (phi in (0, 1)); a GM of T_c below dt colours the first scales only (a non-white start)
TC_MIN_SHARE = 0.125
#: NNLS solves per profile at most (in increasing order of the unconstrained residual): a point
#: whose solution has an amplitude at zero is a smaller candidate's, which the choice fits itself
MAX_NNLS = 64
#: grid points whose residual is recomputed from the columns (the Gram form loses digits near zero)
EXACT_TOP = 256
#: models of three or four GMs: the grid's every COARSE-th point first, then the neighbours of the
#: REFINE best coarse points on the full grid
COARSE = 3
REFINE = 4


def unit_column(code: str, m, dt: float, tc: float | None = None) -> np.ndarray:
    """The wavelet variance (AVAR / 2) of the process ``code`` with unit scale parameter at factors
    ``m`` (``tc`` [s] for a Gauss-Markov term; the BI cut-off at Nyquist)."""
    term = {"QN": lambda: nm.Quantization(1.0), "WN": lambda: nm.WhiteNoise(1.0),
            "BI": lambda: nm.BiasInstability(1.0, 0.5 / dt), "RW": lambda: nm.RandomWalk(1.0),
            "DR": lambda: nm.RateRamp(1.0), "GM": lambda: nm.GaussMarkov(1.0, tc)}[code]()
    return 0.5 * term.avar(m, dt)


def tc_grid(m, dt: float, per_octave: int = PER_OCTAVE, tc_max: float | None = None,
            tc_min: float | None = None) -> np.ndarray:
    """Correlation times from ``tc_min`` (default :data:`TC_MIN_SHARE` dt) to ``tc_max`` (default
    4 tau_max, tau_max = the longest scale), ``per_octave`` per octave [s]."""
    lo = math.log2(TC_MIN_SHARE * dt if tc_min is None else tc_min)
    hi = math.log2(4 * float(np.max(m)) * dt if tc_max is None else tc_max)
    return 2.0 ** np.linspace(lo, hi, int(math.ceil((hi - lo) * per_octave)) + 1)


def basis(codes, m, dt: float, grid=None) -> dict:
    """The unit columns of the terms of ``codes`` at factors ``m`` (``"GM"``: one per grid correlation
    time, and the grid itself under ``"tc"``): computed once, shared by every candidate of a choice."""
    m = np.asarray(m, dtype=float)
    grid = tc_grid(m, dt) if grid is None else np.asarray(grid, dtype=float)
    out = {c: unit_column(c, m, dt) for c in dict.fromkeys(codes) if c != "GM"}
    if "GM" in codes:
        out["GM"] = np.stack([unit_column("GM", m, dt, t) for t in grid], axis=1)
        out["tc"] = grid
    return out


def profile(codes, m, dt: float, wv, whiten, cols: dict | None = None):
    """The best point of the grid: ``(theta, objective, zero)`` with ``theta`` the log-parameters
    (zero amplitudes floored at :data:`ZERO_FLOOR` of the largest), ``objective`` the exact NNLS value
    there and ``zero`` a bool per term (its amplitude is zero at the best point).  ``whiten``: (J,)
    square roots of diagonal weights, or a (J, J) matrix W; ``cols``: :func:`basis` (computed when
    None).  Every grid point is first solved without the constraint, all at once; NNLS runs only
    where that solution has a negative amplitude and could still beat the best feasible point (at most
    :data:`MAX_NNLS` of them).
    Models of three or four GMs are searched coarse to fine (:data:`COARSE`, :data:`REFINE`)."""
    codes = tuple(codes)
    m = np.asarray(m, dtype=float)
    wv = np.asarray(wv, dtype=float)
    cols = basis(codes, m, dt) if cols is None else cols
    W = np.diag(whiten) if np.ndim(whiten) == 1 else np.asarray(whiten, dtype=float)
    fixed = [c for c in codes if c != "GM"]
    k_gm = len(codes) - len(fixed)
    F = np.stack([cols[c] for c in fixed], axis=1) if fixed else np.zeros((m.size, 0))
    grid = cols["tc"] if k_gm else np.zeros(1)
    C = cols["GM"] if k_gm else np.zeros((m.size, 1))
    # scale every column to unit weighted norm (amplitudes span decades)
    WF, WC, y = W @ F, W @ C, W @ wv
    sF = np.linalg.norm(WF, axis=0)
    sF[sF == 0] = 1.0
    sC = np.linalg.norm(WC, axis=0)
    sC[sC == 0] = 1.0
    WF, WC = WF / sF, WC / sC
    A = np.concatenate([WF, WC], axis=1)
    gram, rhs, nf = A.T @ A, A.T @ y, WF.shape[1]

    def solve_at(combos):
        # the normal equations of every grid point from the Gram matrix of all the columns
        idx = np.concatenate([np.broadcast_to(np.arange(nf), (combos.shape[0], nf)), nf + combos], axis=1)  # (P, p)
        G = gram[idx[:, :, None], idx[:, None, :]]
        G += 1e-12 * np.eye(G.shape[1]) * np.trace(G, axis1=1, axis2=2)[:, None, None]
        b = rhs[idx]
        a = np.linalg.solve(G, b[..., None])[..., 0]
        return idx, a, np.maximum(float(y @ y) - np.sum(a * b, axis=1), 0.0)  # |y - X a|^2 at the solution

    if k_gm <= 2:
        combos = (np.array(list(itertools.combinations(range(grid.size), k_gm)), dtype=np.int64) if k_gm
                  else np.zeros((1, 0), dtype=np.int64))
    else:
        # coarse to fine: every combination of every COARSE-th point, then around the best ones every
        # combination of their neighbours on the full grid
        coarse = np.array(list(itertools.combinations(range(0, grid.size, COARSE), k_gm)), dtype=np.int64)
        _, _, r0 = solve_at(coarse)
        near = itertools.product(range(-(COARSE - 1), COARSE), repeat=k_gm)
        steps = np.array(list(near), dtype=np.int64)
        fine = (coarse[np.argsort(r0)[:REFINE]][:, None, :] + steps[None]).reshape(-1, k_gm)
        ok = np.all((fine >= 0) & (fine < grid.size), axis=1) & np.all(np.diff(fine, axis=1) > 0, axis=1)
        allc = np.concatenate([coarse, fine[ok]])
        key = allc @ (grid.size ** np.arange(k_gm, dtype=np.int64))
        combos = allc[np.unique(key, return_index=True)[1]]
    idx, a, res = solve_at(combos)
    top = np.argsort(res)[:EXACT_TOP]  # the best recomputed from the columns (no cancellation)
    res[top] = np.sum((y[None, :] - np.einsum("jpi,pi->pj", A[:, idx[top]], a[top])) ** 2, axis=1)
    feas = np.all(a >= 0, axis=1)
    best = (np.inf, -1, None)
    if np.any(feas):
        i = int(np.argmin(np.where(feas, res, np.inf)))
        best = (float(res[i]), i, a[i])
    tries = 0
    for i in np.argsort(res):
        if res[i] >= best[0] * (1 - 1e-12) or tries >= MAX_NNLS:
            break
        if feas[i]:
            continue
        tries += 1
        ai, r = nnls(A[:, idx[i]], y, maxiter=50 * idx.shape[1])
        if r**2 < best[0]:
            best = (float(r**2), int(i), ai)
    obj, i, a = best
    combo = combos[i]
    amp = a / np.concatenate([sF, sC[combo]])
    floor = ZERO_FLOOR * max(float(np.max(amp)), np.finfo(float).tiny)
    theta, zero, i_f, i_g = [], [], 0, 0
    for c in codes:
        if c == "GM":
            x, tc = amp[len(fixed) + i_g], grid[combo[i_g]]
            i_g += 1
            theta += [0.5 * math.log(max(x, floor)), math.log(tc)]
        else:
            x = amp[i_f]
            i_f += 1
            theta.append(0.5 * math.log(max(x, floor)))
        zero.append(bool(x <= 0.0))
    return np.array(theta), obj, tuple(zero)
