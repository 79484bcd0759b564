"""JCGM 101 Monte Carlo check of the linear (GUM) uncertainty budget of the N25 calibration.

Usage::

    .venv/bin/python bench/budget_mc.py [--runs 1000] [--seed 1] [--out /tmp/budget-mc] [--station FILE]

The truth: the built-in ``n25`` scenario (its IMU and gimbal errors).  Every Monte Carlo run draws
the station's errors from their distributions (:meth:`inscal.uncertainty.station.StationInput.draw`): a
table-angle error and an encoder rounding on both axes at every stop, a wobble tilt about east and
north at every stop, one rate-scale error, the table's non-orthogonality, the gravity, latitude and
height errors and the time-base error; writes them, whole (rotation matrices, not the linearisation),
into the noise-free window means of the path (:func:`inscal.uncertainty.sensitivity.perturb`, at the true
geometry), adds the record noise as the window means' own noise (each window's measured sigma, from a
noisy simulation of the same path: the noise the N25 estimator's sigma describes), and calibrates.

Against it: the linear budget of one noisy calibration (:func:`inscal.uncertainty.sensitivity.calibration_budget`):
per parameter component ``u_c`` vs the Monte Carlo standard deviation of the errors (pass: within
10 %), and the coverage of ``estimate +- U`` (95 %) over the truth (pass: 93-97 %).  The runs go
through :mod:`inscal.analysis.montecarlo` (seeded per run, resumable; ``--scheduler local`` for Dask).
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal.analysis.montecarlo import Experiment, Summary, run_study
from inscal.analysis.montecarlo import summarize as mc_summarize
from inscal.calibrate import calibrate, window_means
from inscal.calibrate.result import flatten
from inscal.core.error_model import ImuNoise
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.montecarlo import draw_deviation
from inscal.uncertainty.station import read_station
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias", "gimbal_nonorthogonality", "mount_attitude")
DEFAULT_STATION = Path(__file__).resolve().parents[1] / "tests" / "data" / "station.toml"
DTH = 24  # the flat index of gimbal_nonorthogonality in NAMES


@functools.lru_cache(maxsize=2)
def setup(noise_seed: int):
    """(scenario, noise-free windows, window sigmas (n, 2, 3)) of the n25 path."""
    sc = scenarios.build("n25")
    rec0 = simulate(replace(sc, noise=ImuNoise())).to_record()
    ws0 = window_means(rec0)
    ws1 = window_means(simulate(sc, np.random.default_rng(noise_seed)).to_record())
    if len(ws1.windows) != len(ws0.windows):
        raise RuntimeError("the noisy and the noise-free records segment differently")
    sig = np.array([[w.gyro_sigma, w.accel_sigma] for w in ws1.windows])
    return sc, ws0, sig, ws1


def one_run(exp: Experiment, point: int, rng: np.random.Generator) -> dict:
    """One Monte Carlo run: the estimate minus the truth (SI, flat in NAMES)."""
    p = exp.params
    sc, ws0, sig, _ = setup(p["noise_seed"])
    station = read_station(p["station"])
    nw = len(ws0.windows)
    dev = draw_deviation(station, nw, rng)
    geo = S.Geometry(sc.gimbal.nonorthogonality, sc.gimbal.mount_attitude, sc.imu.M_g, sc.imu.M_a)
    ws = S.perturb(ws0, geo, dev)
    noise = rng.standard_normal((nw, 2, 3)) * sig
    ws = ws.replace_means(np.array([w.gyro for w in ws.windows]) + noise[:, 0],
                          np.array([w.accel for w in ws.windows]) + noise[:, 1])
    r = calibrate(ws, "n25", uncertainty=False)
    truth = flatten(sc.imu, sc.gimbal, NAMES)
    truth[DTH] += dev.nonorthogonality  # the table's own dth is what N25 estimates
    return {"error": (flatten(r.imu, r.gimbal, NAMES) - truth).tolist()}


def summarize(exp: Experiment, results: list[list[dict]]) -> Summary:
    """Per component: linear u_c, Monte Carlo sigma, their ratio, the coverage of +-U."""
    err = np.array([r["error"] for r in results[0]])
    uc, U, labels, scale = (np.array(exp.params[k]) if k != "labels" else exp.params[k]
                            for k in ("u_c_si", "U_si", "labels", "field"))
    sd = err.std(axis=0, ddof=1)
    cover = (np.abs(err) <= U).mean(axis=0)
    rows = []
    for i, lab in enumerate(labels):
        rows.append({"component": lab, "u_c": uc[i] / scale[i], "mc_sigma": sd[i] / scale[i], "ratio": sd[i] / uc[i],
                     "mc_mean": err[:, i].mean() / scale[i], "coverage": cover[i],
                     "ok": bool(abs(sd[i] / uc[i] - 1) <= 0.10 and 0.93 <= cover[i] <= 0.97)})
    return Summary("N25 budget: linear GUM vs JCGM 101 Monte Carlo",
                   [("component", "component"), ("u_c", "u_c (field)"), ("mc_sigma", "MC sigma"), ("ratio", "MC/u_c"),
                    ("mc_mean", "MC mean"), ("coverage", "coverage of +-U")], rows,
                   [f"{len(err)} runs"])


def main() -> None:
    """Run the study and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise-seed", type=int, default=7)
    ap.add_argument("--out", default="/tmp/budget-mc")
    ap.add_argument("--station", default=str(DEFAULT_STATION))
    ap.add_argument("--scheduler", default="synchronous")
    args = ap.parse_args()
    t0 = time.perf_counter()
    sc, ws0, sig, ws1 = setup(args.noise_seed)
    station = read_station(args.station)
    r1 = calibrate(ws1, "n25")
    t1 = time.perf_counter()
    b = S.calibration_budget(r1, station)
    t_budget = time.perf_counter() - t1
    labels = [c.label for c in b.components]
    from inscal.core import units

    field = [float(units.to_si(1.0, c.unit)) for c in b.components]
    params = {"station": args.station, "noise_seed": args.noise_seed, "labels": labels, "field": field,
              "u_c_si": [c.u_c * f for c, f in zip(b.components, field)],
              "U_si": [c.U * f for c, f in zip(b.components, field)]}
    exp = Experiment("budget-mc-n25", params, ({"path": "n25"},), one_run, summarize)
    t2 = time.perf_counter()
    res = run_study(exp, args.out, args.runs, args.seed, scheduler=args.scheduler, force=True)
    t_mc = time.perf_counter() - t2
    s = mc_summarize(exp, res)
    print(f"setup {t1 - t0:.1f} s, linear budget {t_budget:.1f} s, {args.runs} MC runs {t_mc:.1f} s")
    print(f"{'component':26s} {'u_c':>10s} {'MC sd':>10s} {'ratio':>6s} {'MC mean':>10s} {'cover':>6s}")
    for row in s.rows:
        print(f"{row['component']:26s} {row['u_c']:10.4g} {row['mc_sigma']:10.4g} {row['ratio']:6.3f} "
              f"{row['mc_mean']:10.3g} {row['coverage']:6.3f} {'ok' if row['ok'] else 'FAIL'}")
    Path(args.out, "table.json").write_text(json.dumps(s.to_dict(), indent=1))
    print(f"{sum(r['ok'] for r in s.rows)}/{len(s.rows)} components pass (ratio within 10 %, coverage 93-97 %)")
    print("max |ratio-1|", max(abs(r["ratio"] - 1) for r in s.rows), "coverage range",
          min(r["coverage"] for r in s.rows), max(r["coverage"] for r in s.rows))
    print("notes:", s.notes, "failed:", s.data.get("runs_failed"), "run seconds:", s.data.get("run_seconds_total"))


if __name__ == "__main__":
    main()
