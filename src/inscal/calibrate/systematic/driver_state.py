"""The state the systematic driver (:mod:`inscal.calibrate.systematic.driver`) carries between its steps, as
frozen dataclasses, and the diagnostics and notes it assembles from them."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from inscal.calibrate.systematic.diagnostics import euler_of
from inscal.calibrate.systematic.model_error import ModelError
from inscal.calibrate.systematic.model_error import note as model_error_note
from inscal.calibrate.systematic.params import CompParams
from inscal.calibrate.systematic.states import StateSet, state_spec
from inscal.core import units
from inscal.core.stats import chi2_sf


@dataclasses.dataclass(frozen=True)
class NoiseLevels:
    """The white noise the filter assumes (estimated or given, floored) and its pseudo-measurement noise."""

    arw_v: np.ndarray  # [rad/sqrt(s)] per axis
    vrw_v: np.ndarray  # [m/s/sqrt(s)] per axis
    floored: bool  # raised to ARW_FLOOR / VRW_FLOOR
    resolution_floored: bool  # raised to the rounding noise of the record's quantum or float32 storage
    q_res: np.ndarray  # the quantum of the six columns
    f32: np.ndarray  # the float32 rounding of the six columns
    qg: np.ndarray
    qa: np.ndarray
    vsig: float  # zero-velocity pseudo-measurement sigma [m/s]
    psig: float  # known-position pseudo-measurement sigma [m]
    r: np.ndarray  # their variances (velocity, position)


@dataclasses.dataclass(frozen=True)
class Prepared:
    """The record and states ready for the passes: increments, noise, priors, coarse alignment, encoder rows and
    the starting model-error factors."""

    st: StateSet
    gm_note: str | None
    arw: object  # the white noise asked for (after a noise model's), None: from the record
    vrw: object
    dth: np.ndarray
    dv: np.ndarray
    rate: float
    dt: float
    tin: dict | None
    n_per: int
    T: float
    site: object
    site_v: np.ndarray
    noise: NoiseLevels
    hist_every: int
    nd: int  # navigation and Gauss-Markov states; the parameters follow
    sig: np.ndarray
    sig_par: np.ndarray
    start: CompParams
    nominal: CompParams
    C0: np.ndarray
    enc: np.ndarray | None
    enc_sig: float
    cap: float
    moving: np.ndarray
    me: ModelError
    frozen: bool


@dataclasses.dataclass(frozen=True)
class Passes:
    """The outcome of the filter passes: the last pass, its estimate and posterior, the factors that stand."""

    out: object  # the last pass's PassOutput
    est: CompParams
    p_start: CompParams
    C0: np.ndarray
    P_post: np.ndarray
    Pf_inv: np.ndarray
    sig_used: np.ndarray
    me: ModelError
    passes: list
    converged: bool
    first: tuple  # the first pass's output and prior sigma (for the history)


def diagnostics(p: Prepared, it: Passes, last, fit: dict, nis, dof: int, chisq: float, expected: float, assumed,
                verdict, term_check, accept_unconverged: bool, formal: dict, unobs, robust: bool, weights,
                noise) -> dict:
    """The result's diagnostics: states, noise, innovations, fit, model error, convergence, sigma."""
    st, nv, me = p.st, p.noise, it.me
    diag = {
        "states": st.n_states, "state_options": state_spec(st), "frame": "accelerometer-defined (PSINS triangular)"
        if st.psins else "gyro-defined (S16 m-frame)",
        "filter_rate_hz": 1.0 / p.T, "steps": int(last.steps), "passes": it.passes, "converged": it.converged,
        "noise": {"arw_deg_sqrt_h": units.from_si(nv.arw_v, "deg/sqrt(h)").tolist(),
                  "vrw_ug_sqrt_hz": units.from_si(nv.vrw_v, "ug/sqrt(Hz)").tolist(),
                  "estimated_from_data": p.arw is None and p.vrw is None, "floored": nv.floored,
                  "resolution_floored": nv.resolution_floored,
                  "resolution": {"gyro_arcsec": units.from_si(nv.q_res[:3], "arcsec").tolist(),
                                 "accel_ug_s": units.from_si(nv.q_res[3:], "ug*s").tolist()},
                  "float32": bool(np.all(nv.f32 > 0)),
                  "float32_rounding": {"gyro_arcsec": units.from_si(nv.f32[:3], "arcsec").tolist(),
                                       "accel_ug_s": units.from_si(nv.f32[3:], "ug*s").tolist()},
                  "velocity_sigma_m_s": nv.vsig, "position_sigma_m": nv.psig},
        "innovations": {"nis_mean": float(np.mean(nis)), "nis_expected": expected / max(len(nis), 1), "chi2": chisq,
                        "dof": dof, "expected_chi2": expected,
                        "p_value": chi2_sf(chisq, expected) if dof > 0 else float("nan"),
                        "velocity_rms_m_s": float(np.sqrt(np.mean(last.z[:, :3] ** 2))),
                        "position_rms_m": float(np.sqrt(np.mean(last.z[:, 3:] ** 2)))},
        "initial_attitude_deg": np.degrees(euler_of(it.C0)).tolist(),
    }
    diag["fit"] = fit
    diag["inputs_assumed"] = assumed
    diag["model_error"] = me.as_dict() | {"moving_steps": int(np.sum(p.moving)), "robust": bool(robust),
                                          "outlier_cap": None if not math.isfinite(p.cap) else p.cap,
                                          "shared": weights is not None}
    if st.lever_timing:  # a nuisance (states levtime): the canonical parameters do not depend on it
        off = 0
        for g in st.groups:
            if g.name == "accel_lever_timing":
                break
            off += g.size
        diag["lever_timing"] = {"value_ms": (it.est.levt * 1e3).tolist(),
                                "sigma_ms": (np.sqrt(np.maximum(np.diag(it.P_post)[off:off + 3], 0.0)) * 1e3).tolist()}
    diag["convergence"] = {"converged": it.converged, "verdict": verdict or None,
                           "accepted_unconverged": bool(verdict) and accept_unconverged, "term_check": term_check}
    diag["formal_sigma"] = formal
    diag["unobservable"] = unobs
    if noise is not None:
        diag["noise"]["gauss_markov"] = [{"sensor": g.sensor, "axis": "xyz"[g.axis], "tc_s": g.tc,
                                          "sigma": float(units.from_si(g.sigma, "deg/h" if g.sensor == "gyro" else "ug")),
                                          "sigma_unit": "deg/h" if g.sensor == "gyro" else "ug"} for g in st.gm]
        diag["noise"]["from_model"] = True
    return diag


def result_notes(p: Prepared, me: ModelError, frame: str, verdict, fit: dict, assumed, unobs_note, noise) -> list:
    """The result's notes: the frame, an unconverged run, the fit, the inputs assumed, the model error, the
    unobservable groups and a noise model's states."""
    st = p.st
    notes = [f"systematic {st.n_states}-state filter: parameters in the {frame} frame"]
    if verdict:
        notes.append(f"NOT A CONVERGED CALIBRATION: {verdict}; the last iterate is kept on request "
                     "(--accept-unconverged)")
    if fit["note"]:
        notes.append(fit["note"])
    if assumed is not None:
        notes.append(assumed["note"])
    me_note = model_error_note(me, int(np.sum(p.moving)))
    if me_note and me_note not in (fit["note"] or ""):
        notes.append(me_note)
    if unobs_note:
        notes.append(unobs_note)
    if noise is not None:
        tcs = sorted({round(g.tc, 3) for g in st.gm})
        notes.append(f"noise model given: white noise of its WN terms, {len(st.gm)} Gauss-Markov bias state(s)"
                     + (f" (correlation time {', '.join(f'{t:g}' for t in tcs)} s)" if tcs else ""))
        if p.gm_note:
            notes.append(p.gm_note)
    return notes
