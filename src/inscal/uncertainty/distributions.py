"""The distributions of a budget's inputs (GUM 4.3.7, 4.3.9; JCGM 101:2008 6.4): their names, the factor between
a half-width and the standard uncertainty, their CDF and their sampler, one home for the station file
(:mod:`inscal.uncertainty.station`), the linear budget's coverage factor (:mod:`inscal.uncertainty.budget`) and
the JCGM 101 Monte Carlo (:mod:`inscal.uncertainty.montecarlo`).

A zero-centred distribution of half-width ``a`` has the standard uncertainty ``u = a / d``: rectangular
``d = sqrt(3)`` (GUM 4.3.7), triangular ``d = sqrt(6)`` (GUM 4.3.9), arcsine (U-shaped) ``d = sqrt(2)``
(JCGM 101 6.4.6); a normal one is given by ``u`` itself.  A normal input with a finite number of degrees of
freedom ``nu`` is drawn as the scaled and shifted t of JCGM 101 6.4.9 (``u t_nu``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["DISTRIBUTIONS", "DISTRIBUTION_ALIASES", "cdf", "draw", "half_width"]

#: distribution -> the factor d with ``u = a / d`` for a half-width ``a`` (None: normal, ``u`` given)
DISTRIBUTIONS: dict[str, float | None] = {
    "normal": None,
    "rectangular": math.sqrt(3.0),  # GUM 4.3.7
    "triangular": math.sqrt(6.0),  # GUM 4.3.9
    "arcsine": math.sqrt(2.0),  # JCGM 101 6.4.6 (U-shaped)
}
#: other spellings of the distributions
DISTRIBUTION_ALIASES = {"gaussian": "normal", "uniform": "rectangular", "u-shaped": "arcsine", "u": "arcsine"}


def half_width(distribution: str, u: float) -> float:
    """The half-width ``a = d u`` of a non-normal distribution with standard uncertainty ``u``.

    Parameters
    ----------
    distribution : str
        ``"rectangular"``, ``"triangular"`` or ``"arcsine"`` (a key of :data:`DISTRIBUTIONS` but ``"normal"``).
    u : float
        The standard uncertainty, in any unit.

    Returns
    -------
    float
        The half-width, in the unit of ``u``.

    Raises
    ------
    KeyError
        ``distribution`` is not a distribution with a half-width.

    Examples
    --------
    >>> round(half_width("rectangular", 1.0), 6)
    1.732051
    """
    factor = {k: v for k, v in DISTRIBUTIONS.items() if v is not None}[distribution]
    return u * factor


def cdf(distribution: str, x: np.ndarray, a: float) -> np.ndarray:
    """The CDF of a zero-centred rectangular, triangular or arcsine distribution of half-width ``a``.

    Parameters
    ----------
    distribution : str
        ``"rectangular"``, ``"triangular"`` or ``"arcsine"``.
    x : numpy.ndarray
        Where the CDF is evaluated (the unit of ``a``).
    a : float
        The half-width (> 0).

    Returns
    -------
    numpy.ndarray
        ``P(X <= x)``, 0 below ``-a`` and 1 above ``a``.

    Examples
    --------
    >>> cdf("rectangular", np.array([-2.0, 0.0, 0.5]), 1.0).tolist()
    [0.0, 0.5, 0.75]
    """
    z = np.clip(x / a, -1.0, 1.0)
    if distribution == "rectangular":
        return 0.5 * (z + 1.0)
    if distribution == "triangular":
        return np.where(z < 0, 0.5 * (z + 1.0) ** 2, 1.0 - 0.5 * (1.0 - z) ** 2)
    return 0.5 + np.arcsin(z) / np.pi  # arcsine


def draw(distribution: str, rng: np.random.Generator, size=None, u: float | None = None, a: float | None = None,
         dof: float = math.inf) -> np.ndarray:
    """Zero-centred draws from a distribution (JCGM 101 6.4): normal ``N(0, u)`` (with a finite ``dof``: the
    scaled and shifted t of 6.4.9, ``u t_dof``), rectangular ``U(-a, a)``, triangular on ``[-a, a]``, arcsine
    ``a sin(2 pi U)`` (6.4.6).

    Parameters
    ----------
    distribution : str
        A key of :data:`DISTRIBUTIONS`.
    rng : numpy.random.Generator
        The seeded generator every draw comes from.
    size : int or tuple of int, optional
        The shape of the draws (None: one float).
    u : float, optional
        The standard uncertainty: needed for a normal distribution, and for the others when ``a`` is not given.
    a : float, optional
        The half-width of a non-normal distribution (default: :func:`half_width` of ``u``).
    dof : float, optional
        Degrees of freedom of a normal input (default infinite: a normal draw).

    Returns
    -------
    numpy.ndarray or float
        The draws, in the unit of ``u`` (or ``a``).

    Raises
    ------
    KeyError
        An unknown ``distribution``.

    Examples
    --------
    >>> x = draw("rectangular", np.random.default_rng(0), 100_000, u=2.0)
    >>> bool(abs(x.std() - 2.0) < 0.02), bool(abs(x).max() <= 2.0 * math.sqrt(3.0))
    (True, True)
    """
    if distribution == "normal":
        if math.isfinite(dof):
            return u * rng.standard_t(dof, size)
        return rng.normal(0.0, u, size)
    if a is None:
        a = half_width(distribution, u)
    if distribution == "rectangular":
        return rng.uniform(-a, a, size)
    if distribution == "triangular":
        return rng.triangular(-a, 0.0, a, size)
    if distribution == "arcsine":
        return a * np.sin(2.0 * np.pi * rng.uniform(0.0, 1.0, size))  # JCGM 101 6.4.6
    raise KeyError(distribution)
