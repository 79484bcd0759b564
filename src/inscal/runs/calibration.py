"""One calibration of one record, exactly as ``inscal calibrate`` runs it: the options that decide
the result (:class:`CalibrationSetup`, checked up front), the memory the record asks for, the
check of its encoder angles against the gyros (:mod:`inscal.io.encoders`), the gravity model, the
estimator and the parameter file's metadata.  ``inscal calibrate`` and a batch of calibrations
(:mod:`inscal.runs.batch`) both call :func:`calibrate_record`, so the same record with the same
options gives the same parameter file (:func:`inscal.lab.record.param_file_text`) either way.

This module loads the estimators (numba, SciPy): import it where a record is calibrated (:mod:`inscal.runs`).
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.calibrate import METHODS, NO_TABLE_METHODS, PLATEAU_METHODS, RECORD_METHODS, calibrate, window_means
from inscal.calibrate.fit import fit_note
from inscal.calibrate.systematic.driver import samples_per_step, systematic_bytes
from inscal.calibrate.systematic.gm_states import gm_states, noise_setup
from inscal.calibrate.systematic.states import StateSet
from inscal.calibrate.window_noise import slow_terms
from inscal.calibrate.systematic.selection import largest_states
from inscal.calibrate.thermal import CHAMBER_LABEL, PLATEAU_TOL_C, check_orders
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.earth import parse_gravity
from inscal.io.checks import saturated_samples
from inscal.io.encoders import apply_latency, check_record_encoders, small_latency
from inscal.io.noisefile import NoiseFileError, noise_document, read_noise
from inscal.io.recordfile import load_record  # noqa: F401  (the batch's, re-exported)
from inscal.io.records import Record, RecordInfo, record_attrs
from inscal.lab.record import calibration_options


#: the bounds of the options (beyond them no calibration is sensible, whatever the record)
MAX_FILTER_RATE_HZ = 1000.0  # the systematic filter's update rate [Hz] (at most the record's rate, too)
MAX_ENCODER_SIGMA = 3600.0  # white noise of an encoder angle [arcsec] (1 deg)
MAX_ARW = 100.0  # [deg/sqrt(h)]
MAX_VRW = 1e5  # [ug/sqrt(Hz)]
MAX_WINDOW_S = 86400.0  # --settle-s, --min-static-s [s]
MAX_TREMOR_DPS = 100.0  # --tremor-dps [deg/s rms]: beyond it a "pose" is a move
#: the plausible estimates of a working inertial sensor, whatever the method: scale factors within +-50 %,
#: misalignments (installation angles) within 5 deg; beyond them the data, not the sensor, is at fault
MAX_SCALE_FACTOR = 0.5
MAX_MISALIGNMENT_RAD = math.radians(5.0)


#: the options of the no-turntable methods the command line gives: name -> (flag, lower bound (excluded),
#: upper bound, factor to the flag's unit, unit); face_tilt and turn_closure may also be 0 (exact)
NO_TABLE_OPTIONS = {"alpha": ("--alpha", 0.0, 0.1, 1.0, ""),
                    "gravity_tol": ("--gravity-tol", 0.0, 0.9, 1.0, ""),
                    "face_tilt": ("--face-tilt-deg", 0.0, math.radians(10.0), math.degrees(1.0), "deg"),
                    "min_turn_end": ("--min-turn-end-s", 0.0, MAX_WINDOW_S, 1.0, "s"),
                    "turn_tol_deg": ("--turn-tol-deg", 0.0, 179.0, 1.0, "deg"),
                    "turn_closure": ("--turn-closure-deg", 0.0, math.radians(10.0), math.degrees(1.0), "deg")}


class RecordError(ValueError):
    """A calibration option refused, or a record that cannot be calibrated with the options: one line."""


@dataclass(frozen=True)
class CalibrationSetup:
    """The options of a calibration, as ``inscal calibrate`` takes them (field units: ``arw``
    deg/sqrt(h), ``vrw`` ug/sqrt(Hz), ``encoder_sigma`` arcsec; times in s): ``states``, ``arw``,
    ``vrw``, ``encoder_sigma`` and ``filter_rate_hz`` apply to the systematic methods, ``settle`` and
    ``min_static`` to the window-mean and the no-turntable ones (None: the method's own default, that of
    its function's signature: 1 s and 20 s for a turntable's windows, 0.25 s and 1 s (``multi-position``: hand-held
    poses of 2 s keep about 1.5 s once settled) or 2 s (``ferraris``) for the still poses; :attr:`window_options`), ``quadratic`` (the quadratic
    accelerometer terms) to ``multi-position``; ``gravity`` (wgs84 | psins | m/s^2) overrides the
    record's gravity model; ``encoder_latency`` shifts the encoder angles [s]; ``check_encoders``
    compares them with the gyros before calibrating.  A plateau method (``thermal-plateaus``) runs
    ``per_plateau`` (default n25) on each temperature plateau with the options above that apply to it, then
    fits the thermal model: ``thermal_orders`` ((term, order) pairs over
    :data:`inscal.calibrate.thermal.method.DEFAULT_ORDERS`), ``t_ref`` [degC], ``plateau_tol`` [degC],
    ``temperature_sensor`` ("" = the mean of the record's sensors) and ``chamber_label``."""

    method: str
    states: str | None = None
    settle: float | None = None
    min_static: float | None = None
    filter_rate_hz: float = 1.0
    arw: float | None = None
    vrw: float | None = None
    gravity: str | None = None
    encoder_sigma: float | None = None
    encoder_latency: float = 0.0
    check_encoders: bool = True
    per_plateau: str | None = None
    thermal_orders: tuple[tuple[str, int], ...] = ()
    t_ref: float | None = None
    plateau_tol: float = PLATEAU_TOL_C
    temperature_sensor: str = ""
    chamber_label: str = CHAMBER_LABEL
    accept_unconverged: bool = False  # systematic: keep the last iterate of a run that did not converge (a note)
    quadratic: bool = False  # multi-position: the quadratic accelerometer terms too (12 parameters, >= 12 poses)
    noise: str | None = None  # systematic: an identified noise model (noise.toml): white noise and GM bias states
    #: no-turntable methods: keyword options of the method's function given explicitly, ((name, value), ...) in
    #: its units (alpha, gravity_tol; ferraris: face_tilt, turn_closure [rad], min_turn_end [s], turn_tol_deg);
    #: NO_TABLE_OPTIONS
    method_options: tuple[tuple[str, float], ...] = ()
    tremor: float | None = None  # multi-position: the hand tremor a still pose may hold [deg/s rms] (None: the default)

    @property
    def systematic(self) -> bool:
        """Whether the method reads the record itself (the systematic filter and ``unified``)."""
        return self.method in RECORD_METHODS

    @property
    def plateaus(self) -> bool:
        """Whether the method runs another one per temperature plateau (``thermal-plateaus``)."""
        return self.method in PLATEAU_METHODS

    @property
    def inner(self) -> str:
        """The method that reads the increments: ``per_plateau`` (default n25) for a plateau method."""
        return (self.per_plateau or "n25") if self.plateaus else self.method

    @property
    def inner_systematic(self) -> bool:
        """Whether the method that reads the increments is a systematic one (its options apply)."""
        return self.inner in RECORD_METHODS

    @property
    def window_options(self) -> dict:
        """``settle`` and ``min_static`` [s] of a window-mean or no-turntable method, a None replaced by
        the default of the function that uses it (:func:`~inscal.calibrate.window_means`, or the
        no-turntable method itself); ``quadratic`` for ``multi-position`` when asked."""
        fn = METHODS.get(self.inner) if self.inner in NO_TABLE_METHODS else window_means
        sig = inspect.signature(fn).parameters
        out = {k: float(sig[k].default if v is None else v) for k, v in (("settle", self.settle),
                                                                         ("min_static", self.min_static))}
        if self.quadratic:
            out["quadratic"] = True
        out.update({k: float(v) for k, v in self.method_options})
        if self.tremor is not None:
            out["tremor"] = units.to_si(float(self.tremor), "deg/s")
        return out

    def method_options_problem(self) -> str | None:
        """The one-line refusal of a no-turntable method's option (``method_options``) the method does not take
        or whose value is out of its range (:data:`NO_TABLE_OPTIONS`), else None."""
        for name, v in self.method_options:
            flag, lo, hi, scale, unit = NO_TABLE_OPTIONS[name]
            fn = METHODS.get(self.inner)
            if self.inner not in NO_TABLE_METHODS or name not in inspect.signature(fn).parameters:
                takes = [m for m in sorted(NO_TABLE_METHODS) if name in inspect.signature(METHODS[m]).parameters]
                return f"{flag} applies to --method {' and '.join(takes)}, not {self.inner}"
            zero = name in ("face_tilt", "turn_closure")  # 0: exact faces, exact turns
            if not (math.isfinite(v) and (lo <= v if zero else lo < v) and v <= hi):
                return (f"{flag} must be in {'[' if zero else '('}{lo * scale:g}, {hi * scale:g}]"
                        f"{' ' + unit if unit else ''}, got {v * scale:g}")
        return None

    def problem(self, plots: bool = False) -> str | None:
        """The one-line refusal of a bad option (``plots``: convergence plots are asked for), None if
        the options are usable; checked before any record is read."""
        if self.method not in METHODS:
            return f"unknown method {self.method!r}; choose one of: {', '.join(METHODS)}"
        if (msg := self.thermal_problem()) is not None:
            return msg
        if plots and not self.systematic:
            return f"--plots applies to the systematic methods, not {self.method}"
        if self.quadratic and self.inner != "multi-position":
            return f"--quadratic applies to --method multi-position, not {self.inner}"
        if self.tremor is not None and self.inner != "multi-position":
            return f"--tremor-dps applies to --method multi-position, not {self.inner}"
        if self.tremor is not None and not (math.isfinite(self.tremor) and 0 <= self.tremor <= MAX_TREMOR_DPS):
            return f"--tremor-dps must be a tremor rate of 0 .. {MAX_TREMOR_DPS:g} deg/s rms, got {self.tremor}"
        for name, v in (("--settle-s", self.settle), ("--min-static-s", self.min_static)):
            if v is not None and not (math.isfinite(v) and v >= 0):
                return f"{name} must be a duration >= 0 s, got {v}"
        if (msg := self.method_options_problem()) is not None:
            return msg
        if self.accept_unconverged and not self.inner_systematic:
            return f"--accept-unconverged applies to the systematic methods, not {self.inner}"
        if not self.inner_systematic and (self.states or self.arw is not None or self.vrw is not None
                                          or self.encoder_sigma is not None):
            return f"--states, --plots, --arw, --vrw and --encoder-sigma apply to the systematic methods, not {self.inner}"
        if (msg := self.noise_problem()) is not None:
            return msg
        for name, v, hi, unit in (("--arw", self.arw, MAX_ARW, "deg/sqrt(h)"), ("--vrw", self.vrw, MAX_VRW, "ug/sqrt(Hz)")):
            if v is not None and not (math.isfinite(v) and 0 < v <= hi):
                return f"{name} must be a white-noise level > 0 and at most {hi:g} {unit}, got {v}"
        if not (math.isfinite(self.filter_rate_hz) and 0 < self.filter_rate_hz <= MAX_FILTER_RATE_HZ):
            return (f"--filter-rate-hz must be > 0 and at most {MAX_FILTER_RATE_HZ:g} Hz (and the record's rate), got "
                    f"{self.filter_rate_hz}")
        if self.encoder_sigma is not None and not (np.isfinite(self.encoder_sigma)
                                                   and 0 < self.encoder_sigma <= MAX_ENCODER_SIGMA):
            return f"--encoder-sigma must be in (0, {MAX_ENCODER_SIGMA:g}] arcsec, got {self.encoder_sigma}"
        if self.settle is not None and not (math.isfinite(self.settle) and 0 <= self.settle <= MAX_WINDOW_S):
            return f"--settle-s must be 0 .. {MAX_WINDOW_S:g} s, got {self.settle}"
        if self.min_static is not None and not (math.isfinite(self.min_static) and 0 < self.min_static <= MAX_WINDOW_S):
            return f"--min-static-s must be > 0 and at most {MAX_WINDOW_S:g} s, got {self.min_static}"
        if not self.inner_systematic:
            win = self.window_options  # a None is the method's own default
            if 2 * win["settle"] >= win["min_static"]:
                return (f"--settle-s {win['settle']:g} drops {2 * win['settle']:g} s of every window, all of the "
                        f"shortest one used (--min-static-s {win['min_static']:g}): lower --settle-s or raise "
                        "--min-static-s")
        if (msg := self.states_problem()) is not None:
            return msg
        if not math.isfinite(self.encoder_latency) or abs(self.encoder_latency) > 1.0:
            return f"--encoder-latency must be a finite shift of at most 1 s, got {self.encoder_latency}"
        if self.gravity is not None:
            try:
                parse_gravity(self.gravity)
            except ValueError as exc:
                return f"--gravity: {exc}"
        return None

    def states_problem(self) -> str | None:
        """The one-line refusal of a ``--states`` that is not a state set of the method, else None: its syntax
        (an empty list, an unknown option), and a base (51, 30) other than the method's."""
        if self.states is None:
            return None
        toks = [t.strip() for t in str(self.states).replace("+", ",").split(",")]
        if not any(toks):
            return f"--states {self.states!r}: empty; give auto, 51 or 30 and options (e.g. 51,lever9 or auto,psins)"
        if not all(toks):
            return f"--states {self.states!r}: an empty option between commas"
        base = {"systematic30": "30", "unified": "unified"}.get(self.inner, "51")
        other = [t for t in toks if t in ("51", "30", "unified") and t != base and not (base == "unified" and t == "51")]
        if other:
            return (f"--states {self.states}: the state set {other[0]} is not that of --method {self.inner} "
                    f"({'51,gimbal' if base == 'unified' else base}); use --method "
                    f"{'systematic30' if other[0] == '30' else 'systematic51'} for it")
        try:
            largest_states(base, self.states)
        except CalibrationError as exc:
            return f"--states {self.states}: {exc}"
        return None

    def thermal_problem(self) -> str | None:
        """The one-line refusal of a bad plateau option (or of one given to another method), else None."""
        given = [n for n, v in (("--per-plateau", self.per_plateau), ("--thermal-order", self.thermal_orders or None),
                                ("--t-ref", self.t_ref), ("--plateau-tol", None if self.plateau_tol == PLATEAU_TOL_C
                                                          else self.plateau_tol),
                                ("--temperature-sensor", self.temperature_sensor or None),
                                ("--chamber-label", None if self.chamber_label == CHAMBER_LABEL else self.chamber_label))
                 if v is not None]
        if not self.plateaus:
            return f"{', '.join(given)}: for --method thermal-plateaus, not {self.method}" if given else None
        if self.inner not in METHODS or self.inner in PLATEAU_METHODS:
            return (f"--per-plateau {self.inner!r}: not a method to run on each plateau; choose one of: "
                    f"{', '.join(m for m in METHODS if m not in PLATEAU_METHODS)}")
        try:
            check_orders(dict(self.thermal_orders))
        except CalibrationError as exc:
            return f"--thermal-order: {exc}"
        if self.t_ref is not None and not (math.isfinite(self.t_ref) and -100.0 < self.t_ref < 200.0):
            return f"--t-ref {self.t_ref}: not a temperature in degC"
        if not (math.isfinite(self.plateau_tol) and self.plateau_tol > 0):
            return f"--plateau-tol must be > 0 degC, got {self.plateau_tol}"
        return None

    def thermal_options(self) -> dict:
        """The options of :func:`inscal.calibrate.thermal.thermal_plateaus` (empty for other methods)."""
        if not self.plateaus:
            return {}
        return {"per_plateau": self.inner, "orders": dict(self.thermal_orders),
                "t_ref": 20.0 if self.t_ref is None else float(self.t_ref), "plateau_tol": float(self.plateau_tol),
                "sensor": self.temperature_sensor, "chamber_label": self.chamber_label}

    def noise_problem(self) -> str | None:
        """The one-line refusal of ``--noise`` (a noise.toml the calibration cannot use), None if usable."""
        if self.noise is None:
            return None
        if self.inner in NO_TABLE_METHODS:
            return f"--noise applies to the systematic and the turntable window methods, not {self.inner}"
        if self.arw is not None or self.vrw is not None:
            return "--noise gives the white noise: drop --arw/--vrw, or drop --noise"
        try:
            model = self.noise_model()
        except (NoiseFileError, OSError) as exc:
            return f"--noise: {exc}"
        try:
            st = StateSet.parse(None if self.states in (None, "auto") else self.states.replace("auto", "51"))
        except CalibrationError:  # a bad --states is refused on its own
            st = StateSet()
        try:
            if self.inner_systematic:
                noise_setup(model, None, None, st)
            else:
                slow_terms(model)
        except CalibrationError as exc:
            return f"--noise {self.noise}: {exc}"
        return None

    def noise_model(self):
        """The :class:`~inscal.core.noise_models.NoiseModel` of ``--noise`` (None without it)."""
        return None if self.noise is None else read_noise(self.noise)[0]

    def options(self) -> dict:
        """The canonical options (:func:`inscal.lab.record.calibration_options`): what identifies "the
        same calibration of the same record" in the database."""
        win = {} if self.inner_systematic else self.window_options
        opts = calibration_options(self.method, states=self.states, settle=win.get("settle", 1.0),
                                   min_static=win.get("min_static", 20.0),
                                   filter_rate_hz=self.filter_rate_hz, arw=self.arw, vrw=self.vrw, gravity=self.gravity,
                                   encoder_sigma=self.encoder_sigma, encoder_latency=self.encoder_latency,
                                   check_encoders=self.check_encoders, systematic=self.inner_systematic)
        if win.get("quadratic"):
            opts["quadratic"] = True
        for name, v in self.method_options:  # in the flag's unit, named as the flag (face_tilt_deg, min_turn_end_s)
            flag, _, _, scale, _ = NO_TABLE_OPTIONS[name]
            opts[flag.lstrip("-").replace("-", "_")] = float(v) * scale
        if self.tremor is not None:
            opts["tremor_dps"] = float(self.tremor)
        if self.noise is not None:  # the model itself, not the file's name, decides the result
            opts["noise_model"] = noise_document(self.noise_model())["channel"]
        th = self.thermal_options()
        if th:
            opts.update(per_plateau=th["per_plateau"], thermal_orders=check_orders(th["orders"]), t_ref_c=th["t_ref"],
                        plateau_tol_c=th["plateau_tol"], temperature_sensor=th["sensor"],
                        chamber_label=th["chamber_label"])
        return opts

    def memory_needs(self, info: RecordInfo, name: str) -> list[tuple[float, str, str]]:
        """What calibrating the record of ``info`` (called ``name`` in the messages) holds in memory at
        its peaks, ``[(bytes, what, hint)]``: the record read, then the systematic filter's per-step stores."""
        if not (math.isfinite(info.rate_hz) and info.rate_hz > 0):
            return []
        n, rate = info.n_samples, info.rate_hz
        what = f"{name} ({n} samples, {n / rate:.4g} s at {rate:g} Hz)"
        # float64 time, increments and encoder angles, and at the peak a working copy's worth (measured: 104 B
        # per sample in the encoder check, 80 B in the window means; the systematic driver's own below)
        held = 8.0 * (7 + (2 if info.has_gimbal else 0)) * n
        out = [(held + 104.0 * n, f"reading {what}", "calibrate a shorter record")]
        try:
            st = largest_states({"systematic30": "30", "unified": "unified"}.get(self.inner, "51"), self.states) \
                if self.inner_systematic else None
        except CalibrationError:
            st = None  # the calibration names the bad state set
        if st is not None and self.noise is not None:  # the model's Gauss-Markov states too
            try:
                st = dataclasses.replace(st, gm=gm_states(self.noise_model()))
            except (CalibrationError, NoiseFileError, OSError):
                pass  # refused by noise_problem before
        if st is not None:
            steps = n // samples_per_step(rate, self.filter_rate_hz)
            out.append((held + systematic_bytes(n, rate, st, self.filter_rate_hz),
                        (f"the {st.n_states}-state filter's {steps} steps at --filter-rate-hz {self.filter_rate_hz:g} "
                         f"over {what}"),
                        ("lower --filter-rate-hz (the default 1 Hz suits a turntable record) or calibrate a shorter "
                         "record")))
        return out


@dataclass(frozen=True)
class Calibrated:
    """A record calibrated: the :class:`~inscal.calibrate.CalibrationResult`, the record as calibrated
    (its site with the gravity model used), the parameter file's ``metadata`` and the encoder check's
    summary (None without encoder angles or without the check)."""

    result: object
    record: Record
    metadata: dict
    encoders: dict | None


def implausible(res, setup: CalibrationSetup) -> str | None:
    """The one-line refusal of estimates no working sensor has (a scale factor beyond +-50 %, a misalignment
    beyond 5 deg), with the likely cause; None when every estimate is plausible.  Checked whatever was
    skipped: a consistent fit of impossible values is a fit to wrong data (flipped encoder angles, a wrong
    axis mapping or unit), not a calibration."""
    imu = res.imu
    worst = []
    for name, bound, unit, scale in (("gyro_scale_factor", MAX_SCALE_FACTOR, "ppm", 1e6),
                                     ("accel_scale_factor", MAX_SCALE_FACTOR, "ppm", 1e6),
                                     ("gyro_misalignment", MAX_MISALIGNMENT_RAD, "deg", math.degrees(1.0)),
                                     ("accel_misalignment", MAX_MISALIGNMENT_RAD, "deg", math.degrees(1.0))):
        v = np.ravel(np.asarray(getattr(imu, name), dtype=float))
        bad = ~(np.abs(v) <= bound)  # NaN too
        if bad.any():
            k = int(np.argmax(np.where(np.isfinite(v), np.abs(v), np.inf)))
            worst.append(f"{name}[{k}] = {v[k] * scale:.6g} {unit}")
    if not worst:
        return None
    cause = "an axis mapping, sign or unit error of the record's gyros or accelerometers (inscal import --mapping)"
    if not setup.check_encoders:
        cause = ("the encoder check was skipped (--skip-encoder-check) and what it catches is the likely cause: encoder "
                 f"angles with a flipped sign, in other units or from another column; else {cause}")
    else:
        cause = f"likely cause: {cause}"
    return (f"implausible estimates, {', '.join(worst)} (a working sensor stays within +-{MAX_SCALE_FACTOR:.0%} in scale "
            f"factor and {math.degrees(MAX_MISALIGNMENT_RAD):g} deg in misalignment): not calibrated; {cause}")


def latency_cause(res, rec: Record, again, enc: dict | None) -> None:
    """Name an encoder latency as the cause of ``res``'s misfit where it is: when the fit is inconsistent and
    the encoder check (``enc``, its summary) measured a latency under a sample
    (:func:`~inscal.io.encoders.small_latency`), ``again`` (the same calibration of a record) runs on the
    angles shifted by it;
    if its chi^2 falls below half (or the fit becomes consistent), the fit's cause, share and note in
    ``res`` say so, with both chi^2 and the ``--encoder-latency`` that removes it.  The estimates and sigma
    are left as they are."""
    fit = res.fit
    if fit is None or fit.get("consistent", True) or enc is None or "channels" not in fit or rec.gimbal is None:
        return
    lat, sig = enc.get("latency_s"), enc.get("latency_sigma_s")
    words = small_latency(lat, sig, float(rec.rate_hz))
    if words is None:
        return
    shifted = dataclasses.replace(rec, gimbal=apply_latency(np.asarray(rec.time), np.asarray(rec.gimbal), lat))
    try:
        f2 = again(shifted).fit
    except CalibrationError:
        return
    if f2 is None or "chi2" not in f2 or not (f2["consistent"] or f2["chi2"] < 0.5 * fit["chi2"]):
        return
    old = fit.get("note")
    fit["cause"] = (f"{words}, as the encoder check measured: with --encoder-latency {lat:.6g} the chi2 falls "
                    f"from {fit['chi2']:.4g} to {f2['chi2']:.4g} on {f2['dof']} dof "
                    f"({'consistent' if f2['consistent'] else 'still inconsistent'})")
    fit["cause_share"] = float(1.0 - f2["chi2"] / fit["chi2"])
    fit_note(fit)
    res.notes = [fit["note"] if x == old else x for x in res.notes]


def calibrate_record(rec: Record, data: Path, setup: CalibrationSetup) -> Calibrated:
    """Calibrate record ``rec`` (read from file ``data``) with ``setup`` (checked with
    :meth:`CalibrationSetup.problem`): the encoder latency and check, the gravity model, the estimator
    and the parameter file's metadata.  Raises :class:`RecordError` in one line."""
    enc_report = None
    if rec.gimbal is not None:
        if setup.encoder_latency:
            rec = dataclasses.replace(rec, gimbal=apply_latency(np.asarray(rec.time), np.asarray(rec.gimbal),
                                                                setup.encoder_latency))
        if setup.check_encoders:
            chk = check_record_encoders(rec)
            if not chk.ok:
                raise RecordError(f"{data}: {chk.message} (--skip-encoder-check to calibrate anyway)")
            enc_report = chk.summary() | {"latency_applied_s": setup.encoder_latency}
    elif setup.encoder_latency:
        raise RecordError(f"--encoder-latency: {data} has no encoder angles")
    if setup.gravity is not None:
        try:
            rec = dataclasses.replace(rec, site=rec.site.with_gravity(parse_gravity(setup.gravity)))
        except ValueError as exc:
            raise RecordError(f"--gravity: {exc}") from None
    rate = float(getattr(rec, "rate_hz", 0.0) or 0.0)
    if setup.inner_systematic and rate > 0 and setup.filter_rate_hz > rate * (1 + 1e-9):
        raise RecordError(f"--filter-rate-hz {setup.filter_rate_hz:g} is above the rate of {data} ({rate:g} Hz): the "
                          f"filter updates at most once per sample; give at most {rate:g}")
    try:
        if setup.inner_systematic:
            # the state set: chosen from the data unless given (inscal.calibrate.systematic.selection); per
            # plateau the method's own set, so that every plateau estimates the same parameters
            opts = {"filter_rate_hz": setup.filter_rate_hz}
            if setup.states is not None or not setup.plateaus:
                opts["states"] = "auto" if setup.states is None else setup.states
            if setup.arw is not None:
                opts["arw"] = units.to_si(setup.arw, "deg/sqrt(h)")
            if setup.vrw is not None:
                opts["vrw"] = units.to_si(setup.vrw, "ug/sqrt(Hz)")
            if setup.encoder_sigma is not None:
                opts["encoder_sigma"] = units.to_si(setup.encoder_sigma, "arcsec")
            if setup.accept_unconverged:
                opts["accept_unconverged"] = True
            if setup.noise is not None:
                opts["noise"] = setup.noise_model()
        else:
            opts = dict(setup.window_options)
            marked = (saturated_samples(rec.time, record_attrs(data, ("source",))["source"])
                      if setup.inner == "multi-position" else None)
            if marked is not None:
                opts["clipped"] = marked  # a sensor at its range, marked at import: its moves are not used
            if setup.noise is not None:
                opts["noise"] = setup.noise_model()
        res = calibrate(rec, setup.method, **opts, **setup.thermal_options())
    except CalibrationError as exc:
        raise RecordError(f"{data}: {exc}") from None
    if (msg := implausible(res, setup)) is not None:
        raise RecordError(f"{data}: {msg}")
    if not setup.inner_systematic:
        latency_cause(res, rec, lambda r: calibrate(r, setup.method, **opts, **setup.thermal_options()), enc_report)
    meta = {"scenario": rec.scenario or None, "imu_serial": record_attrs(data, ("imu_serial",))["imu_serial"],
            "windows": len(res.windows.windows) if res.windows else None}
    if setup.plateaus:
        meta.update({"per_plateau": setup.inner, "plateaus": len(res.diagnostics["plateaus"])})
    if setup.systematic:
        d = res.diagnostics
        meta.update({"frame": d["frame"], "states": d["state_options"], "state_count": d["states"],
                     "filter_rate_hz": d["filter_rate_hz"], "nis_mean": d["innovations"]["nis_mean"],
                     "chi2": d["innovations"]["chi2"], "dof": d["innovations"]["dof"],
                     "p_value": d["innovations"]["p_value"]})
        verdict = (d.get("convergence") or {}).get("verdict")
        if verdict:  # --accept-unconverged: the parameter file says what it holds
            meta["not_converged"] = f"NOT A CONVERGED CALIBRATION (kept by --accept-unconverged): {verdict}"
    return Calibrated(res, rec, meta, enc_report)
