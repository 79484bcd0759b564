"""A calibration as imucal's Ferraris calibration JSON (mad-lab-fau/imucal, ``FerrarisCalibrationInfo``;
Ferraris et al., Sensors and Actuators A 46-47, 1995).

imucal's model (raw units ``from_acc_unit`` / ``from_gyr_unit`` -> physical ``acc_unit`` / ``gyr_unit``)::

    acc_raw = K_a R_a acc + b_a                      K diagonal (scales), R rows the axes' unit
    gyr_raw = K_g R_g gyr + K_ga acc + b_g           direction cosines (misalignment)

and its compensation, in this order (the accelerometer first, its result feeds the gyro)::

    acc = R_a^-1 K_a^-1 (acc_raw - b_a)
    gyr = R_g^-1 K_g^-1 (gyr_raw - K_ga acc - b_g)

From inscal's ``N_a = M_a f + nabla``, ``N_g = M_g (w + G f) + eps`` (s-frame; the raw signal is the
increment over dt, so raw rates are ``dth/dt`` [rad/s] and ``dv/dt`` [m/s^2]):
``K_a = diag(|row_i(M_a)|)``, ``R_a = K_a^-1 M_a``, ``b_a = nabla``; with the gyro in deg/s (imucal's
default unit) ``K_g R_g = M_g * (pi/180)``: ``K_g = diag(|row_i(M_g)|) pi/180``, ``R_g`` the rows of
``M_g`` normalised, ``K_ga = M_g G`` [(rad/s)/(m/s^2)], ``b_g = eps`` [rad/s].  All exact; the physical
frame is inscal's s-frame.  The nonlinear accelerometer terms, the lever arms, the time asynchrony and
a thermal model have no counterpart (listed in ``dropped``).
"""

from __future__ import annotations

import json

import numpy as np

from inscal.core.error_model import ImuErrors
from inscal.core.thermal import ThermalModel
from inscal.core.units import DEG
from inscal.io.exports.terms import dropped_terms

#: imucal's calibration file format version this export follows
CAL_FORMAT_VERSION = "2.0.0"


def ferraris_parameters(imu: ImuErrors) -> dict:
    """imucal's Ferraris parameters of ``imu`` (NumPy arrays; see the module docstring)."""
    na = np.linalg.norm(imu.M_a, axis=1)
    ng = np.linalg.norm(imu.M_g, axis=1)
    return {"K_a": np.diag(na), "R_a": imu.M_a / na[:, None], "b_a": imu.accel_bias.copy(),
            "K_g": np.diag(ng * DEG), "R_g": imu.M_g / ng[:, None], "K_ga": imu.M_g @ imu.gyro_g_sensitivity,
            "b_g": imu.gyro_bias.copy()}


def imucal_json(imu: ImuErrors, thermal: ThermalModel | None = None, comment: str = "") -> tuple[str, dict]:
    """The JSON text (imucal's ``FerrarisCalibrationInfo.to_json`` layout) and a summary."""
    p = ferraris_parameters(imu)
    doc = {"cal_type": "Ferraris", "_format_version": CAL_FORMAT_VERSION,
           **{k: v.tolist() for k, v in p.items()},
           "from_acc_unit": "m/s^2", "from_gyr_unit": "rad/s", "acc_unit": "m/s^2", "gyr_unit": "deg/s",
           "comment": comment}
    dropped = dropped_terms(imu, thermal, {"gyro_misalignment", "accel_misalignment", "gyro_g_sensitivity"})
    return json.dumps(doc, indent=2) + "\n", {"dropped": dropped}
