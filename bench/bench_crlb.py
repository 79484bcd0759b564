"""Benchmark: the Cramér-Rao bound of one candidate path (:mod:`inscal.plan.bound`), after
compilation.

Times (best of ``--repeats``, wall clock and CPU time of this process) of
``crlb.evaluate(setup, path)`` for the 51-state model at a 1 Hz filter rate, on:

* S16 Table 1 (``s16-table1``, 1.07 h, 3,861 steps),
* a 1-hour rotation-modulation path (``rotmod16`` cut to 1 h: 16 turns per 1,040 s, so more
  steps with motion than S16's),
* PSINS-style 19 positions (``psins19``, 17 min),

and, for comparison, the covariance view of ``observability()`` on S16 Table 1 (simulation +
one pass of the systematic filter), with the largest relative difference of the two bounds.

Target: one 1-hour candidate path in < 0.2 s.  A busy machine (load average
above the core count, printed) inflates the wall-clock figures; the CPU time is then the
better measure of the code.

Run: ``python bench/bench_crlb.py [--repeats N] [--no-observability]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from inscal.plan import bound as C
from inscal.core.turntable import RotationPath, psins19, rotmod16, s16_table1

TARGET_S = 0.2


def _rotmod_1h() -> RotationPath:
    p = rotmod16(3600.0)
    moves, t = [], 0.0
    for m in p.moves:
        moves.append(m)
        t = RotationPath("x", tuple(moves), accel=p.accel, closed=False).duration
        if t >= 3600.0:
            break
    return RotationPath("rotmod16-1h", tuple(moves), accel=p.accel, closed=False)


def _best(fn, repeats):
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), float(np.median(wall)), min(cpu)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--no-observability", action="store_true")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()
    setup = C.make_setup("51")
    paths = [s16_table1(), _rotmod_1h(), psins19()]
    t0 = time.perf_counter()
    C.evaluate(setup, paths[0])  # compile / load the numba cache
    t_warm = time.perf_counter() - t0
    print(f"bench_crlb: 51-state bound at 1 Hz, S16 site and noise; warm-up {t_warm:.1f} s (not timed); "
          f"{os.cpu_count()} cores, load average {load0[0]:.1f}"
          + ("  (busy machine: wall-clock times inflated)" if load0[0] > 0.75 * (os.cpu_count() or 1) else ""))
    w = 44
    print(f"  {'path':<{w}} {'steps':>6} {'best wall':>10} {'median':>8} {'best CPU':>9}   target")
    ok = True
    for p in paths:
        b = C.evaluate(setup, p)
        best, med, cpu = _best(lambda: C.evaluate(setup, p), a.repeats)
        per_h = 3600.0 / b.duration_s
        lab = f"{p.name} ({b.duration_s / 3600:.2f} h)"
        verdict = ""
        if b.duration_s >= 3000:
            hit = best * per_h < TARGET_S
            ok &= hit
            verdict = f"< {TARGET_S:g} s per hour: {'OK' if hit else 'MISSED'}"
        print(f"  {lab:<{w}} {b.steps:>6d} {best:>8.3f} s {med:>6.3f} s {cpu:>7.3f} s   {verdict}")
    if not a.no_observability:
        from inscal.plan.observability import observability

        t0 = time.perf_counter()
        o = observability("s16-table1")
        t_obs = time.perf_counter() - t0
        b = C.evaluate(setup, paths[0])
        dev = float(np.max(np.abs(b.sigma / np.sqrt(np.diag(o.covariance)) - 1)))
        print(f"  {'observability(s16-table1) covariance view':<{w}} {o.steps:>6d} {t_obs:>8.3f} s   "
              f"(simulation {o.timing_s['simulate']:.2f} s + filter {o.timing_s['filter']:.2f} s); "
              f"bound vs it: max rel. diff {dev:.1e}; speed-up x{t_obs / best:.0f}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
