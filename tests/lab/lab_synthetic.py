"""Synthetic calibration results for the database tests (values and 1 sigma given in field units)."""

from __future__ import annotations

import numpy as np

from inscal.calibrate.result import CalibrationResult
from inscal.core import units
from inscal.core.error_model import PARAMETERS, GimbalErrors, ImuErrors


def synthetic_result(values: dict, sigma: dict, method: str = "manual") -> CalibrationResult:
    """A :class:`CalibrationResult` with ``values`` / ``sigma`` given per parameter name in field units."""
    imu, gim, sig = {}, {}, {}
    for name, v in values.items():
        obj, attr, kind, unit, shape = PARAMETERS[name]
        si = np.asarray(units.to_si(np.asarray(v, dtype=float), unit, kind)).reshape(shape)
        (imu if obj == "imu" else gim)[attr] = si if shape else float(si)
        sig[name] = np.asarray(units.to_si(np.asarray(sigma[name], dtype=float), unit, kind)).reshape(shape)
    return CalibrationResult(method, ImuErrors(**imu), GimbalErrors(**gim), sig, tuple(values))
