"""The rates -> increments rule (:mod:`inscal.io.formats.rates`) against closed-form integrals: exact for
a rate linear in time on the grid, third order per interval on the grid and second order under jitter,
inside its stated bound; the noise covariance of the increments in closed form against a Monte Carlo
(white on the grid); and the stamp checks."""

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


def test_exact_for_a_rate_linear_in_time_on_the_grid_and_within_the_bound_off_it():
    """The midpoint rule is exact for a rate linear in time when the stamps sit at the centres of the grid's
    intervals; off the grid (stamps jittered by 30 % of a step) its error is the first-order term of the
    bound, which covers it."""
    rng = np.random.default_rng(1)
    for jitter in (0.0, 0.3):
        t = np.arange(201) * 0.01 + np.concatenate([[0.0], rng.uniform(-jitter, jitter, 200) * 0.01])
        w = np.column_stack([2.0 * t, -t + 1.0, 0.5 * t])
        ri = integrate_rates(t, w, 3.0 * w, 100.0)
        a, b = ri.time - 0.01, ri.time
        want = np.column_stack([b ** 2 - a ** 2, -(b ** 2 - a ** 2) / 2 + (b - a), (b ** 2 - a ** 2) / 4])
        err = np.abs(np.column_stack([ri.gyro - want, ri.accel - 3.0 * want])).max(axis=0)
        if jitter == 0.0:
            assert ri.on_grid and ri.noise.white
            np.testing.assert_allclose(ri.time, t + 0.005, rtol=0, atol=1e-15)  # each stamp at its interval's centre
            assert np.all(err <= 1e-15 + 1e-13 * np.abs(want).max()) and np.all(ri.bound < 1e-9)
        else:
            assert not ri.on_grid and np.all(err <= ri.bound) and np.all(err >= 0.05 * ri.bound), (err, ri.bound)


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
    # per interval the error falls as h^3 on the grid (h: 0.02 -> 0.005, a factor 64 over two halvings),
    # as h^2 under a jitter proportional to the step (the first-order term: x' h jitter)
    ratio = errs[0] / errs[2]
    want = 64 if jitter == 0.0 else 16
    assert np.all(ratio > want / 2.5) and np.all(ratio < want * 2.5), ratio


def overlaps(t, edges):
    """The oracle of the rule's weights, written from the definition: sample i held over the times nearer its
    stamp than any other's (first and last: symmetric), overlapped with each grid interval."""
    W = np.zeros((edges.size - 1, t.size))
    for i in range(t.size):
        lo = t[i] - (t[i] - t[i - 1]) / 2 if i > 0 else t[0] - (t[1] - t[0]) / 2
        hi = t[i] + (t[i + 1] - t[i]) / 2 if i < t.size - 1 else t[-1] + (t[-1] - t[-2]) / 2
        for j in range(edges.size - 1):
            W[j, i] = max(0.0, min(hi, edges[j + 1]) - max(lo, edges[j]))
    return W


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_noise_covariance_closed_form_against_monte_carlo(jitter):
    """Samples with white noise of density N (variance N^2 / h): the increments' noise covariance is
    N^2 / h W W^T (W from the oracle above), which a Monte Carlo of 6,000 draws reproduces; on the grid it
    is the white N^2 D I the estimators assume (the trapezoid rule's would have a neighbour correlation of
    1/2); the reported noise shape is the closed form's extremes."""
    rng = np.random.default_rng(4)
    h, n, dens = 0.01, 40, 0.3
    t = np.arange(n) * h + np.concatenate([[0.0], rng.uniform(-jitter, jitter, n - 1) * h])
    draws = 6000
    hbar = (t[-1] - t[0]) / (n - 1)  # the samples' mean step
    x = rng.normal(size=(draws // 6, n, 6)) * dens / np.sqrt(hbar)
    inc = []
    for k in range(x.shape[0]):
        ri = integrate_rates(t, x[k, :, :3], x[k, :, 3:], 100.0)
        inc.append(np.column_stack([ri.gyro, ri.accel]).T)
    inc = np.concatenate(inc)  # (draws, M)
    edges = np.concatenate([[ri.time[0] - h], ri.time])
    C = dens ** 2 / hbar * overlaps(t, edges) @ overlaps(t, edges).T
    emp = inc.T @ inc / draws
    scale = dens ** 2 * h
    # the Monte Carlo's standard error of a covariance element is about scale * sqrt(2 / draws)
    assert np.max(np.abs(emp - C)) < 5.0 * scale * np.sqrt(2.0 / draws), np.max(np.abs(emp - C)) / scale
    v = np.diag(C) / scale
    r1 = np.diag(C, 1) / np.sqrt(np.diag(C)[:-1] * np.diag(C)[1:])
    if jitter == 0.0:
        np.testing.assert_allclose(C, scale * np.eye(C.shape[0]), rtol=0, atol=1e-12 * scale)
        assert ri.noise.white and ri.noise.variance == (1.0, 1.0) and ri.noise.correlation == 0.0
    else:
        assert not ri.noise.white
        assert ri.noise.variance == pytest.approx((v.min(), v.max()), rel=1e-9)
        assert ri.noise.correlation == pytest.approx(r1.max(), rel=1e-9) and 0.05 < r1.max() < 0.5


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
