"""A calibration as the IMU-error blocks of a KF-GINS configuration (``kf-gins.yaml``).

KF-GINS (i2Nav) models each axis with a bias and a scale factor, and compensates an increment as
(``GIEngine::imuCompensate``)::

    dth_c = (dth - b_g dt) / (1 + s_g),     dv_c = (dv - b_a dt) / (1 + s_a)     per axis

inscal's ``N = (I + K)(I + E)(...) + bias`` reduces to it exactly when the misalignments ``E``, the
g-sensitivity and the nonlinear terms are zero: ``b_g = eps`` [deg/h], ``b_a = nabla`` [mGal],
``s = K`` [ppm], written as the initial IMU errors ``initgyrbias``, ``initaccbias``, ``initgyrscale``,
``initaccscale``, and the reported 1 sigma as their initial standard deviations ``initbgstd``,
``initbastd``, ``initsgstd``, ``initsastd`` (where the file has them).  Any other non-zero term is
listed (``dropped``) and said in the file: compensate the record with ``inscal compensate`` and
export it as KF-GINS text instead.  KF-GINS's IMU frame is front-right-down: the s-frame axes are
written as they are.  (The ``imunoise`` block comes from a noise model, not from a calibration.)
"""

from __future__ import annotations

import numpy as np

from inscal.core import units
from inscal.core.error_model import ImuErrors
from inscal.core.thermal import ThermalModel
from inscal.io.exports.terms import dropped_terms

#: (KF-GINS key, inscal attribute, field unit, its std key)
BLOCKS = (("initgyrbias", "gyro_bias", "deg/h", "initbgstd"),
          ("initaccbias", "accel_bias", "mGal", "initbastd"),
          ("initgyrscale", "gyro_scale_factor", "ppm", "initsgstd"),
          ("initaccscale", "accel_scale_factor", "ppm", "initsastd"))


def kfgins_yaml(imu: ImuErrors, sigma: dict | None = None, thermal: ThermalModel | None = None,
                source: str = "") -> tuple[str, dict]:
    """The YAML blocks and a summary (``dropped``: the terms KF-GINS cannot hold)."""
    sigma = sigma or {}
    dropped = dropped_terms(imu, thermal, set())
    lines = ["# IMU errors for KF-GINS exported by inscal" + (f" from {source}" if source else ""),
             "# KF-GINS compensates dth_c = (dth - b_g dt) / (1 + s_g), dv_c = (dv - b_a dt) / (1 + s_a) per axis"]
    if dropped:
        lines.append(f"# NOT representable in KF-GINS (non-zero here): {', '.join(dropped)}; compensate the record "
                     "with inscal and export it as KF-GINS text instead")
    for key, attr, unit, std in BLOCKS:
        v = units.from_si(np.asarray(getattr(imu, attr), dtype=float), unit)
        lines.append(f"{key}: [{', '.join(repr(float(x)) for x in v)}]   # [{unit}]")
    for key, attr, unit, std in BLOCKS:
        s = sigma.get(attr)
        if s is not None and np.all(np.isfinite(s)):
            v = units.from_si(np.asarray(s, dtype=float), unit)
            lines.append(f"{std}: [{', '.join(repr(float(x)) for x in v)}]   # [{unit}] 1 sigma")
    return "\n".join(lines) + "\n", {"dropped": dropped}
