"""Benchmark of the ``n25-fig5`` Monte Carlo study (target: the 2,000 runs of N25 Fig. 5 within 2 minutes
on 2 cores).

Default (about a minute): time one simulation and one calibration in this process, the
LocalCluster start-up, and a reduced study on a LocalCluster; extrapolate to the full
study (10 dθ values x 200 runs).  ``--full``: run the whole 2,000-run study and print its
wall time (the results and plot go to ``--out``, by default a temporary folder).

    .venv/bin/python bench/bench_montecarlo.py [--runs 6] [--workers N] [--simulation full|reuse]
    .venv/bin/python bench/bench_montecarlo.py --full --out /tmp/n25-fig5
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import tempfile
import time

import numpy as np

#: the whole 2,000-run study on 2 cores
TARGET_S = 120.0


def _time_one(simulation: str) -> dict:
    from inscal.analysis.studies import common as E
    from inscal.analysis import montecarlo as mc
    from inscal.analysis import studies
    from inscal.cli.montecarlo import format_table
    from inscal.calibrate import calibrate

    exp = studies.get_experiment("n25-fig5", {"dtheta_arcsec": [7.0], "simulation": simulation})
    exp.warmup(exp)
    key = E.scenario_key(exp.params, 7.0)
    E.simulate_record(key, np.random.default_rng(0), simulation)  # fill the cache in reuse mode
    opts = {"uncertainty": exp.params["uncertainty"]}
    calibrate(E.simulate_record(key, np.random.default_rng(0), simulation), exp.params["method"], **opts)  # warm
    ts, tc = [], []
    for i in range(3):
        t0 = time.perf_counter()
        rec = E.simulate_record(key, np.random.default_rng(i + 1), simulation)
        t1 = time.perf_counter()
        calibrate(rec, exp.params["method"], **opts)
        t2 = time.perf_counter()
        ts.append(t1 - t0)
        tc.append(t2 - t1)
    return {"simulate_s": float(np.median(ts)), "calibrate_s": float(np.median(tc))}


def _time_cluster(workers: int) -> float:
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=logging.ERROR)
    client = Client(cluster)
    client.close()
    cluster.close()
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="run the full 2,000-run n25-fig5 study")
    ap.add_argument("--runs", type=int, default=6, help="runs per dθ value of the reduced study (default 6)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--simulation", choices=("full", "reuse"), default=None, help="default: the experiment's default")
    ap.add_argument("--out", default=None, help="study folder (default: a temporary one)")
    ap.add_argument("--json", action="store_true", help="print one JSON line of results at the end")
    a = ap.parse_args(argv)

    from inscal.analysis import montecarlo as mc
    from inscal.analysis import studies
    from inscal.cli.montecarlo import format_table

    params = {} if a.simulation is None else {"simulation": a.simulation}
    exp = studies.get_experiment("n25-fig5", params)
    sim_mode = exp.params["simulation"]
    n_points = len(exp.points)
    target_runs = 200
    report: dict = {"bench": "montecarlo", "experiment": "n25-fig5", "simulation": sim_mode, "workers": a.workers,
                    "cores": os.cpu_count()}
    with tempfile.TemporaryDirectory() as tmp:
        out = a.out or os.path.join(tmp, "study")
        if a.full:
            t0 = time.perf_counter()
            res = mc.run_study(exp, out, target_runs, seed=0, workers=a.workers, force=a.out is None, progress=True)
            wall = time.perf_counter() - t0
            s = mc.summarize(exp, res)
            mc.write_outputs(exp, s, out)
            format_table(s, file=sys.stdout)
            report.update({"mode": "full", "runs": len(res.records), "new_runs": res.n_new, "wall_s": round(wall, 1),
                           "within_target": wall <= TARGET_S if res.n_new == n_points * target_runs else None})
            print(f"full n25-fig5 study: {res.n_new} new runs of {n_points * target_runs} in {wall:.1f} s "
                  f"on {a.workers} worker(s) ({'within' if wall <= TARGET_S else 'OVER'} the {TARGET_S:.0f}-s target); outputs in {out}")
        else:
            one = _time_one(sim_mode)
            t_cluster = _time_cluster(a.workers)
            t0 = time.perf_counter()
            res = mc.run_study(exp, out, a.runs, seed=0, workers=a.workers, force=True)
            wall = time.perf_counter() - t0
            n = res.n_new
            per_run = max(wall - t_cluster, 1e-9) / n
            cpu = float(np.mean([r["elapsed_s"] for r in res.records.values()]))
            extrap = t_cluster + n_points * target_runs * per_run
            report.update({"mode": "reduced", "runs": n, "wall_s": round(wall, 2), "cluster_start_s": round(t_cluster, 2),
                           "per_run_wall_s": round(per_run, 4), "per_run_worker_s": round(cpu, 4), **{k: round(v, 4) for k, v in one.items()},
                           "extrapolated_2000_s": round(extrap, 1), "within_target": extrap <= TARGET_S})
            print(f"one run in this process: simulate {one['simulate_s']:.3f} s + calibrate {one['calibrate_s']:.3f} s "
                  f"(simulation mode {sim_mode!r})")
            print(f"LocalCluster start/stop with {a.workers} workers: {t_cluster:.1f} s")
            print(f"reduced study: {n} runs in {wall:.1f} s -> {per_run:.3f} s wall per run "
                  f"({cpu:.3f} s per run on a worker)")
            print(f"extrapolated full study ({n_points} x {target_runs} runs): {extrap:.0f} s "
                  f"({'within' if extrap <= TARGET_S else 'OVER'} the {TARGET_S:.0f}-s target)")
    if a.json:
        print(json.dumps(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
