"""Short turns in a long static record: each caught and cut out by ``inscal noise``, the model fitted
on the static segments left against the clean record's (inscal.analysis.noise.identify.cut_motion).

A 10,000-s static record at 100 Hz; the z gyro holds white noise, a random walk and a Gauss-Markov
bias (a tactical FOG: N 0.01 deg/sqrt(h), K 0.05 deg/h/sqrt(h), GM 0.5 deg/h at 60 s); then the same
noise with 1, 2 and 4 turns of 90 deg about z, 9 s each (0.09-0.36 % of the record).  Per case: what
was cut (times, seconds, share), the model ``--model auto`` chooses and its parameters beside the clean
record's, and the fit of the same model on the whole window, turns included (what a silent fit would
give).

    .venv/bin/python bench/bench_noise_motion.py
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from inscal import io
from inscal.analysis.noise import identify as idf
from inscal.cli.noise import run_noise
from inscal.core import noise_models as nm
from inscal.core import units
from inscal.core.earth import Site

RATE = 100.0
DT = 1 / RATE
N = 1_000_000
TURN_S = 9.0
GZ = nm.ChannelNoise("gz", "gyro", (nm.WhiteNoise(units.to_si(0.01, "deg/sqrt(h)")),
                                    nm.RandomWalk(units.to_si(0.05, "deg/h/sqrt(h)")),
                                    nm.GaussMarkov(units.to_si(0.5, "deg/h"), 60.0)))


def record(path, turns, seed=7):
    rng = np.random.default_rng(seed)
    dth = np.column_stack([rng.normal(0, 1e-6, N), rng.normal(0, 1e-6, N), GZ.simulate(N, DT, rng)]) * DT
    dv = rng.normal(0, 1e-4, (N, 3)) * DT + np.array([0, 0, 9.8]) * DT
    starts = np.linspace(2000, 8000, turns) if turns else []
    for s in starts:
        i0, n = int(s * RATE), int(TURN_S * RATE)
        dth[i0:i0 + n, 2] += math.radians(90) / n
    io.write_record(path, io.Record(np.arange(1, N + 1) * DT, dth, dv, np.zeros((N, 2)), RATE,
                                    Site(math.radians(45), 0.0, 0.0), scenario="noise"))
    return list(starts)


def params(ch):
    return ", ".join(f"{k} {v['value']:.4g} [{v['lower_95']:.3g}, {v['upper_95']:.3g}] {v['unit']}"
                     for k, v in ch["parameters"].items())


def main():
    with tempfile.TemporaryDirectory() as tmp:
        for k in (0, 1, 2, 4):
            path = Path(tmp) / f"turns{k}.h5"
            starts = record(path, k)
            t0 = time.perf_counter()
            res = run_noise(path, "auto", "gz")
            wall = time.perf_counter() - t0
            ch = res["channels"][0]
            print(f"\n== {k} turns of {TURN_S:g} s at {[float(s) for s in starts]} s ({100 * k * TURN_S / (N * DT):.2f} % "
                  f"of {N * DT:g} s); inscal noise {wall:.1f} s")
            if "cut" in res:
                c = res["cut"]
                caught = all(any(a <= s and s + TURN_S <= b for a, b in c["spans_s"]) for s in starts)
                print(f"cut: {len(c['spans_s'])} stretches {[[round(float(a), 1), round(float(b), 1)] for a, b in c['spans_s']]}, "
                      f"{c['seconds']:.4g} s ({100 * c['share']:.3g} %), {c['static_segments']} static segments; every "
                      f"turn inside a cut: {caught}")
            else:
                print("cut: none")
            print(f"auto: {ch['model']}: {params(ch)}")
            if k:  # the same model on the whole window, turns included (no cut)
                win = io.record_window(path)
                scan = idf.scan_window(path, win)
                c = idf.CHANNELS.index("gz")
                sel = idf.identify_curve(idf.octave_curve(scan.sv, c), ch["model"], np.random.default_rng(0))
                print(f"without the cut: {params(idf.channel_summary('gz', sel, scan.sv, c))}")


if __name__ == "__main__":
    main()
