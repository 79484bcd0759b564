"""An independent reference IMU generator (a test oracle), written from the equations in the
conventions of Yan Gongmin's PSINS toolbox.  NumPy/SciPy only: it shares no code with inscal.

Frames and signs
----------------
* Navigation frame n: East-North-Up (x E, y N, z U) at a static site of latitude L.
* Body frame b = the IMU axes.  ``C_b^n`` maps body to navigation components; its columns are
  the IMU x, y, z axes written in ENU.
* Earth rate ``w_ie^n = [0, W cos L, W sin L]``, ``W = 7.292115e-5 rad/s``; the specific force at
  the centre of the (static) table is ``f^n = [0, 0, +g]`` with g the effective gravity.

Motion (closed form, no integration)
------------------------------------
The IMU starts at ``C_b^n = C0`` (default I: x=E, y=N, z=U) and makes moves; a move turns it by a
signed angle about one of its own axes ``e`` (a body axis)::

    C_b^n(t) = C_b^n(t_m) Rot(e, theta(t - t_m))          Rot(e, a) = I + sin a [e]x + (1 - cos a) [e]x^2

so ``w_nb^b = theta_dot e`` and ``dw_nb^b/dt = theta_ddot e`` (``e`` is an eigenvector of Rot).  The
true body rate and its derivative are::

    w = w_ib^b = theta_dot e + C_n^b w_ie^n
    w_dot      = theta_ddot e - w_nb^b x (C_n^b w_ie^n)        (d/dt C_n^b = -[w_nb^b]x C_n^b)

Rate profiles (per move, angle Theta, peak rate w_max):

* ``smooth``: ``w = w_max (1 - cos(pi s / T_a)) / 2`` for ``0 <= s <= T_a`` (angular acceleration
  continuous), cruise at ``w_max``, symmetric deceleration; the acceleration phase turns
  ``w_max T_a / 2``.
* ``trapezoid``: constant ``accel`` up to ``w_max`` (``T_a = w_max / accel``), cruise, constant
  deceleration.

Sensors (PSINS forms)
---------------------
Accelerometer i sits at ``p_i`` (row i of ``lever``, body axes, from the IMU centre)::

    f_lev,i = e_i . (f^b + w_dot x p_i + w x (w x p_i)),     f^b = C_n^b f^n
    gyro:   w_meas = Kg w + eb + Gs f^b                     Kg = I + dKg (full 3x3)
    accel:  f_meas = Ka f' + Ka2 * f'**2 + db               Ka = I + dKa (lower triangular), Ka2 elementwise
            f' = f_lev - tau (w x f_lev)                    asynchrony="psins" (first order, as PSINS)
            f' = f_lev(t - tau), every accelerometer quantity at t - tau     asynchrony="delay" (exact)

The PSINS form is the first-order expansion of sampling the accelerometers tau EARLY (at t + tau):
``f^b(t + tau) = f^b - tau w_nb^b x f^b + O(tau^2)``; it uses ``w_ib`` where the kinematics have
``w_nb``, so it differs from the exact advance by ``-tau (C_n^b w_ie^n) x f^b`` (a force fixed in n,
``tau g W cos L`` ~ 0.06 ug East for 1 ms), by O(tau^2), and by the advance of the lever-arm terms,
``tau d/dt (w_dot x p_i + w x (w x p_i))``, which it leaves out (a few ug in the ramps of the smooth
profile; at the w_dot steps of a trapezoidal profile, ``tau accel |p|`` of velocity in one sample).

Increments: ``dtheta_k = int w_meas``, ``dv_k = int f_meas`` over ``[t_{k-1}, t_k]`` (``t_k = k / rate``),
by Gauss-Legendre quadrature on every piece of the interval between the breakpoints of the
motion (move start, end of acceleration, start of deceleration, move end; shifted by tau for the
delayed accelerometer windows), so the quadrature is exact to round-off on the piecewise-smooth
motion; a piece inside a dwell, where the integrand is constant, is its length times one value.
Each window has the length ``1/rate`` exactly and node times are kept as (window start, offset),
so the rounding of absolute time (1e-13 s at 1000 s) enters neither.
"""

import math
from dataclasses import dataclass, field, replace

import numpy as np

#: Earth rotation rate [rad/s]
EARTH_RATE = 7.292115e-5
DEG = math.pi / 180.0

# --------------------------------------------------------------------------------------- gravity
# WGS-84 (NIMA TR8350.2, Tables 3.1-3.3)
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_GM = 3.986004418e14
WGS84_GAMMA_E = 9.7803253359
WGS84_GAMMA_P = 9.8321849378

# PSINS toolbox (glvf.m defaults: Re, f, wie; g0)
PSINS_RE = 6378137.0
PSINS_F = 1.0 / 298.257
PSINS_WIE = 7.2921151467e-5
PSINS_G0 = 9.7803267715
#: PSINS's micro-g (glv.ug = 1e-6 g0)
PSINS_UG = 1e-6 * PSINS_G0


def wgs84_gravity(lat: float, h: float = 0.0) -> float:
    """WGS-84 normal gravity [m/s^2]: Somigliana on the ellipsoid (TR8350.2 eq. 4-1)::

        g0 = g_e (1 + k sin^2 L) / sqrt(1 - e^2 sin^2 L),   k = b g_p / (a g_e) - 1

    and the second-order free-air height term (TR8350.2 eq. 4-3)::

        g = g0 [1 - 2/a (1 + f + m - 2 f sin^2 L) h + 3 h^2 / a^2],   m = W^2 a^2 b / GM
    """
    a, f = WGS84_A, WGS84_F
    b = a * (1.0 - f)
    e2 = f * (2.0 - f)
    k = b * WGS84_GAMMA_P / (a * WGS84_GAMMA_E) - 1.0
    m = EARTH_RATE**2 * a * a * b / WGS84_GM
    s2 = math.sin(lat) ** 2
    g0 = WGS84_GAMMA_E * (1.0 + k * s2) / math.sqrt(1.0 - e2 * s2)
    return g0 * (1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * h + 3.0 * h * h / (a * a))


def psins_gravity(lat: float, h: float = 0.0) -> float:
    """Gravity [m/s^2] of the current PSINS toolbox (glvf.m and earth.m)::

        m = Re wie^2 / g0,  beta = 5/2 m - f - 17/14 m f,  beta1 = (5 m f - f^2) / 8
        gL = g0 (1 + beta sin^2 L - beta1 sin^2 2L),  hR = h / (Re (1 - f sin^2 L))
        g  = gL (1 - 2 hR - 5 hR^2)

    with g0 = 9.7803267715, Re = 6378137, f = 1/298.257, wie = 7.2921151467e-5."""
    m = PSINS_RE * PSINS_WIE**2 / PSINS_G0
    beta = 2.5 * m - PSINS_F - 17.0 / 14.0 * m * PSINS_F
    beta1 = (5.0 * m * PSINS_F - PSINS_F**2) / 8.0
    sl2 = math.sin(lat) ** 2
    s2l2 = math.sin(2.0 * lat) ** 2
    gl = PSINS_G0 * (1.0 + beta * sl2 - beta1 * s2l2)
    hr = h / (PSINS_RE * (1.0 - PSINS_F * sl2))
    return gl * (1.0 - 2.0 * hr - 5.0 * hr * hr)


def psins_gravity_legacy(lat: float, h: float = 0.0) -> float:
    """The older PSINS formula (still in its error-matrix code)::

        g = 9.7803267714 (1 + 5.27094e-3 sin^2 L + 2.32718e-5 sin^4 L) - 3.086e-6 h"""
    s2 = math.sin(lat) ** 2
    return 9.7803267714 * (1.0 + 5.27094e-3 * s2 + 2.32718e-5 * s2 * s2) - 3.086e-6 * h


GRAVITY_FORMULAS = {"wgs84": wgs84_gravity, "psins": psins_gravity, "psins-legacy": psins_gravity_legacy}


@dataclass(frozen=True)
class Site:
    """A static site: latitude, longitude [rad], height [m]; ``gravity`` one of
    :data:`GRAVITY_FORMULAS` or a value in m/s^2."""

    lat: float
    lon: float = 0.0
    height: float = 0.0
    gravity: str | float = "wgs84"

    @property
    def g(self) -> float:
        if isinstance(self.gravity, str):
            return float(GRAVITY_FORMULAS[self.gravity](self.lat, self.height))
        return float(self.gravity)

    @property
    def w_ie_n(self) -> np.ndarray:
        """``[0, W cos L, W sin L]``."""
        return np.array([0.0, EARTH_RATE * math.cos(self.lat), EARTH_RATE * math.sin(self.lat)])

    @property
    def f_n(self) -> np.ndarray:
        """``[0, 0, g]``."""
        return np.array([0.0, 0.0, self.g])


# --------------------------------------------------------------------------------------- rotations
def skew(v) -> np.ndarray:
    """[v]x with [v]x u = v x u."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rot(axis: int, angle) -> np.ndarray:
    """Rot(e_axis, angle) (..., 3, 3), right-handed: ``I + sin a K + (1 - cos a) K^2``,
    ``K = [e_axis]x``; ``1 - cos a`` as ``2 sin^2(a/2)`` (no cancellation)."""
    a = np.asarray(angle, dtype=float)
    K = skew(np.eye(3)[axis])
    s = np.sin(a)[..., None, None]
    c1 = (2.0 * np.sin(0.5 * a) ** 2)[..., None, None]
    return np.eye(3) + s * K + c1 * (K @ K)


def rot_exact(axis: int, angle: float) -> np.ndarray:
    """Rot(e_axis, angle) with entries rounded to integers when ``angle`` is a multiple of 90 deg."""
    R = rot(axis, angle)
    q = angle / (0.5 * math.pi)
    return np.round(R) if abs(q - round(q)) < 1e-12 else R


# --------------------------------------------------------------------------------------- profiles
@dataclass(frozen=True)
class RateProfile:
    """Rate profile of one move.  ``kind="smooth"``: ``w = w_max (1 - cos(pi s / t_acc)) / 2``
    over ``t_acc``; ``kind="trapezoid"``: constant ``accel`` [rad/s^2] to ``w_max`` [rad/s]."""

    kind: str = "smooth"
    w_max: float = 10.0 * DEG
    t_acc: float = 1.0
    accel: float = 50.0 * DEG

    def __post_init__(self):
        if self.kind not in ("smooth", "trapezoid"):
            raise ValueError(f"profile kind must be smooth or trapezoid, got {self.kind!r}")

    @property
    def ramp_time(self) -> float:
        """Duration of the acceleration (and of the deceleration) [s]."""
        return self.t_acc if self.kind == "smooth" else self.w_max / self.accel

    @property
    def ramp_angle(self) -> float:
        """Angle turned while accelerating: ``w_max T_a / 2`` for both kinds."""
        return 0.5 * self.w_max * self.ramp_time

    def duration(self, angle: float) -> float:
        """Move duration for ``|angle|``: ``2 T_a + (|angle| - 2 ramp_angle) / w_max``."""
        cruise = (abs(angle) - 2.0 * self.ramp_angle) / self.w_max
        if cruise < -1e-12:
            raise ValueError("move too short for the profile's ramps")
        return 2.0 * self.ramp_time + max(cruise, 0.0)

    def _ramp(self, s):
        """(angle, rate, acceleration) at time ``s`` into the acceleration ramp."""
        Ta, wm = self.ramp_time, self.w_max
        if self.kind == "smooth":
            x = math.pi / Ta * s
            return 0.5 * wm * (s - Ta / math.pi * np.sin(x)), wm * np.sin(0.5 * x) ** 2, 0.5 * wm * math.pi / Ta * np.sin(x)
        a = self.accel
        return 0.5 * a * s * s, a * s, np.full_like(s, a)

    def evaluate(self, s, angle: float):
        """(theta, theta_dot, theta_ddot) at times ``s`` (array) from the move start, for a move
        of ``|angle|`` (signs are applied by the caller)."""
        s = np.asarray(s, dtype=float)
        T, Ta, wm = self.duration(angle), self.ramp_time, self.w_max
        th_r, w_r, a_r = self._ramp(np.clip(s, 0.0, Ta))
        r = np.clip(T - s, 0.0, Ta)
        th_d, w_d, a_d = self._ramp(r)
        up, down = s < Ta, s > T - Ta
        theta = np.where(up, th_r, np.where(down, abs(angle) - th_d, self.ramp_angle + wm * (s - Ta)))
        rate = np.where(up, w_r, np.where(down, w_d, wm))
        acc = np.where(up, a_r, np.where(down, -a_d, 0.0))
        return theta, rate, acc


# --------------------------------------------------------------------------------------- sequences
#: the 18 turns of the 19-position PSINS-style sequence, as (body axis, sign)
PSINS19_TURNS = ((0, +1), (0, +1), (0, +1), (2, -1), (2, -1), (0, -1), (0, -1), (0, -1), (2, +1),
                 (1, -1), (1, -1), (1, -1), (2, +1), (2, +1), (1, +1), (1, +1), (1, +1), (2, -1))
#: dwell at the first position, then after each turn [s]
PSINS19_DWELLS = (90.0, 30.0, 20.0, 60.0, 20.0, 30.0, 90.0, 20.0, 60.0, 30.0,
                  20.0, 90.0, 30.0, 20.0, 60.0, 30.0, 20.0, 60.0, 90.0)
#: the 19 attitudes: the letters of IMU x, y, z in ENU
PSINS19_ATTITUDES = ("ENU", "EUS", "ESD", "EDN", "UEN", "WUN", "WSU", "WDS", "WND", "NED",
                     "DES", "SEU", "UEN", "EDN", "DWN", "SWD", "UWS", "NWU", "ENU")


@dataclass(frozen=True)
class Move:
    """A turn by ``angle`` [rad, signed] about body axis ``axis`` (0, 1, 2), then a dwell [s]."""

    axis: int
    angle: float
    dwell: float


@dataclass(frozen=True)
class Sequence:
    """An initial dwell at ``C0`` (C_b^n) and a series of moves, all with one rate profile."""

    moves: tuple[Move, ...]
    initial_dwell: float
    profile: RateProfile = field(default_factory=RateProfile)
    C0: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def move_starts(self) -> np.ndarray:
        t, out = self.initial_dwell, []
        for m in self.moves:
            out.append(t)
            t += self.profile.duration(m.angle) + m.dwell
        return np.array(out)

    @property
    def duration(self) -> float:
        return self.initial_dwell + sum(self.profile.duration(m.angle) + m.dwell for m in self.moves)

    @property
    def attitudes(self) -> np.ndarray:
        """C_b^n at the start (index 0) and after each move (n_moves + 1, 3, 3), exact for 90-deg turns."""
        C = [np.asarray(self.C0, dtype=float)]
        for m in self.moves:
            C.append(C[-1] @ rot_exact(m.axis, m.angle))
        return np.array(C)

    @property
    def breakpoints(self) -> np.ndarray:
        """Move start, end of acceleration, start of deceleration, move end for every move."""
        Ta = self.profile.ramp_time
        out = []
        for t0, m in zip(self.move_starts, self.moves):
            T = self.profile.duration(m.angle)
            out += [t0, t0 + Ta, t0 + T - Ta, t0 + T]
        return np.array(out)

    def is_static(self, t, u=None):
        """True at the times ``t + u`` that are in a dwell (before, between or after the moves)."""
        t = np.asarray(t, dtype=float)
        tt = t if u is None else t + u
        if not self.moves:
            return np.ones(tt.shape, dtype=bool)
        starts = self.move_starts
        m = np.searchsorted(starts, tt, side="right") - 1
        T = np.array([self.profile.duration(mv.angle) for mv in self.moves])
        return (m < 0) | ((tt - starts[np.maximum(m, 0)]) >= T[np.maximum(m, 0)])

    def kinematics(self, t, u=None):
        """``(C_b^n (n,3,3), w_nb^b (n,3), dw_nb^b/dt (n,3))`` at times ``t + u`` (n,); static at ``C0``
        before the first move and at the last attitude after the last.  ``u`` (default 0): small
        offsets from base times ``t``; the time into a move is ``(t - t_m) + u`` (the base times'
        difference is exact nearby), which keeps the round-off of the absolute time (1e-13 s at
        1000 s) out of the offsets."""
        t = np.asarray(t, dtype=float)
        u = np.zeros_like(t) if u is None else np.asarray(u, dtype=float)
        tt = t + u
        starts = self.move_starts
        Cs = self.attitudes
        n = t.shape[0]
        C = np.empty((n, 3, 3))
        w = np.zeros((n, 3))
        a = np.zeros((n, 3))
        m = np.searchsorted(starts, tt, side="right") - 1
        C[m < 0] = Cs[0]
        for j, mv in enumerate(self.moves):
            sel = np.flatnonzero(m == j)
            if sel.size == 0:
                continue
            s = (t[sel] - starts[j]) + u[sel]
            T = self.profile.duration(mv.angle)
            moving = s < T
            C[sel[~moving]] = Cs[j + 1]
            idx, s = sel[moving], s[moving]
            th, th_d, th_dd = self.profile.evaluate(s, mv.angle)
            sg = math.copysign(1.0, mv.angle)
            C[idx] = Cs[j] @ rot(mv.axis, sg * th)
            w[idx, mv.axis] = sg * th_d
            a[idx, mv.axis] = sg * th_dd
        return C, w, a


def psins19(profile: RateProfile | None = None, dwells=PSINS19_DWELLS) -> Sequence:
    """The 19-position PSINS-style sequence: 18 turns of 90 deg (:data:`PSINS19_TURNS`), dwells
    :data:`PSINS19_DWELLS`; default profile smooth, 10 deg/s, T_a = 1 s (10 s per turn, 1050 s)."""
    moves = tuple(Move(ax, sg * 0.5 * math.pi, float(d)) for (ax, sg), d in zip(PSINS19_TURNS, dwells[1:]))
    return Sequence(moves, float(dwells[0]), profile or RateProfile())


def attitude_letters(C) -> str:
    """The ENU letters of the columns (IMU x, y, z) of a C_b^n made of +-1 and 0."""
    names = {(0, 1): "E", (0, -1): "W", (1, 1): "N", (1, -1): "S", (2, 1): "U", (2, -1): "D"}
    out = ""
    for j in range(3):
        i = int(np.argmax(np.abs(C[:, j])))
        out += names[(i, int(np.sign(C[i, j])))]
    return out


# --------------------------------------------------------------------------------------- errors
@dataclass(frozen=True)
class PsinsErrors:
    """Sensor errors in PSINS conventions (SI):

    ``w_meas = (I + dKg) w + eb + Gs f^b``;  ``f_meas = (I + dKa) f' + Ka2 * f'**2 + db``,
    ``dKa`` lower triangular, ``lever`` rows = accelerometer positions p_i [m], ``tau`` [s] with
    ``asynchrony`` ``"psins"`` (``f' = f_lev - tau w x f_lev``) or ``"delay"`` (``f' = f_lev(t - tau)``).
    """

    dKg: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    eb: np.ndarray = field(default_factory=lambda: np.zeros(3))
    Gs: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    dKa: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    db: np.ndarray = field(default_factory=lambda: np.zeros(3))
    Ka2: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lever: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    tau: float = 0.0
    asynchrony: str = "psins"

    def __post_init__(self):
        for name, shape in (("dKg", (3, 3)), ("eb", (3,)), ("Gs", (3, 3)), ("dKa", (3, 3)), ("db", (3,)),
                            ("Ka2", (3,)), ("lever", (3, 3))):
            a = np.array(getattr(self, name), dtype=float)
            if a.shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if np.any(np.triu(self.dKa, 1)):
            raise ValueError("dKa must be lower triangular (PSINS convention)")
        if self.asynchrony not in ("psins", "delay"):
            raise ValueError(f"asynchrony must be psins or delay, got {self.asynchrony!r}")
        object.__setattr__(self, "tau", float(self.tau))

    @property
    def Kg(self) -> np.ndarray:
        return np.eye(3) + self.dKg

    @property
    def Ka(self) -> np.ndarray:
        return np.eye(3) + self.dKa

    @property
    def convention(self) -> str:
        tau = {"psins": "f' = f_lev - tau w_ib x f_lev (PSINS first order: accelerometers sampled tau early)",
               "delay": "f' = f_lev(t - tau) (accelerometers lag by tau, exact)"}[self.asynchrony]
        return ("PSINS: w_meas = (I+dKg) w + eb + Gs f; f_meas = (I+dKa) f' + Ka2 f'^2 + db, dKa lower "
                f"triangular, f_lev_i = e_i.(f + wdot x p_i + w x (w x p_i)); {tau}")

    def replace(self, **kw) -> "PsinsErrors":
        return replace(self, **kw)


def psins_truth(rng: np.random.Generator, tau: float = 1e-3, asynchrony: str = "psins",
                g_sensitivity_dphpg: float = 0.0) -> PsinsErrors:
    """A navigation-grade error set drawn from ``rng`` (magnitudes uniform in the ranges, random sign):

    gyro scale factors 50-300 ppm, gyro misalignments (off-diagonal dKg) 10-60 arcsec (50-300 ppm),
    gyro bias 0.01-0.05 deg/h; accelerometer scale factors 100-500 ppm, lower misalignments
    0.5e-4-2e-4 rad, bias 50-300 ug, Ka2 5-50 ug/g^2, lever arms 0.5-5 cm (all nine), ``tau``;
    ``Gs`` zero unless ``g_sensitivity_dphpg`` > 0 (then entries up to that many deg/h/g).
    ug = 1e-6 g0 and ug/g^2 = ug / g0^2 with PSINS's g0."""

    def draw(lo, hi, shape):
        return rng.uniform(lo, hi, shape) * rng.choice([-1.0, 1.0], shape)

    arcsec = DEG / 3600.0
    dph = DEG / 3600.0
    dKg = draw(10.0, 60.0, (3, 3)) * arcsec
    dKg[np.diag_indices(3)] = draw(50.0, 300.0, 3) * 1e-6
    eb = draw(0.01, 0.05, 3) * dph
    Gs = draw(0.0, g_sensitivity_dphpg, (3, 3)) * dph / PSINS_G0 if g_sensitivity_dphpg > 0 else np.zeros((3, 3))
    dKa = np.tril(draw(0.5e-4, 2e-4, (3, 3)), -1)
    dKa[np.diag_indices(3)] = draw(100.0, 500.0, 3) * 1e-6
    db = draw(50.0, 300.0, 3) * PSINS_UG
    Ka2 = draw(5.0, 50.0, 3) * PSINS_UG / PSINS_G0**2
    lever = draw(0.005, 0.05, (3, 3))
    return PsinsErrors(dKg=dKg, eb=eb, Gs=Gs, dKa=dKa, db=db, Ka2=Ka2, lever=lever, tau=tau, asynchrony=asynchrony)


# --------------------------------------------------------------------------------------- sensors
def cross(a, b) -> np.ndarray:
    """Row-wise a x b for (n, 3) arrays (b may be one 3-vector)."""
    a, b = np.asarray(a), np.broadcast_to(b, np.shape(a))
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def apply(M, x) -> np.ndarray:
    """Rows ``M x_k`` of (n, 3) ``x``."""
    return (np.asarray(M) @ np.asarray(x).T).T


def body_motion(seq: Sequence, site: Site, t, u=None):
    """``(C_b^n, w_nb^b, w = w_ib^b, w_dot, f^b)`` at times ``t + u`` (see the module docstring and
    :meth:`Sequence.kinematics`)."""
    C, w_nb, a_nb = seq.kinematics(t, u)
    wie_b = np.einsum("nji,j->ni", C, site.w_ie_n)  # C_n^b w_ie^n
    w = w_nb + wie_b
    wdot = a_nb - cross(w_nb, wie_b)
    f_b = np.einsum("nji,j->ni", C, site.f_n)
    return C, w_nb, w, wdot, f_b


def lever_force(f_b, w, wdot, lever) -> np.ndarray:
    """``f_lev,i = e_i . (f^b + w_dot x p_i + w x (w x p_i))``, ``p_i = lever[i]``."""
    out = np.array(f_b, dtype=float, copy=True)
    for i in range(3):
        p = np.broadcast_to(lever[i], w.shape)
        out[:, i] += cross(wdot, p)[:, i] + cross(w, cross(w, p))[:, i]
    return out


def gyro_output(err: PsinsErrors, w, f_b) -> np.ndarray:
    """``Kg w + eb + Gs f^b``."""
    return apply(err.Kg, w) + err.eb + apply(err.Gs, f_b)


def accel_output(err: PsinsErrors, f_lev, w, psins_tau: float) -> np.ndarray:
    """``Ka f' + Ka2 f'^2 + db`` with ``f' = f_lev - psins_tau w x f_lev``."""
    f = f_lev - psins_tau * cross(w, f_lev) if psins_tau else f_lev
    return apply(err.Ka, f) + err.Ka2 * f * f + err.db


# --------------------------------------------------------------------------------------- quadrature
def _pieces(n: int, rate: float, shift: float, breaks):
    """Pieces of the windows ``[k/rate - shift, (k+1)/rate - shift]`` (k = 0..n-1) cut at
    ``breaks``: ``(owner, u0, u1)`` in local window time (each window starts at u = 0 and ends
    at u = dt exactly, so a window without a cut integrates over exactly dt)."""
    dt = 1.0 / rate
    b = np.asarray(breaks, dtype=float) + shift
    k = np.floor(b * rate).astype(np.int64)
    u = b - k / rate
    ok = (k >= 0) & (k < n) & (u > 1e-9 * dt) & (u < (1.0 - 1e-9) * dt)
    owner = np.concatenate([np.arange(n, dtype=np.int64), k[ok]])
    left = np.concatenate([np.zeros(n), u[ok]])
    order = np.lexsort((left, owner))
    owner, left = owner[order], left[order]
    right = np.empty_like(left)
    right[:-1] = left[1:]
    last = np.ones(owner.shape[0], dtype=bool)
    last[:-1] = owner[1:] != owner[:-1]
    right[last] = dt
    return owner, left, right


def integrate(fun, n: int, rate: float, shift: float, breaks, order: int = 6, static=None) -> list[np.ndarray]:
    """``[int_{w_k} fun(t)_j dt]`` over the windows ``w_k = [k/rate - shift, (k+1)/rate - shift]``
    by ``order``-point Gauss-Legendre on every piece between ``breaks``; ``fun(t, u)`` returns a
    list of (m, 3) arrays at the times ``t + u`` (``t`` the window starts, ``u`` the nodes' offsets in
    their window), each integrated (one list entry per output).  ``static(t, u)`` (optional): True
    where the integrand is constant on the whole piece around ``t + u`` (a dwell: pieces never
    straddle a breakpoint); such a piece is ``h fun(midpoint)``, exactly."""
    x, wgl = np.polynomial.legendre.leggauss(order)
    owner, u0, u1 = _pieces(n, rate, shift, breaks)
    h = u1 - u0
    tb = owner / rate - shift
    um = u0 + 0.5 * h
    const = np.zeros(owner.size, dtype=bool) if static is None else np.asarray(static(tb, um), dtype=bool)
    mv = ~const
    u = u0[mv, None] + (0.5 * h[mv])[:, None] * (1.0 + x)[None, :]
    wts = (0.5 * h[mv])[:, None] * wgl[None, :]
    t_all = np.concatenate([np.repeat(tb[mv], order), tb[const]])
    u_all = np.concatenate([u.ravel(), um[const]])
    nm = u.size
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    out = []
    for vals in fun(t_all, u_all):
        v = np.empty((owner.size, 3))
        v[mv] = np.einsum("pg,pgj->pj", wts, vals[:nm].reshape(u.shape + (3,)))
        v[const] = h[const, None] * vals[nm:]
        out.append(np.add.reduceat(v, starts, axis=0))
    return out


# --------------------------------------------------------------------------------------- generator
@dataclass(frozen=True)
class ImuRecord:
    """Generated increments and what produced them (SI).  ``time`` = end of each interval."""

    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    rate_hz: float
    lat: float
    lon: float
    height: float
    gravity: float
    gravity_model: str | float
    C_bn_end: np.ndarray
    truth: PsinsErrors
    sequence: Sequence
    arw: float | np.ndarray = 0.0
    vrw: float | np.ndarray = 0.0

    @property
    def convention(self) -> str:
        return self.truth.convention

    @property
    def site(self) -> Site:
        return Site(self.lat, self.lon, self.height, self.gravity_model)


def _quantize(x: np.ndarray, q: float) -> np.ndarray:
    """Running-sum rounding to counts of ``q``: ``round(cumsum(x) / q)`` differenced, times ``q``."""
    c = np.round(np.cumsum(x, axis=0) / q)
    return np.diff(c, axis=0, prepend=np.zeros((1, x.shape[1]))) * q


def generate(seq: Sequence, site: Site, errors: PsinsErrors | None = None, rate_hz: float = 100.0, *,
             arw: float = 0.0, vrw: float = 0.0, rng: np.random.Generator | None = None,
             dtype: str | None = None, quantum: tuple[float, float] | None = None, order: int = 6) -> ImuRecord:
    """Increments of ``seq`` at ``site`` with ``errors`` (default none).

    ``dtheta_k = int w_meas dt``, ``dv_k = int f_meas dt`` over ``[t_{k-1}, t_k]`` (``t_k = k / rate_hz``,
    k = 1..N, N = round(duration * rate)); white noise ``arw`` [rad/sqrt(s)], ``vrw`` [m/s/sqrt(s)]
    from ``rng`` (gyro draws first, then accelerometer); then ``dtype="float32"`` rounding of every
    increment or ``quantum=(q_gyro, q_accel)`` integer counts by running-sum rounding."""
    err = errors if errors is not None else PsinsErrors()
    n = round(seq.duration * rate_hz)
    if abs(n - seq.duration * rate_hz) > 1e-6:
        raise ValueError(f"duration {seq.duration} s is not a whole number of samples at {rate_hz} Hz")
    breaks = seq.breakpoints
    delay = err.asynchrony == "delay" and err.tau != 0.0
    psins_tau = err.tau if err.asynchrony == "psins" else 0.0

    def both(t, u):
        _, _, w, wdot, f_b = body_motion(seq, site, t, u)
        out = [gyro_output(err, w, f_b)]
        if not delay:
            out.append(accel_output(err, lever_force(f_b, w, wdot, err.lever), w, psins_tau))
        return out

    def accel_only(t, u):
        _, _, w, wdot, f_b = body_motion(seq, site, t, u)
        return [accel_output(err, lever_force(f_b, w, wdot, err.lever), w, 0.0)]

    res = integrate(both, n, rate_hz, 0.0, breaks, order, seq.is_static)
    dth = res[0]
    dv = integrate(accel_only, n, rate_hz, err.tau, breaks, order, seq.is_static)[0] if delay else res[1]
    dt = 1.0 / rate_hz
    if np.any(arw) or np.any(vrw):
        if rng is None:
            raise ValueError("noise needs a numpy.random.Generator (rng)")
        dth = dth + arw * math.sqrt(dt) * rng.standard_normal(dth.shape)
        dv = dv + vrw * math.sqrt(dt) * rng.standard_normal(dv.shape)
    if dtype is not None and quantum is not None:
        raise ValueError("give dtype or quantum, not both")
    if dtype is not None:
        dth = dth.astype(dtype).astype(np.float64)
        dv = dv.astype(dtype).astype(np.float64)
    if quantum is not None:
        dth, dv = _quantize(dth, quantum[0]), _quantize(dv, quantum[1])
    time = np.arange(1, n + 1) / rate_hz
    C_end = seq.kinematics(np.array([time[-1]]))[0][0]
    return ImuRecord(time=time, dtheta=dth, dvel=dv, rate_hz=float(rate_hz), lat=site.lat, lon=site.lon,
                     height=site.height, gravity=site.g, gravity_model=site.gravity, C_bn_end=C_end, truth=err,
                     sequence=seq, arw=np.asarray(arw, dtype=float), vrw=np.asarray(vrw, dtype=float))
