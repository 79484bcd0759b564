"""The compiled parts of window detection give exactly what the NumPy expressions they replace give, so a
calibration (and a Monte Carlo study for the same seeds) is unchanged to the last bit."""

import numpy as np

from inscal.calibrate.windows import _second_difference_mad, all_columns, unwrap_angles


def mad_sigma(d):
    """The NumPy expression the compiled kernel replaces."""
    return 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)


def test_second_difference_mad_equals_numpy():
    rng = np.random.default_rng(5)
    for t in range(1500):
        n = int(rng.integers(3, 3000))
        dt = float(rng.choice([0.01, 0.005, 1 / 128, 1 / 400, 1.0]))
        x = rng.normal(size=(n, 3)) * rng.choice([1e-6, 1e-3, 1.0]) + rng.choice([0.0, 1e-2])
        if t % 5 == 0:
            x = np.round(x * 1e3) / 1e3  # ties
        if t % 7 == 0:
            x = x.astype(np.float32).astype(float)  # a float32 record
        want = mad_sigma(np.diff(x / dt, n=2, axis=0))
        assert np.array_equal(_second_difference_mad(x, dt), want), (t, n, dt)


def test_unwrap_equals_numpy_signed_zeros_and_nan_included():
    rng = np.random.default_rng(6)
    for t in range(1500):
        n, k = int(rng.integers(1, 500)), int(rng.integers(1, 3))
        p = np.cumsum(rng.normal(size=(n, k)) * rng.choice([0.01, 0.5, 1.0, 3.0]), axis=0)
        if t % 3 == 0:
            p = np.mod(p + np.pi, 2 * np.pi) - np.pi  # wrapped: the general path
        if t % 11 == 0:
            p[rng.integers(0, n)] = np.nan
        if t % 13 == 0:
            p[rng.integers(0, n)] = -0.0
        want, got = np.unwrap(p, axis=0), unwrap_angles(p)
        assert np.array_equal(got, want, equal_nan=True) and np.array_equal(np.signbit(got), np.signbit(want)), t


def test_all_columns_equals_numpy():
    rng = np.random.default_rng(7)
    for k in (1, 2, 3):
        m = rng.random((1000, k)) < 0.8
        assert np.array_equal(all_columns(m), np.all(m, axis=1))
