"""The linear static-navigation error model and its closed forms for constant gyro and accelerometer
biases (Schuler, Foucault and 24-h terms)."""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from inscal.core import earth


# ============================================================================ error model / closed forms
def linear_error_model(C_s_n: np.ndarray, lat: float, t: np.ndarray, gyro_bias=(0, 0, 0), accel_bias=(0, 0, 0),
                       height: float = 0.0, phi0=(0, 0, 0)) -> dict:
    """Propagate the linear phi-angle error model of a static IMU with constant biases, exactly.

    The 7-state model (attitude phi, horizontal velocity, latitude and longitude errors) of the module
    docstring, with the biases as constant forcing, propagated by its matrix exponential.

    Parameters
    ----------
    C_s_n : numpy.ndarray
        (3, 3) the static IMU attitude, s-frame to n-frame.
    lat : float
        Latitude [rad].
    t : numpy.ndarray
        (N,) uniformly spaced times [s], ``t[0] = 0``.
    gyro_bias, accel_bias : array_like
        Constant biases in the s-frame [rad/s], [m/s^2].
    height : float
        Height [m].
    phi0 : array_like
        The initial attitude error [rad].

    Returns
    -------
    dict
        ``phi`` (N, 3) [rad], ``dv`` (N, 2) East/North [m/s], ``position`` (N, 2) East/North [m].

    Examples
    --------
    An East accelerometer bias of 10 ug tilts the platform by ``b/g`` (10 urad) at the Schuler peak:

    >>> import numpy as np
    >>> from inscal.nav import linear_error_model
    >>> t = np.arange(0.0, 2600.0, 10.0)  # half a Schuler period
    >>> m = linear_error_model(np.eye(3), 0.0, t, accel_bias=(9.78e-5, 0.0, 0.0))
    >>> round(float(-m["phi"][:, 1].min()) * 1e6, 1)  # urad: 2 b/g at the half period
    20.0
    """
    rm, rn = earth.radii(lat)
    rm, rn = rm + height, rn + height
    g = earth.normal_gravity(lat, height)
    W = earth.OMEGA_IE
    sl, cl = math.sin(lat), math.cos(lat)
    wn, wu = W * cl, W * sl
    C = np.asarray(C_s_n, dtype=float)
    eps = C @ np.asarray(gyro_bias, dtype=float)
    nab = C @ np.asarray(accel_bias, dtype=float)
    # x = [phiE, phiN, phiU, dvE, dvN, dL, dlam]
    F = np.zeros((8, 8))
    F[0:3, 0:3] = -np.array([[0.0, -wu, wn], [wu, 0.0, 0.0], [-wn, 0.0, 0.0]])
    F[0, 4] = 1.0 / rm  # -dw_en
    F[1, 3] = -1.0 / rn
    F[2, 3] = -math.tan(lat) / rn
    F[1, 5] = W * sl  # -dw_ie = -W [0, -sinL, cosL] dL
    F[2, 5] = -W * cl
    F[3, 1] = g  # phi x f
    F[4, 0] = -g
    F[3, 4] = 2 * wu  # -2 w_ie x dv
    F[4, 3] = -2 * wu
    F[5, 4] = 1.0 / rm
    F[6, 3] = 1.0 / (rn * cl)
    F[0:3, 7] = eps  # constant forcing as an augmented state
    F[3:5, 7] = nab[0:2]
    t = np.asarray(t, dtype=float)
    x = np.zeros(8)
    x[0:3] = phi0
    x[7] = 1.0
    out = np.empty((t.size, 8))
    h = t[1] - t[0] if t.size > 1 else 0.0
    Phi = expm(F * h)
    for i in range(t.size):
        out[i] = x
        x = Phi @ x
    return {"phi": out[:, 0:3], "dv": out[:, 3:5],
            "position": np.stack([out[:, 6] * rn * cl, out[:, 5] * rm], axis=-1)}


def gyro_bias_closed_form(eps_n, lat: float, t) -> dict:
    """Schuler-averaged (24-hour) closed-form errors for a constant gyro bias on a static base.

    T&W ch. 12; Britting.  The level tilts are in equilibrium and terms of order (W/w_s)^2 dropped::

        p      = eps_U cos L - eps_N sin L
        dL     = (p/W)(1 - cos Wt) - (eps_E/W) sin Wt
        dlam cos L = eps_N t + sin L [p (t - sin(Wt)/W) - (eps_E/W)(1 - cos Wt)]
        phi_U  = [p sin Wt + eps_E (1 - cos Wt)] / (W cos L)

    (derived from the phi-angle model of the module docstring with phi' = 0 on the level axes).

    Parameters
    ----------
    eps_n : array_like
        The gyro bias [E, N, U] in the n-frame [rad/s].
    lat : float
        Latitude L [rad].
    t : array_like
        Times [s].

    Returns
    -------
    dict
        ``position`` (N, 2) East/North [m] (R the Gaussian mean radius) and ``phi_up`` (N,) [rad].

    Examples
    --------
    A North gyro bias of 0.01 deg/h at the equator turns the longitude at that rate: 0.24 deg,
    about 26.7 km, in a day:

    >>> import numpy as np
    >>> from inscal.nav import gyro_bias_closed_form
    >>> eps = np.radians(0.01) / 3600.0
    >>> cf = gyro_bias_closed_form([0.0, eps, 0.0], 0.0, [86400.0])
    >>> round(float(cf["position"][0, 0]) / 1000.0, 2)  # km East after a day
    26.72
    """
    eE, eN, eU = (float(v) for v in eps_n)
    W = earth.OMEGA_IE
    t = np.asarray(t, dtype=float)
    sl, cl = math.sin(lat), math.cos(lat)
    rm, rn = earth.radii(lat)
    p = eU * cl - eN * sl
    dL = p / W * (1 - np.cos(W * t)) - eE / W * np.sin(W * t)
    dlc = eN * t + sl * (p * (t - np.sin(W * t) / W) - eE / W * (1 - np.cos(W * t)))
    phiU = (p * np.sin(W * t) + eE * (1 - np.cos(W * t))) / (W * cl)
    return {"position": np.stack([dlc * rn, dL * rm], axis=-1), "phi_up": phiU}


def accel_bias_closed_form(b_east: float, lat: float, t) -> dict:
    """Single-channel Schuler solution for an East accelerometer bias (T&W ch. 12).

    Exact for the phi-angle model at the equator (no Foucault or Earth-rate coupling of the
    channel)::

        phi_N = -(b/g)(1 - cos w_s t),  dv_E = (b/w_s) sin w_s t,  dx_E = (b/w_s^2)(1 - cos w_s t)

    with w_s = sqrt(g/R_N) (the East channel's transport rate uses R_N).

    Parameters
    ----------
    b_east : float
        The East accelerometer bias [m/s^2].
    lat : float
        Latitude [rad] (gravity and R_N).
    t : array_like
        Times [s].

    Returns
    -------
    dict
        ``omega`` (w_s [rad/s]), ``phi_north`` [rad], ``dv_east`` [m/s], ``position_east`` [m].

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import accel_bias_closed_form
    >>> cf = accel_bias_closed_form(9.78e-5, 0.0, [0.0, np.pi / 1.2383e-3])
    >>> round(float(cf["position_east"][1]), 2)  # 2 b / w_s^2 at the half period
    127.56
    """
    t = np.asarray(t, dtype=float)
    g = earth.normal_gravity(lat)
    _, rn = earth.radii(lat)
    ws = math.sqrt(g / rn)
    return {"omega": ws, "phi_north": -(b_east / g) * (1 - np.cos(ws * t)),
            "dv_east": b_east / ws * np.sin(ws * t), "position_east": b_east / ws**2 * (1 - np.cos(ws * t))}
