"""The compiled exact median equals NumPy's, value for value, on every kind of data."""

import numpy as np
import pytest

from inscal.core.robust import exact_median


def cases(rng):
    for t in range(4000):
        n = int(rng.integers(1, 60)) if t % 2 else int(rng.integers(1, 5000))
        kind = t % 5
        if kind == 0:
            x = rng.normal(size=n)
        elif kind == 1:  # many ties
            x = np.round(rng.normal(size=n) * 2)
        elif kind == 2:  # almost all equal
            x = np.full(n, 1.5)
            k = max(1, n // 10)
            x[rng.integers(0, n, size=k)] = rng.normal(size=k)
        elif kind == 3:  # sorted either way (the worst case of a naive pivot)
            x = np.sort(rng.normal(size=n))[:: 1 if t % 10 == 3 else -1].copy()
        else:  # wide range, infinities, signed zeros
            x = rng.normal(size=n) * 10.0 ** rng.integers(-300, 300, size=n)
            x[rng.integers(0, n, size=max(1, n // 50))] = rng.choice([np.inf, -np.inf, 0.0, -0.0])
        yield x


def test_median_equals_numpy():
    rng = np.random.default_rng(11)
    pair = np.empty(2)
    bad = [x.size for x in cases(rng) if exact_median(x.copy(), pair) != np.median(x)]
    assert bad == []


@pytest.mark.parametrize("x", [[np.nan], [1.0, np.nan, 2.0], [np.nan] * 40 + [1.0] * 3])
def test_nan_gives_nan(x):
    a = np.array(x)
    assert np.isnan(np.median(a)) and np.isnan(exact_median(a.copy(), np.empty(2)))


def test_a_broken_selection_would_fail():
    """The check above can fail: a median off by one rank (the lower middle for an odd count) differs."""
    x = np.arange(7.0)
    assert exact_median(x.copy(), np.empty(2)) == 3.0 != np.sort(x)[2]
