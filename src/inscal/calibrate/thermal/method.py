"""The ``thermal-plateaus`` method: the per-plateau method on every plateau, then the fit of every
parameter over temperature (see :mod:`inscal.calibrate.thermal`)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from inscal.calibrate.fit import P_INCONSISTENT
from inscal.calibrate.result import CalibrationResult, errors_from_values
from inscal.calibrate.thermal.plateaus import (
    CHAMBER_LABEL,
    MIN_PLATEAU_S,
    PLATEAU_TOL_C,
    Plateau,
    find_plateaus,
    plateau_records,
)
from inscal.calibrate.thermal.polyfit import TermFit, fit_term, result_covariance
from inscal.calibrate.windows import CalibrationError
from inscal.core.error_model import PARAMETERS, parameter_components
from inscal.core.thermal import RATE_TERM, THERMAL_TERMS, ThermalModel

#: default polynomial order per thermal term (0: constant over temperature)
DEFAULT_ORDERS = {"gyro_bias": 2, "gyro_scale_factor": 2, "gyro_misalignment": 0,
                  "accel_bias": 2, "accel_scale_factor": 2, "accel_misalignment": 0}
#: the method name
METHOD = "thermal-plateaus"


# ----------------------------------------------------------------------------- options
def check_orders(orders: dict | None) -> dict[str, int]:
    """The order of every thermal term: :data:`DEFAULT_ORDERS` updated with ``orders`` (name -> 0 ..
    the term's largest order); an unknown term or order is one line."""
    out = dict(DEFAULT_ORDERS)
    for name, k in (orders or {}).items():
        if name not in THERMAL_TERMS:
            if name == RATE_TERM[0]:
                raise CalibrationError(f"thermal order: {name} (the dT/dt term) cannot be seen on plateaus; use the "
                                       "continuous-ramp calibration")
            raise CalibrationError(f"thermal order: unknown term {name!r}; known: {', '.join(THERMAL_TERMS)}")
        try:
            kk = int(k)
        except (TypeError, ValueError):
            raise CalibrationError(f"thermal order of {name}: not a whole number ({k!r})") from None
        if kk != k or not 0 <= kk <= THERMAL_TERMS[name][4]:
            raise CalibrationError(f"thermal order of {name}: {k!r}, expected 0 .. {THERMAL_TERMS[name][4]}")
        out[name] = kk
    return out


# ----------------------------------------------------------------------------- the method
def thermal_plateaus(record_like, per_plateau: str = "n25", *, orders: dict | None = None, t_ref: float = 20.0,
                     sensor: str = "", chamber_label: str | None = CHAMBER_LABEL, plateau_tol: float = PLATEAU_TOL_C,
                     min_plateau_s: float = MIN_PLATEAU_S, run: Callable | None = None,
                     **method_options) -> CalibrationResult:
    """Thermal calibration from temperature plateaus (see the module docstring).

    ``per_plateau``: the method run on each plateau (a name of :data:`inscal.calibrate.METHODS`);
    ``method_options`` go to it.  ``orders``: polynomial order per thermal term (name -> 0 .. 3, 1 for the
    misalignments; default :data:`DEFAULT_ORDERS`, raised while a fit misfits: :func:`combine`; a named order
    is kept).  ``t_ref`` [degC]: the model's reference (inside the
    plateaus' range).  ``sensor``: the temperature sensor ("" = the mean of the record's).
    ``chamber_label``: label prefix of the chamber's transition moves (None: find the plateaus in the
    temperature alone).  ``plateau_tol`` [degC], ``min_plateau_s`` [s]: what counts as a plateau.
    ``run(record, method, **options)``: the calibration dispatcher (:func:`inscal.calibrate.calibrate`
    passes itself)."""
    if run is None:
        raise CalibrationError("thermal_plateaus runs another method per plateau: call it through "
                               "inscal.calibrate.calibrate(record, 'thermal-plateaus', ...)")
    if per_plateau == METHOD:
        raise CalibrationError(f"per_plateau cannot be {METHOD} itself")
    if not (isinstance(t_ref, (int, float)) and math.isfinite(t_ref)):
        raise CalibrationError(f"t_ref must be a temperature in degC, got {t_ref!r}")
    ords = check_orders(orders)
    named = frozenset(orders or {})
    need = max(ords.values()) + 1
    plats = find_plateaus(record_like, sensor, chamber_label, plateau_tol, min_plateau_s)
    where = ", ".join(f"{p.temperature_c:.3g}" for p in plats)
    if len(plats) < need:
        top = max(ords, key=ords.get)
        raise CalibrationError(f"{len(plats)} temperature plateau(s) found{f' (at {where} degC)' if plats else ''}: "
                               f"the order-{ords[top]} polynomial of {top} needs at least {need}"
                               + ("" if plats else f" (plateaus: within +-{plateau_tol:g} degC for {min_plateau_s:g} s)"))
    T = np.array([p.temperature_c for p in plats])
    t_min, t_max = float(np.min(T)), float(np.max(T))
    if not t_min <= t_ref <= t_max:
        raise CalibrationError(f"t_ref {t_ref:g} degC lies outside the plateaus' range {t_min:.4g} .. {t_max:.4g} degC: "
                               "the model's reference must lie inside the range it is calibrated over")
    subs = plateau_records(record_like, plats)
    results = []
    for p, sub in zip(plats, subs):
        try:
            results.append(run(sub, per_plateau, **method_options))
        except CalibrationError as exc:
            raise CalibrationError(f"plateau {p.index + 1} ({p.temperature_c:.3g} degC, {p.t0:.0f}-{p.t1:.0f} s): "
                                   f"{exc}") from None
    return combine(results, plats, ords, t_ref, sensor, per_plateau, named)


def plateau_covariances(results: list[CalibrationResult], names) -> tuple[list[np.ndarray], int]:
    """The covariance of each plateau's estimates (the components of ``names`` in order, SI): the method's
    own where it reports one (:func:`~.polyfit.result_covariance`), else diagonal; components held fixed
    (NaN sigma) keep NaN on the diagonal and no correlation.  Returns the matrices and how many are full."""
    labels = [f"{n}[{c}]" if c else n for n in names for c in parameter_components(n)]
    out, n_full = [], 0
    for r in results:
        sig = np.concatenate([np.ravel(np.asarray(r.sigma.get(n, np.nan), dtype=float)) for n in names])
        C = np.diag(sig ** 2)
        rc = result_covariance(r)
        if rc is not None:
            pos = {lab: i for i, lab in enumerate(rc[0])}
            if all(lab in pos for lab in labels):
                ix = np.array([pos[lab] for lab in labels])
                C = rc[1][np.ix_(ix, ix)].copy()
                bad = ~np.isfinite(sig)
                C[bad, :] = 0.0
                C[:, bad] = 0.0
                C[bad, bad] = np.nan
                n_full += 1
        out.append(C)
    return out, n_full


def inner_notes(results: list[CalibrationResult], plats: list[Plateau], per_plateau: str) -> list[str]:
    """The per-plateau methods' notes: once when every plateau says the same, else per plateau."""
    per = [list(r.notes) for r in results]
    out: list[str] = []
    for r_notes, p in zip(per, plats):
        for note in r_notes:
            if all(note in other for other in per):
                line = f"per plateau ({per_plateau}): {note}"
            else:
                line = f"plateau {p.index + 1} ({p.temperature_c:.3g} degC, {per_plateau}): {note}"
            if line not in out:
                out.append(line)
    return out


def fit_raising_order(name: str, dT: np.ndarray, values: np.ndarray, covs: list[np.ndarray], order: int,
                      top: int) -> tuple[TermFit, str]:
    """:func:`~.polyfit.fit_term` of ``name`` from ``order`` up: while the fit is inconsistent (its chi^2 test, or
    noise-free estimates off the polynomial beyond their round-off) and a higher order up to ``top`` still leaves
    a degree of freedom to test it, the order is raised.  Returns the fit kept and a note (empty when the first
    order fitted)."""
    P = values.shape[0]
    fit = fit_term(name, dT, values, covs, order)
    first = fit
    while not fit.consistent and fit.order < min(top, P - 2):
        fit = fit_term(name, dT, values, covs, fit.order + 1)
    if fit is first:
        return fit, ""
    end = "fits" if fit.consistent else "still misfits (its sigma treated as systematic)"
    why = "misfits the plateaus" + (f" (chi2 {first.chi2:.4g} on {first.dof} dof)" if math.isfinite(first.p_value)
                                    else " (noise-free estimates off it beyond their round-off)")
    return fit, f"{name}: order {order} {why}: raised to order {fit.order}, which {end}"


def combine(results: list[CalibrationResult], plats: list[Plateau], orders: dict[str, int], t_ref: float,
            sensor: str, per_plateau: str, named: frozenset[str] = frozenset()) -> CalibrationResult:
    """Fit the per-plateau results ``results`` (one per plateau of ``plats``) over temperature: every
    parameter with its order (``orders``; 0 for the parameters that are no thermal term), the values at
    ``t_ref`` into ``imu``/``gimbal``/``sigma``, the coefficients into ``thermal``/``thermal_sigma``, the
    statistics into ``thermal_fit``.  A thermal term not in ``named`` (the orders the caller chose) has its order
    raised while its fit misfits the plateaus (:func:`fit_raising_order`, up to the term's largest order), so a
    polynomial too low for the unit does not pass its misfit into the coefficients; a named order is kept."""
    names = tuple(results[0].estimated)
    for r, p in zip(results, plats):
        if tuple(r.estimated) != names:
            raise CalibrationError(f"plateau {p.index + 1}: {per_plateau} estimated {', '.join(r.estimated)}, not "
                                   f"{', '.join(names)} as on the first plateau")
    T = np.array([p.temperature_c for p in plats])
    P = len(plats)
    sizes = {n: PARAMETERS[n].size for n in names}
    sl, k = {}, 0
    for n in names:
        sl[n] = slice(k, k + sizes[n])
        k += sizes[n]
    Y = np.array([np.concatenate([np.ravel(r.value(n)) for n in names]) for r in results])
    full, n_full = plateau_covariances(results, names)
    cov_source = "full" if n_full == P else ("diagonal" if n_full == 0 else "partial")
    notes: list[str] = []
    if n_full < P:
        notes.append(f"{per_plateau} reports 1 sigma per parameter, no covariance"
                     + (f" (on {P - n_full} of {P} plateaus)" if n_full else "")
                     + ": those plateaus are weighted with a diagonal covariance (the coefficients and their sigma "
                     "are unbiased; the correlations between components within a plateau are not used)")
    order = {n: orders.get(n, 0) if n in THERMAL_TERMS else 0 for n in names}
    fits: dict[str, TermFit] = {}
    for n in names:
        covs = [C[sl[n], sl[n]] for C in full]
        if n in THERMAL_TERMS and n not in named:
            fits[n], raised = fit_raising_order(n, T - t_ref, Y[:, sl[n]], covs, order[n], THERMAL_TERMS[n][4])
            order[n] = fits[n].order
            if raised:
                notes.append(raised)
        else:
            fits[n] = fit_term(n, T - t_ref, Y[:, sl[n]], covs, order[n])
        if fits[n].note:
            notes.append(fits[n].note)
    fixed = {n: ~np.isin(np.arange(sizes[n]), fits[n].free) for n in names}
    # the values at t_ref and their sigma; the thermal coefficients and theirs
    vals, sigma = {}, {}
    for n in names:
        shape = PARAMETERS[n].shape
        v, s = fits[n].coef[0], np.where(fixed[n], np.nan, fits[n].sigma[0])
        vals[n] = v.reshape(shape) if shape else float(v[0])
        sigma[n] = s.reshape(shape) if shape else float(s[0])
    imu, gim = errors_from_values(vals)
    th_kw, th_sig = {}, {}
    for n in THERMAL_TERMS:
        o = order.get(n, orders.get(n, 0))
        if n in fits and o > 0:
            th_kw[n] = fits[n].coef[1:]
            th_sig[n] = np.where(fixed[n][None, :], np.nan, fits[n].sigma[1:])
        elif o > 0:
            notes.append(f"{n}: order {o} asked, but {per_plateau} does not estimate it; no thermal model for it")
    th_sig[RATE_TERM[0]] = np.full(3, np.nan)
    model = ThermalModel(t_ref=float(t_ref), t_min=float(np.min(T)), t_max=float(np.max(T)), sensor=sensor, **th_kw)
    notes.append("gyro_bias_rate (the dT/dt term): not estimated, a plateau holds dT/dt = 0; left at zero (sigma NaN)")
    # covariance of the values at t_ref across parameters: cov(a, b) = sum_p A_a,p C_p[a, b] A_b,p^T (scaled)
    labels = [f"{n}[{c}]" if c else n for n in names for c in parameter_components(n)]
    V = np.zeros((len(labels), len(labels)))
    for a in names:
        fa, sa = fits[a], np.where(fixed[a], np.nan, fits[a].scale[0])
        for b in names:
            fb, sb = fits[b], np.where(fixed[b], np.nan, fits[b].scale[0])
            blk = sum(fa.gains[p][:sizes[a]] @ np.nan_to_num(full[p][sl[a], sl[b]]) @ fb.gains[p][:sizes[b]].T
                      for p in range(P))
            V[sl[a], sl[b]] = blk * np.outer(sa, sb)
    thermal = [n for n in names if order[n] > 0]
    t_fit = {
        "per_plateau": per_plateau, "t_ref": float(t_ref), "covariance": cov_source, "p_inconsistent": P_INCONSISTENT,
        "plateaus": [{"temperature_c": p.temperature_c, "spread_c": p.spread_c, "start_s": p.t0,
                      "duration_s": p.duration} for p in plats],
        "terms": {n: fits[n].summary(PARAMETERS[n].unit) for n in thermal},
        "constant": {n: fits[n].summary(PARAMETERS[n].unit) for n in names if n not in thermal},
        "gyro_bias_rate": "not estimated: a plateau holds dT/dt = 0",
    }
    # the per-plateau estimates as the thermal report draws them (report.thermal.plateau_points), and the
    # covariance of [p_0, c_1 .. c_K] per component of every fitted term (report.thermal.term_curve)
    rows = [p.to_json() | {"values": {n: Y[q, sl[n]].tolist() for n in names},
                           "sigma": {n: np.sqrt(np.diag(full[q][sl[n], sl[n]])).tolist() for n in names}}
            for q, p in enumerate(plats)]
    term_cov = {}
    for n in thermal:
        f, m = fits[n], sizes[n]
        term_cov[n] = np.array([f.cov[np.ix_(np.arange(f.order + 1) * m + c, np.arange(f.order + 1) * m + c)]
                                for c in range(m)])
    diag = {"per_plateau": per_plateau, "plateaus": rows, "covariance_source": cov_source,
            "covariance": {"labels": labels, "P": V}, "thermal_covariance": term_cov, "thermal_fit": t_fit,
            "plateau_fits": [r.fit for r in results], "term_fits": fits, "plateau_results": results}
    res = CalibrationResult(METHOD, imu, gim, sigma, names, None, diag,
                            notes + inner_notes(results, plats, per_plateau))
    res.truth_transform = results[0].truth_transform
    res.thermal = model
    res.thermal_sigma = th_sig
    res.thermal_fit = t_fit
    return res


def thermal_truth(res: CalibrationResult, imu, gimbal, thermal: ThermalModel | None) -> dict[str, np.ndarray]:
    """The truth of every fitted thermal coefficient of ``res`` ((order, size) SI per term), in the frame
    of its estimates: the truth errors at each plateau temperature (``thermal.errors_at``, mapped with
    ``res.truth_transform``) fitted with the same polynomial and weights as the estimates.  A truth of
    higher order than the fit gives the coefficients the fit converges to."""
    fits = res.diagnostics["term_fits"]
    plats = res.diagnostics["plateaus"]
    T = np.array([p["temperature_c"] for p in plats])
    out = {}
    for n, f in fits.items():
        if n not in THERMAL_TERMS or f.order == 0:
            continue
        vals = []
        for t in T:
            ti = thermal.errors_at(imu, t) if thermal is not None else imu
            pair = (ti, gimbal)
            if res.truth_transform is not None:
                pair = res.truth_transform(pair)
            vals.append(np.ravel(getattr(pair[0], THERMAL_TERMS[n][0])))
        y = np.array(vals)
        g = sum(f.gains[p] @ y[p] for p in range(len(T)))
        out[n] = g.reshape(f.order + 1, -1)[1:]
    return out
