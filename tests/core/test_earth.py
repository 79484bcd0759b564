"""WGS-84 Earth model against independent references."""

import math

import numpy as np
import pytest

from inscal.core import earth as E


def _q(s):
    """q(s) = ((1 + 3/s^2) atan(s) - 3/s) / 2 by its power series (no cancellation), s = E/u."""
    return 0.5 * sum((-1) ** k * 4 * (k - 1) / (4 * k * k - 1) * s ** (2 * k - 1) for k in range(2, 40))


def _normal_potential(x, z):
    """WGS-84 normal potential U (Heiskanen & Moritz 2-126) at meridian-plane point (x, z)."""
    a, b, GM, w = E.A, E.B, E.GM, E.OMEGA_IE
    Ee = math.sqrt(a * a - b * b)
    r2 = x * x + z * z
    u2 = 0.5 * (r2 - Ee * Ee + math.sqrt((r2 - Ee * Ee) ** 2 + 4 * Ee * Ee * z * z))
    u = math.sqrt(u2)
    sb = z / u
    q, q0 = _q(Ee / u), _q(Ee / b)
    return GM / Ee * math.atan(Ee / u) + 0.5 * w * w * a * a * q / q0 * (sb * sb - 1 / 3) + 0.5 * w * w * x * x


def _gravity_from_potential(lat, h=0.0):
    a = E.A
    rn = a / math.sqrt(1 - E.E2 * math.sin(lat) ** 2)
    x = (rn + h) * math.cos(lat)
    z = (rn * (1 - E.E2) + h) * math.sin(lat)
    d = 20.0
    gx = (_normal_potential(x + d, z) - _normal_potential(x - d, z)) / (2 * d)
    gz = (_normal_potential(x, z + d) - _normal_potential(x, z - d)) / (2 * d)
    return math.hypot(gx, gz)


def test_equator_and_pole_gravity_from_defining_constants():
    """gamma_e, gamma_p derived in closed form from a, f, GM, omega equal the
    published WGS-84 values used by Somigliana's formula (Heiskanen & Moritz 2-141, 2-142)."""
    a, b, GM, w = E.A, E.B, E.GM, E.OMEGA_IE
    ep = math.sqrt(a * a - b * b) / b
    q0 = 0.5 * ((1 + 3 / ep**2) * math.atan(ep) - 3 / ep)
    q0p = 3 * (1 + 1 / ep**2) * (1 - math.atan(ep) / ep) - 1
    m = w * w * a * a * b / GM
    ge = GM / (a * b) * (1 - m - m * ep * q0p / (6 * q0))
    gp = GM / a**2 * (1 + m * ep * q0p / (3 * q0))
    assert ge == pytest.approx(9.7803253359, abs=1e-9)
    assert gp == pytest.approx(9.8321849378, abs=1e-9)


@pytest.mark.parametrize("lat_deg, published", [(0.0, 9.7803253359), (45.0, None), (90.0, 9.8321849378)])
def test_normal_gravity(lat_deg, published):
    lat = math.radians(lat_deg)
    g = E.normal_gravity(lat, 0.0)
    # independent: gradient of the closed-form normal potential
    assert g == pytest.approx(_gravity_from_potential(lat), abs=1e-8)
    if published is not None:  # WGS-84 published equatorial/polar normal gravity
        assert g == pytest.approx(published, abs=1e-8)


def test_normal_gravity_with_height_matches_potential():
    for lat_deg in (10.0, 45.0, 80.0):
        lat = math.radians(lat_deg)
        for h in (100.0, 1000.0):
            # second-order height formula vs. the exact potential: agree to ~1e-7 at 1 km
            assert E.normal_gravity(lat, h) == pytest.approx(_gravity_from_potential(lat, h), abs=2e-7)
    # free-air gradient ~ 3.086e-6 /s^2
    grad = (E.normal_gravity(0.7, 0.0) - E.normal_gravity(0.7, 100.0)) / 100.0
    assert grad == pytest.approx(3.086e-6, rel=2e-3)


def test_radii():
    rm, rn = E.radii(0.0)
    assert rn == pytest.approx(E.A, rel=1e-15)
    assert rm == pytest.approx(E.A * (1 - E.E2), rel=1e-15)
    rm, rn = E.radii(math.pi / 2)
    assert rm == pytest.approx(rn, rel=1e-14)  # at the pole both equal a^2 / b
    assert rn == pytest.approx(E.A**2 / E.B, rel=1e-14)


def test_rates_and_periods():
    lat = math.radians(30.0)
    w = E.earth_rate_n(lat)
    assert np.linalg.norm(w) == pytest.approx(E.OMEGA_IE, rel=1e-15)
    assert w[0] == 0.0 and w[2] == pytest.approx(E.OMEGA_IE * 0.5, rel=1e-12)
    rm, rn = E.radii(lat)
    wen = E.transport_rate_n(lat, 0.0, np.array([10.0, 5.0, 0.0]))
    assert wen == pytest.approx([-5.0 / rm, 10.0 / rn, 10.0 * math.tan(lat) / rn], rel=1e-15)
    assert E.schuler_period(0.0) / 60 == pytest.approx(84.4, abs=0.05)
    assert E.foucault_period(math.radians(30.0)) == pytest.approx(2 * 2 * math.pi / E.OMEGA_IE, rel=1e-12)
