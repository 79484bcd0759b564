"""The result of every calibration method (:class:`CalibrationResult`) and the helpers that turn
named parameter values into error-model objects and flat vectors (names of
:data:`inscal.core.error_model.PARAMETERS`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from inscal.calibrate.windows import CalibrationError, WindowSet  # noqa: F401  (CalibrationError: re-exported)
from inscal.core import units
from inscal.core.error_model import PARAMETERS, GimbalErrors, ImuErrors
from inscal.core.thermal import ThermalModel

#: Parameters of the linear N25 model the calibration methods work with.
IMU_LINEAR = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias",
              "accel_scale_factor", "accel_misalignment", "accel_bias")
GIMBAL = ("gimbal_nonorthogonality", "mount_attitude")


def param_value(imu: ImuErrors, gimbal: GimbalErrors, name: str) -> np.ndarray:
    """The value of parameter ``name`` (SI, its shape in :data:`~inscal.core.error_model.PARAMETERS`) from the IMU or gimbal errors."""
    p = PARAMETERS[name]
    return np.asarray(getattr(imu if p.group == "imu" else gimbal, p.attribute), dtype=float)


def flatten(imu: ImuErrors, gimbal: GimbalErrors, names) -> np.ndarray:
    """The parameters ``names`` as one flat vector (SI), in that order, each raveled row-major."""
    return np.concatenate([np.atleast_1d(param_value(imu, gimbal, n)).ravel() for n in names])


def nparams(names) -> int:
    """The number of scalar components of the parameters ``names``."""
    return sum(PARAMETERS[n].size for n in names)


def unflatten(vec, names) -> dict[str, np.ndarray]:
    """The inverse of :func:`flatten`: ``{name: value}`` (SI, each in its shape; a scalar parameter as a float)."""
    out, k = {}, 0
    for n in names:
        shape = PARAMETERS[n].shape
        size = int(np.prod(shape)) if shape else 1
        out[n] = np.asarray(vec[k:k + size], float).reshape(shape) if shape else float(vec[k])
        k += size
    return out


@dataclass
class CalibrationResult:
    """Estimated IMU and gimbal errors of one calibration method (SI).

    Parameters
    ----------
    method : str
        The method's name.
    imu : ImuErrors
        The IMU error estimates (zeros where the method does not estimate).
    gimbal : GimbalErrors
        The gimbal error estimates (zeros where not estimated).
    sigma : dict of str to numpy.ndarray
        1 sigma of each parameter (SI, the parameter's shape; NaN for components held fixed): for the
        window-mean methods the formal sigma while the fit is consistent, scaled for the misfit when
        it is not (``diagnostics["formal_sigma"]`` keeps the formal one, ``diagnostics["fit"]`` /
        :attr:`fit` the chi^2, dof, p-value, per-window residuals and the note).
    estimated : tuple of str
        The parameters the method estimates (names of :data:`~inscal.core.error_model.PARAMETERS`).
    windows : WindowSet, optional
        The windows it used.
    diagnostics : dict
        Method-specific figures.
    notes : list of str
        What the method assumed, in words.
    truth_transform : callable, optional
        Maps the truth ``(ImuErrors, GimbalErrors)`` into the frame of the estimates, for methods
        that define their own IMU frame (the systematic filter); None = identity.
    history : dict, optional
        The filter's state history (the systematic methods).
    thermal : ThermalModel, optional
        The thermal model estimated with the errors (``imu`` = the errors at ``thermal.t_ref``).
    thermal_sigma : dict
        1 sigma of the thermal coefficients (SI; NaN: held fixed).
    thermal_fit : dict, optional
        The fit of the thermal model (per term chi^2, dof, p-value ...).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import calibrate, window_means
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("n25", np.random.default_rng(0), rate_hz=10.0)
    >>> res = calibrate(window_means(rec), "joint")
    >>> bias = res.to_field((rec.truth.imu, rec.truth.gimbal))["accel_bias"]  # field units, the error against the truth
    >>> bias["unit"], all(abs(e) < 3 * s for e, s in zip(bias["error"], bias["sigma"]))
    ('ug', True)
    """

    method: str
    imu: ImuErrors
    gimbal: GimbalErrors
    sigma: dict[str, np.ndarray]
    estimated: tuple[str, ...]
    windows: WindowSet | None = None
    diagnostics: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    #: maps the truth (``(ImuErrors, GimbalErrors)``) into the frame of the estimates, for
    #: methods that define their own IMU frame (the systematic filter); None = identity
    truth_transform: Callable | None = None
    history: dict | None = None
    #: the thermal model estimated with the errors (``imu`` = the errors at ``thermal.t_ref``), or None
    thermal: ThermalModel | None = None
    #: 1 sigma of the thermal coefficients (SI, the shapes of the model's arrays; NaN: held fixed)
    thermal_sigma: dict[str, np.ndarray] = field(default_factory=dict)
    #: the fit of the thermal model (per term chi^2, dof, p-value ...), written to ``[thermal.fit]``
    thermal_fit: dict | None = None
    # the systematic filter's (None for the other methods; its types are not imported here, its package
    # imports this module):
    #: its states (an :class:`inscal.calibrate.systematic.states.StateSet`)
    states: object | None = None
    #: the frozen model-error factors of its fit (an :class:`inscal.calibrate.systematic.model_error.ModelError`;
    #: the nested fits of ``--states auto`` share them)
    model_error: object | None = None
    #: the formal covariance of its parameter states: ``{"labels": [...], "P": (n, n)}`` (SI)
    covariance: dict | None = None
    #: the estimate as the filter's error state about the nominal (the states of ``covariance``)
    parameter_state: np.ndarray | None = None
    #: its last pass over the record (an :class:`inscal.calibrate.systematic.kernel.PassOutput`), kept on request
    #: (``keep_passes``: the observability analysis reads it)
    pass_output: object | None = None

    @property
    def fit(self) -> dict | None:
        """The fit (``diagnostics["fit"]``): of the window means for the window-mean methods
        (:func:`fit_statistics`), of the innovations for the systematic filter
        (:func:`inscal.calibrate.systematic.diagnostics.innovation_fit`)."""
        return self.diagnostics.get("fit")

    def sigma_scaled(self, name: str) -> bool:
        """Whether the reported sigma of ``name`` differs from its formal sigma (an
        inconsistent fit scaled it, or a known scheme error was added)."""
        formal = (self.diagnostics.get("formal_sigma") or {}).get(name)
        if formal is None:
            return False
        a, b = np.asarray(self.sigma.get(name, np.nan), float), np.asarray(formal, float)
        both = np.isfinite(a) & np.isfinite(b)
        return bool(np.any(np.abs(a[both] - b[both]) > 1e-12 * np.maximum(np.abs(b[both]), 1e-300)))

    def value(self, name: str) -> np.ndarray:
        """Estimated value of a parameter (SI)."""
        return param_value(self.imu, self.gimbal, name)

    def error(self, truth, name: str) -> np.ndarray:
        """Estimate minus truth (SI); ``truth`` as in :meth:`to_field`."""
        ti, tg = self._truth(truth)
        return self.value(name) - param_value(ti, tg, name)

    def _truth(self, truth):
        pair = _truth_pair(truth)
        return self.truth_transform(pair) if self.truth_transform is not None else pair

    @classmethod
    def from_field(cls, values: dict, sigma: dict, method: str = "manual") -> CalibrationResult:
        """A result from values and 1 sigma in field units (the ``value`` and ``sigma`` of
        :meth:`to_field`): a calibration entered by hand or taken from another tool.

        Parameters
        ----------
        values : dict
            ``{parameter name: value}`` in the field unit of :data:`inscal.core.error_model.PARAMETERS`
            (deg/h, ppm, arcsec, ...); the names estimated, in this order.
        sigma : dict
            ``{parameter name: 1 sigma}`` in the same units, for every name of ``values``.
        method : str
            The method's name.

        Returns
        -------
        CalibrationResult
            The estimates (SI) and their 1 sigma; the parameters not named are zero.

        Raises
        ------
        ValueError
            An unknown parameter name, a name without its sigma, or a value of the wrong size.

        Examples
        --------
        >>> from inscal.calibrate import CalibrationResult
        >>> res = CalibrationResult.from_field({"gyro_bias": [0.01, 0.0, 0.0]}, {"gyro_bias": [0.001] * 3})
        >>> res.estimated, res.to_field()["gyro_bias"]["unit"], round(res.to_field()["gyro_bias"]["value"][0], 6)
        (('gyro_bias',), 'deg/h', 0.01)
        """
        si, sig = {}, {}
        for name, v in values.items():
            if name not in PARAMETERS or name not in sigma:
                raise ValueError(f"{name!r}: " + ("no sigma given" if name in PARAMETERS else "unknown parameter"))
            p = PARAMETERS[name]
            try:
                x = np.asarray(units.to_si(np.asarray(v, dtype=float), p.unit, p.kind)).reshape(p.shape)
                sig[name] = np.asarray(units.to_si(np.asarray(sigma[name], dtype=float), p.unit, p.kind)).reshape(p.shape)
            except ValueError as exc:
                raise ValueError(f"{name!r}: {exc}") from None
            si[name] = x if p.shape else float(x)
        imu, gimbal = errors_from_values(si)
        return cls(method, imu, gimbal, sig, tuple(values))

    def to_field(self, truth=None) -> dict:
        """``{NAME: {"value": [...], "sigma": [...], "unit": ..., "error": [...]}}`` in field
        units (``error`` = estimate - truth, only when ``truth`` is given: an object with
        ``.imu`` and ``.gimbal`` or a pair ``(ImuErrors, GimbalErrors)``)."""
        ti, tg = self._truth(truth) if truth is not None else (None, None)
        formal = self.diagnostics.get("formal_sigma") or {}
        out = {}
        for name in self.estimated:
            unit = PARAMETERS[name].unit
            conv = lambda v: np.atleast_1d(units.from_si(np.asarray(v, dtype=float), unit)).tolist()  # noqa: E731
            entry = {"value": conv(self.value(name)), "sigma": conv(self.sigma.get(name, np.nan)), "unit": unit}
            if name in formal and self.sigma_scaled(name):
                entry["sigma_formal"] = conv(formal[name])
            if ti is not None:
                entry["error"] = conv(self.value(name) - param_value(ti, tg, name))
            out[name] = entry
        return out


def _truth_pair(truth):
    if isinstance(truth, tuple):
        return truth
    return truth.imu, truth.gimbal


def make_result(method: str, values: dict, sigma: dict, estimated, ws: WindowSet, diagnostics=None,
                notes=None) -> CalibrationResult:
    """Assemble a result from ``values[name]`` (SI) for the estimated names."""
    imu_kw, gim_kw = {}, {}
    for name, v in values.items():
        p = PARAMETERS[name]
        (imu_kw if p.group == "imu" else gim_kw)[p.attribute] = v
    return CalibrationResult(method, ImuErrors(**imu_kw), GimbalErrors(**gim_kw), sigma, tuple(estimated), ws,
                             diagnostics or {}, list(notes or []))


def errors_from_values(vals: dict):
    """``(ImuErrors, GimbalErrors)`` from ``{parameter name: value}`` (names of :data:`PARAMETERS`)."""
    return ImuErrors(**{PARAMETERS[n].attribute: v for n, v in vals.items() if PARAMETERS[n].group == "imu"}), GimbalErrors(
        **{PARAMETERS[n].attribute: v for n, v in vals.items() if PARAMETERS[n].group == "gimbal"})
