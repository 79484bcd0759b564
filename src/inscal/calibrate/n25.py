"""The N25 self-calibration (scheme 1, N25 section 4): IMU errors plus the gimbal
non-orthogonality and the mounting (vehicle) attitude, without leveling or alignment.

1. Rough accelerometer calibration: the twelve-position least squares with ideal inputs
   (N25 eq. 24-26), and a rough roll ``alpha0`` from the z accelerometer at
   (theta_x, theta_z) = (90, 0) and (0, 0) deg (eq. 38; physics gives
   ``tan alpha0 = -N_z(90, 0) / N_z(0, 0)`` in the frames of ``turntable``; the printed
   equation has no minus sign).  ``alpha0`` must be small for the linearised step 2.
2. ``L`` = x/y part of the roughly compensated difference of the outputs at
   inner-symmetric positions, divided by ``2 g``, minus its ideal value (eq. 40), and the
   least-squares solution ``X = [tan beta0, alpha0, dth]`` of ``L = A X`` (eq. 41-44).
   The design matrix of eq. 42, derived from the model (eq. 5-12),
   per inner-symmetric pair at (theta_x, theta_z) and (theta_x, theta_z + 180 deg)::

       L_x = -cos(tz) tan(b0) + sin(tz) cos(tx) a0 + cos(tz) (1 - cos(tx)) dth
       L_y =  sin(tz) tan(b0) + cos(tz) cos(tx) a0 - sin(tz) (1 - cos(tx)) dth

   (first order in a0, dth and the rough-calibration residuals; tests compare it with
   finite differences of the full model).  Its dropped terms are of second order in the
   small angles (a0, b0, dth, installation angles, scale factors).
3. Refined accelerometer scale factors, installation angles and biases: the eq. 19 least
   squares with the inputs of the full model at the estimated (a0, b0, dth) instead of the
   ideal ones (the paper's "substitute into eq. 21-26").
4. Gyro: ``M_g`` from the CW/CCW rate tests (eq. 28) with the turning axes of the
   estimated gimbal geometry (the outer axis is ``R_z^T u``, not an s-axis); then the
   bias ``eps`` and the Earth rate in the base frame ``w^b`` by least squares from the
   twelve static means ``N_g = M_g C_b^s w^b + eps`` (eq. 11), and the heading
   ``gamma0`` from ``w^b`` (``C_b^n w^b = w_ie^n``).

Windows (:func:`symmetric_windows`): the twelve N25 positions when present, otherwise any
set of inner-symmetric pairs that separates [tan b0, a0, dth] and points every
accelerometer axis up and down; the method refuses only what it truly needs, naming it.

Uncertainty: first order in the measured noise of the window means it reads
(:func:`.result.sensitivity`; the estimator is linear in them, so this is exact to second
order in the small angles: a Monte Carlo over 100 simulated records gives error/sigma RMS
0.98-1.07 for every group, alpha0 included).  Fit: the chi^2 of the exact model's predicted
window means (all windows) against the measured ones, dof = components - 28; when
inconsistent the sigma are scaled for the misfit (:data:`.result.SIGMA_RULE`).
"""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.fit import (
    estimator_reference,
    finish_sigma,
    fit_statistics,
    sensitivity,
)
from inscal.calibrate.positions import (
    TWELVE,
    accel_least_squares,
    accel_twelve,
    gyro_matrix_from_rate_tests,
    nominal_position,
    positions,
    values_from_matrices,
)
from inscal.calibrate.result import (
    GIMBAL,
    IMU_LINEAR,
    CalibrationResult,
    errors_from_values,
    flatten,
    make_result,
    nparams,
)
from inscal.calibrate.window_model import C_b_s, C_n_s, ideal_up
from inscal.calibrate.windows import CalibrationError, WindowSet
from inscal.core.attitude import rot_x, rot_y
from inscal.core.units import DEG

NAMES = IMU_LINEAR + GIMBAL


def design_rows(theta_x: float, theta_z: float) -> np.ndarray:
    """Rows ``(L_x, L_y)`` of the design matrix for X = [tan b0, a0, dth] (N25 eq. 42, derived)."""
    cx, cz, sz = math.cos(theta_x), math.cos(theta_z), math.sin(theta_z)
    return np.array([[-cz, sz * cx, cz * (1.0 - cx)],
                     [sz, cz * cx, -sz * (1.0 - cx)]])


def inner_pairs(ws: WindowSet, idx: list[int]) -> list[tuple[int, int]]:
    """Pairs of window indices at (tx, tz) and (tx, tz + 180) among the windows ``idx``."""
    pos = {nominal_position(ws.windows[k]): k for k in idx}
    pairs, seen = [], set()
    for (tx, tz), k in pos.items():
        q = (tx, (tz + 180) % 360)
        if q in pos and (tx, tz) not in seen:
            pairs.append((k, pos[q]))
            seen.update({(tx, tz), q})
    return pairs


def L_vector(ws: WindowSet, pairs, Ma_rough: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``L`` (N25 eq. 40, normalised by 2 g and minus its ideal value) and the design matrix A."""
    g = ws.site.gravity
    Minv = np.linalg.inv(Ma_rough)
    L, A = [], []
    for k1, k2 in pairs:
        w1, w2 = ws.windows[k1], ws.windows[k2]
        tx, tz = w1.theta
        d = (Minv @ (w1.accel - w2.accel))[:2] / (2.0 * g)  # N25 eq. 40
        ideal = math.sin(tx) * np.array([math.sin(tz), math.cos(tz)])
        L.append(d - ideal)
        A.append(design_rows(tx, tz))
    return np.concatenate(L), np.vstack(A)


def rough_alpha0(ws: WindowSet) -> float | None:
    """N25 eq. 38 (sign from the model): ``tan a0 = -N_z(90, 0) / N_z(0, 0)``."""
    pos = positions(ws)
    if (0, 0) not in pos or (90, 0) not in pos:
        return None
    return math.atan2(-ws.windows[pos[(90, 0)]].accel[2], ws.windows[pos[(0, 0)]].accel[2])


def model_L(ws: WindowSet, pairs, X: np.ndarray) -> np.ndarray:
    """``L`` of N25 eq. 40 as the exact model (eq. 5-12) predicts it at ``X = [tan b0, a0, dth]``: the
    normalised difference of the gravity reactions at the two positions of each pair, minus its ideal value.
    ``model_L(ws, pairs, 0) = 0``; eq. 42's design matrix is its Jacobian at 0."""
    beta0, alpha0, dth = math.atan(X[0]), X[1], X[2]
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for k1, k2 in pairs:
        t1, t2 = ws.windows[k1].theta, ws.windows[k2].theta
        d = 0.5 * (C_n_s(*t1, dth, [alpha0, beta0, 0.0]) @ up - C_n_s(*t2, dth, [alpha0, beta0, 0.0]) @ up)[:2]
        out.append(d - math.sin(t1[0]) * np.array([math.sin(t1[1]), math.cos(t1[1])]))
    return np.concatenate(out)


#: Gauss-Newton iterations of the exact eq. 40 (each one gains the square of the small angles)
EXACT_ITER = 20


def exact_X(ws: WindowSet, pairs, Ma: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``X`` with the exact model's ``L`` (:func:`model_L`) equal to the measured one in the least-squares sense:
    eq. 44 is its first Gauss-Newton step from 0 (the design matrix of eq. 42 as the Jacobian), which leaves
    errors of second order in the angles (a mount tilt of 1 deg biased alpha0 by 0.4"); the iteration removes them."""
    L, A = L_vector(ws, pairs, Ma)
    for _ in range(EXACT_ITER):
        dX, *_ = np.linalg.lstsq(A, L - model_L(ws, pairs, X), rcond=None)
        X = X + dX
        if np.max(np.abs(dX)) < 1e-15:
            break
    return X


def solve_X(ws: WindowSet, idx: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps 1-2: rough twelve-position calibration and the eq. 44 least squares."""
    Ma0, _ = accel_twelve(ws, idx)
    L, A = L_vector(ws, inner_pairs(ws, idx), Ma0)
    X, *_ = np.linalg.lstsq(A, L, rcond=None)  # N25 eq. 44
    return X, L, A


def heading_from_earth_rate(wb: np.ndarray, alpha0: float, beta0: float) -> float:
    """``gamma0`` from the Earth rate in the base frame: ``R_z(g0) R_y(b0) R_x(a0) w^b = w_ie^n``
    has a zero East component."""
    v = rot_y(beta0) @ rot_x(alpha0) @ wb
    return math.atan2(v[0], v[1])


#: fixed-point passes of steps 2-3 when the positions are not the twelve N25 ones
MAX_REFINE = 8


def _refined_accel(ws: WindowSet, idx: list[int], X: np.ndarray):
    """Step 3: the eq. 19 least squares with the model inputs at X = [tan b0, a0, dth]."""
    beta0, alpha0, dth = math.atan(X[0]), X[1], X[2]
    g = ws.site.gravity
    F = np.array([C_n_s(*ws.windows[k].theta, dth, [alpha0, beta0, 0.0]) @ np.array([0.0, 0.0, g]) for k in idx])
    N = np.array([ws.windows[k].accel for k in idx])
    return accel_least_squares(N, F)


def _core(ws: WindowSet, idx: list[int]):
    X, _, _ = solve_X(ws, idx)
    # step 3: refined accelerometer errors with the model inputs (eq. 19 with true inputs)
    Ma, nabla = _refined_accel(ws, idx, X)
    # Without the full inner-symmetric set the rough (ideal-input) calibration of step 1 keeps the leveling
    # error to first order (N25 eq. 24-26 cancel it only over all twelve), which biases step 2 (on the N25 path
    # less the (90, 0)/(90, 180) pair: beta0 off by 68", dth by 0.3"); with all twelve, eq. 42's linearisation
    # leaves errors of second order in the angles (alpha0 off by 0.4" at a 1 deg mount tilt).  Beyond the paper:
    # step 2 with the refined M_a and the exact eq. 40 (exact_X), then step 3 at the new X, until X settles.
    pairs = inner_pairs(ws, idx)
    for _ in range(MAX_REFINE):
        X_new = exact_X(ws, pairs, Ma, X)
        Ma, nabla = _refined_accel(ws, idx, X_new)
        done = np.max(np.abs(X_new - X)) < 1e-12
        X = X_new
        if done:
            break
    beta0, alpha0, dth = math.atan(X[0]), X[1], X[2]
    # step 4: gyro matrix from rate tests about the true turning axes, then eps and w^b
    Mg, used_rate = gyro_matrix_from_rate_tests(ws, dth=dth, ideal=False)
    rows, rhs = [], []
    for k in idx:
        C = C_b_s(*ws.windows[k].theta, dth)
        rows.append(np.hstack([Mg @ C, np.eye(3)]))
        rhs.append(ws.windows[k].gyro)
    sol, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    wb, eps = sol[:3], sol[3:]
    gamma0 = heading_from_earth_rate(wb, alpha0, beta0)
    vals = values_from_matrices(Ma, nabla, Mg, eps)
    vals["gimbal_nonorthogonality"] = dth
    vals["mount_attitude"] = np.array([alpha0, beta0, gamma0])
    return vals, used_rate, X, wb


def symmetric_windows(ws: WindowSet) -> list[int]:
    """The static windows the n25 steps use: the first visit of every nominal position
    (multiples of 90 deg) whose inner-symmetric partner (theta_z + 180 deg) was also visited,
    the twelve N25 positions first, in N25 order.  What the method truly needs, each checked
    here with one clear error naming what is missing: pairs whose design rows (eq. 42) give
    rank 3 for [tan b0, a0, dth], and positions spanning the three accelerometer axes and
    the bias (eq. 19).  (The gyro step's CW/CCW rate tests are checked where they are used.)"""
    pos = positions(ws)
    paired = [p for p in pos if (p[0], (p[1] + 180) % 360) in pos]
    order = [p for p in TWELVE if p in paired] + sorted(p for p in paired if p not in TWELVE)
    idx = [pos[p] for p in order]
    missing = [p for p in TWELVE if p not in pos]
    hint = ("; missing N25 positions (theta_x, theta_z) deg: " + ", ".join(f"({a}, {b})" for a, b in missing)
            if missing else "")
    pairs = inner_pairs(ws, idx)
    A = np.vstack([design_rows(*ws.windows[k1].theta) for k1, _ in pairs]) if pairs else np.zeros((0, 3))
    if np.linalg.matrix_rank(A, tol=1e-6) < 3:
        have = ", ".join(f"({a}, {b})/({a}, {(b + 180) % 360})" for a, b in
                         sorted({min(p, (p[0], (p[1] + 180) % 360)) for p in paired})) or "none"
        raise CalibrationError(
            "n25 calibration needs static windows in inner-symmetric pairs ((theta_x, theta_z) and (theta_x, theta_z + 180) "
            "deg) that separate tan(beta0), alpha0 and dth (N25 eq. 40-44): at least one pair with theta_x = 0 or 180 and "
            f"pairs at theta_x = 90 or 270 with theta_z both along and across the outer axis; pairs found: {have}{hint}")
    F = np.array([np.round(ideal_up(*ws.windows[k].theta)) for k in idx])
    if np.linalg.matrix_rank(np.vstack([F.T, np.ones(len(idx))])) < 4:
        raise CalibrationError("n25 calibration: the inner-symmetric positions do not point every accelerometer axis up "
                               f"and down (rank-deficient eq. 19){hint}")
    return idx


def n25(ws: WindowSet, uncertainty: bool = True, max_alpha0: float = 2.0 * DEG) -> CalibrationResult:
    """Scheme 1 of N25: the IMU errors with the gimbal non-orthogonality and the mount attitude.

    A rough alpha0 (eq. 38), the eq. 40-44 least squares for [tan beta0, alpha0, dth], then the
    accelerometer and gyro errors refined with them (see the module docstring).

    Parameters
    ----------
    ws : WindowSet
        The windows of a turntable record on the N25 path (:func:`window_means`).
    uncertainty : bool
        Propagate the windows' noise to the sigma.
    max_alpha0 : float
        The largest mount angle alpha0 accepted [rad].

    Returns
    -------
    CalibrationResult
        The N25 estimates (SI) of the IMU errors and the gimbal nonorthogonality, their 1 sigma and
        the parameters estimated.

    Raises
    ------
    CalibrationError
        Windows that do not hold the N25 positions, or a mount angle beyond ``max_alpha0``.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import n25, window_means
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("n25", np.random.default_rng(0), rate_hz=10.0)  # with its truth
    >>> res = n25(window_means(rec), uncertainty=False)  # no sigma: faster
    >>> from inscal.core.units import ARCSEC
    >>> round(rec.truth.gimbal.nonorthogonality / ARCSEC, 1), round(res.gimbal.nonorthogonality / ARCSEC, 1)
    (20.0, 20.0)
    """
    idx = symmetric_windows(ws)
    a0 = rough_alpha0(ws)
    if a0 is not None and abs(a0) > max_alpha0:
        raise CalibrationError(
            f"rough roll alpha0 = {math.degrees(a0):.3f} deg (N25 eq. 38) exceeds {math.degrees(max_alpha0):g} deg: "
            "the linearised n25 step needs the outer gimbal near level; turn the outer axis zero or use --method joint")
    vals, used_rate, X, wb = _core(ws, idx)

    def est(w2):
        return flatten(*errors_from_values(_core(w2, idx)[0]), NAMES)

    used = {k: (True, True) for k in idx}
    used.update({k: (True, False) for k in used_rate})
    imu, gim = errors_from_values(vals)
    S = comp = A = None
    if uncertainty:
        S, comp = sensitivity(est, ws, used, flatten(imu, gim, NAMES))
        A = estimator_reference(imu, gim, ws, S, comp, list(range(nparams(NAMES))))
    fit = fit_statistics(imu, gim, ws, nparams(NAMES), A=A, diagnose=uncertainty)
    sig, formal = finish_sigma(S, comp, fit, NAMES, len(ws.windows))
    diag = {"positions": [list(nominal_position(ws.windows[k])) for k in idx], "rough_alpha0_rad": a0, "X": X.tolist(), "earth_rate_b": wb.tolist(),
            "earth_rate_norm_ratio": float(np.linalg.norm(wb) / np.linalg.norm(ws.site.earth_rate_n)),
            "n_rate_windows": len(used_rate), "fit": fit, "formal_sigma": formal}
    return make_result("n25", vals, sig, NAMES, ws, diag,
                       ([fit["note"]] if fit["note"] else [])
                       + ["N25 scheme 1: linearised [tan b0, a0, dth] step (eq. 40-44, design matrix derived from the "
                          "model), refined accelerometer and gyro errors; heading gamma0 from the Earth rate"])
