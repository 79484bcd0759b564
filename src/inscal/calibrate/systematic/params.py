"""The compensation parameters of the systematic filter (S16 eq. 1-12 in the filter's frame), the
reference-history row layout, and the canonical flat parameter vector with its Jacobian."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import rq

from inscal.calibrate.result import flatten
from inscal.calibrate.systematic.states import (
    CROSS_PAIRS,
    K_TH,
    N_TH_ROWS,
    TH_RATE_ROW,
    THERMAL_ROWS,
    THERMAL_TERM_NAMES,
    StateSet,
)
from inscal.core.error_model import (
    PARAMETERS,
    GimbalErrors,
    ImuErrors,
    split_scale_misalignment,
)
from inscal.core.thermal import ThermalModel


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
    #: thermal coefficients by sensor axis (states module docstring): rows 3 t + k - 1 = order k of term t
    #: (gyro bias, gyro scale factor, accelerometer bias, accelerometer scale factor), row 12 the dT/dt term
    th: np.ndarray = field(default_factory=lambda: np.zeros((N_TH_ROWS, 3)))
    #: the lever-arm timing nuisance [s] per accelerometer (states ``levtime``; not an ImuErrors term: the
    #: canonical parameters do not depend on it)
    levt: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def copy(self) -> "CompParams":
        return CompParams(*(np.array(getattr(self, f), dtype=float) for f in self.__dataclass_fields__))

    def flat(self) -> np.ndarray:
        return np.concatenate([np.ravel(getattr(self, f)) for f in self.__dataclass_fields__])

    @classmethod
    def from_flat(cls, v) -> "CompParams":
        v = np.asarray(v, float)
        shapes = [(3, 3), (3,), (3, 3), (3, 3), (3,), (3,), (3, 3), (3, 3), (1,), (4,), (N_TH_ROWS, 3), (3,)]
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
        """The gimbal parameters as :class:`~inscal.core.error_model.GimbalErrors` (N25 eq. 5-8)."""

        return GimbalErrors(float(self.gim[0]), np.array(self.gim[1:4]))

    def to_imu(self) -> ImuErrors:
        """Canonical measurement-form errors (``M = A^-1``, ``eps = M_g b_g``, ``nabla = M_a b_a``)."""
        return ImuErrors(**self.imu_fields())

    def imu_fields(self) -> dict:
        """The fields of :meth:`to_imu` by name (what it validates and stores)."""
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
        return kw

    def corrected(self, states: StateSet, x: np.ndarray) -> "CompParams":
        """The parameters with the error estimate ``x`` (physical, parameter part) removed
        (the feedback of S16 eq. 27, as the kernel applies it)."""
        p = self.copy()
        k = 0
        for g in states.groups:
            v = x[k:k + g.size]
            k += g.size
            if g.kinds[0] == K_TH:
                p.th[list(g.js), list(g.axes)] -= v
            elif g.name in ("gyro_matrix", "accel_matrix"):
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
                for e, (i, j) in enumerate(zip(g.axes, g.js)):
                    p.G[i, j] -= v[e]
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
            elif g.name == "accel_lever_timing":
                p.levt = p.levt - v
            elif g.name == "gimbal_nonorthogonality":
                p.gim = p.gim - np.array([v[0], 0.0, 0.0, 0.0])
            elif g.name == "mount_attitude":
                p.gim = p.gim - np.concatenate([[0.0], v])
        return p

    def error_state(self, states: StateSet, truth: "CompParams") -> np.ndarray:
        """The error state ``x`` (estimate - truth, first order) of these parameters."""
        out = []
        for g in states.groups:
            if g.kinds[0] == K_TH:
                out += list(self.th[list(g.js), list(g.axes)] - truth.th[list(g.js), list(g.axes)])
            elif g.name in ("gyro_matrix", "accel_matrix"):
                A, At = (self.Ag, truth.Ag) if g.name == "gyro_matrix" else (self.Aa, truth.Aa)
                D = np.eye(3) - At @ np.linalg.inv(A)
                out += [D[i, j] for i, j in zip(g.axes, g.js)]
            elif g.name == "gyro_bias":
                out += list(self.bg - truth.bg)
            elif g.name == "accel_bias":
                out += list(self.ba - truth.ba)
            elif g.name == "gyro_g_sensitivity":
                out += [self.G[i, j] - truth.G[i, j] for i, j in zip(g.axes, g.js)]
            elif g.name == "accel_nonlinearity":
                out += list(self.K2 - truth.K2)
            elif g.name == "accel_cross_coupling":
                out += [self.Kx[r, _kx_col(a, b)] - truth.Kx[r, _kx_col(a, b)] for r, a, b in CROSS_PAIRS]
            elif g.name == "accel_lever_arm":
                d = self.lever - truth.lever
                out += list(np.diag(d)) if g.size == 3 else list(d.ravel())
            elif g.name == "time_asynchrony":
                out += list(self.tau - truth.tau)
            elif g.name == "accel_lever_timing":
                out += list(self.levt - truth.levt)
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

    A = np.linalg.inv(imu.M_g if frame == "gyro" else imu.M_a)
    R_, Q_ = rq(A.T)
    L = R_.T
    C_m_s = Q_.T
    S = np.diag(np.sign(np.diag(L)))
    C_m_s = C_m_s @ S
    return C_m_s.T


def thermal_rows(model: ThermalModel | None, imu: ImuErrors) -> np.ndarray:
    """The filter's thermal array (:attr:`CompParams.th`) of a canonical thermal model that goes with the errors
    ``imu`` at its ``t_ref``: the bias coefficients and the dT/dt term as they are, the scale-factor coefficients
    divided by ``1 + K_0`` (states module docstring).  Misalignment terms have no rows (not states)."""
    th = np.zeros((N_TH_ROWS, 3))
    if model is None:
        return th
    for term in THERMAL_TERM_NAMES[:4]:
        row = THERMAL_ROWS[term][0]
        c = np.asarray(getattr(model, term), float)
        if term.endswith("scale_factor"):
            c = c / (1.0 + np.asarray(getattr(imu, term), float))[None, :]
        th[row:row + c.shape[0]] = c
    th[TH_RATE_ROW] = model.gyro_bias_rate
    return th


def thermal_from_rows(th: np.ndarray, orders, imu: ImuErrors, t_ref: float, t_min: float, t_max: float,
                      sensor: str = "") -> ThermalModel:
    """The canonical thermal model of a thermal array (the inverse of :func:`thermal_rows` for the ``orders`` of
    :data:`~inscal.calibrate.systematic.states.THERMAL_TERM_NAMES`), with the errors ``imu`` at ``t_ref``."""
    kw = {}
    for term, o in zip(THERMAL_TERM_NAMES[:4], orders):
        row = THERMAL_ROWS[term][0]
        c = np.array(th[row:row + o], float)
        if term.endswith("scale_factor"):
            c = c * (1.0 + np.asarray(getattr(imu, term), float))[None, :]
        kw[term] = c
    rate = np.array(th[TH_RATE_ROW], float) if orders[4] else np.zeros(3)
    return ThermalModel(t_ref=float(t_ref), t_min=float(t_min), t_max=float(t_max), gyro_bias_rate=rate,
                        sensor=sensor, **kw)


def truth_in_frame(imu: ImuErrors, states: StateSet, gimbal=None, thermal: ThermalModel | None = None) -> CompParams:
    """The true compensation parameters expressed in the filter's frame.  The lever arms are positions: each row
    ``p_i`` is rotated with the frame (``R p_i``, a first-order change: 60 arcsec of frame rotation moves a 5-cm
    lever arm by 15 um, five times the sigma of a noise-free 19-position fit).  The quadratic terms are carried
    unchanged: exact when the frames coincide, as in the s16 and psins19 scenarios; otherwise they mix their axes
    by the rotation times their own size (0.015 ug/g^2 for 50 ug/g^2 and 60 arcsec).  With the
    gimbal states the frame is the canonical s-frame (no rotation) and ``gimbal`` (GimbalErrors)
    supplies the true gimbal parameters; ``thermal`` the true thermal model (:func:`thermal_rows`: sensor axes,
    the same in every frame)."""
    R = np.eye(3) if states.gimbal else frame_rotation(imu, states.frame)
    p = CompParams.from_imu(imu)
    p.Ag = R @ p.Ag
    p.bg = R @ p.bg
    p.G = R @ p.G @ R.T
    p.Aa = R @ p.Aa
    p.ba = R @ p.ba
    p.lever = p.lever @ R.T
    if gimbal is not None:
        p.gim = np.concatenate([[gimbal.nonorthogonality], gimbal.mount_attitude])
    p.th = thermal_rows(thermal, imu)
    return p


# ----------------------------------------------------------------------------- driver
REF_SLICES = {"Ag": (0, 9, (3, 3)), "bg": (9, 12, (3,)), "G": (12, 21, (3, 3)), "Aa": (21, 30, (3, 3)),
              "ba": (30, 33, (3,)), "K2": (33, 36, (3,)), "Kx": (36, 45, (3, 3)), "lever": (45, 54, (3, 3)),
              "tau": (54, 55, (1,)), "gim": (55, 59, (4,)), "th": (59, 59 + 3 * N_TH_ROWS, (N_TH_ROWS, 3)),
              "levt": (59 + 3 * N_TH_ROWS, 62 + 3 * N_TH_ROWS, (3,))}
#: width of a reference-history row (the end of the last slice)
REF_WIDTH = max(b for _, b, _ in REF_SLICES.values())


def params_from_ref(row) -> CompParams:
    return CompParams(**{k: np.array(row[a:b]).reshape(s) for k, (a, b, s) in REF_SLICES.items()})


def ref_error_states(rows: np.ndarray, states: StateSet, truth: CompParams) -> np.ndarray:
    """``params_from_ref(row).error_state(states, truth)`` of every reference-history row (nh, REF_WIDTH) at
    once (nh, n_params): the same expressions, on stacks of rows."""
    rows = np.asarray(rows, float)
    nh = rows.shape[0]

    def field(name):
        a, b, shape = REF_SLICES[name]
        return rows[:, a:b].reshape((nh,) + shape)

    out = []
    for g in states.groups:
        ax, js = list(g.axes), list(g.js)
        if g.kinds[0] == K_TH:
            out.append(field("th")[:, js, ax] - truth.th[js, ax])
        elif g.name in ("gyro_matrix", "accel_matrix"):
            A, At = (field("Ag"), truth.Ag) if g.name == "gyro_matrix" else (field("Aa"), truth.Aa)
            D = np.eye(3) - At @ np.linalg.inv(A)
            out.append(D[:, ax, js])
        elif g.name == "gyro_bias":
            out.append(field("bg") - truth.bg)
        elif g.name == "accel_bias":
            out.append(field("ba") - truth.ba)
        elif g.name == "gyro_g_sensitivity":
            out.append(field("G")[:, ax, js] - truth.G[ax, js])
        elif g.name == "accel_nonlinearity":
            out.append(field("K2") - truth.K2)
        elif g.name == "accel_cross_coupling":
            r, c = [r for r, _, _ in CROSS_PAIRS], [_kx_col(a, b) for _, a, b in CROSS_PAIRS]
            out.append(field("Kx")[:, r, c] - truth.Kx[r, c])
        elif g.name == "accel_lever_arm":
            d = field("lever") - truth.lever
            out.append(d[:, [0, 1, 2], [0, 1, 2]] if g.size == 3 else d.reshape(nh, 9))
        elif g.name == "time_asynchrony":
            out.append(field("tau") - truth.tau)
        elif g.name == "accel_lever_timing":
            out.append(field("levt") - truth.levt)
        elif g.name == "gimbal_nonorthogonality":
            out.append(field("gim")[:, :1] - truth.gim[0])
        elif g.name == "mount_attitude":
            out.append(np.array([[math.remainder(a - b, 2 * math.pi) for a, b in zip(r, truth.gim[1:4])]
                                 for r in field("gim")[:, 1:4]]).reshape(nh, 3))
    return np.concatenate(out, axis=1) if out else np.zeros((nh, 0))


def canonical_flat(p: CompParams, names) -> np.ndarray:
    """``flatten(p.to_imu(), p.to_gimbal(), names)`` from the fields themselves (the same values, without
    building and validating the error-model objects: the canonical Jacobian takes two per state)."""
    kw = p.imu_fields()
    gim = {"nonorthogonality": float(p.gim[0]), "mount_attitude": np.array(p.gim[1:4])}
    out = []
    for n in names:
        obj, attr = PARAMETERS[n].group, PARAMETERS[n].attribute
        src = kw if obj == "imu" else gim
        if attr not in src:
            return flatten(p.to_imu(), p.to_gimbal(), names)
        out.append(np.atleast_1d(np.asarray(src[attr], dtype=float)).ravel())
    return np.concatenate(out)


def canonical_jacobian(p: CompParams, states: StateSet, names, sig_par) -> np.ndarray:
    """d(canonical flat) / d(scaled parameter error state), central differences."""
    n = sig_par.shape[0]
    base = canonical_flat(p, names)
    J = np.empty((base.size, n))
    for c in range(n):
        h = 1e-4 * sig_par[c]
        e = np.zeros(n)
        e[c] = h
        J[:, c] = (canonical_flat(p.corrected(states, -e), names) - canonical_flat(p.corrected(states, e), names)) / (2 * h)
        J[:, c] *= sig_par[c]
    return J
