"""Unified estimator against systematic51 and n25 over seeded noisy records.

    .venv/bin/python bench/unified_table.py [--seeds 10] [--first-seed 1] [--json out.json]

Records (all with the S16 section 4.1 IMU errors and noise, ARW 5e-5 deg/sqrt(h), VRW 1 ug/sqrt(Hz),
on a gimbal with dth = 20" and mount attitude [0.1, 0.1, 20] deg, encoders with 1" white noise):

* ``s16-gimbal``: the S16 Table 1 path (1.07 h), calibrated with ``unified`` (58 states, encoder
  attitude rows) and ``systematic51`` (no gimbal angles, no gimbal states);
* the same IMU and gimbal on the N25 path (twelve positions + rate tests, 0.5 h), calibrated with
  ``n25`` (window means; no g-sensitivity, quadratic or lever-arm terms) and with ``unified``.

Per parameter group: the median over seeds and components of |estimate - truth| (field units) and,
for ``unified``, the median of its smoothed 1 sigma (the filter's covariance: the Cramer-Rao bound
of the linearised problem).  For a consistent estimator median |error| ~ 0.67 sigma.  A group a
method does not estimate shows ``n/e`` and, in brackets, the median |truth| its estimate leaves as
error.  Seeds are passed explicitly (``numpy.random.default_rng(seed)``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from types import SimpleNamespace

import numpy as np

from inscal.sim import scenarios
from inscal.calibrate import calibrate
from inscal.core.error_model import PARAMETERS
from inscal.sim.simulate import simulate

GROUPS = [  # (parameter, label); the S16 Table 2 groups first
    ("gyro_g_sensitivity", "gyro g-sensitivity"),
    ("accel_nonlinearity", "accel nonlinearity"),
    ("accel_cross_coupling", "accel cross-coupling"),
    ("accel_lever_arm", "accel lever arm"),
    ("gimbal_nonorthogonality", "gimbal non-orthogonality dth"),
    ("mount_attitude", "mount attitude (a0, b0, g0)"),
    ("gyro_scale_factor", "gyro scale factor"),
    ("gyro_misalignment", "gyro misalignment"),
    ("gyro_bias", "gyro bias"),
    ("accel_scale_factor", "accel scale factor"),
    ("accel_misalignment", "accel misalignment"),
    ("accel_bias", "accel bias"),
]
RUNS = [("unified", "s16"), ("systematic51", "s16"), ("n25", "n25"), ("unified", "n25")]


def records(seed: int):
    """The two records of one seed: (scenario, record) on the S16 and on the N25 path."""
    g = scenarios.build("s16-gimbal")
    n = dataclasses.replace(scenarios.build("n25"), name="n25-s16imu", imu=g.imu, gimbal=g.gimbal, noise=g.noise)
    out = {}
    for key, sc, k in (("s16", g, 0), ("n25", n, 1)):
        d = simulate(sc, np.random.default_rng([seed, k]))
        out[key] = (sc, SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal,
                                        rate_hz=sc.rate_hz, site=sc.site, path=sc.path))
    return out


def errors(res, sc) -> dict:
    """Per estimated group: (|errors|, sigmas) of the components the method estimates (field units);
    groups it does not estimate: (|truth left in|, None)."""
    f = res.to_field((sc.imu, sc.gimbal))
    formal = res.diagnostics.get("formal_sigma") or {}
    out = {}
    for name, _ in GROUPS:
        if name in f:
            e = np.abs(np.ravel(np.asarray(f[name]["error"], float)))
            s = np.ravel(np.asarray(f[name]["sigma"], float))
            if name in formal:  # the smoothed (formal) sigma, before any misfit scaling
                from inscal.core import units

                s = np.ravel(units.from_si(np.asarray(formal[name], float), PARAMETERS[name].unit))
            ok = np.isfinite(s)
            out[name] = (e[ok], s[ok])
        else:
            from inscal.core import units

            p = PARAMETERS[name]
            t = np.ravel(units.from_si(np.asarray(getattr(sc.imu if p.group == "imu" else sc.gimbal, p.attribute), float),
                                       p.unit))
            if name == "accel_lever_arm":
                t = t[[0, 4, 8]]
            out[name] = (np.abs(t), None)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--json", default=None, help="write the per-seed errors and the table here")
    a = ap.parse_args(argv)
    acc = {run: {name: {"err": [], "sig": [], "estimated": True} for name, _ in GROUPS} for run in RUNS}
    diag = {run: [] for run in RUNS}
    t0 = time.perf_counter()
    for seed in range(a.first_seed, a.first_seed + a.seeds):
        recs = records(seed)
        for run in RUNS:
            method, key = run
            sc, rec = recs[key]
            res = calibrate(rec, method)
            for name, (e, s) in errors(res, sc).items():
                acc[run][name]["err"].append(e)
                if s is None:
                    acc[run][name]["estimated"] = False
                else:
                    acc[run][name]["sig"].append(s)
            d = res.diagnostics
            diag[run].append({"seed": seed, "nis_mean": d.get("innovations", {}).get("nis_mean"),
                              "encoder_nis_mean": d.get("encoder", {}).get("nis_mean")})
        print(f"seed {seed} done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    # ---- table
    heads = [f"{m} ({'S16' if k == 's16' else 'N25'} path)" for m, k in RUNS]
    lines = ["| group | unit | " + " | ".join(heads) + " | unified sigma (S16 path) | unified sigma (N25 path) |",
             "|---|---|" + "---|" * (len(RUNS) + 2)]
    table = {}
    for name, label in GROUPS:
        unit = PARAMETERS[name].unit
        row = [label, unit]
        table[name] = {}
        for run in RUNS:
            c = acc[run][name]
            med = float(np.median(np.concatenate(c["err"])))
            table[name][f"{run[0]}@{run[1]}"] = {"median_abs_error": med, "estimated": c["estimated"],
                                                  "median_sigma": float(np.median(np.concatenate(c["sig"])))
                                                  if c["sig"] else None}
            row.append(f"{med:.3g}" if c["estimated"] else f"n/e ({med:.3g})")
        for run in (("unified", "s16"), ("unified", "n25")):
            row.append(f"{table[name][f'{run[0]}@{run[1]}']['median_sigma']:.3g}")
        lines.append("| " + " | ".join(row) + " |")
    print(f"\n{a.seeds} seeds ({a.first_seed}..{a.first_seed + a.seeds - 1}); median |estimate - truth| over seeds "
          "and components; n/e = not estimated (median |truth| left as error); sigma = the unified filter's "
          "smoothed 1 sigma (median)\n")
    print("\n".join(lines))
    for run in RUNS:
        nis = [x["nis_mean"] for x in diag[run] if x["nis_mean"] is not None]
        enc = [x["encoder_nis_mean"] for x in diag[run] if x["encoder_nis_mean"] is not None]
        if nis:
            print(f"{run[0]}@{run[1]}: velocity/position NIS mean {np.mean(nis):.3f} (6 expected)"
                  + (f", encoder NIS mean {np.mean(enc):.3f}" if enc else ""))
    print(f"total {time.perf_counter() - t0:.0f} s")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"seeds": list(range(a.first_seed, a.first_seed + a.seeds)), "table": table,
                       "diagnostics": {f"{m}@{k}": v for (m, k), v in diag.items()}}, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
