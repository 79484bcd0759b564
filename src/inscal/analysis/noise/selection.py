"""The choice of a noise model among nested sums of processes, and the classic IEEE read-offs.

Every sub-sum of a largest model (the terms of ``QN+WN+BI+RW+DR+4GM`` by default, a candidate only where the curve has more scales than
parameters) is a candidate.
Each is fitted with the efficient weights (two-step GMM: ``V`` the covariance of the wavelet
variances at the largest model's GMWM fit, :func:`inscal.analysis.noise.fit.curve_covariance`), so that
its objective is Hansen's J statistic

    J_c = min_theta (nu_hat - nu_c(theta))' V^-1 (nu_hat - nu_c(theta)),   about chi^2(scales - p_c)

and the J of two nested candidates differ by about chi^2 of their difference in parameters.  The
choice minimises a model-selection criterion of GMM (Andrews & Lu, J. Econometrics 101 (2001)
123-164), by default their Hannan-Quinn one (MMSC-HQIC)

    HQIC_c = J_c + 2.1 p_c ln ln n          (n the samples of the record)

a penalty that grows with the record, so that a spurious term is dropped with a probability that
tends to one (a fixed penalty such as the WVIC's ``2 tr(...)``, an AIC, keeps one in a fixed share
of records: P(chi^2_1 > 2) = 16 % per rival), yet slowly enough that a term whose omission raises J
by 15 or more is kept in more than 93 % of records.  ``criterion="bic"`` takes their BIC penalty
``ln n`` per parameter (consistent too, but it drops terms that a record of 10^6 samples shows
plainly: 14 per parameter), ``"aic"`` 2.

One ``V`` for every candidate is a yardstick fitted to the largest model of all: where that fit
explains the longest scales by a rate ramp (deterministic, no variance of its own) it claims tens of
times the degrees of freedom those scales have, and every smaller candidate is judged on scales it is
told are near exact.  So the table's choice is then checked by nested pairs (:func:`nested_check`),
each on the larger one's own yardstick: a term is dropped where Newey & West's distance statistic
``D = J_smaller - J_larger``, both on ``V`` at the larger one's estimate, stays below its penalty.
Where the choice then fails its own J test (``V`` at its own fit, p below :data:`EXTEND_ALPHA`), the
table's :data:`RESCUE` best are each checked by nested pairs and judged by ``J + pen p`` on their own
yardsticks (Andrews & Lu's criterion with each candidate's own efficient weights,
:func:`own_yardstick`): a smaller candidate whose fit in the table stopped in a local optimum is
reached from its parent's solution less one term, not passed over for a model that fails its test.

The record cannot tell some candidates from smaller ones; they are set aside, not compared (and
the reason is listed), so that "the right model" is the smallest one that describes what the record
can show:

* a term whose amplitude is zero at the candidate's best fit, or below 5 % of the interval
  half-width at every scale: the candidate without it fits the same curve -- a reason that holds
  only where that smaller candidate's criterion is no worse (a reason its J contradicts is none).

A Gauss-Markov term's correlation time runs down to dt / 8 (AR(1) phi = exp(-dt / T_c) down to
3e-4, as GMWM parametrises phi in (0, 1)): a GM of T_c below dt is what a non-white start of a real
curve shows (tau nu rising over the first octaves: an anti-aliasing filter, a sensor's own
bandwidth), a term of the model like any other.  The chosen model is refitted with the GMWM weights;
a term that fit does not show (below 5 % of the interval at every scale) is dropped and the model
refitted, so no unseen term is returned as part of a model.  A Gauss-Markov term's correlation time
is kept at most an eighth of the longest scale tau_max:
its Allan variance peaks at 1.89 T_c, and a GM whose peak does not lie two octaves inside the record
is, over the record, a rate random walk (AVAR -> (2 sigma^2 / T_c) tau / 3, K^2 = 2 sigma^2 / T_c),
which the candidates with RW describe with one parameter fewer; so a record's random walk is not
taken for a long GM, nor the other way round.  A GM of the sensor longer than that is reported as
the random walk it looks like over the record (a longer record resolves it).

The amplitudes of every candidate are solved exactly on a grid of correlation times
(:mod:`inscal.analysis.noise.projection`), the best candidates polished (at most :data:`MAX_POLISH` of them and the :data:`PER_GM_COUNT` best
of each GM count: the choice's time budget), then a backward elimination from the best (each
candidate with one term fewer polished from its estimate); the chosen model is then
refitted with the default GMWM weights (its reported values, intervals and objective).  The result
names the runner-up and the criterion gap, the J-test p-value of the choice and what was set aside.

Where the record is too short to tell the structure apart, the reason names the richer candidates
within two penalties of the choice, their criterion gap and the record length that would separate
them (:func:`_richer`): the choice is the parsimonious one, not a claim that the richer is wrong.

The IEEE read-offs (IEEE 952-2020 Annex C, El-Sheimy et al. 2008) are the lines of slope -1, -1/2,
0, +1/2, +1 tangent to the Allan deviation from below, read at tau = sqrt(3), 1, (minimum),
3, sqrt(2) s: Q, N, B (sigma_min / 0.664), K, R.  Each is an upper bound of its term (every term adds
to the variance), equal to it where that term dominates.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from inscal.analysis.noise import projection
from inscal.analysis.noise.fit import (Curve, NoiseFit, contributions, curve_covariance, fit_curve, n_params, solve,
                                      terms_of)
from inscal.core import noise_models as nm
from inscal.core.stats import chi2_sf

#: the largest model of ``--model auto``: up to four GMs, as published GMWM fits of precise real
#: curves use; a candidate takes part only where the curve has more scales than parameters
AUTO_MODEL = "QN+WN+BI+RW+DR+4GM"
#: the model whose size fixes the shortest record ``auto`` accepts (the candidates of more GMs are
#: tried only where the record's scales allow them)
AUTO_MIN_MODEL = "QN+WN+BI+RW+DR+2GM"
#: candidates polished after the grid: those within this criterion margin of the best grid point
POLISH_MARGIN = 20.0
#: and at most this many of them (the time budget of the choice: the grid is exact, the polish costs)
MAX_POLISH = 8
#: besides, the best candidates on the grid of each GM count (the grid is coarser with more GMs)
PER_GM_COUNT = 2
#: the longest GM correlation time of a candidate, as a share of the longest scale tau_max
GM_TC_MAX_SHARE = 0.125
#: the J-test level below which the simple family's choice opens the extended one
EXTEND_ALPHA = 0.01
#: steps of the backward elimination from the best polished candidate
MAX_ELIMINATE = 3
#: the extended family's elimination starts from this many of its best polished candidates
ELIMINATE_FROM_EXTENDED = 4
#: where the choice fails its own J test, this many of the table's best are judged on their own yardsticks
RESCUE = 10
#: a richer candidate within this many penalty units of the choice "fits nearly as well"
NEAR_PENALTIES = 2.0


def tc_limit(curve: Curve) -> float:
    """The longest Gauss-Markov correlation time a candidate may take [s]: tau_max / 8."""
    return GM_TC_MAX_SHARE * float(curve.m[-1] * curve.dt)


def sub_models(codes) -> list[tuple]:
    """Every non-empty sub-sum of ``codes`` (GM counts 0..k), canonical, without repeats."""
    kinds = [c for c in dict.fromkeys(codes) if c != "GM"]
    k_gm = list(codes).count("GM")
    out = []
    for r in range(len(kinds) + 1):
        for sub in itertools.combinations(kinds, r):
            for g in range(k_gm + 1):
                cand = nm.parse_model("+".join(list(sub) + ([f"{g}GM"] if g else []))) if (sub or g) else None
                if cand and cand not in out:
                    out.append(cand)
    return out


def penalty(criterion: str, n: float) -> float:
    """The penalty per parameter of ``criterion`` ("bic": ln n, "hqic": 2.1 ln ln n, "aic": 2)."""
    n = max(float(n), 16.0)
    return {"bic": math.log(n), "hqic": 2.1 * math.log(math.log(n)), "aic": 2.0}[criterion]


def record_samples(curve: Curve) -> float:
    """The samples behind ``curve``: n = M_1 + 2 m_1 - 1 at its first scale."""
    return float(curve.n_terms[0] + 2 * curve.m[0] - 1)


def unseen_terms(codes, theta, zero, curve: Curve) -> list[int]:
    """The indices of the terms of ``codes`` (at ``theta``) the curve does not show: a zero amplitude,
    or below 5 % of the interval half-width at every scale."""
    terms = terms_of(codes, theta, curve.dt)
    half = 0.5 * (curve.upper - curve.lower)
    seen = np.max(contributions(terms, curve.m, curve.dt) / half[:, None], axis=0)
    return [i for i, (z, x) in enumerate(zip(zero, seen)) if z or x < 0.05]


def set_aside(codes, theta, zero, curve: Curve, whiten=None) -> str:
    """Why the record cannot tell the candidate ``codes`` (at ``theta``) from a smaller one, or ''."""
    terms = terms_of(codes, theta, curve.dt)
    for i in unseen_terms(codes, theta, zero, curve):
        return (f"{terms[i].code} not seen (zero amplitude)" if zero[i]
                else f"{terms[i].code} below 5 % of the interval at every scale")
    return ""


def _without(codes, i) -> tuple:
    return tuple(c for k, c in enumerate(codes) if k != i)


def _contains(big, small) -> bool:
    return all(list(big).count(c) >= list(small).count(c) for c in set(small)) and len(big) > len(small)


@dataclass(frozen=True)
class Selection:
    """The chosen fit, every candidate's row (model, criterion, J, J-test p, parameters, set-aside
    reason or '') sorted by criterion, the criterion's name and why the choice was made; ``richer``:
    the larger candidates that fit nearly as well (model, criterion gap, J drop, record length
    factor that would separate them or None); ``removed``: the terms dropped from the choice as unseen."""

    chosen: NoiseFit
    candidates: tuple
    reason: str
    criterion: str = "hqic"
    richer: tuple = ()
    removed: tuple = ()


def select(curve: Curve, largest: str = AUTO_MODEL, rng: np.random.Generator | None = None,
           n_starts: int = 2, criterion: str = "hqic") -> Selection:
    """Choose among the sub-sums of ``largest`` by ``criterion`` (module docstring) and refit the
    choice with the GMWM weights.  In two stages: the simple family first (the sub-sums of
    :data:`AUTO_MIN_MODEL`'s terms within ``largest``, GM correlation times from 2 dt); the extended
    one (every sub-sum of ``largest``, GM correlation times from dt / 8) where the simple choice fails
    its J test at :data:`EXTEND_ALPHA` or holds a GM at 2 dt: where the record shows more than the
    simple family can say."""
    rng = np.random.default_rng(0) if rng is None else rng
    codes = nm.parse_model(largest)
    simple = tuple(c for c in nm.parse_model(AUTO_MIN_MODEL) if c in codes)
    simple = simple[:len(simple) - max(0, simple.count("GM") - codes.count("GM"))]
    first = _stage(curve, simple, 2.0 * curve.dt, rng, n_starts, criterion)
    at_bound = [t for t in first.chosen.terms if t.code == "GM" and t.tc < 2.05 * curve.dt]
    row = {r[0]: r for r in first.candidates}.get(first.chosen.model)
    p_j = row[3] if row else math.nan
    if simple == codes or not (p_j < EXTEND_ALPHA or at_bound):
        note = "" if simple == codes else (f"; the extended family ({nm.model_string(codes)}, GM T_c from dt / 8) "
                                           f"not tried: the choice passes its J test (p = {p_j:.2g} >= "
                                           f"{EXTEND_ALPHA:g}) with no GM at 2 dt")
        return Selection(first.chosen, first.candidates, first.reason + note, criterion, first.richer, first.removed)
    second = _stage(curve, codes, None, rng, n_starts, criterion)
    why = ("the simple family's choice " + first.chosen.model + (f" fails its J test (p = {p_j:.2g})" if p_j < EXTEND_ALPHA
                                                                 else " holds a GM at 2 dt"))
    return Selection(second.chosen, second.candidates, second.reason + f"; extended family tried: {why}", criterion,
                     second.richer, second.removed)


def _stage(curve: Curve, codes, tc_min, rng, n_starts: int, criterion: str) -> Selection:
    """One stage of :func:`select`: every sub-sum of ``codes`` with GM correlation times from ``tc_min``
    [s] (None: dt / 8)."""
    J = curve.m.size
    fits_full = [c for c in [codes] if sum(n_params(x) for x in c) <= J - 1]
    big = codes if fits_full else max((c for c in sub_models(codes) if sum(n_params(x) for x in c) <= J - 1),
                                      key=lambda c: sum(n_params(x) for x in c))
    full = fit_curve(curve, big, n_starts=0, rng=rng, tc_min=tc_min)
    V = curve_covariance(full.terms, curve)
    W = np.linalg.inv(np.linalg.cholesky(V))  # ||W r||^2 = r' V^-1 r
    pen = penalty(criterion, record_samples(curve))
    tcm = tc_limit(curve)
    cols = projection.basis(codes, curve.m, curve.dt, projection.tc_grid(curve.m, curve.dt, tc_max=tcm, tc_min=tc_min))
    rows = []
    for cand in sub_models(codes):
        p = sum(n_params(c) for c in cand)
        if p > J - 1:
            continue
        th, jg, zero = projection.profile(cand, curve.m, curve.dt, curve.wv, W, cols)
        rows.append([cand, p, th, jg, zero])
    rows.sort(key=lambda r: r[3] + pen * r[1])
    best_grid = rows[0][3] + pen * rows[0][1]
    live = [r for r in rows if not any(r[4])]
    polish = [r[0] for r in live if r[3] + pen * r[1] <= best_grid + POLISH_MARGIN][:MAX_POLISH]
    for k in range(codes.count("GM") + 1):  # the grid is coarser with more GMs: the best of each count too
        polish += [r[0] for r in live if r[0].count("GM") == k and r[0] not in polish][:PER_GM_COUNT]
    fitted = {}
    for cand, p, th, jg, zero in rows:
        if cand in polish:
            th, jg = solve(curve, cand, n_starts=0, rng=rng, theta0=th, whiten=W, grid=False, tc_max=tcm,
                           tc_min=tc_min)[:2]
        fitted[cand] = (p, th, jg, zero)
    # the extended family's grid is coarse (three or four GMs): eliminate from its best few
    _eliminate(curve, fitted, set(polish), pen, W, (tcm, tc_min), rng, 1 if tc_min else ELIMINATE_FROM_EXTENDED)
    table, thetas = [], {}
    for cand, (p, th, jg, zero) in fitted.items():
        why = set_aside(cand, th, zero, curve, W)
        if why:
            # the reason holds only where the candidate without the term does as well by the criterion
            i = unseen_terms(cand, th, zero, curve)[0]
            smaller = fitted.get(_without(cand, i))
            if smaller is not None and smaller[2] + pen * smaller[0] > jg + pen * p:
                why = ""
        name = nm.model_string(cand)
        thetas[name] = (cand, th)
        table.append((name, jg + pen * p, jg, chi2_sf(jg, J - p), p, why))
    table.sort(key=lambda r: r[1])
    ok = [r for r in table if not r[5]] or table
    best = ok[0]
    cand, th = thetas[best[0]]
    # each nested pair judged on the larger one's own yardstick, not the largest model's (Newey & West's D)
    cand, th, tested = nested_check(curve, cand, th, pen, (tcm, tc_min), rng, thetas)
    if tested:
        best = {r[0]: r for r in table}[nm.model_string(cand)]
    chosen, removed = _final_fit(curve, cand, th, thetas, n_starts, rng, tc_min)
    rescue = ""
    if chosen.gof_p < EXTEND_ALPHA:
        # the choice fails its own J test: Andrews & Lu's criterion with each candidate's own V
        cand, th, scores = own_yardstick(curve, [thetas[r[0]] for r in ok[:RESCUE]], (chosen.codes, chosen.theta),
                                         pen, (tcm, tc_min), rng, thetas)
        if cand != chosen.codes:
            rescue = (f"{nm.model_string(cand)}: {chosen.model}, the choice by {criterion.upper()} on the largest "
                      f"model's yardstick, fails its own J test (p = {chosen.gof_p:.2g}); the lowest J + {pen:.3g} p "
                      f"on each one's own yardstick among the table's {RESCUE} best, each checked by nested pairs (" + ", ".join(
                          f"{m} {v:.4g}" for m, v in sorted(scores.items(), key=lambda kv: kv[1])[:3]) + ")")
            chosen, removed = _final_fit(curve, cand, th, thetas, n_starts, rng, tc_min)
            best = {r[0]: r for r in table}.get(nm.model_string(cand), best)
    row = {r[0]: r for r in table}.get(chosen.model, best)
    top = ok[0]
    if rescue:
        why = rescue
    elif tested:
        why = (f"{row[0]}: from {top[0]} (lowest {criterion.upper()} = J + {pen:.3g} p = {top[1]:.4g} on the largest "
               f"model's yardstick, among {len(ok)} of {len(table)} sub-sums of {nm.model_string(codes)} the record "
               "can tell apart) by nested pairs, each on the larger one's own yardstick: "
               + "; ".join(f"{t} adds D = {d:.3g} < {pen * dp:.3g} to {b}" for _, b, t, d, dp in tested))
    else:
        why = (f"{row[0]}: lowest {criterion.upper()} = J + {pen:.3g} p = {row[1]:.4g} among {len(ok)} of "
               f"{len(table)} sub-sums of {nm.model_string(codes)} the record can tell apart")
    if removed:
        why += f" ({best[0]} with {', '.join(removed)} dropped: not seen in the refit)"
    if len(ok) > 1 and not (tested or rescue):
        ru = next(r for r in ok if r[0] != row[0])
        why += f"; runner-up {ru[0]} {ru[1]:.4g} (gap {ru[1] - row[1]:.3g})"
    if tested or rescue:
        why += f"; J = {chosen.gof:.3g} on {chosen.gof_dof} dof at its own fit, p = {chosen.gof_p:.2g}"
    else:
        why += f"; J = {row[2]:.3g} on {J - row[4]} dof, p = {row[3]:.2g}"
    aside = [r for r in table if r[5] and r[1] < min(row[1], top[1])]
    if aside:
        why += "; set aside though lower: " + "; ".join(f"{r[0]} ({r[5]})" for r in aside[:2])
    richer = () if rescue else _richer(row, table, thetas, pen) if not tested else tuple(
        (a, float(pen * dp - d), float(d), _length_factor(d, dp, pen)) for a, _, _, d, dp in reversed(tested[-2:]))
    if richer:
        why += "; richer models fit nearly as well: " + "; ".join(
            f"{m} (gap {g:.3g}" + (f"; if it is there, a record about {s:.3g}x longer would show it)" if s
                                   else "; no sign of it in this record)") for m, g, _, s in richer)
    return Selection(chosen, tuple(table), why, criterion, richer, tuple(removed))


def _final_fit(curve: Curve, cand, th, thetas, n_starts, rng, tc_min):
    """The choice ``cand`` refitted with the GMWM weights from ``th``; a term that fit does not show is
    dropped and the rest refitted.  Returns ``(fit, removed codes)``."""
    chosen = fit_curve(curve, cand, n_starts=n_starts, rng=rng, theta0=th, tc_min=tc_min)
    removed = []
    while any(chosen.negligible) and len(chosen.codes) > 1:
        # a term the chosen fit does not show is no part of the model: drop it and refit
        i = chosen.negligible.index(True)
        removed.append(chosen.codes[i])
        cand = _without(chosen.codes, i)
        key = nm.model_string(cand)
        th0 = thetas[key][1] if key in thetas else np.delete(chosen.theta, slice(
            sum(n_params(c) for c in chosen.codes[:i]), sum(n_params(c) for c in chosen.codes[:i + 1])))
        chosen = fit_curve(curve, cand, n_starts=n_starts, rng=rng, theta0=th0, tc_min=tc_min)
    return chosen, removed


def own_yardstick(curve: Curve, starts, current, pen: float, tc_range, rng, thetas=None):
    """Andrews & Lu's criterion ``J_c + pen p_c`` with each candidate's own efficient weights (``V`` at
    its own estimate, refitted with its ``V^-1/2``), for the choice ``current`` = (codes, theta) and for
    each of ``starts`` (the table's best, (codes, theta)) after its own :func:`nested_check` (a term it
    does not need dropped, each smaller fit started from the larger one's solution less that term, so a
    local optimum of a smaller candidate's fit in the table does not hide it).  Returns the lowest one's
    ``(codes, theta, {model: criterion})``."""
    scores, best = {}, None
    for codes, theta in [current] + list(starts):
        codes, theta, _ = nested_check(curve, codes, theta, pen, tc_range, rng, thetas)
        W = whitener(terms_of(codes, theta, curve.dt), curve)
        if W is None:
            continue
        theta, j = solve(curve, codes, n_starts=0, rng=rng, theta0=theta, whiten=W, grid=False, tc_max=tc_range[0],
                         tc_min=tc_range[1])[:2]
        crit = float(j) + pen * sum(n_params(c) for c in codes)
        key = nm.model_string(codes)
        if key not in scores or crit < scores[key]:
            scores[key] = crit
        if best is None or crit < best[0]:
            best = (crit, codes, theta)
    if best is None:
        return current[0], current[1], scores
    return best[1], best[2], scores


def whitener(terms, curve: Curve):
    """``W`` with ``W' W = V^-1`` for the covariance ``V`` of ``curve``'s wavelet variances under the
    processes ``terms`` (:func:`inscal.analysis.noise.fit.curve_covariance`), or None where ``V`` is not
    positive definite."""
    try:
        W = np.linalg.inv(np.linalg.cholesky(curve_covariance(terms, curve)))
    except np.linalg.LinAlgError:
        return None
    return W if np.all(np.isfinite(W)) else None


def nested_check(curve: Curve, cand, theta, pen: float, tc_range, rng, thetas=None):
    """Backward elimination of the choice ``cand`` (at ``theta``) by nested pairs, each on the larger
    one's own yardstick: ``V`` at the larger candidate's estimate, both refitted with its ``V^-1/2`` and
    ``D = J_smaller - J_larger`` (Newey & West, Int. Econ. Rev. 28 (1987) 777-787: the distance test of
    GMM, chi^2(dp) under the smaller model).  The common yardstick of the choice's table is the largest
    model's ``V``, fitted to the largest model of all: where that fit explains the longest scales by a
    rate ramp (deterministic, no variance of its own) it claims tens of times the degrees of freedom the
    scale has, and every candidate without the term is judged on scales it is told are near exact.
    The term of smallest ``D - pen dp`` is dropped while that is negative (at most :data:`MAX_ELIMINATE`
    steps).  Returns ``(codes, theta, [(larger, smaller, term, D, dp), ...])``; ``thetas`` (model name ->
    (codes, theta)) gives a second start to each smaller fit."""
    thetas = {} if thetas is None else thetas
    tested = []
    for _ in range(MAX_ELIMINATE):
        if len(cand) < 2:
            break
        W = whitener(terms_of(cand, theta, curve.dt), curve)
        if W is None:
            break
        th_p, j_p = solve(curve, cand, n_starts=0, rng=rng, theta0=theta, whiten=W, grid=False, tc_max=tc_range[0],
                          tc_min=tc_range[1])[:2]
        starts = np.cumsum([0] + [n_params(c) for c in cand])
        best = None
        for i in range(len(cand)):
            child = _without(cand, i)
            th0s = [np.delete(th_p, slice(starts[i], starts[i + 1]))]
            if nm.model_string(child) in thetas:
                th0s.append(thetas[nm.model_string(child)][1])
            for th0 in th0s:
                thc, jc = solve(curve, child, n_starts=0, rng=rng, theta0=th0, whiten=W, grid=False,
                                tc_max=tc_range[0], tc_min=tc_range[1])[:2]
                score = jc - j_p - pen * n_params(cand[i])
                if score < 0 and (best is None or score < best[0]):
                    best = (score, child, thc, cand[i], jc - j_p)
        if best is None:
            break
        tested.append((nm.model_string(cand), nm.model_string(best[1]), best[3], float(best[4]), n_params(best[3])))
        cand, theta = best[1], best[2]
    return cand, theta, tested


def _eliminate(curve: Curve, fitted: dict, polished: set, pen: float, W, tc_range, rng, n_from: int = 1) -> None:
    """Backward elimination from the best polished candidate: each candidate with one term fewer is
    polished from its parent's estimate less that term (the grid, coarser than a precise curve's
    scatter, may rank a term's stand-in above the smaller model), and the best moves on while that
    lowers the criterion (at most :data:`MAX_ELIMINATE` steps); from each of the ``n_from`` best polished
    candidates.  ``fitted`` is updated in place; ``tc_range``: the (longest, shortest) GM correlation time [s]."""
    def crit(c):
        return fitted[c][2] + pen * fitted[c][0]

    for start in sorted(polished, key=crit)[:n_from]:
        _eliminate_from(start, curve, fitted, polished, crit, W, tc_range, rng)


def _eliminate_from(best, curve, fitted, polished, crit, W, tc_range, rng) -> None:
    """The elimination chain of :func:`_eliminate` from the candidate ``best``."""
    for _ in range(MAX_ELIMINATE):
        codes, (_, th, _, _) = best, fitted[best]
        starts = np.cumsum([0] + [n_params(c) for c in codes])
        family = [best]
        for i in range(len(codes)):
            child = _without(codes, i)
            if not child or child not in fitted:
                continue
            family.append(child)
            th0 = np.delete(th, slice(starts[i], starts[i + 1]))
            thc, jc = solve(curve, child, n_starts=0, rng=rng, theta0=th0, whiten=W, grid=False, tc_max=tc_range[0],
                            tc_min=tc_range[1])[:2]
            p, _, jold, _ = fitted[child]
            if child not in polished or jc < jold:
                fitted[child] = (p, thc, jc, (False,) * len(child))
            polished.add(child)
        nxt = min(family, key=crit)
        if nxt == best:
            return
        best = nxt


def _richer(row, table, thetas, pen) -> tuple:
    """The candidates containing the choice ``row`` within :data:`NEAR_PENALTIES` penalties of it:
    ``(model, criterion gap, J drop, length factor)``.  The J drop of a term grows about in proportion
    to the record's length (its noncentrality lambda is ~ n), so a record ``s`` times longer shows it
    where ``s lambda`` passes the penalty of its ``dp`` parameters with a margin of 3:
    ``s = (pen dp + 3) / lambda``, ``lambda`` estimated as the J drop less its dp (None where <= 0)."""
    codes = thetas[row[0]][0]
    out = []
    for r in table:
        if r[5] or r[1] - row[1] > NEAR_PENALTIES * pen or not _contains(thetas[r[0]][0], codes):
            continue
        dp = r[4] - row[4]
        drop = row[2] - r[2]
        out.append((r[0], float(r[1] - row[1]), float(drop), _length_factor(drop, dp, pen)))
    return tuple(sorted(out, key=lambda x: x[1])[:2])


def _length_factor(drop: float, dp: int, pen: float):
    """The record length factor that would show a term of ``dp`` parameters whose J drop is ``drop``
    (:func:`_richer`), or None where the drop is no more than its dp."""
    lam = drop - dp
    return float(max((pen * dp + 3.0) / lam, 1.0)) if lam > 0 else None


# ----------------------------------------------------------------------------- IEEE read-offs
#: (term, slope of the Allan deviation, tau where the tangent line is read [s])
READOFFS = (("QN", -1.0, math.sqrt(3.0)), ("WN", -0.5, 1.0), ("BI", 0.0, math.nan), ("RW", 0.5, 3.0),
            ("DR", 1.0, math.sqrt(2.0)))


def readoffs(taus, adev, edf=None, min_edf: float = 30.0) -> dict:
    """The IEEE read-offs of one Allan deviation curve (SI): each term's tangent of its slope from
    below, read at its tau (module docstring); B = sigma_min / 0.664 with the tau of the minimum.
    Each says at which tau it was read (``tau_s``) and the equivalent degrees of freedom there (``edf``,
    NaN without ``edf``).
    With ``edf``, only the points of at least ``min_edf`` degrees of freedom are used (a tangent
    from below otherwise catches the scatter of the longest taus)."""
    taus, adev = np.asarray(taus, float), np.asarray(adev, float)
    e = np.full(taus.size, np.nan) if edf is None else np.asarray(edf, float)
    if edf is not None and np.sum(e >= min_edf) >= 3:
        keep = e >= min_edf
        taus, adev, e = taus[keep], adev[keep], e[keep]
    out = {}
    for code, slope, at in READOFFS:
        if code == "BI":
            i = int(np.argmin(adev))
            out["BI"] = {"value": float(adev[i] / math.sqrt(nm.BI_PLATEAU)), "tau_s": float(taus[i]),
                         "edf": float(e[i]), "flat_bottom": bool(0 < i < taus.size - 1)}
            continue
        c = adev * taus ** (-slope)
        i = int(np.argmin(c))
        out[code] = {"value": float(c[i] * at**slope), "tau_s": float(taus[i]), "edf": float(e[i])}
    return out
