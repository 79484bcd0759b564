"""GMWM-type fit of a sum of noise processes to one channel's Haar wavelet variance.

The generalized method of wavelet moments (Guerrier, Skaloud, Stebler, Victoria-Feser, JASA 108
(2013) 1021-1030) estimates the parameters ``theta`` of a sum of processes by weighted least
squares on the wavelet variance at the octave scales::

    theta_hat = argmin (nu_hat - nu(theta))' Omega (nu_hat - nu(theta))        (Guerrier 2013 eq. 5)

with ``nu(theta)`` the exact discrete-time wavelet variances of :mod:`inscal.core.noise_models`.
Here ``theta`` are the logarithms of the positive parameters (q, n, b, k, ``abs(r)``, each GM's sigma and
tc: no bounds to keep inside, and intervals that stay positive); the default
``Omega = diag(1 / (upper - lower)^2)`` of the 95 % eta3 intervals (GMWM's default, so objective
values compare across tools).  The solver is multi-start: the best point of a grid of GM correlation
times with the amplitudes solved exactly there (variable projection, :mod:`.projection`: the global
optimum up to the grid's spacing), a start from the IEEE read-offs, then ``n_starts`` starts drawn
around it from a seeded generator, each polished by ``scipy.optimize.least_squares``
(trust-region reflective); the best objective wins.

Uncertainty (Guerrier 2013 Proposition 2, the GMM sandwich)::

    cov(theta_hat) = (D' Omega D)^-1 D' Omega V Omega D (D' Omega D)^-1,   D = d nu / d theta

where ``V = cov(nu_hat)`` at the fitted model, from the spectrum S of the channel
(Percival & Walden 2000 eq. 313a, extended across scales)::

    V_jk = 2 / max(M_j, M_k) int_{-1/2}^{1/2} |H_j(f)|^2 |H_k(f)|^2 S(f)^2 df,
    |H_j(f)|^2 = sin^4(pi f m_j) / (m_j^2 sin^2(pi f))  (the Haar MODWT filter of width 2 m_j).

The integral runs on a logarithmic frequency grid; where a filter's oscillation is finer than the
grid (f > 32 / m) its sin^4 is replaced by its mean 3/8 (a documented approximation, below 1 % on
V).  A deterministic ramp adds no variance of its own but a cross term with the noise
(its coefficients shift the noise's: :func:`ramp_covariance`).  95 % intervals are exp(theta_hat +- 1.96 se).  The
goodness of fit is ``T = r' V^-1 r`` (r the residual), about chi^2(J - p) for a right model
(Hansen's J statistic; approximate with a non-optimal Omega).  A parametric bootstrap
(:func:`bootstrap`) gives percentile intervals on request.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from inscal.analysis.noise.estimators import ScaleVariance, octave_scales, scale_variance
from inscal.analysis.noise import projection
from inscal.analysis.noise.intervals import gmwm_weights, wv_interval
from inscal.core import noise_models as nm
from inscal.core.stats import chi2_sf

#: z of a two-sided 95 % interval
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Curve:
    """One channel's wavelet variance at octave factors ``m`` (sample interval ``dt``), its 95 %
    interval and the number of terms behind each value (what a fit needs, from a record or a CSV)."""

    m: np.ndarray
    dt: float
    wv: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    n_terms: np.ndarray

    @classmethod
    def from_scale_variance(cls, sv: ScaleVariance, channel: int = 0) -> "Curve":
        """The curve of channel ``channel`` of ``sv``, with the 95 % chi-square interval of its wavelet
        variances (:func:`inscal.analysis.noise.intervals.wv_interval`)."""
        lo, hi = wv_interval(sv)
        return cls(sv.m, sv.dt, sv.wv[:, channel], lo[:, channel], hi[:, channel], sv.n_terms)


def term_from_theta(code: str, th, dt: float):
    """A process of the family ``code`` from its log-parameters (the BI cut-off at Nyquist)."""
    e = np.exp(th)
    return {"QN": lambda: nm.Quantization(e[0]), "WN": lambda: nm.WhiteNoise(e[0]),
            "BI": lambda: nm.BiasInstability(e[0], 0.5 / dt), "RW": lambda: nm.RandomWalk(e[0]),
            "DR": lambda: nm.RateRamp(e[0]), "GM": lambda: nm.GaussMarkov(e[0], e[1])}[code]()


def n_params(code: str) -> int:
    """The number of parameters of the term ``code``: 2 for a Gauss-Markov term (sigma, tc), 1 otherwise."""
    return 2 if code == "GM" else 1


def param_names(codes) -> list[str]:
    """The parameter labels of the terms ``codes`` in order, e.g. ``WN.n``, ``RW.k``, ``GM1.sigma``, ``GM1.tc``."""
    out, g = [], 0
    for c in codes:
        if c == "GM":
            g += 1
            out += [f"GM{g}.sigma", f"GM{g}.tc"]
        else:
            out.append(f"{c}.{ {'QN': 'q', 'WN': 'n', 'BI': 'b', 'RW': 'k', 'DR': 'r'}[c]}")
    return out


def terms_of(codes, theta, dt: float) -> tuple:
    """The processes of the terms ``codes`` from the stacked log-parameters ``theta`` (sample
    interval ``dt`` [s]), in order."""
    out, i = [], 0
    for c in codes:
        p = n_params(c)
        out.append(term_from_theta(c, theta[i:i + p], dt))
        i += p
    return tuple(out)


def model_wv(codes, theta, m, dt: float) -> np.ndarray:
    """nu(theta): the sum of the terms' exact wavelet variances (AVAR / 2)."""
    return 0.5 * sum(t.avar(m, dt) for t in terms_of(codes, theta, dt))


def contributions(terms, m, dt: float) -> np.ndarray:
    """(J, terms) wavelet variance of each term."""
    return np.stack([0.5 * t.avar(m, dt) for t in terms], axis=1)


def wv_covariance(spectrum, m, n_terms, n_grid_per_decade: int = 1500) -> np.ndarray:
    """V = cov(nu_hat) of the wavelet variances at factors ``m`` for a channel of spectrum
    ``spectrum(f)`` (per sample, f in cycles/sample) (module docstring)."""
    m = np.asarray(m, dtype=float)
    f_lo = 1e-4 / (2 * m.max())
    nu = np.logspace(math.log10(f_lo), math.log10(0.5), int(n_grid_per_decade * math.log10(0.5 / f_lo)) + 1)
    s = np.sin(np.pi * nu)
    h = np.empty((m.size, nu.size))
    for j, mm in enumerate(m):
        osc = np.sin(np.pi * nu * mm) ** 4
        h[j] = np.where(nu * mm > 32, 0.375, osc) / (mm**2 * s**2)
    w = np.gradient(np.log(nu)) * nu * spectrum(nu) ** 2  # df = f dln f
    integ = 2.0 * (h * w) @ h.T  # both halves of [-1/2, 1/2]
    mx = np.maximum.outer(np.asarray(n_terms, float), np.asarray(n_terms, float))
    return 2.0 * integ / mx


def ramp_covariance(spectrum, ramp_wv, m, n_terms, n_grid_per_decade: int = 1500) -> np.ndarray:
    """The part of cov(nu_hat) a deterministic rate ramp adds beside noise of spectrum ``spectrum(f)``.

    A ramp's Haar coefficient is the same constant ``c_j = sqrt(nu_DR,j)`` at every time, so
    ``mean W^2 = c^2 + 2 c mean(w) + mean(w^2)`` (w the noise's coefficients) and
    ``cov(nu_hat_j, nu_hat_k) += 4 c_j c_k cov(mean w_j, mean w_k)``.  The mean of the M_j
    coefficients is a linear filter of the rates spanning the whole record (M_j + 2 m_j - 1 = n
    samples for every j: one linear phase), of real amplitude
    ``g_j(f) = sin^2(pi f m_j) / (m_j sin(pi f)) * sin(pi f M_j) / (M_j sin(pi f))``, so
    ``cov(mean w_j, mean w_k) = int_{-1/2}^{1/2} S(f) g_j(f) g_k(f) df``.  Where the Fejer factors
    oscillate finer than the grid (f M > 32) their product is replaced by its mean
    ``cos(pi f (M_j - M_k)) / 2`` (0 where that oscillates too), as sin^4 in :func:`wv_covariance`."""
    m = np.asarray(m, dtype=float)
    M = np.asarray(n_terms, dtype=float)
    c = np.sqrt(np.maximum(np.asarray(ramp_wv, dtype=float), 0.0))
    f_lo = 1e-3 / (M.max() + 2 * m.max())
    nu = np.logspace(math.log10(f_lo), math.log10(0.5), int(n_grid_per_decade * math.log10(0.5 / f_lo)) + 1)
    s = np.sin(np.pi * nu)
    hj = np.stack([np.where(nu * mm > 32, math.sqrt(0.375), np.sin(np.pi * nu * mm) ** 2) / (mm * s) for mm in m])
    w = np.gradient(np.log(nu)) * nu * spectrum(nu) / (s * s)  # df = f dln f
    sin_m = np.sin(np.pi * nu[None, :] * M[:, None])  # each sin(pi f M_j) once
    wh = w * hj
    out = np.empty((m.size, m.size))
    for j in range(m.size):
        for k in range(j, m.size):
            # where the Fejer factors oscillate finer than the grid: their mean (the cos), else the product
            slow = nu * min(M[j], M[k]) <= 32
            cut = min(int(np.searchsorted(nu, 32.0 / abs(M[j] - M[k]), side="right")), nu.size) if M[j] != M[k] \
                else nu.size
            tot = np.sum(wh[j][slow] * hj[k][slow] * sin_m[j][slow] * sin_m[k][slow])
            fast = ~slow
            fast[cut:] = False  # nu |M_j - M_k| > 32: the mean of the cos is 0 too
            tot += np.sum(wh[j][fast] * hj[k][fast] * 0.5 * np.cos(np.pi * nu[fast] * (M[j] - M[k])))
            out[j, k] = out[k, j] = 2.0 * tot / (M[j] * M[k])  # both halves of [-1/2, 1/2]
    return 4.0 * np.outer(c, c) * out


def curve_covariance(terms, curve: "Curve") -> np.ndarray:
    """V = cov(nu_hat) at ``curve``'s scales for the sum of processes ``terms``: the noise's
    (:func:`wv_covariance`) and, with a rate ramp among them, its cross term (:func:`ramp_covariance`)."""
    noise = [t for t in terms if t.code != "DR"]

    def spec(f):
        return sum((t.spectrum(f, curve.dt) for t in noise), np.zeros(np.shape(f)))

    V = wv_covariance(spec, curve.m, curve.n_terms)
    ramps = [t for t in terms if t.code == "DR"]
    if ramps and noise:
        V = V + ramp_covariance(spec, sum(0.5 * t.avar(curve.m, curve.dt) for t in ramps), curve.m, curve.n_terms)
    return V


def readoff_starts(curve: Curve, codes) -> np.ndarray:
    """A deterministic start: each term's coefficient from the tangent of its slope to the Allan curve
    (the IEEE read-offs), GM correlation times spread over the scales."""
    tau = curve.m * curve.dt
    av = 2 * curve.wv
    th = []
    k_gm = list(codes).count("GM")
    g = 0
    for c in codes:
        if c == "QN":
            th.append(0.5 * np.log(np.min(av * tau**2 / 3)))
        elif c == "WN":
            th.append(0.5 * np.log(np.min(av * tau)))
        elif c == "BI":
            th.append(0.5 * np.log(np.min(av) / nm.BI_PLATEAU))
        elif c == "RW":
            th.append(0.5 * np.log(np.min(3 * av / tau)))
        elif c == "DR":
            th.append(0.5 * np.log(np.min(2 * av / tau**2)))
        else:
            g += 1
            tc = tau[0] * (tau[-1] / tau[0]) ** (g / (k_gm + 1))
            j = int(np.argmin(np.abs(np.log(tau / tc))))
            th += [0.5 * np.log(av[j]), np.log(tc)]
    return np.array(th, dtype=float)


def _bounds(codes, curve: Curve, th0, tc_max: float | None = None, tc_min: float | None = None):
    lo, hi = [], []
    T = curve.n_terms[0] * curve.dt * 10
    for c, i in zip(codes, np.cumsum([0] + [n_params(c) for c in codes])[:-1]):
        lo.append(th0[i] - 25)
        hi.append(th0[i] + 25)
        if c == "GM":
            lo.append(math.log(projection.TC_MIN_SHARE * curve.dt if tc_min is None else tc_min))  # phi to exp(-8)
            hi.append(math.log(100 * T if tc_max is None else tc_max))
    return np.array(lo), np.array(hi)


def _canonical(codes, theta) -> np.ndarray:
    """GM terms in increasing correlation time (their labels are otherwise arbitrary)."""
    idx = [i for i, c in enumerate(codes) if c == "GM"]
    if len(idx) < 2:
        return theta
    starts = np.cumsum([0] + [n_params(c) for c in codes])[:-1]
    blocks = [theta[starts[i]: starts[i] + 2] for i in idx]
    order = np.argsort([b[1] for b in blocks])
    out = theta.copy()
    for slot, k in zip(idx, order):
        out[starts[slot]: starts[slot] + 2] = blocks[k]
    return out


def solve(curve: Curve, codes, weights=None, n_starts: int = 8, rng: np.random.Generator | None = None,
          theta0=None, whiten=None, grid: bool = True, tc_max: float | None = None, tc_min: float | None = None):
    """Multi-start weighted least squares; returns ``(theta, objective, starts that reached it, starts run)``.
    The starts: the best point of the correlation-time grid with the amplitudes solved exactly
    (:func:`inscal.analysis.noise.projection.profile`, ``grid=True``), ``theta0`` (default: the
    read-offs) and ``n_starts`` random ones around it.  ``whiten``: a (J, J) matrix W for the objective
    ``|| W (nu_hat - nu) ||^2`` in place of the diagonal ``weights`` (the efficient ``V^-1/2``);
    ``tc_max``: the longest Gauss-Markov correlation time allowed [s] (default: far beyond the record);
    ``tc_min`` the shortest (default dt / 8: :data:`inscal.analysis.noise.projection.TC_MIN_SHARE`)."""
    rng = np.random.default_rng(0) if rng is None else rng
    w = gmwm_weights(curve.lower, curve.upper) if weights is None else np.asarray(weights, float)
    Wm = np.diag(np.sqrt(w)) if whiten is None else np.asarray(whiten, float)
    th0 = readoff_starts(curve, codes) if theta0 is None else np.asarray(theta0, float)
    lo, hi = _bounds(codes, curve, th0, tc_max, tc_min)
    starts = []
    if grid:
        cols = None if tc_max is None and tc_min is None else projection.basis(codes, curve.m, curve.dt, projection.tc_grid(
            curve.m, curve.dt, tc_max=tc_max, tc_min=tc_min))
        thg = projection.profile(codes, curve.m, curve.dt, curve.wv, Wm, cols)[0]
        lo, hi = np.minimum(lo, thg - 25), np.maximum(hi, thg + 25)
        starts.append(np.clip(thg, lo + 1e-9, hi - 1e-9))
    th0 = np.clip(th0, lo + 1e-9, hi - 1e-9)

    def resid(th):
        return Wm @ (curve.wv - model_wv(codes, th, curve.m, curve.dt))

    def jac(th):
        return -Wm @ jacobian(codes, th, curve.m, curve.dt)

    starts += [th0] + [np.clip(th0 + rng.normal(0, 2.0, th0.size), lo + 1e-9, hi - 1e-9) for _ in range(n_starts)]
    best, fbest, hits = None, np.inf, 0
    for s in starts:
        r = least_squares(resid, s, jac=jac, bounds=(lo, hi), method="trf", x_scale=1.0, xtol=1e-8, ftol=1e-10,
                          gtol=1e-10, max_nfev=100)
        f = float(np.sum(r.fun**2))
        if f < fbest * (1 - 1e-6):
            best, fbest, hits = r.x, f, 1
        elif f <= fbest * (1 + 1e-6):
            hits += 1
    return _canonical(codes, best), fbest, hits, len(starts)


def jacobian(codes, theta, m, dt: float) -> np.ndarray:
    """d nu / d theta: 2 nu_term for a scale parameter (nu is quadratic in it), a central difference
    (step 1e-6) for a GM correlation time."""
    J = np.empty((np.size(m), theta.size))
    i = 0
    for c in codes:
        th = theta[i:i + n_params(c)]
        J[:, i] = avar_term(c, th, m, dt)  # d(AVAR/2)/d log s = AVAR for AVAR proportional to s^2
        if c == "GM":
            e = np.array([0.0, 1e-6])
            J[:, i + 1] = (avar_term(c, th + e, m, dt) - avar_term(c, th - e, m, dt)) / 4e-6
        i += n_params(c)
    return J


def avar_term(code: str, th, m, dt: float) -> np.ndarray:
    """The exact Allan variance at factors ``m`` of the term ``code`` with log-parameters ``th``
    (sample interval ``dt`` [s]), in SI rate units squared."""
    return term_from_theta(code, th, dt).avar(m, dt)


@dataclass(frozen=True)
class NoiseFit:
    """A fitted model of one channel: SI values with 95 % intervals, the fit's statistics and curves."""

    model: str
    codes: tuple
    terms: tuple  # the processes at the estimate (SI)
    names: tuple  # parameter labels
    values: np.ndarray  # SI
    lower: np.ndarray  # 95 % interval (SI)
    upper: np.ndarray
    theta: np.ndarray  # log-parameters
    cov_theta: np.ndarray  # sandwich covariance of theta
    objective: float  # (nu_hat - nu)' Omega (nu_hat - nu)
    weights: np.ndarray  # Omega's diagonal
    gof: float  # r' V^-1 r
    gof_dof: int
    gof_p: float
    penalty: float  # 2 tr(Omega D A^-1 D' Omega V): the WVIC optimism
    starts: int
    hits: int  # starts that reached the best objective
    curve: Curve
    wv_fit: np.ndarray  # nu(theta_hat)
    negligible: tuple  # per term: below 5 % of the interval half-width at every scale (not identified)

    @property
    def se_theta(self) -> np.ndarray:
        """The standard errors of the log-parameters ``theta``: the square roots of the sandwich
        covariance's diagonal."""
        return np.sqrt(np.diag(self.cov_theta))

    @property
    def wvic(self) -> float:
        """The wavelet variance information criterion: the objective plus its optimism ``penalty``
        (smaller is better; model selection compares it across candidate models)."""
        return self.objective + self.penalty


def fit_curve(curve: Curve, model, weights=None, n_starts: int = 8, rng: np.random.Generator | None = None,
              v_terms=None, theta0=None, tc_min: float | None = None) -> NoiseFit:
    """Fit ``model`` (a string like "WN+RW+2GM" or parsed codes) to ``curve``.  ``v_terms``: the
    processes whose spectrum gives V (default: the fitted ones; model selection passes the largest
    model's, so that every candidate is judged with one V); ``tc_min``: the shortest GM correlation time [s]
    (default dt / 8)."""
    codes = nm.parse_model(model) if isinstance(model, str) else tuple(model)
    p = sum(n_params(c) for c in codes)
    if p > curve.m.size:
        raise ValueError(f"model {nm.model_string(codes)} has {p} parameters but the curve only {curve.m.size} "
                         "octave scales")
    w = gmwm_weights(curve.lower, curve.upper) if weights is None else np.asarray(weights, float)
    theta, obj, hits, n_run = solve(curve, codes, w, n_starts, rng, theta0, tc_min=tc_min)
    terms = terms_of(codes, theta, curve.dt)
    D = jacobian(codes, theta, curve.m, curve.dt)
    vt = terms if v_terms is None else v_terms
    V = curve_covariance(vt, curve)
    A = D.T @ (w[:, None] * D)
    Ai = np.linalg.pinv(A)
    WD = w[:, None] * D
    cov = Ai @ (WD.T @ V @ WD) @ Ai
    nu = model_wv(codes, theta, curve.m, curve.dt)
    r = curve.wv - nu
    try:
        gof = float(r @ np.linalg.lstsq(V, r, rcond=None)[0]) if np.all(np.isfinite(V)) else math.nan
    except np.linalg.LinAlgError:
        gof = math.nan
    dof = max(curve.m.size - p, 0)
    penalty = 2.0 * float(np.trace(WD @ Ai @ WD.T @ V))
    se = np.sqrt(np.maximum(np.diag(cov), 0))
    lower, upper = np.exp(np.minimum(theta - Z95 * se, 700)), np.exp(np.minimum(theta + Z95 * se, 700))
    # a term below 5 % of the interval's half-width at every scale is not seen: its interval runs from
    # 0 to the value that would make it reach that half-width (correlation time: the whole search range)
    contrib = contributions(terms, curve.m, curve.dt)
    half = 0.5 * (curve.upper - curve.lower)
    seen = np.max(contrib / half[:, None], axis=0)
    negligible = tuple(bool(x < 0.05) for x in seen)
    blo, bhi = _bounds(codes, curve, theta, tc_min=tc_min)
    i = 0
    for c, neg, ratio in zip(codes, negligible, seen):
        if neg:
            lower[i], upper[i] = 0.0, math.exp(theta[i]) / math.sqrt(max(ratio, 1e-300))
            if c == "GM":
                lower[i + 1], upper[i + 1] = math.exp(blo[i + 1]), math.exp(bhi[i + 1])
        i += n_params(c)
    return NoiseFit(nm.model_string(codes), codes, terms, tuple(param_names(codes)), np.exp(theta),
                    lower, upper, theta, cov, obj, w, gof, dof,
                    chi2_sf(gof, dof) if dof else math.nan, penalty, n_run, hits, curve, nu, negligible)


def bootstrap(fit: NoiseFit, n: int, n_boot: int, rng: np.random.Generator, level: float = 0.95):
    """Parametric bootstrap: ``n_boot`` records of ``n`` samples simulated from the fitted model, each
    refitted from the estimate; returns the ``level`` percentile intervals ``(lower, upper)`` of the
    SI parameters and the (n_boot, p) draws."""
    ch = nm.ChannelNoise("boot", "gyro", fit.terms)
    m = fit.curve.m
    draws = []
    for _ in range(n_boot):
        y = ch.simulate(n, fit.curve.dt, rng)
        sv = scale_variance(y, 1.0 / fit.curve.dt, m[m <= octave_scales(n).max()])
        c = Curve.from_scale_variance(sv)
        th = solve(c, fit.codes, None, 2, rng, fit.theta)[0]
        draws.append(np.exp(th))
    d = np.array(draws)
    a = (1 - level) / 2
    return np.quantile(d, a, axis=0), np.quantile(d, 1 - a, axis=0), d
