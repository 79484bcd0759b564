"""The chi-square distribution's tail probabilities and quantiles, from ``scipy.special``.

``scipy.stats.chi2`` evaluates exactly these special functions (``chdtr``, ``chdtrc``,
``2 gammaincinv(dof / 2, q)``) behind its argument handling, but importing ``scipy.stats`` costs about
0.4 s of every command's start; ``scipy.special`` is loaded anyway.  The values are the same to the
last bit, invalid arguments included (NaN for a non-positive or NaN number of degrees of freedom);
``tests/core/test_stats.py`` compares them with ``scipy.stats.chi2``.
"""

from __future__ import annotations

import math

from scipy import special


def _valid(dof) -> bool:
    return dof > 0 and math.isfinite(dof) or dof == math.inf


def _tail(x: float, dof: float, below_zero: float, function) -> float:
    """``function(dof, x)`` (``chdtr``, ``chdtrc``) with scipy.stats' handling: NaN for an invalid ``dof`` or
    a NaN ``x``, ``below_zero`` for ``x <= 0``."""
    if not _valid(dof) or x != x:
        return math.nan
    if x <= 0:
        return below_zero
    return float(function(dof, x))


def chi2_sf(x: float, dof: float) -> float:
    """P(X > x) for X ~ chi-square(dof)."""
    return _tail(x, dof, 1.0, special.chdtrc)


def chi2_cdf(x: float, dof: float) -> float:
    """P(X <= x) for X ~ chi-square(dof)."""
    return _tail(x, dof, 0.0, special.chdtr)


def chi2_ppf(q: float, dof: float) -> float:
    """The q-quantile of chi-square(dof)."""
    if not _valid(dof) or not 0.0 <= q <= 1.0:
        return math.nan
    if q == 0.0:
        return 0.0
    if q == 1.0:
        return math.inf
    return float(2 * special.gammaincinv(dof / 2, q))
