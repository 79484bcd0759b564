"""The Cramér-Rao bound against a noise-only Monte Carlo of the ``systematic51`` calibration.

For each scenario (``s16``: S16 Table 1, ``n25``: N25 twelve positions + rate tests, ``psins19``:
PSINS-style 19 positions; their own IMU truth, site, gimbal geometry and noise), ``--runs``
records are simulated with independent noise (seeded: ``SeedSequence([seed, scenario index,
run])``; the truth is fixed) at ``--rate-hz`` (default 50 Hz: the bound is rate-independent,
the filter's discretisation at 50 Hz costs < 1 %), each calibrated with ``systematic51``
(default options: noise estimated from the record, up to 5 passes).  Per parameter state of the
filter (estimate - truth in the filter's frame, :meth:`CompParams.error_state` against
:func:`truth_in_frame`):

* ``std`` of the errors over the runs, against the bound ``sigma`` (:func:`inscal.plan.bound.crlb`
  with the scenario's noise) and against the predicted fixed-truth spread ``s`` and mean ``m`` of
  :func:`inscal.plan.bound.predicted_error` (``s = sigma`` and ``m = 0`` where the data
  dominate the prior; where the bound is not far below the prior a fixed truth spreads less than
  the Bayesian bound and the prior pulls the mean);
* per group: min / max of ``std / sigma`` and of ``std / s``, the RMS of ``(error - m) / s``;
  states whose bound is above ``WEAK`` (0.3) of the prior are listed apart.

The sampling 95 % band of ``std / s`` over R runs is about ``1 +- 1.96 / sqrt(2 (R - 1))``
(+-20 % at R = 50), so with ~40 states a few excursions near 20 % are expected by chance.

Run: ``python bench/crlb_vs_mc.py [--runs 50] [--rate-hz 50] [--workers 2] [--scenarios s16,n25,psins19]
[--json OUT.json]``; a few minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

WEAK = 0.3


def _scenario(name: str, rate_hz: float):
    from inscal.sim.scenarios import build

    return replace(build(name), rate_hz=float(rate_hz))


def one_run(args) -> np.ndarray:
    """Error state (estimate - truth, SI) of one seeded noise-only systematic51 calibration."""
    name, rate_hz, seed, idx, run = args
    from inscal.calibrate.systematic.params import CompParams, truth_in_frame
    from inscal.calibrate.systematic.methods import systematic51
    from inscal.sim.simulate import simulate

    sc = _scenario(name, rate_hz)
    rng = np.random.default_rng(np.random.SeedSequence([seed, idx, run]))
    d = simulate(sc, rng)
    rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=sc.rate_hz, site=sc.site)
    res = systematic51(rec)
    st = res.states
    return CompParams.from_imu(res.imu).error_state(st, truth_in_frame(sc.imu, st))


def compare(name: str, errors: np.ndarray, rate_hz: float) -> dict:
    from inscal.core import units
    from inscal.plan.bound import crlb, predicted_error

    sc = _scenario(name, rate_hz)
    b = crlb(sc, "51")
    m, s = predicted_error(b, sc.imu)
    sig = b.sigma
    std = np.std(errors, axis=0, ddof=1)
    mean = np.mean(errors, axis=0)
    z = (errors - m) / s
    weak = sig / b.prior > WEAK
    groups = {}
    for k, lab in enumerate(b.labels):
        g = b.setup.groups[k]
        u = b.setup.units_[k]
        d = groups.setdefault(g, {"unit": u, "rows": []})
        d["rows"].append({"label": lab, "bound": float(units.from_si(sig[k], u)),
                          "spread": float(units.from_si(s[k], u)), "std": float(units.from_si(std[k], u)),
                          "mean": float(units.from_si(mean[k], u)), "pred_mean": float(units.from_si(m[k], u)),
                          "std_over_bound": float(std[k] / sig[k]), "std_over_spread": float(std[k] / s[k]),
                          "rms_z": float(np.sqrt(np.mean(z[:, k] ** 2))), "weak": bool(weak[k])})
    summary = {}
    for g, d in groups.items():
        rows = d["rows"]
        strong = [r for r in rows if not r["weak"]]
        rb = [r["std_over_bound"] for r in strong] or [math.nan]
        rs = [r["std_over_spread"] for r in rows]
        summary[g] = {"unit": d["unit"], "n": len(rows), "n_weak": len(rows) - len(strong),
                      "std_over_bound_min": float(np.min(rb)), "std_over_bound_max": float(np.max(rb)),
                      "std_over_spread_min": float(np.min(rs)), "std_over_spread_max": float(np.max(rs)),
                      "rms_z": float(np.sqrt(np.mean([r["rms_z"] ** 2 for r in rows]))),
                      "bound_rms": float(np.sqrt(np.mean([r["bound"] ** 2 for r in rows])))}
    return {"scenario": name, "path": sc.path.name, "duration_s": sc.path.duration, "runs": int(errors.shape[0]),
            "rate_hz": rate_hz, "groups": summary, "parameters": groups,
            "rms_z_all": float(np.sqrt(np.mean(z**2))),
            "max_abs_dev_spread": float(np.max(np.abs(std / s - 1))),
            "max_abs_dev_bound_strong": float(np.max(np.abs(std[~weak] / sig[~weak] - 1))) if np.any(~weak) else None}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--rate-hz", type=float, default=50.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2016)
    ap.add_argument("--scenarios", default="s16,n25,psins19")
    ap.add_argument("--json", default=None, help="write the full comparison as JSON")
    a = ap.parse_args(argv)
    names = [s.strip() for s in a.scenarios.split(",") if s.strip()]
    t0 = time.perf_counter()
    tasks = [(n, a.rate_hz, a.seed, i, r) for i, n in enumerate(names) for r in range(a.runs)]
    out = {n: [] for n in names}
    with ProcessPoolExecutor(max_workers=max(1, a.workers)) as ex:
        for (n, *_), e in zip(tasks, ex.map(one_run, tasks, chunksize=2)):
            out[n].append(e)
    t_mc = time.perf_counter() - t0
    results = []
    band = 1.96 / math.sqrt(2 * (a.runs - 1))
    print(f"crlb_vs_mc: {a.runs} noise-only runs of systematic51 per scenario at {a.rate_hz:g} Hz, seed {a.seed}; "
          f"{t_mc:.0f} s on {a.workers} workers ({os.cpu_count()} cores); sampling 95 % band of std/s: "
          f"[{1 - band:.2f}, {1 + band:.2f}]")
    for n in names:
        r = compare(n, np.array(out[n]), a.rate_hz)
        results.append(r)
        print(f"\n== {n} (path {r['path']}, {r['duration_s']:.0f} s): RMS of (error - m) / s over all states "
              f"{r['rms_z_all']:.3f}; max |std/s - 1| {r['max_abs_dev_spread']:.3f}"
              + (f"; max |std/bound - 1| (bound < {WEAK:g} prior) {r['max_abs_dev_bound_strong']:.3f}"
                 if r["max_abs_dev_bound_strong"] is not None else ""))
        print(f"  {'group':<22} {'unit':<8} {'n':>2} {'weak':>4} {'bound RMS':>10} {'std/bound':>15} "
              f"{'std/s':>15} {'RMS z':>6}")
        for g, s in r["groups"].items():
            print(f"  {g:<22} {s['unit']:<8} {s['n']:>2} {s['n_weak']:>4} {s['bound_rms']:>10.3g} "
                  f"{s['std_over_bound_min']:>7.3f}-{s['std_over_bound_max']:<7.3f} "
                  f"{s['std_over_spread_min']:>7.3f}-{s['std_over_spread_max']:<7.3f} {s['rms_z']:>6.3f}")
        weak = [p for d in r["parameters"].values() for p in d["rows"] if p["weak"]]
        if weak:
            print(f"  weak states (bound > {WEAK:g} prior; std/s, std/bound): "
                  + ", ".join(f"{p['label']} {p['std_over_spread']:.2f}, {p['std_over_bound']:.2f}" for p in weak))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"runs": a.runs, "rate_hz": a.rate_hz, "seed": a.seed, "seconds": t_mc, "results": results},
                      fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
