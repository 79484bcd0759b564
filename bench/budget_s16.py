"""The S16 path (the systematic filter) in the uncertainty budget: its linear budget and the checks a
1000-run JCGM 101 Monte Carlo of it cannot afford here (one filter run: ~7-10 s on one core).

Usage::

    .venv/bin/python bench/budget_s16.py [--seed 3] [--method systematic30]

1. The linear budget of one noisy ``s16`` record (:func:`inscal.uncertainty.sensitivity.calibration_budget`:
   central differences of the filter through the estimator's belief of the site and clock).
2. Closed forms: a gravity error dg/g and a time-base error eps in the accelerometer scale factors 1:1.
3. The table's inputs enter the filter with sensitivity 0: the same record simulated along a path whose
   every move is off by a normal 2 arcsec (the stops land elsewhere; the filter is told nothing) gives the
   same estimate to within a small fraction of its sigma.
4. Linearity: the estimate at +-3 u of the gravity and the time base against the linear prediction.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal.calibrate import calibrate
from inscal.calibrate.result import flatten, nparams
from inscal.core import units
from inscal.core.turntable import Move, RotationPath
from inscal.core.units import ARCSEC
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.station import read_station
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

STATION = Path(__file__).resolve().parents[1] / "tests" / "data" / "station.toml"


def moved(path: RotationPath, rng: np.random.Generator, sigma: float) -> RotationPath:
    """``path`` with every turn off by a normal ``sigma`` [rad] (the stops accumulate them; not closed)."""
    moves = tuple(replace(m, angle=m.angle + rng.normal(0.0, sigma)) if m.axis != "none" else m for m in path.moves)
    return replace(path, moves=moves, closed=False)


def main() -> None:
    """Run the checks and print them."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--method", default="systematic30")
    args = ap.parse_args()
    st = read_station(STATION)
    sc = scenarios.build("s16")
    sc = replace(sc, site=sc.site.with_gravity(st["gravity"].value))
    rec = simulate(sc, np.random.default_rng(args.seed)).to_record()
    t0 = time.perf_counter()
    r = calibrate(rec, args.method, states="30")
    t_run = time.perf_counter() - t0
    opts = {"states": "30", "arw": units.to_si(r.diagnostics["noise"]["arw_deg_sqrt_h"], "deg/sqrt(h)"),
            "vrw": units.to_si(r.diagnostics["noise"]["vrw_ug_sqrt_hz"], "ug/sqrt(Hz)")}
    t0 = time.perf_counter()
    b = S.calibration_budget(r, st, record=rec, **opts)
    t_budget = time.perf_counter() - t0
    print(f"one {args.method} run {t_run:.1f} s; the linear budget (8 more runs) {t_budget:.1f} s")
    for c in b.components:
        top = max(c.contributions, key=lambda x: x.share)
        print(f"  {c.label:24s} u_c {c.u_c:9.4g} {c.unit:7s} U {c.U:9.4g} k {c.k:.3f}  largest {top.input} "
              f"{top.share * 100:.0f} %")
    g = rec.site.gravity
    asf = [c for c in b.components if c.parameter == "accel_scale_factor"]
    grav = [next(x for x in c.contributions if x.input == "gravity").sensitivity for c in asf]
    tb = [next(x for x in c.contributions if x.input == "time_base").sensitivity for c in asf]  # |c| (GUM lines)
    print("closed form: gravity -> accel scale factor [ppm/mGal]", np.round(grav, 4), "expected", 1e-5 / g * 1e6)
    print("closed form: time base -> accel scale factor [ppm/ppm]", np.round(tb, 4), "expected 1")
    # 3. the table's errors: a path whose stops are off by 2 arcsec, the record's table angles kept
    names = r.estimated
    x0 = flatten(r.imu, r.gimbal, names)
    sig = np.concatenate([np.ravel(r.sigma[n]) for n in names])
    sc2 = replace(sc, path=moved(sc.path, np.random.default_rng(11), 2.0 * ARCSEC))
    rec2 = simulate(sc2, np.random.default_rng(args.seed)).to_record()
    rec2 = replace(rec2, gimbal=None if rec.gimbal is None else rec.gimbal[:rec2.time.size], path=rec.path)
    r2 = calibrate(rec2, args.method, **opts)
    d = (flatten(r2.imu, r2.gimbal, names) - x0) / sig
    print(f"table stops moved by N(0, 2 arcsec): estimate change / sigma: max {np.nanmax(np.abs(d)):.3f}, "
          f"rms {np.sqrt(np.nanmean(d ** 2)):.3f} (sensitivity 0 expected)")
    # 4. linearity at 3 u: the slope of the accelerometer scale factors between -3u and +3u
    j = nparams(names[:names.index("accel_scale_factor")])
    for key, u in (("gravity", st["gravity"].u), ("time_base", st["time_base"].u)):
        xs = []
        for s in (-1, 1):
            q = calibrate(S.believe_record(rec, S.Deviation(**{key: s * 3 * u})), args.method, **opts)
            xs.append(flatten(q.imu, q.gimbal, names))
        slope = (xs[1] - xs[0])[j:j + 3] / (6 * u)  # Deviation: truth minus belief
        print(f"{key} at +-3u: accel scale factor slope {np.round(slope, 4)} [1 per SI unit of the input]")

if __name__ == "__main__":
    main()
