"""WGS-84 Earth model: constants, normal gravity, radii of curvature, Earth and
transport rates in the local East-North-Up (ENU) navigation frame.

References: NIMA TR8350.2 (WGS-84), Titterton & Weston ch. 3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from inscal.core import earth

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


# --- PSINS toolbox gravity (Yan Gongmin, NWPU; ``glvf.m`` and ``earth.m``) ---
# Checked against the PSINS sources (public copies of glvf.m / earth.m): the current
# toolbox sets g0 = 9.7803267715, derives beta = 5/2 m - f - 17/14 m f and
# beta1 = (5 m f - f^2)/8 with m = Re wie^2 / g0 (Re = 6378137, f = 1/298.257,
# wie = 7.2921151467e-5), and evaluates
#     gL = g0 (1 + beta sin^2 L - beta1 sin^2 2L),   hR = h / (Re (1 - f sin^2 L)),
#     g  = gL (1 - 2 hR - 5 hR^2).
# (Older releases used g0 = 9.7803267714 and g0 (1 + 5.27094e-3 sin^2 L + 2.32718e-5 sin^4 L)
# - 3.086e-6 h; ``glv.beta3`` = 8.08e-9 is a horizontal gradient, not a height term.)
PSINS_RE = 6378137.0
PSINS_F = 1.0 / 298.257
PSINS_WIE = 7.2921151467e-5
PSINS_G0 = 9.7803267715
_PSINS_M = PSINS_RE * PSINS_WIE**2 / PSINS_G0
PSINS_BETA = 2.5 * _PSINS_M - PSINS_F - 17.0 / 14.0 * _PSINS_M * PSINS_F
PSINS_BETA1 = (5.0 * _PSINS_M * PSINS_F - PSINS_F**2) / 8.0


@njit(cache=True)
def psins_gravity(lat: float, h: float = 0.0) -> float:
    """Magnitude of gravity [m/s^2] by the PSINS toolbox formula (see the comment above)."""
    sl = math.sin(lat)
    s2l = math.sin(2.0 * lat)
    gl = PSINS_G0 * (1.0 + PSINS_BETA * sl * sl - PSINS_BETA1 * s2l * s2l)
    hr = h / (PSINS_RE * (1.0 - PSINS_F * sl * sl))
    return gl * (1.0 - 2.0 * hr - 5.0 * hr * hr)


GRAVITY_KINDS = ("wgs84", "psins", "measured")


@dataclass(frozen=True)
class GravityModel:
    """Gravity magnitude at a site: ``wgs84`` normal gravity, the ``psins`` toolbox formula,
    or a ``measured`` value [m/s^2] taken at ``height`` [m] (``None``: at whatever height it is
    asked for, i.e. the site height; other heights follow the WGS-84 normal free-air gradient)."""

    kind: str = "wgs84"
    value: float | None = None
    height: float | None = None

    def __post_init__(self):
        if self.kind not in GRAVITY_KINDS:
            raise ValueError(f"gravity model must be one of {', '.join(GRAVITY_KINDS)} or a value in m/s^2, "
                             f"got {self.kind!r}")
        if self.kind == "measured":
            v = self.value
            if v is None or not math.isfinite(v) or not (9.7 <= v <= 9.9):
                raise ValueError(f"measured gravity must be a finite value in 9.7..9.9 m/s^2, got {v}")
            if self.height is not None and not math.isfinite(self.height):
                raise ValueError("measured gravity height must be finite")
        elif self.value is not None or self.height is not None:
            raise ValueError(f"gravity model {self.kind!r} takes no value")

    def g(self, lat: float, h: float = 0.0) -> float:
        """Gravity magnitude [m/s^2] at latitude ``lat`` [rad], height ``h`` [m]."""
        if self.kind == "wgs84":
            return float(normal_gravity(lat, h))
        if self.kind == "psins":
            return float(psins_gravity(lat, h))
        if self.height is None:
            return float(self.value)
        return float(self.value) + float(normal_gravity(lat, h)) - float(normal_gravity(lat, self.height))

    def scale(self, lat: float, h: float = 0.0) -> float:
        """g_model / WGS-84 normal gravity at (lat, h); 1.0 for ``wgs84``."""
        if self.kind == "wgs84":
            return 1.0
        return self.g(lat, h) / float(normal_gravity(lat, h))

    def to_json(self) -> dict:
        """The model as a JSON table: ``{"kind", "value"}``, plus ``"height"`` [m] for a measured value."""
        d = {"kind": self.kind, "value": self.value}
        if self.height is not None:
            d["height"] = self.height
        return d

    @classmethod
    def from_json(cls, d) -> "GravityModel":
        """The model from :meth:`to_json`'s table or from its text form (``wgs84`` | ``psins`` | a value in m/s^2); None is WGS-84."""
        if d is None:
            return WGS84_GRAVITY
        if isinstance(d, str):
            return parse_gravity(d)
        if not isinstance(d, dict) or "kind" not in d:
            raise ValueError(f"gravity model must be {{'kind': ..., 'value': ...}}, got {d!r}")
        v = d.get("value")
        hh = d.get("height")
        return cls(str(d["kind"]), None if v is None else float(v), None if hh is None else float(hh))

    def describe(self) -> str:
        """One line for reports: the model's name, or the measured value [m/s^2] and its height."""
        if self.kind != "measured":
            return self.kind
        return f"measured {self.value!r} m/s^2" + ("" if self.height is None else f" at {self.height:g} m")


WGS84_GRAVITY = GravityModel("wgs84")
PSINS_GRAVITY = GravityModel("psins")


def parse_gravity(text, height: float | None = None) -> GravityModel:
    """``wgs84`` | ``psins`` | a number in m/s^2 (measured at ``height``)."""
    if isinstance(text, GravityModel):
        return text
    s = str(text).strip().lower()
    if s in ("wgs84", "wgs-84", "normal"):
        return WGS84_GRAVITY
    if s == "psins":
        return PSINS_GRAVITY
    try:
        v = float(s)
    except ValueError:
        raise ValueError(f"gravity must be wgs84, psins or a value in m/s^2, got {text!r}") from None
    return GravityModel("measured", v, None if height is None else float(height))


@dataclass(frozen=True)
class Site:
    """A static site: geodetic latitude, longitude [rad], ellipsoidal height [m] and the
    gravity model (:class:`~inscal.core.earth.GravityModel`, WGS-84 normal gravity by default)."""

    latitude: float
    longitude: float = 0.0
    height: float = 0.0
    gravity_model: earth.GravityModel = earth.WGS84_GRAVITY

    def __post_init__(self):
        for n in ("latitude", "longitude", "height"):
            if not math.isfinite(getattr(self, n)):
                raise ValueError(f"site {n} must be finite")
        if abs(self.latitude) > math.pi / 2:
            raise ValueError("site latitude must be within +-90 deg")
        if not isinstance(self.gravity_model, earth.GravityModel):
            object.__setattr__(self, "gravity_model", earth.parse_gravity(self.gravity_model))

    @property
    def gravity(self) -> float:
        """Gravity magnitude at the site [m/s^2] by the site's gravity model."""
        return self.gravity_model.g(self.latitude, self.height)

    @property
    def gravity_scale(self) -> float:
        """Site gravity / WGS-84 normal gravity at the site (1.0 for ``wgs84``): the factor the
        navigation kernels apply to their normal gravity."""
        return self.gravity_model.scale(self.latitude, self.height)

    def with_gravity(self, model) -> "Site":
        """This site with another gravity model (``GravityModel`` or ``wgs84``/``psins``/value)."""
        return replace(self, gravity_model=earth.parse_gravity(model))

    @property
    def earth_rate_n(self) -> np.ndarray:
        """The Earth rate in the ENU frame at the site's latitude [rad/s]."""
        return earth.earth_rate_n(self.latitude)
