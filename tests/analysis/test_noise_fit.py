"""The GMWM-type fit: exact curves give back their parameters (the multi-start reaches the global
optimum), the covariance V of the wavelet variances against a small Monte Carlo, the intervals on
one simulated record, the choice among sub-sums, the read-offs on exact curves, the bootstrap."""

import math

import numpy as np
import pytest

from inscal.analysis.noise.estimators import octave_scales, scale_variance
from inscal.analysis.noise.fit import Curve, bootstrap, curve_covariance, fit_curve, wv_covariance
from inscal.analysis.noise import projection
from inscal.analysis.noise.intervals import chi2_bounds, gmwm_weights
from inscal.analysis.noise.selection import nested_check, own_yardstick, penalty, readoffs, record_samples, select, sub_models, tc_limit
from inscal.core import noise_models as nm

DT = 0.01


def exact_curve(ch, n=1 << 18):
    """The channel's exact wavelet variance at the octave scales, with eta3 intervals around it."""
    m = octave_scales(n).astype(float)
    wv = ch.wvar(m, DT)
    M = n - 2 * m + 1
    lo, hi = chi2_bounds(np.maximum(M / (2 * m), 1))
    return Curve(m, DT, wv, lo * wv, hi * wv, M)


@pytest.mark.parametrize("terms", [
    (nm.WhiteNoise(1e-4), nm.GaussMarkov(3e-5, 5.0)),
    (nm.Quantization(2e-6), nm.WhiteNoise(1e-4), nm.RandomWalk(3e-6), nm.GaussMarkov(2e-5, 0.5),
     nm.GaussMarkov(2e-5, 20.0)),
    (nm.WhiteNoise(1e-4), nm.BiasInstability(1e-5, 50.0), nm.RateRamp(2e-6)),
])
def test_exact_curve_gives_back_the_parameters(terms):
    ch = nm.ChannelNoise("g", "gyro", terms)
    f = fit_curve(exact_curve(ch), ch.model, n_starts=4, rng=np.random.default_rng(0))
    truth = np.array([getattr(t, p) for t in ch.terms for p in t.params])
    np.testing.assert_allclose(f.values, truth, rtol=2e-4)
    assert f.objective < 1e-10 and f.gof < 1e-6 and not any(f.negligible)


def test_wavelet_variance_covariance_against_monte_carlo():
    """V's diagonal and one neighbour correlation against 300 records of 4096 samples."""
    ch = nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-3), nm.GaussMarkov(1e-3, 0.3), nm.RandomWalk(1e-4)))
    rng = np.random.default_rng(11)
    n = 4096
    m = octave_scales(n)
    est = np.array([scale_variance(ch.simulate(n, DT, rng), 1 / DT, m).wv[:, 0] for _ in range(300)])
    V = wv_covariance(lambda f: ch.spectrum(f, DT), m, n - 2 * m + 1)
    emp = np.cov(est.T)
    ratio = np.diag(emp) / np.diag(V)
    assert np.all(np.abs(ratio[:6] - 1) < 0.3), ratio  # the scales with many terms
    corr_emp = emp[2, 3] / math.sqrt(emp[2, 2] * emp[3, 3])
    corr_v = V[2, 3] / math.sqrt(V[2, 2] * V[3, 3])
    assert abs(corr_emp - corr_v) < 0.15, (corr_emp, corr_v)


def test_intervals_cover_on_a_record_and_bootstrap():
    ch = nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-4), nm.GaussMarkov(4e-5, 3.0)))
    y = ch.simulate(1 << 16, DT, np.random.default_rng(5))
    f = fit_curve(Curve.from_scale_variance(scale_variance(y, 1 / DT)), "WN+GM", rng=np.random.default_rng(1))
    truth = [1e-4, 4e-5, 3.0]
    assert np.all((f.lower < truth) & (np.array(truth) < f.upper)), (f.lower, f.upper)
    assert f.gof_dof == f.curve.m.size - 3 and 0 < f.gof_p <= 1
    lo, hi, draws = bootstrap(f, 1 << 13, 4, np.random.default_rng(2))
    assert draws.shape == (4, 3) and np.all(lo <= hi)


def test_selection_finds_a_clear_model_and_says_why():
    """WN+RW is chosen over every sub-sum of WN+RW+GM; a GM may not stand in for the random walk
    (its correlation time is held within tau_max / 8, where it imitates one poorly)."""
    ch = nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-4), nm.RandomWalk(2e-5)))
    curve = exact_curve(ch, 1 << 16)
    s = select(curve, "WN+RW+GM", rng=np.random.default_rng(0))
    assert s.chosen.model == "WN+RW" and s.criterion == "hqic"
    assert s.reason.startswith("WN+RW: lowest HQIC") and "runner-up" in s.reason and "gap" in s.reason
    rows = {r[0]: r for r in s.candidates}
    assert rows["WN+RW"][2] < 1e-6 and rows["WN+GM"][2] > 5  # J of the truth, of the GM in RW's place
    assert rows["WN+GM"][1] - rows["WN+RW"][1] > 10  # and a parameter more
    assert rows["WN+RW+GM"][5]  # the GM is not seen beside the random walk: set aside, with its reason
    assert len(sub_models(nm.parse_model("QN+WN+2GM"))) == 11


def test_projection_solves_the_amplitudes_and_marks_an_absent_term():
    """On an exact WN+GM curve the grid's best point for WN+RW+GM has RW's amplitude exactly zero and
    the others near the truth (the polish then lands on them: test_exact_curve_gives_back_the_parameters)."""
    ch = nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-4), nm.GaussMarkov(3e-5, 5.0)))
    c = exact_curve(ch, 1 << 16)
    th, obj, zero = projection.profile(("WN", "RW", "GM"), c.m, DT, c.wv, np.sqrt(gmwm_weights(c.lower, c.upper)))
    assert zero == (False, True, False)
    assert math.exp(th[0]) == pytest.approx(1e-4, rel=0.02) and math.exp(th[2]) == pytest.approx(3e-5, rel=0.1)
    assert 5.0 / 1.3 < math.exp(th[3]) < 5.0 * 1.3  # on the grid (3 per octave)


def test_readoffs_on_exact_curves():
    """Each read-off equals its term where that term alone makes the curve (IEEE 952 Annex C)."""
    tau = np.logspace(-2, 4, 200)
    m = tau / DT
    for term, code, attr in [(nm.WhiteNoise(2e-4), "WN", "n"), (nm.RandomWalk(3e-6), "RW", "k"),
                             (nm.RateRamp(1e-7), "DR", "r")]:
        ro = readoffs(tau, np.sqrt(term.avar(m, DT)))
        assert ro[code]["value"] == pytest.approx(getattr(term, attr), rel=1e-3)
    q = nm.Quantization(1e-6)
    assert readoffs(tau, np.sqrt(q.avar(m, DT)))["QN"]["value"] == pytest.approx(1e-6, rel=1e-9)
    b = nm.BiasInstability(1e-5, 50.0)
    assert readoffs(tau, np.sqrt(b.avar(m, DT) + nm.WhiteNoise(1e-9).avar(m, DT)))["BI"]["value"] == pytest.approx(1e-5, rel=2e-2)


def test_a_ramp_adds_its_cross_term_to_the_covariance():
    """Beside noise, a rate ramp multiplies the variance of the wavelet variances where it dominates
    (its constant coefficients shift the noise's): V with the cross term against 300 records."""
    n = 1 << 13
    ch = nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-3), nm.RandomWalk(2e-4), nm.RateRamp(3e-4)))
    rng = np.random.default_rng(3)
    m = octave_scales(n)
    est = np.array([scale_variance(ch.simulate(n, DT, rng), 1 / DT, m).wv[:, 0] for _ in range(300)])
    M = (n - 2 * m + 1).astype(float)
    V = curve_covariance(ch.terms, Curve(m.astype(float), DT, est.mean(0), est.mean(0), est.mean(0), M))
    V0 = wv_covariance(lambda f: sum(t.spectrum(f, DT) for t in ch.terms[:2]), m, M)
    emp = np.var(est, axis=0, ddof=1)
    assert np.all(np.abs(emp / np.diag(V) - 1) < 0.3), emp / np.diag(V)
    assert emp[-1] / V0[-1, -1] > 4  # the noise alone misses most of it


def test_a_non_white_start_is_kept_as_a_short_gauss_markov_term():
    """A low-pass filtered white noise (an AR(1) of T_c = 0.4 dt, phi = 0.08: tau nu rises 17 % over the
    first octaves) beside a slower GM: the simple family (T_c from 2 dt) fails its J test, the extended
    one finds the short term (T_c below dt, as GMWM's phi down to ~0) and the structure."""
    ch = nm.ChannelNoise("g", "gyro", (nm.GaussMarkov(1e-3, 0.4 * DT), nm.GaussMarkov(2e-4, 1.0)))
    s = select(exact_curve(ch, 1 << 16), rng=np.random.default_rng(0))
    assert s.chosen.model == "2GM" and "extended family tried" in s.reason
    tcs = sorted(t.tc for t in s.chosen.terms)
    assert tcs[0] == pytest.approx(0.4 * DT, rel=1e-3) and tcs[1] == pytest.approx(1.0, rel=1e-3)
    assert not any(r[5].startswith("GM of T_c") for r in s.candidates)  # no set-aside for the bound any more
    for m, gap, _, _ in s.richer:  # what fits nearly as well contains the choice
        assert "GM" in m and 0 <= gap


def test_nested_pairs_drop_a_spurious_ramp_and_keep_the_true_terms():
    """Each nested pair on the larger one's own yardstick (Newey-West's D): a ramp beside the truth's
    random walk adds nothing to the exact curve (D ~ 0: dropped, the truth's values back), while every
    true term's D is its noncentrality, far above the penalty (kept)."""
    truth = (nm.WhiteNoise(1e-4), nm.RandomWalk(1e-4), nm.GaussMarkov(3e-4, 1.0))
    c = exact_curve(nm.ChannelNoise("g", "gyro", truth), 1 << 16)
    pen, tcr = penalty("hqic", record_samples(c)), (tc_limit(c), None)
    th = np.log([1e-4, 1e-4, 1e-6, 3e-4, 1.0])  # WN+RW+DR+GM, a small spurious ramp
    codes, th2, tested = nested_check(c, ("WN", "RW", "DR", "GM"), th, pen, tcr, np.random.default_rng(0))
    assert codes == ("WN", "RW", "GM") and [t[2] for t in tested] == ["DR"] and tested[0][3] < pen
    assert np.exp(th2) == pytest.approx([1e-4, 1e-4, 3e-4, 1.0], rel=1e-3)
    codes, _, tested = nested_check(c, ("WN", "RW", "GM"), np.log([1e-4, 1e-4, 3e-4, 1.0]), pen, tcr,
                                    np.random.default_rng(0))
    assert codes == ("WN", "RW", "GM") and tested == []


def test_a_choice_failing_its_own_j_test_gives_way_on_each_ones_own_yardstick():
    """Andrews & Lu's criterion with each candidate's own V: a choice that misses the random walk
    (J far above its penalty) gives way to a larger candidate of the table, which its own nested check
    brings down to the truth (the spurious ramp dropped; values back)."""
    truth = (nm.WhiteNoise(1e-4), nm.RandomWalk(1e-4), nm.GaussMarkov(3e-4, 1.0))
    c = exact_curve(nm.ChannelNoise("g", "gyro", truth), 1 << 16)
    pen, tcr = penalty("hqic", record_samples(c)), (tc_limit(c), None)
    wrong = (("WN", "GM"), np.log([1e-4, 3e-4, 1.0]))
    start = (("WN", "RW", "DR", "GM"), np.log([1e-4, 1e-4, 1e-6, 3e-4, 1.0]))
    codes, th, scores = own_yardstick(c, [start], wrong, pen, tcr, np.random.default_rng(0))
    assert codes == ("WN", "RW", "GM") and np.exp(th) == pytest.approx([1e-4, 1e-4, 3e-4, 1.0], rel=1e-3)
    assert scores["WN+GM"] > scores["WN+RW+GM"] + 10 * pen


def test_fit_counts_its_starts_and_flags_unresolved_intervals():
    """``starts`` counts every start solve ran (the grid's too), so ``starts_at_best`` never exceeds it;
    a term the curve does not show has an interval down to 0: flagged unresolved in the summary."""
    from inscal.analysis.noise.estimators import ScaleVariance
    from inscal.analysis.noise.identify import channel_summary, identify_curve

    c = exact_curve(nm.ChannelNoise("g", "gyro", (nm.WhiteNoise(1e-4), nm.GaussMarkov(3e-5, 5.0))), 1 << 14)
    sel = identify_curve(c, "WN+RW+GM", np.random.default_rng(0), n_starts=3)
    assert sel.chosen.starts == 5 and 1 <= sel.chosen.hits <= sel.chosen.starts
    sv = ScaleVariance(c.m, c.dt, 1 << 14, c.wv[:, None], c.n_terms)
    summ = channel_summary("gx", sel, sv, 0)
    assert "RW.k" in summ["unresolved"]["parameters"] and summ["parameters"]["RW.k"]["unresolved"]
    assert "WN.n" not in summ["unresolved"]["parameters"]
    assert summ["ieee_readoffs"]["BI"]["edf"] > 1 and summ["starts"] == 5
    with pytest.raises(ValueError, match="has no term"):
        nm.parse_model("WN+0GM")
