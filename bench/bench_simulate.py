"""Benchmark: simulate the full built-in ``s16`` scenario (S16 Table 1, ~1.07 h at 100 Hz,
386,100 samples, every error term and noise) in memory, after compilation."""

import time

import numpy as np

from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def main(repeats: int = 5) -> None:
    sc = scenarios.build("s16")
    simulate(sc, np.random.default_rng(0))  # compile / load the numba cache
    times = []
    for k in range(repeats):
        t0 = time.perf_counter()
        d = simulate(sc, np.random.default_rng(k))
        times.append(time.perf_counter() - t0)
    n = d.dtheta.shape[0]
    best = min(times)
    print(f"simulate s16: {n} samples ({n / sc.rate_hz / 3600:.2f} h at {sc.rate_hz:g} Hz) in {best:.3f} s "
          f"(best of {repeats}; median {np.median(times):.3f} s) = {n / best / 1e6:.2f} M samples/s; target < 0.5 s")


if __name__ == "__main__":
    main()
