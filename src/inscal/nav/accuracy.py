"""Navigation errors against the truth, and their Schuler, Foucault and Earth-rate oscillations."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from inscal.core import earth
from inscal.core.attitude import dcm_from_euler, euler_from_dcm
from inscal.core.error_model import GimbalErrors
from inscal.core.kinematics import true_attitude
from inscal.nav.frames import attitude_error
from inscal.nav.strapdown import NavOutput

DAY = 86400.0


# ============================================================================ truth and errors
@dataclass
class NavErrors:
    """Errors of a navigation output against a static-site truth (SI).

    Without a simulation truth (recorded data) only the position and velocity errors are known (the
    site is static and surveyed); ``attitude`` and ``vehicle`` are then None.

    Parameters
    ----------
    time : numpy.ndarray
        (N,) output times [s].
    attitude : numpy.ndarray or None
        (N, 3) IMU attitude error phi in the n-frame [rad].
    vehicle : numpy.ndarray or None
        (N, 3) vehicle [roll, pitch, yaw] error [rad].
    velocity : numpy.ndarray
        (N, 3) velocity error, East, North, Up [m/s].
    position : numpy.ndarray
        (N, 3) position error, East, North, Up [m].

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import NavErrors
    >>> err = NavErrors(np.array([0.0, 1.0]), None, None, np.zeros((2, 3)), np.array([[0, 0, 0], [3.0, 4.0, 1.0]]))
    >>> err.horizontal.tolist()
    [0.0, 5.0]
    """

    time: np.ndarray
    attitude: np.ndarray | None  # IMU attitude error phi, n-frame (N, 3) [rad]
    vehicle: np.ndarray | None  # vehicle [roll, pitch, yaw] error (N, 3) [rad]
    velocity: np.ndarray  # (N, 3) [m/s]
    position: np.ndarray  # East, North, Up (N, 3) [m]

    @property
    def horizontal(self) -> np.ndarray:
        """The horizontal position error [m] at each output time."""
        return np.hypot(self.position[:, 0], self.position[:, 1])


def _wrap(a):
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def navigation_errors(out: NavOutput, scenario=None, gimbal_model: GimbalErrors | None = None,
                      site=None) -> NavErrors:
    """Errors of a navigation output against the truth of a static site.

    With a simulated ``scenario``: the site position, zero velocity, the true IMU attitude
    (:func:`inscal.core.kinematics.true_attitude`) and the true vehicle attitude (the gimbal mount
    attitude, N25 eq. 8).  With only a ``site`` (recorded data on a static base): position and velocity
    errors.

    Parameters
    ----------
    out : NavOutput
        The navigation output (:attr:`NavResult.output <inscal.nav.run.NavResult>`).
    scenario : Scenario, optional
        The simulated scenario whose truth to compare with.
    gimbal_model : GimbalErrors, optional
        The gimbal model for the vehicle attitude from the gimbal angles.
    site : Site, optional
        The static site, when there is no scenario.

    Returns
    -------
    NavErrors
        The errors at each output time (estimate minus truth).

    Raises
    ------
    ValueError
        Neither a scenario nor a site.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.nav import navigation_errors
    >>> from inscal.nav.strapdown import NavOutput
    >>> site = Site(np.radians(45.0))
    >>> q = np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))
    >>> pos = np.array([[site.latitude, 0.0, 0.0], [site.latitude + 1e-6, 0.0, 0.0]])
    >>> out = NavOutput(np.array([0, 5999]), np.array([0.0, 60.0]), q, np.zeros((2, 3)), pos)
    >>> err = navigation_errors(out, site=site)
    >>> np.round(err.position[1], 2).tolist()  # 1e-6 rad of latitude is about 6.4 m North
    [0.0, 6.37, 0.0]
    """

    if scenario is not None:
        site = scenario.site
        C_true = true_attitude(scenario, out.time)
        phi = attitude_error(np.ascontiguousarray(out.quaternion, dtype=np.float64), C_true)  # small_angle_error
        if out.gimbal is not None:
            veh_true = euler_from_dcm(dcm_from_euler(scenario.gimbal.mount_attitude))
        else:  # no gimbal angles recorded: compare the IMU attitude's Euler angles
            veh_true = euler_from_dcm(C_true)
        veh = _wrap(out.vehicle_attitude(gimbal_model) - veh_true)
    elif site is None:
        raise ValueError("navigation errors need a scenario (truth) or at least the static site")
    else:
        phi = veh = None
    rm, rn = earth.radii(site.latitude)
    pos = np.stack([
        _wrap(out.position[:, 1] - site.longitude) * (rn + site.height) * math.cos(site.latitude),
        (out.position[:, 0] - site.latitude) * (rm + site.height),
        out.position[:, 2] - site.height,
    ], axis=-1)
    return NavErrors(out.time.copy(), phi, veh, out.velocity.copy(), pos)


# ----------------------------------------------------------------------- oscillations
def schuler_frequency(lat: float, h: float = 0.0) -> float:
    """The Schuler frequency ``w_s = sqrt(g / R)`` [rad/s], R the geometric mean radius (T&W ch. 12).

    Parameters
    ----------
    lat : float
        Latitude [rad].
    h : float
        Height [m].

    Returns
    -------
    float
        ``w_s`` [rad/s] (period about 84.4 min at the equator).

    Examples
    --------
    >>> import math
    >>> from inscal.nav import schuler_frequency
    >>> round(2 * math.pi / schuler_frequency(math.radians(45.0)) / 60.0, 1)  # minutes
    84.5
    """
    return 2.0 * math.pi / earth.schuler_period(lat, h)


def foucault_frequency(lat: float) -> float:
    """The Foucault frequency ``OMEGA_IE |sin L|`` [rad/s].

    Parameters
    ----------
    lat : float
        Latitude L [rad].

    Returns
    -------
    float
        The frequency [rad/s] (zero at the equator).

    Examples
    --------
    >>> import math
    >>> from inscal.nav import foucault_frequency
    >>> round(2 * math.pi / foucault_frequency(math.radians(30.0)) / 3600.0, 2)  # hours
    47.87
    """
    return earth.OMEGA_IE * abs(math.sin(lat))


def fit_oscillation(t: np.ndarray, x: np.ndarray, period_guess: float, trend: bool = True) -> dict:
    """Least-squares fit of ``x = c0 [+ c1 t] + A cos(2 pi t / P + p)`` with the period P free.

    Variable projection: the linear coefficients are solved for each P.

    Parameters
    ----------
    t : numpy.ndarray
        (N,) times [s].
    x : numpy.ndarray
        (N,) the series.
    period_guess : float
        Where the search for P starts [s].
    trend : bool
        Fit the slope ``c1`` too.

    Returns
    -------
    dict
        ``period`` [s], ``amplitude``, ``phase`` [rad], ``offset``, ``slope`` (per second) and
        ``rms_residual``, in the unit of ``x``.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import fit_oscillation
    >>> t = np.arange(0.0, 20000.0, 10.0)
    >>> fit = fit_oscillation(t, 2.0 + 3.0 * np.cos(2 * np.pi * t / 5064.0), 5000.0)
    >>> round(fit["period"], 3), round(fit["amplitude"], 6), round(fit["offset"], 6)
    (5064.0, 3.0, 2.0)
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    tc = t - t[0]
    tn = tc / max(tc[-1], 1.0)

    def design(P):
        w = 2 * math.pi / P
        cols = [np.ones_like(tc)] + ([tn] if trend else []) + [np.cos(w * tc), np.sin(w * tc)]
        return np.stack(cols, axis=-1)

    def resid(p):
        A = design(p[0])
        c, *_ = np.linalg.lstsq(A, x, rcond=None)
        return A @ c - x

    r = least_squares(resid, [period_guess], x_scale=[period_guess * 0.01], xtol=1e-14, ftol=1e-14, gtol=1e-14)
    P = float(r.x[0])
    A = design(P)
    c, *_ = np.linalg.lstsq(A, x, rcond=None)
    a, b = c[-2], c[-1]
    return {"period": P, "amplitude": float(math.hypot(a, b)), "phase": float(math.atan2(-b, a)),
            "offset": float(c[0]), "slope": float(c[1] / max(tc[-1], 1.0)) if trend else 0.0,
            "rms_residual": float(np.sqrt(np.mean((A @ c - x) ** 2)))}


def oscillation_components(t: np.ndarray, x: np.ndarray, lat: float) -> dict:
    """Amplitudes of the Schuler (84.4 min), Earth (24 h) and Foucault components of an error series.

    Linear least squares on fixed frequencies with an offset and a trend:

    * Schuler: the Schuler-band oscillation.  When the record resolves the Foucault splitting
      (duration >= one Foucault period 2 pi/(W sin L)), the band is modelled as the two lines
      ``w_s +- w_F`` with amplitudes A+ and A-; ``schuler`` = A+ + A- (the peak of the envelope) and
      ``foucault`` = min(A+, A-) (half the envelope's peak-to-peak modulation over a Foucault period).
      Otherwise one line at w_s and ``foucault`` = None.  Needs at least one Schuler period.
    * Earth: the line at W (needs >= 24 h, else None).

    Parameters
    ----------
    t : numpy.ndarray
        (N,) times [s].
    x : numpy.ndarray
        (N,) an error series (a position or velocity component, an attitude angle).
    lat : float
        Latitude [rad] (the Schuler and Foucault frequencies).

    Returns
    -------
    dict
        ``schuler``, ``foucault``, ``earth`` (amplitudes in the unit of ``x``, None where the span
        does not resolve them), ``trend`` (per second) and ``duration`` [s].

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import oscillation_components, schuler_frequency
    >>> lat = np.radians(45.0)
    >>> t = np.arange(0.0, 3 * 3600.0, 10.0)
    >>> c = oscillation_components(t, 50.0 * np.sin(schuler_frequency(lat) * t), lat)
    >>> round(c["schuler"], 6), c["foucault"], c["earth"]
    (50.0, None, None)
    """
    return oscillation_components_of(t, np.asarray(x, dtype=float)[:, None], lat)[0]


def oscillation_components_of(t: np.ndarray, xs: np.ndarray, lat: float) -> list[dict]:
    """:func:`oscillation_components` of each column of ``xs`` (N, m): one design matrix and one
    least-squares solve for all of them, through the normal equations (a few columns of lines that
    the span resolves: the Gram matrix is well conditioned; its pseudo-inverse for the rest)."""
    t = np.asarray(t, dtype=float)
    xs = np.asarray(xs, dtype=float)
    tc = t - t[0]
    T = float(tc[-1]) if tc.size else 0.0
    ws = schuler_frequency(lat)
    wf = foucault_frequency(lat)
    W = earth.OMEGA_IE
    res = [{"schuler": None, "foucault": None, "earth": None, "trend": None, "duration": T} for _ in range(xs.shape[1])]
    if T <= 0:
        return res
    names = []
    if T >= 2 * math.pi / ws:
        freqs = [ws - wf, ws + wf] if (wf > 0 and T >= 2 * math.pi / wf) else [ws]
        names += [("schuler", f) for f in freqs]
    if T >= 2 * math.pi / W:
        names.append(("earth", W))
    At = np.empty((2 + 2 * len(names), tc.size))  # the design matrix's columns as rows
    At[0] = 1.0
    np.divide(tc, T, out=At[1])
    for i, (_, f) in enumerate(names):
        np.multiply(tc, f, out=At[2 + 2 * i])
        np.sin(At[2 + 2 * i], out=At[3 + 2 * i])
        np.cos(At[2 + 2 * i], out=At[2 + 2 * i])
    cs = np.linalg.lstsq(At @ At.T, At @ xs, rcond=None)[0]
    for r, c in zip(res, cs.T):
        r["trend"] = float(c[1] / T)
        amps: dict = {}
        for i, (name, _f) in enumerate(names):
            amps.setdefault(name, []).append(float(math.hypot(c[2 + 2 * i], c[3 + 2 * i])))
        if "schuler" in amps:
            a = amps["schuler"]
            r["schuler"] = float(sum(a))
            r["foucault"] = float(min(a)) if len(a) == 2 else None
        if "earth" in amps:
            r["earth"] = amps["earth"][0]
    return res


def absmax_columns(a: np.ndarray) -> np.ndarray:
    """``np.max(np.abs(a), axis=0)`` of an (N, m) array, column by column (a reduction over the
    strided axis is some 20 times slower)."""
    return np.array([np.max(np.abs(a[:, i])) for i in range(a.shape[1])])


def summarize(err: NavErrors, lat: float) -> dict:
    """Summary figures of navigation errors (SI): maxima, final values, oscillation components.

    Parameters
    ----------
    err : NavErrors
        The errors (:func:`navigation_errors`).
    lat : float
        The site's latitude [rad] (the oscillation frequencies).

    Returns
    -------
    dict
        ``duration_s``, ``max_position_error_m`` and ``final_position_error_m`` (horizontal),
        ``max_velocity_error_mps``, ``max_velocity_error_enu_mps``, ``final_position_error_en_m``,
        ``max_attitude_error_rad`` and ``max_imu_attitude_error_rad`` (None without an attitude
        truth), and ``components``: :func:`oscillation_components` of each series.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import NavErrors, summarize
    >>> t = np.arange(0.0, 600.0, 1.0)
    >>> pos = np.zeros((600, 3))
    >>> pos[:, 0] = 0.01 * t
    >>> s = summarize(NavErrors(t, None, None, np.zeros((600, 3)), pos), np.radians(45.0))
    >>> round(s["final_position_error_m"], 2), s["max_attitude_error_rad"]
    (5.99, None)
    """
    hor = err.horizontal
    out = {
        "duration_s": float(err.time[-1] - err.time[0]) if err.time.size else 0.0,
        "max_position_error_m": float(np.max(hor)),
        "final_position_error_m": float(hor[-1]),
        "max_velocity_error_mps": float(np.max(np.hypot(err.velocity[:, 0], err.velocity[:, 1]))),
        "max_velocity_error_enu_mps": absmax_columns(err.velocity),
        "final_position_error_en_m": err.position[-1, 0:2],
        "max_attitude_error_rad": None,
        "max_imu_attitude_error_rad": None,
    }
    series = [("position_east", err.position[:, 0]), ("position_north", err.position[:, 1]),
              ("velocity_east", err.velocity[:, 0]), ("velocity_north", err.velocity[:, 1])]
    if err.vehicle is not None:
        out["max_attitude_error_rad"] = absmax_columns(err.vehicle)  # roll, pitch, yaw
        out["max_imu_attitude_error_rad"] = absmax_columns(err.attitude)  # phi E, N, U
        series += [("roll", err.vehicle[:, 0]), ("pitch", err.vehicle[:, 1]), ("yaw", err.vehicle[:, 2])]
    comps = oscillation_components_of(err.time, np.stack([x for _, x in series]).T, lat)
    out["components"] = {name: c for (name, _), c in zip(series, comps)}
    return out
