"""The choice of a noise model among nested sums of processes, and the classic IEEE read-offs.

Every sub-sum of a largest model (the terms of ``QN+WN+BI+RW+DR+2GM`` by default) is a candidate.
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

The record cannot tell some candidates from smaller ones; they are set aside, not compared (and
the reason is listed), so that "the right model" is the smallest one that describes what the record
can show:

* a term whose amplitude is zero at the candidate's best fit, or below 5 % of the interval
  half-width at every scale: the candidate without it fits the same curve;
* a Gauss-Markov term at the shortest correlation time allowed (2 dt): white noise at every scale.

and a Gauss-Markov term's correlation time is kept at most an eighth of the longest scale tau_max:
its Allan variance peaks at 1.89 T_c, and a GM whose peak does not lie two octaves inside the record
is, over the record, a rate random walk (AVAR -> (2 sigma^2 / T_c) tau / 3, K^2 = 2 sigma^2 / T_c),
which the candidates with RW describe with one parameter fewer; so a record's random walk is not
taken for a long GM, nor the other way round.  A GM of the sensor longer than that is reported as
the random walk it looks like over the record (a longer record resolves it).

The amplitudes of every candidate are solved exactly on a grid of correlation times
(:mod:`inscal.analysis.noise.projection`), the best candidates polished; the chosen model is then
refitted with the default GMWM weights (its reported values, intervals and objective).  The result
names the runner-up and the criterion gap, the J-test p-value of the choice and what was set aside.

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

#: the largest model of ``--model auto``
AUTO_MODEL = "QN+WN+BI+RW+DR+2GM"
#: candidates polished after the grid (the lowest criterion on the grid; the others are far above)
POLISH_MARGIN = 20.0
#: the longest GM correlation time of a candidate, as a share of the longest scale tau_max
GM_TC_MAX_SHARE = 0.125


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


def set_aside(codes, theta, zero, curve: Curve, whiten) -> str:
    """Why the record cannot tell the candidate ``codes`` (at ``theta``) from a smaller one, or ''."""
    terms = terms_of(codes, theta, curve.dt)
    for t, z in zip(terms, zero):
        if z:
            return f"{t.code} not seen (zero amplitude)"
    half = 0.5 * (curve.upper - curve.lower)
    seen = np.max(contributions(terms, curve.m, curve.dt) / half[:, None], axis=0)
    for t, x in zip(terms, seen):
        if x < 0.05:
            return f"{t.code} below 5 % of the interval at every scale"
    for t in terms:
        if t.code == "GM" and t.tc < 2.05 * curve.dt:
            return f"GM of T_c = {t.tc:.3g} s at 2 dt: white noise at every scale"
    return ""


@dataclass(frozen=True)
class Selection:
    """The chosen fit, every candidate's row (model, criterion, J, J-test p, parameters, set-aside
    reason or '') sorted by criterion, the criterion's name and why the choice was made."""

    chosen: NoiseFit
    candidates: tuple
    reason: str
    criterion: str = "hqic"


def select(curve: Curve, largest: str = AUTO_MODEL, rng: np.random.Generator | None = None,
           n_starts: int = 2, criterion: str = "hqic") -> Selection:
    """Choose among the sub-sums of ``largest`` by ``criterion`` (module docstring) and refit the
    choice with the GMWM weights."""
    rng = np.random.default_rng(0) if rng is None else rng
    codes = nm.parse_model(largest)
    J = curve.m.size
    fits_full = [c for c in [codes] if sum(n_params(x) for x in c) <= J - 1]
    big = codes if fits_full else max((c for c in sub_models(codes) if sum(n_params(x) for x in c) <= J - 1),
                                      key=lambda c: sum(n_params(x) for x in c))
    full = fit_curve(curve, big, n_starts=0, rng=rng)
    V = curve_covariance(full.terms, curve)
    W = np.linalg.inv(np.linalg.cholesky(V))  # ||W r||^2 = r' V^-1 r
    pen = penalty(criterion, record_samples(curve))
    tcm = tc_limit(curve)
    cols = projection.basis(codes, curve.m, curve.dt, projection.tc_grid(curve.m, curve.dt, tc_max=tcm))
    rows = []
    for cand in sub_models(codes):
        p = sum(n_params(c) for c in cand)
        if p > J - 1:
            continue
        th, jg, zero = projection.profile(cand, curve.m, curve.dt, curve.wv, W, cols)
        rows.append([cand, p, th, jg, zero])
    best_grid = min(r[3] + pen * r[1] for r in rows)
    table, thetas = [], {}
    for cand, p, th, jg, zero in rows:
        if jg + pen * p <= best_grid + POLISH_MARGIN and not any(zero):
            th, jg, _ = solve(curve, cand, n_starts=0, rng=rng, theta0=th, whiten=W, grid=False, tc_max=tcm)
        why = set_aside(cand, th, zero, curve, W)
        name = nm.model_string(cand)
        thetas[name] = (cand, th)
        table.append((name, jg + pen * p, jg, chi2_sf(jg, J - p), p, why))
    table.sort(key=lambda r: r[1])
    ok = [r for r in table if not r[5]] or table
    best = ok[0]
    cand, th = thetas[best[0]]
    chosen = fit_curve(curve, cand, n_starts=n_starts, rng=rng, theta0=th)
    why = (f"{best[0]}: lowest {criterion.upper()} = J + {pen:.3g} p = {best[1]:.4g} among {len(ok)} of "
           f"{len(table)} sub-sums of {nm.model_string(codes)} the record can tell apart")
    if len(ok) > 1:
        ru = ok[1]
        why += f"; runner-up {ru[0]} {ru[1]:.4g} (gap {ru[1] - best[1]:.3g})"
    why += f"; J = {best[2]:.3g} on {J - best[4]} dof, p = {best[3]:.2g}"
    aside = [r for r in table if r[5] and r[1] < best[1]]
    if aside:
        why += "; set aside though lower: " + "; ".join(f"{r[0]} ({r[5]})" for r in aside[:2])
    return Selection(chosen, tuple(table), why, criterion)


# ----------------------------------------------------------------------------- IEEE read-offs
#: (term, slope of the Allan deviation, tau where the tangent line is read [s])
READOFFS = (("QN", -1.0, math.sqrt(3.0)), ("WN", -0.5, 1.0), ("BI", 0.0, math.nan), ("RW", 0.5, 3.0),
            ("DR", 1.0, math.sqrt(2.0)))


def readoffs(taus, adev, edf=None, min_edf: float = 30.0) -> dict:
    """The IEEE read-offs of one Allan deviation curve (SI): each term's tangent of its slope from
    below, read at its tau (module docstring); B = sigma_min / 0.664 with the tau of the minimum.
    With ``edf``, only the points of at least ``min_edf`` degrees of freedom are used (a tangent
    from below otherwise catches the scatter of the longest taus)."""
    taus, adev = np.asarray(taus, float), np.asarray(adev, float)
    if edf is not None and np.sum(np.asarray(edf) >= min_edf) >= 3:
        keep = np.asarray(edf) >= min_edf
        taus, adev = taus[keep], adev[keep]
    out = {}
    for code, slope, at in READOFFS:
        if code == "BI":
            i = int(np.argmin(adev))
            out["BI"] = {"value": float(adev[i] / math.sqrt(nm.BI_PLATEAU)), "tau_s": float(taus[i]),
                         "flat_bottom": bool(0 < i < taus.size - 1)}
            continue
        c = adev * taus ** (-slope)
        i = int(np.argmin(c))
        out[code] = {"value": float(c[i] * at**slope), "tau_s": float(taus[i])}
    return out
