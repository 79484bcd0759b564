"""The rates -> increments rule (:mod:`inscal.io.formats.rates`) against closed-form integrals: exact for
a rate linear in time, third order per interval (second order overall) on and off the grid, inside
its stated bound; and the stamp checks."""

from __future__ import annotations

import numpy as np
import pytest

from inscal.io.formats.rates import check_stamps, integrate_rates
from inscal.io.mapping import ImportFileError

OM, PH = np.array([3.0, 5.0, 7.0, 2.0, 4.0, 6.0]), np.array([0.1, 0.7, -0.4, 1.1, 0.3, -0.9])


def signal(t):
    x = np.sin(OM * np.asarray(t)[:, None] + PH)
    return x[:, :3], x[:, 3:]


def exact(a, b):
    v = (np.cos(OM * np.asarray(a)[:, None] + PH) - np.cos(OM * np.asarray(b)[:, None] + PH)) / OM
    return v[:, :3], v[:, 3:]


def worst(ri):
    g, a = exact(ri.time - 1.0 / ri.rate_hz, ri.time)
    return np.abs(np.column_stack([ri.gyro - g, ri.accel - a])).max(axis=0)


def test_exact_for_a_rate_linear_in_time_on_a_jittered_grid():
    rng = np.random.default_rng(1)
    t = np.arange(201) * 0.01 + np.concatenate([[0.0], rng.uniform(-0.003, 0.003, 200)])
    w = np.column_stack([2.0 * t, -t + 1.0, 0.5 * t])
    ri = integrate_rates(t, w, 3.0 * w, 100.0)
    a, b = ri.time - 0.01, ri.time
    want = np.column_stack([b ** 2 - a ** 2, -(b ** 2 - a ** 2) / 2 + (b - a), (b ** 2 - a ** 2) / 4])
    np.testing.assert_allclose(ri.gyro, want, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(ri.accel, 3.0 * want, rtol=1e-13, atol=3e-15)
    assert np.all(ri.bound < 1e-9)  # no curvature, no error


@pytest.mark.parametrize("jitter", [0.0, 0.2])
def test_second_order_within_the_bound(jitter):
    rng = np.random.default_rng(2)
    errs = []
    for h in (0.02, 0.01, 0.005):
        n = int(round(4.0 / h))
        t = np.arange(n + 1) * h
        t[1:] += jitter * h * rng.uniform(-1, 1, n)
        ri = integrate_rates(t, *signal(t), 1.0 / h)
        assert ri.on_grid == (jitter == 0.0)
        e = worst(ri)
        assert np.all(e <= ri.bound), (e, ri.bound)
        assert np.all(e >= (0.5 if jitter == 0.0 else 0.05) * ri.bound), (e, ri.bound)  # and not loose
        errs.append(e)
    # per interval the error falls as h^3 (h: 0.02 -> 0.005, a factor 64 over two halvings)
    ratio = errs[0] / errs[2]
    assert np.all(ratio > 64 / 2.5) and np.all(ratio < 64 * 2.5), ratio


@pytest.mark.parametrize("t, needle", [
    ([0.0, 0.01, 0.02, 0.015, 0.03], "stamps go backwards at message 4"),
    ([0.0, 0.01, 0.02, 0.02, 0.03], "duplicated stamp at message 4"),
    ([0.0, 0.01, 0.02, 0.03, 0.06, 0.07], "2 message(s) dropped before message 5"),
    ([0.0, 0.01, float("nan"), 0.03], "the stamp of message 3 is nan"),
    ([0.0, 0.01], "2 message(s); at least 3 are needed"),
])
def test_stamp_checks_name_the_message(t, needle):
    with pytest.raises(ImportFileError, match=None) as exc:
        check_stamps(np.array(t), "bag", "message")
    assert needle in str(exc.value)


def test_a_grid_rate_far_from_the_stamps_is_refused():
    t = np.arange(101) * 0.01
    w, f = signal(t)
    assert integrate_rates(t, w, f, 100.05).rate_hz == 100.05  # a clock 500 ppm off: accepted
    with pytest.raises(ImportFileError, match="--rate-hz 200 is inconsistent with the stamps: 100 Hz on average"):
        integrate_rates(t, w, f, 200.0)
