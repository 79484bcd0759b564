"""The choice of a noise model among nested sums of processes, and the classic IEEE read-offs.

Every sub-sum of a largest model (the terms of ``QN+WN+RW+DR+2GM`` by default) is fitted
(:func:`inscal.analysis.noise.fit.fit_curve`, warm-started from the largest fit), each judged with the
same ``V`` (the largest model's) by the wavelet-variance information criterion

    WVIC = (nu_hat - nu(theta_hat))' Omega (nu_hat - nu(theta_hat)) + 2 tr(Omega D (D' Omega D)^-1 D' Omega V)

an estimate of the objective on an independent record of the same sensor (the training objective
plus its optimism, as Mallows's C_p; Guerrier, Molinari, Stebler, "Wavelet-based improvements for
inertial sensor error modeling", IEEE TIM 65 (2016); Zhang, Stat. Sinica 18 (2008)).  A candidate
with a term that is not seen (below 5 % of the interval half-width at every scale) is set aside: the
smaller sum without it describes the same curve.  The choice is the lowest WVIC; the result says by
how much it beats the next candidates.

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

from inscal.analysis.noise.fit import Curve, NoiseFit, fit_curve, n_params
from inscal.core import noise_models as nm

#: the largest model of ``--model auto``
AUTO_MODEL = "QN+WN+RW+DR+2GM"


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


def _warm(full: NoiseFit, codes) -> np.ndarray:
    """The largest fit's log-parameters of the terms of ``codes`` (a sub-sum with fewer GMs keeps the
    largest fit's first ones, in increasing correlation time)."""
    blocks: dict[str, list] = {}
    i = 0
    for c in full.codes:
        blocks.setdefault(c, []).append(full.theta[i:i + n_params(c)])
        i += n_params(c)
    out, used = [], {}
    for c in codes:
        j = used.get(c, 0)
        used[c] = j + 1
        out.append(blocks[c][j])
    return np.concatenate(out)


@dataclass(frozen=True)
class Selection:
    """The chosen fit, every candidate's (model, WVIC, objective, J-test p, any unseen term) and why."""

    chosen: NoiseFit
    candidates: tuple  # (model, wvic, objective, gof_p, has_unseen_term), sorted by WVIC
    reason: str


def select(curve: Curve, largest: str = AUTO_MODEL, rng: np.random.Generator | None = None,
           n_starts: int = 2, rule: str = "wvic") -> Selection:
    """Fit every sub-sum of ``largest`` and choose by WVIC (module docstring).  ``rule="parsimony"``:
    the fewest parameters among the candidates the J test does not reject at 5 %, then the lowest WVIC."""
    rng = np.random.default_rng(0) if rng is None else rng
    codes = nm.parse_model(largest)
    full = fit_curve(curve, codes, rng=rng)
    table, fits, sizes = [], {}, {}
    for cand in sub_models(codes):
        if sum(n_params(c) for c in cand) > curve.m.size:
            continue
        f = full if cand == codes else fit_curve(curve, cand, n_starts=n_starts, rng=rng, v_terms=full.terms,
                                                 theta0=_warm(full, cand))
        if cand == codes:  # judged with the same V as the others
            f = fit_curve(curve, cand, n_starts=0, rng=rng, v_terms=full.terms, theta0=full.theta)
        fits[f.model] = f
        sizes[f.model] = sum(n_params(c) for c in cand)
        table.append((f.model, f.wvic, f.objective, f.gof_p, any(f.negligible)))
    table.sort(key=lambda r: r[1])
    ok = [r for r in table if not r[4]] or table
    if rule == "parsimony":
        passing = [r for r in ok if r[3] >= 0.05]
        if passing:
            fewest = min(sizes[r[0]] for r in passing)
            ok = [r for r in passing if sizes[r[0]] == fewest] + [r for r in ok if r not in passing or sizes[r[0]] != fewest]
    best = ok[0]
    nxt = [r for r in ok[1:3]]
    why = (f"{best[0]}: lowest WVIC {best[1]:.4g} among {len(table)} sub-sums of {nm.model_string(codes)}"
           + (" (next: " + ", ".join(f"{r[0]} {r[1]:.4g}" for r in nxt) + ")" if nxt else "")
           + f"; J-test p = {best[3]:.2g}")
    dropped = [r[0] for r in table if r[4] and r[1] < best[1]]
    if dropped:
        why += f"; set aside with a term the data do not show: {', '.join(dropped[:3])}"
    return Selection(fits[best[0]], tuple(table), why)


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
