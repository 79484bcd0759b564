"""The site and clock inputs of a calibration in its Cramér-Rao bound: how an error in what the systematic filter
takes as exact moves its estimate (a consider analysis; Bierman 1977 ch. VIII, the "consider" covariance).

The filter is told the site's gravity, latitude and height and reads the record on its own time base.  An error
``s`` in any of them (truth minus what the filter assumes) is no noise: it drives the true navigation error through
a column of its own, in the rows where a parameter column acts (``[dphi'; dv']``, the sensor error in the
navigation frame, as :func:`inscal.calibrate.systematic.dynamics.column_values` has it for a bias):

* gravity ``dg``: the computed specific force misses ``dg`` along the up axis: ``[0; e_U]``;
* height ``dh``: the same through the site's gravity model, ``[0; e_U dg/dh]`` (zero for a measured, constant
  gravity: the height then moves nothing the filter uses);
* latitude ``dL``: the navigation removes the Earth rate at the assumed latitude, the gyros sense the true one:
  ``[d w_ie^n / dL; 0]`` with ``w_ie^n = Omega [0, cos L, sin L]`` (ENU); the gravity is the site's own input;
* time base ``eps`` (the acquisition clock fast by ``eps``): the increments are integrals over the true sample
  interval, the navigation removes the Earth rate and gravity over the believed, shorter one ``dt / (1 + eps)``:
  its frame turns ``eps w_ie^n`` and its velocity gains ``eps g`` up per second, ``[w_ie^n; g e_U]``.  An
  isotropic scale factor of the accelerometers (the specific force at rest is all gravity), not of the gyros: the
  table's turns are integrated from the increments, whatever the clock says of their duration.

The kernel (:mod:`inscal.plan.bound_kernel`) carries ``E = d(x^ - x)/ds`` with the filter's own gain; the
parameters' sensitivity is ``d(estimate)/ds = -E_p`` (the estimate is the nominal minus the estimated error,
:meth:`~inscal.calibrate.systematic.params.CompParams.corrected`).  The turntable's own inputs (its angles, rates,
wobble, the axes' non-orthogonality, the encoder) do not enter: the filter reads neither the table's angles nor
its rates, only the dwells' zero velocity and known position.

Canonical parameters (:func:`canonical`): the bound's states are the S16 matrix entries of the filter; the
budget's parameters are the calibration result's (:data:`inscal.core.error_model.PARAMETERS`).  The map is the
systematic driver's: the Jacobian of the canonical parameters by the parameter error state at the nominal (ideal)
unit, ``Sigma_c = J P J^T`` and ``c = J S``; the components the filter holds fixed (frame conventions) are NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.calibrate.systematic.params import CompParams, canonical_flat, canonical_jacobian
from inscal.calibrate.systematic.states import estimated_names, fixed_mask
from inscal.core import earth

#: the inputs a bound can carry, in the station's names (:data:`inscal.uncertainty.station.INPUTS`)
CONSIDER_INPUTS = ("gravity", "latitude", "height", "time_base")


def consider_columns(site, names) -> np.ndarray:
    """The columns ``Vc`` (6, m) of the inputs ``names`` at ``site`` (SI per SI; module docstring)."""
    Vc = np.zeros((6, len(names)))
    lat, h = site.latitude, site.height
    for c, n in enumerate(names):
        if n == "gravity":
            Vc[5, c] = 1.0
        elif n == "height":
            Vc[5, c] = (site.gravity_model.g(lat, h + 1.0) - site.gravity_model.g(lat, h - 1.0)) / 2.0
        elif n == "latitude":
            Vc[1, c] = -earth.OMEGA_IE * math.sin(lat)
            Vc[2, c] = earth.OMEGA_IE * math.cos(lat)
        elif n == "time_base":
            Vc[0:3, c] = earth.earth_rate_n(lat)
            Vc[5, c] = site.gravity
        else:
            raise ValueError(f"unknown consider input {n!r}; known: {', '.join(CONSIDER_INPUTS)}")
    return Vc


@dataclass(frozen=True)
class CanonicalBound:
    """A bound in the calibration result's parameters (:func:`canonical`): ``names``, the nominal ``values`` and the
    flat ``sigma`` (SI; NaN where the filter holds a component fixed) and per input the flat sensitivity (SI per SI)."""

    names: tuple[str, ...]
    values: np.ndarray
    sigma: np.ndarray
    sensitivity: dict[str, np.ndarray]

    def combined(self, u: dict[str, float]) -> np.ndarray:
        """``sqrt(sigma^2 + sum_i (c_i u_i)^2)`` (SI) with the inputs' standard uncertainties ``u`` (SI)."""
        v = self.sigma**2
        for k, x in u.items():
            v = v + (self.sensitivity[k] * x) ** 2
        return np.sqrt(v)


def canonical(bound) -> CanonicalBound:
    """The bound ``bound`` (:class:`inscal.plan.bound.Bound`) in the result's canonical parameters at the nominal
    unit: ``J P J^T`` and ``J S`` (module docstring)."""
    su = bound.setup
    st = su.states
    names = estimated_names(st)
    sig_par = su.prior
    J = canonical_jacobian(CompParams(), st, names, sig_par) / sig_par
    cov = J @ bound.covariance @ J.T
    sigma = np.sqrt(np.maximum(np.diag(cov), 0.0))
    fixed = fixed_mask(st, names)
    sigma[fixed] = np.nan
    sens = {}
    if bound.sensitivity is not None:
        S = J @ bound.sensitivity
        sens = {n: S[:, c] for c, n in enumerate(su.consider)}
    return CanonicalBound(tuple(names), canonical_flat(CompParams(), names), sigma, sens)
