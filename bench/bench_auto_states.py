"""Benchmark: the automatic choice of the systematic filter's optional terms (``--states auto``,
:func:`inscal.calibrate.systematic.selection.select_states`) on the ``psins19`` record with its noise
(1035.6 s at 100 Hz, ARW 0.002 deg/sqrt(h), VRW 5 ug/sqrt(Hz)).

Four truths, each over the same seeds (one noise draw per seed):

* ``plain``: the psins19 IMU as built (no asynchrony, lever arms along each accelerometer's axis);
* ``async``: plus a 1 ms gyro-accelerometer time asynchrony;
* ``lever9``: plus off-diagonal lever-arm components of 1-2 cm (the full 3x3 inner lever arm);
* ``both``: both.

(a) For every seed, ``systematic51(rec, states="auto")``: the chosen set is right when its optional
    terms (``async``, ``lever9``) are exactly the truth's.  Printed per variant: the seeds with the
    right set, per term the seeds deciding it right, and the chosen sets with their counts.  The
    droppable groups are decided too and shown, not scored: ``nocross`` should never be chosen (the
    psins19 cross-coupling of 10-28 ug/g^2 is significant); ``gdiag`` (drop the off-diagonal
    g-sensitivity) may be, although the truth has two such terms (2e-4 and 1e-4 deg/h/g): they are
    below what this record resolves at this noise, so the F-test rightly finds them insignificant.
(b) The wall time of the auto fit (its nested fits) against one explicit ``systematic51`` fit
    (``states="51"``) of the same record, median over the seeds, after a warm-up (numba cache).

Run: ``python bench/bench_auto_states.py [--seeds N] [--quick]`` (``--quick``: 3 seeds).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from collections import Counter
from types import SimpleNamespace

import numpy as np

from inscal.calibrate.systematic import systematic51
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

#: off-diagonal inner lever-arm components added by the lever9 variants [m] (as tests/calibrate/test_selection.py)
OFF_DIAGONAL_LEVER = np.array([[0.0, 0.01, -0.02], [0.015, 0.0, 0.01], [-0.01, 0.02, 0.0]])
ASYNC_S = 1e-3
#: variant -> (time asynchrony [s], full lever arm)
VARIANTS = {"plain": (0.0, False), "async": (ASYNC_S, False), "lever9": (0.0, True), "both": (ASYNC_S, True)}
OPTIONAL = ("async", "lever9")


def scenario(async_s: float, lever9: bool):
    sc = scenarios.build("psins19")
    imu = sc.imu.replace(time_asynchrony=async_s)
    if lever9:
        imu = imu.replace(accel_lever_arm=np.asarray(sc.imu.accel_lever_arm) + OFF_DIAGONAL_LEVER)
    return dataclasses.replace(sc, imu=imu)


def record(sc, seed: int):
    d = simulate(sc, np.random.default_rng(seed))
    return SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=None, rate_hz=sc.rate_hz, site=sc.site)


def truth_terms(async_s: float, lever9: bool) -> set[str]:
    return ({"async"} if async_s else set()) | ({"lever9"} if lever9 else set())


def _warm_up() -> float:
    """Load (or compile) the kernels on a short record: not part of any timing."""
    sc = scenarios.build("psins19")
    rec = record(sc, 12345)
    n = int(300 * sc.rate_hz)
    short = SimpleNamespace(dtheta=rec.dtheta[:n], dvel=rec.dvel[:n], rate_hz=rec.rate_hz, site=rec.site)
    t0 = time.perf_counter()
    systematic51(short, states="lever9,async", max_passes=1, accept_unconverged=True)
    return time.perf_counter() - t0


def run_variant(name: str, seeds: list[int]) -> dict:
    async_s, lever9 = VARIANTS[name]
    sc = scenario(async_s, lever9)
    truth = truth_terms(async_s, lever9)
    rows = []
    for seed in seeds:
        rec = record(sc, seed)
        t0 = time.perf_counter()
        res = systematic51(rec, states="auto")
        t_auto = time.perf_counter() - t0
        t0 = time.perf_counter()
        systematic51(rec, states="51")
        t_51 = time.perf_counter() - t0
        sel = res.diagnostics["selection"]
        chosen = set(sel["chosen"].split(","))
        rows.append({"seed": seed, "chosen": sel["chosen"], "optional": chosen & set(OPTIONAL),
                     "fits": sel["fits"], "t_auto": t_auto, "t_51": t_51})
    right = sum(r["optional"] == truth for r in rows)
    per_term = {t: sum((t in r["optional"]) == (t in truth) for r in rows) for t in OPTIONAL}
    return {"variant": name, "truth": truth, "rows": rows, "right": right, "per_term": per_term,
            "sets": Counter(r["chosen"] for r in rows)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10, help="noise draws per variant (default 10)")
    ap.add_argument("--quick", action="store_true", help="3 seeds (a smoke run)")
    a = ap.parse_args(argv)
    n = 3 if a.quick else a.seeds
    if n < 1:
        ap.error("--seeds must be >= 1")
    seeds = list(range(n))
    load0 = os.getloadavg()
    t_warm = _warm_up()
    t_start = time.perf_counter()
    out = [run_variant(v, seeds) for v in VARIANTS]
    t_total = time.perf_counter() - t_start

    sc = scenarios.build("psins19")
    print(f"bench_auto_states: psins19 record ({sc.n_samples} samples, {sc.path.duration:.1f} s at {sc.rate_hz:g} Hz, "
          f"with noise), {n} seeds x {len(VARIANTS)} variants; warm-up {t_warm:.1f} s (not timed), "
          f"total {t_total:.0f} s")
    cores = os.cpu_count() or 1
    print(f"  {cores} cores, load average {load0[0]:.1f} at the start, {os.getloadavg()[0]:.1f} now"
          + ("  (busy machine: other processes share the cores, the times are inflated)" if load0[0] > 0.75 * cores
             else ""))
    print("  (a) terms chosen by systematic51(rec, states='auto'): seeds whose optional terms (async, lever9)"
          " are exactly the truth's")
    w = 8
    print(f"  {'variant':<{w}} {'truth':<14} {'right set':>10} {'async ok':>9} {'lever9 ok':>10}   chosen sets (seeds)")
    for r in out:
        truth = ",".join(t for t in OPTIONAL if t in r["truth"]) or "-"
        sets = "; ".join(f"{k} ({c})" for k, c in r["sets"].most_common())
        print(f"  {r['variant']:<{w}} {truth:<14} {r['right']:>6d}/{n:<3d} {r['per_term']['async']:>5d}/{n:<3d} "
              f"{r['per_term']['lever9']:>6d}/{n:<3d}   {sets}")
    tot_right = sum(r["right"] for r in out)
    print(f"  {'all':<{w}} {'':<14} {tot_right:>6d}/{n * len(out):<3d}")
    wrong = [(r["variant"], x["seed"], x["chosen"]) for r in out for x in r["rows"] if x["optional"] != r["truth"]]
    if wrong:
        print("  wrong choices (variant, seed, chosen): " + "; ".join(f"{v} {s} {c}" for v, s, c in wrong))
    print("  (b) wall time per record, median over the seeds [s]: auto (all its nested fits) vs one explicit '51' fit")
    print(f"  {'variant':<{w}} {'auto':>8} {'51':>8} {'ratio':>7} {'fits':>6}")
    all_auto, all_51 = [], []
    for r in out:
        ta = np.array([x["t_auto"] for x in r["rows"]])
        t5 = np.array([x["t_51"] for x in r["rows"]])
        fits = Counter(x["fits"] for x in r["rows"])
        all_auto += list(ta)
        all_51 += list(t5)
        print(f"  {r['variant']:<{w}} {np.median(ta):>8.2f} {np.median(t5):>8.2f} {np.median(ta / t5):>6.1f}x "
              f"{'/'.join(str(k) for k in sorted(fits)):>6}")
    ratio = np.median(np.array(all_auto) / np.array(all_51))
    print(f"  {'all':<{w}} {np.median(all_auto):>8.2f} {np.median(all_51):>8.2f} {ratio:>6.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
