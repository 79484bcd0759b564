"""The weighted polynomial fit of one parameter over the temperature plateaus, and the covariance of a
per-plateau result in the canonical parameters (see :mod:`inscal.calibrate.thermal`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.calibrate.fit import P_INCONSISTENT
from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.systematic.params import CompParams, canonical_jacobian
from inscal.calibrate.windows import CalibrationError
from inscal.core.error_model import PARAMETERS, parameter_components
from inscal.core.stats import chi2_sf

#: a noise-free plateau estimate is exact to this fraction of its size (the tolerance every method's noise-free
#: test holds it to): a polynomial that leaves a larger residual misfits the plateaus
NOISE_FREE_REL = 1e-6


# ----------------------------------------------------------------------------- per-plateau covariance
def result_covariance(res: CalibrationResult) -> tuple[list[str], np.ndarray] | None:
    """The covariance of a result's estimates in the canonical parameter components (labels
    ``name[component]``, SI, scaled like its reported sigma), or None when the method reports none.
    The systematic filter's state covariance is mapped with the Jacobian of the canonical parameters
    (:func:`inscal.calibrate.systematic.params.canonical_jacobian`) and kept only when its diagonal
    reproduces the reported sigma."""
    cov = (res.diagnostics or {}).get("covariance")
    if isinstance(cov, dict) and "P" in cov and "labels" in cov:
        return [str(x) for x in cov["labels"]], np.asarray(cov["P"], dtype=float)
    st = res.states
    sc = res.covariance
    if st is None or not isinstance(sc, dict) or "P" not in sc or getattr(st, "gimbal", False):
        return None
    P = np.asarray(sc["P"], dtype=float)
    scale = np.sqrt(np.maximum(np.diag(P), 0.0))
    if P.ndim != 2 or not np.all(scale > 0):
        return None
    names = tuple(res.estimated)
    try:
        J = canonical_jacobian(CompParams.from_imu(res.imu), st, names, scale) / scale
    except (ValueError, KeyError, AttributeError, np.linalg.LinAlgError):
        return None
    fit_scale = float((res.fit or {}).get("scale", 1.0) or 1.0)
    S = (J @ P @ J.T) * fit_scale ** 2
    labels = [f"{n}[{c}]" if c else n for n in names for c in parameter_components(n)]
    sig = np.concatenate([np.ravel(np.asarray(res.sigma[n], dtype=float)) for n in names])
    d = np.sqrt(np.maximum(np.diag(S), 0.0))
    ok = np.isfinite(sig)
    if S.shape != (len(labels), len(labels)) or not np.allclose(d[ok], sig[ok], rtol=1e-3, atol=0.0):
        return None
    return labels, S


# ----------------------------------------------------------------------------- the polynomial fit
@dataclass
class TermFit:
    """The fit of one parameter over the plateaus: ``coef`` (order + 1, size) SI (row k: the coefficient
    of ``dT^k``; NaN rows for fixed components), ``cov`` its covariance (k-major: index ``k size + c``),
    the gain ``A[p]`` of each plateau's estimate (``coef.ravel() = sum_p A[p] y_p``), chi^2 statistics
    and the factor applied to each coefficient's formal sigma (``scale``, (order + 1, size); 1 while the
    fit is consistent)."""

    name: str
    order: int
    coef: np.ndarray
    cov: np.ndarray
    gains: list[np.ndarray]
    free: np.ndarray
    chi2: float
    dof: int
    p_value: float
    consistent: bool
    scale: np.ndarray
    chi2_components: np.ndarray
    residuals: np.ndarray  # (plateaus, size) normalised by the plateau sigma
    note: str = ""

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0)).reshape(self.order + 1, -1)

    def summary(self, unit: str) -> dict:
        d = {"order": self.order, "chi2": self.chi2, "dof": self.dof, "p_value": self.p_value,
             "consistent": self.consistent, "scale": self.scale.tolist(),
             "chi2_components": self.chi2_components.tolist(), "unit": unit}
        if self.note:
            d["note"] = self.note
        return d


def _whiten(C: np.ndarray) -> tuple[np.ndarray, bool]:
    """``W`` with ``W C W^T = I`` (via the correlation matrix's Cholesky factor); diagonal when ``C`` is
    not positive definite.  Returns ``(W, full)``."""
    d = np.sqrt(np.maximum(np.diag(C), 0.0))
    if not np.all(d > 0):
        raise CalibrationError("a plateau estimate has a zero or non-finite sigma: it cannot be weighted")
    R = C / np.outer(d, d)
    try:
        L = np.linalg.cholesky(0.5 * (R + R.T))
        return np.linalg.solve(L, np.diag(1.0 / d)), True
    except np.linalg.LinAlgError:
        return np.diag(1.0 / d), False


def fit_term(name: str, dT: np.ndarray, values: np.ndarray, covs: list[np.ndarray], order: int) -> TermFit:
    """Generalised least-squares fit of ``values`` (plateaus, size) with covariances ``covs[p]`` (size,
    size) by a polynomial of ``order`` in ``dT`` per component (see the module docstring).  Components
    whose sigma is NaN at every plateau are fixed (NaN coefficients)."""
    P, m = values.shape
    sig = np.array([np.sqrt(np.diag(C)) for C in covs])
    fixed = ~np.isfinite(sig).any(axis=0)
    mixed = ~fixed & ~np.isfinite(sig).all(axis=0)
    if np.any(mixed):
        raise CalibrationError(f"{name}: estimated on some plateaus and held fixed on others; cannot fit over temperature")
    # a noise-free record: plateau estimates with a zero sigma cannot be weighted; they are exact up to round-off,
    # so an unweighted fit (each component alike) returns the coefficients, with sigma from the residual scatter
    unweighted = bool(np.any(~fixed & np.any(~(sig > 0), axis=0)))
    if unweighted:
        covs = [np.eye(m) for _ in range(P)]
        sig = np.where(fixed[None, :], np.nan, np.ones((P, m)))
    free = np.flatnonzero(~fixed)
    mf = free.size
    K = order
    nb = (K + 1) * m
    coef = np.full((K + 1, m), np.nan)
    cov = np.full((nb, nb), np.nan)
    gains = [np.zeros((nb, m)) for _ in range(P)]
    res_n = np.full((P, m), np.nan)
    if mf == 0:
        coef[0] = np.mean(values, axis=0)
        return TermFit(name, K, coef, cov, gains, free, math.nan, 0, math.nan, True, np.ones((K + 1, m)),
                       np.full(m, np.nan), res_n)
    s = max(float(np.max(np.abs(dT))), 1.0)  # dT scaled to [-1, 1] for the conditioning
    x = dT / s
    rows, rhs, Ws = [], [], []
    for p in range(P):
        C = covs[p][np.ix_(free, free)]
        W, _ = _whiten(C)
        Xp = np.kron(x[p] ** np.arange(K + 1), np.eye(mf))  # (mf, (K+1) mf)
        rows.append(W @ Xp)
        rhs.append(W @ values[p, free])
        Ws.append(W)
    A = np.vstack(rows)
    y = np.concatenate(rhs)
    Q, R = np.linalg.qr(A)
    if np.linalg.matrix_rank(R) < R.shape[0]:
        raise CalibrationError(f"{name}: an order-{K} polynomial is not determined by the plateaus at "
                               f"{', '.join(f'{t:.3g}' for t in dT)} degC from t_ref")
    Rinv = np.linalg.inv(R)
    g = Rinv @ Q.T @ y
    cov_g = Rinv @ Rinv.T
    r = y - A @ g
    chi2 = float(r @ r)
    dof = P * mf - (K + 1) * mf
    # per-component chi2 with the marginal sigma (the Birge ratio of each component)
    fitted = np.array([np.kron(x[p] ** np.arange(K + 1), np.eye(mf)) @ g for p in range(P)])
    res_n[:, free] = (values[:, free] - fitted) / sig[:, free]
    chi2_c = np.full(m, np.nan)
    chi2_c[free] = np.sum(res_n[:, free] ** 2, axis=0)
    p_value = chi2_sf(chi2, dof) if dof > 0 and not unweighted else math.nan
    consistent = not (dof > 0 and p_value < P_INCONSISTENT)
    floor = NOISE_FREE_REL * np.max(np.abs(values[:, free]), axis=0)
    rms_c = np.sqrt(chi2_c[free] / (P - (K + 1))) if dof > 0 else np.zeros(mf)  # each component's residual rms
    if unweighted and np.any(rms_c > floor):
        consistent = False  # noise-free estimates off the polynomial by more than their round-off: the order misfits
    elif unweighted:  # the residual variance per component takes the place of the plateau sigma
        cov_g = cov_g * (chi2 / dof if dof > 0 else 0.0)
    # back to unscaled dT: coefficient k divided by s^k (full index k*m + c); the gains per plateau:
    # coef_free = D R^-1 Q^T blockdiag(W_p) y, the rows of Q^T taken plateau by plateau
    unscale = np.repeat(s ** -np.arange(K + 1, dtype=float), mf)
    cov_g = cov_g * np.outer(unscale, unscale)
    g = g * unscale
    full_idx = np.array([k * m + c for k in range(K + 1) for c in free])
    G = (Rinv @ Q.T) * unscale[:, None]
    blocks = [G[:, p * mf:(p + 1) * mf] @ Ws[p] for p in range(P)]
    factor = np.ones(full_idx.size)
    s_c = np.ones(m)
    note = ""
    if unweighted and consistent:
        note = (f"{name}: the plateau estimates have a zero sigma (a noise-free record): unweighted least squares, "
                f"sigma from the residual scatter ({'none' if dof == 0 else f'rms {math.sqrt(chi2 / dof):.3g} SI'}), "
                "no chi2 test")
    elif dof == 0:
        note = f"{name}: order {K} through {P} plateaus leaves no degree of freedom: the fit cannot be tested"
    elif not consistent:
        # the misfit treated as systematic (calibrate.fit.SIGMA_RULE): the largest error a misfit of the
        # observed size, of either sign on every plateau, can cause, with each component's Birge ratio
        s_c[free] = rms_c if unweighted else np.maximum(1.0, np.sqrt(chi2_c[free] / (P - (K + 1))))
        syst = sum(np.abs(blocks[p]) @ (s_c[free] * sig[p, free]) for p in range(P))
        formal = np.sqrt(np.maximum(np.diag(cov_g), 0.0))
        factor = np.maximum(syst / formal, np.tile(s_c[free], K + 1))
        cov_g = cov_g * np.outer(factor, factor)
        comps = parameter_components(name) if name in PARAMETERS else [str(c) for c in range(m)]
        what = f"the order-{K} fit" if K else "the weighted mean"
        why = ("a higher order, a plateau not settled or hysteresis would explain it" if K else
               "it changes with temperature more than its sigma allow (a thermal term: give it an order)")
        if unweighted:  # sigma_plateau = 1 above: s_c is each component's residual rms
            stat = ("noise-free plateau estimates (zero sigma) off the polynomial by rms "
                    + ", ".join(f"{comps[c] or name} {s_c[c]:.3g}" for c in free)
                    + f" SI, above their round-off ({NOISE_FREE_REL:g} of their size)")
            rule = "the residual rms"
            size = ""
        else:
            stat = (f"chi2 {chi2:.4g} on {dof} dof, p = {p_value:.2g}; sqrt(chi2/dof) "
                    + ", ".join(f"{comps[c] or name} {s_c[c]:.3g}" for c in free))
            rule = "sqrt(chi2/dof) sigma_plateau"
            size = f", {np.min(factor):.3g} .. {np.max(factor):.3g} x the formal sigma"
        note = (f"{name}: {what} over {P} plateaus is inconsistent ({stat}): the misfit is treated as systematic, "
                f"sigma = sum over plateaus of |d estimate / d plateau value| {rule}{size}; {why}")
    coef[:, free] = g.reshape(K + 1, mf)
    for c in np.flatnonzero(fixed):
        coef[0, c] = float(np.mean(values[:, c]))
        coef[1:, c] = 0.0
    cov[np.ix_(full_idx, full_idx)] = cov_g
    scale = np.ones(nb)
    scale[full_idx] = factor
    for p in range(P):
        gains[p][np.ix_(full_idx, free)] = blocks[p]
    return TermFit(name, K, coef, cov, gains, free, chi2, dof, p_value, consistent, scale.reshape(K + 1, m), chi2_c,
                   res_n, note)
