"""The vertical channel: free (pure inertial, unstable), and the damped loop on an external height."""

from __future__ import annotations

import math

import numpy as np
import pytest

from inscal.core import earth, turntable
from inscal import nav as nv
from inscal.core.error_model import ImuErrors
from inscal.sim.simulate import Scenario, simulate
from inscal.core.earth import Site
from inscal.core.kinematics import true_attitude
from inscal.nav.strapdown import NavConfig, NavState

LAT = math.radians(30.686651)
LON = math.radians(120.664265)
H0 = 20.0
UG = 9.80665e-6


def static_record(seconds, imu=None, rate_hz=10):
    scn = Scenario("vert", turntable.static(seconds), Site(LAT, LON, H0), imu=imu or ImuErrors(), rate_hz=rate_hz)
    return scn, simulate(scn)


def gradient():
    """k = -dg/dh of the navigator's normal gravity at the site [1/s^2] (~ 2 g / R)."""
    return -(earth.normal_gravity(LAT, H0 + 1.0) - earth.normal_gravity(LAT, H0 - 1.0)) / 2.0


def closed_form(t, h0, b, coriolis=True):
    """h'' = k h + b, h(0) = h0, h'(0) = 0  ->  h = h0 cosh(t sqrt k) + (b / k)(cosh(t sqrt k) - 1).

    ``coriolis``: with the East-Up Coriolis coupling of a static site, c = 2 W cos L:
    v_E' = -c v_U gives v_E = -c (h - h0), which feeds back into h'' = k h + b + c v_E, so
    h'' = (k - c^2) h + b + c^2 h0 (c^2 / k = 0.5 %: 0.3 % on h after 30 min)."""
    k = gradient()
    f = b
    if coriolis:
        c2 = (2.0 * earth.OMEGA_IE * math.cos(LAT)) ** 2
        k, f = k - c2, b + c2 * h0
    c = np.cosh(np.sqrt(k) * t)
    return h0 * c + f / k * (c - 1.0)


def test_gradient_is_the_textbook_two_g_over_r():
    k = gradient()
    g = earth.normal_gravity(LAT, H0)
    assert k == pytest.approx(2 * g / earth.A, rel=0.01)
    assert 1.0 / math.sqrt(k) == pytest.approx(570.0, abs=10.0)  # the e-folding time sqrt(R/2g)


@pytest.mark.parametrize("h0, b_ug", [(1.0, 0.0), (0.0, 20.0), (-0.5, -10.0)])
def test_free_vertical_channel_diverges_like_the_closed_form(h0, b_ug):
    """A small initial height error and/or a vertical accelerometer bias, 30 min (3.2 e-folding
    times): the free channel follows the closed-form solution of h'' = 2 g h / R + b."""
    T = 1800.0
    scn, _ = static_record(10.0)
    C = true_attitude(scn, np.array([0.0]))[0]
    up = int(np.argmax(np.abs(C[2])))  # the IMU axis that points up (or down)
    bias = np.zeros(3)
    bias[up] = b_ug * UG * np.sign(C[2, up])  # an upward specific-force bias of b_ug
    scn, d = static_record(T, ImuErrors(accel_bias=bias))
    init = NavState.from_truth(scn)
    init.height += h0
    r = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, init=init, scenario=scn,
                    config=NavConfig(vertical="free"))
    t = r.errors.time
    up_err = r.errors.position[:, 2]
    ref = closed_form(t, h0, b_ug * UG)
    assert abs(ref[-1]) > 5 * max(abs(h0), 0.1)  # it diverges, which is the point
    np.testing.assert_allclose(up_err, ref, rtol=5e-4, atol=1e-3)
    # h'' = 2 g h / R + b alone (no Coriolis) is within 0.4 %
    np.testing.assert_allclose(up_err, closed_form(t, h0, b_ug * UG, coriolis=False), rtol=4e-3, atol=1e-3)
    # the held channel stays at the site height; the damped loop stays bounded
    held = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, init=init, scenario=scn).errors.position[:, 2]
    assert np.max(np.abs(held - h0)) < 1e-9
    damped = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, init=init, scenario=scn,
                         config=NavConfig(vertical="damped")).errors.position[:, 2]
    assert np.max(np.abs(damped)) < abs(h0) + 1.0


def test_damped_loop_tracks_an_external_height_profile():
    """A 20 m, one-hour sine in the external height (a barometer on a static IMU): after the
    loop's transient (tau = 100 s) the navigated height follows the reference within a few
    percent of the amplitude; a constant reference is reached exactly."""
    T = 3600.0
    scn, d = static_record(T)
    tp = np.arange(0.0, T + 10.0, 5.0)
    hp = H0 + 20.0 * np.sin(2 * math.pi * tp / 3600.0)
    ref = nv.HeightReference(hp, tp)
    r = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, scenario=scn, config=NavConfig(vertical="damped"),
                    height_ref=ref)
    t, h = r.output.time, r.output.position[:, 2]
    late = t > 900.0
    assert np.max(np.abs(h[late] - ref(t[late]))) < 1.0  # 5 % of the amplitude
    assert np.ptp(h[late]) > 35.0  # it really moves with the reference
    # hold follows the reference exactly (at the 1-s update steps)
    r = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, scenario=scn, config=NavConfig(vertical="hold"),
                    height_ref=ref)
    assert np.max(np.abs(r.output.position[:, 2] - ref(r.output.time))) < 0.02
    # a constant reference 12.5 m (the IMU starts at 20 m)
    r = nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, scenario=scn, config=NavConfig(vertical="damped"),
                    height_ref=12.5)
    h = r.output.position[:, 2]
    assert abs(h[-1] - 12.5) < 0.01 and abs(h[0] - H0) < 0.5  # starts at 20 m, settles on 12.5 m


def test_height_reference_refused_with_a_free_channel_and_bad_profiles(tmp_path):
    scn, d = static_record(20.0)
    with pytest.raises(ValueError, match="free"):
        nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, scenario=scn, config=NavConfig(vertical="free"),
                    height_ref=10.0)
    with pytest.raises(ValueError, match="increase"):
        nv.HeightReference([1.0, 2.0, 3.0], [0.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="finite"):
        nv.HeightReference(float("nan"))
    p = tmp_path / "h.csv"
    p.write_text("# barometer\ntime_s,height_m\n0,10\n10,12\n")
    ref = nv.HeightReference.read_csv(p)
    assert ref(5.0) == pytest.approx(11.0) and ref(100.0) == pytest.approx(12.0)
    p.write_text("t,h\n0,1\n")
    with pytest.raises(ValueError, match="time_s and height_m"):
        nv.HeightReference.read_csv(p)
    p.write_text("time_s,height_m\n0,abc\n")
    with pytest.raises(ValueError, match="row 2"):
        nv.HeightReference.read_csv(p)
