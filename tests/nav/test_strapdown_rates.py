"""The kernel's rates: Earth quantities updated at a lower rate than the samples (against the update
at every sample), output decimated inside the kernel (against decimating the full-rate output),
the reference-height profile read inside the kernel, chunking; and the restructured arithmetic
(rotation-vector series, normalisation once per update) against the per-sample step functions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from inscal import nav as nv
from inscal.core import earth, turntable
from inscal.core.attitude import (
    dcm_from_quat,
    quat_from_dcm,
    quat_from_rotvec_xyz,
    small_angle_error,
)
from inscal.core.earth import Site
from inscal.core.error_model import ImuErrors
from inscal.nav.strapdown import (
    N_STATE,
    S_E_G0,
    S_E_GH,
    S_E_RM,
    S_E_RN,
    S_E_SECL,
    S_E_TL,
    S_E_WN,
    S_E_WU,
    NavConfig,
    NavOutput,
    NavState,
    Strapdown,
    attitude_step,
    earth_update,
    rotvec_quat,
    two_sample,
    velocity_step,
)
from inscal.sim.simulate import Scenario, simulate

DEGH = math.pi / 180 / 3600
UG = 9.80665e-6
LAT = math.radians(30.686651)


def run(scn, d, chunk=1 << 20, **kw):
    nav = Strapdown(NavState.from_truth(scn), 1.0 / scn.rate_hz, NavConfig(**kw))
    return NavOutput.concatenate([nav.run(d.dtheta[k:k + chunk], d.dvel[k:k + chunk], d.gimbal[k:k + chunk])
                                     for k in range(0, d.dtheta.shape[0], chunk)])


def differences(a, b, lat):
    rm, rn = earth.radii(lat)
    dpos = np.hypot((a.position[:, 0] - b.position[:, 0]) * rm,
                    (a.position[:, 1] - b.position[:, 1]) * rn * math.cos(lat))
    datt = small_angle_error(dcm_from_quat(a.quaternion), dcm_from_quat(b.quaternion))
    return float(np.max(dpos)), float(np.max(np.abs(a.velocity - b.velocity))), float(np.max(np.abs(datt)))


def horizontal_error(out, site):
    rm, rn = earth.radii(site.latitude)
    return float(np.max(np.hypot((out.position[:, 0] - site.latitude) * rm,
                                 (out.position[:, 1] - site.longitude) * rn * math.cos(site.latitude))))


# ----------------------------------------------------------------------------- Earth quantities
@pytest.mark.parametrize("case", ["static north gyro 24 h", "rotation modulation 6 h", "damped 4 h"])
def test_low_rate_earth_update_matches_the_update_at_every_sample(case):
    """The default 1-Hz update of the latitude's Earth quantities (at the latitude extrapolated to
    the middle of the interval) against the update at every sample: after hours of navigation with
    errors of 0.3-10 km, the position differs by 1e-5 m (measured: 9.6e-6 m, 1.1e-5 m, 3.5e-7 m), the
    velocity by 1e-8 m/s, the attitude by 2e-12 rad: 1e-9 to 3e-8 of the errors the tests judge.  The
    difference is second order in the interval (0.1 Hz: 100 times that), which the test also checks."""
    if case == "static north gyro 24 h":
        scn = Scenario("gb", turntable.static(86400), Site(LAT), imu=ImuErrors(gyro_bias=[0, 0.005 * DEGH, 0]),
                       rate_hz=10)
        kw = {}
    elif case == "rotation modulation 6 h":
        scn = Scenario("rm", turntable.rotmod16(6 * 3600), Site(LAT), rate_hz=20,
                       imu=ImuErrors(gyro_bias=[0.01 * DEGH, -0.01 * DEGH, 0.01 * DEGH],
                                     accel_bias=[100 * UG, -100 * UG, 100 * UG]))
        kw = {}
    else:
        scn = Scenario("dd", turntable.rotmod16(4 * 3600), Site(math.radians(60.0), 0.0, 500.0), rate_hz=10,
                       imu=ImuErrors(gyro_bias=[0.02 * DEGH] * 3, accel_bias=[200 * UG, -50 * UG, 80 * UG]))
        kw = {"mode": "damped", "vertical": "damped"}
    d = simulate(scn)
    every = run(scn, d, earth_update_hz=scn.rate_hz, **kw)
    default = run(scn, d, **kw)
    assert NavConfig().earth_update_hz == 1.0
    slow = run(scn, d, earth_update_hz=0.1, **kw)
    peak = horizontal_error(every, scn.site)
    assert peak > 300.0  # errors the navigation tests judge in metres
    dpos, dvel, datt = differences(default, every, scn.site.latitude)
    assert dpos < 1e-4 and dpos < 3e-7 * peak, (dpos, peak)
    assert dvel < 1e-7 and datt < 1e-10, (dvel, datt)
    # second order in the update interval: ten times longer, about a hundred times larger
    dpos10 = differences(slow, every, scn.site.latitude)[0]
    assert 30.0 < dpos10 / max(dpos, 1e-300) < 300.0, (dpos10, dpos)


def test_earth_update_reproduces_the_earth_model():
    """The quantities the kernel holds for an update interval are the WGS-84 model's (T&W ch. 3,
    TR8350.2 eq. 4-1, 4-3) at the extrapolated latitude; gravity's height term applied per sample."""
    st = np.zeros(N_STATE)
    lat, h, vn, ahead = 0.61, 812.5, 3.0, 0.45
    earth_update(st, lat, h, vn, ahead, 1.0)
    rm0, _ = earth.radii(lat)
    lm = lat + ahead * vn / (rm0 + h)
    rm, rn = earth.radii(lm)
    assert st[S_E_RM] == pytest.approx(rm, rel=1e-15) and st[S_E_RN] == pytest.approx(rn, rel=1e-15)
    assert st[S_E_TL] == pytest.approx(math.tan(lm), rel=1e-15)
    assert st[S_E_SECL] == pytest.approx(1.0 / math.cos(lm), rel=1e-15)
    assert st[S_E_WN] == pytest.approx(earth.OMEGA_IE * math.cos(lm), rel=1e-15)
    assert st[S_E_WU] == pytest.approx(earth.OMEGA_IE * math.sin(lm), rel=1e-15)
    for hh in (-400.0, 0.0, 812.5, 9000.0):
        g = st[S_E_G0] * (1.0 - st[S_E_GH] * hh + 3.0 * hh * hh / (earth.A * earth.A))
        assert g == pytest.approx(earth.normal_gravity(lm, hh), rel=2e-16)


def test_earth_update_hz_is_checked():
    with pytest.raises(ValueError, match="earth_update_hz"):
        NavConfig(earth_update_hz=0.0)
    assert NavConfig(earth_update_hz=1.0).earth_samples(0.01) == 100
    assert NavConfig(earth_update_hz=1000.0).earth_samples(0.01) == 1


# ----------------------------------------------------------------------------- the arithmetic
def test_rotation_vector_series_is_the_exact_quaternion():
    """The kernel's trigonometry-free quaternion of a rotation vector (the series to u^4) equals the
    exact one to round-off over the whole range it is used for (and beyond, where it switches)."""
    rng = np.random.default_rng(5)
    worst = 0.0
    for a in np.r_[0.0, np.geomspace(1e-12, 1.0, 300)]:
        u = rng.normal(size=3)
        v = a * u / np.linalg.norm(u)
        ref = np.array(quat_from_rotvec_xyz(*v))
        got = np.array(rotvec_quat(*v))
        worst = max(worst, float(np.max(np.abs(got - ref))))
    assert worst < 4e-16


def test_kernel_equals_the_per_sample_steps():
    """The kernel (Earth quantities at every sample) against a plain loop over the per-sample step
    functions (:func:`two_sample`, :func:`velocity_step`, :func:`attitude_step`, trigonometric
    quaternions normalised at every sample): the same mechanization to round-off after 20 000 samples
    of a rotating IMU with biases (measured: 2e-7 m, mostly the loop's plain latitude sum against the
    kernel's compensated one, 4e-11 m/s, 1e-14 rad)."""
    scn = Scenario("ps", turntable.rotmod16(2000.0), Site(LAT, 2.0, 30.0), rate_hz=10,
                   imu=ImuErrors(gyro_bias=[0.05 * DEGH] * 3, accel_bias=[300 * UG, -200 * UG, 100 * UG]))
    d = simulate(scn)
    dt = 1.0 / scn.rate_hz
    out = run(scn, d, earth_update_hz=scn.rate_hz, output_rate_hz=scn.rate_hz)
    init = NavState.from_truth(scn)
    q0 = quat_from_dcm(init.C_s_n)
    q = tuple(float(x) for x in q0 / np.linalg.norm(q0))
    ve = vn = vu = 0.0
    lat, lon, h = init.latitude, init.longitude, init.height
    p = u = (0.0, 0.0, 0.0)
    pos, vel, quat = [], [], []
    for k in range(d.dtheta.shape[0]):
        a, b = tuple(d.dtheta[k]), tuple(d.dvel[k])
        r0, r1, r2, c0, c1, c2 = two_sample(*a, *b, *p, *u, k > 0)
        nve, nvn, _, sl, cl, rmh, rnh, wie_n, wie_u = velocity_step(*q, c0, c1, c2, ve, vn, vu, lat, h, dt, 1.0)
        mve, mvn = 0.5 * (ve + nve), 0.5 * (vn + nvn)
        q = attitude_step(*q, r0, r1, r2, -mvn / rmh * dt, (wie_n + mve / rnh) * dt,
                          (wie_u + mve * sl / (cl * rnh)) * dt)
        lat += 0.5 * (vn + nvn) / rmh * dt
        lon += 0.5 * (ve + nve) / (rnh * cl) * dt
        ve, vn = nve, nvn
        p, u = a, b
        pos.append((lat, lon))
        vel.append((ve, vn))
        quat.append(q)
    pos, vel, quat = np.array(pos), np.array(vel), np.array(quat)
    rm, rn = earth.radii(LAT)
    assert horizontal_error(out, scn.site) > 10.0  # the biases move it
    assert np.max(np.abs(out.position[:, 0] - pos[:, 0])) * rm < 1e-6
    assert np.max(np.abs(out.position[:, 1] - pos[:, 1])) * rn < 1e-6
    assert np.max(np.abs(out.velocity[:, 0:2] - vel)) < 1e-9  # measured 3.7e-11 (of ~1 m/s)
    assert np.max(np.abs(small_angle_error(dcm_from_quat(out.quaternion), dcm_from_quat(quat)))) < 1e-13
    assert np.max(np.abs(np.sum(out.quaternion**2, axis=1) - 1.0)) < 1e-14  # normalised once per update


# ----------------------------------------------------------------------------- output and chunks
@pytest.mark.parametrize("out_hz", [1.0, 2.5, 10.0])
def test_decimation_inside_the_kernel_equals_decimating_the_full_rate_output(out_hz):
    scn = Scenario("dc", turntable.rotmod16(1200.0), Site(LAT), rate_hz=10, imu=ImuErrors(accel_bias=[50 * UG] * 3))
    d = simulate(scn)
    full = run(scn, d, chunk=777, output_rate_hz=scn.rate_hz)
    dec = run(scn, d, chunk=1000, output_rate_hz=out_hz)
    m = NavConfig(output_rate_hz=out_hz).decimation(1.0 / scn.rate_hz)
    sel = slice(m - 1, None, m)
    assert dec.index.size == d.dtheta.shape[0] // m
    for name in ("index", "time", "quaternion", "velocity", "position", "gimbal"):
        np.testing.assert_array_equal(getattr(dec, name), getattr(full, name)[sel], err_msg=name)
    np.testing.assert_array_equal(dec.time, (dec.index + 1) * (1.0 / scn.rate_hz))


def test_chunking_changes_nothing_with_damping_low_rate_updates_and_a_height_profile():
    """Chunks of 777 samples (the 1-s Earth updates and the 1-s height blocks straddle them), one
    chunk, and a start after an alignment-like offset give bit-identical navigation."""
    scn = Scenario("hc", turntable.rotmod16(1800.0), Site(LAT, 0.0, 20.0), rate_hz=20,
                   imu=ImuErrors(gyro_bias=[0.02 * DEGH] * 3, accel_bias=[80 * UG, -40 * UG, 30 * UG]))
    d = simulate(scn)
    tp = np.arange(0.0, 1900.0, 7.0)
    ref = nv.HeightReference(20.0 + 5.0 * np.sin(tp / 300.0), tp)
    cfg = NavConfig(mode="damped", vertical="damped", output_rate_hz=2.0)
    runs = [nv.navigate(nv.chunks_of(d, c), scn.rate_hz, scn.site, scenario=scn, config=cfg, height_ref=ref)
            for c in (777, 1 << 20, 4096)]
    for r in runs[1:]:
        for name in ("index", "time", "quaternion", "velocity", "position"):
            np.testing.assert_array_equal(getattr(r.output, name), getattr(runs[0].output, name), err_msg=name)
    # a navigator that starts at sample 1234 (k0, as after an alignment) updates on the global grid too
    init = NavState.from_truth(scn)
    a = Strapdown(init, 0.05, cfg, k0=1234)
    b = Strapdown(init, 0.05, cfg, k0=1234)
    n = 20 * 300
    oa = NavOutput.concatenate([a.run(d.dtheta[k:min(k + 333, n)], d.dvel[k:min(k + 333, n)])
                                for k in range(0, n, 333)])
    ob = b.run(d.dtheta[:n], d.dvel[:n])
    np.testing.assert_array_equal(oa.position, ob.position)
    np.testing.assert_array_equal(oa.quaternion, ob.quaternion)


def test_held_height_follows_the_profile_block_by_block():
    """Vertical "hold" with a height profile: the height of every sample is the reference read at the
    middle of its 1-s block (global blocks of the sample index), inside the kernel."""
    scn = Scenario("hp", turntable.static(600.0), Site(LAT, 0.0, 20.0), rate_hz=10)
    d = simulate(scn)
    tp = np.array([0.0, 300.0, 700.0])
    ref = nv.HeightReference([20.0, 60.0, 10.0], tp)
    r = nv.navigate(nv.chunks_of(d, 333), 10, scn.site, scenario=scn, config=NavConfig(output_rate_hz=10.0),
                    height_ref=ref)
    k = r.output.index
    blk = round(nv.HeightReference.UPDATE_S * 10)
    mid = (k // blk * blk + 0.5 * (blk + 1)) / 10.0
    np.testing.assert_allclose(r.output.position[:, 2], ref(mid), rtol=0, atol=1e-12)
    assert np.ptp(r.output.position[:, 2]) > 30.0
