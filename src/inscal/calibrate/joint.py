"""Joint calibration (beyond N25): one nonlinear least-squares fit of every IMU error of the
linear N25 model (eq. 1-4), the gimbal non-orthogonality dth and the mounting attitude
[alpha0, beta0, gamma0] to the means of every static and constant-rate window at once,
with the exact forward model of :mod:`.window_model` (no small-angle approximation).

* Residuals: (predicted - measured) window means divided by their measured 1-sigma noise
  (floored at 1e-6 deg/h and 1e-6 ug so noise-free data stay well conditioned).
* Internal parameters (28): K_g, E_g, eps / w_ie, K_a, E_a, nabla / g, dth, alpha0, beta0,
  gamma0; Jacobian analytic in the IMU errors (the model is linear in them) and by
  central differences in the four angles.
* Observability: the singular values of the column-normalised weighted Jacobian at the
  start point (angles below 1e-3 rad moved to 1e-3 rad so that an exactly level start
  does not hide what a real tilt reveals).  A direction with relative singular value
  below ``sv_tol`` is reported (as the parameter combination) and one parameter of it is
  held at its start value (zero unless given in ``fix``): the IMU error with the largest
  weight among those within a factor 2 of the largest, else the largest; see
  ``result.diagnostics["unobservable"]`` and ``result.notes``.
* 1 sigma: ``sqrt(diag((J^T J)^-1))`` of the weighted Jacobian at the solution (the
  measured window noise) while the fit is consistent.  The fit (chi^2, dof, p, per-window
  residuals, ``diagnostics["fit"]``, :func:`.fit.fit_statistics`) is always reported;
  when it is inconsistent (p < 0.001) the likely cause is named in a note and the sigma are
  scaled for the misfit (:data:`.result.SIGMA_RULE`; the formal ones stay in
  ``diagnostics["formal_sigma"]``).  A misfit is systematic (unmodelled terms), so the
  scaling uses the sensitivity ``S = (J^T J)^-1 J^T`` of every estimate to every residual:
  ``sum_j |S_ij| s_c``, not only ``sqrt(chi2/dof)`` times the formal sigma (which on the
  ``s16`` record leaves the accelerometer biases at 3.5-4.6 sigma).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from inscal.calibrate.fit import fit_statistics, scaled_sigma
from inscal.calibrate.n25 import n25
from inscal.calibrate.result import CalibrationResult, make_result
from inscal.calibrate.window_model import (
    NAMES,
    NP,
    WindowModel,
    component_label,
    parse_component,
)
from inscal.calibrate.windows import CalibrationError, WindowSet
from inscal.core.error_model import GimbalErrors, ImuErrors


def _initial(ws: WindowSet) -> tuple[np.ndarray, str]:
    """Start point: the n25 estimate when the record allows it, else zeros."""

    try:
        r = n25(ws, uncertainty=False)
    except CalibrationError as exc:
        return np.zeros(NP), f"zeros (n25 start not available: {exc})"
    x = np.concatenate([r.imu.gyro_scale_factor, r.imu.gyro_misalignment, r.imu.gyro_bias, r.imu.accel_scale_factor,
                        r.imu.accel_misalignment, r.imu.accel_bias, [r.gimbal.nonorthogonality], r.gimbal.mount_attitude])
    return x, "n25"


def observability(J: np.ndarray, free: np.ndarray, sv_tol: float) -> list[dict]:
    """Unobservable directions of the free columns of J (column-normalised SVD)."""
    Jf = J[:, free]
    norms = np.linalg.norm(Jf, axis=0)
    out = []
    zero = norms <= 1e-300
    for i in np.flatnonzero(zero):
        out.append({"combination": {component_label(int(free[i])): 1.0}, "relative_singular_value": 0.0,
                    "fixed": component_label(int(free[i])), "index": int(free[i])})
    keep = ~zero
    if keep.sum() == 0:
        return out
    Jn = Jf[:, keep] / norms[keep]
    _, s, Vt = np.linalg.svd(Jn, full_matrices=False)
    rel = s / s[0]
    cols = free[keep]
    for r, v in zip(rel, Vt):
        if r < sv_tol:
            order = np.argsort(-np.abs(v))
            comb = {component_label(int(cols[i])): round(float(v[i]), 4) for i in order[:4] if abs(v[i]) > 0.05}
            # hold an IMU error (a nuisance of the scheme) rather than the gimbal geometry when both
            # carry the direction comparably
            big = [i for i in order if abs(v[i]) >= 0.5 * abs(v[order[0]])]
            imu = [i for i in big if cols[i] < 24]
            i_fix = int(cols[imu[0] if imu else order[0]])
            out.append({"combination": comb, "relative_singular_value": float(r), "fixed": component_label(i_fix),
                        "index": i_fix})
    return out


def joint(ws: WindowSet, uncertainty: bool = True, fix: dict | None = None, initial=None,
          sv_tol: float = 1e-7) -> CalibrationResult:
    """Fit every IMU error, the non-orthogonality and the mount attitude jointly to all windows.

    One nonlinear least-squares fit; 1 sigma from the Jacobian and the measured window noise;
    unobservable directions are reported and held fixed (see the module docstring).

    Parameters
    ----------
    ws : WindowSet
        The windows of a turntable record (:func:`window_means`).
    uncertainty : bool
        Compute the sigma.
    fix : dict, optional
        ``{"NAME" or "NAME[comp]": value_SI}`` held fixed (a prior).
    initial : tuple of (ImuErrors, GimbalErrors), optional
        The start point (default: the ``n25`` estimate).
    sv_tol : float
        The relative singular value below which a direction is unobservable.

    Returns
    -------
    CalibrationResult
        The IMU and gimbal errors of the joint least squares (SI), their 1 sigma and the parameters
        estimated; the unobservable directions it held are in ``diagnostics`` and ``notes``.

    Raises
    ------
    CalibrationError
        An unknown parameter in ``fix``, or too few windows.

    Examples
    --------
    >>> from numpy.random import default_rng
    >>> from inscal.calibrate import joint, window_means
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("n25", default_rng(0), rate_hz=10.0)  # with its truth
    >>> ws = window_means(rec)
    >>> res = joint(ws)
    >>> true = rec.truth.gimbal.nonorthogonality
    >>> z = (res.gimbal.nonorthogonality - true) / res.sigma["gimbal_nonorthogonality"]
    >>> bool(abs(z) < 3)
    True
    """
    if len(ws.windows) < 5:
        raise CalibrationError(f"joint calibration needs at least 5 windows, found {len(ws.windows)}")
    model = WindowModel(ws)
    if initial is not None:
        imu0, gim0 = initial
        x0 = np.concatenate([imu0.gyro_scale_factor, imu0.gyro_misalignment, imu0.gyro_bias, imu0.accel_scale_factor,
                             imu0.accel_misalignment, imu0.accel_bias, [gim0.nonorthogonality], gim0.mount_attitude])
        start = "given"
    else:
        x0, start = _initial(ws)
    free = np.ones(NP, bool)
    notes = []
    for key, val in (fix or {}).items():
        for i in parse_component(key):
            free[i] = False
            x0[i] = float(np.ravel(val)[0]) if np.ndim(val) == 0 or len(np.ravel(val)) == 1 else float(
                np.ravel(val)[parse_component(key).index(i)])
        notes.append(f"{key} held fixed at the given value")
    p0 = model.from_si(x0)
    # structural observability at a generic point near the start: exactly zero angles would
    # hide parameters that the tilt of a real mount makes (weakly) observable
    xg = x0.copy()
    xg[24] += 1e-4 if abs(xg[24]) < 1e-4 else 0.0
    xg[25:27] += np.where(np.abs(xg[25:27]) < 1e-3, 1e-3, 0.0)
    pg = model.from_si(xg)
    unobs = []
    for _ in range(NP):
        found = observability(model.jacobian(pg), np.flatnonzero(free), sv_tol)
        if not found:
            break
        d = found[0]
        free[d["index"]] = False
        unobs.append(d)
        comb = " + ".join(f"{c:+g}*{k}" for k, c in d["combination"].items())
        notes.append(f"unobservable direction ({comb}, relative singular value {d['relative_singular_value']:.1e}): "
                     f"{d['fixed']} held at its start value {x0[d['index']]:.3e} (SI)")
    fi = np.flatnonzero(free)
    if fi.size == 0:
        raise CalibrationError("no observable parameter in this record")

    def fun(q):
        p = p0.copy()
        p[fi] = q
        return model.residual(p)

    def jac(q):
        p = p0.copy()
        p[fi] = q
        return model.jacobian(p)[:, fi]

    sol = least_squares(fun, p0[fi], jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200,
                        x_scale="jac")
    p = p0.copy()
    p[fi] = sol.x
    x = model.to_si(p)
    chi2 = float(np.sum(sol.fun ** 2))
    dof = max(1, sol.fun.size - fi.size)
    kg, eg, eps, ka, ea, nab, dth, mount = model.unpack(x)
    imu_hat = ImuErrors(gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=eps, accel_scale_factor=ka,
                        accel_misalignment=ea, accel_bias=nab)
    gim_hat = GimbalErrors(float(dth), np.array(mount))
    fit = fit_statistics(imu_hat, gim_hat, ws, fi.size, model_columns=list(fi), diagnose=uncertainty)
    S = idx = None
    if uncertainty:
        J = model.jacobian(p)[:, fi]
        try:
            cov = np.linalg.inv(J.T @ J)
            Sf = (cov @ J.T) * model.scale[fi][:, None]  # d x_i / d residual_j (residuals in sigma units)
            S = np.full((NP, J.shape[0]), 0.0)
            S[fi] = Sf
            idx = np.arange(J.shape[0])  # residual order of WindowModel: gyro (window-major), then accelerometer
        except np.linalg.LinAlgError:
            notes.append("Jacobian singular at the solution: no uncertainties")
    if S is not None:
        sig_full = scaled_sigma(S, idx, fit, len(ws.windows))
        formal_full = np.sqrt(np.sum(S ** 2, axis=1))
        sig_full[~free] = np.nan
        formal_full[~free] = np.nan
    else:
        sig_full = np.full(NP, np.nan)
        formal_full = np.full(NP, np.nan)
    vals = {"gyro_scale_factor": kg, "gyro_misalignment": eg, "gyro_bias": eps, "accel_scale_factor": ka,
            "accel_misalignment": ea, "accel_bias": nab, "gimbal_nonorthogonality": float(dth),
            "mount_attitude": np.array(mount)}

    def by_name(v):
        k = model.unpack(v)
        return dict(zip(NAMES, [k[0], k[1], k[2], k[3], k[4], k[5], np.array(k[6]), k[7]]))

    sigma, formal = by_name(sig_full), by_name(formal_full)
    # report gamma0 within (-pi, pi]
    vals["mount_attitude"][2] = math.remainder(vals["mount_attitude"][2], 2 * math.pi)
    diag = {"start": start, "status": int(sol.status), "message": sol.message, "nfev": int(sol.nfev),
            "chi2": chi2, "dof": int(dof), "unobservable": [{k: v for k, v in d.items() if k != "index"} for d in unobs],
            "n_windows": len(ws.windows), "fit": fit, "formal_sigma": formal}
    if not sol.success:
        notes.append(f"least squares did not converge: {sol.message}")
    return make_result("joint", vals, sigma, NAMES, ws, diag,
                       ([fit["note"]] if fit["note"] else [])
                       + ["joint nonlinear least squares of all window means (exact model)"] + notes)
