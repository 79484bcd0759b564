"""Dual-axis (U-T) turntable / gimbal kinematics and rotation paths as data.

Geometry (N25 section 2.3):

* b-frame: fixed to the turntable base; x = the outer axis direction with zero
  non-orthogonality, z = the inner axis at zero gimbal angles.  The outer axis is
  ``u = [cos dtheta, 0, sin dtheta]`` in b (N25 Fig. 1).
* ``C_s^b = Rot(u, theta_x) R_z(theta_z)`` (N25 eq. 5-7, with the exact Rodrigues
  rotation about the tilted axis instead of the first-order eq. 5).
* ``C_b^n = R_z(gamma0) R_y(beta0) R_x(alpha0)`` (N25 eq. 8).  With zero mount
  attitude the outer axis points East and the IMU starts E-N-U (S16 Table 1).

A path is a list of moves: each move turns one axis by ``angle`` at a cruise
``rate`` with a trapezoidal rate profile of angular acceleration ``accel``, then
dwells.  Paths compile to piecewise-quadratic angle segments that the simulator
integrates exactly.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from inscal.core.attitude import axis_angle_xyz, dcm_from_euler, euler_from_dcm
from inscal.core.units import DEG

AXES = ("outer", "inner")


class PathError(ValueError):
    """A rotation path that cannot be run."""


@dataclass(frozen=True)
class Move:
    """One move: turn ``axis`` by ``angle`` [rad] at cruise ``rate`` [rad/s] (> 0), then dwell [s].

    ``axis`` is "outer", "inner" or "none" (a pure dwell).  ``label`` is free text, e.g.
    "rate-test +z" (the calibration segmenter uses the constant-rate windows whatever the label).
    """

    axis: str
    angle: float = 0.0
    rate: float = 0.0
    dwell: float = 0.0
    label: str = ""

    def __post_init__(self):
        if self.axis not in AXES + ("none",):
            raise PathError(f"move axis must be 'outer', 'inner' or 'none', got {self.axis!r}")
        for n in ("angle", "rate", "dwell"):
            v = getattr(self, n)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise PathError(f"move {n} must be a finite number, got {v!r}")
        if self.dwell < 0:
            raise PathError(f"move dwell must be >= 0 s, got {self.dwell}")
        if self.axis != "none":
            if self.rate <= 0:
                raise PathError(f"move rate must be > 0 (direction is the sign of the angle), got {self.rate / DEG:g} deg/s")
            if self.angle == 0:
                raise PathError("a move on an axis needs a non-zero angle")


@dataclass(frozen=True)
class RotationPath:
    """A rotation path.  ``closed`` paths must end at their start angles (mod 360 deg)."""

    name: str
    moves: tuple[Move, ...]
    accel: float = 10.0 * DEG  # angular acceleration of the trapezoidal profile [rad/s^2]
    initial: tuple[float, float] = (0.0, 0.0)  # (theta_x, theta_z) [rad]
    initial_dwell: float = 0.0  # [s]
    closed: bool = True

    def __post_init__(self):
        object.__setattr__(self, "moves", tuple(self.moves))
        object.__setattr__(self, "initial", tuple(float(a) for a in self.initial))
        if not self.moves:
            raise PathError(f"path {self.name!r} has no moves")
        if not (math.isfinite(self.accel) and self.accel > 0):
            raise PathError(f"path {self.name!r}: angular acceleration must be > 0")
        if not (math.isfinite(self.initial_dwell) and self.initial_dwell >= 0):
            raise PathError(f"path {self.name!r}: initial_dwell must be >= 0")
        if self.closed:
            end = self.final_angles()
            for k, ax in enumerate(AXES):
                d = math.remainder(end[k] - self.initial[k], 2 * math.pi)
                if abs(d) > 1e-9:
                    raise PathError(
                        f"path {self.name!r} ends at {ax}={end[0 if k == 0 else 1] / DEG:g} deg, not at its start "
                        f"(outer={self.initial[0] / DEG:g}, inner={self.initial[1] / DEG:g} deg); "
                        "a closed path must return to its starting position (set closed = false to allow)"
                    )

    def final_angles(self) -> tuple[float, float]:
        """The (outer, inner) gimbal angles [rad] after the last move."""
        th = list(self.initial)
        for m in self.moves:
            if m.axis != "none":
                th[AXES.index(m.axis)] += m.angle
        return th[0], th[1]

    @property
    def duration(self) -> float:
        """The length of the path [s], dwells included."""
        return float(self.segments().t1[-1])

    def segments(self) -> "Segments":
        """The path compiled into its piecewise-quadratic segments (:func:`compile_path`)."""
        return compile_path(self)

    # -- (de)serialisation in field units (deg, deg/s, s)
    def to_dict(self) -> dict:
        """The path as a table in the units of a path file (degrees, seconds), as :meth:`from_dict` reads it."""
        return {
            "name": self.name,
            "accel_dps2": self.accel / DEG,
            "initial_deg": [a / DEG for a in self.initial],
            "initial_dwell_s": self.initial_dwell,
            "closed": self.closed,
            "moves": [
                {"axis": m.axis, "angle_deg": m.angle / DEG, "rate_dps": m.rate / DEG, "dwell_s": m.dwell, "label": m.label}
                for m in self.moves
            ],
        }

    def to_json(self) -> str:
        """The path as JSON text (:meth:`to_dict`), as a record's ``path`` attribute holds it."""
        return json.dumps(self.to_dict())

    @classmethod
    def from_dict(cls, d: dict) -> "RotationPath":
        """A path from a ``[path]`` table (degrees, seconds); unknown keys and malformed moves are a :class:`PathError`."""
        known = {"name", "accel_dps2", "initial_deg", "initial_dwell_s", "closed", "moves"}
        unknown = set(d) - known
        if unknown:
            raise PathError(f"unknown path keys {sorted(unknown)}; known: {sorted(known)}")
        if "moves" not in d or not isinstance(d["moves"], list):
            raise PathError("path needs a list of moves")
        moves = []
        for k, m in enumerate(d["moves"]):
            mk = {"axis", "angle_deg", "rate_dps", "dwell_s", "label"}
            if not isinstance(m, dict) or set(m) - mk:
                raise PathError(f"move {k + 1}: expected keys among {sorted(mk)}, got {m!r}")
            try:
                moves.append(
                    Move(
                        axis=m.get("axis", "none"),
                        angle=float(m.get("angle_deg", 0.0)) * DEG,
                        rate=float(m.get("rate_dps", 0.0)) * DEG,
                        dwell=float(m.get("dwell_s", 0.0)),
                        label=str(m.get("label", "")),
                    )
                )
            except (TypeError, ValueError) as exc:
                raise PathError(f"move {k + 1}: {exc}") from None
        init = d.get("initial_deg", [0.0, 0.0])
        if len(init) != 2:
            raise PathError("initial_deg must be [outer, inner]")
        return cls(
            name=str(d.get("name", "custom")),
            moves=tuple(moves),
            accel=float(d.get("accel_dps2", 10.0)) * DEG,
            initial=(float(init[0]) * DEG, float(init[1]) * DEG),
            initial_dwell=float(d.get("initial_dwell_s", 0.0)),
            closed=bool(d.get("closed", True)),
        )

    @classmethod
    def from_json(cls, s: str) -> "RotationPath":
        """A path from :meth:`to_json`'s text."""
        return cls.from_dict(json.loads(s))


@dataclass(frozen=True)
class Segments:
    """Piecewise-quadratic gimbal angles: on segment k, for t in [t0[k], t1[k]],
    ``theta = th0[k] + w0[k] (t - t0[k]) + 0.5 acc[k] (t - t0[k])^2`` (columns: outer, inner)."""

    t0: np.ndarray
    t1: np.ndarray
    th0: np.ndarray
    w0: np.ndarray
    acc: np.ndarray
    move_index: np.ndarray  # index of the move each segment belongs to (-1: initial dwell)

    def angles(self, t):
        """(theta, rate, accel) arrays of shape (N, 2) at times t (N,)."""
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.t1, t, side="left"), 0, len(self.t0) - 1)
        tau = (t - self.t0[k])[:, None]
        th = self.th0[k] + self.w0[k] * tau + 0.5 * self.acc[k] * tau**2
        w = self.w0[k] + self.acc[k] * tau
        return th, w, self.acc[k].copy()


def compile_path(path: RotationPath) -> Segments:
    """The path as :class:`Segments`: for each piece its start and end time, the angles, rates and
    angular accelerations of both gimbals at its start, and the move it belongs to (-1: the initial dwell).
    """
    t0, t1, th0, w0, acc, mi = [], [], [], [], [], []
    t = 0.0
    th = np.array(path.initial, dtype=float)

    def add(dur, w=(0.0, 0.0), a=(0.0, 0.0), m=-1):
        nonlocal t, th
        if dur <= 0:
            return
        t0.append(t)
        t1.append(t + dur)
        th0.append(th.copy())
        w0.append(np.array(w, dtype=float))
        acc.append(np.array(a, dtype=float))
        mi.append(m)
        th = th + np.array(w) * dur + 0.5 * np.array(a) * dur * dur
        t += dur

    add(path.initial_dwell, m=-1)
    for k, m in enumerate(path.moves):
        if m.axis != "none":
            ax = AXES.index(m.axis)
            sgn = math.copysign(1.0, m.angle)
            A, W, al = abs(m.angle), m.rate, path.accel
            target = th[ax] + m.angle
            if A >= W * W / al:  # trapezoid
                ta, tc, wp = W / al, (A - W * W / al) / W, W
            else:  # triangle
                wp = math.sqrt(A * al)
                ta, tc = wp / al, 0.0
            vec = np.zeros(2)
            vec[ax] = 1.0
            add(ta, w=0 * vec, a=sgn * al * vec, m=k)
            add(tc, w=sgn * wp * vec, m=k)
            add(ta, w=sgn * wp * vec, a=-sgn * al * vec, m=k)
            th[ax] = target  # remove round-off accumulated by the profile
        add(m.dwell, m=k)
    return Segments(np.array(t0), np.array(t1), np.array(th0), np.array(w0), np.array(acc), np.array(mi))


# ------------------------------------------------------------------- kinematics
def outer_axis(dtheta: float) -> np.ndarray:
    """Outer gimbal axis in the b-frame (N25 Fig. 1)."""
    return np.array([math.cos(dtheta), 0.0, math.sin(dtheta)])


@njit(cache=True)
def c_s_b_rows(tx, tz, x, y, z, out):
    """``out[i] = Rot(u, tx[i]) R_z(tz[i])`` for the unit axis ``u = (x, y, z)`` (Rodrigues, as
    :func:`inscal.core.attitude.axis_angle_dcm`, times ``R_z``; N25 eq. 7), over 1-D angle arrays."""
    for i in range(tx.shape[0]):
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = axis_angle_xyz(math.cos(tx[i]), math.sin(tx[i]), x, y, z)
        cz, sz = math.cos(tz[i]), math.sin(tz[i])
        out[i, 0, 0], out[i, 0, 1], out[i, 0, 2] = r00 * cz + r01 * sz, r01 * cz - r00 * sz, r02
        out[i, 1, 0], out[i, 1, 1], out[i, 1, 2] = r10 * cz + r11 * sz, r11 * cz - r10 * sz, r12
        out[i, 2, 0], out[i, 2, 1], out[i, 2, 2] = r20 * cz + r21 * sz, r21 * cz - r20 * sz, r22


def C_s_b(theta_x, theta_z, dtheta: float = 0.0) -> np.ndarray:
    """``C_s^b = Rot(u, theta_x) R_z(theta_z)`` (N25 eq. 7), scalar or arrays -> (..., 3, 3)."""
    u = outer_axis(dtheta)
    x, y, z = u / math.sqrt(u @ u)
    tx = np.atleast_1d(np.asarray(theta_x, dtype=float))
    tz = np.atleast_1d(np.asarray(theta_z, dtype=float))
    tx, tz = np.broadcast_arrays(tx, tz)
    out = np.empty(tx.shape + (3, 3))
    c_s_b_rows(np.ascontiguousarray(tx).reshape(-1), np.ascontiguousarray(tz).reshape(-1), x, y, z,
               out.reshape(-1, 3, 3))
    if np.ndim(theta_x) == 0 and np.ndim(theta_z) == 0:
        return out[0]
    return out


def C_b_n(mount_attitude) -> np.ndarray:
    """``C_b^n`` of the turntable base (N25 eq. 8)."""
    return dcm_from_euler(mount_attitude)


def vehicle_attitude_from_imu(C_s_n, theta_x, theta_z, dtheta_model: float = 0.0) -> np.ndarray:
    """Vehicle (base) attitude ``[roll, pitch, yaw]`` from the IMU attitude and gimbal
    angles, using a gimbal model with non-orthogonality ``dtheta_model`` (N25 eq. 34-36)."""

    Csb = C_s_b(theta_x, theta_z, dtheta_model)
    Cbn = np.einsum("...ij,...kj->...ik", C_s_n, Csb)  # C_s^n (C_s^b)^T
    return euler_from_dcm(Cbn)


def attitude_error_nonorthogonality(theta_x, dtheta: float) -> np.ndarray:
    """First-order vehicle attitude error ``[d roll, d pitch, d yaw]`` from neglecting the
    non-orthogonality ``dtheta`` when the IMU attitude is mapped to the vehicle.

    Derived from the exact model above: ``C~_b^n = C_b^n Rot(u, th_x) R_x(th_x)^T``, and
    ``Rot(x + dth z, t) R_x(t)^T ~ I + [phi x]`` with
    ``phi = dth [0, -(1 - cos t), sin t] = [0, -2 dth sin^2(t/2), dth sin t]``.
    N25 eq. 37 prints ``[0, 2 dth sin^2(th_x/2) cos(th_z), dth sin(th_x)]``: the same
    magnitudes, but the exact model has no th_z dependence (the inner rotation is about
    the true inner axis and cancels) and the opposite pitch sign for the error defined
    as computed minus true; at th_z = 180 deg both agree.  See tests/core/test_turntable.py.
    """
    tx = np.asarray(theta_x, dtype=float)
    return np.stack([np.zeros_like(tx), -2.0 * dtheta * np.sin(tx / 2) ** 2, dtheta * np.sin(tx)], axis=-1)


# ------------------------------------------------------------------ built-in paths
def s16_table1(rate_dps: float = 5.0, dwell_s: float = 180.0, accel_dps2: float = 10.0) -> RotationPath:
    """S16 Table 1: 18 rotations, 5 deg/s, 180 s pause at every position (~1 h)."""
    seq = [
        ("outer", 90), ("outer", 180), ("outer", 180), ("inner", 90), ("inner", 180), ("inner", 180),
        ("outer", 90), ("outer", 180), ("outer", 180), ("outer", 90), ("outer", 90), ("outer", 90),
        ("inner", 90), ("inner", 90), ("inner", 90), ("outer", 90), ("outer", 90), ("outer", 90),
    ]
    moves = tuple(Move(ax, a * DEG, rate_dps * DEG, dwell_s, label=f"S16 #{k + 1}") for k, (ax, a) in enumerate(seq))
    return RotationPath("s16-table1", moves, accel=accel_dps2 * DEG, initial_dwell=dwell_s)


#: S16 Table 1 attitudes of the IMU axes (x, y, z) after each rotation, in E/N/U/W/S/D letters.
S16_TABLE1_ATTITUDES = [
    "ENU", "EUS", "EDN", "EUS", "UWS", "DES", "UWS", "SWD", "NWU", "SWD",
    "DWN", "NWU", "UWS", "WDS", "DES", "EUS", "ESD", "EDN", "ENU",
]

#: N25 twelve positions (theta_x, theta_z) [deg]: each IMU axis up and down, each at two
#: inner-symmetric angles (theta_z and theta_z + 180).  See N25 Table 1 / Fig. 4.
N25_TWELVE_POSITIONS = [
    (0, 0), (0, 180), (90, 180), (90, 270), (90, 0), (90, 90),
    (180, 90), (180, 270), (270, 270), (270, 0), (270, 90), (270, 180),
]


def n25_twelve(dwell_s: float = 100.0, rate_dps: float = 4.0, rate_test_dps: float = 10.0,
               rate_test_turns: int = 2, accel_dps2: float = 10.0, rate_tests: bool = True) -> RotationPath:
    """N25 twelve-position scheme (100 s per position, 4 deg/s moves) followed by
    clockwise/counter-clockwise rate tests about the three IMU axes (N25 eq. 28).

    Rate tests: about z (inner axis, z up), about x (outer axis at theta_z = 0) and about y
    (outer axis at theta_z = 90 deg, so y lies along -outer).  Each turns
    ``rate_test_turns`` full turns plus the acceleration angle plus 2 s of cruise at each
    end, so the constant-rate part still covers ``rate_test_turns`` whole turns after the
    settling time is dropped; first +, then -.
    """
    pos = N25_TWELVE_POSITIONS
    moves = []
    cur = list(pos[0])
    for k, (tx, tz) in enumerate(pos[1:], start=2):
        for ax, i, tgt in (("outer", 0, tx), ("inner", 1, tz)):
            d = (tgt - cur[i]) % 360
            if d:
                d = d if d <= 180 else d - 360
                moves.append(Move(ax, d * DEG, rate_dps * DEG, 0.0))
                cur[i] = tgt
        moves[-1] = Move(moves[-1].axis, moves[-1].angle, moves[-1].rate, dwell_s, label=f"position {k}")
    # back to (0, 0): outer 270 -> 360, inner 180 -> 360
    moves.append(Move("outer", 90 * DEG, rate_dps * DEG, 0.0))
    moves.append(Move("inner", 180 * DEG, rate_dps * DEG, dwell_s, label="position 1 (return)"))
    if rate_tests:
        extra = rate_test_dps**2 / accel_dps2  # angle spent accelerating + decelerating
        margin = 4.0 * rate_test_dps  # 2 s of cruise at each end, so settling can be dropped
        ang = rate_test_turns * 360.0 + extra + margin
        rt = rate_test_dps * DEG
        short = 30.0
        # about z (z up): inner axis
        moves += [Move("inner", ang * DEG, rt, short, "rate-test z+"), Move("inner", -ang * DEG, rt, short, "rate-test z-")]
        # about x: outer axis at theta_z = 0 (x along the outer axis)
        moves += [Move("outer", ang * DEG, rt, short, "rate-test x+"), Move("outer", -ang * DEG, rt, short, "rate-test x-")]
        # about y: inner to 90 deg, then outer (y along -outer axis)
        moves += [Move("inner", 90 * DEG, rate_dps * DEG, short),
                  Move("outer", ang * DEG, rt, short, "rate-test y-"), Move("outer", -ang * DEG, rt, short, "rate-test y+"),
                  Move("inner", -90 * DEG, rate_dps * DEG, dwell_s, "position 1 (end)")]
    return RotationPath("n25-twelve", tuple(moves), accel=accel_dps2 * DEG, initial_dwell=dwell_s)


#: 16-sequence dual-axis rotation modulation (in the style of Yuan et al. 2012 / Ji et al.
#: 2013): 180 deg turns alternating inner and outer axes, the second half reversing the
#: first so every axis' turns cancel in direction over one cycle.
ROTMOD16_SEQUENCE = [
    ("inner", +180), ("outer", +180), ("inner", +180), ("outer", +180),
    ("outer", -180), ("inner", -180), ("outer", -180), ("inner", -180),
    ("inner", -180), ("outer", -180), ("inner", -180), ("outer", -180),
    ("outer", +180), ("inner", +180), ("outer", +180), ("inner", +180),
]


def rotmod16(duration_s: float = 6 * 3600.0, dwell_s: float = 300.0, rate_dps: float = 10.0,
             accel_dps2: float = 10.0) -> RotationPath:
    """16-sequence rotation modulation repeated to cover ``duration_s`` (whole cycles,
    rounded up).  ``dwell_s`` is the stop at each of the 16 positions."""
    one = [Move(ax, a * DEG, rate_dps * DEG, dwell_s, label=f"seq {k + 1}") for k, (ax, a) in enumerate(ROTMOD16_SEQUENCE)]
    p1 = RotationPath("rotmod16", tuple(one), accel=accel_dps2 * DEG)
    n = max(1, math.ceil(duration_s / p1.duration))
    return RotationPath("rotmod16", tuple(one) * n, accel=accel_dps2 * DEG)


def static(duration_s: float) -> RotationPath:
    """A static base: one dwell of ``duration_s``."""
    if not duration_s > 0:
        raise PathError("duration must be > 0 s")
    return RotationPath("static", (Move("none", dwell=float(duration_s)),))


#: PSINS-style 19-position sequence: (gimbal axis, angle [deg], IMU axis and sense of the turn).
#: With the outer axis East and the inner axis = IMU z, an outer turn ``a`` at inner angle
#: ``theta_z`` turns the IMU about ``[cos theta_z, -sin theta_z, 0]`` (s-frame) by ``a``:
#: about +x at 0 deg, -y at 90 deg, -x at 180 deg, +y at 270 deg.
PSINS19_SEQUENCE = [
    ("outer", +90, "+x"), ("outer", +90, "+x"), ("outer", +90, "+x"),
    ("inner", -90, "-z"), ("inner", -90, "-z"),
    ("outer", +90, "-x"), ("outer", +90, "-x"), ("outer", +90, "-x"),
    ("inner", +90, "+z"),
    ("outer", -90, "-y"), ("outer", -90, "-y"), ("outer", -90, "-y"),
    ("inner", +90, "+z"), ("inner", +90, "+z"),
    ("outer", -90, "+y"), ("outer", -90, "+y"), ("outer", -90, "+y"),
    ("inner", -90, "-z"),
]

#: Attitudes of the IMU axes (x, y, z) at the 19 positions of :func:`psins19` (E/N/U/W/S/D).
PSINS19_ATTITUDES = [
    "ENU", "EUS", "ESD", "EDN", "UEN", "WUN", "WSU", "WDS", "WND", "NED",
    "DES", "SEU", "UEN", "EDN", "DWN", "SWD", "UWS", "NWU", "ENU",
]

#: Dwell after each of the 18 moves [s] (the first position has ``initial_dwell_s``).
PSINS19_DWELLS_S = (30.0, 20.0, 60.0, 20.0, 30.0, 90.0, 20.0, 60.0, 30.0,
                    20.0, 90.0, 30.0, 20.0, 60.0, 30.0, 20.0, 60.0, 90.0)


def psins19(rate_dps: float = 10.0, accel_dps2: float = 50.0, dwells_s=PSINS19_DWELLS_S,
            initial_dwell_s: float = 90.0) -> RotationPath:
    """PSINS-style 19-position systematic-calibration path (in the manner of Yan Gongmin's
    PSINS toolbox: 18 turns of 90 deg, ~9 s each, 20-90 s stops) for the dual-axis table.

    Every IMU axis points up and down (x up 3x / down 2x, y up 2x / down 3x, z up 4x /
    down 4x), the IMU turns about each of its three axes three times in each sense, with
    the turning axis in several orientations (x turns with x East and West, y turns with y
    East and West, z turns with z North, Down and Up), and the first 18 positions are the
    16 distinct orientations a 90-deg dual-axis table can reach plus two repeats.  Both
    gimbals return to their start without net winding (outer: +540 then -540 deg; inner
    within +-180 deg).

    Timing: cruise ``rate_dps`` (10 deg/s) with a trapezoidal profile of ``accel_dps2``
    (50 deg/s^2), so each 90-deg turn lasts ``90/10 + 10/50 = 9.2 s`` (the PSINS 9 s turn at
    10 deg/s plus the 0.2 s the acceleration costs).  Dwells: ``initial_dwell_s`` (90 s, for
    the alignment) at the first position, then :data:`PSINS19_DWELLS_S` (20/30/60/90 s).
    Duration with the defaults: 90 + 18 x 9.2 + 780 = 1035.6 s (17.3 min).

    ====  ======  =====  ==========  ======  =========
    pos   gimbal  angle  IMU turn    x y z   dwell [s]
    ====  ======  =====  ==========  ======  =========
    0     --      --     --          E N U   90
    1     outer   +90    +x (x = E)  E U S   30
    2     outer   +90    +x (x = E)  E S D   20
    3     outer   +90    +x (x = E)  E D N   60
    4     inner   -90    -z (z = N)  U E N   20
    5     inner   -90    -z (z = N)  W U N   30
    6     outer   +90    -x (x = W)  W S U   90
    7     outer   +90    -x (x = W)  W D S   20
    8     outer   +90    -x (x = W)  W N D   60
    9     inner   +90    +z (z = D)  N E D   30
    10    outer   -90    -y (y = E)  D E S   20
    11    outer   -90    -y (y = E)  S E U   90
    12    outer   -90    -y (y = E)  U E N   30
    13    inner   +90    +z (z = N)  E D N   20
    14    inner   +90    +z (z = N)  D W N   60
    15    outer   -90    +y (y = W)  S W D   30
    16    outer   -90    +y (y = W)  U W S   20
    17    outer   -90    +y (y = W)  N W U   60
    18    inner   -90    -z (z = U)  E N U   90
    ====  ======  =====  ==========  ======  =========

    "IMU turn" is the IMU axis (and its direction while it turns) about which the move
    turns the IMU, right-handed; the letters give where the IMU axes point after the move
    (:data:`PSINS19_ATTITUDES`), with zero mount attitude (outer axis East).
    """
    dwells = tuple(float(d) for d in dwells_s)
    if len(dwells) != len(PSINS19_SEQUENCE):
        raise PathError(f"psins19 needs {len(PSINS19_SEQUENCE)} dwells, got {len(dwells)}")
    moves = tuple(
        Move(ax, a * DEG, rate_dps * DEG, dwells[k], label=f"psins19 #{k + 1}: {turn}")
        for k, (ax, a, turn) in enumerate(PSINS19_SEQUENCE)
    )
    return RotationPath("psins19", moves, accel=accel_dps2 * DEG, initial_dwell=float(initial_dwell_s))


BUILTIN_PATHS = {"s16-table1": s16_table1, "n25-twelve": n25_twelve, "rotmod16": rotmod16, "static": static,
                 "psins19": psins19}
