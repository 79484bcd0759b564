"""The exact Allan / Haar wavelet variances of inscal.core.noise_models against the mean over many
simulated realisations (default 1000 of 4096 samples), for several parameter values and sample rates:
per process, the largest |mean - theory| in standard errors over the octave scales, and the largest
relative departure.  The estimator here is written out (no code shared with the library).

    .venv/bin/python bench/bench_noise_models.py --realisations 1000
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from inscal.core import noise_models as nm


def oavar(y, m):
    x = np.concatenate([[0.0], np.cumsum(y)])
    d = x[2 * m:] - 2 * x[m:-m] + x[: -2 * m]
    return np.mean(d**2) / (2.0 * m * m)


CASES = [
    (nm.Quantization(1e-6), 100.0), (nm.Quantization(3e-5), 1000.0),
    (nm.WhiteNoise(1e-4), 100.0), (nm.WhiteNoise(3e-6), 10.0),
    (nm.RandomWalk(1e-5), 100.0), (nm.RandomWalk(1e-7), 1.0),
    (nm.RateRamp(1e-6), 100.0),
    (nm.GaussMarkov(1e-4, 0.03), 100.0), (nm.GaussMarkov(1e-4, 5.0), 100.0), (nm.GaussMarkov(2e-6, 300.0), 10.0),
    (nm.BiasInstability(1e-5, 50.0), 100.0), (nm.BiasInstability(1e-5, 2.0), 100.0), (nm.BiasInstability(1e-6, 0.05), 1.0),
]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--realisations", type=int, default=1000)
    ap.add_argument("--n", type=int, default=4096)
    ap.add_argument("--seed", type=int, default=2026)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    ms = 2 ** np.arange(0, int(math.log2(a.n // 8)) + 1)
    print(f"{a.realisations} realisations of {a.n} samples, m = 1 .. {ms[-1]}")
    print(f"{'process':<44}{'rate Hz':>8}{'max |z|':>9}{'max |mean/theory - 1|':>24}")
    worst = 0.0
    for term, rate in CASES:
        dt = 1.0 / rate
        est = np.array([[oavar(term.simulate(a.n, dt, rng), int(m)) for m in ms] for _ in range(a.realisations)])
        th = term.avar(ms.astype(float), dt)
        mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(a.realisations)
        random = np.all(se > 1e-9 * np.abs(mean))  # a deterministic term (the ramp) has no sampling error
        z = np.abs(mean - th) / se if random else np.zeros_like(th)
        worst = max(worst, float(np.max(z)))
        print(f"{repr(term)[:44]:<44}{rate:>8g}{np.max(z):>9.2f}{np.max(np.abs(mean / th - 1)):>24.2e}")
    print(f"largest |z| over {len(CASES)} cases x {ms.size} scales: {worst:.2f} (the wavelet variance is AVAR / 2 exactly)")


if __name__ == "__main__":
    main()
