"""Strapdown mechanization against the exact simulator and against closed forms
(Titterton & Weston ch. 12; N25 eq. 35-37).  All runs are noise-free; the simulator's
increments are exact at any rate, so low rates (10-20 Hz) keep the suite fast."""

from __future__ import annotations

import math

import numpy as np
import pytest

from inscal.core import earth, turntable
from inscal import nav as nv
from inscal.core.attitude import small_angle_error
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.sim.simulate import Scenario, simulate, simulate_chunks
from inscal.core.earth import Site
from inscal.core.kinematics import true_attitude
from inscal.nav.strapdown import NavConfig, NavState, Strapdown

DEGH = math.pi / 180 / 3600
UG = 9.80665e-6
AS = math.pi / 180 / 3600
LAT = math.radians(30.686651)  # N25 site
LON = math.radians(120.664265)


def run(scn, **kw):
    d = simulate(scn)
    return nv.navigate(nv.chunks_of(d), scn.rate_hz, scn.site, scenario=scn, **kw)


def schuler_mean(x, dt_out, lat):
    """Moving average over one Schuler period (removes the Schuler oscillation)."""
    w = int(round(earth.schuler_period(lat) / dt_out))
    return np.convolve(x, np.ones(w) / w, mode="valid")


# ----------------------------------------------------------------------------- exactness
def test_error_free_24h_static_below_one_metre():
    scn = Scenario("ef", turntable.static(86400), Site(LAT, LON, 12.0), rate_hz=10)
    r = run(scn)
    e = r.errors
    assert e.time[-1] == pytest.approx(86400.0)
    assert np.max(e.horizontal) < 1.0  # the strapdown algorithm's numerical floor
    assert np.max(np.abs(e.velocity)) < 1e-6
    assert np.max(np.abs(e.attitude)) < 1e-3 * AS
    assert r.summary["max_position_error_m"] == pytest.approx(np.max(e.horizontal))


def test_chunk_size_does_not_change_the_result():
    scn = Scenario("ch", turntable.rotmod16(3000.0), Site(LAT), rate_hz=20,
                   imu=ImuErrors(gyro_bias=[0.01 * DEGH] * 3, accel_bias=[50 * UG] * 3))
    d = simulate(scn)
    a = nv.navigate(nv.chunks_of(d, 1 << 20), scn.rate_hz, scn.site, scenario=scn)
    b = nv.navigate(nv.chunks_of(d, 777), scn.rate_hz, scn.site, scenario=scn)
    c = nv.navigate(simulate_chunks(scn, None, chunk_size=4096), scn.rate_hz, scn.site, scenario=scn)
    np.testing.assert_array_equal(a.output.index, b.output.index)
    np.testing.assert_array_equal(a.output.position, b.output.position)
    np.testing.assert_array_equal(a.output.quaternion, c.output.quaternion)


def test_coning_and_sculling_corrections_matter_under_rotation():
    """Switching the corrections off must degrade an error-free rotating run (the test can fail)."""
    scn = Scenario("cs", turntable.rotmod16(3600.0), Site(LAT), rate_hz=20)
    on = run(scn)
    off = run(scn, config=NavConfig(coning=False))
    assert np.max(on.errors.horizontal) < 0.05
    assert np.max(off.errors.horizontal) > 5 * np.max(on.errors.horizontal)


# ----------------------------------------------------------------------------- accelerometer bias
def test_east_accel_bias_schuler_period_amplitude_and_tilt():
    """100 ug East accelerometer bias at the equator (no Foucault coupling of the channel):
    north tilt -b/g, Schuler period 2 pi sqrt(R/g) ~ 84.4 min, amplitude b R / g."""
    b = 100 * UG
    scn = Scenario("ab", turntable.static(6 * 3600), Site(0.0), imu=ImuErrors(accel_bias=[b, 0, 0]), rate_hz=10)
    e = run(scn).errors
    cf = nv.accel_bias_closed_form(b, 0.0, e.time)
    P_cf = 2 * math.pi / cf["omega"]
    fit = nv.fit_oscillation(e.time, e.position[:, 0], 0.98 * P_cf)
    assert abs(fit["period"] / P_cf - 1) < 0.005
    assert abs(fit["period"] / (84.4 * 60) - 1) < 0.005
    assert abs(fit["amplitude"] / (b / cf["omega"] ** 2) - 1) < 0.02
    tilt = nv.fit_oscillation(e.time, e.attitude[:, 1], P_cf)
    g = earth.normal_gravity(0.0)
    assert abs(tilt["offset"] / (-b / g) - 1) < 0.02  # north tilt -b/g
    vel = nv.fit_oscillation(e.time, e.velocity[:, 0], P_cf)
    assert abs(vel["amplitude"] / (b / cf["omega"]) - 1) < 0.02
    # the whole series against the closed form
    assert np.max(np.abs(e.position[:, 0] - cf["position_east"])) < 0.01 * np.max(cf["position_east"])
    assert np.max(np.abs(e.position[:, 1])) < 1e-3 * np.max(cf["position_east"])


def test_accel_bias_mid_latitude_matches_linear_error_model():
    """At 30.7 deg the Foucault rotation couples the channels; the full linear error model
    (phi-angle form, Earth rate) must follow the mechanization to 1 %."""
    bias = np.array([100 * UG, -60 * UG, 0.0])
    scn = Scenario("ab2", turntable.static(8 * 3600), Site(LAT), imu=ImuErrors(accel_bias=bias), rate_hz=10)
    e = run(scn).errors
    lm = nv.linear_error_model(np.eye(3), LAT, np.r_[0.0, e.time], accel_bias=bias)
    pos = lm["position"][1:]
    scale = np.max(np.abs(pos))
    assert np.max(np.abs(e.position[:, 0:2] - pos)) < 0.01 * scale
    assert np.max(np.abs(e.attitude[:, 0:2] - lm["phi"][1:, 0:2])) < 0.01 * np.max(np.abs(lm["phi"][:, 0:2]))


# ----------------------------------------------------------------------------- gyro biases
@pytest.mark.parametrize("axis", ["east", "north"])
def test_level_gyro_bias_position_growth_24h(axis):
    """East / North gyro bias (IMU aligned E-N-U) over 24 h against the textbook
    Schuler-averaged solution (T&W ch. 12): within 2 % of the peak error, after a
    one-Schuler-period moving average of both; and the full series against the linear model."""
    eps = np.zeros(3)
    eps[0 if axis == "east" else 1] = 0.005 * DEGH
    scn = Scenario("gb", turntable.static(86400), Site(LAT), imu=ImuErrors(gyro_bias=eps), rate_hz=10)
    e = run(scn).errors
    cf = nv.gyro_bias_closed_form(eps, LAT, e.time)
    for k in range(2):
        sim = schuler_mean(e.position[:, k], 1.0, LAT)
        ref = schuler_mean(cf["position"][:, k], 1.0, LAT)
        assert np.max(np.abs(sim - ref)) < 0.02 * np.max(np.abs(ref)), (axis, k)
    if axis == "north":  # unbounded longitude growth: R eps_N cos^2 L t + ...
        assert abs(e.position[-1, 0] / cf["position"][-1, 0] - 1) < 0.02
        assert e.position[-1, 0] > 0.9 * earth.radii(LAT)[1] * eps[1] * 86400 * math.cos(LAT) ** 2
    lm = nv.linear_error_model(np.eye(3), LAT, np.r_[0.0, e.time], gyro_bias=eps)["position"][1:]
    assert np.max(np.abs(e.position[:, 0:2] - lm)) < 0.01 * np.max(np.abs(lm))


def test_vertical_gyro_bias_heading_drift():
    """Up gyro bias: heading error eps_U sin(Wt)/W (T&W ch. 12), i.e. eps_U t at first."""
    eps = np.array([0.0, 0.0, 0.005 * DEGH])
    scn = Scenario("gz", turntable.static(86400), Site(LAT), imu=ImuErrors(gyro_bias=eps), rate_hz=10)
    e = run(scn).errors
    cf = nv.gyro_bias_closed_form(eps, LAT, e.time)
    sim = schuler_mean(e.attitude[:, 2], 1.0, LAT)
    ref = schuler_mean(cf["phi_up"], 1.0, LAT)
    assert np.max(np.abs(sim - ref)) < 0.02 * np.max(np.abs(ref))
    # first hour: linear drift at eps_U
    one = e.time <= 3600
    slope = np.polyfit(e.time[one], e.attitude[one, 2], 1)[0]
    assert abs(slope / eps[2] - 1) < 0.02
    # the vehicle yaw (through the gimbal angles) carries the same error
    np.testing.assert_allclose(e.vehicle[:, 2], e.attitude[:, 2], atol=1e-3 * AS)


# ----------------------------------------------------------------------------- rotation modulation
def test_rotation_modulation_reduces_bias_position_error_tenfold():
    imu = ImuErrors(gyro_bias=[0.01 * DEGH, -0.01 * DEGH, 0.01 * DEGH], accel_bias=[100 * UG, -100 * UG, 100 * UG])
    rot = turntable.rotmod16(6 * 3600)
    rm = run(Scenario("rm", rot, Site(LAT), imu=imu, rate_hz=20)).errors
    st = run(Scenario("st", turntable.static(rot.duration), Site(LAT), imu=imu, rate_hz=20)).errors
    assert rm.time[-1] == pytest.approx(st.time[-1])
    assert np.max(st.horizontal) > 10 * np.max(rm.horizontal)
    assert st.horizontal[-1] > 10 * rm.horizontal[-1]


def test_gimbal_nonorthogonality_vehicle_attitude_error_n25():
    """d theta = 20": navigating in the IMU frame, the vehicle attitude through an orthogonal
    gimbal model is wrong by the N25 eq. 35-37 term, periodic with amplitude ~ d theta."""
    dth = 20 * AS
    scn = Scenario("dt", turntable.rotmod16(2 * 3600), Site(LAT), gimbal=GimbalErrors(dth), rate_hz=20)
    r = run(scn, config=NavConfig(output_rate_hz=5))
    e = r.errors
    assert np.max(np.abs(e.attitude)) < 0.01 * AS  # the IMU-frame navigation itself is exact
    assert np.max(e.horizontal) < 1.0
    pred = turntable.attitude_error_nonorthogonality(r.output.gimbal[:, 0], dth)
    np.testing.assert_allclose(e.vehicle, pred, atol=0.02 * AS)
    assert np.max(np.abs(e.vehicle[:, 2])) == pytest.approx(dth, rel=0.01)  # yaw: dth sin(theta_x)
    assert np.max(np.abs(e.vehicle[:, 1])) == pytest.approx(2 * dth, rel=0.01)  # pitch: 2 dth sin^2(theta_x/2)
    # with the true gimbal model the vehicle attitude is exact
    good = nv.navigation_errors(r.output, scn, GimbalErrors(dth))
    assert np.max(np.abs(good.vehicle)) < 0.01 * AS


# ----------------------------------------------------------------------------- compensation
def s16_like_errors():
    rng = np.random.default_rng(3)
    return ImuErrors(
        gyro_scale_factor=rng.uniform(-300, 300, 3) * 1e-6, gyro_misalignment=rng.uniform(-180, 180, 6) * AS,
        gyro_bias=rng.uniform(-0.05, 0.05, 3) * DEGH, gyro_g_sensitivity=rng.uniform(-1e-3, 1e-3, (3, 3)) * DEGH / 9.80665,
        accel_scale_factor=rng.uniform(-300, 300, 3) * 1e-6, accel_misalignment=rng.uniform(-180, 180, 6) * AS,
        accel_bias=rng.uniform(-200, 200, 3) * UG, accel_nonlinearity=rng.uniform(-300, 300, 3) * UG / 9.80665**2,
        accel_cross_coupling=rng.uniform(-300, 300, 6) * UG / 9.80665**2, accel_lever_arm=[0.02, -0.02, 0.02],
    )


def test_compensation_with_true_parameters_restores_error_free_navigation():
    imu = s16_like_errors()
    scn = Scenario("cp", turntable.rotmod16(2 * 3600), Site(LAT), imu=imu, rate_hz=20)
    raw = run(scn).errors
    comp = run(scn, params=imu).errors
    linear = run(scn, params=imu.replace(accel_nonlinearity=np.zeros(3), accel_cross_coupling=np.zeros(6),
                                         accel_lever_arm=np.zeros((3, 3)))).errors
    assert np.max(raw.horizontal) > 1000.0
    assert np.max(comp.horizontal) < 1.0
    assert np.max(np.abs(comp.attitude)) < 0.05 * AS
    # the nonlinear terms (300 ug/g^2 ~ 300 ug at 1 g) are visible when left out
    assert np.max(linear.horizontal) > 50 * np.max(comp.horizontal)


def test_kernel_compensation_equals_error_model_compensation():
    """On a static base (no w-dot) the kernel's on-the-fly compensation equals
    ImuErrors.compensate_increments applied beforehand."""
    imu = s16_like_errors()
    scn = Scenario("k", turntable.static(1800), Site(LAT), imu=imu, rate_hz=10,
                   gimbal=GimbalErrors(0.0, [0.3, -0.2, 1.0]))
    d = simulate(scn)
    dt = 1 / scn.rate_hz
    a = Strapdown(NavState.from_truth(scn), dt, params=imu).run(d.dtheta, d.dvel)
    cth, cdv = imu.compensate_increments(dt, d.dtheta, d.dvel)
    b = Strapdown(NavState.from_truth(scn), dt).run(cth, cdv)
    np.testing.assert_allclose(a.velocity, b.velocity, atol=1e-9)
    np.testing.assert_allclose(a.quaternion, b.quaternion, atol=1e-12)


# ----------------------------------------------------------------------------- modes
def test_horizontal_damping_removes_the_schuler_oscillation():
    b = np.array([100 * UG, 0.0, 0.0])
    scn = Scenario("hd", turntable.static(6 * 3600), Site(LAT), imu=ImuErrors(accel_bias=b), rate_hz=10)
    d = simulate(scn)
    free = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn).errors
    damp = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn, config=NavConfig(mode="damped")).errors
    late = free.time > 3 * 3600
    vf = np.max(np.abs(free.velocity[late, 0:2]))
    vd = np.max(np.abs(damp.velocity[late, 0:2]))
    assert vf > 0.5 * b[0] / nv.schuler_frequency(LAT)
    assert vd < 0.02 * vf
    # the reference may be given per sample (sailing test: a log or GNSS velocity)
    per_sample = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn, config=NavConfig(mode="damped"),
                             vref=lambda t: np.zeros((t.shape[0], 3))).errors
    np.testing.assert_array_equal(per_sample.velocity, damp.velocity)
    # a wrong reference (0.1 m/s East while static) pulls the tilt: the loop is really closed
    biased = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn, config=NavConfig(mode="damped"),
                         vref=np.array([0.1, 0.0, 0.0])).errors
    assert np.max(np.abs(biased.attitude[:, 1] - damp.attitude[:, 1])) > 1e-5


def test_vertical_channel_hold_and_damped():
    b = np.array([0.0, 0.0, 50 * UG])
    scn = Scenario("vc", turntable.static(4 * 3600), Site(LAT, 0.0, 100.0), imu=ImuErrors(accel_bias=b), rate_hz=10)
    d = simulate(scn)
    hold = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn).errors
    assert np.max(np.abs(hold.position[:, 2])) == 0.0 and np.max(np.abs(hold.velocity[:, 2])) == 0.0
    damp = nv.navigate(nv.chunks_of(d), 10, scn.site, scenario=scn,
                       config=NavConfig(vertical="damped", vertical_tau=100.0)).errors
    # third-order loop with a triple pole at -1/tau: a bias step b gives
    # dh(s) = b / (s + 1/tau)^3, i.e. dh(t) = b t^2 exp(-t/tau) / 2, peak 2 b tau^2 e^-2 at t = 2 tau
    tau = 100.0
    i = np.argmax(np.abs(damp.position[:, 2]))
    assert damp.position[i, 2] == pytest.approx(2 * b[2] * tau**2 * math.exp(-2), rel=0.02)
    assert damp.time[i] == pytest.approx(2 * tau, abs=3.0)
    ref = b[2] * damp.time**2 * np.exp(-damp.time / tau) / 2
    assert np.max(np.abs(damp.position[:, 2] - ref)) < 0.02 * np.max(ref)


# ----------------------------------------------------------------------------- alignment
def test_alignment_error_free_is_exact_even_while_turning():
    scn = Scenario("al", turntable.rotmod16(1800), Site(LAT, LON, 10.0), rate_hz=20,
                   gimbal=GimbalErrors(0.0, np.radians([0.1, 0.1, 20.0])))
    d = simulate(scn)
    a = nv.align(nv.SampleStream(nv.chunks_of(d)), 1 / 20, LAT, LON, 10.0, nv.AlignConfig(coarse_time=120, fine_time=300))
    C = true_attitude(scn, np.array([a.time_end, 120.0]))
    assert np.max(np.abs(small_angle_error(a.coarse_C_s_n, C[1]))) < 0.5 * AS
    assert np.max(np.abs(small_angle_error(a.state.C_s_n, C[0]))) < 0.5 * AS


def test_alignment_reaches_the_textbook_limits():
    """Static alignment with biases settles at tilt = -nabla^n/g (level) and heading error
    (eps_E + W sinL phi_N)/(W cosL) (gyrocompassing limit, T&W ch. 10)."""
    mount = np.radians([0.1, 0.1, 20.0])
    eps_s = np.array([0.01, 0.005, 0.0]) * DEGH
    nab_s = np.array([50.0, -30.0, 0.0]) * UG
    scn = Scenario("al2", turntable.static(1200), Site(LAT, LON, 10.0), rate_hz=20,
                   imu=ImuErrors(gyro_bias=eps_s, accel_bias=nab_s), gimbal=GimbalErrors(0.0, mount))
    d = simulate(scn)
    cfg = nv.AlignConfig(coarse_time=60, fine_time=900)
    a = nv.align(nv.SampleStream(nv.chunks_of(d)), 1 / 20, LAT, LON, 10.0, cfg)
    C = true_attitude(scn, np.array([a.time_end]))[0]
    phi = small_angle_error(a.state.C_s_n, C)
    g = earth.normal_gravity(LAT, 10.0)
    eps_n, nab_n = C @ eps_s, C @ nab_s
    W = earth.OMEGA_IE
    exp_level = np.array([nab_n[1] / g, -nab_n[0] / g])
    exp_head = (eps_n[0] + W * math.sin(LAT) * exp_level[1]) / (W * math.cos(LAT))
    np.testing.assert_allclose(phi[0:2], exp_level, atol=1.0 * AS)
    assert abs(phi[2] - exp_head) < 0.05 * abs(exp_head)
    # navigation after the alignment starts from there and runs
    r = nv.navigate(nv.chunks_of(d), 20, scn.site, scenario=scn, init="align", align_config=cfg)
    assert r.errors.time[0] == pytest.approx(a.time_end + 1.0)
    assert r.alignment is not None and r.init == "align"


# ----------------------------------------------------------------------------- analysis helpers
def test_oscillation_components_recovers_known_amplitudes():
    t = np.arange(0.0, 5 * 86400.0, 10.0)
    ws = nv.schuler_frequency(LAT)
    wf = nv.foucault_frequency(LAT)
    W = earth.OMEGA_IE
    x = 3.0 + 1e-4 * t + 100 * np.cos((ws + wf) * t + 0.3) + 40 * np.sin((ws - wf) * t) + 700 * np.cos(W * t + 1.0)
    c = nv.oscillation_components(t, x, LAT)
    assert c["schuler"] == pytest.approx(140.0, rel=1e-3)
    assert c["foucault"] == pytest.approx(40.0, rel=1e-3)
    assert c["earth"] == pytest.approx(700.0, rel=1e-3)
    short = nv.oscillation_components(t[t < 6 * 3600], x[t < 6 * 3600], LAT)
    assert short["earth"] is None and short["foucault"] is None and short["schuler"] is not None


def test_bad_inputs_are_refused():
    scn = Scenario("x", turntable.static(10), Site(LAT), rate_hz=10)
    nav = Strapdown(NavState.from_truth(scn), 0.1)
    with pytest.raises(ValueError, match="increments"):
        nav.run(np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="mode"):
        NavConfig(mode="wobbly")
    with pytest.raises(ValueError, match="rotation"):
        NavState(np.eye(3) * 2)
    with pytest.raises(ValueError, match="truth"):
        nv.navigate(nv.chunks_of(simulate(scn)), 10, scn.site, init="truth")
    with pytest.raises(ValueError, match="coarse"):
        nv.navigate(nv.chunks_of(simulate(scn)), 10, scn.site, init="align")
