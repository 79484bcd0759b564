"""WGS-84 Earth model: constants, normal gravity, radii of curvature, Earth and
transport rates in the local East-North-Up (ENU) navigation frame.

References: NIMA TR8350.2 (WGS-84), Titterton & Weston ch. 3.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# --- WGS-84 defining and derived constants (TR8350.2 Tables 3.1-3.3) ---
A = 6378137.0  # semi-major axis [m]
F = 1.0 / 298.257223563  # flattening
GM = 3.986004418e14  # gravitational constant [m^3/s^2]
OMEGA_IE = 7.292115e-5  # Earth rotation rate [rad/s]
B = A * (1.0 - F)  # semi-minor axis [m]
E2 = F * (2.0 - F)  # first eccentricity squared
GAMMA_E = 9.7803253359  # normal gravity at the equator [m/s^2]
GAMMA_P = 9.8321849378  # normal gravity at the poles [m/s^2]
K_SOMIGLIANA = (B * GAMMA_P) / (A * GAMMA_E) - 1.0
M_RATIO = OMEGA_IE**2 * A**2 * B / GM  # m = w^2 a^2 b / GM


@njit(cache=True)
def normal_gravity(lat: float, h: float = 0.0) -> float:
    """Magnitude of WGS-84 normal gravity [m/s^2] at geodetic latitude ``lat`` [rad]
    and ellipsoidal height ``h`` [m].

    Somigliana's closed formula on the ellipsoid (TR8350.2 eq. 4-1) and the
    second-order height expansion (TR8350.2 eq. 4-3).
    """
    s2 = math.sin(lat) ** 2
    g0 = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) / math.sqrt(1.0 - E2 * s2)
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))


@njit(cache=True)
def radii(lat: float) -> tuple[float, float]:
    """Meridian (R_M) and prime-vertical (R_N) radii of curvature [m]."""
    s2 = math.sin(lat) ** 2
    w = math.sqrt(1.0 - E2 * s2)
    return A * (1.0 - E2) / (w * w * w), A / w


def earth_rate_n(lat: float) -> np.ndarray:
    """Earth rotation rate in ENU, w_ie^n [rad/s]."""
    return np.array([0.0, OMEGA_IE * math.cos(lat), OMEGA_IE * math.sin(lat)])


def transport_rate_n(lat: float, h: float, v_n: np.ndarray) -> np.ndarray:
    """Transport rate w_en^n [rad/s] for ENU velocity ``v_n`` [m/s]."""
    rm, rn = radii(lat)
    ve, vn = float(v_n[0]), float(v_n[1])
    return np.array([-vn / (rm + h), ve / (rn + h), ve * math.tan(lat) / (rn + h)])


def schuler_period(lat: float = 0.0, h: float = 0.0) -> float:
    """Schuler period 2*pi*sqrt(R/g) [s], with R the geometric mean radius at ``lat``."""
    rm, rn = radii(lat)
    return 2.0 * math.pi * math.sqrt(math.sqrt((rm + h) * (rn + h)) / normal_gravity(lat, h))


def foucault_period(lat: float) -> float:
    """Foucault period 2*pi / (w_ie sin L) [s]."""
    return 2.0 * math.pi / (OMEGA_IE * abs(math.sin(lat)))
