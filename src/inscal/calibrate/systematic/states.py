"""State sets of the systematic filter as data (S16 eq. 17-27): the navigation states, the parameter
groups with their names, sizes, units, initial sigma and the kind of Jacobian column that feeds them,
and the options (``51``, ``30``, ``lever9``, ``async``, ``psins``, ``gimbal``, ``thermal``).

Thermal states (option ``thermal``; the model of :mod:`inscal.core.thermal`).  The coefficients of the
bias and scale-factor polynomials in ``dT = T - T_ref`` and the gyro bias per ``dT/dt`` are states of
their own, one group per term and order (``gyro_bias_dT1``, ``gyro_bias_dT2``, ...,
``accel_scale_factor_dT2``, ``gyro_bias_rate``), with the measured temperature a known input of every
sample.  They act on each sensor's raw output, before the compensation matrix (the canonical
measurement model ``N = (I + K(T))(I + E) u + b(T)``, inverted exactly as
:meth:`inscal.core.thermal.ThermalModel.to_reference` does)::

    y_i = (N_i / dt - eps_i - beta_i(T)) / (1 + s_i(T)) + eps_i       eps = A^-1 b, the base bias (sensor axes)
    beta_i = sum_k c_b,ik dT^k (+ D_i dT/dt for the gyros),   s_i = sum_k c_s,ik dT^k

and ``A y`` replaces ``A N / dt`` (``u_g``, ``u_a`` of S16 eq. 3, 6).  The bias coefficients are those of
the canonical model; the scale-factor ones are ``c_K,k / (1 + K_0,i)`` (the canonical ``K(T) = K_0 + sum_k
c_K,k dT^k``), so the family holds the model exactly.  Being sensor-axis quantities they need no frame
rotation.  Their Jacobian columns are the base columns times a known scalar of the sample (``C_m^n e_i``
times ``-dT^k``, ``-(u - b)_i dT^k`` or ``-dT/dt``; the factors ``A e_i`` and ``1 / (1 + s_i)`` of the exact
derivative differ from ``e_i`` and 1 by parts in 1e4, and a scale-factor column takes ``(u - b)_i`` of the
compensated frame for the sensor axis's ``y_i - eps_i``, off by ``|A - I| |u|``: parts in 1e4 of the group's
largest column, though a nearly level axis's own column may be off by its whole size: a Jacobian approximation
that the iterated passes do not see in their fixed point).  Thermal misalignment terms are not states.

Gauss-Markov bias states (from a noise model with GM terms: :mod:`inscal.calibrate.systematic.gm_states`).  One
first-order Gauss-Markov bias per GM term of a gyro or accelerometer channel, a *dynamic* state like the navigation
errors: the state vector is ``[navigation (9) | GM biases (n_gm) | parameters]``, so the square-root prediction and
the smoother move the first ``n_dyn = 9 + n_gm`` states and keep the parameters constant."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.core.error_model import CROSS_NAMES

N_NAV = 9
IDX_MEAS = np.array([3, 4, 5, 6, 7, 8], dtype=np.int64)

# column kinds of the per-sample parameter Jacobian (row block 0: phi rows, 1: dv rows)
K_UG, K_M1G, K_MF, K_UA, K_M1A, K_F2, K_FX, K_LEVD, K_LEVF, K_TAU = range(10)
# gimbal states (dth, alpha0, beta0, gamma0; js = index into the gimbal array): no column in Phi_np
K_GIM = 10
# thermal coefficient states (js = the row of the thermal array, THERMAL_ROWS; axes = the sensor axis)
K_TH = 11
#: the lever-arm timing nuisance (``levtime``): per accelerometer, the time by which the lever-arm terms it
#: senses lag the rest of its specific force, in navigation axes (dynamics.lever_timing_rate)
K_LEVT = 12

DIAG = ((0, 0), (1, 1), (2, 2))
OFFD = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))  # = errors.MISALIGN_INDEX order
LOWER = DIAG + ((1, 0), (2, 0), (2, 1))
FULL = DIAG + OFFD
AX = "xyz"
CROSS_PAIRS = ((0, 0, 1), (0, 0, 2), (1, 0, 1), (1, 1, 2), (2, 0, 2), (2, 1, 2))  # (row, a, b): S16 eq. 12


# ----------------------------------------------------------------------------- state sets
@dataclass(frozen=True)
class Group:
    """One parameter group of the state vector."""

    name: str  # gyro_matrix, gyro_bias, gyro_g_sensitivity, accel_matrix, accel_bias,
    # accel_nonlinearity, accel_cross_coupling, accel_lever_arm, time_asynchrony
    labels: tuple[str, ...]
    kinds: tuple[int, ...]
    axes: tuple[int, ...]  # row i (the sensor axis) of each column
    js: tuple[int, ...]  # second index (column j / product pair / lever component)
    sigma0: float  # default prior 1 sigma (SI)
    unit: str  # field unit for reports

    @property
    def size(self) -> int:
        return len(self.labels)


def _matrix_group(name, ij, kind, sigma0, unit):
    labels = tuple(f"{AX[i]}{AX[j]}" for i, j in ij)
    return Group(name, labels, (kind,) * len(ij), tuple(i for i, _ in ij), tuple(j for _, j in ij), sigma0, unit)


def _vec_group(name, kind, sigma0, unit):
    return Group(name, tuple(AX), (kind,) * 3, (0, 1, 2), (0, 1, 2), sigma0, unit)


UG = units.to_si(1.0, "ug")
#: passes after the first run with prior widths of at most DEFLATE times the previous posterior sigma
DEFLATE = 30.0
#: prior 1 sigma of the navigation states: level, heading [rad], velocity [m/s], position [m]
NAV_SIGMA0 = tuple([units.to_si(600.0, "arcsec")] * 2 + [units.to_si(1.0, "deg")] + [0.01] * 6)
ARW_FLOOR = units.to_si(1e-5, "deg/sqrt(h)")
VRW_FLOOR = units.to_si(0.2, "ug/sqrt(Hz)")
DEFAULT_SIGMA0 = {
    "gyro_matrix": 1e-3, "gyro_bias": units.to_si(0.1, "deg/h"), "gyro_g_sensitivity": units.to_si(0.01, "deg/h/g"),
    "accel_matrix": 1e-3, "accel_bias": 1000 * UG, "accel_nonlinearity": units.to_si(1000.0, "ug/g^2"),
    "accel_cross_coupling": units.to_si(1000.0, "ug/g^2"), "accel_lever_arm": 0.05, "time_asynchrony": 5e-3,
    "accel_lever_timing": 20e-3,
    "gimbal_nonorthogonality": units.to_si(60.0, "arcsec"), "mount_attitude": units.to_si(1.0, "deg"),
}
#: prior 1 sigma of each thermal term's change over the record's temperature span (SI of the base quantity): the
#: coefficient of order k gets ``sigma / span^k`` (span = the largest ``|T - T_ref|`` of the record, at least
#: 1 degC); the dT/dt term its own sigma [rad/degC]
THERMAL_SIGMA0 = {"gyro_bias": units.to_si(1.0, "deg/h"), "gyro_scale_factor": 1e-3, "accel_bias": 3000 * UG,
                  "accel_scale_factor": 1e-3, "gyro_bias_rate": units.to_si(1.0, "deg/h/(degC/min)")}
#: the thermal terms the filter estimates: name -> (first row of the thermal array, base unit, gyro triad)
THERMAL_ROWS = {"gyro_bias": (0, "deg/h", True), "gyro_scale_factor": (3, "ppm", True),
                "accel_bias": (6, "ug", False), "accel_scale_factor": (9, "ppm", False),
                "gyro_bias_rate": (12, "deg/h/(degC/min)", True)}
#: rows of the thermal array: three orders of each polynomial term, then the dT/dt term
N_TH_ROWS = 13
TH_RATE_ROW = 12
#: default orders (gyro bias, gyro scale factor, accelerometer bias, accelerometer scale factor, dT/dt term 0/1):
#: those of the built-in thermal scenarios' model (``inscal.sim.scenarios.THERMAL_ERRORS``)
THERMAL_ORDERS = (2, 2, 3, 2, 1)
#: the thermal terms the filter can carry as states, in the order of their rows
THERMAL_TERM_NAMES = tuple(THERMAL_ROWS)
#: default white noise of each encoder angle (gimbal states)
ENCODER_SIGMA = units.to_si(1.0, "arcsec")
FRAME_GIMBAL = "gimbal-defined (N25 s-frame)"

#: named options of ``--states``
STATE_OPTIONS = {
    "51": "S16 eq. 22: attitude, velocity, position, gyro matrix (lower-triangular, 6), gyro bias, accelerometer "
          "matrix (full, 9), accelerometer bias, g-sensitivity (9), nonlinearity (3), cross-coupling (6), lever arm (3)",
    "30": "S16's traditional 30-state filter: no g-sensitivity, nonlinearity, cross-coupling or lever arm",
    "lever9": "full inner lever arm: a 3-vector per accelerometer (9 states instead of 3)",
    "async": "gyro-accelerometer time asynchrony (1 state)",
    "gimbal": "gimbal non-orthogonality and mount attitude (4 states) observed through the encoder angles; the "
              "frame is then the gimbal's s-frame and the gyro matrix full (9): 51 + 3 + 4 = 58 states",
    "unified": "51,gimbal: the unified estimator (S16 51-state filter plus the N25 gimbal states)",
    "psins": "PSINS triangular convention: gyro matrix full (9), accelerometer matrix lower-triangular (6); "
              "the IMU frame is then defined by the accelerometers",
    "gdiag": "g-sensitivity diagonal only (3 states instead of 9): the off-diagonal terms fixed at zero",
    "nocross": "no accelerometer cross-coupling states (6 fewer): fixed at zero",
    "thermal": "thermal coefficients as states, the record's temperature a known input: bias and scale-factor "
               "polynomials in T - T_ref of both triads (orders 2, 2, 3, 2) and the gyro bias per dT/dt (3): 30 states; "
               "thermal=GSABR picks the orders (gyro bias, gyro scale factor, accel bias, accel scale factor 0-3, "
               "dT/dt term 0-1), e.g. thermal=11110",
    "levtime": "lever-arm timing (3 nuisance states, one per accelerometer): the lever-arm terms it senses lag the "
               "rest of its specific force by their own time, as a generator that does not advance them with the "
               "asynchrony writes them; needs the extended model",
    "auto": "chosen from the record: start from 51 and add or drop async, lever9, levtime, gdiag and nocross by an F-test "
            "on the innovations, and with lever9 the frame (psins or not) by the lower chi2 (see "
            "inscal.calibrate.systematic.selection)",
}
#: what each option sets on :class:`StateSet`
_OPTION_FLAGS = {"51": {"extended": True}, "30": {"extended": False}, "lever9": {"lever9": True},
                 "async": {"asynchrony": True}, "gimbal": {"gimbal": True}, "levtime": {"lever_timing": True},
                 "unified": {"extended": True, "gimbal": True}, "psins": {"psins": True},
                 "gdiag": {"gsens_offdiag": False}, "nocross": {"cross": False}}


@dataclass(frozen=True)
class GMState:
    """One first-order Gauss-Markov bias state: ``sensor`` 'gyro' or 'accel', sensor ``axis`` 0-2, stationary
    ``sigma`` [rad/s or m/s^2] and correlation time ``tc`` [s] (:class:`inscal.core.noise_models.GaussMarkov`)."""

    sensor: str
    axis: int
    sigma: float
    tc: float

    @property
    def label(self) -> str:
        """``gm_gyro_bias[x]``; a second term on the same axis adds its number (``gm_gyro_bias[x2]``)."""
        return f"gm_{self.sensor}_bias[{AX[self.axis]}]"


@dataclass(frozen=True)
class StateSet:
    """A configuration of the systematic filter's parameter states (S16 eq. 22)."""

    extended: bool = True  # G, K2, Kx, lever arm
    lever9: bool = False
    asynchrony: bool = False
    psins: bool = False
    lever_timing: bool = False  # the lever-arm timing nuisance (levtime)
    gimbal: bool = False  # dth + mount attitude, encoder attitude rows; frame = the gimbal's s-frame
    gsens_offdiag: bool = True  # the six off-diagonal g-sensitivity terms (extended model)
    cross: bool = True  # the six cross-coupling terms (extended model)
    #: orders of the thermal terms (THERMAL_TERM_NAMES; empty: no thermal states)
    thermal: tuple[int, ...] = ()
    #: Gauss-Markov bias states (dynamic, between the navigation states and the parameters; empty: none)
    gm: tuple[GMState, ...] = ()

    @classmethod
    def parse(cls, spec: str | None) -> "StateSet":
        """``"51"``, ``"30"``, optionally followed by ``,lever9``, ``,async``, ``,psins``, ``,gimbal``;
        ``"unified"`` = ``"51,gimbal"``."""
        if spec is None or str(spec).strip() == "":
            return cls()
        toks = [t.strip() for t in str(spec).replace("+", ",").split(",") if t.strip()]
        kw = {"extended": True}
        for t in toks:
            if t.startswith("thermal="):
                kw["thermal"] = parse_thermal_orders(t[len("thermal="):])
                continue
            if t == "thermal":
                kw["thermal"] = THERMAL_ORDERS
                continue
            if t not in _OPTION_FLAGS:
                raise CalibrationError(f"unknown state option {t!r}; options: {', '.join(STATE_OPTIONS)}")
            kw.update(_OPTION_FLAGS[t])
        if "auto" in toks:
            raise CalibrationError("'auto' is chosen by inscal.calibrate.systematic.selection.select_states, "
                                   "not a fixed state set")
        for opt in ("lever9", "gsens_offdiag", "cross", "lever_timing"):
            if opt in kw and kw[opt] != cls.__dataclass_fields__[opt].default and not kw["extended"]:
                raise CalibrationError(f"{ {'gsens_offdiag': 'gdiag', 'cross': 'nocross', 'lever_timing': 'levtime'}.get(opt, opt)} needs the "
                                       "extended (51-state) model")
        if kw.get("gimbal") and kw.get("psins"):
            raise CalibrationError("psins (accelerometer-defined frame) and gimbal (the gimbal's s-frame) exclude "
                                   "each other")
        return cls(**kw)

    @property
    def frame(self) -> str:
        return "gimbal" if self.gimbal else ("accel" if self.psins else "gyro")

    @property
    def groups(self) -> tuple[Group, ...]:
        s = DEFAULT_SIGMA0
        gm = _matrix_group("gyro_matrix", FULL if (self.psins or self.gimbal) else LOWER, K_UG, s["gyro_matrix"], "ppm")
        am = _matrix_group("accel_matrix", LOWER if self.psins else FULL, K_UA, s["accel_matrix"], "ppm")
        out = [gm, _vec_group("gyro_bias", K_M1G, s["gyro_bias"], "deg/h"), am,
               _vec_group("accel_bias", K_M1A, s["accel_bias"], "ug")]
        if self.extended:
            ij9 = tuple((i, j) for i in range(3) for j in range(3))
            out.append(_matrix_group("gyro_g_sensitivity", ij9 if self.gsens_offdiag else DIAG, K_MF,
                                     s["gyro_g_sensitivity"], "deg/h/g"))
            out.append(Group("accel_nonlinearity", tuple(AX), (K_F2,) * 3, (0, 1, 2), (0, 1, 2),
                             s["accel_nonlinearity"], "ug/g^2"))
            if self.cross:
                out.append(Group("accel_cross_coupling", CROSS_NAMES, (K_FX,) * 6, tuple(p[0] for p in CROSS_PAIRS),
                                 tuple(range(6)), s["accel_cross_coupling"], "ug/g^2"))
            if self.lever9:
                out.append(_matrix_group("accel_lever_arm", ij9, K_LEVF, s["accel_lever_arm"], "cm"))
            else:
                out.append(Group("accel_lever_arm", tuple(AX), (K_LEVD,) * 3, (0, 1, 2), (0, 1, 2),
                                 s["accel_lever_arm"], "cm"))
        if self.extended and self.lever_timing:
            out.append(Group("accel_lever_timing", tuple(AX), (K_LEVT,) * 3, (0, 1, 2), (0, 1, 2),
                             s["accel_lever_timing"], "ms"))
        if self.asynchrony:
            out.append(Group("time_asynchrony", ("",), (K_TAU,), (0,), (0,), s["time_asynchrony"], "ms"))
        if self.gimbal:  # N25 eq. 5-8; js = index into the gimbal array [dth, alpha0, beta0, gamma0]
            out.append(Group("gimbal_nonorthogonality", ("",), (K_GIM,), (0,), (0,), s["gimbal_nonorthogonality"],
                             "arcsec"))
            out.append(Group("mount_attitude", ("alpha0", "beta0", "gamma0"), (K_GIM,) * 3, (0, 0, 0), (1, 2, 3),
                             s["mount_attitude"], "arcsec"))
        out += thermal_groups(self.thermal)  # last: the thermal block of the covariance is its lower-right corner
        return tuple(out)

    @property
    def n_params(self) -> int:
        return sum(g.size for g in self.groups)

    @property
    def n_dyn(self) -> int:
        """The dynamic states: navigation (9) and the Gauss-Markov biases; the parameters follow them."""
        return N_NAV + len(self.gm)

    @property
    def n_states(self) -> int:
        return self.n_dyn + self.n_params

    def gm_labels(self) -> list[str]:
        """The labels of the Gauss-Markov states (a repeated axis numbered: ``gm_gyro_bias[x2]``)."""
        out, seen = [], {}
        for g in self.gm:
            k = seen[g.label] = seen.get(g.label, 0) + 1
            out.append(g.label if k == 1 else g.label[:-1] + f"{k}]")
        return out

    def labels(self) -> list[str]:
        nav = [f"attitude[{a}]" for a in "ENU"] + [f"velocity[{a}]" for a in "ENU"] + [f"position[{a}]" for a in "ENU"]
        return nav + self.gm_labels() + [f"{g.name}[{lab}]" if lab else g.name for g in self.groups
                                         for lab in g.labels]

    def offsets(self) -> dict[str, int]:
        off, k = {}, self.n_dyn
        for g in self.groups:
            off[g.name] = k
            k += g.size
        return off

    def columns(self):
        kinds, axes, js = [], [], []
        for g in self.groups:
            kinds += g.kinds
            axes += g.axes
            js += g.js
        return np.array(kinds, np.int64), np.array(axes, np.int64), np.array(js, np.int64)


def parse_thermal_orders(text: str) -> tuple[int, ...]:
    """The orders of ``thermal=GSABR`` (five digits: gyro bias, gyro scale factor, accelerometer bias and scale
    factor 0-3, the dT/dt term 0-1)."""
    if len(text) != len(THERMAL_TERM_NAMES) or not text.isdigit():
        raise CalibrationError(f"thermal={text}: expected five digits (orders of gyro bias, gyro scale factor, accel bias, "
                               "accel scale factor 0-3 and the dT/dt term 0-1), e.g. thermal=22321")
    orders = tuple(int(c) for c in text)
    if max(orders[:4]) > 3 or orders[4] > 1:
        raise CalibrationError(f"thermal={text}: the polynomial orders go up to 3 and the dT/dt term is 0 or 1")
    return orders if any(orders) else ()


def thermal_orders_from(orders: dict) -> tuple[int, ...]:
    """The orders tuple of a dict ``term -> order`` (missing terms: the defaults :data:`THERMAL_ORDERS`)."""
    unknown = set(orders) - set(THERMAL_TERM_NAMES)
    if unknown:
        raise CalibrationError(f"thermal orders: unknown term(s) {sorted(unknown)}; the filter estimates "
                               f"{', '.join(THERMAL_TERM_NAMES)} (misalignments do not follow the temperature here)")
    out = []
    for name, default in zip(THERMAL_TERM_NAMES, THERMAL_ORDERS):
        k = orders.get(name, default)
        top = 1 if name == "gyro_bias_rate" else 3
        if isinstance(k, bool) or int(k) != k or not 0 <= int(k) <= top:
            raise CalibrationError(f"thermal order of {name}: {k!r}, expected a whole number 0 .. {top}")
        out.append(int(k))
    return tuple(out) if any(out) else ()


def thermal_group_name(term: str, order: int) -> str:
    """``gyro_bias_dT2`` (the coefficient of dT^2), ``gyro_bias_rate`` (the dT/dt term)."""
    return term if term == "gyro_bias_rate" else f"{term}_dT{order}"


def thermal_groups(orders: tuple[int, ...]) -> list[Group]:
    """The thermal state groups (module docstring), one per term and order; ``sigma0`` is the span-level prior
    (:data:`THERMAL_SIGMA0`; :func:`prior_sigma` scales it per order)."""
    out = []
    for term, o in zip(THERMAL_TERM_NAMES, orders or ()):
        row, unit, _ = THERMAL_ROWS[term]
        for k in range(1, o + 1):
            u = unit if term == "gyro_bias_rate" else units.per_degree_unit(unit, k)
            out.append(Group(thermal_group_name(term, k), tuple(AX), (K_TH,) * 3, (0, 1, 2), (row + k - 1,) * 3,
                             THERMAL_SIGMA0[term], u))
    return out


def thermal_group_term(g: Group) -> str:
    """The thermal term (:data:`THERMAL_TERM_NAMES`) of a thermal group."""
    j = g.js[0]
    return "gyro_bias_rate" if j == TH_RATE_ROW else THERMAL_TERM_NAMES[j // 3]


def thermal_group_order(g: Group) -> int:
    """The order k of a thermal group's coefficient (0: the dT/dt term)."""
    return 0 if g.js[0] == TH_RATE_ROW else g.js[0] % 3 + 1


def prior_sigma(states: StateSet, sig0: dict, span_c: float = 1.0) -> np.ndarray:
    """Prior 1 sigma of every parameter state (SI): ``sig0[group]`` (default :data:`DEFAULT_SIGMA0`); a thermal
    coefficient of order k ``THERMAL_SIGMA0[term] / span_c^k`` unless ``sig0`` names its group."""
    span = max(float(span_c), 1.0)
    out = []
    for g in states.groups:
        if g.kinds[0] == K_TH and g.name not in sig0:
            v = THERMAL_SIGMA0[thermal_group_term(g)] / span ** thermal_group_order(g)
        else:
            v = sig0.get(g.name, DEFAULT_SIGMA0.get(g.name, g.sigma0))
        out += [float(v)] * g.size
    return np.array(out)


def field_value(x, unit: str):
    """SI ``x`` in a state group's field ``unit`` (a per-degree unit ``<unit>/degC^k``: SI per degC^k)."""
    try:
        base, _ = units.split_per_degree(unit)
    except units.UnitError:
        return units.from_si(x, unit)
    return units.from_si(x, base)


def estimated_names(states: StateSet) -> tuple[str, ...]:
    names = ["gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
             "accel_bias"]
    if states.extended:
        names += ["gyro_g_sensitivity", "accel_nonlinearity", "accel_cross_coupling", "accel_lever_arm"]
    if states.asynchrony:
        names.append("time_asynchrony")
    if states.gimbal:
        names += ["gimbal_nonorthogonality", "mount_attitude"]
    return tuple(names)


def fixed_mask(states: StateSet, names) -> np.ndarray:
    """Components of the canonical vector that the state set does not estimate (NaN sigma):
    the misalignment angles fixed by the frame definition, off-diagonal lever arms (S16 form)."""

    mask = []
    for n in names:
        shape = PARAMETERS[n].shape
        size = int(np.prod(shape)) if shape else 1
        m = np.zeros(size, bool)
        tri = "accel_misalignment" if states.psins else "gyro_misalignment"
        if n == tri and not states.gimbal:  # upper angles [xy, xz, yz] are zero by the frame definition
            m[[0, 1, 3]] = True
        if n == "accel_lever_arm" and not states.lever9:
            m[[1, 2, 3, 5, 6, 7]] = True
        if n == "gyro_g_sensitivity" and not states.gsens_offdiag:
            m[[1, 2, 3, 5, 6, 7]] = True
        if n == "accel_cross_coupling" and not states.cross:
            m[:] = True
        mask.append(m)
    return np.concatenate(mask)


def state_spec(st: StateSet) -> str:
    parts = ["51" if st.extended else "30"]
    parts += [n for n, f in (("lever9", st.lever9), ("async", st.asynchrony), ("levtime", st.lever_timing),
                             ("psins", st.psins),
                             ("gimbal", st.gimbal), ("gdiag", st.extended and not st.gsens_offdiag),
                             ("nocross", st.extended and not st.cross)) if f]
    if st.thermal:
        parts.append("thermal" if tuple(st.thermal) == THERMAL_ORDERS else "thermal=" + "".join(map(str, st.thermal)))
    if st.gm:
        parts.append(f"gm({len(st.gm)})")
    return ",".join(parts)
