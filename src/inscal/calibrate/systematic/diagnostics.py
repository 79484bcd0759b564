"""Diagnostics of a systematic calibration: the chi-square fit of the innovations by time block, the
encoder residuals, the mount attitude, and the per-pass history for convergence plots."""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.systematic.kernel import PassOutput
from inscal.calibrate.systematic.params import (
    CompParams,
    canonical_flat,
    params_from_ref,
    ref_error_states,
    truth_in_frame,
)
from inscal.calibrate.systematic.record_stats import step_rates
from inscal.calibrate.systematic.states import FRAME_GIMBAL, StateSet
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.attitude import euler_from_dcm
from inscal.core.error_model import (
    PARAMETERS,
    GimbalErrors,
    ImuErrors,
    parameter_components,
)
from inscal.core.stats import chi2_cdf, chi2_sf
from inscal.core.turntable import C_s_b

#: p-value below which the innovations are declared inconsistent with the noise model
P_INCONSISTENT = 1e-3
#: time blocks of the per-window innovation residuals (at most this many, at least 60 s each)
FIT_BLOCKS = 24
#: posterior / prior sigma at or above which a parameter component is reported as not observable from
#: the record (:func:`unobservable`).  Posterior precision = prior precision + data precision, so at 0.5
#: the estimate owes at least a quarter of its precision to the prior (at 0.71, half): the record does not
#: determine it on its own.  0.5 also catches a component that shares one observed combination with others
#: (on a static base, the bias, scale factor and nonlinearity of the vertical accelerometer sit at 0.82
#: each: only their sum along gravity is seen), which 0.9 would miss; it is the bound of the verdict
#: "unobservable" of :mod:`inscal.plan.observability`, so the path analysis and the calibration of its
#: record name the same components; on the s16 record the largest ratio is 0.18.
UNOBSERVABLE_RATIO = 0.5


def innovation_fit(nis: np.ndarray, z: np.ndarray, T: float, chisq: float, dof: int, st: StateSet,
                   signature: dict | None = None, expected: float | None = None, floor: str | None = None) -> dict:
    """The fit of a systematic-filter run, in the form of the window-mean methods' fit
    (:func:`inscal.calibrate.fit.fit_statistics`): chi^2 of the normalised innovations on
    ``dof`` = 6 per filter step, p-value, and per time block (the filter has no windows) the
    mean NIS (expected 6 less the pseudo-measurement part, ``expected``) with the velocity / position
    innovation RMS.

    When p < :data:`P_INCONSISTENT` the reported sigma are the formal (smoothed) ones times
    ``scale = sqrt(chi2 / dof)`` (``sqrt(mean NIS / 6)``): the innovation sequence says the
    noise model understates what the filter sees (unmodelled terms, a wrong path or wrong
    gravity add to every innovation); the formal sigma are kept beside them.  A chi^2 far *below*
    its dof (lower-tail p < :data:`P_INCONSISTENT`) is as much a misfit: the assumed noise is
    larger than the data's (``--arw``/``--vrw`` too large, a noise floor above a noise-free
    record's, or rounding that does not accumulate as white noise would).  It is reported as
    inconsistent with that cause, and the sigma are left as they are: conservative, never scaled
    down by a fit that says the noise model is wrong.

    ``floor``: the noise floors the record's own noise (estimated from it) fell below, in words (a noise-free,
    quantized or float32 record).  A chi^2 far below its dof is then what such a record shows, not a misfit: the
    fit is consistent at its floors.  The floors are not lowered to the record's white rounding: on a float32
    record the dwells' increments are constant, their rounding a constant per attitude (up to half a unit in the
    last place per sample, 0.04 ug for a 0.1-m/s increment) that the bias and attitude states absorb and the
    NIS cannot see, and that the floors stand for (on the independent oracle's float32 19-position record the
    largest error/sigma at the floors is 2.2, the accelerometer nonlinearity, 0.04 ug/g^2 against 0.009 ug/g^2
    on the same record in double precision)."""

    e = float(dof) if expected is None else float(expected)  # the chi2's expectation (its dof, less the
    # part of S the data do not carry: see the driver); tested as chi2 with that many degrees of freedom
    p = chi2_sf(chisq, e) if dof > 0 else float("nan")
    p_low = chi2_cdf(chisq, e) if dof > 0 else float("nan")
    too_high, too_low = p < P_INCONSISTENT, p_low < P_INCONSISTENT
    below_floor = too_low and floor is not None  # a record quieter than the floors (docstring)
    consistent = not (too_high or (too_low and not below_floor))
    scale = math.sqrt(max(chisq / e, 1.0)) if too_high else 1.0
    n = len(nis)
    nb = int(max(1, min(FIT_BLOCKS, n * T // 60.0)))
    edges = np.linspace(0, n, nb + 1).astype(int)
    res = []
    for k in range(nb):
        a, b = edges[k], edges[k + 1]
        if b <= a:
            continue
        res.append({"window": k, "label": f"t {a * T:7.0f}-{b * T:7.0f} s",
                    "nis_mean": float(np.mean(nis[a:b])),
                    "velocity_rms_m_s": float(np.sqrt(np.mean(z[a:b, :3] ** 2))),
                    "position_rms_m": float(np.sqrt(np.mean(z[a:b, 3:] ** 2)))})
    fit = {"chi2": chisq, "dof": int(dof), "expected_chi2": e, "p_value": p, "p_value_low": p_low,
           "consistent": consistent,
           "scale": scale, "residuals": res, "cause": None, "note": None,
           "sigma_rule": "systematic filter: sigma x sqrt(chi2/dof) of the innovations when p < 0.001"}
    if below_floor:
        fit["note"] = (f"innovation chi2 = {chisq:.4g} on {dof} dof ({e:.5g} expected) is below it as on any record "
                       f"quieter than the noise floors ({floor}): consistent at the floors; the sigma are those of "
                       "the floors, which stand for what such a record still carries and the innovations cannot see "
                       "(a float32 record's rounding is a constant per attitude)")
    elif too_low:
        cause = ("the assumed noise is larger than the data's: --arw/--vrw too large, a noise floor above a noise-free "
                 "or quantized record's own, or rounding that does not accumulate as white noise would")
        fit["cause"] = cause
        fit["note"] = (f"fit inconsistent: innovation chi2 = {chisq:.4g} on {dof} dof ({e:.5g} expected) is far below "
                       f"it (NIS mean {chisq / max(n, 1):.3g} vs {e / max(n, 1):.3g}, lower-tail p = {p_low:.2g}); likely cause: {cause}; the sigma "
                       "are conservative (not scaled down)")
    elif not consistent:
        worst = max(res, key=lambda r: r["nis_mean"])
        if not st.extended:
            cause = ("unmodelled terms (the 30-state set has no g-sensitivity, quadratic, cross-coupling or "
                     "lever-arm states: try --states 51)")
        else:
            cause = ("unmodelled terms, wrong noise (--arw/--vrw), a wrong path or wrong gravity (--gravity); "
                     f"worst block {worst['label'].strip()} (NIS {worst['nis_mean']:.3g})")
        if signature is not None:
            cause += f"; where: {signature_line(signature)}"
        fit["cause"] = cause
        fit["note"] = (f"fit inconsistent: innovation chi2 = {chisq:.4g} on {dof} dof ({e:.5g} expected; NIS mean "
                       f"{chisq / max(n, 1):.3g} vs {e / max(n, 1):.3g}, p = {p:.2g}); likely cause: {cause}; sigma scaled by sqrt(chi2/dof) = {scale:.3g}, "
                       "formal sigma kept")
    if signature is not None:
        fit["signature"] = signature
    return fit


#: a filter step turns when its mean body rate exceeds this [rad/s] (the Earth rate is 7e-5)
TURNING_RATE = 0.1 * math.pi / 180.0


def misfit_signature(nis: np.ndarray, dtheta: np.ndarray, dt: float, n_per: int) -> dict:
    """Where and with what the innovations misfit: the mean NIS of the static and the turning filter
    steps, the rank correlation of the per-step NIS with what the motion does in the step (mean rate
    ``|w|``, its square, the largest rate change ``|w-dot|`` within the step and at its end, where a
    velocity error of the angular acceleration's sampling shows), and the worst steps with their time.
    A model that misses a term of the moves (asynchrony, a lever arm, a scheme difference) fits the
    dwells and misfits the turns; wrong noise misfits both alike."""
    M = nis.shape[0]
    mean_rate, dw_max, dw_end = step_rates(np.ascontiguousarray(dtheta, dtype=float), dt, dt ** 2, n_per, M)
    feats = {"rate": mean_rate, "rate_squared": mean_rate ** 2, "angular_acceleration": dw_max,
             "angular_acceleration_at_step_end": dw_end}
    turning = mean_rate > TURNING_RATE
    rank = np.argsort(np.argsort(nis))
    corr = {}
    for k, v in feats.items():
        if np.ptp(v) > 0:
            rv = np.argsort(np.argsort(v))
            corr[k] = float(np.corrcoef(rank, rv)[0, 1])
    worst = np.argsort(-nis)[:5]
    out = {"nis_mean_static": float(np.mean(nis[~turning])) if (~turning).any() else None,
           "nis_mean_turning": float(np.mean(nis[turning])) if turning.any() else None,
           "turning_steps": int(turning.sum()), "rank_correlation": corr,
           "worst_steps": [{"t_s": float((k + 1) * n_per * dt), "nis": float(nis[k]), "turning": bool(turning[k]),
                            "rate_deg_s": float(np.degrees(mean_rate[k]))} for k in worst]}
    strongest = max(corr, key=lambda k: abs(corr[k])) if corr else None
    out["strongest"] = strongest
    return out


def signature_line(sig: dict) -> str:
    """One sentence of :func:`misfit_signature` for the fit's note."""
    parts = []
    if sig["nis_mean_static"] is not None and sig["nis_mean_turning"] is not None:
        parts.append(f"NIS mean {sig['nis_mean_static']:.3g} at rest, {sig['nis_mean_turning']:.3g} turning")
    if sig["strongest"]:
        parts.append(f"most correlated with {sig['strongest'].replace('_', ' ')} "
                     f"(rank correlation {sig['rank_correlation'][sig['strongest']]:.2f})")
    ws = ", ".join(f"{w['t_s']:.0f} s ({w['nis']:.3g}{', turning' if w['turning'] else ''})"
                   for w in sig["worst_steps"][:3])
    parts.append(f"worst steps ending at {ws}")
    return "; ".join(parts)


def encoder_angles(rec, n: int, dt: float) -> np.ndarray:
    """Gimbal angles [outer, inner] (n, 2) [rad] at the end of every sample: the record's ``gimbal``
    dataset (non-finite entries: no encoder sample), or, without one, its path's angles at the
    sample times (noise-free: simulated records, the observability analysis)."""
    g = getattr(rec, "gimbal", None)
    if g is not None:
        g = np.array(g, dtype=float)
        if g.shape != (n, 2):
            raise CalibrationError(f"encoder angles must be an ({n}, 2) array like the increments, got {g.shape}")
        g[~np.all(np.isfinite(g), axis=1)] = np.nan
        return g
    path = getattr(rec, "path", None)
    if path is None:
        raise CalibrationError("the gimbal states need the encoder angles (the record's gimbal dataset) or its path")
    t = getattr(rec, "time", None)
    t = (np.arange(n) + 1) * dt if t is None else np.asarray(t, float)
    return path.segments().angles(t)[0]


def mount_from_attitude(C_s_n, angles, dth: float = 0.0) -> np.ndarray:
    """``[alpha0, beta0, gamma0]`` of ``C_b^n = C_s^n (Rot(u, tx) R_z(tz))^T`` (N25 eq. 7-8 inverted)."""

    return euler_of(np.asarray(C_s_n, float) @ C_s_b(float(angles[0]), float(angles[1]), float(dth)).T)


def gimbal_diagnostics(res, last: PassOutput, st: StateSet, enc_sig: float, every: int) -> None:
    """The unified filter's frame label and its encoder attitude innovations (``diagnostics["encoder"]``)."""
    d = res.diagnostics
    d["frame"] = FRAME_GIMBAL
    if res.notes:
        res.notes[0] = f"systematic {st.n_states}-state filter: parameters in the {FRAME_GIMBAL} frame"
    used = np.asarray(last.att_used, bool)
    nis = last.nis_att[used]
    za = last.z_att[used]
    # E[NIS] = tr(S^-1 (H P H^T + R_enc)) = 3 - floor tr(S^-1): the floor is not in the data (between 2 and 3)
    Sia = last.smoother.Sia_st[used]
    expected = float(np.mean(3.0 - last.smoother.enc_floor * np.trace(Sia, axis1=1, axis2=2))) if nis.size else float("nan")
    d["encoder"] = {"sigma_arcsec": float(units.from_si(enc_sig, "arcsec")), "every_steps": every,
                    "updates": int(used.sum()), "nis_mean": float(np.mean(nis)) if nis.size else float("nan"),
                    "nis_expected": expected,
                    "residual_rms_arcsec": (units.from_si(np.sqrt(np.mean(za**2, axis=0)), "arcsec").tolist()
                                            if za.size else None)}


def truth_gimbal(truth, st: StateSet):

    if not st.gimbal:
        return GimbalErrors()
    return truth[1] if isinstance(truth, tuple) else truth.gimbal


def truth_imu(truth, st: StateSet) -> ImuErrors:
    imu = truth[0] if isinstance(truth, tuple) else truth.imu
    return truth_in_frame(imu, st).to_imu()


def euler_of(C) -> np.ndarray:

    return np.asarray(euler_from_dcm(C))


def pass_history(out: PassOutput, st: StateSet, names, sig, J, final: CompParams, P_post) -> dict:
    """Parameter histories in the canonical layout (SI) at the stored steps: ``filtered`` (the
    reference before each stored update, 1 sigma from the predicted covariance) and ``smoothed``.

    The parameters are constants, so their smoothed estimate and covariance at every step are the
    final ones (the RTS smoother with zero parameter process noise); inscal uses that identity
    rather than the adjoint recursion, whose parameter part loses precision early in the record
    when the zero-velocity updates are ~1e8 times more informative than the prior.  The recursion's
    own parameter estimates (``mbf``) are kept for checks; they agree with the final ones once the
    record is well conditioned (tests/calibrate/test_systematic.py)."""
    nd = st.n_dyn
    sig_par = sig[nd:]
    t = (out.hist_step + 1).astype(float)
    # canonical values to first order about the final estimate: canon(ref) = canon(final) + J x_ref,
    # x_ref = the error state of each reference relative to the final (exact conversions at both ends)
    fin = canonical_flat(final, names)
    xr = ref_error_states(out.hist_ref, st, final)
    filt = fin + xr @ J.T
    filt[0] = canonical_flat(params_from_ref(out.hist_ref[0]), names)
    mbf = fin + (xr - out.hist_x[:, nd:] * sig_par) @ J.T
    # diag(J P J^T) of every row in one product: sum_jk P_jk J_ij J_ik = P (flattened) . (J_i outer J_i)
    Pm = out.hist_Pm[:, nd:, nd:] * np.outer(sig_par, sig_par)
    JJ = (J[:, :, None] * J[:, None, :]).reshape(J.shape[0], -1)
    sf = np.sqrt(np.maximum(Pm.reshape(Pm.shape[0], -1) @ JJ.T, 0.0))
    sfin = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", J, P_post, J), 0.0))
    n = filt.shape[0]
    return {"step": out.hist_step, "names": names, "filtered": filt, "filtered_sigma": sf,
            "smoothed": np.tile(fin, (n, 1)), "smoothed_sigma": np.tile(sfin, (n, 1)), "mbf": mbf,
            "t_steps": t}


def unobservable(names, sigma: np.ndarray, prior: np.ndarray,
                 threshold: float = UNOBSERVABLE_RATIO) -> tuple[list[dict], str | None]:
    """The parameter components the record does not observe: formal posterior ``sigma`` at least
    ``threshold`` times the ``prior`` sigma (canonical flat vectors of ``names``, SI; NaN: a component
    the state set holds fixed, skipped).  Returns ``(entries, note)``: per component its parameter,
    component, ``sigma_ratio`` and both sigmas in the parameter's field unit, and one note line naming
    them (None when every component is observed)."""
    entries, parts = [], []
    k = 0
    for n in names:
        comps = parameter_components(n)
        unit = PARAMETERS[n].unit
        flagged = []
        for c in comps:
            s, s0 = float(sigma[k]), float(prior[k])
            k += 1
            if not (math.isfinite(s) and math.isfinite(s0) and s0 > 0) or s < threshold * s0:
                continue
            entries.append({"parameter": n, "component": c, "sigma_ratio": s / s0,
                            "sigma": float(units.from_si(s, unit)), "prior_sigma": float(units.from_si(s0, unit)),
                            "unit": unit})
            flagged.append((c, s0))
        if flagged:
            s0s = sorted({f"{float(f'{float(units.from_si(v, unit)):.3g}'):g}" for _, v in flagged}, key=float)
            prior_txt = " / ".join(s0s) + f" {unit}"
            cs = ", ".join(c for c, _ in flagged if c)
            parts.append(f"{n.replace('_', ' ')}{' ' + cs if cs else ''} (prior sigma {prior_txt})")
    if not entries:
        return entries, None
    note = (f"not observable from this record (posterior sigma >= {threshold:g} x prior sigma): {'; '.join(parts)}; "
            "their values are the prior's (zero) or close to it, not a calibration: a path that turns the IMU "
            "through these axes observes them (inscal observability)")
    return entries, note
