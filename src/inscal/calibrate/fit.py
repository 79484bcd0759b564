"""Fit statistics of the window methods: the sensitivity of an estimator to the window means, the
chi-square of the normalised residuals, the likely cause of a misfit, and sigma scaled to the fit."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from inscal.calibrate.result import GIMBAL, IMU_LINEAR, flatten, nparams, unflatten
from inscal.calibrate.window_model import (
    ACCEL_FLOOR,
    GYRO_FLOOR,
    WindowModel,
    predict,
    window_inputs,
)
from inscal.calibrate.windows import WindowSet
from inscal.core.attitude import rot_z
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.core.stats import chi2_sf
from inscal.core.turntable import outer_axis


def sensitivity(estimator: Callable[[WindowSet], np.ndarray], ws: WindowSet, used: dict[int, tuple[bool, bool]],
                x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First-order response of ``estimator(ws)`` (a flat vector) to the noise of the window
    means it reads, by one-sided differences (the estimators are linear in the means up to
    terms of second order in the small error angles).

    ``used[k] = (gyro, accel)``: which channels of window k the estimator reads.  Returns
    ``(S, idx)``: column j of ``S`` is ``d estimate / d mean_j * sigma_j`` for one
    component of one window mean, ``idx[j]`` its place among the 6n components (gyro
    ``3 k + c``, then accelerometer ``3 n + 3 k + c``; the order of :func:`normalised_residuals`).
    """
    G = np.array([w.gyro for w in ws.windows])
    A = np.array([w.accel for w in ws.windows])
    x0 = estimator(ws) if x0 is None else x0
    cols, idx = [], []
    n = len(ws.windows)
    for k, (ug, ua) in used.items():
        w = ws.windows[k]
        for ch, use, arr, sig, floor in ((0, ug, G, w.gyro_sigma, 1e-9), (1, ua, A, w.accel_sigma, 1e-6)):
            if not use:
                continue
            for c in range(3):
                if not sig[c] > 0:
                    continue
                h = max(sig[c], floor)
                arr[k, c] += h
                x1 = estimator(ws.replace_means(G, A))
                arr[k, c] -= h
                cols.append((x1 - x0) / h * sig[c])
                idx.append(3 * n * ch + 3 * k + c)
    S = np.array(cols).T if cols else np.zeros((x0.size, 0))
    return S, np.array(idx, dtype=int)


def propagate(estimator: Callable[[WindowSet], np.ndarray], ws: WindowSet, used: dict[int, tuple[bool, bool]],
              x0: np.ndarray | None = None) -> np.ndarray:
    """First-order standard deviations of ``estimator(ws)`` from the measured noise of the
    window means (see :func:`sensitivity`)."""
    S, _ = sensitivity(estimator, ws, used, x0)
    return np.sqrt(np.sum(S ** 2, axis=1))


# ----------------------------------------------------------------------------- fit statistics
#: a fit with p below this is reported as inconsistent and its sigma are scaled
P_INCONSISTENT = 1e-3
#: floors of the window-mean sigma (noise-free data stay well conditioned): 1e-6 deg/h, 1e-6 ug
CHANNELS = ("gyro", "accel")

#: how the reported 1 sigma follows from the fit (the text written with every result)
SIGMA_RULE = ("consistent fit: sigma = formal (measured window noise); inconsistent fit (p < 0.001): for each channel "
              "whose own fit is inconsistent the misfit is treated as systematic, sigma_i = sqrt(sum_consistent "
              "S_ij^2 + (sum_inconsistent |S_ij| s_c)^2) with S_ij = d x_i / d m_j * sigma_j and s_c = "
              "sqrt(chi2_c / expected_c) of that channel (the largest error a misfit of the observed size, of either "
              "sign in every window, can cause; >= the formal sigma times s_c); ideal-input schemes: s_c from the "
              "misfit left after the turntable tilt and non-orthogonality are fitted out, and their effect on the "
              "estimates (the known scheme error to all orders, for the tilt of a joint fit) is added to sigma")


def normalised_residuals(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet) -> tuple[np.ndarray, np.ndarray]:
    """``(predicted - measured) / sigma`` of every window mean, gyro and accelerometer (n, 3)
    each, with the exact forward model (:func:`.window_model.predict`) and the floored sigma."""

    Ng, Na = predict(imu, gimbal, ws)
    G = np.array([w.gyro for w in ws.windows])
    A = np.array([w.accel for w in ws.windows])
    sg = np.maximum(np.array([w.gyro_sigma for w in ws.windows]), GYRO_FLOOR)
    sa = np.maximum(np.array([w.accel_sigma for w in ws.windows]), ACCEL_FLOOR)
    return (Ng - G) / sg, (Na - A) / sa


def estimator_reference(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, S: np.ndarray, idx: np.ndarray,
                        columns: list[int], nuisance: list[int] = ()) -> np.ndarray:
    """``A`` with normalised residuals ``r = A n`` for window-mean noise ``n`` (unit
    variance) of an estimator that is linear in the means with sensitivity ``S`` (rows:
    the internal parameters ``columns`` of :data:`.joint.COMPONENTS`, SI; from
    :func:`sensitivity`) and least-squares ``nuisance`` parameters fitted after it:
    ``A = (I - P_nuisance)(I - J S)``.  For a least-squares estimator ``A`` is the residual
    projector and chi^2 has ``dof`` degrees of freedom; an estimator that is not least
    squares leaves more of the noise in the residuals (``tr A^T A >= dof``)."""

    m = WindowModel(ws)
    J = m.jacobian(m.from_si(flatten(imu, gimbal, IMU_LINEAR + GIMBAL))) / m.scale[None, :]
    N = J.shape[0]
    Sf = np.zeros((len(columns), N))
    Sf[:, idx] = S[:len(columns)]
    A = np.eye(N) - J[:, columns] @ Sf
    if len(nuisance):
        Jn = J[:, list(nuisance)] * m.scale[list(nuisance)][None, :]
        A = A - Jn @ np.linalg.lstsq(Jn, A, rcond=None)[0]
    return A


def _reference_p(chi2: float, A: np.ndarray | None, rows, dof: int) -> tuple[float, float, float]:
    """``(p, expected chi2, effective dof)``: chi2 distribution with ``dof`` when ``A`` is
    None, else the distribution of ``|A_rows n|^2`` by Satterthwaite's approximation
    ``c chi2_nu`` (same mean and variance)."""
    if A is None:
        return chi2_sf(chi2, dof), float(dof), float(dof)
    Ar = A[rows]
    E = float(np.sum(Ar ** 2))
    Q = float(np.sum((Ar @ Ar.T) ** 2))
    if E <= 0 or Q <= 0:
        return chi2_sf(chi2, dof), float(dof), float(dof)
    c, nu = Q / E, E * E / Q
    return chi2_sf(chi2 / c, nu), E, nu


def fit_statistics(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, n_params: int,
                   model_columns: list[int] | None = None, geometry: bool = False,
                   A: np.ndarray | None = None, diagnose: bool = True) -> dict:
    """The fit of a calibration: chi^2 of the predicted minus the measured window means
    (all windows, both channels, exact forward model) over their measured noise.

    ``n_params``: parameters fitted to the means (estimates and nuisances);
    ``model_columns``: the columns (indices of :data:`.joint.COMPONENTS`) the method
    estimates, used to name the likely cause of a misfit (what the fitted model cannot
    absorb); ``geometry``: the method assumes a level, orthogonal turntable (the tilt and
    non-orthogonality are candidate causes); ``A``: from :func:`estimator_reference` for an
    estimator that is not least squares (its chi^2 exceeds dof by the noise it leaves in the
    residuals; the p-value uses that reference distribution, ``expected_chi2`` and
    ``dof_effective`` report it); ``diagnose``: name the likely cause of a misfit (:func:`likely_cause`;
    False: "not diagnosed", for the runs of an estimator whose sigma nobody reads, e.g. the differences and the
    Monte Carlo of an uncertainty budget).  Returns the ``diagnostics["fit"]`` dict::

        chi2, dof (components - n_params), expected_chi2, dof_effective, p_value,
        consistent (p >= 0.001), scale (sqrt(chi2 / expected_chi2) if inconsistent else 1),
        channels: {gyro|accel: {chi2, dof, p_value, scale, systematic}},
        residuals: [{window, label, gyro, accel}] (RMS of the normalised residuals of each window),
        cause, cause_share, note (one line, or None when consistent)
    """
    rg, ra = normalised_residuals(imu, gimbal, ws)
    n = len(ws.windows)
    ncomp = 6 * n
    chi2 = float(np.sum(rg ** 2) + np.sum(ra ** 2))
    dof = max(1, ncomp - int(n_params))
    p, expected, nu = _reference_p(chi2, A, slice(None), dof)
    consistent = p >= P_INCONSISTENT
    chans = {}
    for c, (name, r) in enumerate(zip(CHANNELS, (rg, ra))):
        c2 = float(np.sum(r ** 2))
        d = max(1, int(round(r.size * dof / ncomp)))
        pc, ec, _ = _reference_p(c2, A, slice(3 * n * c, 3 * n * (c + 1)), d)
        chans[name] = {"chi2": c2, "dof": d, "expected_chi2": ec, "p_value": pc, "scale": 1.0, "systematic": False}
    if not consistent:
        bad = [c for c in CHANNELS if chans[c]["p_value"] < P_INCONSISTENT] or list(CHANNELS)
        for c in bad:
            chans[c]["scale"] = max(1.0, math.sqrt(chans[c]["chi2"] / chans[c]["expected_chi2"]))
            chans[c]["systematic"] = True
    res = [{"window": k, "label": w.describe(), "gyro": float(np.sqrt(np.mean(rg[k] ** 2))),
            "accel": float(np.sqrt(np.mean(ra[k] ** 2)))} for k, w in enumerate(ws.windows)]
    fit = {"chi2": chi2, "dof": int(dof), "expected_chi2": expected, "dof_effective": nu, "p_value": p,
           "consistent": bool(consistent), "scale": 1.0 if consistent else math.sqrt(chi2 / expected),
           "channels": chans, "residuals": res,
           "cause": None, "cause_share": None, "note": None, "sigma_rule": SIGMA_RULE}
    if not consistent:
        cause, share = likely_cause(imu, gimbal, ws, rg, ra, model_columns, geometry) if diagnose else \
            ("not diagnosed (no uncertainty asked for)", None)
        fit["cause"], fit["cause_share"] = cause, share
        fit_note(fit)
    return fit


def fit_note(fit: dict, extra: str = "") -> str:
    """(Re)build the one-line note of an inconsistent fit from its current numbers."""
    ch = fit["channels"]
    exp_txt = "" if fit["expected_chi2"] == fit["dof"] else f", {fit['expected_chi2']:.4g} expected"
    scales = ", ".join(f"{c} x{ch[c]['scale']:.3g}" for c in CHANNELS if ch[c]["systematic"])
    how = (f"scaled for the misfit (systematic rule: {scales})" if scales
           else "not scaled (the misfit this cause leaves is within the noise)")
    fit["note"] = (f"fit inconsistent: chi2 = {fit['chi2']:.4g} on {fit['dof']} dof{exp_txt} "
                   f"(p = {fit['p_value']:.2g}, "
                   f"sqrt(chi2/{'dof' if not exp_txt else 'expected'}) = {fit['scale']:.3g}); likely cause: "
                   f"{fit['cause']}; sigma {how}{extra}; "
                   "formal sigma kept")
    return fit["note"]


def remove_geometry(fit: dict, imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, model_columns: list[int]) -> None:
    """For an ideal-input scheme: the channel scales from the misfit left once the turntable
    tilt and non-orthogonality (columns 24-26 of :data:`.joint.COMPONENTS`) are fitted out
    with the model.  Their effect on the estimates is the scheme's known error, which the
    caller accounts for (N25 eq. 21-26, 29)."""

    rg, ra = normalised_residuals(imu, gimbal, ws)
    r = np.concatenate([rg.ravel(), ra.ravel()])
    m = WindowModel(ws)
    J = m.jacobian(m.from_si(flatten(imu, gimbal, IMU_LINEAR + GIMBAL)))
    B = J[:, list(model_columns) + [24, 25, 26]]
    r = r - B @ np.linalg.lstsq(B, r, rcond=None)[0]
    n = len(ws.windows)
    for c, name in enumerate(CHANNELS):
        ch = fit["channels"][name]
        c2 = float(np.sum(r[3 * n * c:3 * n * (c + 1)] ** 2))
        expected = max(1.0, ch["expected_chi2"] - 1.5)  # the three geometry parameters, shared by two channels
        p = chi2_sf(c2, int(round(expected)))
        ch.update(chi2_unexplained=c2, p_unexplained=p, systematic=bool(p < P_INCONSISTENT),
                  scale=max(1.0, math.sqrt(c2 / expected)) if p < P_INCONSISTENT else 1.0)
    fit["geometry_fitted_out"] = True


def _signatures(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, geometry: bool, model_jac, wvec) -> dict:
    """Candidate causes of a misfit as columns over the 6n normalised residual components
    (gyro rows first, window-major; ``wvec`` the sigma of each component)."""

    n = len(ws.windows)
    g = ws.site.gravity
    _, F = window_inputs(ws, gimbal.nonorthogonality, gimbal.mount_attitude)
    static = np.array([w.kind == "static" for w in ws.windows])
    out = {}
    # accelerometer quadratic / cross-coupling terms (static windows) and size effect (rate windows)
    cols = []
    pairs = [(i, i) for i in range(3)] + [(i, j) for i in range(3) for j in range(3) if j != i]
    for i, j in pairs:
        c = np.zeros((2, n, 3))
        c[1, :, i] = np.where(static, F[:, i] * F[:, j] / g, 0.0)
        cols.append(c.ravel())
    for i in range(3):
        c = np.zeros((2, n, 3))
        for k, w in enumerate(ws.windows):
            if w.kind in ("rate", "turn"):
                a = (np.array([0.0, 0.0, 1.0]) if w.axis == "inner"
                     else rot_z(w.theta[1]).T @ outer_axis(gimbal.nonorthogonality))
                c[1, k, i] = w.rate ** 2 * (1.0 - a[i] ** 2)
        cols.append(c.ravel())
    out["unmodelled accelerometer terms (nonlinearity, cross-coupling or size effect, S16 eq. 4-12; "
        "try --method systematic51)"] = np.array(cols).T / wvec[:, None]
    cols = []
    for i in range(3):
        for j in range(3):
            c = np.zeros((2, n, 3))
            c[0, :, i] = F[:, j] / g
            cols.append(c.ravel())
    out["unmodelled gyro g-sensitivity (S16 eq. 1-3; try --method systematic51)"] = np.array(cols).T / wvec[:, None]
    c = np.zeros((2, n, 3))
    c[1] = F
    out["wrong gravity (the site gravity does not match the data)"] = c.reshape(-1, 1) / wvec[:, None]
    if geometry:
        out["turntable not level or gimbal axes not orthogonal (wrong path geometry: this scheme assumes ideal, "
            "level and orthogonal inputs)"] = model_jac[:, 24:27]
    return out


def likely_cause(imu: ImuErrors, gimbal: GimbalErrors, ws: WindowSet, rg: np.ndarray, ra: np.ndarray,
                 model_columns: list[int] | None = None, geometry: bool = False) -> tuple[str, float]:
    """Name the likely cause of a misfit: one window carrying most of chi^2 (wrong path or
    angles there), else the candidate signature (:func:`_signatures`) that explains the
    largest share of chi^2 once what the fitted model absorbs is projected out (from the
    residuals and from the signatures)."""

    r = np.concatenate([rg.ravel(), ra.ravel()])
    chi2 = float(r @ r)
    if chi2 <= 0:
        return "none", 0.0
    per_win = np.sum(rg ** 2, axis=1) + np.sum(ra ** 2, axis=1)
    k = int(np.argmax(per_win))
    share_w = float(per_win[k] / chi2)
    if len(ws.windows) >= 4 and share_w > 0.5:
        return (f"wrong path: window {k} ({ws.windows[k].describe()}) carries {100 * share_w:.0f}% of chi2 (its "
                "angles or segmentation do not match the record)"), share_w
    m = WindowModel(ws)
    x = flatten(imu, gimbal, IMU_LINEAR + GIMBAL)
    J = m.jacobian(m.from_si(x))  # normalised residual per internal parameter
    cols = list(range(J.shape[1])) if model_columns is None else list(model_columns)
    Jm = J[:, cols]
    wvec = np.concatenate([np.maximum(np.array([w.gyro_sigma for w in ws.windows]), GYRO_FLOOR).ravel(),
                           np.maximum(np.array([w.accel_sigma for w in ws.windows]), ACCEL_FLOOR).ravel()])
    # an estimator that is not least squares leaves residuals its own model could absorb: the
    # shares are of the part it cannot
    if Jm.shape[1]:
        r = r - Jm @ np.linalg.lstsq(Jm, r, rcond=None)[0]
    chi2 = float(r @ r)
    if chi2 <= 0:
        return "none", 0.0
    best, best_share = None, 0.0
    for name, Cw in _signatures(imu, gimbal, ws, geometry, J, wvec).items():
        if Jm.shape[1]:
            coef, *_ = np.linalg.lstsq(Jm, Cw, rcond=None)
            Cw = Cw - Jm @ coef
        nrm = np.linalg.norm(Cw, axis=0)
        Cw = Cw[:, nrm > 1e-9 * max(1.0, float(nrm.max(initial=0.0)))]
        if Cw.shape[1] == 0:
            continue
        q, *_ = np.linalg.lstsq(Cw, r, rcond=None)
        share = float(np.sum((Cw @ q) ** 2) / chi2)
        if share > best_share:
            best, best_share = name, share
    if best is None or best_share < 0.5:
        return ("unexplained by the tested signatures (the window noise may be under-estimated, or errors the model "
                "lacks)"), best_share
    return f"{best}, explains {100 * best_share:.0f}% of chi2", best_share


def scaled_sigma(S: np.ndarray, idx: np.ndarray, fit: dict, n_windows: int) -> np.ndarray:
    """The reported sigma of a fit (see :data:`SIGMA_RULE`); the formal sigma if consistent.
    ``S``, ``idx`` as returned by :func:`sensitivity`."""
    if not any(fit["channels"][c].get("systematic") for c in CHANNELS):
        return np.sqrt(np.sum(S ** 2, axis=1))
    chan = (np.asarray(idx) >= 3 * n_windows).astype(int)
    rand = np.zeros(S.shape[0])
    syst = np.zeros(S.shape[0])
    for c, name in enumerate(CHANNELS):
        Sc = S[:, chan == c]
        ch = fit["channels"][name]
        if ch.get("systematic"):
            syst += np.sum(np.abs(Sc), axis=1) * ch["scale"]
        else:
            rand += np.sum(Sc ** 2, axis=1)
    return np.sqrt(rand + syst ** 2)


def finish_sigma(S: np.ndarray | None, idx: np.ndarray | None, fit: dict, names, n_windows: int) -> tuple[dict, dict]:
    """``(sigma, formal_sigma)`` dicts (SI, by parameter name) from the sensitivity matrix
    (NaN when ``S`` is None: no uncertainty asked for)."""
    if S is None:
        nan = unflatten(np.full(nparams(names), np.nan), names)
        return nan, nan
    formal = np.sqrt(np.sum(S ** 2, axis=1))
    return unflatten(scaled_sigma(S, idx, fit, n_windows), names), unflatten(formal, names)
