"""The chi-square functions of inscal.core.stats equal scipy.stats.chi2's to the last bit."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

from inscal.core.stats import chi2_cdf, chi2_ppf, chi2_sf

DOFS = [0.5, 1, 2, 3, 5.5, 7, 20, 51, 100, 1234, 1e5, 2.5e6]


@pytest.mark.parametrize("dof", DOFS)
def test_tails_equal_scipy(dof):
    xs = [0.0, -1.0, 1e-300, 1e-8, 0.3, 1.0, dof / 3, dof, dof * 1.7, 3 * dof + 40, 1e6, math.inf, math.nan]
    for x in xs:
        for mine, ref in ((chi2_sf(x, dof), chi2.sf(x, dof)), (chi2_cdf(x, dof), chi2.cdf(x, dof))):
            assert np.array_equal(np.float64(mine), np.float64(ref), equal_nan=True), (x, dof, mine, ref)


@pytest.mark.parametrize("dof", DOFS)
def test_quantiles_equal_scipy(dof):
    for q in [0.0, 1e-12, 0.001, 0.025, 0.05, 0.5, 0.95, 0.975, 0.999, 1 - 1e-12, 1.0, -0.1, 1.1, math.nan]:
        mine, ref = chi2_ppf(q, dof), chi2.ppf(q, dof)
        assert np.array_equal(np.float64(mine), np.float64(ref), equal_nan=True), (q, dof, mine, ref)


@pytest.mark.parametrize("dof", [0, -1, math.nan])
def test_invalid_degrees_of_freedom_give_nan(dof):
    for f, g in ((chi2_sf, chi2.sf), (chi2_cdf, chi2.cdf)):
        assert math.isnan(f(3.0, dof)) and math.isnan(g(3.0, dof))
    assert math.isnan(chi2_ppf(0.5, dof)) and math.isnan(chi2.ppf(0.5, dof))
