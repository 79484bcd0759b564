"""A calibration as imu_tk's two calibration files (Tedaldi, Pretto & Menegatti, ICRA 2014; imu_tk's
``CalibratedTriad``, ``calibration.h``), one for the accelerometers and one for the gyros.

imu_tk's model of a triad (raw reading ``X``, calibrated reading ``X'``, the same for both triads)::

    X' = T K (X - B)          T misalignment (unit diagonal), K = diag(s_x, s_y, s_z), B bias (raw units)

        [   1     -mis_yz   mis_zy ]        general case (the gyros): six angles
    T = [ mis_xz     1     -mis_zx ]
        [-mis_xy   mis_yx     1    ]        "body" frame case (the accelerometers): mis_xz = mis_xy = mis_yx = 0,
                                            T upper triangular

Frames.  imu_tk's calibrated readings are in its *body* frame b, the frame its accelerometer
calibration defines: ``T_a K_a`` upper triangular, so its inverse, the accelerometer matrix ``M``
(``X = M X' + B``), is upper triangular too: the accelerometer **z** axis is b's z axis and the
accelerometer **y** axis lies in b's y-z plane (x is then free).  The gyro triad is calibrated into the
same frame b (its ``T_g`` full).  inscal's parameter file is in its s-frame (a multi-position or
ferraris result: the accelerometer frame with x along accelerometer x,
:mod:`inscal.calibrate.multiposition`), so the export rotates it: with the QR factorisation
``M_a^-1 = C_s_b R`` (``R`` upper triangular with a positive diagonal, ``C_s_b`` a rotation),
``C_b_s = C_s_b^T`` takes s-frame vectors into b (``x_b = C_b_s x_s``) and::

    K_a = diag(R),   T_a = R K_a^-1,   B_a = nabla
    T_g K_g = C_b_s M_g^-1:   K_g = diag(C_b_s M_g^-1),   T_g = C_b_s M_g^-1 K_g^-1,   B_g = eps

from inscal's ``N_a = M_a f + nabla``, ``N_g = M_g w + eps`` (:mod:`inscal.core.error_model`).  Exact:
imu_tk's compensation followed by ``x_s = C_b_s^T x_b`` gives inscal's.  The rotation ``C_b_s`` (a few
misalignment angles) is in the summary (``C_b_s``, and its angle in ``frame_angle_rad``); it does not
enter imu_tk's files.

Units: the raw readings are inscal's increments over their interval, ``dth/dt`` [rad/s] and ``dv/dt``
[m/s^2] (imu_tk integrates rad/s and compares specific forces with ``g_mag`` in m/s^2); ``B_g`` [rad/s],
``B_a`` [m/s^2].  The g-sensitivity of the gyros, the nonlinear accelerometer terms, the lever arms, the
time asynchrony and a thermal model have no counterpart (listed in ``dropped``).

File layout (``CalibratedTriad_::save`` / ``load``): the 3x3 misalignment matrix ``T`` (rows), a blank
line, the 3x3 scale matrix ``K`` (rows), a blank line, the bias vector ``B`` (one value a line) --
21 whitespace-separated numbers read row-major by ``load``.  Written with 17 significant digits (imu_tk's
own ``save`` writes Eigen's default 6), so the round trip is exact to the last bits.
"""

from __future__ import annotations

import numpy as np

from inscal.core.error_model import ImuErrors
from inscal.core.thermal import ThermalModel
from inscal.io.exports.terms import dropped_terms

#: the suffix of the accelerometer file; the gyro file replaces it by :data:`GYRO_SUFFIX`
ACC_SUFFIX = "_acc.calib"
GYRO_SUFFIX = "_gyro.calib"


def imutk_parameters(imu: ImuErrors) -> dict:
    """imu_tk's ``T``, ``K``, ``B`` of both triads and the frame change ``C_b_s`` (module docstring),
    NumPy arrays in SI."""
    q, r = np.linalg.qr(np.linalg.inv(imu.M_a))  # M_a^-1 = C_s_b R
    s = np.sign(np.diag(r))
    c_s_b, r = q * s[None, :], s[:, None] * r
    c_b_s = c_s_b.T
    k_a = np.diag(r)
    t_a = np.triu(r / k_a[None, :])
    a_g = c_b_s @ np.linalg.inv(imu.M_g)
    k_g = np.diag(a_g)
    return {"T_a": t_a, "K_a": np.diag(k_a), "B_a": imu.accel_bias.copy(),
            "T_g": a_g / k_g[None, :], "K_g": np.diag(k_g), "B_g": imu.gyro_bias.copy(), "C_b_s": c_b_s}


def triad_text(T: np.ndarray, K: np.ndarray, B: np.ndarray) -> str:
    """One triad's calibration file as ``CalibratedTriad_::load`` reads it (module docstring)."""
    rows = lambda m: "\n".join(" ".join(f"{float(x):.17g}" for x in r) for r in m)  # noqa: E731
    return f"{rows(T)}\n\n{rows(K)}\n\n" + "\n".join(f"{float(x):.17g}" for x in B) + "\n\n"


def imutk_files(imu: ImuErrors, thermal: ThermalModel | None = None) -> tuple[str, str, dict]:
    """The accelerometer and the gyro file's text and a summary (``dropped`` terms, ``C_b_s``,
    ``frame_angle_rad``)."""
    p = imutk_parameters(imu)
    dropped = dropped_terms(imu, thermal, {"gyro_misalignment", "accel_misalignment"})
    angle = float(np.arccos(np.clip((np.trace(p["C_b_s"]) - 1.0) / 2.0, -1.0, 1.0)))
    return (triad_text(p["T_a"], p["K_a"], p["B_a"]), triad_text(p["T_g"], p["K_g"], p["B_g"]),
            {"dropped": dropped, "C_b_s": p["C_b_s"].tolist(), "frame_angle_rad": angle})
