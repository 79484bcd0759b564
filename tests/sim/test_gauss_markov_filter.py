"""The compiled Gauss-Markov recursion is scipy.signal.lfilter([1], [1, -phi]) to the last bit."""

import numpy as np
from scipy.signal import lfilter

from inscal.sim.kernel import gauss_markov_filter


def test_equals_lfilter_with_its_state():
    rng = np.random.default_rng(9)
    for t in range(300):
        n, k = int(rng.integers(1, 3000)), int(rng.integers(1, 4))
        phi = float(rng.choice([0.0, 0.5, 0.999, 1 - 1e-7, float(np.exp(-0.01 / 3600))]))
        x = rng.normal(size=(n, k)) * 10.0 ** rng.integers(-12, 2)
        zi = rng.normal(size=(1, k)) * (t % 3 != 0)
        want, zf = lfilter([1.0], [1.0, -phi], x, axis=0, zi=zi)
        z = zi[0].copy()
        got = gauss_markov_filter(x, phi, z)
        assert np.array_equal(got, want) and np.array_equal(z, zf[0]), (t, n, k, phi)
        # split in two chunks: the state carries the recursion on
        z2 = zi[0].copy()
        m = n // 2
        both = np.vstack([gauss_markov_filter(x[:m], phi, z2), gauss_markov_filter(x[m:], phi, z2)])
        assert np.array_equal(both, want)
