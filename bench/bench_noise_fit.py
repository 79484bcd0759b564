"""Monte Carlo recovery of the GMWM-type noise fit (inscal.analysis.noise): a navigation-grade FOG-like
gyro (QN + WN + GM + RW, 10 Hz, 2^18 samples = 7.3 h) and a tactical MEMS-like gyro
(QN + WN + 2 GM + RW + DR, 100 Hz, 2^18 samples = 44 min).  Per parameter: the bias of the estimate
over its empirical standard deviation, the coverage of the 95 % sandwich intervals, and the same bias
for the IEEE read-offs; the automatic choice (``--model auto``) right in how many runs.

    .venv/bin/python bench/bench_noise_fit.py --runs 200 --procs 2
"""

from __future__ import annotations

import argparse
import math
import time
from multiprocessing import Pool

import numpy as np

from inscal.analysis.noise.estimators import octave_scales, scale_variance
from inscal.analysis.noise.fit import Curve, fit_curve, n_params
from inscal.analysis.noise.selection import readoffs, select
from inscal.core import noise_models as nm
from inscal.core import units

G = nm.FIELD_UNITS["gyro"]


def si(v, key):
    return float(units.to_si(v, G[key]))


SCENARIOS = {
    "FOG": (0.1, nm.ChannelNoise("g", "gyro", (
        nm.Quantization(si(0.03, "q")), nm.WhiteNoise(si(0.002, "n")), nm.RandomWalk(si(0.02, "k")),
        nm.GaussMarkov(si(0.015, "sigma"), 300.0)))),
    "MEMS": (0.01, nm.ChannelNoise("g", "gyro", (
        nm.Quantization(si(2.0, "q")), nm.WhiteNoise(si(0.2, "n")), nm.RandomWalk(si(50.0, "k")),
        nm.RateRamp(si(200.0, "r")), nm.GaussMarkov(si(20.0, "sigma"), 1.0), nm.GaussMarkov(si(8.0, "sigma"), 30.0)))),
}
N = 1 << 18
#: random starts of each fit besides the read-off one (the library default is 8; fewer here for time)
N_STARTS = 4


def truth_vector(ch):
    return np.array([abs(getattr(t, p)) for t in ch.terms for p in t.params])


def parsimony(table):
    """The fewest parameters among the candidates the J test keeps (p >= 0.05), then the lowest WVIC
    (select(..., rule="parsimony") on the same table)."""
    ok = [r for r in table if not r[4]] or list(table)
    keep = [r for r in ok if r[3] >= 0.05]
    if not keep:
        return ok[0][0]
    size = {r[0]: sum(n_params(c) for c in nm.parse_model(r[0])) for r in keep}
    fewest = min(size.values())
    return min((r for r in keep if size[r[0]] == fewest), key=lambda r: r[1])[0]


def one(args):
    name, seed, do_select = args
    dt, ch = SCENARIOS[name]
    rng = np.random.default_rng(seed)
    y = ch.simulate(N, dt, rng)
    sv = scale_variance(y, 1 / dt, octave_scales(N))
    curve = Curve.from_scale_variance(sv)
    t0 = time.perf_counter()
    f = fit_curve(curve, ch.model, n_starts=N_STARTS, rng=np.random.default_rng(seed + 1))
    t_fit = time.perf_counter() - t0
    chosen, t_sel = None, 0.0
    if do_select:
        t0 = time.perf_counter()
        s = select(curve, rng=np.random.default_rng(seed + 2))
        t_sel = time.perf_counter() - t0
        chosen = (s.chosen.model, parsimony(s.candidates))
    ro = readoffs(sv.taus, sv.adev[:, 0], sv.edf)
    return f.values, f.lower, f.upper, chosen, {k: v["value"] for k, v in ro.items()}, t_fit, t_sel, f.hits


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--select-runs", type=int, default=200)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--seed", type=int, default=12345)
    a = ap.parse_args()
    for name, (dt, ch) in SCENARIOS.items():
        jobs = [(name, a.seed + 10 * r, r < a.select_runs) for r in range(a.runs)]
        t0 = time.perf_counter()
        with Pool(a.procs) as pool:
            out = pool.map(one, jobs)
        wall = time.perf_counter() - t0
        truth = truth_vector(ch)
        est = np.array([o[0] for o in out])
        lo = np.array([o[1] for o in out])
        hi = np.array([o[2] for o in out])
        names = [f"{t.code}.{p}" for t in ch.terms for p in t.params]
        print(f"\n== {name}: {ch.model}, dt = {dt} s, n = {N} ({N * dt / 3600:.2f} h), {a.runs} runs, "
              f"wall {wall:.0f} s on {a.procs} processes; mean fit {np.mean([o[5] for o in out]):.2f} s, "
              f"selection {np.mean([o[6] for o in out if o[3]]):.2f} s per channel")
        print(f"{'parameter':<12}{'truth':>12}{'mean est':>12}{'bias/SD':>10}{'median/truth':>14}{'coverage95':>12}")
        for i, pn in enumerate(names):
            e = est[:, i]
            bias_sd = (e.mean() - truth[i]) / e.std(ddof=1)
            cov = np.mean((lo[:, i] <= truth[i]) & (truth[i] <= hi[:, i]))
            print(f"{pn:<12}{truth[i]:>12.4g}{e.mean():>12.4g}{bias_sd:>10.3f}{np.median(e) / truth[i]:>14.3f}{cov:>12.3f}")
        for k, rule in enumerate(("WVIC", "parsimony (fewest parameters the J test keeps)")):
            sel = [o[3][k] for o in out if o[3] is not None]
            if sel:
                right = np.mean([s == ch.model for s in sel])
                counts = {}
                for s in sel:
                    counts[s] = counts.get(s, 0) + 1
                top = sorted(counts.items(), key=lambda kv: -kv[1])[:4]
                print(f"choice by {rule}: right in {100 * right:.1f} % of {len(sel)} runs; most chosen: {top}")
        code_key = {"QN": "q", "WN": "n", "RW": "k", "DR": "r"}
        print("IEEE read-offs (tangent lines) vs truth:")
        for t in ch.terms:
            if t.code in code_key:
                r = np.array([o[4][t.code] for o in out])
                tv = abs(getattr(t, code_key[t.code]))
                print(f"  {t.code}: mean read-off / truth = {r.mean() / tv:.3f}  (bias/SD {(r.mean() - tv) / r.std(ddof=1):.2f})")
        gm = [t for t in ch.terms if t.code == "GM"]
        if gm:
            b = np.array([o[4]["BI"] for o in out])
            print(f"  B read-off sigma_min/0.664: mean {b.mean():.4g} rad/s (GM sigmas {[round(g.sigma, 12) for g in gm]})")
        print(f"  starts reaching the best objective: median {np.median([o[7] for o in out]):.0f} of {N_STARTS + 1}")


if __name__ == "__main__":
    main()
