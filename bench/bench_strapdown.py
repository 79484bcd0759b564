"""Benchmark: strapdown mechanization throughput (samples per second after compilation).

Feeds a 5-day, 100 Hz record (43.2 M samples) through the navigator in chunks of
2^20 samples, as a streamed record would be: one chunk of simulated increments
(rotation-modulated, noise-free) is generated once and fed repeatedly with the state
carried across calls, so only one chunk of increments is ever in memory.  Timed after
a warm-up call (compilation).  Two figures: raw increments, and with a full 51-state
(S16) parameter set compensated on the fly.

Run: python bench/bench_strapdown.py [--days D] [--rate HZ]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from inscal.core import turntable
from inscal.core.error_model import ImuErrors
from inscal.sim.simulate import Scenario, simulate_chunks
from inscal.core.earth import Site
from inscal.nav.strapdown import NavConfig, NavState, Strapdown

CHUNK = 1 << 20


def bench(days: float, rate: float, params: ImuErrors | None) -> tuple[float, int, float]:
    scn = Scenario("bench", turntable.rotmod16(2 * 3600), Site(math.radians(30.0)), rate_hz=rate)
    ch = next(simulate_chunks(scn, None, chunk_size=CHUNK))
    dth, dv = np.ascontiguousarray(ch.dtheta), np.ascontiguousarray(ch.dvel)
    total = int(round(days * 86400 * rate))
    nav = Strapdown(NavState.from_truth(scn), 1.0 / rate, NavConfig(output_rate_hz=1.0), params)
    nav.run(dth[:1000], dv[:1000])  # compile / warm up
    nav = Strapdown(NavState.from_truth(scn), 1.0 / rate, NavConfig(output_rate_hz=1.0), params)
    done = 0
    t0 = time.perf_counter()
    while done < total:
        n = min(CHUNK, total - done)
        nav.run(dth[:n], dv[:n])
        done += n
    el = time.perf_counter() - t0
    return done / el, done, el


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=float, default=5.0)
    ap.add_argument("--rate", type=float, default=100.0)
    a = ap.parse_args()
    deg_h, ug = math.pi / 180 / 3600, 9.80665e-6
    s16 = ImuErrors(gyro_scale_factor=[3e-4] * 3, gyro_misalignment=[8.7e-4] * 6, gyro_bias=[0.05 * deg_h] * 3,
                    gyro_g_sensitivity=np.full((3, 3), 0.001 * deg_h / 9.80665), accel_scale_factor=[3e-4] * 3,
                    accel_misalignment=[8.7e-4] * 6, accel_bias=[200 * ug] * 3,
                    accel_nonlinearity=[300 * ug / 9.80665**2] * 3, accel_cross_coupling=[300 * ug / 9.80665**2] * 6,
                    accel_lever_arm=[0.02, 0.02, 0.02])
    for label, params in (("no compensation", None), ("S16 51-state compensation on the fly", s16)):
        sps, n, el = bench(a.days, a.rate, params)
        print(f"strapdown: {sps / 1e6:.2f} M samples/s ({n / 1e6:.1f} M samples, {a.days:g} d at {a.rate:g} Hz, "
              f"{el:.2f} s; {label})")


if __name__ == "__main__":
    main()
