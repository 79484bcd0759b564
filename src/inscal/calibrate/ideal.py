"""What the ideal-input schemes (six- and twelve-position) share once their equations are solved:
the heading fit, the result with its sigma, and the note on the error a gimbal model would remove."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from inscal.calibrate.fit import (
    estimator_reference,
    finish_sigma,
    fit_note,
    fit_statistics,
    normalised_residuals,
    remove_geometry,
    sensitivity,
)
from inscal.calibrate.joint import joint
from inscal.calibrate.positions import predicted_scheme_errors, rate_test_groups
from inscal.calibrate.result import IMU_LINEAR, CalibrationResult, errors_from_values, flatten, make_result, nparams, unflatten
from inscal.calibrate.window_model import predict
from inscal.calibrate.windows import CalibrationError, WindowSet
from inscal.core.error_model import GimbalErrors
from inscal.core.units import DEG, from_si


def fit_heading(imu, ws: WindowSet) -> float:
    """The heading ``gamma0`` that best fits the window means for the given IMU errors on a
    level, orthogonal turntable (a nuisance of the ideal-input schemes).  The predicted means
    are exactly ``P0 + cos(g0) Pc + sin(g0) Ps`` there (``C_n^b = R_z(g0)^T``), so chi^2 is
    minimised on a 0.1 deg grid of that form, then refined (bounded 1-D search)."""

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
    imu, _ = errors_from_values(vals)
    g0 = fit_heading(imu, ws)
    gim = GimbalErrors(0.0, [0.0, 0.0, g0])
    S = comp = A = None
    if uncertainty:
        S, comp = sensitivity(est, ws, used, flatten(imu, GimbalErrors(), IMU_LINEAR))
        A = estimator_reference(imu, gim, ws, S, comp, list(range(24)), nuisance=[27])
    fit = fit_statistics(imu, gim, ws, nparams(IMU_LINEAR) + 1, model_columns=list(range(24)) + [27], geometry=True,
                         A=A, diagnose=uncertainty)
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
