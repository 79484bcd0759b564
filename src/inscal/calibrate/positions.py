"""Shared helpers of the multi-position schemes (N25 sec. 3-4): nominal positions of static windows,
accelerometer least squares, gyro matrices from CW/CCW rate tests, the twelve N25 positions, and the
leveling deviation that an unmodelled gimbal leaves in the ideal schemes."""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.window_model import ideal_up
from inscal.calibrate.windows import CalibrationError, Window, WindowSet
from inscal.core.attitude import rot_z
from inscal.core.error_model import off_diagonal_angles, split_scale_misalignment
from inscal.core.turntable import N25_TWELVE_POSITIONS, outer_axis
from inscal.core.units import DEG

AXIS_NAMES = ("x", "y", "z")


def nominal_position(w: Window, tol: float = 2.0 * DEG) -> tuple[int, int] | None:
    """Nominal (theta_x, theta_z) in whole degrees (multiples of 90, mod 360) of a static
    window, or None if its angles are not within ``tol`` of such a position."""
    out = []
    for a in w.theta:
        q = round(a / (math.pi / 2))
        if abs(a - q * math.pi / 2) > tol:
            return None
        out.append(int(q * 90) % 360)
    return out[0], out[1]


def orientation(pos: tuple[int, int]) -> str:
    """Which s-axis points up at a nominal position for a level turntable: '+x', '-z', ..."""
    up = ideal_up(pos[0] * DEG, pos[1] * DEG)
    j = int(np.argmax(np.abs(up)))
    return ("+" if up[j] > 0 else "-") + AXIS_NAMES[j]


def positions(ws: WindowSet) -> dict[tuple[int, int], int]:
    """Nominal position -> index of its first static window (the scheme's visit; later
    returns to the same position, e.g. between rate tests, are not used)."""
    best: dict[tuple[int, int], int] = {}
    for k, w in enumerate(ws.windows):
        if w.kind != "static":
            continue
        p = nominal_position(w)
        if p is not None and p not in best:
            best[p] = k
    return best


def accel_least_squares(N: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[M | nabla] = U A^T (A A^T)^-1`` (N25 eq. 19) with ``U`` (3 x n) the mean outputs
    and ``A`` (4 x n) the inputs ``F`` (n x 3) stacked over a row of ones (eq. 17)."""
    A = np.vstack([F.T, np.ones(F.shape[0])])
    U = N.T
    AAt = A @ A.T
    if np.linalg.matrix_rank(AAt) < 4:
        raise CalibrationError("the static positions do not span the three axes and the bias (rank-deficient eq. 19)")
    Mt = U @ A.T @ np.linalg.inv(AAt)
    return Mt[:, :3], Mt[:, 3]


def rate_test_groups(ws: WindowSet) -> list[tuple[str, float, list[int], list[int]]]:
    """Constant-rate windows grouped by (axis, fixed angle of the other axis): each group
    with its positive- and negative-rate window indices (CW/CCW pairs, eq. 28)."""
    groups: dict[tuple[str, int], tuple[list, list]] = {}
    for k, w in enumerate(ws.windows):
        if w.kind != "rate":
            continue
        fixed = w.theta[1] if w.axis == "outer" else w.theta[0]
        key = (w.axis, int(round(math.degrees(fixed))) % 360)
        pos, neg = groups.setdefault(key, ([], []))
        (pos if w.rate > 0 else neg).append(k)
    return [(ax, float(f), p, n) for (ax, f), (p, n) in sorted(groups.items()) if p and n]


def rate_test_axis(axis: str, fixed_deg: float, dth: float) -> np.ndarray:
    """s-frame direction of the turning axis: inner -> e_z; outer at theta_z -> R_z^T u (N25 eq. 9)."""
    if axis == "inner":
        return np.array([0.0, 0.0, 1.0])
    return rot_z(math.radians(fixed_deg)).T @ outer_axis(dth)


def gyro_matrix_from_rate_tests(ws: WindowSet, dth: float = 0.0, ideal: bool = True) -> tuple[np.ndarray, list[int]]:
    """``M_g`` from CW/CCW rate tests: ``M_g a = (N+ - N-) / (w+ - w-)`` for each turning
    axis ``a`` (N25 eq. 28: the difference of the CW and CCW outputs over
    the difference of the rates, ``w+ - w-``), solved by least
    squares over all pairs.  ``ideal``: round ``a`` to the nearest s-axis (the classical
    scheme, which ignores the non-orthogonality); otherwise ``a`` uses ``dth``."""
    groups = rate_test_groups(ws)
    cols_a, cols_b, used = [], [], []
    for axis, fixed, pos, neg in groups:
        a = rate_test_axis(axis, fixed, 0.0 if ideal else dth)
        if ideal:
            j = int(np.argmax(np.abs(a)))
            a = np.sign(a[j]) * np.eye(3)[j]
        Np = np.mean([ws.windows[k].gyro for k in pos], axis=0)
        Nn = np.mean([ws.windows[k].gyro for k in neg], axis=0)
        wp = np.mean([ws.windows[k].rate for k in pos])
        wn = np.mean([ws.windows[k].rate for k in neg])
        cols_a.append(a)
        cols_b.append((Np - Nn) / (wp - wn))  # N25 eq. 28
        used += pos + neg
    A = np.array(cols_a).T if cols_a else np.zeros((3, 0))
    missing = [AXIS_NAMES[j] for j in range(3) if A.shape[1] == 0 or np.max(np.abs(A[j])) < 0.5]
    if missing or np.linalg.matrix_rank(A) < 3:
        raise CalibrationError(
            "no clockwise/counter-clockwise rate-test pair about the " + ", ".join(missing or ["(independent)"])
            + " axis: the gyro scale factors and installation angles need constant-rate windows of at least one "
              "whole turn in both directions about x, y and z (N25 eq. 28)")
    B = np.array(cols_b).T
    Mg = B @ A.T @ np.linalg.inv(A @ A.T)
    return Mg, used


def values_from_matrices(Ma, nabla, Mg, eps) -> dict:
    ka, ea = split_scale_misalignment(Ma)
    kg, eg = split_scale_misalignment(Mg)
    return {"gyro_scale_factor": kg, "gyro_misalignment": eg, "gyro_bias": eps,
            "accel_scale_factor": ka, "accel_misalignment": ea, "accel_bias": nabla}


def leveling_deviation(theta_x: float, theta_z: float, alpha0: float, beta0: float, dth: float) -> np.ndarray:
    """First-order deviation of the unit up vector in the s-frame from its ideal value
    (generalises N25 eq. 20 to any position)::

        dn = R_z(tz)^T [-b0 + (1 - cos tx) dth,  cos(tx) a0,  -sin(tx) a0]

    For tx = 180 deg this is eq. 20 with ``-b0 + 2 dth`` where N25 prints ``b0 + 2 dth``:
    the printed pitch has the opposite sign to the z-y-x Euler pitch of eq. 8 used here
    (the physics, checked against the exact model in tests/calibrate/test_calibrate_schemes.py).
    """
    cx, sx = math.cos(theta_x), math.sin(theta_x)
    return rot_z(theta_z).T @ np.array([-beta0 + (1.0 - cx) * dth, cx * alpha0, -sx * alpha0])


def predicted_scheme_errors(windows: list[Window], g: float, alpha0: float, beta0: float, dth: float,
                            rate_axes: list[tuple[str, float]] = ()) -> dict:
    """First-order errors of the ideal-input schemes caused by the leveling error (a0, b0)
    and the non-orthogonality dth (N25 eq. 21-23 for six positions, eq. 24-26 for twelve,
    eq. 29 for the rate tests), for the static ``windows`` actually used and the rate-test
    groups ``rate_axes`` = [(axis, fixed angle deg)].  Returns SI arrays
    ``accel_bias`` (3), ``accel_misalignment`` (6), ``gyro_misalignment`` (6).

    With the ideal inputs ``g n_k`` and true inputs ``g (n_k + dn_k)``, the eq. 19 least
    squares returns ``[M | nabla] + g M [dn_k] A^T (A A^T)^-1``; to first order the
    scale factors are unaffected (their error is second order, eq. 22/25).
    """
    F = np.array([np.round(ideal_up(*w.theta)) * g for w in windows])
    D = np.array([g * leveling_deviation(*w.theta, alpha0, beta0, dth) for w in windows])
    A = np.vstack([F.T, np.ones(len(windows))])
    dMt = D.T @ A.T @ np.linalg.inv(A @ A.T)
    out = {"accel_bias": dMt[:, 3], "accel_misalignment": off_diagonal_angles(dMt[:, :3])}
    dMg = np.zeros((3, 3))
    for axis, fixed in rate_axes:
        a = rate_test_axis(axis, fixed, dth)
        j = int(np.argmax(np.abs(a)))
        sgn = np.sign(a[j])
        dMg[:, j] = sgn * a - np.eye(3)[j]  # eq. 28/29: the column is measured along the tilted axis
    out["gyro_misalignment"] = off_diagonal_angles(dMg)
    return out


TWELVE = [tuple(p) for p in N25_TWELVE_POSITIONS]


def twelve_windows(ws: WindowSet, method: str = "twelve-position") -> list[int]:
    """Window indices of the twelve N25 positions, in N25 order; a clear error if any is missing."""
    pos = positions(ws)
    missing = [p for p in TWELVE if p not in pos]
    if missing:
        raise CalibrationError(
            f"{method} calibration needs static windows at the twelve N25 positions (theta_x, theta_z) deg; "
            f"missing {len(missing)}: " + ", ".join(f"({a}, {b})" for a, b in missing))
    return [pos[p] for p in TWELVE]


def accel_twelve(ws: WindowSet, idx: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 24-26: the eq. 19 least squares over the twelve positions with ideal inputs."""
    g = ws.site.gravity
    N = np.array([ws.windows[k].accel for k in idx])
    F = np.array([np.round(ideal_up(*ws.windows[k].theta)) * g for k in idx])
    return accel_least_squares(N, F)
