"""Systematic calibration (S16 section 3): a closed-loop error-state Kalman filter with RTS
smoother on the navigation errors of a static-site turntable record.

Formulation
-----------
Frames: n = local ENU at the (fixed, known) site; m = the IMU frame the calibration
defines, the gyro-defined frame of S16 section 2.1 (gyro matrix lower-triangular), or
with ``psins`` the accelerometer-defined frame (accelerometer matrix lower-triangular,
gyro matrix full).  No gimbal angles are used: the base is static, so the record may
come from any path, with or without encoders.

Compensation (the S16 form, eq. 3, 6-8, 12; rates = increments / dt)::

    u_g = A_g dtheta/dt,   u_a = A_a dv/dt
    f0  = u_a - b_a  (+ tau (f0_k - f0_{k-1}) / dt       time asynchrony, when estimated)
    f~  = f0 - K2 f~^(2) - Kx f~^(x) - a_size(w~, w~-dot)           (fixed point, eq. 7-8)
    w~  = u_g - b_g - G f~

``a_size`` is the size effect of :func:`inscal.errors.size_effect`: with S16's diagonal
lever arm ``a_size_i = -(|w|^2 - w_i^2) r_i`` (S16 eq. 9-11, the physics).  **S16 eq. 12 and
block F29 as printed have the opposite sign; inscal keeps eq. 9, so inscal's r is the
position of each accelerometer (S16's printed convention would report -r).**

Error states (estimate minus truth).  Navigation (n = 9): attitude ``phi`` with
``C_est = (I + [phi x]) C_true`` (n-frame), velocity ``dv`` (ENU), position ``dp`` (ENU
metres).  Parameters: ``A_g,true = (I - dKG) A_g``, ``A_a,true = (I - dKA) A_a`` (dKG lower
triangular in the S16 set, eq. 20), every other parameter additive (``b_true = b - db``).
Then, to first order (S16 eq. 18-19 in this sign convention)::

    dw = dKG u_g - db_g - dG f~                                            # S16 eq. 18
    df = dKA u_a - db_a - dK2 f~^(2) - dKx f~^(x) + (d a_size / d r) dr + dtau f-dot  # eq. 19

and the error dynamics on the static base (S16 eq. 17, ENU, v = 0)::

    phi' = phi x w_ie^n - dw_ie(dL) - dw_en(dv) + C_m^n dw
    dv'  = phi x f^n + C_m^n df - 2 w_ie^n x dv + dg(dh)
    dp'  = dv

The parameter rows of F are zero (eq. 21).  F-blocks are checked against finite
differences of the nonlinear error propagation in ``tests/test_systematic.py``.

Discretisation.  The navigation runs at the IMU rate (compiled kernel, two-sample coning
and sculling); the filter steps every ``T`` (default 1 s).  Over one step ``F_nn`` is constant
on a static base (``f^n`` = the step's mean of ``C f~``), while ``F_np(t)`` follows the rotation
sample by sample, so::

    Phi_nn = I + F T + F^2 T^2/2 + F^3 T^3/6
    Phi_np = sum_k e^{F (T - t_k)} F_np(t_k) dt = M0 + F M1 + F^2 M2,  M_i = sum_k (T - t_k)^i / i! F_np(t_k) dt

(``M_i`` accumulated per sample), and ``Q_d`` is the third-order Van Loan series of the
white gyro and accelerometer noise.  Measurements at each step: zero velocity and the
known position (S16 eq. 25-26 plus the fixed-position observation).

Feedback and smoothing.  After every update the whole estimate is fed back (S16 eq. 27):
the attitude, velocity and position of the navigator and every parameter of the
compensation, so the filter's state is zero between updates.  The smoother
(:mod:`inscal.filters`, the RTS smoother of S16 eq. 13-16 in modified Bryson-Frazier form)
returns the smoothed error of the *pre-update reference* at each stored step; adding it to the
reference kept at that step gives the smoothed estimate, consistent with the feedback.  The
parameters are constants (zero process noise), so their smoothed estimate and covariance at
every step equal the final filtered ones: the result and the smoothed history use that
identity, and the recursion supplies the smoothed navigation states (the initial attitude
of the next pass).  Its own parameter values agree with the identity where the record is well
conditioned (``tests/test_systematic.py``); with zero-velocity updates ~1e8 times more
informative than the prior, the recursion's parameter part loses digits early in the record.

Sample-to-sample terms.  The time asynchrony and the size effect's w-dot use centred
differences of the neighbouring samples (one sample of look-ahead), as
:meth:`inscal.errors.ImuErrors.compensate` and the navigator do.

Passes.  Pass 1 linearises around the nominal parameters (prior mean); each later pass
re-runs the record with the compensation of the previous result and the smoothed initial
attitude (an iterated, Gauss-Newton smoother).  Each pass runs with a prior centred on its own
start; after pass 1 its widths are deflated to at most ``DEFLATE`` (30) previous posterior
sigmas.  The exact linear-Gaussian change of prior then restores the real one, centred on the
nominal parameters: with the pass's data information ``L_d = P_f^-1 - P_pass^-1``,
``P = (L_d + P_0^-1)^-1`` and ``x = P (P_f^-1 x_pass + P_0^-1 mu)``.  The deflation is
numerical: with the full prior the covariance spans ~1e10 and, on a quiet IMU (VRW 0.5 ug/sqrt(Hz)),
round-off made the 51-state filter inconsistent (NEES 240 on 42 parameters; 39 with deflation).  Passes stop when no parameter moved by more than ``tol`` of its sigma (default 0.2:
the iteration converges about quadratically, 24 -> 0.14 -> 0.001 sigma on the s16 record).

Gimbal states and encoder observations (state option ``gimbal``; ``unified`` = ``51,gimbal``; the
``unified`` method of :mod:`inscal.calibrate.unified`).  With the record's encoder angles the filter
also estimates the gimbal non-orthogonality ``dth`` and the mount (base) attitude ``[alpha0, beta0,
gamma0]`` of N25 eq. 5-8 (errors estimate minus truth, additive; ``K_GIM`` columns, zero in
``Phi_np``: they do not enter the navigation error dynamics).  The IMU frame is then N25's s-frame
(z = the inner axis, x = the outer axis's projection at zero angles, i.e. the encoders' zero; the
canonical frame of :mod:`inscal.errors`), not the gyro-defined m-frame: the gimbal, not the gyro
triad, fixes the frame, so the gyro matrix is full (9) like the accelerometer's (18 matrix states
= 6 scale factors + the 12 installation angles of N25 eq. 1-4; without encoders the three extra
states would be a frame rotation the velocity data cannot see).  At every ``encoder_every``-th
filter step the navigated attitude ``C_nav`` (of the s-frame) is compared with the gimbal model's::

    C_pred = C_b^n(alpha0, beta0, gamma0) Rot(u, theta_x) R_z(theta_z),  u = [cos dth, 0, sin dth]  # N25 eq. 5-8, 34
    z = vee(C_nav C_pred^T) ~ phi - psi      (3 rows, n-frame; vee(I + [a x]) = a)                  # N25 eq. 35-36
    psi = e_z dgamma0 + R_z(g0) e_y dbeta0 + R_z(g0) R_y(b0) e_x dalpha0 + C_b^n (sin tx du + (1 - cos tx) u x du) ddth
    R = s_enc^2 (a a^T + c c^T) + (s_enc / 10)^2 I,   a = C_b^n u,  c = C_b^n Rot(u, tx) e_z

``psi`` is the n-frame rotation of ``C_pred`` for an error of the gimbal parameters (``du = du/d dth``;
the ``dth`` term is the left Jacobian of a rotation about a tilting axis: with ``dth = 0`` it is
``C_b^n ddth [0, -(1 - cos tx), sin tx]``, seed-notes section 5).  White encoder noise (``s_enc`` per
angle) turns ``C_pred`` about the outer axis ``a`` and the inner axis ``c`` only; the isotropic tenth
is a floor for the third direction (unmodelled wobble; it keeps ``S`` well conditioned).  The
encoder sample at the end of each filter step (``gimbal[(k+1) n_per - 1]``, the time of the
navigation) is used; a record without encoders but with its path uses the path's angles.  The
attitude rows are a second, sequential update at the same step (innovation ``z - H x_v`` after the
velocity/position update's ``x_v``, one feedback of the sum), stored beside the first (``K``,
``S^-1``, ``S^-1 nu`` and the dense ``H``) so the MBF smoother runs both backwards, the attitude
rows first: exact, as one 9-row update would be.  The velocity/position innovations keep their own
NIS (dof 6 per step: the fit); the encoder rows' are in ``diagnostics["encoder"]`` with their
expectation ``3 - floor tr(S^-1)`` (between 2 and 3: the floor direction carries no encoder noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .. import earth, filters, units
from ..attitude import axis_angle_dcm, quat_from_dcm, quat_from_rotvec_xyz as _qrv, rot_x, rot_y, rot_z
from ..errors import ImuErrors, split_scale_misalignment
from ..filters import gain_and_joseph
from ..strapdown import _attitude_step, _qmul, _qrot, _two_sample, _velocity_step
from .result import CalibrationResult
from .segment import CalibrationError

N_NAV = 9
IDX_MEAS = np.array([3, 4, 5, 6, 7, 8], dtype=np.int64)

# column kinds of the per-sample parameter Jacobian (row block 0: phi rows, 1: dv rows)
K_UG, K_M1G, K_MF, K_UA, K_M1A, K_F2, K_FX, K_LEVD, K_LEVF, K_TAU = range(10)
# gimbal states (dth, alpha0, beta0, gamma0; js = index into the gimbal array): no column in Phi_np
K_GIM = 10

DIAG = ((0, 0), (1, 1), (2, 2))
OFFD = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))  # = errors.MISALIGN_INDEX order
LOWER = DIAG + ((1, 0), (2, 0), (2, 1))
FULL = DIAG + OFFD
AX = "xyz"
CROSS_PAIRS = ((0, 0, 1), (0, 0, 2), (1, 0, 1), (1, 1, 2), (2, 0, 2), (2, 1, 2))  # (row, a, b): S16 eq. 12
CROSS_NAMES = ("xy", "xz", "yx", "yz", "zx", "zy")


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
    "gimbal_nonorthogonality": units.to_si(60.0, "arcsec"), "mount_attitude": units.to_si(1.0, "deg"),
}
#: default white noise of each encoder angle (gimbal states)
ENCODER_SIGMA = units.to_si(1.0, "arcsec")
FRAME_GIMBAL = "gimbal-defined (N25 s-frame)"
GROUP_UNITS = {
    "gyro_matrix": "ppm", "gyro_bias": "deg/h", "gyro_g_sensitivity": "deg/h/g", "accel_matrix": "ppm",
    "accel_bias": "ug", "accel_nonlinearity": "ug/g^2", "accel_cross_coupling": "ug/g^2", "accel_lever_arm": "cm",
    "time_asynchrony": "ms", "gimbal_nonorthogonality": "arcsec", "mount_attitude": "arcsec",
}

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
}
#: what each option sets on :class:`StateSet`
_OPTION_FLAGS = {"51": {"extended": True}, "30": {"extended": False}, "lever9": {"lever9": True},
                 "async": {"asynchrony": True}, "gimbal": {"gimbal": True},
                 "unified": {"extended": True, "gimbal": True}, "psins": {"psins": True}}


@dataclass(frozen=True)
class StateSet:
    """A configuration of the systematic filter's parameter states (S16 eq. 22)."""

    extended: bool = True  # G, K2, Kx, lever arm
    lever9: bool = False
    asynchrony: bool = False
    psins: bool = False
    gimbal: bool = False  # dth + mount attitude, encoder attitude rows; frame = the gimbal's s-frame

    @classmethod
    def parse(cls, spec: str | None) -> "StateSet":
        """``"51"``, ``"30"``, optionally followed by ``,lever9``, ``,async``, ``,psins``, ``,gimbal``;
        ``"unified"`` = ``"51,gimbal"``."""
        if spec is None or str(spec).strip() == "":
            return cls()
        toks = [t.strip() for t in str(spec).replace("+", ",").split(",") if t.strip()]
        kw = {"extended": True}
        for t in toks:
            if t not in _OPTION_FLAGS:
                raise CalibrationError(f"unknown state option {t!r}; options: {', '.join(STATE_OPTIONS)}")
            kw.update(_OPTION_FLAGS[t])
        if kw.get("lever9") and not kw["extended"]:
            raise CalibrationError("lever9 needs the extended (51-state) model")
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
            out.append(_matrix_group("gyro_g_sensitivity", ij9, K_MF, s["gyro_g_sensitivity"], "deg/h/g"))
            out.append(Group("accel_nonlinearity", tuple(AX), (K_F2,) * 3, (0, 1, 2), (0, 1, 2),
                             s["accel_nonlinearity"], "ug/g^2"))
            out.append(Group("accel_cross_coupling", CROSS_NAMES, (K_FX,) * 6, tuple(p[0] for p in CROSS_PAIRS),
                             tuple(range(6)), s["accel_cross_coupling"], "ug/g^2"))
            if self.lever9:
                out.append(_matrix_group("accel_lever_arm", ij9, K_LEVF, s["accel_lever_arm"], "cm"))
            else:
                out.append(Group("accel_lever_arm", tuple(AX), (K_LEVD,) * 3, (0, 1, 2), (0, 1, 2),
                                 s["accel_lever_arm"], "cm"))
        if self.asynchrony:
            out.append(Group("time_asynchrony", ("",), (K_TAU,), (0,), (0,), s["time_asynchrony"], "ms"))
        if self.gimbal:  # N25 eq. 5-8; js = index into the gimbal array [dth, alpha0, beta0, gamma0]
            out.append(Group("gimbal_nonorthogonality", ("",), (K_GIM,), (0,), (0,), s["gimbal_nonorthogonality"],
                             "arcsec"))
            out.append(Group("mount_attitude", ("alpha0", "beta0", "gamma0"), (K_GIM,) * 3, (0, 0, 0), (1, 2, 3),
                             s["mount_attitude"], "arcsec"))
        return tuple(out)

    @property
    def n_params(self) -> int:
        return sum(g.size for g in self.groups)

    @property
    def n_states(self) -> int:
        return N_NAV + self.n_params

    def labels(self) -> list[str]:
        nav = [f"attitude[{a}]" for a in "ENU"] + [f"velocity[{a}]" for a in "ENU"] + [f"position[{a}]" for a in "ENU"]
        return nav + [f"{g.name}[{lab}]" if lab else g.name for g in self.groups for lab in g.labels]

    def offsets(self) -> dict[str, int]:
        off, k = {}, N_NAV
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


# ----------------------------------------------------------------------------- parameters
@dataclass
class CompParams:
    """Compensation parameters of the S16 form (SI, the filter's frame)."""

    Ag: np.ndarray = field(default_factory=lambda: np.eye(3))
    bg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    G: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    Aa: np.ndarray = field(default_factory=lambda: np.eye(3))
    ba: np.ndarray = field(default_factory=lambda: np.zeros(3))
    K2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    Kx: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # errors.cross_matrix layout
    lever: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # rows p_i
    tau: np.ndarray = field(default_factory=lambda: np.zeros(1))
    gim: np.ndarray = field(default_factory=lambda: np.zeros(4))  # [dth, alpha0, beta0, gamma0] (gimbal states)

    def copy(self) -> "CompParams":
        return CompParams(*(np.array(getattr(self, f), dtype=float) for f in self.__dataclass_fields__))

    def flat(self) -> np.ndarray:
        return np.concatenate([np.ravel(getattr(self, f)) for f in self.__dataclass_fields__])

    @classmethod
    def from_flat(cls, v) -> "CompParams":
        v = np.asarray(v, float)
        shapes = [(3, 3), (3,), (3, 3), (3, 3), (3,), (3,), (3, 3), (3, 3), (1,), (4,)]
        out, k = [], 0
        for s in shapes:
            n = int(np.prod(s))
            out.append(v[k:k + n].reshape(s).copy())
            k += n
        return cls(*out)

    @classmethod
    def from_imu(cls, imu: ImuErrors) -> "CompParams":
        """The compensation set equivalent to a canonical (measurement-form) error model."""
        Ag = np.linalg.inv(imu.M_g)
        Aa = np.linalg.inv(imu.M_a)
        return cls(Ag, Ag @ imu.gyro_bias, np.array(imu.gyro_g_sensitivity), Aa, Aa @ imu.accel_bias,
                   np.array(imu.accel_nonlinearity), np.array(imu.K_cross), np.array(imu.accel_lever_arm),
                   np.array([float(getattr(imu, "time_asynchrony", 0.0))]))

    def to_gimbal(self):
        """The gimbal parameters as :class:`~inscal.errors.GimbalErrors` (N25 eq. 5-8)."""
        from ..errors import GimbalErrors

        return GimbalErrors(float(self.gim[0]), np.array(self.gim[1:4]))

    def to_imu(self) -> ImuErrors:
        """Canonical measurement-form errors (``M = A^-1``, ``eps = M_g b_g``, ``nabla = M_a b_a``)."""
        Mg = np.linalg.inv(self.Ag)
        Ma = np.linalg.inv(self.Aa)
        kg, eg = split_scale_misalignment(Mg)
        ka, ea = split_scale_misalignment(Ma)
        kc = self.Kx
        kw = dict(gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=Mg @ self.bg, gyro_g_sensitivity=self.G,
                  accel_scale_factor=ka, accel_misalignment=ea, accel_bias=Ma @ self.ba,
                  accel_nonlinearity=self.K2,
                  accel_cross_coupling=[kc[0, 0], kc[0, 1], kc[1, 0], kc[1, 2], kc[2, 1], kc[2, 2]],
                  accel_lever_arm=self.lever)
        if "time_asynchrony" in ImuErrors.__dataclass_fields__:
            kw["time_asynchrony"] = float(self.tau[0])
        return ImuErrors(**kw)

    def corrected(self, states: StateSet, x: np.ndarray) -> "CompParams":
        """The parameters with the error estimate ``x`` (physical, parameter part) removed
        (the feedback of S16 eq. 27, as the kernel applies it)."""
        p = self.copy()
        k = 0
        for g in states.groups:
            v = x[k:k + g.size]
            k += g.size
            if g.name in ("gyro_matrix", "accel_matrix"):
                D = np.zeros((3, 3))
                for e, (i, j) in enumerate(zip(g.axes, g.js)):
                    D[i, j] = v[e]
                if g.name == "gyro_matrix":
                    p.Ag = (np.eye(3) - D) @ p.Ag
                else:
                    p.Aa = (np.eye(3) - D) @ p.Aa
            elif g.name == "gyro_bias":
                p.bg = p.bg - v
            elif g.name == "accel_bias":
                p.ba = p.ba - v
            elif g.name == "gyro_g_sensitivity":
                p.G = p.G - v.reshape(3, 3)
            elif g.name == "accel_nonlinearity":
                p.K2 = p.K2 - v
            elif g.name == "accel_cross_coupling":
                for e, (r, a, b) in enumerate(CROSS_PAIRS):
                    p.Kx[r, _kx_col(a, b)] -= v[e]
            elif g.name == "accel_lever_arm":
                if g.size == 3:
                    p.lever = p.lever - np.diag(v)
                else:
                    p.lever = p.lever - v.reshape(3, 3)
            elif g.name == "time_asynchrony":
                p.tau = p.tau - v
            elif g.name == "gimbal_nonorthogonality":
                p.gim = p.gim - np.array([v[0], 0.0, 0.0, 0.0])
            elif g.name == "mount_attitude":
                p.gim = p.gim - np.concatenate([[0.0], v])
        return p

    def error_state(self, states: StateSet, truth: "CompParams") -> np.ndarray:
        """The error state ``x`` (estimate - truth, first order) of these parameters."""
        out = []
        for g in states.groups:
            if g.name in ("gyro_matrix", "accel_matrix"):
                A, At = (self.Ag, truth.Ag) if g.name == "gyro_matrix" else (self.Aa, truth.Aa)
                D = np.eye(3) - At @ np.linalg.inv(A)
                out += [D[i, j] for i, j in zip(g.axes, g.js)]
            elif g.name == "gyro_bias":
                out += list(self.bg - truth.bg)
            elif g.name == "accel_bias":
                out += list(self.ba - truth.ba)
            elif g.name == "gyro_g_sensitivity":
                out += list((self.G - truth.G).ravel())
            elif g.name == "accel_nonlinearity":
                out += list(self.K2 - truth.K2)
            elif g.name == "accel_cross_coupling":
                out += [self.Kx[r, _kx_col(a, b)] - truth.Kx[r, _kx_col(a, b)] for r, a, b in CROSS_PAIRS]
            elif g.name == "accel_lever_arm":
                d = self.lever - truth.lever
                out += list(np.diag(d)) if g.size == 3 else list(d.ravel())
            elif g.name == "time_asynchrony":
                out += list(self.tau - truth.tau)
            elif g.name == "gimbal_nonorthogonality":
                out += [self.gim[0] - truth.gim[0]]
            elif g.name == "mount_attitude":
                out += [math.remainder(a - b, 2 * math.pi) for a, b in zip(self.gim[1:4], truth.gim[1:4])]
        return np.array(out)


def _kx_col(a: int, b: int) -> int:
    """Column of the cross-coupling matrix acting on f^(x) = [fx fy, fx fz, fy fz]."""
    return {(0, 1): 0, (0, 2): 1, (1, 2): 2}[(a, b)]


def frame_rotation(imu: ImuErrors, frame: str = "gyro") -> np.ndarray:
    """``C_s^m``: the rotation from the canonical s-frame to the frame in which the chosen
    triad's compensation matrix is lower-triangular (QL decomposition, as errors.to_s16)."""
    from scipy.linalg import rq

    A = np.linalg.inv(imu.M_g if frame == "gyro" else imu.M_a)
    R_, Q_ = rq(A.T)
    L = R_.T
    C_m_s = Q_.T
    S = np.diag(np.sign(np.diag(L)))
    C_m_s = C_m_s @ S
    return C_m_s.T


def truth_in_frame(imu: ImuErrors, states: StateSet, gimbal=None) -> CompParams:
    """The true compensation parameters expressed in the filter's frame (the quadratic terms
    and lever arms are carried unchanged: exact when the frames coincide, as in the s16 and
    psins19 scenarios; otherwise to first order in the rotation, seed-notes section 5).  With the
    gimbal states the frame is the canonical s-frame (no rotation) and ``gimbal`` (GimbalErrors)
    supplies the true gimbal parameters."""
    R = np.eye(3) if states.gimbal else frame_rotation(imu, states.frame)
    p = CompParams.from_imu(imu)
    p.Ag = R @ p.Ag
    p.bg = R @ p.bg
    p.G = R @ p.G @ R.T
    p.Aa = R @ p.Aa
    p.ba = R @ p.ba
    if gimbal is not None:
        p.gim = np.concatenate([[gimbal.nonorthogonality], gimbal.mount_attitude])
    return p


# ----------------------------------------------------------------------------- the kernel
@njit(cache=True, inline="always")
def _lin(A, b, x, idt, out):
    """``out = A x / dt - b`` (the linear part of the compensation, a rate)."""
    for i in range(3):
        out[i] = (A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]) * idt - b[i]


@njit(cache=True)
def _compensate(dth, dv, dt, Ag, bg, G, Aa, ba, K2, Kx, lev, tau, nl, f0m, f0p, wlm, wlp, ug, ua, w, f, fdot, wdot):
    """S16 compensation of one sample (module docstring); fills ug, ua, w, f (rates), the
    centred derivatives ``fdot`` (of the accelerometer output) and ``wdot``.

    ``f0m``/``f0p`` and ``wlm``/``wlp``: the linearly compensated specific force and rate of the
    previous and next samples (equal to this sample's at the ends of the record).  Time asynchrony:
    the accelerometer increment over [t_k-1 - tau, t_k - tau] is moved to [t_k-1, t_k] by a quadratic
    interpolation of the integrated output, ``fb_k += tau (fb_k+1 - fb_k-1) / (2 dt)
    + tau^2 (fb_k+1 - 2 fb_k + fb_k-1) / (2 dt^2)`` (error of order tau dt^2 times the third
    derivative of f).  The size effect's w-dot is the centred difference ``(wb_k+1 - wb_k-1) / (2 dt)``."""
    idt = 1.0 / dt
    for i in range(3):
        ug[i] = (Ag[i, 0] * dth[0] + Ag[i, 1] * dth[1] + Ag[i, 2] * dth[2]) * idt
        ua[i] = (Aa[i, 0] * dv[0] + Aa[i, 1] * dv[1] + Aa[i, 2] * dv[2]) * idt
    f0x = ua[0] - ba[0]
    f0y = ua[1] - ba[1]
    f0z = ua[2] - ba[2]
    fdot[0] = (f0p[0] - f0m[0]) * 0.5 * idt
    fdot[1] = (f0p[1] - f0m[1]) * 0.5 * idt
    fdot[2] = (f0p[2] - f0m[2]) * 0.5 * idt
    for i in range(3):
        wdot[i] = (wlp[i] - wlm[i]) * 0.5 * idt
    if tau != 0.0:
        c2 = 0.5 * tau * tau * idt * idt
        f0x += tau * fdot[0] + c2 * (f0p[0] - 2.0 * f0x + f0m[0])
        f0y += tau * fdot[1] + c2 * (f0p[1] - 2.0 * f0y + f0m[1])
        f0z += tau * fdot[2] + c2 * (f0p[2] - 2.0 * f0z + f0m[2])
    fx, fy, fz = f0x, f0y, f0z
    for i in range(3):
        w[i] = ug[i] - bg[i] - (G[i, 0] * fx + G[i, 1] * fy + G[i, 2] * fz)
    if nl:
        d0, d1, d2 = wdot[0], wdot[1], wdot[2]
        for _ in range(3):  # S16 eq. 8 (fixed point)
            c0, c1, c2_ = fx * fy, fx * fz, fy * fz
            w0, w1, w2 = w[0], w[1], w[2]
            ww = w0 * w0 + w1 * w1 + w2 * w2
            wp0 = w0 * lev[0, 0] + w1 * lev[0, 1] + w2 * lev[0, 2]
            wp1 = w0 * lev[1, 0] + w1 * lev[1, 1] + w2 * lev[1, 2]
            wp2 = w0 * lev[2, 0] + w1 * lev[2, 1] + w2 * lev[2, 2]
            s0 = w0 * wp0 - lev[0, 0] * ww + (d1 * lev[0, 2] - d2 * lev[0, 1])  # S16 eq. 9-11 (+ w-dot)
            s1 = w1 * wp1 - lev[1, 1] * ww + (d2 * lev[1, 0] - d0 * lev[1, 2])
            s2 = w2 * wp2 - lev[2, 2] * ww + (d0 * lev[2, 1] - d1 * lev[2, 0])
            nx = f0x - (K2[0] * fx * fx + Kx[0, 0] * c0 + Kx[0, 1] * c1 + Kx[0, 2] * c2_) - s0  # S16 eq. 12
            ny = f0y - (K2[1] * fy * fy + Kx[1, 0] * c0 + Kx[1, 1] * c1 + Kx[1, 2] * c2_) - s1
            nz = f0z - (K2[2] * fz * fz + Kx[2, 0] * c0 + Kx[2, 1] * c1 + Kx[2, 2] * c2_) - s2
            fx, fy, fz = nx, ny, nz
            for i in range(3):
                w[i] = ug[i] - bg[i] - (G[i, 0] * fx + G[i, 1] * fy + G[i, 2] * fz)
    f[0], f[1], f[2] = fx, fy, fz


@njit(cache=True)
def _column_values(kinds, axes, js, ug, ua, w, f, wd, fdot, vals):
    """Per-sample value of each parameter column of dw (kinds 0-2) or df (kinds 3-9): the column
    is ``C[:, axes[c]] * vals[c]`` except for the asynchrony (``C fdot``, handled by the caller)."""
    ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    for c in range(kinds.shape[0]):
        k = kinds[c]
        i = axes[c]
        j = js[c]
        if k == 0:  # dKG u_g
            vals[c] = ug[j]
        elif k == 1 or k == 4:  # -db
            vals[c] = -1.0
        elif k == 2:  # -dG f
            vals[c] = -f[j]
        elif k == 3:  # dKA u_a
            vals[c] = ua[j]
        elif k == 5:  # -dK2 f_i^2
            vals[c] = -f[i] * f[i]
        elif k == 6:  # -dKx f_a f_b
            if j == 0 or j == 2:
                vals[c] = -f[0] * f[1]
            elif j == 1 or j == 4:
                vals[c] = -f[0] * f[2]
            else:
                vals[c] = -f[1] * f[2]
        elif k == 7:  # diagonal lever arm: -d a_size_i / d r_i = |w|^2 - w_i^2
            vals[c] = ww - w[i] * w[i]
        elif k == 8:  # full lever arm p_ij: -(w_i w_j - delta_ij |w|^2 + (wdot x e_j)_i)
            cr = 0.0
            if j == 0:
                cr = 0.0 if i == 0 else (wd[2] if i == 1 else -wd[1])
            elif j == 1:
                cr = -wd[2] if i == 0 else (0.0 if i == 1 else wd[0])
            else:
                cr = wd[1] if i == 0 else (-wd[0] if i == 1 else 0.0)
            vals[c] = -(w[i] * w[j] - (ww if i == j else 0.0) + cr)
        else:
            vals[c] = 0.0


@njit(cache=True)
def _nav_F(lat, h, fn, F, g_scale=1.0):
    """Continuous F_nn (9 x 9) of the static-base error model (module docstring); ``g_scale``:
    site gravity model / WGS-84 normal gravity."""
    for i in range(9):
        for j in range(9):
            F[i, j] = 0.0
    W = earth.OMEGA_IE
    sl, cl = math.sin(lat), math.cos(lat)
    rm, rn = earth.radii(lat)
    rm += h
    rn += h
    wn, wu = W * cl, W * sl
    # phi' = phi x w_ie  = -[w_ie x] phi
    F[0, 1] = wu
    F[0, 2] = -wn
    F[1, 0] = -wu
    F[2, 0] = wn
    # - dw_en(dv):  dw_en = [-dvN/RM, dvE/RN, dvE tanL/RN]
    F[0, 4] = 1.0 / rm
    F[1, 3] = -1.0 / rn
    F[2, 3] = -sl / cl / rn
    # - dw_ie(dL), dL = dpN / RM: dw_ie = W [0, -sinL, cosL] dL
    F[1, 7] = W * sl / rm
    F[2, 7] = -W * cl / rm
    # dv' = phi x f^n = -[f x] phi
    F[3, 1] = fn[2]
    F[3, 2] = -fn[1]
    F[4, 0] = -fn[2]
    F[4, 2] = fn[0]
    F[5, 0] = fn[1]
    F[5, 1] = -fn[0]
    # - 2 w_ie x dv
    F[3, 4] = 2.0 * wu
    F[3, 5] = -2.0 * wn
    F[4, 3] = -2.0 * wu
    F[5, 3] = 2.0 * wn
    # gravity gradient: g_U = -gamma(h), d(dv_U)/d(h) = +2 gamma / R
    F[5, 8] = 2.0 * earth.normal_gravity(lat, h) * g_scale / math.sqrt(rm * rn)
    # dp' = dv
    F[6, 3] = 1.0
    F[7, 4] = 1.0
    F[8, 5] = 1.0


@njit(cache=True)
def _gimbal_attitude(gim, tx, tz, C, a, c, Hg):
    """The gimbal model's IMU attitude ``C = C_b^n Rot(u, tx) R_z(tz)`` (N25 eq. 5-8, 34; exact
    Rodrigues rotation about ``u = [cos dth, 0, sin dth]``), the outer and inner axes in n (``a``,
    ``c``: the directions of the encoder noise) and ``Hg = d psi / d[dth, alpha0, beta0, gamma0]``
    (3 x 4), ``psi`` the n-frame rotation of ``C`` for a change of the gimbal parameters (module
    docstring); ``gim = [dth, alpha0, beta0, gamma0]``."""
    dth = gim[0]
    u = np.array([math.cos(dth), 0.0, math.sin(dth)])
    du = np.array([-math.sin(dth), 0.0, math.cos(dth)])
    Rzg = rot_z(gim[3])
    RzRy = Rzg @ rot_y(gim[2])
    Cbn = RzRy @ rot_x(gim[1])  # N25 eq. 8
    Rx = axis_angle_dcm(u, tx)  # N25 eq. 5 (exact)
    C[:, :] = Cbn @ (Rx @ rot_z(tz))  # N25 eq. 7
    s1, c1 = math.sin(tx), 1.0 - math.cos(tx)
    # left Jacobian of Rot(u, tx) for a change du of the unit axis (du perpendicular to u)
    w0 = s1 * du[0] + c1 * (u[1] * du[2] - u[2] * du[1])
    w1 = s1 * du[1] + c1 * (u[2] * du[0] - u[0] * du[2])
    w2 = s1 * du[2] + c1 * (u[0] * du[1] - u[1] * du[0])
    for i in range(3):
        a[i] = Cbn[i, 0] * u[0] + Cbn[i, 1] * u[1] + Cbn[i, 2] * u[2]
        c[i] = Cbn[i, 0] * Rx[0, 2] + Cbn[i, 1] * Rx[1, 2] + Cbn[i, 2] * Rx[2, 2]
        Hg[i, 0] = Cbn[i, 0] * w0 + Cbn[i, 1] * w1 + Cbn[i, 2] * w2  # N25 eq. 35-36 (d dth)
        Hg[i, 1] = RzRy[i, 0]  # d alpha0: R_z R_y e_x
        Hg[i, 2] = Rzg[i, 1]  # d beta0: R_z e_y
        Hg[i, 3] = 1.0 if i == 2 else 0.0  # d gamma0: e_z


@njit(cache=True)
def _update_h(P, H, R, nu, K, Sinv, x):
    """:func:`inscal.filters.update` for a dense ``H`` (m x N) and a full ``R`` (m x m): Joseph-form
    update, writes ``K``, ``S^-1`` and ``x = K nu``; returns ``nu^T S^-1 nu``."""
    N = P.shape[0]
    m = H.shape[0]
    PHt = np.zeros((N, m))
    for i in range(N):
        for a in range(m):
            s = 0.0
            for j in range(N):
                s += P[i, j] * H[a, j]
            PHt[i, a] = s
    S = np.empty((m, m))
    for a in range(m):
        for b in range(m):
            s = R[a, b]
            for j in range(N):
                s += H[a, j] * PHt[j, b]
            S[a, b] = s
    return gain_and_joseph(P, PHt, S, nu, K, Sinv, x)


@njit(cache=True)
def _smoother_step_h(lam, Lam, H, K, Sinv, sz):
    """:func:`inscal.filters.smoother_step` for a dense ``H``: ``lam <- H^T S^-1 nu + (I - K H)^T lam``,
    ``Lam <- H^T S^-1 H + (I - K H)^T Lam (I - K H)``, in place."""
    N = lam.shape[0]
    m = H.shape[0]
    d = np.empty(m)
    for a in range(m):
        s = sz[a]
        for i in range(N):
            s -= K[i, a] * lam[i]
        d[a] = s
    for i in range(N):
        s = 0.0
        for a in range(m):
            s += H[a, i] * d[a]
        lam[i] += s
    LK = Lam @ K  # (N, m)
    C = K.T @ LK + Sinv  # (m, m)
    B = LK @ H  # Lam K H (N, N)
    HtC = H.T @ C  # (N, m)
    add = HtC @ H
    for i in range(N):
        for j in range(i, N):
            v = 0.5 * (Lam[i, j] + Lam[j, i]) - B[i, j] - B[j, i] + 0.5 * (add[i, j] + add[j, i])
            Lam[i, j] = v
            Lam[j, i] = v


@njit(cache=True)
def _pass_kernel(dth, dv, dt, n_per, nav0, site, Ag, bg, G, Aa, ba, K2, Kx, lev, tau, nl, est_tau,
                 kinds, axes, js, sig, qg, qa, r, P, hist_every,
                 K_st, Si_st, sz_st, phinn_st, phinp_st, nis_st, z_st,
                 hist_Pm, hist_ref, hist_Pf, nav_out,
                 gim, enc, enc_var, enc_floor, att_used, Ka_st, Sia_st, sza_st, Ha_st, nisa_st, za_st, Ra_st):
    """One closed-loop filter pass over the record (see the module docstring).

    ``nav0`` = [q(4), v(3), lat, lon, h]; ``site`` = [lat0, lon0, h0(, g_scale)] (g_scale: site
    gravity model / WGS-84 normal gravity, 1 when absent); parameter arrays are
    updated in place by the feedback.  ``sig``: state scaling (the filter works on x / sig).
    Stores per step the smoother data; every ``hist_every`` steps the predicted covariance
    and the pre-update reference parameters.  Returns the number of steps.

    Gimbal states: ``gim = [dth, alpha0, beta0, gamma0]`` (updated in place by the feedback);
    ``enc`` (M, 2) the encoder angles at the end of each step (NaN: no attitude rows that step; shape
    (0, 2) without gimbal states), ``enc_var``/``enc_floor`` the encoder and floor variances; the
    attitude update's ``K``, ``S^-1``, ``S^-1 nu``, scaled ``H``, NIS, raw ``z`` and ``R`` are stored per
    step (``att_used[k] = 1`` where it ran).
    """
    N = sig.shape[0]
    npar = N - 9
    M = dth.shape[0] // n_per
    T = n_per * dt
    q0, q1, q2, q3 = nav0[0], nav0[1], nav0[2], nav0[3]
    ve, vn, vu = nav0[4], nav0[5], nav0[6]
    lat, lon, h = nav0[7], nav0[8], nav0[9]
    lat0, lon0, h0 = site[0], site[1], site[2]
    g_scale = site[3] if site.shape[0] > 3 else 1.0
    ug = np.empty(3)
    ua = np.empty(3)
    w = np.empty(3)
    f = np.empty(3)
    fdot = np.empty(3)
    f0m = np.empty(3)  # linear-compensated specific force / rate of the previous, this, next sample
    f0c = np.empty(3)
    f0n = np.empty(3)
    wlm = np.empty(3)
    wlc = np.empty(3)
    wln = np.empty(3)
    wd = np.zeros(3)
    idt = 1.0 / dt
    if M > 0:
        _lin(Aa, ba, dv[0], idt, f0c)
        _lin(Ag, bg, dth[0], idt, wlc)
        f0m[:] = f0c
        wlm[:] = wlc
    vals = np.empty(npar)
    M0 = np.zeros((6, npar))
    M1 = np.zeros((6, npar))
    M2 = np.zeros((6, npar))
    F = np.zeros((9, 9))
    fn = np.zeros(3)
    K = np.empty((N, 6))
    Si = np.empty((6, 6))
    xs = np.empty(N)
    z = np.empty(6)
    rs = np.empty(6)
    for a in range(6):
        rs[a] = r[a] / sig[3 + a] ** 2
    have_enc = enc.shape[0] > 0
    Cp = np.empty((3, 3))
    Ce = np.empty((3, 3))
    ga = np.empty(3)
    gc = np.empty(3)
    Hg = np.empty((3, 4))
    Ha = np.zeros((3, N))
    Ra = np.empty((3, 3))
    Ka = np.empty((N, 3))
    Sia = np.empty((3, 3))
    za = np.empty(3)
    nu = np.empty(3)
    xa = np.empty(N)
    p0, p1, p2 = 0.0, 0.0, 0.0
    u0, u1, u2 = 0.0, 0.0, 0.0
    have_prev = False
    qgm = (qg[0] + qg[1] + qg[2]) / 3.0
    qam = (qa[0] + qa[1] + qa[2]) / 3.0
    ih = 0
    for k in range(M):
        for a in range(6):
            for c in range(npar):
                M0[a, c] = 0.0
                M1[a, c] = 0.0
                M2[a, c] = 0.0
        fn[0] = 0.0
        fn[1] = 0.0
        fn[2] = 0.0
        for jj in range(n_per):
            s = k * n_per + jj
            if s + 1 < dth.shape[0]:
                _lin(Aa, ba, dv[s + 1], idt, f0n)
                _lin(Ag, bg, dth[s + 1], idt, wln)
            else:
                f0n[:] = f0c
                wln[:] = wlc
            _compensate(dth[s], dv[s], dt, Ag, bg, G, Aa, ba, K2, Kx, lev, tau[0], nl, f0m, f0n, wlm, wln,
                        ug, ua, w, f, fdot, wd)
            f0m[:] = f0c
            f0c[:] = f0n
            wlm[:] = wlc
            wlc[:] = wln
            a0, a1, a2 = w[0] * dt, w[1] * dt, w[2] * dt
            b0, b1, b2 = f[0] * dt, f[1] * dt, f[2] * dt
            r0, r1, r2, c0, c1, c2 = _two_sample(a0, a1, a2, b0, b1, b2, p0, p1, p2, u0, u1, u2, have_prev)
            nve, nvn, nvu, sl, cl, rmh, rnh, wie_n, wie_u = _velocity_step(q0, q1, q2, q3, c0, c1, c2, ve, vn, vu,
                                                                            lat, h, dt, g_scale)
            # attitude with the midpoint transport rate
            mve = 0.5 * (ve + nve)
            mvn = 0.5 * (vn + nvn)
            oq0, oq1, oq2, oq3 = q0, q1, q2, q3
            q0, q1, q2, q3 = _attitude_step(q0, q1, q2, q3, r0, r1, r2, -mvn / rmh * dt, (wie_n + mve / rnh) * dt,
                                            (wie_u + mve * sl / (cl * rnh)) * dt)
            lat += 0.5 * (vn + nvn) / rmh * dt
            lon += 0.5 * (ve + nve) / (rnh * cl) * dt
            h += 0.5 * (vu + nvu) * dt
            ve, vn, vu = nve, nvn, nvu
            p0, p1, p2 = a0, a1, a2
            u0, u1, u2 = b0, b1, b2
            have_prev = True
            # ---- Jacobian accumulation with the mid-sample attitude
            m0, m1, m2, m3 = oq0 + q0, oq1 + q1, oq2 + q2, oq3 + q3
            mn = 1.0 / math.sqrt(m0 * m0 + m1 * m1 + m2 * m2 + m3 * m3)
            m0 *= mn
            m1 *= mn
            m2 *= mn
            m3 *= mn
            _column_values(kinds, axes, js, ug, ua, w, f, wd, fdot, vals)
            sw = (n_per - jj - 0.5) * dt
            wt0 = dt
            wt1 = sw * dt
            wt2 = 0.5 * sw * sw * dt
            fe, fnn_, fu = _qrot(m0, m1, m2, m3, f[0], f[1], f[2])
            fn[0] += fe * dt
            fn[1] += fnn_ * dt
            fn[2] += fu * dt
            # columns of C_m^n: C e_i
            cx0, cx1, cx2 = _qrot(m0, m1, m2, m3, 1.0, 0.0, 0.0)
            cy0, cy1, cy2 = _qrot(m0, m1, m2, m3, 0.0, 1.0, 0.0)
            cz0, cz1, cz2 = _qrot(m0, m1, m2, m3, 0.0, 0.0, 1.0)
            for c in range(npar):
                kk = kinds[c]
                if kk == K_GIM:  # gimbal states: constants outside the navigation error dynamics
                    continue
                rb = 0 if kk <= 2 else 3
                if kk == 9:
                    if not est_tau:
                        continue
                    v0 = cx0 * fdot[0] + cy0 * fdot[1] + cz0 * fdot[2]
                    v1 = cx1 * fdot[0] + cy1 * fdot[1] + cz1 * fdot[2]
                    v2 = cx2 * fdot[0] + cy2 * fdot[1] + cz2 * fdot[2]
                else:
                    i = axes[c]
                    vv = vals[c]
                    if i == 0:
                        v0, v1, v2 = cx0 * vv, cx1 * vv, cx2 * vv
                    elif i == 1:
                        v0, v1, v2 = cy0 * vv, cy1 * vv, cy2 * vv
                    else:
                        v0, v1, v2 = cz0 * vv, cz1 * vv, cz2 * vv
                M0[rb, c] += v0 * wt0
                M0[rb + 1, c] += v1 * wt0
                M0[rb + 2, c] += v2 * wt0
                M1[rb, c] += v0 * wt1
                M1[rb + 1, c] += v1 * wt1
                M1[rb + 2, c] += v2 * wt1
                M2[rb, c] += v0 * wt2
                M2[rb + 1, c] += v1 * wt2
                M2[rb + 2, c] += v2 * wt2
        # ---- discretisation (module docstring)
        fn[0] /= T
        fn[1] /= T
        fn[2] /= T
        _nav_F(lat0, h0, fn, F, g_scale)
        F2 = F @ F
        F3 = F2 @ F
        phinn = np.eye(9) + F * T + F2 * (T * T / 2.0) + F3 * (T * T * T / 6.0)
        Fnp = np.zeros((9, npar))
        Fnp[0:6, :] = M0
        phinp = Fnp + np.ascontiguousarray(F[:, 0:6]) @ M1 + np.ascontiguousarray(F2[:, 0:6]) @ M2
        Qc = np.zeros((9, 9))
        for i in range(3):
            Qc[i, i] = qgm
            Qc[3 + i, 3 + i] = qam
        FQ = F @ Qc
        Qd = Qc * T + (FQ + FQ.T) * (T * T / 2.0) + (F2 @ Qc + 2.0 * FQ @ F.T + Qc @ F2.T) * (T * T * T / 6.0)
        # scaling
        for i in range(9):
            for j in range(9):
                phinn[i, j] *= sig[j] / sig[i]
                Qd[i, j] /= sig[i] * sig[j]
            for c in range(npar):
                phinp[i, c] *= sig[9 + c] / sig[i]
        filters.predict(P, 9, phinn, phinp, Qd, np.zeros(npar))
        phinn_st[k] = phinn
        phinp_st[k] = phinp
        # ---- measurement: zero velocity, known position
        rm0, rn0 = earth.radii(lat0)
        z[0], z[1], z[2] = ve, vn, vu
        z[3] = (lon - lon0) * (rn0 + h0) * math.cos(lat0)
        z[4] = (lat - lat0) * (rm0 + h0)
        z[5] = h - h0
        for a in range(6):
            z_st[k, a] = z[a]
            z[a] /= sig[3 + a]
        if k % hist_every == 0 or k == M - 1:
            hist_Pm[ih] = P
            hist_ref[ih, 0:9] = Ag.ravel()
            hist_ref[ih, 9:12] = bg
            hist_ref[ih, 12:21] = G.ravel()
            hist_ref[ih, 21:30] = Aa.ravel()
            hist_ref[ih, 30:33] = ba
            hist_ref[ih, 33:36] = K2
            hist_ref[ih, 36:45] = Kx.ravel()
            hist_ref[ih, 45:54] = lev.ravel()
            hist_ref[ih, 54] = tau[0]
            hist_ref[ih, 55:59] = gim
        nis_st[k] = filters.update(P, IDX_MEAS, rs, z, K, Si, xs)
        K_st[k] = K
        Si_st[k] = Si
        sz_st[k] = Si @ z
        if have_enc and enc[k, 0] == enc[k, 0] and enc[k, 1] == enc[k, 1]:
            # ---- encoder attitude rows (module docstring): z = vee(C_nav C_pred^T) ~ phi - psi
            _gimbal_attitude(gim, enc[k, 0], enc[k, 1], Cp, ga, gc, Hg)
            e0, e1, e2 = _qrot(q0, q1, q2, q3, 1.0, 0.0, 0.0)
            Ce[0, 0], Ce[1, 0], Ce[2, 0] = e0, e1, e2
            e0, e1, e2 = _qrot(q0, q1, q2, q3, 0.0, 1.0, 0.0)
            Ce[0, 1], Ce[1, 1], Ce[2, 1] = e0, e1, e2
            e0, e1, e2 = _qrot(q0, q1, q2, q3, 0.0, 0.0, 1.0)
            Ce[0, 2], Ce[1, 2], Ce[2, 2] = e0, e1, e2
            Em = Ce @ Cp.T
            za[0] = 0.5 * (Em[2, 1] - Em[1, 2])
            za[1] = 0.5 * (Em[0, 2] - Em[2, 0])
            za[2] = 0.5 * (Em[1, 0] - Em[0, 1])
            for i in range(3):
                for j in range(N):
                    Ha[i, j] = 0.0
                Ha[i, i] = sig[i]
            for c in range(npar):
                if kinds[c] == K_GIM:
                    for i in range(3):
                        Ha[i, 9 + c] = -Hg[i, js[c]] * sig[9 + c]
            for i in range(3):
                for j in range(3):
                    Ra[i, j] = enc_var * (ga[i] * ga[j] + gc[i] * gc[j])
                Ra[i, i] += enc_floor
            # sequential update: innovation against the pending velocity/position estimate xs (scaled)
            for i in range(3):
                s_ = za[i]
                for j in range(N):
                    s_ -= Ha[i, j] * xs[j]
                nu[i] = s_
            nisa_st[k] = _update_h(P, Ha, Ra, nu, Ka, Sia, xa)
            for i in range(N):
                xs[i] += xa[i]
            Ka_st[k] = Ka
            Sia_st[k] = Sia
            sza_st[k] = Sia @ nu
            Ha_st[k] = Ha
            za_st[k] = za
            Ra_st[k] = Ra
            att_used[k] = 1
        if k % hist_every == 0 or k == M - 1:
            for i in range(N):
                hist_Pf[ih, i] = P[i, i]
            ih += 1
        # ---- feedback (S16 eq. 27)
        for i in range(N):
            xs[i] *= sig[i]
        e0, e1, e2, e3 = _qrv(-xs[0], -xs[1], -xs[2])
        q0, q1, q2, q3 = _qmul(e0, e1, e2, e3, q0, q1, q2, q3)
        ve -= xs[3]
        vn -= xs[4]
        vu -= xs[5]
        lon -= xs[6] / ((rn0 + h0) * math.cos(lat0))
        lat -= xs[7] / (rm0 + h0)
        h -= xs[8]
        _feedback_params(xs, kinds, axes, js, Ag, bg, G, Aa, ba, K2, Kx, lev, tau, gim)
    nav_out[0], nav_out[1], nav_out[2], nav_out[3] = q0, q1, q2, q3
    nav_out[4], nav_out[5], nav_out[6] = ve, vn, vu
    nav_out[7], nav_out[8], nav_out[9] = lat, lon, h
    return M


@njit(cache=True)
def _feedback_params(xs, kinds, axes, js, Ag, bg, G, Aa, ba, K2, Kx, lev, tau, gim):
    """Remove the parameter estimates (physical, ``xs[9:]``) from the compensation (in place)."""
    npar = kinds.shape[0]
    Dg = np.zeros((3, 3))
    Da = np.zeros((3, 3))
    for c in range(npar):
        v = xs[9 + c]
        k = kinds[c]
        i = axes[c]
        j = js[c]
        if k == 0:
            Dg[i, j] = v
        elif k == 1:
            bg[i] -= v
        elif k == 2:
            G[i, j] -= v
        elif k == 3:
            Da[i, j] = v
        elif k == 4:
            ba[i] -= v
        elif k == 5:
            K2[i] -= v
        elif k == 6:
            col = 0 if (j == 0 or j == 2) else (1 if (j == 1 or j == 4) else 2)
            Kx[i, col] -= v
        elif k == 7:
            lev[i, i] -= v
        elif k == 8:
            lev[i, j] -= v
        elif k == K_GIM:
            gim[j] -= v
        else:
            tau[0] -= v
    nA = Ag - Dg @ Ag
    Ag[:, :] = nA
    nA = Aa - Da @ Aa
    Aa[:, :] = nA


@njit(cache=True)
def _smooth_kernel(P0, K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, M, hist_Pm, hist_x, hist_P, x0, Pc0,
                   att_used, Ka_st, Sia_st, sza_st, Ha_st):
    """Backward MBF pass (inscal.filters): smoothed errors and covariances at the stored steps and at
    the start (``x0``, ``Pc0``).  Steps with encoder attitude rows (``att_used``) undo that second,
    later update first."""
    N = P0.shape[0]
    lam = np.zeros(N)
    Lam = np.zeros((N, N))
    ih = hist_Pm.shape[0] - 1
    for k in range(M - 1, -1, -1):
        if att_used.shape[0] > 0 and att_used[k]:
            _smoother_step_h(lam, Lam, Ha_st[k], Ka_st[k], Sia_st[k], sza_st[k])
        filters.smoother_step(lam, Lam, IDX_MEAS, K_st[k], Si_st[k], sz_st[k])
        if k % hist_every == 0 or k == M - 1:
            x, Ps = filters.smoothed(hist_Pm[ih], lam, Lam)
            hist_x[ih] = x
            hist_P[ih] = Ps
            ih -= 1
        filters.adjoint_back(lam, Lam, 9, phinn_st[k], phinp_st[k])
    x, Ps = filters.smoothed(P0, lam, Lam)
    x0[:] = x
    Pc0[:, :] = Ps


@njit(cache=True)
def _smooth_vector_kernel(K_st, sz_st, phinn_st, phinp_st, M, x0, att_used, Ka_st, sza_st, Ha_st):
    """The adjoint recursion for the smoothed state at the start only (``x0 = P_0 lambda_0`` with
    ``P_0 = I``): what the passes before the last need (the initial attitude)."""
    N = x0.shape[0]
    lam = np.zeros(N)
    d = np.empty(3)
    for k in range(M - 1, -1, -1):
        if att_used.shape[0] > 0 and att_used[k]:  # the encoder attitude rows (the later update)
            for a in range(3):
                s = sza_st[k, a]
                for i in range(N):
                    s -= Ka_st[k, i, a] * lam[i]
                d[a] = s
            for i in range(N):
                lam[i] += Ha_st[k, 0, i] * d[0] + Ha_st[k, 1, i] * d[1] + Ha_st[k, 2, i] * d[2]
        K = K_st[k]
        ktl = K.T @ lam
        for a in range(IDX_MEAS.shape[0]):
            lam[IDX_MEAS[a]] += sz_st[k, a] - ktl[a]
        ln = lam[:9].copy()
        lam[9:] = lam[9:] + phinp_st[k].T @ ln
        lam[:9] = phinn_st[k].T @ ln
    x0[:] = lam


# ----------------------------------------------------------------------------- driver
REF_SLICES = {"Ag": (0, 9, (3, 3)), "bg": (9, 12, (3,)), "G": (12, 21, (3, 3)), "Aa": (21, 30, (3, 3)),
              "ba": (30, 33, (3,)), "K2": (33, 36, (3,)), "Kx": (36, 45, (3, 3)), "lever": (45, 54, (3, 3)),
              "tau": (54, 55, (1,)), "gim": (55, 59, (4,))}


def _params_from_ref(row) -> CompParams:
    return CompParams(**{k: np.array(row[a:b]).reshape(s) for k, (a, b, s) in REF_SLICES.items()})


#: body rate [rad/s] (0.5-s mean) above which a sample counts as turning, for the alignment window
ALIGN_STATIC_RATE = 0.05 * math.pi / 180.0


def _first_motion(dth: np.ndarray, dt: float) -> int:
    """Samples before the first turn (0.5-s mean body rate above :data:`ALIGN_STATIC_RATE`;
    Earth rate is 0.004 deg/s); the whole record when it never turns."""
    h = max(1, int(round(0.5 / dt)))
    n = dth.shape[0]
    if n <= h:
        return n
    c = np.cumsum(dth, axis=0)
    rate = np.linalg.norm(c[h:] - c[:-h], axis=1) / (h * dt)
    idx = np.flatnonzero(rate > ALIGN_STATIC_RATE)
    return int(idx[0]) if idx.size else n


def estimate_white_noise(dtheta, dvel, dt) -> tuple[np.ndarray, np.ndarray]:
    """Angle and velocity random walk [rad/sqrt(s), m/s/sqrt(s)] per axis from the record itself:
    the robust spread (1.4826 MAD) of second differences of the increments, which removes
    constant rates and constant-rate rotations (var of a second difference of white noise = 6 s^2)."""
    out = []
    step = max(1, x_len // 200_000) if (x_len := len(dtheta)) else 1  # a subsample is plenty for a spread
    for x in (dtheta, dvel):
        d2 = (x[2:] - 2.0 * x[1:-1] + x[:-2])[::step]
        mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
        out.append(1.4826 * mad / math.sqrt(6.0) / math.sqrt(dt))
    return out[0], out[1]


@dataclass
class PassOutput:
    params: CompParams
    P0s: np.ndarray  # smoothed covariance at the start (scaled)
    x0s: np.ndarray  # smoothed error at the start (scaled)
    nis: np.ndarray
    z: np.ndarray
    steps: int
    hist_step: np.ndarray
    hist_ref: np.ndarray
    hist_x: np.ndarray
    hist_P: np.ndarray
    hist_Pm: np.ndarray
    Pf: np.ndarray | None = None  # filtered covariance after the last update (scaled)
    phinn: np.ndarray | None = None
    phinp: np.ndarray | None = None
    att_used: np.ndarray | None = None  # per step: 1 where the encoder attitude rows were used
    nis_att: np.ndarray | None = None  # their NIS (3 dof; NaN where unused)
    z_att: np.ndarray | None = None  # their raw residual vee(C_nav C_pred^T) [rad] (NaN where unused)
    # with keep_phi: the encoder rows' H (M, 3, N; scaled states, as Phi) and R (M, 3, 3; rad^2) per step,
    # for an observability matrix with the encoder rows (whitened by R^-1/2; zero where att_used is 0)
    H_att: np.ndarray | None = None
    R_att: np.ndarray | None = None


def run_pass(dth, dv, dt, n_per, C0, site, params: CompParams, states: StateSet, sig, qg, qa, r, hist_every,
             keep_phi: bool = False, smooth: bool = True, enc=None, enc_sigma: float = ENCODER_SIGMA) -> PassOutput:
    """One forward filter pass and its smoother (compiled kernels).  ``smooth=False`` runs only
    the adjoint recursion for the smoothed initial state (:func:`smooth_pass` completes it).
    Gimbal states: ``enc`` (>= M, 2) the encoder angles [outer, inner] at the end of each filter step
    (NaN rows: none), ``enc_sigma`` their white noise [rad] (module docstring)."""
    N = states.n_states
    npar = N - N_NAV
    M = dth.shape[0] // n_per
    if M < 2:
        raise CalibrationError(f"record too short for the filter: {dth.shape[0] * dt:g} s at a {n_per * dt:g} s step")
    nh = (M - 1) // hist_every + 1 + (1 if (M - 1) % hist_every else 0)
    p = params.copy()
    kinds, axes, js = states.columns()
    q = quat_from_dcm(C0)
    nav0 = np.concatenate([q / np.linalg.norm(q), np.zeros(3), [site[0], site[1], site[2]]])
    P = np.eye(N)
    K_st = np.empty((M, N, 6))
    Si_st = np.empty((M, 6, 6))
    sz_st = np.empty((M, 6))
    phinn_st = np.empty((M, 9, 9))
    phinp_st = np.empty((M, 9, npar))
    nis = np.empty(M)
    z_st = np.empty((M, 6))
    hist_Pm = np.empty((nh, N, N))
    hist_ref = np.empty((nh, 59))
    hist_Pf = np.empty((nh, N))
    nav_out = np.empty(10)
    if states.gimbal:
        if enc is None or np.shape(enc)[0] < M or np.shape(enc)[1:] != (2,):
            raise CalibrationError("the gimbal states need the encoder angles at every filter step")
        enc_a = np.ascontiguousarray(np.asarray(enc, float)[:M])
    else:
        enc_a = np.empty((0, 2))
    Ma = enc_a.shape[0]
    att_used = np.zeros(Ma, np.int8)
    Ka_st, Sia_st, sza_st = np.zeros((Ma, N, 3)), np.zeros((Ma, 3, 3)), np.zeros((Ma, 3))
    Ha_st, nisa_st, za_st = np.zeros((Ma, 3, N)), np.full(Ma, np.nan), np.full((Ma, 3), np.nan)
    Ra_st = np.zeros((Ma, 3, 3))
    nl = bool(states.extended or np.any(p.K2) or np.any(p.Kx) or np.any(p.lever) or np.any(p.G))
    Mk = _pass_kernel(np.ascontiguousarray(dth, dtype=float), np.ascontiguousarray(dv, dtype=float), float(dt),
                      int(n_per), nav0, np.asarray(site, float), p.Ag, p.bg, p.G, p.Aa, p.ba, p.K2, p.Kx, p.lever,
                      p.tau, nl, bool(states.asynchrony), kinds, axes, js, sig, qg, qa, r, P, int(hist_every),
                      K_st, Si_st, sz_st, phinn_st, phinp_st, nis, z_st, hist_Pm, hist_ref, hist_Pf, nav_out,
                      p.gim, enc_a, float(enc_sigma) ** 2, (0.1 * float(enc_sigma)) ** 2, att_used, Ka_st, Sia_st,
                      sza_st, Ha_st, nisa_st, za_st, Ra_st)
    x0 = np.empty(N)
    _smooth_vector_kernel(K_st, sz_st, phinn_st, phinp_st, Mk, x0, att_used, Ka_st, sza_st, Ha_st)
    steps = np.array(sorted(set(range(0, Mk, hist_every)) | {Mk - 1}))
    out = PassOutput(p, None, x0, nis, z_st, Mk, steps, hist_ref, None, None, hist_Pm, P)
    out._smoother_data = (K_st, Si_st, sz_st, phinn_st, phinp_st, int(hist_every), att_used, Ka_st, Sia_st, sza_st,
                          Ha_st)
    out.att_used, out.nis_att, out.z_att = att_used, nisa_st, za_st
    out._enc_floor = (0.1 * float(enc_sigma)) ** 2
    if keep_phi and Ma:
        out.H_att, out.R_att = Ha_st, Ra_st
    if keep_phi:
        out.phinn, out.phinp = phinn_st, phinp_st
    if smooth:
        smooth_pass(out)
    return out


def smooth_pass(out: PassOutput) -> PassOutput:
    """Run the full smoother (states and covariances at the stored steps and at the start) on a
    pass's stored data, in place."""
    K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, att_used, Ka_st, Sia_st, sza_st, Ha_st = out._smoother_data
    N = K_st.shape[1]
    nh = out.hist_Pm.shape[0]
    out.hist_x = np.empty((nh, N))
    out.hist_P = np.empty((nh, N, N))
    x0 = np.empty(N)
    out.P0s = np.empty((N, N))
    _smooth_kernel(np.eye(N), K_st, Si_st, sz_st, phinn_st, phinp_st, hist_every, out.steps, out.hist_Pm, out.hist_x,
                   out.hist_P, x0, out.P0s, att_used, Ka_st, Sia_st, sza_st, Ha_st)
    out.x0s = x0
    return out


def _canon_flat(p: CompParams, names) -> np.ndarray:
    from .result import flatten
    from ..errors import GimbalErrors

    return flatten(p.to_imu(), p.to_gimbal(), names)


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


def _fixed_mask(states: StateSet, names) -> np.ndarray:
    """Components of the canonical vector that the state set does not estimate (NaN sigma):
    the misalignment angles fixed by the frame definition, off-diagonal lever arms (S16 form)."""
    from ..errors import PARAMETERS

    mask = []
    for n in names:
        shape = PARAMETERS[n][4]
        size = int(np.prod(shape)) if shape else 1
        m = np.zeros(size, bool)
        tri = "accel_misalignment" if states.psins else "gyro_misalignment"
        if n == tri and not states.gimbal:  # upper angles [xy, xz, yz] are zero by the frame definition
            m[[0, 1, 3]] = True
        if n == "accel_lever_arm" and not states.lever9:
            m[[1, 2, 3, 5, 6, 7]] = True
        mask.append(m)
    return np.concatenate(mask)


def _jacobian(p: CompParams, states: StateSet, names, sig_par) -> np.ndarray:
    """d(canonical flat) / d(scaled parameter error state), central differences."""
    n = sig_par.shape[0]
    base = _canon_flat(p, names)
    J = np.empty((base.size, n))
    for c in range(n):
        h = 1e-4 * sig_par[c]
        e = np.zeros(n)
        e[c] = h
        J[:, c] = (_canon_flat(p.corrected(states, -e), names) - _canon_flat(p.corrected(states, e), names)) / (2 * h)
        J[:, c] *= sig_par[c]
    return J


def systematic(ws_or_record, states: str | StateSet = "51", *, filter_rate_hz: float = 1.0, max_passes: int = 5,
               tol: float = 0.2, arw=None, vrw=None, velocity_sigma: float | None = None,
               position_sigma: float | None = None, prior: dict | None = None, history_s: float = 10.0,
               align_s: float = 120.0, initial: ImuErrors | None = None, method_name: str | None = None,
               keep_passes: bool = False, encoder_sigma: float | None = None,
               encoder_every: int = 1) -> CalibrationResult:
    """Systematic calibration of a static-site rotation record (S16 section 3).

    ``states``: a :class:`StateSet` or its spec (``"51"``, ``"30"``, ``"51,lever9,async"``, ...).
    ``arw``/``vrw``: white noise [rad/sqrt(s)], [m/s/sqrt(s)] (scalar or per axis); estimated from
    the record when None.  ``prior``: prior 1 sigma per group name (SI), default
    :data:`DEFAULT_SIGMA0`.  ``initial``: linearisation start (canonical errors; default ideal).
    Gimbal states (``gimbal``/``unified``): ``encoder_sigma`` the white noise of each encoder angle
    [rad] (default :data:`ENCODER_SIGMA`, 1"), ``encoder_every`` the encoder attitude rows every n-th
    filter step (default every step); the record's ``gimbal`` dataset, else its ``path``.
    """
    rec = ws_or_record
    st = states if isinstance(states, StateSet) else StateSet.parse(states)
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
    if not (filter_rate_hz > 0 and math.isfinite(filter_rate_hz)):
        raise CalibrationError(f"filter rate must be > 0 Hz, got {filter_rate_hz}")
    n_per = max(1, int(round(rate / filter_rate_hz)))
    T = n_per * dt
    site = rec.site
    site_v = np.array([site.latitude, site.longitude, site.height, site.gravity_scale])
    # noise model
    est_arw, est_vrw = estimate_white_noise(dth, dv, dt)
    arw_v = np.broadcast_to(np.asarray(est_arw if arw is None else arw, float), (3,)).copy()
    vrw_v = np.broadcast_to(np.asarray(est_vrw if vrw is None else vrw, float), (3,)).copy()
    # floors: a filter tuned to (near) noise-free data loses its numerical footing; these are
    # far below navigation-grade noise (S16: 5e-5 deg/sqrt(h), 1 ug/sqrt(Hz))
    floored = bool(np.any(arw_v < ARW_FLOOR) or np.any(vrw_v < VRW_FLOOR))
    arw_v = np.maximum(arw_v, ARW_FLOOR)
    vrw_v = np.maximum(vrw_v, VRW_FLOOR)
    qg, qa = arw_v**2, vrw_v**2
    vsig = float(velocity_sigma) if velocity_sigma is not None else 0.05 * float(np.mean(vrw_v)) * math.sqrt(T)
    psig = float(position_sigma) if position_sigma is not None else vsig * T
    r = np.array([vsig**2] * 3 + [psig**2] * 3)
    # state scaling = prior sigma
    sig0 = dict(DEFAULT_SIGMA0)
    for k, v in (prior or {}).items():
        if k not in sig0:
            raise CalibrationError(f"prior: unknown group {k!r}; groups: {', '.join(sig0)}")
        sig0[k] = float(v)
    sig = np.array(list(NAV_SIGMA0) + [sig0[gr.name] for gr in st.groups for _ in gr.labels])
    sig_par = sig[N_NAV:]
    hist_every = max(1, int(round(history_s / T)))
    # coarse alignment (inertial-frame Wahba; valid while turning)
    from ..navigation import coarse_align

    n_al = min(dth.shape[0], max(int(round(min(align_s, dth.shape[0] * dt) * rate)), int(5 * rate) + 1))
    # ... but within the first dwell: the inertial-frame alignment is exact while turning only for
    # an ideal IMU at the table's centre; on a designed path whose first turn starts at 60 s, a
    # 120 s window gave a 25 deg heading error and a diverging first pass
    n_dwell = _first_motion(dth, dt)
    if n_dwell >= int(5 * rate) + 1:
        n_al = min(n_al, n_dwell)
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
    passes = []
    p_start = start
    prev = None
    converged = False
    inv_prior = 1.0 / sig_par**2
    sig_pass = sig.copy()
    first = None
    for ip in range(max_passes):
        out = run_pass(dth, dv, dt, n_per, C0, site_v, p_start, st, sig_pass, qg, qa, r, hist_every,
                       keep_phi=keep_passes, smooth=(max_passes == 1), enc=enc, enc_sigma=enc_sig)
        if not (np.all(np.isfinite(out.Pf)) and np.all(np.isfinite(out.params.error_state(st, nominal)))):
            raise CalibrationError(f"systematic filter diverged in pass {ip + 1} (non-finite state): the linearisation "
                                   "is too far from the data (a coarse alignment off, or errors beyond the priors)")
        sp = sig_pass[N_NAV:]
        # This pass ran with the prior N(p_start, diag(sp^2)) (deflated after pass 1 for numerical range).
        # Exact linear-Gaussian change of prior to N(nominal, diag(sig0^2)): data information
        # L_d = Pf^-1 - diag(sp^-2), posterior P = (L_d + diag(sig0^-2))^-1,
        # x = P (Pf^-1 x' + diag(sig0^-2) mu) with x' the pass's total correction and mu = p_start - nominal.
        Pf = out.Pf[N_NAV:, N_NAV:] * np.outer(sp, sp)
        Pf = 0.5 * (Pf + Pf.T)
        Pf_inv = np.linalg.inv(Pf)
        Pf_inv = 0.5 * (Pf_inv + Pf_inv.T)
        L_d = Pf_inv - np.diag(1.0 / sp**2)
        P_post = np.linalg.inv(L_d + np.diag(inv_prior))
        P_post = 0.5 * (P_post + P_post.T)
        x_pass = p_start.error_state(st, out.params)  # estimate(start) - estimate(end) = the correction
        mu = p_start.error_state(st, nominal)
        x_post = P_post @ (Pf_inv @ x_pass + inv_prior * mu)
        est = out.params.corrected(st, x_post - x_pass)
        sig_post = np.sqrt(np.maximum(np.diag(P_post), 0.0))
        phi0 = out.x0s[:3] * sig_pass[:3]
        C0 = _rotvec_dcm(-phi0) @ C0
        if first is None:
            first = (out, sig_pass.copy())
        passes.append({"pass": ip + 1, "nis_mean": float(np.mean(out.nis)),
                       "prior_deflation": float(np.max(sig_par / sp)),
                       "change_max_sigma": None if prev is None else
                       float(np.max(np.abs(est.error_state(st, prev)) / np.maximum(sig_post, 1e-300)))})
        if prev is not None and passes[-1]["change_max_sigma"] < tol:
            converged = True
            p_start = est
            break
        prev = est
        p_start = est
        # next pass: prior widths of at most DEFLATE posterior sigmas about the new start (its
        # information is removed again above), which keeps the covariance's range ~1e4 instead of ~1e10
        sig_pass = sig.copy()
        sig_pass[N_NAV:] = np.minimum(sig_par, DEFLATE * np.maximum(sig_post, 1e-6 * sig_par))
    last = out if max_passes == 1 else smooth_pass(out)
    names = estimated_names(st)
    J = _jacobian(est, st, names, sig_par) / sig_par  # d(canonical) / d(physical error state)
    Sig = J @ P_post @ J.T
    sflat = np.sqrt(np.maximum(np.diag(Sig), 0.0))
    fixed = _fixed_mask(st, names)
    sflat[fixed] = np.nan
    imu = est.to_imu()
    from ..errors import GimbalErrors
    from .result import unflatten

    # innovation statistics (normalised innovation squared; dof = 6 per step) and the fit
    from scipy.stats import chi2 as _chi2

    nis = last.nis
    dof = 6 * last.steps
    chisq = float(np.sum(nis))
    fit = innovation_fit(nis, last.z, T, chisq, dof, st)
    formal = unflatten(sflat, names)
    sigma = unflatten(sflat * fit["scale"], names)
    diag = {
        "states": st.n_states, "state_options": _state_spec(st), "frame": "accelerometer-defined (PSINS triangular)"
        if st.psins else "gyro-defined (S16 m-frame)",
        "filter_rate_hz": 1.0 / T, "steps": int(last.steps), "passes": passes, "converged": converged,
        "noise": {"arw_deg_sqrt_h": units.from_si(arw_v, "deg/sqrt(h)").tolist(),
                  "vrw_ug_sqrt_hz": units.from_si(vrw_v, "ug/sqrt(Hz)").tolist(),
                  "estimated_from_data": arw is None and vrw is None, "floored": floored,
                  "velocity_sigma_m_s": vsig, "position_sigma_m": psig},
        "innovations": {"nis_mean": float(np.mean(nis)), "nis_expected": 6.0, "chi2": chisq, "dof": dof,
                        "p_value": float(_chi2.sf(chisq, dof)) if dof > 0 else float("nan"),
                        "velocity_rms_m_s": float(np.sqrt(np.mean(last.z[:, :3] ** 2))),
                        "position_rms_m": float(np.sqrt(np.mean(last.z[:, 3:] ** 2)))},
        "initial_attitude_deg": np.degrees(_euler(C0)).tolist(),
    }
    diag["fit"] = fit
    diag["formal_sigma"] = formal
    notes = [f"systematic {st.n_states}-state filter: parameters in the {diag['frame']} frame"]
    if fit["note"]:
        notes.append(fit["note"])
    res = CalibrationResult(method_name or ("systematic51" if st.extended else "systematic30"), imu,
                            est.to_gimbal() if st.gimbal else GimbalErrors(), sigma, names, None, diag, notes)
    res.truth_transform = lambda truth, _st=st: (_truth_imu(truth, _st), _truth_gimbal(truth, _st))
    if st.gimbal:
        _gimbal_diagnostics(res, last, st, enc_sig, int(encoder_every))
    h_out, h_sig = first
    if h_out.hist_x is None:
        smooth_pass(h_out)
    res.history = _history(h_out, st, names, h_sig, J, est, P_post)
    res.history["time_s"] = res.history["t_steps"] * T
    res.states = st
    res.covariance = {"labels": st.labels()[N_NAV:], "P": P_post}
    if keep_passes:
        res.pass_output = last
    return res


#: p-value below which the innovations are declared inconsistent with the noise model
P_INCONSISTENT = 1e-3
#: time blocks of the per-window innovation residuals (at most this many, at least 60 s each)
FIT_BLOCKS = 24


def innovation_fit(nis: np.ndarray, z: np.ndarray, T: float, chisq: float, dof: int, st: StateSet) -> dict:
    """The fit of a systematic-filter run, in the form of the window-mean methods' fit
    (:func:`inscal.calibrate.result.fit_statistics`): chi^2 of the normalised innovations on
    ``dof`` = 6 per filter step, p-value, and per time block (the filter has no windows) the
    mean NIS (expected 6) with the velocity / position innovation RMS.

    When p < :data:`P_INCONSISTENT` the reported sigma are the formal (smoothed) ones times
    ``scale = sqrt(chi2 / dof)`` (``sqrt(mean NIS / 6)``): the innovation sequence says the
    noise model understates what the filter sees (unmodelled terms, a wrong path or wrong
    gravity add to every innovation); the formal sigma are kept beside them."""
    from scipy.stats import chi2 as _chi2

    p = float(_chi2.sf(chisq, dof)) if dof > 0 else float("nan")
    consistent = not (p < P_INCONSISTENT)
    scale = 1.0 if consistent else math.sqrt(max(chisq / dof, 1.0))
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
    fit = {"chi2": chisq, "dof": int(dof), "expected_chi2": float(dof), "p_value": p, "consistent": consistent,
           "scale": scale, "residuals": res, "cause": None, "note": None,
           "sigma_rule": "systematic filter: sigma x sqrt(chi2/dof) of the innovations when p < 0.001"}
    if not consistent:
        worst = max(res, key=lambda r: r["nis_mean"])
        if not st.extended:
            cause = ("unmodelled terms (the 30-state set has no g-sensitivity, quadratic, cross-coupling or "
                     "lever-arm states: try --states 51)")
        else:
            cause = ("unmodelled terms, wrong noise (--arw/--vrw), a wrong path or wrong gravity (--gravity); "
                     f"worst block {worst['label'].strip()} (NIS {worst['nis_mean']:.3g})")
        fit["cause"] = cause
        fit["note"] = (f"fit inconsistent: innovation chi2 = {chisq:.4g} on {dof} dof (NIS mean {chisq / max(n, 1):.3g} "
                       f"vs 6, p = {p:.2g}); likely cause: {cause}; sigma scaled by sqrt(chi2/dof) = {scale:.3g}, "
                       "formal sigma kept")
    return fit


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
    from ..turntable import C_s_b

    return _euler(np.asarray(C_s_n, float) @ C_s_b(float(angles[0]), float(angles[1]), float(dth)).T)


def _gimbal_diagnostics(res, last: PassOutput, st: StateSet, enc_sig: float, every: int) -> None:
    """The unified filter's frame label and its encoder attitude innovations (``diagnostics["encoder"]``)."""
    d = res.diagnostics
    d["frame"] = FRAME_GIMBAL
    if res.notes:
        res.notes[0] = f"systematic {st.n_states}-state filter: parameters in the {FRAME_GIMBAL} frame"
    used = np.asarray(last.att_used, bool)
    nis = last.nis_att[used]
    za = last.z_att[used]
    # E[NIS] = tr(S^-1 (H P H^T + R_enc)) = 3 - floor tr(S^-1): the floor is not in the data (between 2 and 3)
    Sia = last._smoother_data[8][used]
    expected = float(np.mean(3.0 - last._enc_floor * np.trace(Sia, axis1=1, axis2=2))) if nis.size else float("nan")
    d["encoder"] = {"sigma_arcsec": float(units.from_si(enc_sig, "arcsec")), "every_steps": every,
                    "updates": int(used.sum()), "nis_mean": float(np.mean(nis)) if nis.size else float("nan"),
                    "nis_expected": expected,
                    "residual_rms_arcsec": (units.from_si(np.sqrt(np.mean(za**2, axis=0)), "arcsec").tolist()
                                            if za.size else None)}


def _truth_gimbal(truth, st: StateSet):
    from ..errors import GimbalErrors

    if not st.gimbal:
        return GimbalErrors()
    return truth[1] if isinstance(truth, tuple) else truth.gimbal


def _truth_imu(truth, st: StateSet) -> ImuErrors:
    imu = truth[0] if isinstance(truth, tuple) else truth.imu
    return truth_in_frame(imu, st).to_imu()


def _state_spec(st: StateSet) -> str:
    parts = ["51" if st.extended else "30"]
    parts += [n for n, f in (("lever9", st.lever9), ("async", st.asynchrony), ("psins", st.psins),
                             ("gimbal", st.gimbal)) if f]
    return ",".join(parts)


def _rotvec_dcm(v) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(v, float)).as_matrix()


def _euler(C) -> np.ndarray:
    from ..attitude import euler_from_dcm

    return np.asarray(euler_from_dcm(C))


def _history(out: PassOutput, st: StateSet, names, sig, J, final: CompParams, P_post) -> dict:
    """Parameter histories in the canonical layout (SI) at the stored steps: ``filtered`` (the
    reference before each stored update, 1 sigma from the predicted covariance) and ``smoothed``.

    The parameters are constants, so their smoothed estimate and covariance at every step are the
    final ones (the RTS smoother with zero parameter process noise); inscal uses that identity
    rather than the adjoint recursion, whose parameter part loses precision early in the record
    when the zero-velocity updates are ~1e8 times more informative than the prior.  The recursion's
    own parameter estimates (``mbf``) are kept for checks; they agree with the final ones once the
    record is well conditioned (tests/test_systematic.py)."""
    sig_par = sig[N_NAV:]
    t = (out.hist_step + 1).astype(float)
    # canonical values to first order about the final estimate: canon(ref) = canon(final) + J x_ref,
    # x_ref = the error state of each reference relative to the final (exact conversions at both ends)
    fin = _canon_flat(final, names)
    refs = [_params_from_ref(r) for r in out.hist_ref]
    xr = np.array([r.error_state(st, final) for r in refs])
    filt = fin + xr @ J.T
    filt[0] = _canon_flat(refs[0], names)
    mbf = fin + (xr - out.hist_x[:, N_NAV:] * sig_par) @ J.T
    Pm = out.hist_Pm[:, N_NAV:, N_NAV:] * np.outer(sig_par, sig_par)
    sf = np.sqrt(np.maximum(np.sum((J @ Pm) * J, axis=2), 0.0))
    sfin = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", J, P_post, J), 0.0))
    n = filt.shape[0]
    return {"step": out.hist_step, "names": names, "filtered": filt, "filtered_sigma": sf,
            "smoothed": np.tile(fin, (n, 1)), "smoothed_sigma": np.tile(sfin, (n, 1)), "mbf": mbf,
            "t_steps": t}


def systematic51(ws_or_record, **kw) -> CalibrationResult:
    """S16's 51-state systematic calibration (``states="51"`` plus options)."""
    extra = kw.pop("states", None)
    spec = "51" + ("," + extra if extra else "")
    return systematic(ws_or_record, spec, method_name="systematic51", **kw)


def systematic30(ws_or_record, **kw) -> CalibrationResult:
    """S16's traditional 30-state filter (no g-sensitivity, nonlinearity, cross-coupling, lever arm)."""
    extra = kw.pop("states", None)
    spec = "30" + ("," + extra if extra else "")
    return systematic(ws_or_record, spec, method_name="systematic30", **kw)


def one_step(dth, dv, dt, nav0, site, params: CompParams, states: StateSet):
    """Propagate the navigation over the samples given (one filter step, no update) from the
    navigation state ``nav0 = [q(4), v(3), lat, lon, h]``; returns the final state (10) and the
    step's physical ``(Phi_nn, Phi_np)``.  For tests of the F blocks against finite differences
    of this same nonlinear propagation."""
    N = states.n_states
    n = dth.shape[0]
    p = params.copy()
    kinds, axes, js = states.columns()
    P = np.eye(N)
    one = lambda *s: np.empty((1,) + s)  # noqa: E731
    K_st, Si_st, sz_st = one(N, 6), one(6, 6), one(6)
    phinn, phinp = one(9, 9), one(9, N - N_NAV)
    nis, z = np.empty(1), one(6)
    hP, hr, hf = one(N, N), one(59), one(N)
    out = np.empty(10)
    _pass_kernel(np.ascontiguousarray(dth, float), np.ascontiguousarray(dv, float), float(dt), n,
                 np.asarray(nav0, float), np.asarray(site, float), p.Ag, p.bg, p.G, p.Aa, p.ba, p.K2, p.Kx,
                 p.lever, p.tau, True, bool(states.asynchrony), kinds, axes, js, np.ones(N), np.zeros(3),
                 np.zeros(3), np.full(6, 1e30), P, 1, K_st, Si_st, sz_st, phinn, phinp, nis, z, hP, hr, hf, out,
                 p.gim, np.empty((0, 2)), 0.0, 0.0, np.zeros(0, np.int8), np.empty((0, N, 3)), np.empty((0, 3, 3)),
                 np.empty((0, 3)), np.empty((0, 3, N)), np.empty(0), np.empty((0, 3)), np.empty((0, 3, 3)))
    return out, phinn[0], phinp[0]
