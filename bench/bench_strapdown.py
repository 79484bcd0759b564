"""Benchmark: strapdown mechanization throughput (samples per second after compilation), the
kernel alone and the public :func:`inscal.nav.navigate` on the same data.

Feeds a 5-day, 100 Hz record (43.2 M samples) through the navigator in chunks of
2^20 samples, as a streamed record would be: one chunk of simulated increments
(rotation-modulated, noise-free) is generated once and fed repeatedly with the state
carried across calls, so only one chunk of increments is ever in memory.  Timed after
a warm-up call (compilation).  Figures:

* the kernel (:meth:`Strapdown.run` chunk by chunk) with 1-Hz output, with full-rate output,
  and with a full 51-state (S16) parameter set compensated on the fly;
* :func:`navigate` on the same chunks (with their time stamps and gimbal angles) with 1-Hz
  output and the errors against the scenario's truth, as ``inscal navigate`` does on a simulated
  record, and its time over the kernel's (1-Hz output, the best of two alternating runs each);
* the peak RSS of a process that runs that :func:`navigate` (``--days`` of data).

Run: python bench/bench_strapdown.py [--days D] [--rate HZ]
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import time

import numpy as np

from inscal.core import turntable
from inscal.core.earth import Site
from inscal.core.error_model import ImuErrors
from inscal.nav.run import navigate
from inscal.nav.strapdown import NavConfig, NavState, Strapdown
from inscal.sim.simulate import Scenario, simulate_chunks

CHUNK = 1 << 20


def scenario(days: float, rate: float) -> Scenario:
    return Scenario("bench", turntable.rotmod16(days * 86400.0), Site(math.radians(30.0)), rate_hz=rate)


def first_chunk(scn: Scenario):
    ch = next(simulate_chunks(scn, None, chunk_size=CHUNK))
    return np.ascontiguousarray(ch.dtheta), np.ascontiguousarray(ch.dvel), np.ascontiguousarray(ch.gimbal)


def kernel(scn: Scenario, dth, dv, total: int, out_hz: float, params: ImuErrors | None) -> float:
    """Seconds for ``total`` samples through :meth:`Strapdown.run`, chunk by chunk."""
    rate = scn.rate_hz
    nav = Strapdown(NavState.from_truth(scn), 1.0 / rate, NavConfig(output_rate_hz=out_hz), params)
    nav.run(dth[:1000], dv[:1000])  # compile / warm up
    nav = Strapdown(NavState.from_truth(scn), 1.0 / rate, NavConfig(output_rate_hz=out_hz), params)
    done = 0
    t0 = time.perf_counter()
    while done < total:
        n = min(CHUNK, total - done)
        nav.run(dth[:n], dv[:n])
        done += n
    return time.perf_counter() - t0


def chunks(dth, dv, g, total: int, rate: float):
    """The repeated chunk as a record's ``(time, dtheta, dvel, gimbal)`` chunks (the time stamps
    written into one buffer: a reader's cost is not navigate()'s)."""
    tk = np.arange(1, dth.shape[0] + 1) / rate
    t = np.empty_like(tk)
    done = 0
    while done < total:
        n = min(CHUNK, total - done)
        np.add(tk[:n], done / rate, out=t[:n])
        yield t[:n], dth[:n], dv[:n], g[:n]
        done += n


def public(scn: Scenario, dth, dv, g, total: int) -> float:
    """Seconds for :func:`navigate` on ``total`` samples (1-Hz output, errors against the truth)."""
    init = NavState.from_truth(scn)
    t0 = time.perf_counter()
    navigate(chunks(dth, dv, g, total, scn.rate_hz), scn.rate_hz, scn.site, init=init, scenario=scn,
             config=NavConfig(output_rate_hz=1.0))
    return time.perf_counter() - t0


def peak_rss_mb(days: float, rate: float) -> float:
    """Peak RSS [MB] of a child process that runs :func:`public` once (after its warm-up)."""
    p = subprocess.Popen([sys.executable, __file__, "--days", str(days), "--rate", str(rate), "--rss-child"],
                         stdout=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    if status != 0:
        raise RuntimeError(f"navigate child exited with {status}")
    return ru.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=float, default=5.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--rss-child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    scn = scenario(a.days, a.rate)
    dth, dv, g = first_chunk(scn)
    total = round(a.days * 86400 * a.rate)
    if a.rss_child:
        public(scn, dth[:1000], dv[:1000], g[:1000], 1000)  # compile / warm up
        public(scn, dth, dv, g, total)
        return
    deg_h, ug = math.pi / 180 / 3600, 9.80665e-6
    s16 = ImuErrors(gyro_scale_factor=[3e-4] * 3, gyro_misalignment=[8.7e-4] * 6, gyro_bias=[0.05 * deg_h] * 3,
                    gyro_g_sensitivity=np.full((3, 3), 0.001 * deg_h / 9.80665), accel_scale_factor=[3e-4] * 3,
                    accel_misalignment=[8.7e-4] * 6, accel_bias=[200 * ug] * 3,
                    accel_nonlinearity=[300 * ug / 9.80665**2] * 3, accel_cross_coupling=[300 * ug / 9.80665**2] * 6,
                    accel_lever_arm=[0.02, 0.02, 0.02])
    what = f"{total / 1e6:.1f} M samples, {a.days:g} d at {a.rate:g} Hz"
    public(scn, dth[:1000], dv[:1000], g[:1000], 1000)  # compile / warm up
    tk = tn = math.inf
    for _ in range(2):  # alternating, the best of two each: the ratio sees the same machine load
        tk = min(tk, kernel(scn, dth, dv, total, 1.0, None))
        tn = min(tn, public(scn, dth, dv, g, total))
    print(f"strapdown kernel, 1-Hz output: {total / tk / 1e6:.2f} M samples/s ({what}) in {tk:.2f} s")
    el = kernel(scn, dth, dv, total, a.rate, None)
    print(f"strapdown kernel, full-rate output: {total / el / 1e6:.2f} M samples/s ({what}) in {el:.2f} s")
    el = kernel(scn, dth, dv, total, 1.0, s16)
    print(f"strapdown kernel, S16 51-state compensation on the fly: {total / el / 1e6:.2f} M samples/s ({what}) "
          f"in {el:.2f} s")
    print(f"navigate(), 1-Hz output, errors against the truth: {total / tn / 1e6:.2f} M samples/s ({what}) "
          f"in {tn:.2f} s; navigate()/kernel = {tn / tk:.2f}")
    print(f"navigate() peak RSS ({what}): {peak_rss_mb(a.days, a.rate):.0f} MB")


if __name__ == "__main__":
    main()
