"""The systematic calibration driver: noise from the record, coarse alignment on the first dwell,
iterated filter/smoother passes with prior deflation, and the result with its fit."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from scipy.linalg import solve_triangular

from inscal.calibrate.result import CalibrationResult, unflatten
from inscal.calibrate.systematic.diagnostics import (
    encoder_angles,
    gimbal_diagnostics,
    innovation_fit,
    misfit_signature,
    mount_from_attitude,
    pass_history,
    truth_gimbal,
    truth_imu,
    unobservable,
)
from inscal.calibrate.systematic.model_error import (
    TERM_SHIFT_LIMIT,
    WEIGHT_PASSES,
    ModelError,
    moving_steps,
    term_shift,
    update_factors,
)
from inscal.calibrate.systematic.model_error import initial as no_model_error
from inscal.calibrate.systematic.model_error import note as model_error_note
from inscal.calibrate.systematic.driver_state import NoiseLevels, Passes, Prepared, diagnostics, result_notes
from inscal.calibrate.systematic.gm_states import noise_setup
from inscal.calibrate.systematic.kernel import pass_bytes, run_pass, smooth_pass
from inscal.calibrate.systematic.params import CompParams, canonical_jacobian
from inscal.calibrate.systematic.sensitivity import forcings, parameter_shift, tolerances
from inscal.calibrate.systematic.record_stats import (
    column_quantum,
    first_turn,
    second_difference_mad,
)
from inscal.calibrate.systematic.states import (
    ARW_FLOOR,
    DEFAULT_SIGMA0,
    DEFLATE,
    ENCODER_SIGMA,
    N_NAV,
    NAV_SIGMA0,
    VRW_FLOOR,
    StateSet,
    estimated_names,
    fixed_mask,
    prior_sigma,
    state_spec,
    thermal_orders_from,
)
from inscal.calibrate.systematic.thermal_states import T_REF_C, sample_inputs, thermal_offset, thermal_result
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.attitude import dcm_from_quat, quat_from_rotvec
from inscal.core.earth import OMEGA_IE
from inscal.core.error_model import GimbalErrors, ImuErrors, parameter_components
from inscal.core.thermal import RATE_WINDOW_S
from inscal.nav.align import coarse_align

#: body rate [rad/s] (0.5-s mean) above which a sample counts as turning, for the alignment window
ALIGN_STATIC_RATE = 0.05 * math.pi / 180.0
#: default NIS above which a filter step is down-weighted (chi2 with 6 dof exceeds 36 with probability 1e-6)
NIS_CAP = 36.0
#: the median of chi2 with 6 degrees of freedom
CHI2_6_MEDIAN = 5.348
#: the first pass whose innovations may set the model-error factors (model_error), and the pass whose innovations
#: set them at the latest; before that a pass sets them once it changed the estimate by less than FACTOR_CHANGE
#: sigma (its innovations then show the record, not the linearisation point).  The passes before run with
#: bounded influence
FIRST_FACTOR_PASS = 2
LAST_BOUNDED_PASS = 4
FACTOR_CHANGE = 100.0
#: an estimate further than this many prior sigma from its nominal ends the run (convergence_verdict)
PRIOR_EXCESS = 5.0
#: runs asked for fewer passes than this are deliberate first iterates: only a diverged navigation ends them
MIN_VERDICT_PASSES = 4
#: a position innovation beyond this [m] on a static site ends the run (the navigation diverged)
STATIC_POSITION_LIMIT = 10.0
#: default interval between the stored history rows [s]
HISTORY_S = 10.0
#: peak memory of the driver's working copies of the increments, beyond the record itself [bytes per sample]:
#: an upper bound, measured 143 B with 51 states when the noise estimate and the first-motion search formed
#: full-size NumPy temporaries, 173 B with gimbal states (a copy of the encoder angles besides); the compiled
#: scans of record_stats need less (one second-difference column, 8 B; the radix keys of one channel, 16 B)
WORK_BYTES_PER_SAMPLE = 176
#: with thermal states: each sample's temperature difference and rate, and the temporaries that interpolate them
THERMAL_BYTES_PER_SAMPLE = 64


#: a temperature rate of note [degC/s] (0.1 degC/min): a profile reverses when its rate passes it both ways
RATE_OF_NOTE = 0.1 / 60.0


def reverses(rate: np.ndarray) -> bool:
    """Whether a temperature history both rises and falls at a rate of note (:data:`RATE_OF_NOTE`)."""
    return bool(np.any(rate > RATE_OF_NOTE) and np.any(rate < -RATE_OF_NOTE))


def samples_per_step(rate_hz: float, filter_rate_hz: float) -> int:
    """Samples per filter step at ``filter_rate_hz`` on a record at ``rate_hz``."""
    return max(1, int(round(rate_hz / filter_rate_hz)))


def history_every(step_s: float, history_s: float = HISTORY_S) -> int:
    """Filter steps between two stored history rows."""
    return max(1, int(round(history_s / step_s)))


def systematic_bytes(n_samples: float, rate_hz: float, states: StateSet, filter_rate_hz: float = 1.0,
                     history_s: float = HISTORY_S) -> float:
    """Peak memory [bytes] of :func:`systematic` beyond the record it is given (``n_samples`` at ``rate_hz``):
    the working copies of the increments (:data:`WORK_BYTES_PER_SAMPLE`), one pass's stores
    (:func:`~inscal.calibrate.systematic.kernel.pass_bytes`: a pass's stores are freed before the next
    pass allocates its own) and what the first pass keeps for the history (its history rows, and per step
    its NIS, innovations and factor on R)."""
    n_per = samples_per_step(rate_hz, filter_rate_hz)
    M = math.floor(float(n_samples) / n_per)
    every = history_every(n_per / rate_hz, history_s)
    work = WORK_BYTES_PER_SAMPLE + (THERMAL_BYTES_PER_SAMPLE if states.thermal else 0)
    return (work * float(n_samples) + pass_bytes(M, states, every)
            + pass_bytes(M, states, every, stores=False))


def _first_motion(dth: np.ndarray, dt: float) -> int:
    """Samples before the first turn (0.5-s mean body rate above :data:`ALIGN_STATIC_RATE`;
    Earth rate is 0.004 deg/s); the whole record when it never turns."""
    h = max(1, int(round(0.5 / dt)))
    return int(first_turn(np.ascontiguousarray(dth, dtype=float), h, dt, ALIGN_STATIC_RATE))


def estimate_white_noise(dtheta, dvel, dt) -> tuple[np.ndarray, np.ndarray]:
    """Angle and velocity random walk [rad/sqrt(s), m/s/sqrt(s)] per axis from the record itself:
    the robust spread (1.4826 MAD) of second differences of the increments, which removes
    constant rates and constant-rate rotations (var of a second difference of white noise = 6 s^2)."""
    out = []
    step = max(1, x_len // 200_000) if (x_len := len(dtheta)) else 1  # a subsample is plenty for a spread
    for x in (dtheta, dvel):
        mad = second_difference_mad(np.ascontiguousarray(x, dtype=float), step)
        out.append(1.4826 * mad / math.sqrt(6.0) / math.sqrt(dt))
    return out[0], out[1]


def data_resolution(x: np.ndarray, max_rows: int = 200_000) -> np.ndarray:
    """The quantum of each column of ``x`` (N, k): the step ``q`` when every value is a whole
    multiple of it (integer counts times a scale factor, as a quantized log holds), else 0.
    Rounding to ``q`` adds white noise of variance ``q^2 / 12`` to each increment, whatever the
    record's own noise: a filter tuned below it cannot fit the data (a noise-free record whose
    second differences are mostly zero estimates a noise of exactly zero).  A handful of distinct values
    (fewer than 16: the dwells of a noise-free record) shows no grid; a value off the grid of the smallest
    step between distinct values by 1e-3 of it rules it out."""
    x = np.ascontiguousarray(x, dtype=float)
    step = max(1, x.shape[0] // max_rows)
    return np.array([column_quantum(x, c, step) for c in range(x.shape[1])])


def float32_rounding(x: np.ndarray, max_rows: int = 200_000) -> np.ndarray:
    """The rounding noise [same unit as ``x``, per increment, 1 sigma] of each column of ``x`` (N, k) when
    every value is a float32 number (a record written in single precision, e.g. a PSINS float32 ``.bin``),
    else 0: rounding to the float32 grid adds white noise of variance ``ulp^2 / 12``, the grid spacing
    ``ulp`` following each value's magnitude (2^-24 of it).  Far below any real IMU's noise; it shows a
    noise-free float32 record's floor."""
    x = np.asarray(x, float)
    sub = x[::max(1, x.shape[0] // max_rows)]
    out = np.zeros(x.shape[1])
    for c in range(x.shape[1]):
        v = sub[:, c]
        f = v.astype(np.float32)
        if v.size and np.all(f.astype(float) == v) and np.any(v != 0):
            out[c] = math.sqrt(float(np.mean(np.spacing(np.abs(f)).astype(float) ** 2)) / 12.0)
    return out


def inputs_assumed(out, site, sig, gain: np.ndarray, J: np.ndarray, sigma: np.ndarray, names, T: float) -> dict:
    """The site latitude and the time-scale accuracy the reported sigma assume
    (:mod:`inscal.calibrate.systematic.sensitivity`): how far each may be off before the largest shift of a
    parameter reaches its sigma, from the last pass's gains.  ``gain``: the driver's change of prior (``P_post
    Pf^-1``), ``J`` the canonical Jacobian, ``sigma`` the reported canonical sigma."""
    lat = site.latitude
    h = 1e-4
    dg = (site.gravity_model.g(lat + h, site.height) - site.gravity_model.g(lat - h, site.height)) / (2 * h)
    sm = out.smoother
    shift = parameter_shift(sm.K_st, sm.phinn_st, sm.phinp_st, out.steps, np.asarray(sig, float),
                            forcings(lat, site.gravity, dg), T)
    can = J @ (gain @ shift)
    tol_lat, tol_time, i_lat, i_time = tolerances(can, sigma)
    labels = [f"{n}[{c}]" if c else n for n in names for c in parameter_components(n)]
    lat_deg = math.degrees(tol_lat)
    r_earth = 6.371e6
    note = (f"inputs the fit cannot check: the sigma assume the site latitude right to {lat_deg:.2g} deg "
            f"({tol_lat * r_earth:.3g} m; {labels[i_lat]} moves by its sigma beyond that) and the sample rate right to "
            f"{tol_time * 1e6:.3g} ppm ({labels[i_time]})")
    return {"latitude_deg": lat_deg, "latitude_m": tol_lat * r_earth, "latitude_parameter": labels[i_lat],
            "time_scale_ppm": tol_time * 1e6, "time_scale_parameter": labels[i_time],
            "shift_per_deg_latitude": dict(zip(labels, (can[:, 0] * math.pi / 180.0).tolist())),
            "shift_per_ppm_time_scale": dict(zip(labels, (can[:, 1] * 1e-6).tolist())),
            "rule": "the largest |shift| / sigma of a canonical parameter reaches 1 (linear, from the last pass's "
                    "gains: inscal.calibrate.systematic.sensitivity)", "note": note}


class NotConverged(CalibrationError):
    """The passes did not settle, an estimate left its prior far behind, or the navigation wandered off the static
    site: the last iterate is no calibration (``accept_unconverged`` keeps it, with a note).

    ``result``: that last iterate as the same call with ``accept_unconverged=True`` returns it (its note and
    ``diagnostics["convergence"]["accepted_unconverged"]`` included), made from the run that raised when first
    read (None where the raiser gave none); it is not pickled with the exception (a worker's error travels as
    its message)."""

    def __init__(self, message: str, result: Callable[[], CalibrationResult] | None = None):
        super().__init__(message)
        self._make, self._result = result, None

    @property
    def result(self) -> CalibrationResult | None:
        """The last iterate kept (see the class docstring), or None."""
        if self._result is None and self._make is not None:
            self._result, self._make = self._make(), None
        return self._result

    def __reduce__(self):
        return type(self), self.args


def convergence_verdict(passes: list, converged: bool, tol: float, prior_z: np.ndarray, labels: list,
                        position_max: float, truncated: bool = False) -> str:
    """Why a run's last iterate is not a calibration, in one clause ("" when it is): passes that did not
    settle (oscillating or drifting, with the last changes in sigma), an estimate beyond
    :data:`PRIOR_EXCESS` prior sigma of its nominal, or a position innovation beyond
    :data:`STATIC_POSITION_LIMIT` on a static site.  A ``truncated`` run (fewer than :data:`MIN_VERDICT_PASSES`
    passes asked for: a deliberate first iterate, as the observability report and the demo run) is judged on
    its position innovations only."""
    if position_max > STATIC_POSITION_LIMIT:
        return (f"position innovations reach {position_max:.3g} m on a static site (limit {STATIC_POSITION_LIMIT:g} m): "
                "the navigation diverged (a wrong path, rate or site, or an error far beyond the model)")
    if truncated:
        return ""
    worst = int(np.argmax(np.abs(prior_z))) if prior_z.size else 0
    if prior_z.size and abs(prior_z[worst]) > PRIOR_EXCESS:
        return (f"the estimate of {labels[worst]} lies {abs(prior_z[worst]):.3g} prior sigma from its nominal (limit "
                f"{PRIOR_EXCESS:g}): the unit is far outside the prior or the run diverged (a record that does not turn "
                "the unit leaves such states free; --accept-unconverged keeps the last iterate with a note)")
    if not converged:
        changes = [p["change_max_sigma"] for p in passes if p["change_max_sigma"] is not None]
        tail = ", ".join(f"{c:.3g}" for c in changes[-4:])
        kind = ("oscillating" if len(changes) >= 3 and changes[-1] > 0.5 * changes[-3] else "still moving")
        return (f"not converged in {len(passes)} passes ({kind}: the largest change per pass {tail} sigma, "
                f"tolerance {tol:g})")
    return ""


def systematic(ws_or_record, states: str | StateSet = "51", *, filter_rate_hz: float = 1.0, max_passes: int = 10,
               tol: float = 0.2, arw=None, vrw=None, velocity_sigma: float | None = None,
               position_sigma: float | None = None, prior: dict | None = None, history_s: float = HISTORY_S,
               align_s: float = 120.0, initial: ImuErrors | None = None, method_name: str | None = None,
               keep_passes: bool = False, encoder_sigma: float | None = None,
               encoder_every: int = 1, nis_cap: float | None = NIS_CAP, thermal_orders: dict | None = None,
               t_ref: float = T_REF_C, temperature_sensor: str = "",
               temperature_rate_window_s: float = RATE_WINDOW_S, robust: bool = True,
               weights=None, accept_unconverged: bool = False, noise=None) -> CalibrationResult:
    """Systematic calibration of a static-site rotation record (S16 section 3).

    ``states``: a :class:`StateSet` or its spec (``"51"``, ``"30"``, ``"51,lever9,async"``, ...).
    ``arw``/``vrw``: white noise [rad/sqrt(s)], [m/s/sqrt(s)] (scalar or per axis); estimated from
    the record when None.  ``prior``: prior 1 sigma per group name (SI), default
    :data:`DEFAULT_SIGMA0`.  ``initial``: linearisation start (canonical errors; default ideal).
    Gimbal states (``gimbal``/``unified``): ``encoder_sigma`` the white noise of each encoder angle
    [rad] (default :data:`ENCODER_SIGMA`, 1"), ``encoder_every`` the encoder attitude rows every n-th
    filter step (default every step); the record's ``gimbal`` dataset, else its ``path``.
    ``robust`` (default True): the velocity model-error term of :mod:`inscal.calibrate.systematic.model_error`,
    factors on the accelerometer noise per motion state and for isolated outliers, estimated from the
    innovations of the first passes and then frozen; ``nis_cap`` the NIS above which a step (at its motion
    state's factor) is an outlier (default :data:`NIS_CAP`, a 1e-6 tail of chi2(6); None: no outliers).
    ``weights``: frozen factors (a :class:`~inscal.calibrate.systematic.model_error.ModelError` or an (M,) array)
    instead of estimating them (the nested fits of ``--states auto`` share the full model's).
    ``accept_unconverged``: return the last iterate, with a note, where the run would end with
    :class:`NotConverged` (passes that do not settle within ``max_passes``, an estimate beyond
    :data:`PRIOR_EXCESS` prior sigma, position innovations beyond :data:`STATIC_POSITION_LIMIT`).
    Thermal states (``thermal``; :mod:`inscal.calibrate.systematic.thermal_states`): the record's
    ``temperature`` readings (sensor ``temperature_sensor``, default the mean of the sensors; dT/dt their
    least-squares slope over ``temperature_rate_window_s``) drive the model about ``t_ref`` [degC];
    ``thermal_orders`` (term -> order, :data:`~inscal.calibrate.systematic.states.THERMAL_TERM_NAMES`) turns
    them on with those orders.  The result's ``thermal`` is the canonical model with ``thermal_sigma``; the
    prior of each coefficient is ``THERMAL_SIGMA0`` spread over the record's span (``prior`` may name a
    coefficient group, e.g. ``gyro_bias_dT2``, in SI per degC^k).
    ``noise``: an identified noise model (:class:`inscal.core.noise_models.NoiseModel` of the six channels): its
    white terms are the white noise (unless ``arw``/``vrw`` are given) and its Gauss-Markov terms become bias
    states (:mod:`inscal.calibrate.systematic.gm_states`).
    """
    rec = ws_or_record
    p = prepare(rec, states, thermal_orders=thermal_orders, noise=noise, arw=arw, vrw=vrw,
                filter_rate_hz=filter_rate_hz, t_ref=t_ref, temperature_sensor=temperature_sensor,
                temperature_rate_window_s=temperature_rate_window_s, velocity_sigma=velocity_sigma,
                position_sigma=position_sigma, prior=prior, history_s=history_s, align_s=align_s, initial=initial,
                encoder_sigma=encoder_sigma, encoder_every=encoder_every, nis_cap=nis_cap, weights=weights,
                robust=robust)
    st, nd, sig_par = p.st, p.nd, p.sig_par
    it = filter_passes(p, max_passes, tol, keep_passes)
    out, est = it.out, it.est
    verdict = convergence_verdict(it.passes, it.converged, tol, est.error_state(st, p.nominal) / sig_par,
                                  st.labels()[nd:], float(np.max(np.abs(out.z[:out.steps, 3:]))) if out.steps else 0.0,
                                  truncated=max_passes < MIN_VERDICT_PASSES)
    x_est = est.error_state(st, p.nominal)
    term_check = None
    wider = dataclasses.replace(st, asynchrony=True, lever9=True)
    if (not verdict and robust and weights is None and max_passes >= MIN_VERDICT_PASSES and st.extended
            and not st.gimbal and wider != st and max(it.me.group_factor.values()) > 1.0):
        # the record misfits the model beyond its noise: a white model-error term accounts for the misfit only if
        # no term the states leave out drives it.  The same record with the candidate terms of --states auto added
        # says whether one does (model_error.term_shift)
        def refit():
            return systematic(rec, wider, filter_rate_hz=filter_rate_hz, max_passes=max_passes, tol=tol, arw=p.arw,
                              vrw=p.vrw, velocity_sigma=velocity_sigma, position_sigma=position_sigma, prior=prior,
                              history_s=history_s, align_s=align_s, initial=est.to_imu(), method_name=method_name,
                              nis_cap=nis_cap, t_ref=t_ref, temperature_sensor=temperature_sensor,
                              temperature_rate_window_s=temperature_rate_window_s, robust=robust)
        verdict, term_check = missing_term_check(refit, wider, st, x_est, it.P_post, nd)

    def build(accepted: bool) -> CalibrationResult:
        """The result of the last iterate (``accepted``: kept where the verdict says it is no calibration)."""
        # the result needs the forward pass's stores only; the smoothed covariances go with the pass kept for the
        # caller
        last = smooth_pass(out) if keep_passes else out
        names = estimated_names(st)
        J = canonical_jacobian(est, st, names, sig_par) / sig_par  # d(canonical) / d(physical error state)
        Sig = J @ it.P_post @ J.T
        sflat = np.sqrt(np.maximum(np.diag(Sig), 0.0))
        fixed = fixed_mask(st, names)
        sflat[fixed] = np.nan
        cost = None
        if robust and weights is None and it.me.weighted_away:
            cost = model_error_cost(p, it, J, sflat, names)
        # the prior in the same canonical components: the yardstick of what the record observed
        prior_flat = np.sqrt(np.maximum(np.einsum("ij,j,ij->i", J, sig_par**2, J), 0.0))
        unobs, unobs_note = unobservable(names, sflat, prior_flat)
        imu = est.to_imu()
        nis, dof, chisq, expected, fit = innovation_statistics(p, it, last, cost)
        formal = unflatten(sflat, names)
        sigma = unflatten(sflat * fit["scale"], names)
        assumed = None if st.gimbal else inputs_assumed(last, p.site, it.sig_used, it.P_post @ it.Pf_inv, J,
                                                        sflat * fit["scale"], names, p.T)
        diag = diagnostics(p, it, last, fit, nis, dof, chisq, expected, assumed, verdict, term_check, accepted,
                           formal, unobs, robust, weights, noise)
        notes = result_notes(p, it.me, diag["frame"], verdict, fit, assumed, unobs_note, noise)
        res = CalibrationResult(method_name or ("systematic51" if st.extended else "systematic30"), imu,
                                est.to_gimbal() if st.gimbal else GimbalErrors(), sigma, names, None, diag, notes)
        res.truth_transform = lambda truth, _st=st: (truth_imu(truth, _st), truth_gimbal(truth, _st))
        if st.gimbal:
            gimbal_diagnostics(res, last, st, p.enc_sig, int(encoder_every))
        if p.tin is not None:
            attach_thermal(res, p, it, imu, fit, chisq, dof, expected)
        h_out, h_sig = it.first
        res.history = pass_history(h_out, st, names, h_sig, J, est, it.P_post)
        res.history["time_s"] = res.history["t_steps"] * p.T
        res.states = st
        res.model_error = it.me  # the frozen model-error factors (the nested fits of --states auto share them)
        res.covariance = {"labels": st.labels()[nd:], "P": it.P_post}
        res.parameter_state = x_est  # the estimate as the filter's error state about the nominal (P_post's)
        if keep_passes:
            res.pass_output = last
        return res

    if verdict and not accept_unconverged:
        raise NotConverged(f"systematic filter: {verdict}; try --arw/--vrw with the unit's real noise, other --states, "
                           "or --accept-unconverged to keep the last iterate", result=lambda: build(True))
    return build(accept_unconverged)


def prepare(rec, states, *, thermal_orders, noise, arw, vrw, filter_rate_hz, t_ref, temperature_sensor,
            temperature_rate_window_s, velocity_sigma, position_sigma, prior, history_s, align_s, initial,
            encoder_sigma, encoder_every, nis_cap, weights, robust) -> Prepared:
    """The record checked and ready for the passes (:func:`systematic`'s options): the states, the increments,
    the noise, the priors, the coarse alignment on the first dwell, the encoder rows and the model-error start."""
    st = states if isinstance(states, StateSet) else StateSet.parse(states)
    if thermal_orders is not None:
        st = dataclasses.replace(st, thermal=thermal_orders_from(thermal_orders))
    gm_note = None
    if noise is not None:
        arw, vrw, st, gm_note = noise_setup(noise, arw, vrw, st)
    for attr in ("dtheta", "dvel", "rate_hz", "site"):
        if not hasattr(rec, attr):
            raise CalibrationError(f"systematic calibration needs a record with increments, rate and site (no {attr!r})")
    dth = np.ascontiguousarray(rec.dtheta, dtype=float)
    dv = np.ascontiguousarray(rec.dvel, dtype=float)
    if dth.ndim != 2 or dth.shape[1] != 3 or dv.shape != dth.shape:
        raise CalibrationError(f"increments must be (n, 3) arrays of equal shape, got {dth.shape} and {dv.shape}")
    if not (np.all(np.isfinite(dth)) and np.all(np.isfinite(dv))):
        raise CalibrationError("increments contain NaN or infinite values")
    rate = float(rec.rate_hz)
    dt = 1.0 / rate
    tin = None
    if st.thermal:
        tin = sample_inputs(rec, dth.shape[0], rate, t_ref, temperature_sensor, temperature_rate_window_s)
    if not (filter_rate_hz > 0 and math.isfinite(filter_rate_hz)):
        raise CalibrationError(f"filter rate must be > 0 Hz, got {filter_rate_hz}")
    n_per = samples_per_step(rate, filter_rate_hz)
    T = n_per * dt
    site = rec.site
    site_v = np.array([site.latitude, site.longitude, site.height, site.gravity_scale])
    nv = noise_levels(dth, dv, dt, T, arw, vrw, velocity_sigma, position_sigma)
    # state scaling = prior sigma
    sig0 = dict(DEFAULT_SIGMA0)
    known = list(sig0) + [g.name for g in st.groups if g.name not in sig0]
    for k, v in (prior or {}).items():
        if k not in known:
            raise CalibrationError(f"prior: unknown group {k!r}; groups: {', '.join(known)}")
        sig0[k] = float(v)
    hist_every = history_every(T, history_s)
    # coarse alignment (inertial-frame Wahba; valid while turning)

    n_al = min(dth.shape[0], max(int(round(min(align_s, dth.shape[0] * dt) * rate)), int(5 * rate) + 1))
    # ... but within the first dwell: the inertial-frame alignment is exact while turning only for
    # an ideal IMU at the table's centre; on a designed path whose first turn starts at 60 s, a
    # 120 s window gave a 25 deg heading error and a diverging first pass
    n_dwell = _first_motion(dth, dt)
    if n_dwell >= int(5 * rate) + 1:
        n_al = min(n_al, n_dwell)
    # the heading of the coarse alignment is only as good as the horizontal Earth rate it measures: with
    # white gyro noise, sigma_psi = (ARW / sqrt(window)) / (W_ie cos L).  A noisy gyro (10x the N25 unit's
    # 0.02 deg/sqrt(h)) leaves it degrees off after a minute; a prior of 1 deg about that start would be
    # 4 sigma wrong and the passes would crawl towards the truth.  The heading prior (and the mount azimuth
    # of the gimbal states, which inherits it) widens to twice that sigma when it exceeds the default.
    sigma_psi = float(np.mean(nv.arw_v)) / math.sqrt(n_al * dt) / (OMEGA_IE * max(math.cos(site.latitude), 1e-3))
    nav_sig0 = list(NAV_SIGMA0)
    nav_sig0[2] = max(nav_sig0[2], 2.0 * sigma_psi)
    if "mount_attitude" not in (prior or {}):
        sig0["mount_attitude"] = max(sig0["mount_attitude"], 2.0 * sigma_psi)
    nd = st.n_dyn  # navigation and Gauss-Markov states; the parameters follow
    sig = np.concatenate([nav_sig0, [g.sigma for g in st.gm], prior_sigma(st, sig0, tin["span"] if tin else 1.0)])
    sig_par = sig[nd:]
    start = CompParams() if initial is None else CompParams.from_imu(initial)
    nominal = CompParams()
    try:
        C0 = coarse_align(dth[:n_al], dv[:n_al], dt, site.latitude, site.height, params=start.to_imu(), at_start=True,
                          gravity=site.gravity_model)
    except ValueError as exc:
        raise CalibrationError(f"coarse alignment failed: {exc}") from None
    enc = None
    enc_sig = ENCODER_SIGMA if encoder_sigma is None else float(encoder_sigma)
    if st.gimbal:
        enc = encoder_rows(rec, dth, dt, n_per, C0, start, nominal, enc_sig, encoder_sigma, encoder_every)
    cap = np.inf if nis_cap is None else float(nis_cap)
    if not cap > 0:
        raise CalibrationError(f"nis_cap must be > 0 (or None for plain updates), got {nis_cap}")
    Msteps = dth.shape[0] // n_per
    moving = moving_steps(dth, dt, n_per, Msteps)
    if weights is not None:  # a caller's frozen factors (the nested fits of --states auto share the full model's)
        me = weights if isinstance(weights, ModelError) else ModelError(
            np.asarray(weights, float), np.ones(Msteps), {}, 0, True)
        if me.q_factor.shape[0] < Msteps:
            raise CalibrationError(f"model-error factors for {me.q_factor.shape[0]} steps, the record has {Msteps}")
    else:
        me = no_model_error(Msteps)
    frozen = weights is not None or not robust
    return Prepared(st, gm_note, arw, vrw, dth, dv, rate, dt, tin, n_per, T, site, site_v, nv, hist_every, nd, sig,
                    sig_par, start, nominal, C0, enc, enc_sig, cap, moving, me, frozen)


def noise_levels(dth, dv, dt: float, T: float, arw, vrw, velocity_sigma, position_sigma) -> NoiseLevels:
    """The white noise of the filter: given, else estimated from the record; floored, and at least the rounding
    noise of the record's quantum or float32 storage; and the zero-velocity/known-position pseudo-measurement
    noise of a filter step of ``T`` seconds."""
    est_arw, est_vrw = estimate_white_noise(dth, dv, dt)
    arw_v = np.broadcast_to(np.asarray(est_arw if arw is None else arw, float), (3,)).copy()
    vrw_v = np.broadcast_to(np.asarray(est_vrw if vrw is None else vrw, float), (3,)).copy()
    # floors: a filter tuned to (near) noise-free data loses its numerical footing; these are
    # far below navigation-grade noise (S16: 5e-5 deg/sqrt(h), 1 ug/sqrt(Hz)) ...
    floored = bool(np.any(arw_v < ARW_FLOOR) or np.any(vrw_v < VRW_FLOOR))
    arw_v = np.maximum(arw_v, ARW_FLOOR)
    vrw_v = np.maximum(vrw_v, VRW_FLOOR)
    # ... and, for a quantized record, the rounding noise of its quantum (q / sqrt(12) per increment)
    q_res = np.concatenate([data_resolution(dth), data_resolution(dv)])  # no copy of the record
    arw_q, vrw_q = q_res[:3] / math.sqrt(12.0 * dt), q_res[3:] / math.sqrt(12.0 * dt)
    # ... or of float32 storage (white, ulp / sqrt(12) per increment)
    f32 = np.concatenate([float32_rounding(dth), float32_rounding(dv)])
    arw_q = np.maximum(arw_q, f32[:3] / math.sqrt(dt))
    vrw_q = np.maximum(vrw_q, f32[3:] / math.sqrt(dt))
    resolution_floored = bool(np.any(arw_v < arw_q) or np.any(vrw_v < vrw_q))
    arw_v = np.maximum(arw_v, arw_q)
    vrw_v = np.maximum(vrw_v, vrw_q)
    qg, qa = arw_v**2, vrw_v**2
    vsig = float(velocity_sigma) if velocity_sigma is not None else 0.05 * float(np.mean(vrw_v)) * math.sqrt(T)
    psig = float(position_sigma) if position_sigma is not None else vsig * T
    r = np.array([vsig**2] * 3 + [psig**2] * 3)
    return NoiseLevels(arw_v, vrw_v, floored, resolution_floored, q_res, f32, qg, qa, vsig, psig, r)


def encoder_rows(rec, dth, dt: float, n_per: int, C0, start: CompParams, nominal: CompParams, enc_sig: float,
                 encoder_sigma, encoder_every) -> np.ndarray:
    """The encoder angles at the filter steps (NaN where a step has no encoder row); sets the mount attitude of
    ``start`` and ``nominal`` from the coarse alignment ``C0`` (N25 eq. 8)."""
    if not (math.isfinite(enc_sig) and enc_sig > 0):
        raise CalibrationError(f"encoder sigma must be > 0, got {encoder_sigma}")
    if int(encoder_every) != encoder_every or encoder_every < 1:
        raise CalibrationError(f"encoder_every must be a whole number >= 1, got {encoder_every}")
    ang = encoder_angles(rec, dth.shape[0], dt)
    Msteps = dth.shape[0] // n_per
    enc = ang[(np.arange(Msteps) + 1) * n_per - 1].copy()
    enc[np.arange(Msteps) % int(encoder_every) != 0] = np.nan
    if not np.all(np.isfinite(ang[0])):
        raise CalibrationError("the gimbal states need the encoder angles at the first sample (the mount attitude "
                               "starts from the coarse alignment there)")
    # N25 eq. 8 at the start: C_b^n = C_s^n (Rot(u, tx) R_z(tz))^T with dth = the start value
    mount0 = mount_from_attitude(C0, ang[0], start.gim[0])
    start.gim = np.concatenate([start.gim[:1], mount0])
    nominal.gim = np.concatenate([[0.0], mount0])
    return enc


def filter_passes(p: Prepared, max_passes: int, tol: float, keep_passes: bool) -> Passes:
    """The iterated filter passes with prior deflation, each changed back to the prior about the nominal, and the
    model-error factors set from the innovations of the first passes, until a pass moves the estimate by less than
    ``tol`` sigma with the weights that stay (or ``max_passes``)."""
    st, nd, nominal, sig, sig_par, nv = p.st, p.nd, p.nominal, p.sig, p.sig_par, p.noise
    C0, me, frozen, cap = p.C0, p.me, p.frozen, p.cap
    updates = 0
    passes = []
    p_start = p.start
    prev = None
    converged = False
    inv_prior = 1.0 / sig_par**2
    sig_pass = sig.copy()
    first = None
    rs_scaled = nv.r / sig[3:N_NAV] ** 2
    qam = float(np.mean(nv.qa))
    for ip in range(max_passes):
        out = None  # the last pass's per-step stores go before this one allocates its own: one pass's worth at a time
        sig_used = sig_pass
        try:
            out = run_pass(p.dth, p.dv, p.dt, p.n_per, C0, p.site_v, p_start, st, sig_pass, nv.qg, nv.qa, nv.r,
                           p.hist_every, keep_phi=keep_passes, smooth=False, enc=p.enc, enc_sigma=p.enc_sig,
                           nis_cap=cap if (updates == 0 and ip < LAST_BOUNDED_PASS) else np.inf,
                           temperature=None if p.tin is None else (p.tin["dT"], p.tin["rate"]), q_factor=me.q_factor,
                           r_factor=me.r_factor)
        except np.linalg.LinAlgError:
            raise CalibrationError(
                f"systematic filter: numerical failure in pass {ip + 1} (the covariance lost its positive "
                f"definiteness; ARW {units.from_si(float(np.min(nv.arw_v)), 'deg/sqrt(h)'):.3g} .. "
                f"{units.from_si(float(np.max(nv.arw_v)), 'deg/sqrt(h)'):.3g} deg/sqrt(h), VRW "
                f"{units.from_si(float(np.min(nv.vrw_v)), 'ug/sqrt(Hz)'):.3g} .. "
                f"{units.from_si(float(np.max(nv.vrw_v)), 'ug/sqrt(Hz)'):.3g} ug/sqrt(Hz): a noise far from the "
                "data's, or a record the filter cannot follow; try --arw/--vrw)") from None
        if not (np.all(np.isfinite(out.Pf)) and np.all(np.isfinite(out.params.error_state(st, nominal)))):
            raise CalibrationError(f"systematic filter diverged in pass {ip + 1} (non-finite state): the linearisation "
                                   "is too far from the data (a coarse alignment off, or errors beyond the priors)")
        sp = sig_pass[nd:]
        Pf_inv, P_post, est, sig_post = change_of_prior(out, sp, nd, inv_prior, p_start, st, nominal)
        phi0 = out.x0s[:3] * sig_pass[:3]
        C0 = dcm_from_quat(quat_from_rotvec(-phi0)) @ C0
        if first is None:  # its history needs only the smoothed states at the stored rows (run_pass has them)
            first = (out.without_stores() if max_passes > 1 else out, sig_pass.copy())
        change = None if prev is None else float(np.max(np.abs(est.error_state(st, prev)) / np.maximum(sig_post, 1e-300)))
        passes.append({"pass": ip + 1, "nis_mean": float(np.mean(out.nis)), "change_max_sigma": change,
                       "downweighted_steps": int(np.sum(out.q_used[:out.steps] > me.q_factor[:out.steps])),
                       "position_innovation_max_m": float(np.max(np.abs(out.z[:out.steps, 3:]))) if out.steps else 0.0,
                       "model_error": me.as_dict() | {"frozen": bool(frozen)},
                       "prior_deflation": float(np.max(sig_par / sp)),
                       "prior_excess_sigma": float(np.max(np.abs(est.error_state(st, nominal)) / sig_par))})
        # The passes before the model-error term exists run with bounded influence (R inflated where a step's NIS
        # passes the cap): a safety net against a numerical failure.  The first pass linearises about the nominal
        # parameters, and its innovations show that start, not the record: the factors come from the second pass
        # on, once a pass changed the estimate by less than FACTOR_CHANGE sigma.
        capped = bool(np.any(out.q_used[:out.steps] > me.q_factor[:out.steps]))
        kept = True  # this pass's factors stay for the next one
        near = change is not None and change < FACTOR_CHANGE  # this pass linearised near its end point
        if not frozen and ip + 1 >= FIRST_FACTOR_PASS and (near or ip + 1 >= LAST_BOUNDED_PASS):
            updates += 1  # the model-error factors of the next pass, from this pass's innovations (model_error)
            Si = out.smoother.Si_st[:out.steps]
            D = sig_pass[3:N_NAV]
            S_raw = np.linalg.inv(Si) * np.outer(D, D)[None]
            expected_k = 6.0 - np.diagonal(Si, axis1=1, axis2=2) @ rs_scaled
            new = update_factors(me, S_raw, out.z[:out.steps], expected_k, p.moving, qam, p.T, nv.r, out.r_factor,
                                 out.q_used, cap)
            if new.settled:
                frozen = True  # the factors this pass ran with stand
            else:
                me, kept = new, False
                frozen = updates >= WEIGHT_PASSES
        # converged: this pass ran with the weights that stay (no step capped, factors kept) and moved the estimate
        # by less than tol sigma from its start, the previous pass's estimate: it is the fixed point of one weighted
        # least-squares problem to the tolerance (the previous pass's weights do not enter)
        if change is not None and change < tol and kept and not capped:
            converged = True
            p_start = est
            break
        prev = est
        p_start = est
        # next pass: prior widths of at most DEFLATE posterior sigmas about the new start (its
        # information is removed again above), which keeps the covariance's range ~1e4 instead of ~1e10
        sig_pass = sig.copy()
        sig_pass[nd:] = np.minimum(sig_par, DEFLATE * np.maximum(sig_post, 1e-6 * sig_par))
    return Passes(out, est, p_start, C0, P_post, Pf_inv, sig_used, me, passes, converged, first)


def change_of_prior(out, sp: np.ndarray, nd: int, inv_prior: np.ndarray, p_start: CompParams, st: StateSet,
                    nominal: CompParams) -> tuple:
    """A pass's data information about its start, and the posterior with the prior about the nominal:
    (Pf^-1, P, the estimate, its sigma)."""
    # This pass ran with the prior N(p_start, diag(sp^2)) (deflated after pass 1 for numerical range).
    # Exact linear-Gaussian change of prior to N(nominal, diag(sig0^2)): data information
    # L_d = Pf^-1 - diag(sp^-2), posterior P = (L_d + diag(sig0^-2))^-1,
    # x = P (Pf^-1 x' + diag(sig0^-2) mu) with x' the pass's total correction and mu = p_start - nominal.
    # P_pp = U_pp U_pp^T (U upper triangular, navigation first): its inverse from the factor, which has
    # half the dynamic range of P
    Ui = solve_triangular(out.Uf[nd:, nd:], np.eye(sp.shape[0]))
    Pf_inv = (Ui.T @ Ui) / np.outer(sp, sp)
    Pf_inv = 0.5 * (Pf_inv + Pf_inv.T)
    L_d = Pf_inv - np.diag(1.0 / sp**2)
    P_post = np.linalg.inv(L_d + np.diag(inv_prior))
    P_post = 0.5 * (P_post + P_post.T)
    x_pass = p_start.error_state(st, out.params)  # estimate(start) - estimate(end) = the correction
    mu = p_start.error_state(st, nominal)
    x_post = P_post @ (Pf_inv @ x_pass + inv_prior * mu)
    est = out.params.corrected(st, x_post - x_pass)
    sig_post = np.sqrt(np.maximum(np.diag(P_post), 0.0))
    return Pf_inv, P_post, est, sig_post


def missing_term_check(refit, wider: StateSet, st: StateSet, x_est, P_post, nd: int) -> tuple:
    """Whether a term the states leave out drives the estimate of a misfitting record: ``refit()`` the same record
    with the ``wider`` states (model_error.term_shift).  Returns (verdict or None, the check's diagnostics)."""
    verdict = None
    try:
        big = refit()
    except CalibrationError as exc:
        term_check = {"done": False, "why": str(exc), "states": state_spec(wider)}
    else:
        labels = st.labels()[nd:]
        z = term_shift(x_est, P_post, labels, big.parameter_state, big.covariance["P"], big.covariance["labels"])
        worst = int(np.argmax(z))
        term_check = {"done": True, "states": state_spec(wider), "shift_max_sigma": float(z[worst]),
                      "state": labels[worst], "limit": TERM_SHIFT_LIMIT,
                      "model_error_with_terms": big.model_error.as_dict()}
        if z[worst] > TERM_SHIFT_LIMIT:
            verdict = (f"the record misfits the model beyond its noise and a term the states leave out drives the "
                       f"estimate: with --states {state_spec(wider)} {labels[worst]} moves {z[worst]:.3g} sigma "
                       f"(limit {TERM_SHIFT_LIMIT:g}); calibrate with those states or --states auto")
    return verdict, term_check


def model_error_cost(p: Prepared, it: Passes, J, sflat, names) -> dict | None:
    """What the model-error term costs (its last resort): each group's sigma against the bound without it, the
    same record and linearisation with every factor 1 (the filter's posterior of the record at the noise
    assumed); None where that pass fails."""
    nd, nv = p.nd, p.noise
    try:
        plain = run_pass(p.dth, p.dv, p.dt, p.n_per, it.C0, p.site_v, it.p_start, p.st, it.sig_used, nv.qg, nv.qa,
                         nv.r, p.hist_every, smooth=False, enc=p.enc, enc_sigma=p.enc_sig,
                         temperature=None if p.tin is None else (p.tin["dT"], p.tin["rate"]))
        spu = it.sig_used[nd:]
        Uiu = solve_triangular(plain.Uf[nd:, nd:], np.eye(spu.shape[0]))
        Pfu = (Uiu.T @ Uiu) / np.outer(spu, spu)
        P_bound = np.linalg.inv(0.5 * (Pfu + Pfu.T) - np.diag(1.0 / spu**2) + np.diag(1.0 / p.sig_par**2))
        s_bound = unflatten(np.sqrt(np.maximum(np.diag(J @ P_bound @ J.T), 0.0)), names)
        s_now = unflatten(sflat, names)
        return {n: float(np.nanmax(np.asarray(s_now[n], float) / np.asarray(s_bound[n], float)))
                for n in names if np.any(np.isfinite(np.asarray(s_now[n], float)))}
    except (np.linalg.LinAlgError, CalibrationError):
        return None


def innovation_statistics(p: Prepared, it: Passes, last, cost: dict | None) -> tuple:
    """The innovation statistics of the last pass (normalised innovation squared; dof = 6 per step) and the fit:
    (NIS, dof, chi2, its expectation, the fit with the model-error term's notes)."""
    me, nv = it.me, p.noise
    nis = last.nis
    dof = 6 * last.steps
    chisq = float(np.sum(nis))
    # expectation of the chi2: the zero-velocity/known-position pseudo-measurement noise R regularises the
    # filter but is not in a static record's data, so E[nu^T S^-1 nu] = 6 - tr(S^-1 R) per step (the
    # encoder rows' expectation is formed the same way); steps down-weighted by the cap count 6
    rs_scaled = nv.r / p.sig[3:N_NAV] ** 2
    Si_diag = np.diagonal(last.smoother.Si_st[:last.steps], axis1=1, axis2=2)
    per_step = 6.0 - Si_diag @ rs_scaled
    per_step[last.q_used[:last.steps] > me.q_factor[:last.steps]] = 6.0  # bounded steps (a jump): their own
    # NIS is that of the nominal model
    expected = float(np.sum(per_step))
    floor_words = None
    if nv.floored and p.arw is None and p.vrw is None:  # the record's own noise, estimated, is below the floors
        floor_words = (f"ARW {units.from_si(ARW_FLOOR, 'deg/sqrt(h)'):.2g} deg/sqrt(h), VRW "
                       f"{units.from_si(VRW_FLOOR, 'ug/sqrt(Hz)'):.2g} ug/sqrt(Hz)"
                       + ("; the record is float32" if np.any(nv.f32 > 0) else "")
                       + ("; the record is quantized" if np.any(nv.q_res > 0) else ""))
    fit = innovation_fit(nis, last.z, p.T, chisq, dof, p.st, misfit_signature(nis, p.dth, p.dt, p.n_per), expected,
                         floor_words)
    if any(f > 1.0 for f in me.group_factor.values()):
        # the chi2 is of the model with its velocity model-error term, estimated to fit: the model as given
        # misfits the record beyond its noise (model_error), which the fit says; the sigma of the weighted
        # filter carry the misfit already (not scaled again unless the chi2 itself rejects)
        fit["consistent"] = False
        fit["cause"] = fit["cause"] or "model error: the record misfits the model beyond its noise"
        fit["model_error"] = me.as_dict()
        fit["note"] = (fit["note"] + "; " if fit["note"] else "") + model_error_note(me, int(np.sum(p.moving)))
    if cost:
        top = sorted(cost.items(), key=lambda kv: -kv[1])[:3]
        fit["model_error_cost"] = cost
        fit["note"] = ((fit["note"] + "; " if fit["note"] else "") + "the model-error term costs the sigma (against the "
                       "bound without it): " + ", ".join(f"{n} x{v:.3g}" for n, v in top))
    return nis, dof, chisq, expected, fit


def attach_thermal(res: CalibrationResult, p: Prepared, it: Passes, imu: ImuErrors, fit: dict, chisq: float,
                   dof: int, expected: float) -> None:
    """The thermal states' canonical model, its fit and diagnostics on ``res``
    (:mod:`inscal.calibrate.systematic.thermal_states`)."""
    st, tin, sig_par, P_post, diag = p.st, p.tin, p.sig_par, it.P_post, res.diagnostics
    o = thermal_offset(st)
    res.thermal, res.thermal_sigma, table, th_notes = thermal_result(it.est, st, P_post[o:, o:], sig_par[o:],
                                                                     fit["scale"], imu, tin, P_all=P_post,
                                                                     prior_all=sig_par)
    res.thermal_fit = {"method": "thermal states of the systematic filter (one run)", "chi2": chisq, "dof": dof,
                       "expected_chi2": expected, "p_value": diag["innovations"]["p_value"],
                       "consistent": fit["consistent"], "scale": fit["scale"]}
    diag["thermal"] = {"t_ref": tin["t_ref"], "t_min": tin["t_min"], "t_max": tin["t_max"], "span": tin["span"],
                       "rate_max_c_per_min": 60.0 * tin["rate_max"], "sensor": tin["sensor"],
                       "rate_window_s": tin["rate_window_s"],
                       "orders": dict(zip(("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor",
                                           "gyro_bias_rate"), st.thermal)),
                       "coefficients": table}
    res.notes += th_notes
    if st.thermal[-1] and not reverses(tin["rate"]):
        res.notes.append(
            "the temperature never falls (or never rises) at a rate of note: the gyro bias's dT/dt term is told from "
            "its polynomial in T only where the rate changes (the ends of a ramp), and over seeds of thermal-ramp "
            "their sigma undercover (RMS error/sigma 1.2-1.4; bench/thermal_ramp.py); a profile that crosses each "
            "temperature both ways (thermal-cycle: in band) separates them")
