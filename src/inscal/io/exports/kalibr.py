"""A calibration in Kalibr's IMU intrinsics (Rehder et al., ICRA 2016, "Extending kalibr"): the
``scale-misalignment`` model, and ``scale-misalignment-size-effect`` where lever arms exist.

Kalibr's measurement model, in its IMU frame ``i`` (the accelerometer triad's frame: ``M_accel`` is
lower triangular, so the accelerometer x axis is i's x axis and its y axis lies in i's x-y plane)::

    a_m = M_accel a_i + b_a                                   (+ the size effect below)
    w_m = M_gyro C_gyro_i w_i + A C_gyro_i a_i + b_g          M_gyro lower triangular, C_gyro_i a rotation
    size effect: a_i,k = e_k . (f + dw/dt x r_k + w x (w x r_k))   at the position r_k of axis k (rx_i, ry_i, rz_i)

(kalibr's ``ScaledMisalignedImu``: ``w = M * (C_gyro_b * w_b) + Ma * (C_gyro_b * a_b)``, its ``A`` acting
on the specific force in the gyros' frame), and its inverse, the compensation::

    a_i = M_accel^-1 (a_m - b_a)
    w_i = C_gyro_i^T M_gyro^-1 (w_m - b_g - A C_gyro_i a_i)

inscal's model (:mod:`inscal.core.error_model`, s-frame): ``N_a = M_a f + nabla``,
``N_g = M_g (w + G f) + eps``.  The frame change: the LQ factorisation ``M_a = L_a Q_a`` (``L_a`` lower
triangular with a positive diagonal, ``Q_a`` a rotation) gives ``M_accel = L_a`` and
``C_i_s = Q_a`` (``a_i = C_i_s f_s``); then ``M_g C_i_s^T = L_g Q_g`` gives ``M_gyro = L_g``,
``C_gyro_i = Q_g``, and ``A = M_g G C_i_s^T C_gyro_i^T``, ``b_a = nabla``, ``b_g = eps``.  These are
exact: Kalibr's compensation followed by ``f_s = C_i_s^T a_i``, ``w_s = C_i_s^T w_i`` gives inscal's.

The size effect: ``r_k = C_i_s p_k`` (``p_k``, row k of inscal's ``accel_lever_arm``), so the
compensated specific force refers to inscal's origin of the lever arms (a Kalibr calibration fixes
``rx_i = 0``, its origin the x accelerometer's position).  Kalibr projects on the axes of ``i``, inscal
on those of ``s``: the two differ by the angle of ``C_i_s`` (the accelerometer misalignment,
arcseconds) times the size-effect acceleration, which the export states (``size_effect_frame_error``
[rad]).  Biases: Kalibr estimates them as random walks per run; the file carries inscal's constant
biases beside the intrinsics (``inscal: b_gyro`` [rad/s], ``b_accel`` [m/s^2], and the frame change
``C_i_s``).  The nonlinear accelerometer terms, the time asynchrony and a thermal model have no
counterpart (listed in ``dropped``).  Units: SI (rad/s, m/s^2, m).  The layout is that of the IMU
configuration Kalibr writes (``accelerometers: M [, rx_i, ry_i, rz_i]``, ``gyroscopes: M, A,
C_gyro_i``) under ``imu0``.
"""

from __future__ import annotations

import numpy as np

from inscal.core.error_model import ImuErrors
from inscal.core.thermal import ThermalModel
from inscal.io.exports.terms import dropped_terms


def lq(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``m = L Q``: ``L`` lower triangular with a positive diagonal, ``Q`` orthogonal (a rotation for
    a matrix near the identity)."""
    q, r = np.linalg.qr(np.asarray(m, dtype=float).T)
    L, Q = np.tril(r.T) + 0.0, q.T  # + 0.0: no negative zeros above the diagonal
    s = np.sign(np.diag(L))
    return L * s + 0.0, s[:, None] * Q


def kalibr_intrinsics(imu: ImuErrors) -> dict:
    """Kalibr's intrinsics of ``imu`` (see the module docstring), NumPy arrays in SI."""
    m_accel, c_i_s = lq(imu.M_a)
    m_gyro, c_gyro_i = lq(imu.M_g @ c_i_s.T)
    out = {"M_accel": m_accel, "M_gyro": m_gyro, "A": imu.M_g @ imu.gyro_g_sensitivity @ c_i_s.T @ c_gyro_i.T,
           "C_gyro_i": c_gyro_i, "C_i_s": c_i_s, "b_gyro": imu.gyro_bias.copy(), "b_accel": imu.accel_bias.copy()}
    if np.any(imu.accel_lever_arm):
        r = imu.accel_lever_arm @ c_i_s.T  # row k: C_i_s p_k
        out.update(rx_i=r[0], ry_i=r[1], rz_i=r[2])
    return out


def _yaml_value(v) -> str:
    a = np.asarray(v, dtype=float)
    if a.ndim == 1:
        return "[" + ", ".join(repr(float(x)) for x in a) + "]"
    return "[" + ", ".join(_yaml_value(r) for r in a) + "]"


def kalibr_yaml(imu: ImuErrors, thermal: ThermalModel | None = None, topic: str = "/imu0",
                source: str = "") -> tuple[str, dict]:
    """The YAML text and a summary (``model``, ``dropped`` terms, ``size_effect_frame_error`` [rad])."""
    k = kalibr_intrinsics(imu)
    model = "scale-misalignment-size-effect" if "rx_i" in k else "scale-misalignment"
    dropped = dropped_terms(imu, thermal, {"gyro_misalignment", "accel_misalignment", "gyro_g_sensitivity",
                                           "accel_lever_arm"})
    angle = float(np.arccos(np.clip((np.trace(k["C_i_s"]) - 1.0) / 2.0, -1.0, 1.0)))
    lines = [f"# Kalibr IMU intrinsics ({model}) exported by inscal" + (f" from {source}" if source else ""),
             "# measurement: a_m = M_accel a_i + b_a;  w_m = M_gyro C_gyro_i w_i + A C_gyro_i a_i + b_g   (SI)",
             "# compensation: a_i = M_accel^-1 (a_m - b_a);  w_i = C_gyro_i^T M_gyro^-1 (w_m - b_g - A C_gyro_i a_i)",
             "# frame: i = the accelerometer triad's frame; inscal.C_i_s rotates inscal's s-frame into it",
             "imu0:", f"  rostopic: {topic}", f"  model: {model}", "  accelerometers:",
             f"    M: {_yaml_value(k['M_accel'])}"]
    for key in ("rx_i", "ry_i", "rz_i"):
        if key in k:
            lines.append(f"    {key}: {_yaml_value(k[key])}")
    lines += ["  gyroscopes:", f"    M: {_yaml_value(k['M_gyro'])}", f"    A: {_yaml_value(k['A'])}",
              f"    C_gyro_i: {_yaml_value(k['C_gyro_i'])}",
              "  # inscal's constant biases (Kalibr estimates its own, as random walks) [rad/s], [m/s^2]",
              "  inscal:", f"    b_gyro: {_yaml_value(k['b_gyro'])}", f"    b_accel: {_yaml_value(k['b_accel'])}",
              f"    C_i_s: {_yaml_value(k['C_i_s'])}"]
    if dropped:
        lines.append(f"# not represented in Kalibr's model (compensate with inscal for these): {', '.join(dropped)}")
    return "\n".join(lines) + "\n", {"model": model, "dropped": dropped, "size_effect_frame_error": angle}
