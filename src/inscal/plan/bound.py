"""Cramér-Rao bound of a calibration experiment without running it.

What it is.  The systematic filter (:mod:`inscal.calibrate.systematic`) is a Kalman filter on
the linearised error state ``x = [phi, dv, dp | parameters]``.  For a linear-Gaussian model the
filter's covariance does not depend on the data, only on the trajectory, the noise and the
prior; the posterior covariance of the constant parameter states (smoothed = final filtered,
because their process noise is zero) is the Bayesian Cramér-Rao bound of the experiment: the
inverse of the Fisher information of the data plus that of the prior.  No unbiased-in-the-mean
estimator that uses the same prior can do better; the iterated systematic filter attains it
to first order (``bench/crlb_vs_mc.py`` checks that against Monte Carlo).

How it is computed (no sensor simulation, no navigation).  Per filter step ``k`` over
``[kT, (k+1)T]`` (``T = 1 / filter_rate_hz``, 1 s by default, as the systematic filter):

* Kinematics from the path: ``C_s^n(t)``, ``w_is^s(t)``, ``f^s(t)`` from the piecewise
  quadratic gimbal angles (:class:`inscal.core.turntable.Segments`), the gimbal geometry (N25 eq.
  5-8: mount attitude, outer-axis non-orthogonality), the Earth rate and the site's gravity
  (:func:`kinematics`, the formulas of ``inscal.core.kinematics.rates_at`` plus the attitude).  The
  IMU is ideal: the nominal parameters are the filter's linearisation point in its first pass.
* ``Phi_np = M0 + F M1 + F^2 M2``, ``M_i = sum_j (T - t_j)^i / i! F_np(t_j) h`` with the
  parameter columns of :func:`inscal.calibrate.systematic.dynamics.column_values` (the same column
  kinds, so every state set of :class:`~inscal.calibrate.systematic.StateSet` is supported),
  exactly as the systematic kernel accumulates them per sample.  A step inside a dwell takes
  one evaluation with the exact moments ``T, T^2/2, T^3/6``; a step with motion takes
  ``n_sub`` mid-point sub-samples (``sub_rate_hz``, 20 Hz by default; 50 sub-samples change
  the s16 bound by < 0.1 %).
* ``Phi_nn = I + F T + F^2 T^2/2 + F^3 T^3/6`` with ``F`` = :func:`~inscal.calibrate.systematic._nav_F`
  at ``f^n = [0, 0, g]`` (a static base: one ``Phi_nn`` for the whole path), and ``Q_d`` the
  same third-order Van Loan series of the white ARW/VRW as the systematic kernel.
* Measurements as the systematic filter: zero velocity and the known position every step,
  ``sigma_v = 0.05 VRW sqrt(T)``, ``sigma_p = sigma_v T`` (its defaults), with its noise floors.
* Covariance only: structured prediction (parameters constant) and the update
  ``P <- P - K (P H^T)^T`` (symmetrised), in the scaled state ``x / sigma0`` like the filter.

Bias instability (not in the systematic filter, which has none): ``bias_noise`` adds
process noise on the bias states, either a random walk (``P_bb += q T`` per step, ``q`` the
rate random-walk PSD) or a first-order Gauss-Markov bias ``(sigma, tau)`` as the simulator
draws it (:class:`inscal.core.error_model.ImuNoise`): three extra states per triad with the bias
columns of ``Phi_np``, ``phi = exp(-T / tau)`` and ``q = sigma^2 (1 - phi^2)``, stationary
prior ``sigma``.  The reported bound of a bias is then that of its constant part (the GM
states are marginalised); with a random walk it is the bias at the end of the record.

Thermal states (``51,thermal``; :mod:`inscal.plan.thermal`).  The scenario's temperature profile, as a record
of it carries it and the filter reads it (:class:`~inscal.plan.thermal.KnownTemperature`), is the known input:
its ``T - t_ref`` and ``dT/dt`` at every sub-sample give the thermal columns (the base columns times ``-dT^k``,
``-w_i dT^k``, ``-f_i dT^k`` or ``-dT/dt``, :mod:`inscal.plan.bound_kernel`); with them every step takes the
sub-sample moments (the columns move along a dwell while the temperature does).  The prior of each coefficient
is the filter's, spread over the path's temperature span.  The bound equals the filter's posterior per state
within 4e-5 on ``thermal-ramp`` (72 parameters, 2.1 h) and 4.6e-5 on the 9-h ``thermal-plateaus-s16``; on the
17-min PSINS path with a 4 degC/min ramp within 1.2e-4 on the thermal states, 2.7e-4 on the others (1.3e-4
there without thermal states: the filter's 20-Hz discretisation of that path's turns;
``tests/plan/test_observability_thermal.py``).  Speed: 0.35 s for ``thermal-ramp`` (7,542 steps, 81 states).

Extra measurement rows.  A state set whose error model has other observations (e.g. encoder
attitude rows of a unified gimbal model) plugs them in through :func:`register_rows`: a builder
returns per-step rows ``H`` (physical units) and variances, applied after the velocity/position
update (scalar sequential updates).

Agreement with the filter (``tests/plan/test_bound.py``): the bound equals the covariance view of
:func:`inscal.plan.observability.observability` (one pass of the systematic filter on a
noise-free 20 Hz simulation, i.e. the ``systematic()`` posterior) per parameter within 3e-5 on s16,
5e-5 on psins19, 1e-5 on n25 (states 51; also 30, psins, async and unified within 3e-4); with
``lever9`` the filter's own discretisation of the angular acceleration (centred differences of
the 20 Hz samples smear the turntable's acceleration steps) costs it up to 6 % on the
off-diagonal lever arms at 20 Hz, 1.2 % at 100 Hz, converging to this bound.  Filter rate:
1 Hz vs 5 Hz differ by < 1 % (worst: the lever arm), as the filter's own (0.2 % on s16).
Speed (``bench/bench_crlb.py``): ~0.06 s of CPU for the 1.07-h S16 path (3,861 steps, 51
states), against ~1 s for the simulation and filter pass of ``observability()``.
Monte Carlo (``bench/crlb_vs_mc.py``): 50 noise-only ``systematic51`` runs per path on s16, n25
and psins19: the RMS of the normalised errors is 1.00-1.01 on each path.

Time series.  The filtered covariance after step ``k`` is the bound of the experiment cut at
``(k+1) T`` (constant parameters): :attr:`Bound.history` keeps its diagonal at every step,
which gives the bound over time and the information each move adds
(:mod:`inscal.report.path`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from inscal.calibrate.systematic.dynamics import nav_F
from inscal.calibrate.systematic.params import CompParams, truth_in_frame
from inscal.calibrate.systematic.states import (
    ARW_FLOOR,
    K_M1A,
    K_M1G,
    K_LEVT,
    K_TAU,
    N_NAV,
    NAV_SIGMA0,
    VRW_FLOOR,
    StateSet,
    field_value,
    prior_sigma,
    state_spec,
)
from inscal.calibrate.systematic.thermal_states import T_REF_C
from inscal.calibrate.windows import CalibrationError
from inscal.core import earth, units
from inscal.core.attitude import dcm_from_euler
from inscal.core.error_model import GimbalErrors
from inscal.core.thermal import RATE_WINDOW_S
from inscal.core.turntable import RotationPath, outer_axis
from inscal.plan.bound_kernel import bound_kernel
from inscal.plan.consider import CONSIDER_INPUTS, consider_columns
from inscal.plan.observability import (
    DEFAULT_ARW,
    DEFAULT_VRW,
    ObservabilityError,
    load_source,
    resolve_noise,
)
from inscal.plan.rows import BiasNoise, BoundError, extra_rows
from inscal.plan.slices import run_in_slices
from inscal.plan.thermal import KnownTemperature, default_t_ref, known_temperature
from inscal.sim.scenarios import S16_SITE
from inscal.sim.simulate import Scenario

#: velocity-measurement sigma of the systematic filter: VELOCITY_FACTOR * mean(VRW) * sqrt(T) (its default)
VELOCITY_FACTOR = 0.05
#: default sub-sample rate of the kinematics inside steps with motion [Hz]
SUB_RATE_HZ = 20.0
#: most filter steps of one bound (10^7: 116 days at 1 Hz, a day at 100 Hz; about 4 min of CPU with 51
#: states, 8 min with the unified model's encoder rows): more is no sensible experiment
MAX_STEPS = 10**7
#: CPU time of one filter step with 51 states [s] (measured on one core: 1.5e-5 on the S16 path, 2e-5 on N25's)
STEP_SECONDS = 2.5e-5


# ----------------------------------------------------------------------------- setup and result
@dataclass(frozen=True)
class Setup:
    """Everything of a bound that does not depend on the path (for repeated evaluation, e.g.
    path design): state set, site, gimbal geometry, noise, filter rate, prior and the
    constant matrices.  Build with :func:`make_setup`."""

    states: StateSet
    site: object  # inscal.core.earth.Site
    gimbal: object  # inscal.core.error_model.GimbalErrors
    arw: np.ndarray
    vrw: np.ndarray
    bias: BiasNoise
    T: float
    n_sub: int
    sig: np.ndarray  # scaling (prior sigma) of the full state incl. any GM states
    n_gm: int  # appended Gauss-Markov bias states
    kinds: np.ndarray
    axes: np.ndarray
    js: np.ndarray
    phinn: np.ndarray
    F: np.ndarray
    F2: np.ndarray
    qd: np.ndarray
    rs: np.ndarray  # scaled measurement variances
    phi_p: np.ndarray
    q_p: np.ndarray
    velocity_sigma: float
    position_sigma: float
    floored: bool
    need_rates: bool
    row_options: dict  # options of the extra measurement rows (e.g. encoder_sigma)
    labels: tuple[str, ...]  # parameter labels (without GM states)
    groups: tuple[str, ...]  # group of each parameter
    units_: tuple[str, ...]  # field unit of each parameter
    temperature: KnownTemperature | None = None  # thermal states: the filter's known temperature
    thermal: dict | None = None  # thermal states: t_ref, t_min, t_max, span, ... (KnownTemperature.info)
    consider: tuple[str, ...] = ()  # site and clock inputs whose sensitivity the bound carries (inscal.plan.consider)
    consider_u: np.ndarray | None = None  # their standard uncertainties (SI; zeros: sensitivities only)
    #: nominal lever arms (rows p_i, m) of the lever-arm timing's columns (``levtime``: they scale them)
    lever_arm: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    @property
    def n_params(self) -> int:
        """The number of parameter states the bound covers."""
        return len(self.labels)

    @property
    def prior(self) -> np.ndarray:
        """Prior sigma of the parameters (SI)."""
        return self.sig[N_NAV:N_NAV + self.n_params]

    def scenario(self, path: RotationPath):

        """A scenario of ``path`` at the setup's site and gimbal (for the functions that need one)."""
        return Scenario(path.name, path, self.site, gimbal=self.gimbal)


def make_setup(states: str | StateSet = "51", site=None, gimbal=None, arw=None, vrw=None,
               bias_noise: BiasNoise | None = None, filter_rate_hz: float = 1.0, sub_rate_hz: float = SUB_RATE_HZ,
               prior: dict | None = None, velocity_sigma: float | None = None,
               position_sigma: float | None = None, encoder_sigma: float | None = None,
               temperature: KnownTemperature | None = None, t_ref: float | None = None,
               consider: dict[str, float] | None = None, lever_arm=None) -> Setup:
    """The path-independent part of a bound (:class:`Setup`).  ``site``: a
    :class:`~inscal.core.earth.Site` (default S16's, 30 N 114 E); ``gimbal``: a
    :class:`~inscal.core.error_model.GimbalErrors` (default ideal); ``arw`` [rad/sqrt(s)] and ``vrw``
    [m/s/sqrt(s)], scalar or per axis (default S16's 5e-5 deg/sqrt(h), 1 ug/sqrt(Hz));
    ``prior``: prior 1 sigma per group (SI; default the groups' own); ``encoder_sigma`` [rad]: the
    encoder noise of the gimbal states' attitude rows (default the filter's).  Thermal states: ``temperature``
    the filter's known temperature over the experiment (:class:`~inscal.plan.thermal.KnownTemperature`; its
    span spreads the coefficients' prior), ``t_ref`` [degC] (default 20).  ``consider``: the site and clock inputs
    (:data:`inscal.plan.consider.CONSIDER_INPUTS`) whose sensitivity the bound carries, with their standard
    uncertainties (SI; 0: the sensitivity alone), for :attr:`Bound.combined_sigma`.  ``lever_arm`` (3, 3) [m]: the
    nominal lever arms (rows) about which the lever-arm timing's columns (``levtime``) are linearised: the columns
    are proportional to them, so at the ideal unit's zero lever arms those states keep their prior."""

    try:
        st = states if isinstance(states, StateSet) else StateSet.parse(states)
    except CalibrationError as exc:
        raise BoundError(str(exc)) from None
    site = S16_SITE if site is None else site
    gimbal = GimbalErrors() if gimbal is None else gimbal
    for n, v in (("filter rate", filter_rate_hz), ("sub-sample rate", sub_rate_hz)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise BoundError(f"{n} must be > 0 Hz, got {v}")
    T = 1.0 / float(filter_rate_hz)
    n_sub = max(1, int(round(sub_rate_hz * T)))
    nz = []
    for n, v, d in (("arw", arw, DEFAULT_ARW), ("vrw", vrw, DEFAULT_VRW)):
        a = np.broadcast_to(np.asarray(d if v is None else v, float), (3,)).copy()
        if not np.all(np.isfinite(a)) or np.any(a <= 0):
            raise BoundError(f"{n} must be a positive number, got {v}")
        nz.append(a)
    arw_v, vrw_v = nz
    floored = bool(np.any(arw_v < ARW_FLOOR) or np.any(vrw_v < VRW_FLOOR))
    arw_v = np.maximum(arw_v, ARW_FLOOR)
    vrw_v = np.maximum(vrw_v, VRW_FLOOR)
    bias = BiasNoise() if bias_noise is None else bias_noise
    # prior scaling
    pri = {}
    for k, v in (prior or {}).items():
        if k not in {g.name for g in st.groups}:
            raise BoundError(f"prior: unknown group {k!r}; groups: {', '.join(g.name for g in st.groups)}")
        if not (math.isfinite(float(v)) and float(v) > 0):
            raise BoundError(f"prior {k} must be > 0, got {v}")
        pri[k] = float(v)
    thermal = None
    if st.thermal:
        if temperature is None:
            raise BoundError("the thermal states need a temperature profile (a constant temperature leaves every "
                             "coefficient in one combination with its base term)")
        n_grid = max(1, int(bound_steps(temperature.duration_s, 1.0 / T))) * n_sub  # the kernel's sub-samples
        thermal = temperature.info(T_REF_C if t_ref is None else t_ref, n_grid, T / n_sub, "the temperature profile",
                                   BoundError)
    labels, groups, unit_l = [], [], []
    for gr in st.groups:
        for lab in gr.labels:
            labels.append(f"{gr.name}[{lab}]" if lab else gr.name)
            groups.append(gr.name)
            unit_l.append(gr.unit)
    # the filter's prior (a thermal coefficient's spread over the span of the temperature)
    sig_p = prior_sigma(st, pri, thermal["span"] if thermal else 1.0).tolist()
    kinds, axes, js = st.columns()
    p = len(labels)
    phi_p = np.ones(p)
    q_p = np.zeros(p)
    off = st.offsets()
    for gname, rw in (("gyro_bias", bias.gyro_rw), ("accel_bias", bias.accel_rw)):
        if np.any(rw) and gname in off:
            for i in range(3):
                c = off[gname] - N_NAV + i
                q_p[c] = rw[i] ** 2 * T / sig_p[c] ** 2
    n_gm = 0
    extra_k, extra_a, extra_s, extra_phi, extra_q = [], [], [], [], []
    for gname, kind, gm, tau in (("gyro_bias", K_M1G, bias.gyro_gm, bias.gyro_tau),
                                 ("accel_bias", K_M1A, bias.accel_gm, bias.accel_tau)):
        if np.any(gm) and gname in off:
            ph = math.exp(-T / tau)
            for i in range(3):
                sg = max(float(gm[i]), 1e-30)
                extra_k.append(kind)
                extra_a.append(i)
                extra_s.append(sg)
                extra_phi.append(ph)
                extra_q.append(1.0 - ph * ph)  # scaled: sigma^2 (1 - phi^2) / sigma^2
                n_gm += 1
    if n_gm:
        kinds = np.concatenate([kinds, np.array(extra_k, np.int64)])
        axes = np.concatenate([axes, np.array(extra_a, np.int64)])
        js = np.concatenate([js, np.array(extra_a, np.int64)])
        phi_p = np.concatenate([phi_p, extra_phi])
        q_p = np.concatenate([q_p, extra_q])
    sig = np.array(list(NAV_SIGMA0) + sig_p + extra_s)
    need_rates = bool(np.any(kinds == K_TAU) or np.any(kinds == 8) or np.any(kinds == K_LEVT))
    lev = np.zeros((3, 3)) if lever_arm is None else np.asarray(lever_arm, float)
    if lev.shape != (3, 3) or not np.all(np.isfinite(lev)):
        raise BoundError(f"lever_arm must be a finite 3 x 3 array of rows p_i [m], got shape {lev.shape}")
    # constant matrices (static base: f^n = [0, 0, g])
    lat, h = site.latitude, site.height
    gsc = float(site.gravity_scale)
    F = np.zeros((9, 9))
    nav_F(lat, h, np.array([0.0, 0.0, float(site.gravity)]), F, gsc)
    F2 = F @ F
    F3 = F2 @ F
    phinn = np.eye(9) + F * T + F2 * (T * T / 2) + F3 * (T**3 / 6)
    Qc = np.zeros((9, 9))
    Qc[0:3, 0:3] = np.eye(3) * float(np.mean(arw_v**2))
    Qc[3:6, 3:6] = np.eye(3) * float(np.mean(vrw_v**2))
    FQ = F @ Qc
    qd = Qc * T + (FQ + FQ.T) * (T * T / 2) + (F2 @ Qc + 2.0 * FQ @ F.T + Qc @ F2.T) * (T**3 / 6)
    vsig = float(velocity_sigma) if velocity_sigma is not None else VELOCITY_FACTOR * float(np.mean(vrw_v)) * math.sqrt(T)
    psig = float(position_sigma) if position_sigma is not None else vsig * T
    r = np.array([vsig**2] * 3 + [psig**2] * 3)
    rs = r / sig[3:9] ** 2
    cons = dict(consider or {})
    for k, v in cons.items():
        if k not in CONSIDER_INPUTS:
            raise BoundError(f"consider: unknown input {k!r}; known: {', '.join(CONSIDER_INPUTS)}")
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
            raise BoundError(f"consider: the uncertainty of {k} must be >= 0, got {v}")
    return Setup(st, site, gimbal, arw_v, vrw_v, bias, T, n_sub, sig, n_gm, kinds, axes, js, phinn, F, F2, qd, rs,
                 phi_p, q_p, vsig, psig, floored, need_rates, {"encoder_sigma": encoder_sigma}, tuple(labels),
                 tuple(groups), tuple(unit_l), temperature if thermal else None, thermal, tuple(cons),
                 np.array([float(v) for v in cons.values()]), np.ascontiguousarray(lev))


@dataclass(frozen=True)
class Bound:
    """The bound of one experiment (SI inside; :meth:`table` gives field units)."""

    path_name: str
    duration_s: float
    setup: Setup
    steps: int
    covariance: np.ndarray  # (p, p) posterior covariance of the parameters (SI)
    history: np.ndarray | None  # (steps, p) posterior variance after each step (SI)
    seconds: float
    sensitivity: np.ndarray | None = None  # (p, m) d(estimate) / d(consider input), SI per SI (setup.consider)

    @property
    def combined_sigma(self) -> np.ndarray:
        """The bound combined with the consider inputs' uncertainties (SI): ``sqrt(sigma^2 + sum_i (S_i u_i)^2)``
        (GUM eq. 10); the bound itself without them."""
        s = self.sigma
        if self.sensitivity is None or not self.setup.consider:
            return s
        return np.sqrt(s**2 + np.sum((self.sensitivity * self.setup.consider_u) ** 2, axis=1))

    @property
    def labels(self) -> tuple[str, ...]:
        """The parameter states' labels, in the order of ``sigma``."""
        return self.setup.labels

    @property
    def sigma(self) -> np.ndarray:
        """Bound (1 sigma, SI) of each parameter."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    @property
    def prior(self) -> np.ndarray:
        """The prior 1 sigma of every parameter state (SI)."""
        return self.setup.prior

    @property
    def t_steps(self) -> np.ndarray:
        """Time of each update (end of each filter step) [s]."""
        return (np.arange(self.steps) + 1.0) * self.setup.T

    def sigma_history(self) -> np.ndarray:
        """(steps, p) bound over time (SI): the bound of the experiment cut at :attr:`t_steps`."""
        if self.history is None:
            raise BoundError("the bound was computed without its history")
        return np.sqrt(np.maximum(self.history, 0.0))

    def by_label(self) -> dict[str, float]:
        """The bound's 1 sigma (SI) of every parameter state, by label."""
        return dict(zip(self.labels, self.sigma.tolist()))

    def table(self) -> list[dict]:
        """Per parameter: label, group, field unit, prior, bound and bound / prior."""
        out = []
        s, p0 = self.sigma, self.prior
        for k, lab in enumerate(self.labels):
            u = self.setup.units_[k]
            out.append({"label": lab, "group": self.setup.groups[k], "unit": u,
                        "prior": float(field_value(p0[k], u)), "bound": float(field_value(s[k], u)),
                        "ratio": float(s[k] / p0[k])})
        return out

    def group_rms(self, sigma: np.ndarray | None = None) -> dict[str, float]:
        """RMS of the bound per group (field units): ``sqrt(mean sigma^2)`` over its components."""
        s = self.sigma if sigma is None else sigma
        out: dict[str, list] = {}
        for k, g in enumerate(self.setup.groups):
            out.setdefault(g, []).append(float(field_value(s[k], self.setup.units_[k])))
        return {g: float(np.sqrt(np.mean(np.square(v)))) for g, v in out.items()}

    def to_dict(self) -> dict:
        """The bound as JSON (``observability --crlb --json``): path, states, rates, site, noise and every
        parameter's bound in field units.
        """
        su = self.setup
        return {"path": {"name": self.path_name, "duration_s": self.duration_s}, "states": _spec(su.states),
                "n_params": su.n_params, "filter_rate_hz": 1.0 / su.T, "sub_rate_hz": su.n_sub / su.T,
                "steps": self.steps,
                "site": {"latitude_deg": math.degrees(su.site.latitude), "longitude_deg": math.degrees(su.site.longitude),
                         "height_m": su.site.height},
                "noise": {"arw_deg_sqrt_h": units.from_si(su.arw, "deg/sqrt(h)").tolist(),
                          "vrw_ug_sqrt_hz": units.from_si(su.vrw, "ug/sqrt(Hz)").tolist(), "floored": su.floored,
                          "velocity_sigma_m_s": su.velocity_sigma, "position_sigma_m": su.position_sigma,
                          "bias": su.bias.to_dict() if su.bias.active else None},
                "parameters": self.table(), "group_rms": self.group_rms(), "seconds": self.seconds,
                **({"temperature": su.thermal} if su.thermal else {})}


def _spec(st: StateSet) -> str:

    try:
        return state_spec(st)
    except Exception:  # a state set the helper does not know
        return str(st)


def bound_steps(duration_s: float, filter_rate_hz: float) -> float:
    """Filter steps of the bound of a ``duration_s`` path at ``filter_rate_hz``, counted as
    :func:`evaluate` counts them (a float: an absurd request need not fit an int; inf if not finite)."""
    x = float(duration_s) / (1.0 / float(filter_rate_hz)) + 1e-9
    return float(math.floor(x)) if math.isfinite(x) else math.inf


def bound_bytes(setup: Setup, steps: float, keep_history: bool = True) -> float:
    """Memory [bytes] of a bound that grows with its ``steps``: the history (diag(P) per step, then
    its parameter part in SI).  Without the history a bound runs in memory independent of its length
    (the extra measurement rows are built one slice of steps at a time)."""
    return 8.0 * steps * (setup.sig.size + setup.n_params) if keep_history else 0.0


def evaluate(setup: Setup, path: RotationPath, keep_history: bool = True) -> Bound:
    """The bound of ``path`` under ``setup`` (module docstring).  The kernel runs in slices of steps
    (:func:`inscal.plan.slices.run_in_slices`), so an interrupt is honoured within a fraction of a second."""
    t0 = time.perf_counter()
    seg = path.segments()
    T = setup.T
    M = bound_steps(seg.t1[-1], 1.0 / T)
    if M < 2:
        raise BoundError(f"path {path.name!r} is too short ({seg.t1[-1]:g} s) for a {T:g} s filter step")
    if M > MAX_STEPS:
        raise BoundError(f"path {path.name!r} ({seg.t1[-1]:.4g} s) at a {T:g} s filter step is {M:.3g} steps, more "
                         f"than the {MAX_STEPS:.0e} of a sensible bound")
    M = int(M)
    if setup.thermal and abs(setup.temperature.duration_s - seg.t1[-1]) > 1e-6 * max(1.0, seg.t1[-1]):
        raise BoundError(f"path {path.name!r} lasts {seg.t1[-1]:.6g} s, its known temperature "
                         f"{setup.temperature.duration_s:.6g} s (make_setup with the path's KnownTemperature)")
    N = setup.sig.size
    ns = setup.states.n_states
    u = outer_axis(setup.gimbal.nonorthogonality)
    Cbn = dcm_from_euler(setup.gimbal.mount_attitude)
    wie = earth.earth_rate_n(setup.site.latitude)
    sc = setup.scenario(path)
    path_arrays = (*(np.ascontiguousarray(a, float) for a in (seg.t0, seg.t1, seg.th0, seg.w0, seg.acc)), u, Cbn, wie,
                   float(setup.site.gravity))
    P = np.eye(N)
    hist = np.empty((M if keep_history else 0, N))
    last = np.full(1, -1, np.int64)  # the kernel's state between slices: dwell, its Phi_np, its columns
    phinp = np.empty((9, N - N_NAV))
    Vs = np.zeros((6, N - N_NAV))

    no_temp = np.empty((0, setup.n_sub))
    Vc = consider_columns(setup.site, setup.consider)
    E = np.zeros((N, Vc.shape[1]))

    def kernel(k0: int, k1: int) -> None:
        xH, xr = extra_rows(setup.states, sc, (np.arange(k0, k1) + 1.0) * T, setup.sig[:ns], setup.row_options)
        if xH.shape[1]:
            if N > ns:
                xH = np.concatenate([xH, np.zeros(xH.shape[:2] + (N - ns,))], axis=2)
            xH = xH * setup.sig[None, None, :]
        th = (setup.temperature.steps(setup.thermal["t_ref"], k0, k1, T, setup.n_sub) if setup.thermal
              else (no_temp, no_temp))
        bound_kernel(k0, k1, T, setup.n_sub, path_arrays, setup.need_rates,
                     setup.kinds, setup.axes, setup.js, setup.sig, setup.phinn, setup.F, setup.F2, setup.qd,
                     setup.rs, setup.phi_p[:N - N_NAV], setup.q_p, np.ascontiguousarray(xH),
                     np.ascontiguousarray(xr, float), P, hist[k0:k1] if keep_history else hist, last, phinp, Vs, *th,
                     Vc, E, setup.lever_arm)

    run_in_slices(M, kernel, first=max(1, 4096 // setup.n_sub))
    p = setup.n_params
    sp = setup.sig[N_NAV:N_NAV + p]
    cov = P[N_NAV:N_NAV + p, N_NAV:N_NAV + p] * np.outer(sp, sp)
    h = hist[:, N_NAV:N_NAV + p] * sp**2 if keep_history else None
    sens = -E[N_NAV:N_NAV + p] * sp[:, None] if setup.consider else None  # the estimate is nominal - x^
    return Bound(path.name, float(seg.t1[-1]), setup, M, cov, h, time.perf_counter() - t0, sens)


def crlb(source, states: str | StateSet = "51", *, arw=None, vrw=None, bias_noise: BiasNoise | None = None,
         filter_rate_hz: float = 1.0, sub_rate_hz: float = SUB_RATE_HZ, prior: dict | None = None,
         keep_history: bool = True, t_ref: float | None = None, rate_window_s: float | None = RATE_WINDOW_S,
         consider: dict[str, float] | None = None, site=None) -> Bound:
    """The Cramér-Rao bound of a calibration experiment (the systematic filter's information).

    From a Scenario, RotationPath, built-in name or TOML file (as
    :func:`inscal.plan.observability.load_source`): the scenario's site, gimbal geometry and noise
    (ARW/VRW; its Gauss-Markov bias instability unless ``bias_noise`` is given); a bare path at the S16
    site with the S16 noise.  With the lever-arm timing (``levtime``) its columns are linearised at the
    scenario's lever arms (a bare path: zero, the prior).

    Parameters
    ----------
    source : Scenario, RotationPath or str
        The experiment.
    states : str or StateSet
        The state set (``"51"``, ``"30"``, ``"51,thermal"``, ...).
    arw, vrw : float, optional
        White noise [rad/sqrt(s)], [m/s/sqrt(s)] instead of the scenario's.
    bias_noise : BiasNoise, optional
        The bias instability model.
    filter_rate_hz, sub_rate_hz : float
        The filter's rate and the rate its steps are integrated at [Hz].
    prior : dict, optional
        Prior sigma by state group.
    keep_history : bool
        Keep the bound's history over the path (for the figures).
    t_ref : float, optional
        The thermal states' reference temperature [degC] (default the scenario's thermal model's,
        else 20).
    rate_window_s : float or None
        The window of the temperature's slope [s] (None: the profile's exact rate).
    consider : dict, optional
        Consider parameters and their sigma (as :func:`make_setup`).
    site : Site, optional
        A site instead of the scenario's (a station's).

    Returns
    -------
    Bound
        The covariance bound of the parameters (``sigma``, ``table()`` in field units).

    Raises
    ------
    BoundError
        A source or state set that cannot be evaluated, or a thermal state set without a known
        temperature.

    Examples
    --------
    >>> from inscal.plan.bound import crlb
    >>> bound = crlb("n25", "30", keep_history=False)
    >>> row = bound.table()[0]
    >>> row["label"], row["unit"], bool(row["bound"] < row["prior"])
    ('gyro_matrix[xx]', 'ppm', True)
    """

    try:
        sc, kind, label = load_source(source)
        arw_v, vrw_v, _ = resolve_noise(sc, kind, arw, vrw)
        st = states if isinstance(states, StateSet) else StateSet.parse(states)
    except ObservabilityError as exc:
        raise BoundError(str(exc)) from None
    except CalibrationError as exc:
        raise BoundError(str(exc)) from None
    if bias_noise is None and kind == "scenario":
        bias_noise = BiasNoise.from_imu_noise(sc.noise)
    if site is not None:
        sc = replace(sc, site=site)
    temp = known_temperature(sc, label, rate_window_s=rate_window_s, error=BoundError) if st.thermal else None
    lev = np.asarray(sc.imu.accel_lever_arm, float) if (st.lever_timing and kind == "scenario") else None
    setup = make_setup(st, sc.site, sc.gimbal, arw_v, vrw_v, bias_noise, filter_rate_hz, sub_rate_hz, prior,
                       temperature=temp, t_ref=default_t_ref(sc) if t_ref is None else t_ref, consider=consider,
                       lever_arm=lev)
    return evaluate(setup, sc.path, keep_history)


def predicted_error(b: Bound, imu) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the error (estimate - truth, the filter's parameter error
    state, SI) of a linear-Gaussian calibration of an IMU whose truth ``imu`` (canonical
    :class:`~inscal.core.error_model.ImuErrors`) is fixed while only the noise varies (a noise-only Monte
    Carlo).  With the bound ``P``, the prior ``P0 = diag(sigma0^2)`` centred on the nominal (ideal)
    parameters and the data information ``L = P^-1 - P0^-1``, the posterior mean is
    ``x^ = P (L x + P0^-1 mu)``, so ``x^ - x`` has mean ``P P0^-1 (mu - x)`` (the prior's pull) and
    covariance ``P L P = P - P P0^-1 P`` (the noise).  Both are zero / equal to ``P`` where the data
    dominate the prior (bound << prior); where they do not, a fixed-truth spread is smaller than
    the bound.  Constant parameters only (no Gauss-Markov bias states)."""

    su = b.setup
    if su.n_gm:
        raise BoundError("predicted_error needs constant parameter states (no Gauss-Markov bias states)")
    st = su.states
    x_nom = CompParams().error_state(st, truth_in_frame(imu, st))  # nominal - truth (first order)
    P = b.covariance
    L0 = 1.0 / su.prior**2
    mean = P @ (L0 * x_nom)
    cov = P - (P * L0) @ P
    return mean, np.sqrt(np.maximum(np.diag(cov), 0.0))
