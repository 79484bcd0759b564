"""Monte Carlo recovery of the GMWM-type noise fit and of the automatic model choice
(inscal.analysis.noise): a navigation-grade FOG-like gyro (QN + WN + RW + a B-like sum of two GMs,
10 Hz, 2^20 samples = 29 h) and a tactical MEMS-like gyro (QN + WN + RW + DR + 2 GM, 100 Hz, 2^22
samples = 11.7 h).

What "the right model" means.  A term can be chosen only where the record shows it: its
noncentrality, the J statistic of the best model without it (or with it replaced by its nearest
rival: RW by a GM, the GM sum by BI; every GM of T_c <= tau_max / 2, as in the choice) on the exact
curve with the efficient weights, is the
expected rise of J when it is left out.  The scenarios are sized so that every such noncentrality is
at least 15 (printed first): then the criterion's penalty (HQIC, 5.5 per parameter here) is passed
in more than 93 % of records for each term (P(noncentral chi2_1(15) > 5.5)), and the choice of the
exact model is a fair test.  Every noncentrality is printed, so the sizing can be checked.  (J is unchanged when
every level is scaled by one factor: what sizes a scenario is the ratio of its terms and the record
length.  The FOG's levels are those of a tactical FOG, its shape a navigation-grade one's: at
navigation-grade levels, N 0.002 deg/sqrt(h) beside B ~ 0.003 deg/h, the same terms show only in a
record of several days.)

Per parameter: the mean estimate, its bias over the empirical SD and over the mean sandwich SE,
the coverage of the 95 % intervals, and the same bias for the IEEE read-offs side by side; the
automatic choice right in how many runs, by HQIC (the default) and, from the same candidate fits,
by BIC and AIC.

    .venv/bin/python bench/bench_noise_fit.py --runs 200 --procs 2
    .venv/bin/python bench/bench_noise_fit.py --choice-only --only FOG --runs 200 --procs 2

``--choice-only``: the automatic choice alone (no fixed fit, no read-offs) on the same records and
seeds as the full study (record ``seed + 10 r``, the choice's generator ``seed + 10 r + 2``): the
share of runs where it is the true model, the models chosen, and the reasons of the wrong ones.
"""

from __future__ import annotations

import argparse
import time
from multiprocessing import Pool

import numpy as np

from inscal.analysis.noise import projection
from inscal.analysis.noise.estimators import octave_scales, scale_variance
from inscal.analysis.noise.fit import Curve, curve_covariance, fit_curve, solve
from inscal.analysis.noise.intervals import chi2_bounds
from inscal.analysis.noise.selection import penalty, readoffs, record_samples, select, tc_limit
from inscal.core import noise_models as nm
from inscal.core import units

G = nm.FIELD_UNITS["gyro"]


def si(v, key):
    return float(units.to_si(v, G[key]))


SCENARIOS = {
    "FOG": (0.1, 1 << 20, nm.ChannelNoise("g", "gyro", (
        nm.Quantization(si(0.1, "q")), nm.WhiteNoise(si(0.002, "n")), nm.RandomWalk(si(0.1, "k")),
        nm.GaussMarkov(si(0.05, "sigma"), 5.0), nm.GaussMarkov(si(0.05, "sigma"), 100.0)))),
    "MEMS": (0.01, 1 << 22, nm.ChannelNoise("g", "gyro", (
        nm.Quantization(si(2.0, "q")), nm.WhiteNoise(si(0.2, "n")), nm.RandomWalk(si(60.0, "k")),
        nm.RateRamp(si(200.0, "r")), nm.GaussMarkov(si(20.0, "sigma"), 0.5), nm.GaussMarkov(si(10.0, "sigma"), 8.0)))),
}
#: random starts of the fixed-model fit besides the grid and read-off ones
N_STARTS = 2
ORDER = ("QN", "WN", "BI", "RW", "DR", "GM")


def truth_vector(ch):
    return np.array([abs(getattr(t, p)) for t in ch.terms for p in t.params])


def exact_curve(ch, dt, n):
    m = octave_scales(n).astype(float)
    wv = ch.wvar(m, dt)
    M = n - 2 * m + 1
    lo, hi = chi2_bounds(np.maximum(M / (2 * m), 1))
    return Curve(m, dt, wv, lo * wv, hi * wv, M)


def noncentralities(ch, dt, n) -> dict:
    """J of the best rival of the truth on the exact curve (efficient weights at the truth)."""
    c = exact_curve(ch, dt, n)
    V = curve_covariance(ch.terms, c)
    W = np.linalg.inv(np.linalg.cholesky(V))
    codes = nm.parse_model(ch.model)
    alts = {f"without {codes[i]}{i if codes[i] == 'GM' else ''}": codes[:i] + codes[i + 1:] for i in range(len(codes))}
    if "RW" in codes:
        alts["RW as a GM"] = tuple(x for x in codes if x != "RW") + ("GM",)
    if codes.count("GM") == 2:
        alts["one GM as BI"] = tuple(sorted([x for x in codes if x != "GM"] + ["BI", "GM"], key=ORDER.index))
        alts["the GMs as BI"] = tuple(sorted([x for x in codes if x != "GM"] + ["BI"], key=ORDER.index))
    out = {}
    tcm = tc_limit(c)
    cols = projection.basis(ORDER + ("GM",), c.m, dt, projection.tc_grid(c.m, dt, tc_max=tcm))
    for k, a in alts.items():
        th, _, _ = projection.profile(a, c.m, dt, c.wv, W, cols)
        out[k] = solve(c, a, n_starts=0, theta0=th, whiten=W, grid=False, tc_max=tcm)[1]
    return out


def rechoose(table, pen_new, pen_old):
    """The choice by another penalty from the same candidate rows (criterion = J + pen p)."""
    ok = [r for r in table if not r[5]] or list(table)
    return min(ok, key=lambda r: r[2] + pen_new * r[4])[0] if pen_new != pen_old else ok[0][0]


def one(args):
    name, seed, do_select = args
    dt, n, ch = SCENARIOS[name]
    rng = np.random.default_rng(seed)
    y = ch.simulate(n, dt, rng)
    sv = scale_variance(y, 1 / dt, octave_scales(n))
    curve = Curve.from_scale_variance(sv)
    t0 = time.perf_counter()
    f = fit_curve(curve, ch.model, n_starts=N_STARTS, rng=np.random.default_rng(seed + 1))
    t_fit = time.perf_counter() - t0
    chosen, t_sel, reason = None, 0.0, ""
    if do_select:
        t0 = time.perf_counter()
        s = select(curve, rng=np.random.default_rng(seed + 2), criterion="hqic")
        t_sel = time.perf_counter() - t0
        ns = record_samples(curve)
        p_h = penalty("hqic", ns)
        chosen = (s.chosen.model, rechoose(s.candidates, penalty("bic", ns), p_h),
                  rechoose(s.candidates, penalty("aic", ns), p_h))
        reason = s.reason
    ro = readoffs(sv.taus, sv.adev[:, 0], sv.edf)
    return (f.values, f.lower, f.upper, f.se_theta, chosen, {k: v["value"] for k, v in ro.items()}, t_fit, t_sel,
            f.hits, reason, f.gof_p)


def one_choice(args):
    """The automatic choice alone on run ``seed``'s record (the records and generators of :func:`one`)."""
    name, seed = args
    dt, n, ch = SCENARIOS[name]
    y = ch.simulate(n, dt, np.random.default_rng(seed))
    curve = Curve.from_scale_variance(scale_variance(y, 1 / dt, octave_scales(n)))
    t0 = time.perf_counter()
    s = select(curve, rng=np.random.default_rng(seed + 2), criterion="hqic")
    return seed, s.chosen.model, time.perf_counter() - t0, s.reason


def choice_only(name, runs, procs, seed0):
    """Print how often the automatic choice is the true model of scenario ``name`` over ``runs`` records."""
    ch = SCENARIOS[name][2]
    t0 = time.perf_counter()
    out = []
    with Pool(procs) as pool:
        for o in pool.imap(one_choice, [(name, seed0 + 10 * r) for r in range(runs)], chunksize=1):
            out.append(o)
            if len(out) % 25 == 0:  # progress
                print(f"  {len(out)} runs: choice right in {100 * np.mean([x[1] == ch.model for x in out]):.1f} %",
                      flush=True)
    counts = {}
    for o in out:
        counts[o[1]] = counts.get(o[1], 0) + 1
    print(f"== {name} ({ch.model}), choice only: right in {100 * np.mean([o[1] == ch.model for o in out]):.1f} % of "
          f"{runs} runs (wall {time.perf_counter() - t0:.0f} s on {procs} processes, selection "
          f"{np.mean([o[2] for o in out]):.2f} s per run); chosen: {sorted(counts.items(), key=lambda kv: -kv[1])[:5]}")
    for o in [o for o in out if o[1] != ch.model]:
        print(f"  seed {o[0]}: {o[3][:300]}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--select-runs", type=int, default=200)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--only", choices=tuple(SCENARIOS))
    ap.add_argument("--choice-only", action="store_true", help="the automatic choice alone (no fits, no read-offs)")
    a = ap.parse_args()
    if a.choice_only:
        for name in [a.only] if a.only else SCENARIOS:
            choice_only(name, a.runs, a.procs, a.seed)
        return
    for name, (dt, n, ch) in SCENARIOS.items():
        if a.only and name != a.only:
            continue
        lam = noncentralities(ch, dt, n)
        print(f"\n== {name}: {ch.model}, dt = {dt} s, n = {n} ({n * dt / 3600:.1f} h); noncentrality of each rival "
              "(J on the exact curve): " + ", ".join(f"{k} {v:.3g}" for k, v in lam.items()))
        jobs = [(name, a.seed + 10 * r, r < a.select_runs) for r in range(a.runs)]
        t0 = time.perf_counter()
        out = []
        with Pool(a.procs) as pool:
            for o in pool.imap(one, jobs, chunksize=1):
                out.append(o)
                if len(out) % 25 == 0:  # progress: the choice so far
                    right = np.mean([x[4][0] == ch.model for x in out if x[4]])
                    print(f"  {len(out)} runs: choice right in {100 * right:.1f} %", flush=True)
        wall = time.perf_counter() - t0
        truth = truth_vector(ch)
        est = np.array([o[0] for o in out])
        lo = np.array([o[1] for o in out])
        hi = np.array([o[2] for o in out])
        se_log = np.array([o[3] for o in out])
        names = [f"{t.code}.{p}" for t in ch.terms for p in t.params]
        print(f"{a.runs} runs, wall {wall:.0f} s on {a.procs} processes; mean fit {np.mean([o[6] for o in out]):.2f} s, "
              f"selection {np.mean([o[7] for o in out if o[4]]):.2f} s per channel; J-test p < 0.05 of the true model "
              f"in {100 * np.mean([o[10] < 0.05 for o in out]):.1f} % of runs")
        print(f"{'parameter':<11}{'truth':>11}{'mean est':>11}{'bias/SD':>9}{'bias/SE':>9}{'SE/SD':>7}{'cover95':>9}")
        for i, pn in enumerate(names):
            e = est[:, i]
            sd = e.std(ddof=1)
            se = np.mean(e * se_log[:, i])  # delta method: se(x) = x se(log x)
            cov = np.mean((lo[:, i] <= truth[i]) & (truth[i] <= hi[:, i]))
            print(f"{pn:<11}{truth[i]:>11.4g}{e.mean():>11.4g}{(e.mean() - truth[i]) / sd:>9.3f}"
                  f"{(e.mean() - truth[i]) / se:>9.3f}{se / sd:>7.2f}{cov:>9.3f}")
        print(f"(a coverage of 0.95 measured on {a.runs} runs lies within +-{1.96 * (0.95 * 0.05 / a.runs) ** 0.5:.3f} "
              "in 95 % of studies)")
        sel = [o[4] for o in out if o[4] is not None]
        for k, rule in enumerate(("HQIC (default)", "BIC", "AIC")):
            picks = [s[k] for s in sel]
            right = np.mean([s == ch.model for s in picks])
            counts = {}
            for s in picks:
                counts[s] = counts.get(s, 0) + 1
            top = sorted(counts.items(), key=lambda kv: -kv[1])[:4]
            print(f"choice by {rule}: right in {100 * right:.1f} % of {len(picks)} runs; most chosen: {top}")
        wrong = [o[9] for o in out if o[4] is not None and o[4][0] != ch.model]
        if sel:
            print(f"  e.g.: {out[0][9]}")
        for w in wrong[:3]:
            print(f"  a wrong choice: {w}")
        code_key = {"QN": "q", "WN": "n", "RW": "k", "DR": "r"}
        print("IEEE read-offs (tangent lines) beside the fit:")
        for t in ch.terms:
            if t.code in code_key:
                r = np.array([o[5][t.code] for o in out])
                tv = abs(getattr(t, code_key[t.code]))
                i = names.index(f"{t.code}.{code_key[t.code]}")
                print(f"  {t.code}: read-off mean/truth {r.mean() / tv:.3f} (bias/SD {(r.mean() - tv) / r.std(ddof=1):.2f})"
                      f"   fit mean/truth {est[:, i].mean() / tv:.3f} (bias/SD {(est[:, i].mean() - tv) / est[:, i].std(ddof=1):.2f})")
        gm = [t for t in ch.terms if t.code == "GM"]
        b = np.array([o[5]["BI"] for o in out])
        print(f"  B read-off sigma_min/0.664: mean {b.mean():.4g} rad/s (GM sigmas {[float(f'{g.sigma:.4g}') for g in gm]})")
        print(f"  starts reaching the best objective: median {np.median([o[8] for o in out]):.0f} of {N_STARTS + 2}")


if __name__ == "__main__":
    main()
