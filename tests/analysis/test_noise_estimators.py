"""The one engine of the Allan and Haar wavelet variances: allantools.oadev to 1e-12, an explicit
MODWT Haar filter (oracle), any chunking, and the chi-square intervals."""

import math

import allantools
import numpy as np
import pytest

from inscal.analysis.noise.estimators import StreamingScaleVariance, log_scales, octave_scales, scale_variance
from inscal.analysis.noise.intervals import chi2_bounds, gmwm_weights, wv_interval

RATE = 200.0


def _rates(n, k=2, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(0, 1e-3, (n, k)) + np.cumsum(rng.normal(0, 1e-5, (n, k)), axis=0) + 1e-4


def test_oadev_equals_allantools_to_1e12():
    y = _rates(20_000)
    m = log_scales(y.shape[0], per_octave=4)
    sv = scale_variance(y, RATE, m)
    for c in range(2):
        taus, ad, _, _ = allantools.oadev(y[:, c], rate=RATE, data_type="freq", taus=m / RATE)
        np.testing.assert_allclose(taus, sv.taus)
        np.testing.assert_allclose(sv.adev[:, c], ad, rtol=1e-12)


def test_haar_wavelet_variance_is_half_the_allan_variance():
    """The MODWT Haar coefficients computed by an explicit filter (h = +-1/(2m), width 2m)."""
    y = _rates(3000, k=1, seed=4)[:, 0]
    sv = scale_variance(y, RATE, octave_scales(3000))
    for j, m in enumerate(sv.m.astype(int)):
        h = np.r_[np.full(m, 1.0 / (2 * m)), np.full(m, -1.0 / (2 * m))]
        w = np.convolve(y, h, mode="valid")  # the coefficients with no boundary effect
        assert w.size == sv.n_terms[j]
        assert sv.wv[j, 0] == pytest.approx(np.mean(w**2), rel=1e-10)
    np.testing.assert_allclose(sv.avar, 2 * sv.wv)
    np.testing.assert_allclose(sv.scale_index, np.arange(1, sv.m.size + 1))  # m = 2^(j-1)


@pytest.mark.parametrize("chunk, piece", [(97, 1024), (1000, 1024), (4096, 1 << 18)])
def test_any_chunking_gives_the_same_sums(chunk, piece):
    x = _rates(9_001, k=3) / RATE  # increments
    ref = scale_variance(x * RATE, RATE, log_scales(9_001))
    acc = StreamingScaleVariance(9_001, RATE, 3, log_scales(9_001), piece=piece, increments=True)
    for a in range(0, 9_001, chunk):
        acc.update(x[a:a + chunk])
    r = acc.result()
    np.testing.assert_allclose(r.wv, ref.wv, rtol=1e-9)
    assert np.array_equal(r.n_terms, ref.n_terms)


def test_intervals_cover_and_weights():
    lo, hi = chi2_bounds([1.0, 10.0, 1e4])
    assert np.all(lo < 1) and np.all(hi > 1) and hi[0] > 100 and hi[2] - lo[2] < 0.06
    # eta nu_hat / nu ~ chi2(eta): P(nu in interval) = 0.95 for a chi2 variate
    rng = np.random.default_rng(1)
    e = 7.0
    v = rng.chisquare(e, 20_000) / e
    lo, hi = chi2_bounds([e])
    assert abs(np.mean((lo * v <= 1) & (1 <= hi * v)) - 0.95) < 0.006
    sv = scale_variance(_rates(2000, k=1), RATE)
    lo, hi = wv_interval(sv)
    assert np.all(lo < sv.wv) and np.all(sv.wv < hi)
    np.testing.assert_allclose(sv.edf, np.maximum((2000 - 2 * sv.m + 1) / (2 * sv.m), 1))
    np.testing.assert_allclose(gmwm_weights(lo, hi), 1 / (hi - lo) ** 2)


def test_guards():
    with pytest.raises(ValueError, match="16"):
        StreamingScaleVariance(10, RATE)
    acc = StreamingScaleVariance(100, RATE, 1)
    with pytest.raises(ValueError, match="NaN"):
        acc.update(np.array([1.0, math.nan]))
    with pytest.raises(ValueError, match="shape"):
        acc.update(np.zeros((3, 2)))


def test_streamed_sums_match_an_extended_precision_reference_on_a_wandering_record():
    """A rate that wanders far from its first mean (a steep random walk plus a ramp) fed in small
    pieces, so that the history is shifted and re-based many times: each Allan variance equals the
    one computed in one go in extended precision (numpy.longdouble) to 1e-12."""
    rng = np.random.default_rng(9)
    n = 60_000
    y = rng.normal(0, 1e-3, (n, 2)) + np.cumsum(rng.normal(0, 1e-4, (n, 2)), axis=0) + 1e-5 * np.arange(n)[:, None]
    m = octave_scales(n)
    acc = StreamingScaleVariance(n, RATE, 2, m, piece=1024, increments=False)
    for a in range(0, n, 777):
        acc.update(y[a:a + 777])
    sv = acc.result()
    for c in range(2):
        ph = np.concatenate([[0], np.cumsum(y[:, c].astype(np.longdouble))])
        for j, mm in enumerate(m):
            d = ph[2 * mm:] - 2 * ph[mm:-mm] + ph[:-2 * mm]
            ref = float(np.sum(d * d) / (2 * mm * mm * d.size))
            assert sv.avar[j, c] == pytest.approx(ref, rel=1e-12, abs=0)  # 1e-11 without the re-basing
