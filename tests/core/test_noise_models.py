"""The noise processes' exact Allan variances: against brute-force sums of their autocovariance,
against the integral of their spectrum through the Allan filter, and against the mean of simulated
realisations (a small Monte Carlo here; bench/bench_noise_models.py runs >= 1000 realisations)."""

import math

import numpy as np
import pytest
from scipy import integrate

from inscal.core import noise_models as nm
from inscal.core import units

DT = 0.01


def oadev2(y, m):
    """Overlapping Allan variance written out (an oracle: no code shared with inscal)."""
    x = np.concatenate([[0.0], np.cumsum(y)])
    d = x[2 * m:] - 2 * x[m:-m] + x[: -2 * m]
    return np.mean(d**2) / (2.0 * m * m)


def brute_gm(sigma, tc, m):
    """E[(S_b - S_a)^2] / (2 m^2) summed lag by lag over the AR(1) autocovariance."""
    phi = math.exp(-DT / tc)
    c = np.r_[-np.ones(m), np.ones(m)]
    w = np.correlate(c, c, "full")
    lag = np.abs(np.arange(-(2 * m - 1), 2 * m))
    return float(np.sum(w * sigma**2 * phi**lag)) / (2 * m * m)


@pytest.mark.parametrize("tc", [0.004, 0.3, 50.0])
def test_gauss_markov_exact_against_lag_sums(tc):
    g = nm.GaussMarkov(2e-4, tc)
    for m in (1, 2, 7, 64, 500):
        assert g.avar(np.array([m]), DT)[0] == pytest.approx(brute_gm(2e-4, tc, m), rel=1e-11)


def test_gauss_markov_long_correlation_is_a_random_walk():
    """For tc >> tau the AR(1) is a random walk of step variance sigma^2 (1 - phi^2) ~ 2 sigma^2 dt / tc."""
    g = nm.GaussMarkov(1e-3, 1e9)
    rw = nm.RandomWalk(1e-3 * math.sqrt(2 / 1e9))
    m = np.array([1.0, 10.0, 1e3, 1e5])
    np.testing.assert_allclose(g.avar(m, DT), rw.avar(m, DT), rtol=1e-6)


@pytest.mark.parametrize("term", [nm.Quantization(3e-6), nm.WhiteNoise(2e-5), nm.RandomWalk(4e-7),
                                  nm.GaussMarkov(1e-4, 0.8), nm.BiasInstability(1e-5, 50.0),
                                  nm.BiasInstability(1e-5, 4.0)])
def test_avar_is_the_spectrum_through_the_allan_filter(term):
    for m in (1, 3, 40):
        nu0 = getattr(term, "f0", 1e9) * DT
        pts = np.unique(np.r_[np.linspace(1e-12, 0.5, 8 * m + 2), [min(nu0, 0.5)]])
        f = lambda nu: term.spectrum(nu, DT) * nm.haar_gain(nu, m)  # noqa: E731
        ref = 2 * sum(integrate.quad(f, a, b, epsabs=0, epsrel=1e-12)[0] for a, b in zip(pts[:-1], pts[1:]))
        assert term.avar(np.array([float(m)]), DT)[0] == pytest.approx(ref, rel=1e-8)


def test_bias_instability_plateau_and_asymptotes():
    b = nm.BiasInstability(1.0, 50.0)
    assert b.avar(np.array([1e5]), DT)[0] == pytest.approx(nm.BI_PLATEAU, rel=1e-4)  # IEEE 952: 0.664^2 B^2
    assert math.sqrt(nm.BI_PLATEAU) == pytest.approx(0.6643, abs=1e-4)
    assert nm.RateRamp(2.0).avar(np.array([3.0]), DT)[0] == pytest.approx(0.5 * (2.0 * 0.03) ** 2)
    rw = nm.RandomWalk(1.0)
    assert rw.avar(np.array([1e4]), DT)[0] == pytest.approx(1e4 * DT / 3, rel=1e-6)  # K^2 tau / 3


CASES = [nm.Quantization(3e-6), nm.WhiteNoise(2e-5), nm.RandomWalk(4e-5), nm.GaussMarkov(1e-4, 0.08),
         nm.GaussMarkov(1e-4, 3.0), nm.BiasInstability(1e-4, 50.0), nm.BiasInstability(1e-4, 2.0)]


@pytest.mark.parametrize("term", CASES, ids=lambda t: type(t).__name__ + str(getattr(t, "tc", getattr(t, "f0", ""))))
def test_mean_of_realisations_equals_theory(term):
    """200 realisations of 512 samples: the mean overlapping AVAR at m = 1..32 within 4.5 standard
    errors of the exact value (the wavelet variance is half of it, one engine)."""
    rng = np.random.default_rng(7)
    ms = [1, 2, 4, 8, 16, 32]
    est = np.array([[oadev2(term.simulate(512, DT, rng), m) for m in ms] for _ in range(200)])
    mean, se = est.mean(axis=0), est.std(axis=0, ddof=1) / math.sqrt(est.shape[0])
    theory = term.avar(np.array(ms, float), DT)
    assert np.all(np.abs(mean - theory) < 4.5 * se), (mean / theory - 1, se / theory)
    np.testing.assert_allclose(nm.ChannelNoise("gx", "gyro", (term,)).wvar(np.array(ms, float), DT), theory / 2)


def test_rate_ramp_is_exact_and_sums_add():
    y = nm.RateRamp(0.3).simulate(200, DT, np.random.default_rng(0))
    for m in (1, 5, 50):
        assert oadev2(y, m) == pytest.approx(nm.RateRamp(0.3).avar(np.array([m]), DT)[0], rel=1e-9)
    ch = nm.ChannelNoise("ax", "accel", (nm.WhiteNoise(1e-4), nm.GaussMarkov(1e-5, 2.0), nm.RateRamp(1e-6)))
    m = np.array([1.0, 8.0, 100.0])
    np.testing.assert_allclose(ch.avar(m, DT), sum(t.avar(m, DT) for t in ch.terms))
    assert ch.model == "WN+DR+GM"


def test_simulation_is_reproducible_from_the_generator():
    model = nm.NoiseModel((nm.ChannelNoise("gx", "gyro", (nm.WhiteNoise(1e-5), nm.BiasInstability(1e-6, 10.0))),
                           nm.ChannelNoise("ax", "accel", (nm.GaussMarkov(1e-4, 1.0),))), 100.0)
    a = model.simulate(1000, np.random.default_rng(3))
    b = model.simulate(1000, np.random.default_rng(3))
    assert a.shape == (1000, 2) and np.array_equal(a, b)
    assert not np.array_equal(a, model.simulate(1000, np.random.default_rng(4)))


def test_parse_model():
    assert nm.parse_model("WN+RW+2GM") == ("WN", "RW", "GM", "GM")
    assert nm.parse_model("gm + Q + N") == ("QN", "WN", "GM")
    assert nm.model_string(nm.parse_model("QN+WN+DR+RW+2GM")) == "QN+WN+RW+DR+2GM"
    for bad, why in [("WN+XX", "unknown term"), ("WN+WN", "more than once"), ("5GM", "at most 4"),
                     ("WN++RW", "joined by"), ("", "joined by")]:
        with pytest.raises(ValueError, match=why):
            nm.parse_model(bad)


def test_field_units_convert():
    assert units.to_si(1.0, nm.FIELD_UNITS["gyro"]["k"], "rrw") == pytest.approx(math.radians(1) / 3600 / 60)
    assert units.to_si(1.0, nm.FIELD_UNITS["gyro"]["r"], "rate-ramp") == pytest.approx(math.radians(1) / 3600**2)
    assert units.to_si(1.0, nm.FIELD_UNITS["accel"]["k"], "arrw") == pytest.approx(9.80665e-6)
    assert units.to_si(1.0, nm.FIELD_UNITS["accel"]["r"], "accel-ramp") == pytest.approx(9.80665e-6 / 3600)
    assert units.to_si(60.0, "m/s/sqrt(h)", "vrw") == pytest.approx(1.0)
    d = nm.discrete(nm.GaussMarkov(2.0, 1.0), 0.1)
    assert d["phi"] == pytest.approx(math.exp(-0.1)) and d["innovation_std"] ** 2 == pytest.approx(4 * (1 - math.exp(-0.2)))
