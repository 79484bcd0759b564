"""Monte Carlo coverage of the multi-position calibration (no turntable): 50 seeds of a noisy hand-held
log (12 poses, tremor 0.5 deg at 8 Hz in the moves, clock jitter 20 %) from the independent generator
of tests/oracles/handheld_imu.py, per grade; prints the spread (standard deviation) of error / sigma of
every parameter group and overall (target 0.8 - 1.2) and the share of |error| < 3 sigma.

Run: ``python bench/bench_multiposition.py [seeds] [grades...]`` (default 50 seeds, mems tactical).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "oracles"))
from handheld_imu import canonical_truth, generate, grade  # noqa: E402

from inscal.calibrate import calibrate  # noqa: E402
from inscal.core.earth import Site  # noqa: E402

NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias")


def study(kind: str, seeds: int) -> dict:
    z = {n: [] for n in NAMES}
    rejected = 0
    t0 = time.process_time()
    for seed in range(seeds):
        rng = np.random.default_rng(1000 + seed)
        Mg, bg, Ma, ba, arw, vrw = grade(kind, rng)
        lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=100.0, lat=0.8, g=9.80, arw=arw, vrw=vrw,
                      tremor_deg=0.5, tremor_hz=8.0, jitter=0.2)
        rec = SimpleNamespace(time=lg.time, dtheta=lg.dtheta, dvel=lg.dvel, site=Site(0.8, gravity_model=9.80))
        res = calibrate(rec, "multi-position", min_static=2.0, settle=0.25)
        rejected += not res.fit["consistent"]
        truth = canonical_truth(Mg, bg, Ma, ba)
        for n in NAMES:
            s = res.sigma[n]
            free = np.isfinite(s)
            z[n].extend(((res.value(n) - truth[n])[free] / s[free]).tolist())
    out = {n: (float(np.std(v)), float(np.mean(np.abs(v) < 3.0))) for n, v in z.items()}
    allz = np.concatenate([np.asarray(v) for v in z.values()])
    out["all"] = (float(np.std(allz)), float(np.mean(np.abs(allz) < 3.0)))
    out["cpu_s_per_fit"] = (time.process_time() - t0) / seeds
    out["fits_rejecting_the_model"] = rejected
    return out


def main() -> None:
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    grades = sys.argv[2:] or ["mems", "tactical"]
    for kind in grades:
        r = study(kind, seeds)
        print(f"{kind}: {seeds} seeds, {r['cpu_s_per_fit']:.2f} s CPU per log, {r['fits_rejecting_the_model']} fits "
              "rejecting the model (p < 0.001)")
        for n in (*NAMES, "all"):
            sd, cov = r[n]
            print(f"  {n:20s} std(error/sigma) {sd:.3f}   |error| < 3 sigma: {cov:.1%}")


if __name__ == "__main__":
    main()
