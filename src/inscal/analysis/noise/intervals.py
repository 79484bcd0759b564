"""Confidence intervals of the Allan and Haar wavelet variances from their equivalent degrees of
freedom: ``eta nu_hat / nu ~ chi^2(eta)`` (Percival & Walden 2000 eq. 313c), so the 1 - alpha interval
is ``[eta nu_hat / chi2_{1-alpha/2}(eta), eta nu_hat / chi2_{alpha/2}(eta)]`` with eta = eta3
(:attr:`inscal.analysis.noise.estimators.ScaleVariance.edf`), GMWM's default.  The GMWM weights
are ``Omega = diag(1 / (upper - lower)^2)`` of the 95 % intervals of the wavelet variance
(Guerrier et al. 2013, the ``wvar`` intervals of the R package simts)."""

from __future__ import annotations

import numpy as np

from inscal.analysis.noise.estimators import ScaleVariance
from inscal.core.stats import chi2_ppf


def chi2_bounds(edf, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Factors ``(lo, hi)`` such that ``[lo v, hi v]`` is the ``level`` interval of a variance v of ``edf``."""
    a = 1.0 - level
    edf = np.atleast_1d(np.asarray(edf, dtype=float))
    lo = np.array([e / chi2_ppf(1 - a / 2, e) for e in edf])
    hi = np.array([e / chi2_ppf(a / 2, e) for e in edf])
    return lo, hi


def wv_interval(sv: ScaleVariance, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` of the wavelet variance, shaped like ``sv.wv``; twice them for the Allan variance."""
    lo, hi = chi2_bounds(sv.edf, level)
    return lo[:, None] * sv.wv, hi[:, None] * sv.wv


def gmwm_weights(lower, upper) -> np.ndarray:
    """GMWM's default weights: 1 / (upper - lower)^2 of the 95 % interval of each wavelet variance."""
    w = np.asarray(upper, dtype=float) - np.asarray(lower, dtype=float)
    return 1.0 / np.maximum(w, np.finfo(float).tiny) ** 2
