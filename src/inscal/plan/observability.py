"""Observability of a rotation path for the systematic filter, without data.

Judge a rotation path before running it on hardware: which parameter states of the
systematic filter (:mod:`inscal.calibrate.systematic`) the path makes observable, and how
well.  Two views, both from the path alone:

1. **Covariance (the filter's own answer).**  A noise-free record of the path is simulated
   with an ideal IMU (the covariance of a linear(ised) Kalman filter does not depend on the
   data, only on the trajectory it is linearised about and on the noise model), and one pass
   of :func:`~inscal.calibrate.systematic.systematic` runs over it (``max_passes=1``, ARW/VRW
   given explicitly, so nothing is estimated from the noise-free data).  Per parameter state:
   prior sigma, posterior sigma (the smoothed one; for constant parameters it equals the final
   filtered one) and ``ratio = posterior / prior``, with the verdict::

       ratio < 0.01  well observed      0.01 <= ratio < 0.1  observed
       0.1 <= ratio < 0.5  weak         ratio >= 0.5         unobservable

   This includes the process noise (ARW, VRW), so it says what a calibration on the path
   would deliver with that IMU.

2. **Deterministic observability matrix.**  With the filter's own per-step transition
   matrices (scaled state ``x / sigma0``, so a unit column is a one-sigma prior error)::

       Psi_k = Phi_k ... Phi_1 = [[A_k, B_k], [0, I]]     A_k = Phi_nn,k A_{k-1},
                                                          B_k = Phi_nn,k B_{k-1} + Phi_np,k
       O = [W H Psi_1; W H Psi_2; ...; W H Psi_M]          W = R^-1/2 (whitened rows)

   ``H`` selects velocity and position (zero velocity, known position each filter step).  With
   gimbal states (``gimbal``/``unified``) each step that has encoder attitude rows adds them too,
   whitened the same way, ``L_k^-1 H_enc,k Psi_k`` with ``L_k L_k^T = R_enc,k`` (the filter's own
   per-step ``H_enc`` and ``R_enc``, kept by ``keep_passes``): the encoders observe the attitude
   against the gimbal model, so ``dth`` and the mount attitude appear as observed where the path
   separates them (``dth`` needs turns of the outer axis away from zero; with the inner axis only
   it stays in the null space).  ``O``
   is reduced as it is built to its triangular factor (``O = Q R``, a Householder update of
   ``R`` with each step's six (nine) rows; memory independent of the path length), whose singular values are
   those of ``O`` to round-off relative to the largest (better than the square root of the
   Gramian's eigenvalues, which loses half the digits).  Reported: the singular values of the
   full state (navigation initial state + parameters) and those of the parameter columns
   after projecting out the initial navigation state (the lower-right block ``R_pp`` of
   ``R`` with the navigation columns first, i.e. the Schur complement of the Gramian: the
   information on the parameters when the initial attitude, velocity and position are
   unknown), each normalised by its largest; the numerical rank at the relative tolerance
   :data:`RANK_TOL`; and the weakest parameter directions (right singular vectors of
   ``R_pp``, largest components with their labels).  No process noise enters ``O``: it
   says which combinations the path separates at all, not how well a noisy IMU resolves
   them (that is view 1).

Vertical channel.  The error model keeps the gravity gradient (``dg/dh = 2 g / R``), so the
vertical channel is unstable with the time constant ``sqrt(R / 2g) ~ 570 s``: ``A_k`` and the
``B_k`` columns that drive the vertical channel grow like ``cosh(t / 570 s)`` (~4e2 over the
1.07 h of S16 Table 1, ~1e19 over 7 h).  How it is handled: (a) ``O`` is never squared into a
Gramian, the QR keeps round-off at ``eps`` of the largest singular value, so the numbers stay
finite and accurate (checked up to the 7 h ``rotmod16`` path); (b) the headline spectrum, rank
and weakest directions are those of the parameter block with the initial navigation state
projected out, which removes the largest (vertical initial-state) columns; (c) the growth is
reported as ``vertical_growth`` (``max_k |A_k[8, 8]|``, the factor on an initial height error)
and, above :data:`GROWTH_NOTE` (paths longer than ~1.5 h), a note says that the normalised
singular values are then dominated by the vertical channel (small ones understate the
horizontal information; the full-state rank collapses first).  The covariance view is
unaffected (the measurement every step holds the vertical channel).

Thermal states (``51,thermal``, ``thermal=GSABR``; :mod:`inscal.plan.thermal`).  The scenario's temperature
profile is the filter's known input: the noise-free record carries it as a record of the scenario does (read
at its sensor's rate, exactly; the filter takes dT/dt as its 60-s slope), about the scenario's ``t_ref``, and the
IMU has no thermal errors (the covariance does not depend on them).  What separates a coefficient from its base term and
from the other orders is the temperature history alone; the report adds, per coefficient, the state it is most
correlated with a posteriori (``thermal.partners``) and the weakest directions name the combinations.  A
scenario without a profile is refused (a constant temperature is no information on any coefficient).

Simulation: the path at ``rate_hz`` (20 Hz by default; enough for the filter's per-sample
Jacobians at turntable rates, and the covariance does not depend on the data noise), an
ideal IMU, no noise; a scenario keeps its site and its gimbal geometry (mount attitude,
non-orthogonality), its IMU errors are irrelevant and dropped.  A bare path runs at the S16
site (30 N) with the S16 noise (ARW 5e-5 deg/sqrt(h), VRW 1 ug/sqrt(Hz)); a scenario uses its
own ARW/VRW (or these defaults when it has none), unless ``arw``/``vrw`` are given.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from numba import njit

from inscal.calibrate.systematic.driver import THERMAL_BYTES_PER_SAMPLE, systematic
from inscal.calibrate.systematic.states import (
    DEFAULT_SIGMA0,
    K_TH,
    N_NAV,
    NAV_SIGMA0,
    StateSet,
    field_value,
    prior_sigma,
)
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.dense import product_entry
from inscal.core.error_model import ImuErrors, ImuNoise
from inscal.core.turntable import BUILTIN_PATHS, RotationPath
from inscal.io.tomlfile import read_toml
from inscal.plan.slices import run_in_slices
from inscal.plan.thermal import default_t_ref, known_temperature
from inscal.sim import scenarios
from inscal.sim.scenarios import S16_SITE
from inscal.sim.simulate import Scenario, simulate

#: verdict thresholds on ratio = posterior / prior sigma (upper bounds, exclusive)
THRESHOLDS = (("well observed", 0.01), ("observed", 0.1), ("weak", 0.5))
UNOBSERVABLE = "unobservable"
#: numerical rank: singular values above RANK_TOL times the largest
RANK_TOL = 1e-9
#: vertical-channel growth (cosh(t / 570 s): ~1.5 h) above which the normalised spectrum gets a note
GROWTH_NOTE = 1e4
#: relative difference of the two passes' posterior sigmas above which a note is added
MISMATCH_NOTE = 0.01
#: a Householder column below this (scaled, whitened units) is round-off: dropped (:func:`_factor_kernel`)
HOUSEHOLDER_TINY = 1e-150
#: weakest directions reported, and components listed per direction
N_WEAKEST = 5
N_COMPONENTS = 4
#: S16 defaults for a bare path (site 30 N, 114 E; S16 section 4.1 noise)
DEFAULT_ARW = units.to_si(5e-5, "deg/sqrt(h)")
DEFAULT_VRW = units.to_si(1.0, "ug/sqrt(Hz)")
#: navigation prior sigma of the observability matrix's initial state (scaling only; the
#: parameter-block results do not depend on it): tilt 600", heading 1 deg, 1 cm/s, 1 cm
NAV_SIGMA = NAV_SIGMA0
#: most samples of the noise-free simulation (10^9: ~250 GB of memory, about an hour of CPU)
MAX_SAMPLES = 10**9
#: memory per sample of the in-memory simulation and the filter pass over it (measured 174 B with 51 states,
#: 190 B with the unified model, n25 at 200-800 Hz; the simulation's chunks are joined into one record)
BYTES_PER_SAMPLE = 256
#: with thermal states, per sample: the readings of the profile (time, value) and what the driver keeps
THERMAL_SAMPLE_BYTES = 16 + THERMAL_BYTES_PER_SAMPLE


class ObservabilityError(ValueError):
    """A path, scenario or option the observability analysis cannot use."""


def verdict(ratio: float) -> str:
    """The verdict for ``ratio = posterior / prior`` sigma (:data:`THRESHOLDS`)."""
    for name, lim in THRESHOLDS:
        if ratio < lim:
            return name
    return UNOBSERVABLE


@dataclass(frozen=True)
class StateResult:
    """One parameter state: sigmas in the group's field unit."""

    label: str  # e.g. "gyro_matrix[xx]"
    group: str
    component: str  # e.g. "xx"
    unit: str
    prior: float
    posterior: float
    ratio: float
    verdict: str

    def to_dict(self) -> dict:
        """The state's result as JSON."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class Direction:
    """A right singular vector of the parameter block: normalised singular value and its
    largest components (label, weight; unit vector in the scaled parameter space).  Where several
    singular values are (numerically) equal, e.g. a null space of dimension > 1, any basis of
    that subspace is as valid as the one reported."""

    singular_value: float
    components: tuple[tuple[str, float], ...]

    def to_dict(self) -> dict:
        """The direction as JSON: its singular value and the weight of each state."""
        return {"singular_value": self.singular_value,
                "components": [{"label": lab, "weight": w} for lab, w in self.components]}

    def describe(self) -> str:
        """The direction as one line: ``+0.71 label_a -0.71 label_b ...``."""
        return " ".join(f"{w:+.2f} {lab}" for lab, w in self.components)


@dataclass(frozen=True)
class ObservabilityReport:
    """Result of :func:`observability` (SI inside, field units in ``states``)."""

    source: str
    kind: str  # "scenario" or "path"
    path_name: str
    duration_s: float
    site: dict  # latitude_deg, longitude_deg, height_m
    state_spec: str
    n_states: int
    noise: dict  # arw_deg_sqrt_h, vrw_ug_sqrt_hz, source
    rate_hz: float
    filter_rate_hz: float
    steps: int
    states: tuple[StateResult, ...]
    singular_values: np.ndarray  # parameter block after projecting out the nav initial state, / largest
    largest_singular_value: float  # of the parameter block (whitened, scaled)
    rank: int
    full_singular_values: np.ndarray  # full state (nav initial state + parameters), / largest
    full_rank: int
    weakest: tuple[Direction, ...]
    vertical_growth: float
    timing_s: dict
    consistency: float = 0.0  # max relative difference of the posterior sigmas of the two passes
    covariance: np.ndarray | None = None  # posterior covariance of the parameter states (SI), not in to_dict
    factor: np.ndarray | None = None  # R_pp: triangular factor of the parameter block (scaled), not in to_dict
    notes: tuple[str, ...] = field(default_factory=tuple)
    #: thermal states: the temperature (t_ref, t_min, t_max, span, rate, profile) and, per thermal state, the
    #: state it is most correlated with a posteriori (:func:`thermal_partners`)
    thermal: dict | None = None

    @property
    def n_params(self) -> int:
        """The number of parameter states reported."""
        return len(self.states)

    def by_label(self, label: str) -> StateResult:
        """The result of the state ``label``; a KeyError when there is none."""
        for s in self.states:
            if s.label == label:
                return s
        raise KeyError(label)

    def ratios(self) -> dict[str, float]:
        """The posterior over prior 1 sigma of every parameter state, by label."""
        return {s.label: s.ratio for s in self.states}

    def null_weight(self, label: str) -> float:
        """Norm of the projection of one parameter state (unit vector in the scaled parameter
        space) on the numerical null space of the parameter block (singular values at or below
        :data:`RANK_TOL` times the largest): 0 for a state the path separates, 1 for one it
        cannot see at all, whatever basis the (degenerate) null space is reported in."""
        if self.factor is None:
            raise ValueError("no factor kept")
        j = [s.label for s in self.states].index(label)
        _, sv, Vt = np.linalg.svd(self.factor)
        null = Vt[sv <= RANK_TOL * sv[0]] if sv[0] > 0 else Vt
        return float(np.linalg.norm(null[:, j]))

    def weakest_states(self, n: int = 5) -> list[StateResult]:
        """The ``n`` states the path observes least (largest posterior/prior ratio first)."""
        return sorted(self.states, key=lambda s: -s.ratio)[:n]

    def groups(self) -> dict[str, dict]:
        """Per group: unit, worst (largest) ratio, its state and verdict, states per verdict."""
        out: dict[str, dict] = {}
        for s in self.states:
            g = out.setdefault(s.group, {"unit": s.unit, "max_ratio": -1.0, "worst": "", "counts": {}})
            if s.ratio > g["max_ratio"]:
                g["max_ratio"], g["worst"] = s.ratio, s.label
            g["counts"][s.verdict] = g["counts"].get(s.verdict, 0) + 1
        for g in out.values():
            g["verdict"] = verdict(g["max_ratio"])
        return out

    def to_dict(self) -> dict:
        """The report as ``inscal observability --json`` prints it."""
        return {
            "source": self.source, "kind": self.kind, "path": {"name": self.path_name, "duration_s": self.duration_s},
            "site": self.site, "states": self.state_spec, "n_states": self.n_states, "n_params": self.n_params,
            "noise": self.noise, "rate_hz": self.rate_hz, "filter_rate_hz": self.filter_rate_hz, "steps": self.steps,
            "thresholds": {name: lim for name, lim in THRESHOLDS},
            "parameters": [s.to_dict() for s in self.states],
            "groups": self.groups(),
            "svd": {
                "definition": "O = [W H Psi_1; ...; W H Psi_M], scaled states (x / prior sigma), rows whitened by "
                              "the measurement sigma (velocity, position and, with gimbal states, the encoder attitude "
                              "rows); parameter block after projecting out the initial navigation state",
                "singular_values": self.singular_values, "largest": self.largest_singular_value,
                "rank": self.rank, "n": self.n_params, "rank_tolerance": RANK_TOL,
                "full_state": {"singular_values": self.full_singular_values, "rank": self.full_rank,
                               "n": self.n_states},
                "weakest": [d.to_dict() for d in self.weakest],
                "vertical_growth": self.vertical_growth,
            },
            "consistency": self.consistency,
            "notes": list(self.notes),
            "timing_s": self.timing_s,
            **({"temperature": self.thermal} if self.thermal else {}),
        }


# ----------------------------------------------------------------------------- input
def load_source(source):
    """``(Scenario, kind, label)`` from a :class:`~inscal.sim.simulate.Scenario`, a
    :class:`~inscal.core.turntable.RotationPath`, a built-in scenario or path name, a scenario TOML or a
    path TOML (a ``[path]`` table only, or the path keys at the top level)."""

    if isinstance(source, Scenario):
        return source, "scenario", source.name
    if isinstance(source, RotationPath):
        return _bare(source), "path", source.name
    if not isinstance(source, (str, Path)):
        raise ObservabilityError(f"expected a scenario, a path, a name or a TOML file, got {type(source).__name__}")
    name = str(source)
    fs = Path(name)
    try:
        if fs.is_file() or name.endswith(".toml"):
            d = read_toml(fs, ObservabilityError)
            if set(d) <= {"path", "schema_version"} and "path" in d:
                sc = scenarios.scenario_from_dict(d, default_name=fs.stem)
                return _bare(sc.path), "path", name
            if "moves" in d:  # RotationPath.to_dict() layout at the top level
                return _bare(RotationPath.from_dict(d)), "path", name
            return scenarios.load_toml(fs), "scenario", name
        if name in scenarios.BUILTIN:
            return scenarios.build(name), "scenario", name
        if name in BUILTIN_PATHS:
            fn = BUILTIN_PATHS[name]
            return _bare(fn(3600.0) if name in ("static", "rotmod16") else fn()), "path", name
    except ObservabilityError:
        raise
    except (ValueError, TypeError) as exc:  # ScenarioError, PathError, Site / Scenario validation
        msg = str(exc)
        raise ObservabilityError(msg if msg.startswith(name) else f"{name}: {msg}") from None
    raise ObservabilityError(f"unknown scenario or path {name!r}; built-in scenarios: {', '.join(scenarios.BUILTIN)}; "
                             f"built-in paths: {', '.join(BUILTIN_PATHS)}; or a .toml file")


def _bare(path: RotationPath):

    return Scenario(path.name, path, S16_SITE)


def resolve_noise(sc, kind: str, arw, vrw) -> tuple[np.ndarray, np.ndarray, str]:
    """The gyro and accelerometer white noise (SI, per axis) for the bound: ``arw`` / ``vrw`` when
    given, else the scenario's, else S16's defaults; returns them with where they came from.
    A non-positive value is an :class:`ObservabilityError`.
    """
    sa, sv = np.asarray(sc.noise.arw, float), np.asarray(sc.noise.vrw, float)
    have = kind == "scenario" and np.all(sa > 0) and np.all(sv > 0)
    if arw is None:
        arw = sa if have else DEFAULT_ARW
    if vrw is None:
        vrw = sv if have else DEFAULT_VRW
    out = []
    for n, v in (("arw", arw), ("vrw", vrw)):
        a = np.broadcast_to(np.asarray(v, float), (3,)).copy()
        if not np.all(np.isfinite(a)) or np.any(a <= 0):
            raise ObservabilityError(f"{n} must be a positive number, got {v}")
        out.append(a)
    src = "scenario" if have else ("S16 default" if kind == "path" else "S16 default (the scenario has no ARW/VRW)")
    return out[0], out[1], src


# ----------------------------------------------------------------------------- size
def observability_bytes(n_samples: float, steps: float, states: StateSet) -> float:
    """Memory [bytes] of :func:`observability` that grows with the path: the noise-free record
    (:data:`BYTES_PER_SAMPLE` per sample) and, per filter step, what the filter pass keeps for the
    smoother and this module (gains, innovation covariances, transitions ``Phi_nn``, ``Phi_np``: 6 N + 131
    + 9 p floats; with gimbal states the encoder rows with their gains and covariances, 6 N + 25, and
    their whitened copies here, 6 N + 9)."""
    N = states.n_states
    per_step = 6 * N + 131 + 9 * (N - N_NAV) + (12 * N + 34 if states.gimbal else 0)
    per_sample = BYTES_PER_SAMPLE + (THERMAL_SAMPLE_BYTES if states.thermal else 0)
    return per_sample * float(n_samples) + 8.0 * per_step * float(steps)


# ----------------------------------------------------------------------------- analysis
def observability(scenario_or_path, states: str | StateSet = "51", rate_hz: float = 20.0, arw=None, vrw=None,
                  filter_rate_hz: float = 1.0, t_ref: float | None = None) -> ObservabilityReport:
    """Observability of the systematic filter's parameter states on a rotation path (module
    docstring).  ``scenario_or_path``: a Scenario, a RotationPath, a built-in scenario/path name or a
    TOML file.  ``arw`` [rad/sqrt(s)], ``vrw`` [m/s/sqrt(s)]: scalar or per axis; default
    the scenario's, else S16's.  ``rate_hz``: simulation rate of the noise-free record.  Thermal states
    (``51,thermal``, ``thermal=GSABR``): the scenario's temperature profile is the filter's known input, about
    ``t_ref`` [degC] (default the scenario's thermal model's, else 20; :mod:`inscal.plan.thermal`)."""

    t_start = time.perf_counter()
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise ObservabilityError(f"rate must be > 0 Hz, got {rate_hz}")
    if not (isinstance(filter_rate_hz, (int, float)) and math.isfinite(filter_rate_hz) and 0 < filter_rate_hz <= rate_hz):
        raise ObservabilityError(f"filter rate must be > 0 Hz and <= the simulation rate, got {filter_rate_hz}")
    try:
        st = states if isinstance(states, StateSet) else StateSet.parse(states)
    except CalibrationError as exc:
        raise ObservabilityError(str(exc)) from None
    sc, kind, label = load_source(scenario_or_path)
    if not sc.path.duration * rate_hz <= MAX_SAMPLES:
        raise ObservabilityError(f"{label}: {sc.path.duration * rate_hz:.3g} samples ({sc.path.duration:.4g} s at "
                                 f"{rate_hz:g} Hz) is more than the {MAX_SAMPLES:.0e} of a sensible simulation")
    arw_v, vrw_v, noise_src = resolve_noise(sc, kind, arw, vrw)
    # ideal IMU, no noise, no thermal errors; keep the site, the gimbal geometry and the temperature profile; with the
    # lever-arm timing the scenario's lever arms, the point its columns are linearised about (they scale them)
    imu0 = ImuErrors(accel_lever_arm=sc.imu.accel_lever_arm) if (st.lever_timing and kind == "scenario") else ImuErrors()
    sc0 = replace(sc, imu=imu0, noise=ImuNoise(), rate_hz=float(rate_hz), thermal=None)
    if sc0.n_samples * filter_rate_hz / rate_hz < 10:
        raise ObservabilityError(f"path {sc.path.name!r} is too short ({sc.path.duration:g} s) for the filter")
    tinfo, known = None, None
    if st.thermal:  # the temperature a record of the scenario carries (inscal.plan.thermal)
        known = known_temperature(sc, label, error=ObservabilityError)
        tinfo = known.info(default_t_ref(sc) if t_ref is None else t_ref, sc0.n_samples, 1.0 / rate_hz, label,
                           ObservabilityError)
    data = simulate(sc0)
    t_sim = time.perf_counter()
    rec = SimpleNamespace(time=data.time, dtheta=data.dtheta, dvel=data.dvel, gimbal=None, rate_hz=float(rate_hz),
                          site=sc.site, path=sc.path, temperature=known.readings() if known else None)
    opts = {"t_ref": tinfo["t_ref"], "temperature_rate_window_s": known.rate_window_s} if tinfo else {}
    try:
        res = systematic(rec, st, filter_rate_hz=filter_rate_hz, max_passes=1, arw=arw_v, vrw=vrw_v,
                         history_s=1e12, keep_passes=True, initial=imu0, **opts)
    except CalibrationError as exc:
        raise ObservabilityError(f"{label}: {exc}") from None
    t_filt = time.perf_counter()
    # ---- covariance view
    groups = st.groups
    # the filter's prior (a thermal coefficient's spread over the record's temperature span)
    prior = prior_sigma(st, DEFAULT_SIGMA0, res.diagnostics["thermal"]["span"] if tinfo else 1.0)
    post = np.sqrt(np.maximum(np.diag(res.covariance["P"]), 0.0))
    ratio = post / prior
    rows = []
    k = 0
    for g in groups:
        for lab in g.labels:
            full = f"{g.name}[{lab}]" if lab else g.name
            rows.append(StateResult(full, g.name, lab, g.unit, float(field_value(prior[k], g.unit)),
                                    float(field_value(post[k], g.unit)), float(ratio[k]), verdict(ratio[k])))
            k += 1
    # ---- observability matrix
    noise = res.diagnostics["noise"]
    r = np.array([noise["velocity_sigma_m_s"] ** 2] * 3 + [noise["position_sigma_m"] ** 2] * 3)
    sig = np.concatenate([NAV_SIGMA, prior])
    out = res.pass_output  # the same pass: its per-step transitions (keep_passes keeps them)
    Rf, growth = _triangular_factor(out.phinn, out.phinp, r / sig[3:9] ** 2, *_encoder_rows(out))
    # self-check: this pass's posterior must be the systematic() one (same trajectory, noise, priors)
    mismatch = float(np.max(np.abs(np.sqrt(np.maximum(np.diag(out.Pf)[N_NAV:], 0.0)) / ratio - 1.0)))
    full_sv = np.linalg.svd(Rf, compute_uv=False)
    _, psv, Vt = np.linalg.svd(Rf[N_NAV:, N_NAV:])
    t_obs = time.perf_counter()
    labels = [s.label for s in rows]
    nsv = psv / psv[0] if psv[0] > 0 else psv
    nfull = full_sv / full_sv[0] if full_sv[0] > 0 else full_sv
    weakest = []
    for i in range(1, min(N_WEAKEST, len(psv)) + 1):
        v = Vt[-i]
        v = v * (1.0 if v[np.argmax(np.abs(v))] > 0 else -1.0)
        idx = np.argsort(-np.abs(v))[:N_COMPONENTS]
        weakest.append(Direction(float(nsv[-i]), tuple((labels[j], float(round(v[j], 4))) for j in idx)))
    notes = []
    if growth > GROWTH_NOTE:
        notes.append(f"the unstable vertical channel grows by {growth:.1e} over the path: the normalised singular "
                     "values are dominated by it, small ones understate the horizontal information")
    if mismatch > MISMATCH_NOTE:
        notes.append(f"the transition pass and systematic() disagree on the posterior by {mismatch:.1%} "
                     "(NAV_SIGMA out of step with systematic?)")
    if kind == "path":
        notes.append("bare path: S16 site (30 N, 114 E, 0 m)")
    if tinfo:
        tinfo = dict(tinfo, partners=thermal_partners(st, res.covariance["P"], labels))
        notes.append(f"thermal states: the temperature profile ({tinfo['t_min']:.4g} .. {tinfo['t_max']:.4g} degC, "
                     f"up to {tinfo['rate_max_c_per_min']:.3g} degC/min) is the filter's known input about T_ref "
                     f"{tinfo['t_ref']:g} degC; each coefficient's prior spreads its term's over the span "
                     f"{tinfo['span']:.4g} degC")
    lat, lon, h = sc.site.latitude, sc.site.longitude, sc.site.height
    return ObservabilityReport(
        source=label, kind=kind, path_name=sc.path.name, duration_s=float(sc.path.duration),
        site={"latitude_deg": math.degrees(lat), "longitude_deg": math.degrees(lon), "height_m": h},
        state_spec=res.diagnostics["state_options"], n_states=st.n_states,
        noise={"arw_deg_sqrt_h": units.from_si(arw_v, "deg/sqrt(h)").tolist(),
               "vrw_ug_sqrt_hz": units.from_si(vrw_v, "ug/sqrt(Hz)").tolist(), "source": noise_src,
               "velocity_sigma_m_s": noise["velocity_sigma_m_s"], "position_sigma_m": noise["position_sigma_m"]},
        rate_hz=float(rate_hz), filter_rate_hz=float(res.diagnostics["filter_rate_hz"]), steps=int(out.steps), states=tuple(rows),
        singular_values=nsv, largest_singular_value=float(psv[0]), rank=int(np.sum(nsv > RANK_TOL)),
        full_singular_values=nfull, full_rank=int(np.sum(nfull > RANK_TOL)), weakest=tuple(weakest),
        vertical_growth=float(growth), consistency=mismatch, covariance=res.covariance["P"], factor=Rf[N_NAV:, N_NAV:],
        timing_s={"simulate": t_sim - t_start, "filter": t_filt - t_sim, "observability_matrix": t_obs - t_filt,
                  "total": t_obs - t_start},
        notes=tuple(notes), thermal=tinfo)


def thermal_partners(st: StateSet, P: np.ndarray, labels: list[str]) -> dict[str, dict]:
    """Per thermal coefficient state: the other parameter state it is most correlated with in the posterior
    ``P`` (its base term when the temperature history cannot tell them apart, e.g. ``gyro_bias_dT1[x]`` with
    ``gyro_bias[x]`` at a constant temperature, or ``gyro_bias_rate[x]`` with ``gyro_bias[x]`` on a ramp at one
    rate) and that correlation coefficient."""
    d = np.sqrt(np.maximum(np.diag(P), 1e-300))
    Rc = P / np.outer(d, d)
    np.fill_diagonal(Rc, 0.0)
    out, k = {}, 0
    for g in st.groups:
        for _ in g.labels:
            if g.kinds[0] == K_TH:
                j = int(np.argmax(np.abs(Rc[k])))
                out[labels[k]] = {"with": labels[j], "correlation": float(Rc[k, j])}
            k += 1
    return out


def _encoder_rows(out) -> tuple:
    """``(W, used)`` of a pass with gimbal states: the encoder attitude rows of every step,
    whitened, ``W_k = L_k^-1 H_k`` with ``L_k L_k^T = R_k`` (any square root gives the same
    ``O^T O``; (M, 3, N), scaled states like ``Phi``) and ``used`` (M,) 1 where the step has them;
    ``()`` without gimbal states (or without the stored rows)."""
    H, Rm, used = getattr(out, "H_att", None), getattr(out, "R_att", None), getattr(out, "att_used", None)
    if H is None or Rm is None or used is None or len(used) == 0:
        return ()
    M = out.phinn.shape[0]
    used = np.asarray(used[:M], np.int8)
    W = np.zeros((M,) + H.shape[1:])
    k = np.flatnonzero(used)
    if k.size:
        L = np.linalg.cholesky(Rm[k])
        W[k] = np.linalg.solve(L, H[k])
    return W, used


def _triangular_factor(phinn: np.ndarray, phinp: np.ndarray, r_scaled: np.ndarray, w_att: np.ndarray | None = None,
                       att_used: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Upper-triangular ``R`` with ``R^T R = O^T O`` for the stacked, whitened observability
    matrix of the scaled state (module docstring), and ``max_k |A_k[8, 8]|`` (vertical-channel growth:
    the initial height error's factor, ``cosh(t / 570 s)``).

    ``phinn`` (M, 9, 9), ``phinp`` (M, 9, p): per-step scaled transitions; ``r_scaled`` (6,):
    measurement variances of the scaled velocity and position.  Gimbal states: ``w_att`` (M, 3, 9 + p)
    the whitened encoder attitude rows ``R^-1/2 H`` of each step (on the state after that step's
    transition, like the velocity/position rows), ``att_used`` (M,) nonzero where a step has them."""
    M, _, p = phinp.shape
    if w_att is None:
        w_att, att_used = np.zeros((0, 3, N_NAV + p)), np.zeros(0, np.int8)
    elif w_att.shape != (M, 3, N_NAV + p) or np.shape(att_used) != (M,):
        raise ValueError(f"encoder rows must be ({M}, 3, {N_NAV + p}) with ({M},) flags, got {w_att.shape}")
    R = np.zeros((N_NAV + p, N_NAV + p))
    args = (np.ascontiguousarray(phinn, dtype=float), np.ascontiguousarray(phinp, dtype=float),
            1.0 / np.sqrt(np.asarray(r_scaled, float)), np.ascontiguousarray(w_att, dtype=float),
            np.ascontiguousarray(att_used, dtype=np.int8), R)
    A, B, growth = np.eye(9), np.zeros((9, p)), np.ones(1)  # Psi_k and the growth, carried between slices
    run_in_slices(M, lambda k0, k1: _factor_kernel(k0, k1, *args, A, B, growth))
    growth = float(growth[0])
    if not (np.all(np.isfinite(R)) and math.isfinite(growth)):
        raise ObservabilityError("observability matrix overflowed (path too long for the unstable vertical channel)")
    return R, growth


@njit(cache=True)
def _factor_kernel(k0, k1, phinn, phinp, w, w_att, att_used, R, A, B, growth):
    """``Psi_k`` recursion and a Householder update of ``R`` with the six whitened rows
    ``w * H Psi_k`` of every step (``[R; X] = Q [R'; 0]``), plus the three whitened encoder
    attitude rows ``W_k Psi_k`` where ``att_used[k]`` (``w_att`` empty: none), over the steps
    ``k0 .. k1 - 1`` (:mod:`inscal.plan.slices`).  No BLAS: plain loops, so the cost (~12 N^2 per
    step) does not depend on a threaded BLAS.  Carried from one call to the next: ``R``, ``Psi_k``
    = ``[[A, B], [0, I]]`` (``A`` (9, 9), ``B`` (9, p)) and ``growth`` (1,), ``max |A_k[8, 8]|``
    (vertical-channel growth)."""
    p = phinp.shape[2]
    N = 9 + p
    have_att = w_att.shape[0] > 0
    A2 = np.empty((9, 9))
    B2 = np.empty((9, p))
    X = np.empty((9, N))
    for k in range(k0, k1):
        P = phinn[k]
        for i in range(9):
            for j in range(9):
                A2[i, j] = product_entry(0.0, P, i, A, j, 9)
            for j in range(p):
                B2[i, j] = product_entry(phinp[k, i, j], P, i, B, j, 9)
        A[:, :] = A2
        B[:, :] = B2
        if abs(A[8, 8]) > growth[0]:
            growth[0] = abs(A[8, 8])
        for a in range(6):
            for j in range(9):
                X[a, j] = w[a] * A[3 + a, j]
            for j in range(p):
                X[a, 9 + j] = w[a] * B[3 + a, j]
        nr = 6
        if have_att and att_used[k] != 0:
            # W Psi_k = [W_n A_k, W_n B_k + W_p]
            Wk = w_att[k]
            for a in range(3):
                for j in range(9):
                    X[6 + a, j] = product_entry(0.0, Wk, a, A, j, 9)
                for j in range(p):
                    X[6 + a, 9 + j] = product_entry(Wk[a, 9 + j], Wk, a, B, j, 9)
            nr = 9
        # Householder: annihilate column j of X against R[j, j]
        for j in range(N):
            scale = abs(R[j, j])
            for a in range(nr):
                if abs(X[a, j]) > scale:
                    scale = abs(X[a, j])
            if scale < HOUSEHOLDER_TINY:
                # nothing left to annihilate (exactly dependent columns, e.g. thermal columns that are multiples
                # of their base term's while the temperature holds, leave round-off that would underflow
                # 1 / (alpha v0)): dropping it changes O^T O by less than this squared
                for a in range(nr):
                    X[a, j] = 0.0
                continue
            rj = R[j, j] / scale
            nx = 0.0
            for a in range(nr):
                nx += (X[a, j] / scale) ** 2
            if nx == 0.0:
                continue
            alpha = -math.copysign(scale * math.sqrt(rj * rj + nx), R[j, j])
            v0 = R[j, j] - alpha
            beta = 1.0 / (alpha * v0)  # = -2 / (v^T v) with v = [v0, X[:, j]]
            for c in range(j + 1, N):
                s = v0 * R[j, c]
                for a in range(nr):
                    s += X[a, j] * X[a, c]
                s *= beta
                R[j, c] += s * v0
                for a in range(nr):
                    X[a, c] += s * X[a, j]
            R[j, j] = alpha
            for a in range(nr):
                X[a, j] = 0.0
