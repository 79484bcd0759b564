"""The calibration result object and first-order uncertainty propagation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import units
from ..errors import PARAMETERS, GimbalErrors, ImuErrors
from .segment import WindowSet

#: Parameters of the linear N25 model the calibration methods work with.
IMU_LINEAR = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias",
              "accel_scale_factor", "accel_misalignment", "accel_bias")
GIMBAL = ("gimbal_nonorthogonality", "mount_attitude")


def param_value(imu: ImuErrors, gimbal: GimbalErrors, name: str) -> np.ndarray:
    obj, attr, _, _, _ = PARAMETERS[name]
    return np.asarray(getattr(imu if obj == "imu" else gimbal, attr), dtype=float)


def flatten(imu: ImuErrors, gimbal: GimbalErrors, names) -> np.ndarray:
    return np.concatenate([np.atleast_1d(param_value(imu, gimbal, n)).ravel() for n in names])


def nparams(names) -> int:
    return sum(int(np.prod(PARAMETERS[n][4])) if PARAMETERS[n][4] else 1 for n in names)


def unflatten(vec, names) -> dict[str, np.ndarray]:
    out, k = {}, 0
    for n in names:
        shape = PARAMETERS[n][4]
        size = int(np.prod(shape)) if shape else 1
        out[n] = np.asarray(vec[k:k + size], float).reshape(shape) if shape else float(vec[k])
        k += size
    return out


@dataclass
class CalibrationResult:
    """Estimated IMU and gimbal errors of one calibration method (SI).

    ``imu`` / ``gimbal`` hold the estimates (zeros where the method does not estimate);
    ``sigma[name]`` is the 1-sigma uncertainty (SI, same shape as the parameter; NaN for
    components held fixed); ``estimated`` names the parameters the method estimates.
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

    def to_field(self, truth=None) -> dict:
        """``{NAME: {"value": [...], "sigma": [...], "unit": ..., "error": [...]}}`` in field
        units (``error`` = estimate - truth, only when ``truth`` is given: an object with
        ``.imu`` and ``.gimbal`` or a pair ``(ImuErrors, GimbalErrors)``)."""
        ti, tg = self._truth(truth) if truth is not None else (None, None)
        out = {}
        for name in self.estimated:
            unit = PARAMETERS[name][3]
            conv = lambda v: np.atleast_1d(units.from_si(np.asarray(v, dtype=float), unit)).tolist()  # noqa: E731
            entry = {"value": conv(self.value(name)), "sigma": conv(self.sigma.get(name, np.nan)), "unit": unit}
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
        obj, attr, _, _, _ = PARAMETERS[name]
        (imu_kw if obj == "imu" else gim_kw)[attr] = v
    return CalibrationResult(method, ImuErrors(**imu_kw), GimbalErrors(**gim_kw), sigma, tuple(estimated), ws,
                             diagnostics or {}, list(notes or []))


def propagate(estimator: Callable[[WindowSet], np.ndarray], ws: WindowSet, used: dict[int, tuple[bool, bool]],
              x0: np.ndarray | None = None) -> np.ndarray:
    """First-order standard deviations of ``estimator(ws)`` (a flat vector) from the
    measured noise of the window means, by one-sided differences (the estimators are
    linear in the means up to terms of second order in the small error angles).

    ``used[k] = (gyro, accel)``: which channels of window k the estimator reads.
    """
    G = np.array([w.gyro for w in ws.windows])
    A = np.array([w.accel for w in ws.windows])
    x0 = estimator(ws) if x0 is None else x0
    var = np.zeros_like(x0)
    for k, (ug, ua) in used.items():
        w = ws.windows[k]
        for chan, use, arr, sig, floor in (("g", ug, G, w.gyro_sigma, 1e-9), ("a", ua, A, w.accel_sigma, 1e-6)):
            if not use:
                continue
            for c in range(3):
                if not sig[c] > 0:
                    continue
                h = max(sig[c], floor)
                arr[k, c] += h
                x1 = estimator(ws.replace_means(G, A))
                arr[k, c] -= h
                var += ((x1 - x0) / h * sig[c]) ** 2
    return np.sqrt(var)
