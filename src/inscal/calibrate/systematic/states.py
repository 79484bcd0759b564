"""State sets of the systematic filter as data (S16 eq. 17-27): the navigation states, the parameter
groups with their names, sizes, units, initial sigma and the kind of Jacobian column that feeds them,
and the options (``51``, ``30``, ``lever9``, ``async``, ``psins``, ``gimbal``)."""

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
    "gimbal_nonorthogonality": units.to_si(60.0, "arcsec"), "mount_attitude": units.to_si(1.0, "deg"),
}
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
    "auto": "chosen from the record: start from 51 and add or drop async, lever9, gdiag and nocross by an F-test "
            "on the innovations (see inscal.calibrate.systematic.selection)",
}
#: what each option sets on :class:`StateSet`
_OPTION_FLAGS = {"51": {"extended": True}, "30": {"extended": False}, "lever9": {"lever9": True},
                 "async": {"asynchrony": True}, "gimbal": {"gimbal": True},
                 "unified": {"extended": True, "gimbal": True}, "psins": {"psins": True},
                 "gdiag": {"gsens_offdiag": False}, "nocross": {"cross": False}}


@dataclass(frozen=True)
class StateSet:
    """A configuration of the systematic filter's parameter states (S16 eq. 22)."""

    extended: bool = True  # G, K2, Kx, lever arm
    lever9: bool = False
    asynchrony: bool = False
    psins: bool = False
    gimbal: bool = False  # dth + mount attitude, encoder attitude rows; frame = the gimbal's s-frame
    gsens_offdiag: bool = True  # the six off-diagonal g-sensitivity terms (extended model)
    cross: bool = True  # the six cross-coupling terms (extended model)

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
        if "auto" in toks:
            raise CalibrationError("'auto' is chosen by inscal.calibrate.systematic.selection.select_states, "
                                   "not a fixed state set")
        for opt in ("lever9", "gsens_offdiag", "cross"):
            if opt in kw and kw[opt] != cls.__dataclass_fields__[opt].default and not kw["extended"]:
                raise CalibrationError(f"{ {'gsens_offdiag': 'gdiag', 'cross': 'nocross'}.get(opt, opt)} needs the "
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
        shape = PARAMETERS[n][4]
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
    parts += [n for n, f in (("lever9", st.lever9), ("async", st.asynchrony), ("psins", st.psins),
                             ("gimbal", st.gimbal), ("gdiag", st.extended and not st.gsens_offdiag),
                             ("nocross", st.extended and not st.cross)) if f]
    return ",".join(parts)
