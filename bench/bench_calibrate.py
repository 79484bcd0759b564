"""Benchmark: one full n25 calibration (segmentation, the method, error propagation) of a
simulated N25 record (246 500 samples at 100 Hz, with noise), timed after a warm-up.

Run: ``python bench/bench_calibrate.py``.  Target: under 1 s.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from inscal.sim import scenarios, simulate
from inscal.calibrate import calibrate


def main(repeats: int = 5) -> float:
    sc = scenarios.build("n25")
    d = simulate.simulate(sc, np.random.default_rng(1))
    rec = SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal, rate_hz=sc.rate_hz, site=sc.site)
    calibrate(rec, "n25")  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        calibrate(rec, "n25")
        times.append(time.perf_counter() - t0)
    best = min(times)
    print(f"bench_calibrate: n25 calibration of a {d.time.size}-sample record: best {best:.3f} s, "
          f"median {float(np.median(times)):.3f} s over {repeats} runs (target < 1 s)")
    return best


if __name__ == "__main__":
    main()
