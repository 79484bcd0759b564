"""Stochastic error processes of an inertial sensor channel, their exact discrete-time Allan and
Haar wavelet variances, spectra and simulation.

Conventions (SI inside, as everywhere in inscal).  A channel's output error is a *rate* series
``y_t`` (rad/s for a gyro, m/s^2 for an accelerometer) sampled every ``dt`` seconds; the record's
increments are ``y_t dt``.  For an averaging factor ``m`` (``tau = m dt``)

    AVAR(m) = 1/2 E[(ybar_{t+m} - ybar_t)^2],  ybar = mean of m consecutive samples   (IEEE 952 eq. C.8)
    WV(m)   = E[W_t^2] = AVAR(m) / 2,  W the Haar MODWT coefficient of width L = 2m    (Percival & Walden 2000 eq. 170)

so the Haar wavelet variance at scale index ``j`` (``m = 2^(j-1)``, width ``2^j``) is half the
Allan variance at ``m``.  With ``V(k)`` the variance of a sum of ``k`` consecutive samples of a
stationary ``y``,  ``AVAR(m) = (4 V(m) - V(2m)) / (2 m^2)``  (the blocks' sums S_a, S_b: var(S_b - S_a)).

The processes (IEEE Std 952-2020 Annex C, IEEE Std 1293-2018 for accelerometers), each defined in
discrete time so that its variances below are exact for every ``m >= 1``, not only asymptotically::

    =====  ===========================================  ==========================================
     Q     quantization: white phase error of var Q^2     AVAR = 3 Q^2 / tau^2
     N     white rate noise, var N^2 / dt (ARW, VRW)      AVAR = N^2 / tau
     B     flicker rate noise cut off at f0               AVAR -> (2 ln 2 / pi) B^2 (the plateau)
           (two-sided S(f) = B^2 / (2 pi |f|), |f| <= f0)   (IEEE 952 eq. C.17, integrated exactly)
     K     rate random walk, steps of var K^2 dt          AVAR = K^2 tau / 3 + K^2 dt^2 / (6 tau)
     R     rate ramp y = R t (deterministic)              AVAR = R^2 tau^2 / 2
     GM    first-order Gauss-Markov (AR(1)): stationary   AVAR = s^2 F / (m^2 (1 - phi)^2),
           std s, correlation time T, phi = exp(-dt/T)      F below (Guerrier et al. 2013 appendix)
    =====  ===========================================  ==========================================

Sources: IEEE Std 952-2020 (gyros), IEEE Std 1293-2018 (accelerometers); N. El-Sheimy, H. Hou,
X. Niu, "Analysis and modeling of inertial sensors using Allan variance", IEEE TIM 57 (2008);
S. Guerrier, J. Skaloud, Y. Stebler, M.-P. Victoria-Feser, "Wavelet-variance-based estimation for
composite stochastic processes", JASA 108 (2013) 1021-1030; D. B. Percival, A. T. Walden,
"Wavelet Methods for Time Series Analysis" (2000).
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import numpy as np
from scipy import integrate, signal

#: the bias-instability plateau factor: AVAR -> (2 ln 2 / pi) B^2  (IEEE 952 eq. C.17)
BI_PLATEAU = 2.0 * math.log(2.0) / math.pi
#: orders and factorials of the series of the Gauss-Markov Allan variance (GaussMarkov.avar)
_SERIES_N = np.arange(3, 26)
_SERIES_FACT = np.array([math.factorial(int(k)) for k in _SERIES_N], dtype=float)
#: Gauss-Legendre nodes per half-period of the flicker integrand
_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)


def _m(m) -> np.ndarray:
    m = np.asarray(m, dtype=float)
    if np.any(m < 1):
        raise ValueError("averaging factors m must be >= 1")
    return m


def haar_gain(nu, m) -> np.ndarray:
    """``|H(nu)|^2`` of the Allan filter of averaging factor ``m`` (per sample frequency ``nu`` in
    cycles/sample): ``AVAR(m) = int_{-1/2}^{1/2} S(nu) |H|^2 dnu = 2 sin^4(pi nu m) / (m^2 sin^2(pi nu))``."""
    nu, m = np.asarray(nu, dtype=float), np.asarray(m, dtype=float)
    s = np.sin(np.pi * nu)
    with np.errstate(invalid="ignore", divide="ignore"):
        g = 2.0 * np.sin(np.pi * nu * m) ** 4 / (m**2 * s**2)
    return np.where(s == 0.0, 0.0, g)


# ----------------------------------------------------------------------------- the processes
@dataclass(frozen=True)
class Quantization:
    """Angle (velocity) quantization Q [rad] ([m/s]): a white phase error of variance Q^2."""

    q: float
    code = "QN"
    params = ("q",)

    def avar(self, m, dt: float) -> np.ndarray:
        """The exact Allan variance ``3 Q^2 / tau^2`` at factors ``m`` (``tau = m dt``) [(rad/s)^2 or (m/s^2)^2]."""
        return 3.0 * self.q**2 / (_m(m) * dt) ** 2  # IEEE 952 eq. C.3 (exact for white phase)

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """The two-sided rate spectrum ``4 Q^2 sin^2(pi nu) / dt^2`` per cycle/sample at ``nu`` [cycles/sample]."""
        return 4.0 * self.q**2 * np.sin(np.pi * np.asarray(nu)) ** 2 / dt**2

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` rate samples [SI]: the differences of a white phase error of std Q, over ``dt``."""
        return np.diff(rng.normal(0.0, self.q, n + 1)) / dt


@dataclass(frozen=True)
class WhiteNoise:
    """White rate noise of density N [rad/sqrt(s)] ([m/s/sqrt(s)]): per sample std N / sqrt(dt)."""

    n: float
    code = "WN"
    params = ("n",)

    def avar(self, m, dt: float) -> np.ndarray:
        """The exact Allan variance ``N^2 / tau`` at factors ``m`` (``tau = m dt``)."""
        return self.n**2 / (_m(m) * dt)  # IEEE 952 eq. C.6

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """The flat two-sided rate spectrum ``N^2 / dt`` per cycle/sample at ``nu`` [cycles/sample]."""
        return np.full(np.shape(nu), self.n**2 / dt)

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` independent normal rate samples of std ``N / sqrt(dt)`` [SI]."""
        return rng.normal(0.0, self.n / math.sqrt(dt), n)


@dataclass(frozen=True)
class BiasInstability:
    """Flicker (1/f) rate noise B [rad/s] ([m/s^2]) with two-sided density B^2 / (2 pi abs(f)) up to the
    cut-off ``f0`` [Hz] (at most the Nyquist frequency), zero above (IEEE 952 eq. C.16).  The sampled
    process has the same spectrum (no aliasing), so AVAR is the exact integral of it through the
    Allan filter; it rises to the plateau (2 ln 2 / pi) B^2 for tau >> 1/f0."""

    b: float
    f0: float
    code = "BI"
    params = ("b",)

    def unit_avar(self, m, dt: float) -> np.ndarray:
        """AVAR(m) / B^2: (2/pi) int_0^nu0 sin^4(pi nu m) / (nu m^2 sin^2(pi nu)) dnu, nu0 = f0 dt."""
        nu0 = self.f0 * dt
        if not 0 < nu0 <= 0.5 + 1e-12:
            raise ValueError(f"bias-instability cut-off {self.f0} Hz must be in (0, Nyquist = {0.5 / dt} Hz]")
        nu0 = min(nu0, 0.5)
        out = []
        for mm in np.atleast_1d(_m(m)):
            out.append(_flicker_integral(float(mm), nu0))
        return (2.0 / math.pi) * np.asarray(out).reshape(np.shape(m))

    def avar(self, m, dt: float) -> np.ndarray:
        """The exact Allan variance at factors ``m``: ``B^2`` times :meth:`unit_avar`."""
        return self.b**2 * self.unit_avar(m, dt)

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """The two-sided rate spectrum ``B^2 / (2 pi abs(nu))`` per cycle/sample for ``0 < abs(nu) <= f0 dt``, zero
        elsewhere (``nu`` in cycles/sample)."""
        nu = np.abs(np.asarray(nu, dtype=float))
        with np.errstate(divide="ignore"):
            s = self.b**2 / (2.0 * math.pi * nu)
        return np.where((nu > 0) & (nu <= self.f0 * dt), s, 0.0)

    def simulate(self, n: int, dt: float, rng: np.random.Generator, oversample: int = 16) -> np.ndarray:
        """Spectral synthesis on a circle of ``L >= oversample n`` samples (its autocovariance is the
        Riemann sum of the spectrum on the grid k / L: the lowest frequency is 1 / (L dt))."""
        L = 1 << int(math.ceil(math.log2(max(2, oversample * n))))
        nu = np.fft.rfftfreq(L)
        amp = np.sqrt(self.spectrum(nu, dt))
        y = np.fft.irfft(np.fft.rfft(rng.normal(0.0, 1.0, L)) * amp, L)
        return y[:n]


@functools.lru_cache(maxsize=4096)  # a pure function of two floats: the fits evaluate it at the same scales
def _flicker_integral(m: float, nu0: float) -> float:
    """int_0^nu0 sin^4(pi nu m) / (nu m^2 sin^2(pi nu)) dnu: Gauss-Legendre over half-periods up to
    ``min(nu0, 32 / m)``, then sin^4 x = 3/8 - cos(2x)/2 + cos(4x)/8 with QAWO for the oscillating
    parts of the smooth envelope g = 1 / (nu m^2 sin^2(pi nu))."""
    nu1 = min(nu0, 32.0 / m)
    edges = np.linspace(0.0, nu1, max(2, int(math.ceil(nu1 * 2 * m)) + 1))
    a, b = edges[:-1, None], edges[1:, None]
    x = 0.5 * (b - a) * _GL_X[None, :] + 0.5 * (a + b)
    f = np.sin(np.pi * x * m) ** 4 / (x * m**2 * np.sin(np.pi * x) ** 2)
    total = float(np.sum(0.5 * (b - a) * f * _GL_W[None, :]))
    if nu1 < nu0:
        def g(nu):
            return 1.0 / (nu * m**2 * math.sin(math.pi * nu) ** 2)

        total += 0.375 * integrate.quad(g, nu1, nu0, limit=200, epsabs=0)[0]
        total -= 0.5 * integrate.quad(g, nu1, nu0, weight="cos", wvar=2 * math.pi * m, limit=400, epsabs=0)[0]
        total += 0.125 * integrate.quad(g, nu1, nu0, weight="cos", wvar=4 * math.pi * m, limit=400, epsabs=0)[0]
    return total


@dataclass(frozen=True)
class RandomWalk:
    """Rate random walk K [rad/s/sqrt(s)] ([m/s^2/sqrt(s)]): y_t = y_{t-1} + u_t, var u = K^2 dt."""

    k: float
    code = "RW"
    params = ("k",)

    def avar(self, m, dt: float) -> np.ndarray:
        """The exact Allan variance ``K^2 dt (2 m^2 + 1) / (6 m)`` at factors ``m`` (``K^2 tau / 3`` for large m)."""
        m = _m(m)
        return self.k**2 * dt * (2.0 * m**2 + 1.0) / (6.0 * m)  # var(S_b - S_a) = s^2 m (2 m^2 + 1) / 3

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """The two-sided rate spectrum ``K^2 dt / (4 sin^2(pi nu))`` per cycle/sample at ``nu`` [cycles/sample]
        (infinite at ``nu = 0``)."""
        with np.errstate(divide="ignore"):
            return self.k**2 * dt / (4.0 * np.sin(np.pi * np.asarray(nu, dtype=float)) ** 2)

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` rate samples [SI]: the running sum of normal steps of std ``K sqrt(dt)``, from zero."""
        return np.cumsum(rng.normal(0.0, self.k * math.sqrt(dt), n))


@dataclass(frozen=True)
class RateRamp:
    """Rate ramp R [rad/s^2] ([m/s^3]): the deterministic drift y = R t."""

    r: float
    code = "DR"
    params = ("r",)

    def avar(self, m, dt: float) -> np.ndarray:
        """The exact Allan variance ``R^2 tau^2 / 2`` at factors ``m`` (``tau = m dt``)."""
        return 0.5 * (self.r * _m(m) * dt) ** 2  # IEEE 952 eq. C.14

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """Zeros shaped like ``nu``: a deterministic ramp adds nothing to the estimator's variance."""
        return np.zeros(np.shape(nu))  # deterministic: no contribution to the estimator's variance

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` rate samples [SI] of the ramp ``R t`` at ``t = 0, dt, ...`` (``rng`` unused)."""
        return self.r * dt * np.arange(n)


@dataclass(frozen=True)
class GaussMarkov:
    """First-order Gauss-Markov process: stationary std ``sigma`` [rad/s] ([m/s^2]) and correlation
    time ``tc`` [s]; sampled, the AR(1) y_t = phi y_{t-1} + e_t, phi = exp(-dt/tc),
    var e = sigma^2 (1 - phi^2)."""

    sigma: float
    tc: float
    code = "GM"
    params = ("sigma", "tc")

    def phi(self, dt: float) -> float:
        """The AR(1) coefficient ``exp(-dt / tc)`` at sample interval ``dt`` [s]."""
        return math.exp(-dt / self.tc)

    def avar(self, m, dt: float) -> np.ndarray:
        """AVAR = s^2 F / (m^2 (1 - phi)^2) with (b = dt / tc)
        F = m (1 - e^{-2b}) - 3 e^{-b} + 4 e^{-(m+1) b} - e^{-(2m+1) b} = sum_{n>=3} (-b)^n c_n / n!,
        c_n = 4 (m+1)^n - (2m+1)^n - m 2^n - 3 (the series where m b is small: F's terms cancel)."""
        m = _m(m)
        b = dt / self.tc
        f = m * -np.expm1(-2 * b) - 3 * np.exp(-b) + 4 * np.exp(-(m + 1) * b) - np.exp(-(2 * m + 1) * b)
        small = 2 * m * b < 0.5
        if np.any(small):
            ms = m[small][:, None] if np.ndim(m) else np.atleast_1d(m)[:, None]
            n = _SERIES_N[None, :]
            # c_n b^n written with the products m b (no overflow for large m); terms < 0.5^n / n!
            cbn = 4 * ((ms + 1) * b) ** n - ((2 * ms + 1) * b) ** n - ms * (2 * b) ** n - 3 * b**n
            ser = np.sum(np.where(n % 2 == 1, -cbn, cbn) / _SERIES_FACT[None, :], axis=1)
            if np.ndim(m):
                f = np.array(f, copy=True)
                f[small] = ser
            else:
                f = ser[0]
        return self.sigma**2 * f / (m**2 * np.expm1(-b) ** 2)

    def spectrum(self, nu, dt: float) -> np.ndarray:
        # sigma^2 (1 - phi^2) / |1 - phi e^{-i 2 pi nu}|^2, written with expm1 so that phi -> 1 (tc >> dt) stays finite
        """The two-sided rate spectrum of the AR(1),
        ``sigma^2 (1 - phi^2) / abs(1 - phi exp(-2 pi i nu))^2`` per cycle/sample, at ``nu`` [cycles/sample]."""
        b = dt / self.tc
        den = np.expm1(-b) ** 2 + 4 * math.exp(-b) * np.sin(np.pi * np.asarray(nu, dtype=float)) ** 2
        return self.sigma**2 * -np.expm1(-2 * b) / den

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` rate samples [SI] of the AR(1), stationary from the first sample (``y_0`` of std sigma)."""
        p = self.phi(dt)
        e = rng.normal(0.0, 1.0, n)
        e[0] *= self.sigma
        e[1:] *= self.sigma * math.sqrt(1 - p * p)
        return signal.lfilter([1.0], [1.0, -p], e)  # y_0 ~ N(0, sigma^2): stationary from the start


PROCESSES = (Quantization, WhiteNoise, BiasInstability, RandomWalk, RateRamp, GaussMarkov)
#: accepted spellings of each term in a model string ("WN+RW+2GM", simts's names and IEEE letters)
TERM_NAMES = {"QN": "QN", "Q": "QN", "WN": "WN", "N": "WN", "BI": "BI", "B": "BI", "RW": "RW", "K": "RW",
              "RRW": "RW", "DR": "DR", "R": "DR", "RR": "DR", "GM": "GM", "AR1": "GM"}
#: at most this many Gauss-Markov terms in a model
MAX_GM = 4


def parse_model(text: str) -> tuple[str, ...]:
    """``"WN+RW+2GM"`` -> ``("WN", "RW", "GM", "GM")`` in the canonical order QN, WN, BI, RW, DR, GM;
    ValueError (one line) for an unknown term, a repeated one or more than :data:`MAX_GM` GMs."""
    order = ("QN", "WN", "BI", "RW", "DR", "GM")
    out: list[str] = []
    parts = [p.strip() for p in str(text).split("+")]
    if not parts or any(not p for p in parts):
        raise ValueError(f"model {text!r}: write terms joined by '+', e.g. 'QN+WN+RW+2GM'")
    for p in parts:
        mt = re.fullmatch(r"(\d*)\s*\*?\s*([A-Za-z0-9]+)", p)
        name = TERM_NAMES.get(mt.group(2).upper()) if mt else None
        if name is None:
            raise ValueError(f"model {text!r}: unknown term {p!r}; known: {', '.join(sorted(set(TERM_NAMES)))}")
        k = int(mt.group(1)) if mt.group(1) else 1
        if k < 1:
            raise ValueError(f"model {text!r}: {p!r} has no term (a count of at least 1, or leave {name} out)")
        if name != "GM" and (k > 1 or name in out):
            raise ValueError(f"model {text!r}: {name} appears more than once (only GM may repeat)")
        out += [name] * k
    if out.count("GM") > MAX_GM:
        raise ValueError(f"model {text!r}: at most {MAX_GM} Gauss-Markov terms")
    return tuple(sorted(out, key=order.index))


def model_string(codes) -> str:
    """The inverse of :func:`parse_model`: ``("WN", "GM", "GM")`` -> ``"WN+2GM"``."""
    codes = list(codes)
    k = codes.count("GM")
    names = [c for c in codes if c != "GM"] + ([f"{k}GM" if k > 1 else "GM"] if k else [])
    return "+".join(names)


# ----------------------------------------------------------------------------- field units
#: IEEE 952-2020 / 1293-2018 field unit of each parameter, per sensor kind (converted in core.units)
FIELD_UNITS = {
    "gyro": {"q": "arcsec", "n": "deg/sqrt(h)", "b": "deg/h", "k": "deg/h/sqrt(h)", "r": "deg/h^2",
             "sigma": "deg/h", "tc": "s", "f0": "Hz"},
    "accel": {"q": "ug*s", "n": "ug/sqrt(Hz)", "b": "ug", "k": "ug*sqrt(Hz)", "r": "ug/h",
              "sigma": "ug", "tc": "s", "f0": "Hz"},
}
#: the SI unit of each parameter, per sensor kind
SI_UNITS = {
    "gyro": {"q": "rad", "n": "rad/sqrt(s)", "b": "rad/s", "k": "rad/s/sqrt(s)", "r": "rad/s^2",
             "sigma": "rad/s", "tc": "s", "f0": "Hz"},
    "accel": {"q": "m/s", "n": "m/s/sqrt(s)", "b": "m/s^2", "k": "m/s^2/sqrt(s)", "r": "m/s^3",
              "sigma": "m/s^2", "tc": "s", "f0": "Hz"},
}


def discrete(term, dt: float) -> dict:
    """The per-sample (discrete-time) form of a term at sample interval ``dt``, in SI: the std of what
    is added to each rate sample (or to the phase, for Q), and phi for a Gauss-Markov term."""
    if isinstance(term, Quantization):
        return {"phase_std": term.q}
    if isinstance(term, WhiteNoise):
        return {"std": term.n / math.sqrt(dt)}
    if isinstance(term, RandomWalk):
        return {"step_std": term.k * math.sqrt(dt)}
    if isinstance(term, RateRamp):
        return {"step": term.r * dt}
    if isinstance(term, GaussMarkov):
        p = term.phi(dt)
        return {"phi": p, "innovation_std": term.sigma * math.sqrt(1 - p * p)}
    return {"b": term.b, "nu0": term.f0 * dt}


# ----------------------------------------------------------------------------- a channel, a model
@dataclass(frozen=True)
class ChannelNoise:
    """The sum of independent processes that makes one channel's noise (``kind`` 'gyro' or 'accel')."""

    name: str
    kind: str
    terms: tuple

    def __post_init__(self):
        if self.kind not in FIELD_UNITS:
            raise ValueError(f"channel {self.name!r}: kind must be 'gyro' or 'accel', got {self.kind!r}")

    @property
    def model(self) -> str:
        """The channel's model string, e.g. ``"WN+RW+2GM"`` (:func:`model_string` of its terms)."""
        return model_string(t.code for t in self.terms)

    def avar(self, m, dt: float) -> np.ndarray:
        """The channel's exact Allan variance at factors ``m``: the sum of its terms' (independent processes)."""
        return sum((t.avar(m, dt) for t in self.terms), np.zeros(np.shape(m)))

    def wvar(self, m, dt: float) -> np.ndarray:
        """Haar wavelet variance at width 2m: AVAR(m) / 2 (Percival & Walden 2000 eq. 170)."""
        return 0.5 * self.avar(m, dt)

    def spectrum(self, nu, dt: float) -> np.ndarray:
        """The channel's two-sided rate spectrum at ``nu`` [cycles/sample]: the sum of its terms'."""
        return sum((t.spectrum(nu, dt) for t in self.terms), np.zeros(np.shape(nu)))

    def simulate(self, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` rate samples [SI] of the channel's noise (every draw from ``rng``)."""
        y = np.zeros(n)
        for t in self.terms:
            y += t.simulate(n, dt, rng)
        return y


@dataclass(frozen=True)
class NoiseModel:
    """The noise of every channel of a unit; ``rate_hz`` is the sample rate it was identified at
    (the discrete forms refer to it)."""

    channels: tuple
    rate_hz: float

    def channel(self, name: str) -> ChannelNoise:
        """The channel named ``name`` (``gx`` ... ``az``); KeyError naming the channels there are otherwise."""
        for c in self.channels:
            if c.name == name:
                return c
        raise KeyError(f"no channel {name!r} (have {', '.join(c.name for c in self.channels)})")

    def simulate(self, n: int, rng: np.random.Generator, dt: float | None = None) -> np.ndarray:
        """``(n, channels)`` rate samples [SI], one channel after the other from ``rng``."""
        dt = 1.0 / self.rate_hz if dt is None else dt
        return np.stack([c.simulate(n, dt, rng) for c in self.channels], axis=1)
