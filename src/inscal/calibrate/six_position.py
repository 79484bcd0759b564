"""Classical discrete calibration (N25 section 3.1, scheme 2): six-position accelerometer
least squares (eq. 15-19), gyro bias from the Earth rate with each gyro axis up and down,
gyro scale factors and installation angles from clockwise/counter-clockwise rate tests
(eq. 28).  The turntable is assumed level and orthogonal (ideal inputs): this is the
scheme whose leveling and non-orthogonality errors N25 eq. 21-23 and 29 describe.

The helpers here (position matching, the eq. 19 least squares, the eq. 28 rate-test
solution, the fit of an ideal-input scheme) are shared with the twelve-position and n25
methods.

Fit: the estimated IMU errors predict every window mean through the exact model
(:func:`.model.predict`) for the turntable the scheme assumes (level, orthogonal), with the
heading ``gamma0`` (which the scheme does not need) fitted as a nuisance; chi^2, dof
(window-mean components minus 24 IMU errors minus the heading) and p are in
``diagnostics["fit"]``.  When the fit is inconsistent the note names the likely cause and
adds the scheme's known error (N25 eq. 21-23, 29: :func:`predicted_scheme_errors`) for
the tilt and non-orthogonality of this record, taken from a joint fit of the same windows.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import GimbalErrors, off_diagonal_angles, split_scale_misalignment
from ..units import from_si
from .model import _rz, ideal_up, outer_axis
from .result import (IMU_LINEAR, CalibrationResult, estimator_reference, finish_sigma, fit_note, fit_statistics,
                     flatten, make_result, nparams, normalised_residuals, remove_geometry, sensitivity, unflatten)
from .segment import CalibrationError, Window, WindowSet

DEG = math.pi / 180.0
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
    return _rz(math.radians(fixed_deg)).T @ outer_axis(dth)


def gyro_matrix_from_rate_tests(ws: WindowSet, dth: float = 0.0, ideal: bool = True) -> tuple[np.ndarray, list[int]]:
    """``M_g`` from CW/CCW rate tests: ``M_g a = (N+ - N-) / (w+ - w-)`` for each turning
    axis ``a`` (N25 eq. 28, with the minus sign the extraction lost), solved by least
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


def _need_orientations(ws: WindowSet, pos: dict) -> dict[str, int]:
    """For each of the six orientations, the index of its first static window."""
    by: dict[str, int] = {}
    for p, k in sorted(pos.items(), key=lambda q: q[1]):
        by.setdefault(orientation(p), k)
    missing = [o for o in ("+x", "-x", "+y", "-y", "+z", "-z") if o not in by]
    if missing:
        words = ", ".join(f"{o[1]} axis {'up' if o[0] == '+' else 'down'}" for o in missing)
        raise CalibrationError(f"six-position calibration needs a static window with each IMU axis up and down; "
                               f"missing: {words} (found {len(by)} of 6 orientations)")
    return by


def _six_core(ws: WindowSet, sel: dict[str, int]):
    g = ws.site.gravity
    order = ("+x", "-x", "+y", "-y", "+z", "-z")
    idx = [sel[o] for o in order]
    N = np.array([ws.windows[k].accel for k in idx])
    F = np.array([g * ideal_up(*ws.windows[k].theta) for k in idx])  # N25 eq. 17 (ideal inputs)
    F = np.round(F / g) * g
    Ma, nabla = accel_least_squares(N, F)  # N25 eq. 19
    # gyro bias from the Earth rate: axis j vertical up and down (its horizontal input is zero)
    eps = np.array([0.5 * (ws.windows[sel["+" + a]].gyro[j] + ws.windows[sel["-" + a]].gyro[j])
                    for j, a in enumerate(AXIS_NAMES)])
    Mg, used_rate = gyro_matrix_from_rate_tests(ws, ideal=True)  # N25 eq. 28
    return Ma, nabla, Mg, eps, used_rate


def _values(Ma, nabla, Mg, eps) -> dict:
    ka, ea = split_scale_misalignment(Ma)
    kg, eg = split_scale_misalignment(Mg)
    return {"gyro_scale_factor": kg, "gyro_misalignment": eg, "gyro_bias": eps,
            "accel_scale_factor": ka, "accel_misalignment": ea, "accel_bias": nabla}


def six_position(ws: WindowSet, uncertainty: bool = True) -> CalibrationResult:
    """Scheme 2 of N25: six-position accelerometer LS, Earth-rate gyro bias, rate tests."""
    pos = positions(ws)
    sel = _need_orientations(ws, pos)
    Ma, nabla, Mg, eps, used_rate = _six_core(ws, sel)
    vals = _values(Ma, nabla, Mg, eps)

    def est(w2):
        return flatten(*_imu_gim(_values(*_six_core(w2, sel)[:4])), IMU_LINEAR)

    used = {k: (True, True) for k in sel.values()}
    used.update({k: (True, False) for k in used_rate})
    static_used = [ws.windows[k] for k in sel.values()]
    return finish_ideal("six-position", ws, vals, est, used, static_used, uncertainty,
                        {"positions": {o: list(nominal_position(ws.windows[k])) for o, k in sel.items()},
                         "n_rate_windows": len(used_rate)},
                        ["ideal inputs: turntable assumed level and orthogonal (N25 scheme 2); "
                         "gimbal non-orthogonality and mount attitude not estimated"], "N25 eq. 21-23, 29")


def fit_heading(imu, ws: WindowSet) -> float:
    """The heading ``gamma0`` that best fits the window means for the given IMU errors on a
    level, orthogonal turntable (a nuisance of the ideal-input schemes).  The predicted means
    are exactly ``P0 + cos(g0) Pc + sin(g0) Ps`` there (``C_n^b = R_z(g0)^T``), so chi^2 is
    minimised on a 0.1 deg grid of that form, then refined (bounded 1-D search)."""
    from scipy.optimize import minimize_scalar

    def res(g0):
        rg, ra = normalised_residuals(imu, GimbalErrors(0.0, [0.0, 0.0, g0]), ws)
        return np.concatenate([rg.ravel(), ra.ravel()])

    r0p, r90, r180 = res(0.0), res(0.5 * math.pi), res(math.pi)
    r0, rc = 0.5 * (r0p + r180), 0.5 * (r0p - r180)
    rs = r90 - r0

    def chi2(g0):
        g0 = np.atleast_1d(g0)
        r = r0[None, :] + np.cos(g0)[:, None] * rc[None, :] + np.sin(g0)[:, None] * rs[None, :]
        return np.sum(r * r, axis=1)

    grid = np.radians(np.arange(-180.0, 180.0, 0.1))
    g0 = grid[int(np.argmin(chi2(grid)))]
    r = minimize_scalar(lambda g: float(chi2(g)[0]), bounds=(g0 - 0.1 * DEG, g0 + 0.1 * DEG), method="bounded",
                        options={"xatol": 1e-10})
    return math.remainder(float(r.x), 2 * math.pi)


def finish_ideal(method: str, ws: WindowSet, vals: dict, est, used: dict, static_used: list, uncertainty: bool,
                 diag: dict, notes: list[str], equations: str) -> CalibrationResult:
    """Fit, sigma and notes of an ideal-input scheme (six- and twelve-position)."""
    imu, _ = _imu_gim(vals)
    g0 = fit_heading(imu, ws)
    gim = GimbalErrors(0.0, [0.0, 0.0, g0])
    S = comp = A = None
    if uncertainty:
        S, comp = sensitivity(est, ws, used, flatten(imu, GimbalErrors(), IMU_LINEAR))
        A = estimator_reference(imu, gim, ws, S, comp, list(range(24)), nuisance=[27])
    fit = fit_statistics(imu, gim, ws, nparams(IMU_LINEAR) + 1, model_columns=list(range(24)) + [27], geometry=True,
                         A=A)
    fit["nuisance"] = {"gamma0_rad": g0}
    sig, formal = finish_sigma(S, comp, fit, IMU_LINEAR, len(ws.windows))
    diag.update(fit=fit, formal_sigma=formal)
    if not fit["consistent"]:
        groups = [(ax, f) for ax, f, _, _ in rate_test_groups(ws)]
        if uncertainty:
            text, exact = scheme_error_note(ws, static_used, groups, equations, diag, est)
        else:  # no sigma asked for: the joint fit behind the scheme error is skipped (Monte Carlo studies)
            text, exact = f"known scheme error ({equations}) not evaluated (uncertainty=False)", None
        extra = "; " + text
        if exact is not None:
            if fit["cause"].startswith("turntable"):
                # the geometry explains the misfit, and its effect on these estimates is the scheme error:
                # only the misfit the geometry leaves scales sigma further
                remove_geometry(fit, imu, gim, ws, list(range(24)) + [27])
                sig, _ = finish_sigma(S, comp, fit, IMU_LINEAR, len(ws.windows))
            if uncertainty:
                # a known systematic error of the estimates, added to the statistical sigma (linearly: the error is
                # that systematic plus the noise)
                sig = unflatten(flatten_sigma(sig) + np.abs(exact), IMU_LINEAR)
                extra += ("; sigma = statistical sigma + |scheme error to all orders| (the scheme run on the exact "
                          "means of that fit)")
        notes = [fit_note(fit, extra)] + notes
    return make_result(method, vals, sig, IMU_LINEAR, ws, diag, notes)


def flatten_sigma(sig: dict) -> np.ndarray:
    return np.concatenate([np.atleast_1d(np.asarray(sig[n], float)).ravel() for n in IMU_LINEAR])


def scheme_error_note(ws: WindowSet, static_used: list, rate_axes: list, equations: str, diag: dict,
                      est=None) -> tuple[str, np.ndarray | None]:
    """The known error of an ideal-input scheme for the tilt and non-orthogonality of this
    record, from a joint fit of the same windows: the first-order prediction
    (``predicted_scheme_errors``, N25 eq. 21-26, 29) in words, and the error to all orders
    (``est`` run on the exact model's means for the joint estimates, minus them; flat, SI,
    :data:`IMU_LINEAR` order; None without ``est`` or a joint fit)."""
    from .joint import joint
    from .model import predict

    try:
        ref = joint(ws, uncertainty=False)
    except CalibrationError as exc:
        return f"known scheme error ({equations}) not predicted: no joint fit of this record ({exc})", None
    a0, b0, _ = ref.gimbal.mount_attitude
    dth = ref.gimbal.nonorthogonality
    pred = predicted_scheme_errors(static_used, ws.site.gravity, a0, b0, dth, rate_axes)
    exact = None
    if est is not None:
        exact = est(ws.replace_means(*predict(ref.imu, ref.gimbal, ws))) - flatten(ref.imu, ref.gimbal, IMU_LINEAR)
    diag["predicted_scheme_error"] = {"alpha0_rad": float(a0), "beta0_rad": float(b0), "dtheta_rad": float(dth),
                                      "first_order": {k: np.asarray(v).tolist() for k, v in pred.items()},
                                      "all_orders": None if exact is None else unflatten(exact, IMU_LINEAR)}
    asec = lambda v: float(from_si(v, "arcsec"))  # noqa: E731
    bz = float(from_si(pred["accel_bias"][2], "ug"))
    return (f"known scheme error ({equations}, first order) for the tilt alpha0 = {asec(a0):.1f}\", "
            f"beta0 = {asec(b0):.1f}\" and dtheta = {asec(dth):.1f}\" of a joint fit of this record: z accelerometer "
            f"bias {bz:+.1f} ug, accelerometer installation angles up to "
            f"{asec(np.max(np.abs(pred['accel_misalignment']))):.1f}\", gyro installation angles up to "
            f"{asec(np.max(np.abs(pred['gyro_misalignment']))):.1f}\""), exact


def _imu_gim(vals: dict):
    from ..errors import GimbalErrors, ImuErrors
    from ..errors import PARAMETERS as P

    return ImuErrors(**{P[n][1]: v for n, v in vals.items() if P[n][0] == "imu"}), GimbalErrors(
        **{P[n][1]: v for n, v in vals.items() if P[n][0] == "gimbal"})


def leveling_deviation(theta_x: float, theta_z: float, alpha0: float, beta0: float, dth: float) -> np.ndarray:
    """First-order deviation of the unit up vector in the s-frame from its ideal value
    (generalises N25 eq. 20 to any position)::

        dn = R_z(tz)^T [-b0 + (1 - cos tx) dth,  cos(tx) a0,  -sin(tx) a0]

    For tx = 180 deg this is eq. 20 with ``-b0 + 2 dth`` where N25 prints ``b0 + 2 dth``:
    the printed pitch has the opposite sign to the z-y-x Euler pitch of eq. 8 used here
    (the physics, checked against the exact model in tests/test_calibrate_schemes.py).
    """
    cx, sx = math.cos(theta_x), math.sin(theta_x)
    return _rz(theta_z).T @ np.array([-beta0 + (1.0 - cx) * dth, cx * alpha0, -sx * alpha0])


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
