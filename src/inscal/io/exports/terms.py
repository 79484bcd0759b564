"""What a calibration holds that another tool's convention cannot: the terms an export leaves out."""

from __future__ import annotations

import numpy as np

from inscal.core.error_model import ImuErrors
from inscal.core.thermal import ThermalModel

#: the terms of :class:`~inscal.core.error_model.ImuErrors` an export may leave out, by attribute
TERMS = ("gyro_misalignment", "gyro_g_sensitivity", "accel_misalignment", "accel_nonlinearity",
         "accel_cross_coupling", "accel_lever_arm", "time_asynchrony")


def dropped_terms(imu: ImuErrors, thermal: ThermalModel | None, represented) -> list[str]:
    """The non-zero terms of ``imu`` (and a non-zero ``thermal`` model, as ``thermal``) not in
    ``represented``: an export without them compensates differently, and says so."""
    out = [t for t in TERMS if t not in represented and np.any(getattr(imu, t))]
    if thermal is not None and not thermal.is_zero and "thermal" not in represented:
        out.append("thermal")
    return out
