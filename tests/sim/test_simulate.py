"""IMU simulator: exactness against independent quadrature and closed forms, noise statistics."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from inscal.core import earth, units
from inscal.core import turntable as tt
from inscal.analysis.allan import allan
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
from inscal.sim.scenarios import s16_errors
from inscal.sim.simulate import Scenario, simulate, simulate_chunks
from inscal.core.earth import Site
from inscal.core.kinematics import true_attitude, true_rates

DEG = math.pi / 180
SITE = Site(30.686651 * DEG, 120.664265 * DEG, 12.0)
GIMBAL = GimbalErrors(20 / 3600 * DEG, np.array([0.1, 0.1, 20]) * DEG)


def test_static_mean_gyro_equals_projected_earth_rate():
    path = tt.RotationPath("s", (tt.Move("none", dwell=100.0),), initial=(0.7, 2.1))
    sc = Scenario("s", path, SITE, gimbal=GIMBAL)
    d = simulate(sc)
    Csn = true_attitude(sc, [50.0])[0]
    w_expected = Csn.T @ earth.earth_rate_n(SITE.latitude)
    f_expected = Csn.T @ np.array([0, 0, earth.normal_gravity(SITE.latitude, SITE.height)])
    T = d.time[-1]
    assert np.abs(d.dtheta.sum(0) / T - w_expected).max() < 1e-12  # rad/s
    assert np.abs(d.dvel.sum(0) / T - f_expected).max() < 1e-12  # m/s^2
    assert np.abs(d.dtheta - w_expected * 0.01).max() < 1e-17  # and per sample


def _single_move_scenario(axis, angle_deg, rate_dps, dwell=10.0):
    path = tt.RotationPath("m", (tt.Move(axis, angle_deg * DEG, rate_dps * DEG, dwell),), initial_dwell=dwell, closed=False)
    return Scenario("m", path, SITE, gimbal=GIMBAL)


def test_summed_increments_over_90deg_move_equal_90deg_plus_earth_rate():
    sc = _single_move_scenario("inner", 90.0, 5.0)
    d = simulate(sc)
    T = sc.path.duration
    assert d.time[-1] == pytest.approx(T)
    total = d.dtheta.sum(0)
    Csn0 = true_attitude(sc, [0.0])[0]
    w0 = Csn0.T @ earth.earth_rate_n(SITE.latitude)
    # z (inner axis): the Earth-rate component along z is invariant under the inner rotation
    assert abs(total[2] - (math.pi / 2 + w0[2] * T)) < 1e-10
    # x, y: independent adaptive quadrature of R_z(theta(t))^T w0 with the analytic profile
    seg = sc.path.segments()

    def comp(c, t):
        th = seg.angles(np.array([t]))[0][0, 1]
        cz, sz = math.cos(th), math.sin(th)
        return (cz * w0[0] + sz * w0[1]) if c == 0 else (-sz * w0[0] + cz * w0[1])

    for c in (0, 1):
        ref = sum(quad(lambda t: comp(c, t), a, b, epsabs=1e-16, epsrel=1e-13)[0] for a, b in zip(seg.t0, seg.t1))
        assert abs(total[c] - ref) < 1e-12


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")  # quad at round-off level
def test_every_increment_exact_against_adaptive_quadrature():
    """Samples inside the motion, including samples that straddle profile breakpoints."""
    sc = _single_move_scenario("outer", 47.0, 7.0, dwell=1.0)
    d = simulate(sc, keep_truth=True)
    dt = 1 / sc.rate_hz
    seg = sc.path.segments()
    inside = np.flatnonzero((d.time > seg.t0[1]) & (d.time < seg.t1[-2] + 2 * dt))
    straddle = [k for k in inside if np.any((seg.t1 > d.time[k] - dt) & (seg.t1 < d.time[k]))]
    assert len(straddle) >= 2
    picks = sorted(set(straddle) | set(inside[:: max(1, inside.size // 15)]))
    for k in picks:
        a, b = d.time[k] - dt, d.time[k]
        brk = [a] + [t for t in seg.t1 if a < t < b] + [b]
        for c in range(3):
            wref = sum(quad(lambda t: true_rates(sc, [t])[0][0, c], lo, hi, epsabs=1e-18, epsrel=1e-14)[0] for lo, hi in zip(brk[:-1], brk[1:]))
            fref = sum(quad(lambda t: true_rates(sc, [t])[1][0, c], lo, hi, epsabs=1e-18, epsrel=1e-14)[0] for lo, hi in zip(brk[:-1], brk[1:]))
            assert abs(d.true_dtheta[k, c] - wref) < 1e-15  # far below the 1e-9 rad requirement
            assert abs(d.true_dvel[k, c] - fref) < 1e-13  # far below the 1e-9 m/s requirement


def test_measured_increments_with_all_error_terms_exact():
    """Nonlinear terms, g-sensitivity and the size effect including w-dot x r, during motion."""
    imu = s16_errors().replace(accel_lever_arm=np.array([[0.02, 0.01, -0.015], [0.005, 0.03, 0.01], [-0.01, 0.02, 0.025]]))
    path = tt.RotationPath("m", (tt.Move("outer", 60 * DEG, 20 * DEG, 1.0), tt.Move("inner", 60 * DEG, 20 * DEG, 1.0)),
                   accel=30 * DEG, initial_dwell=1.0, closed=False)
    sc = Scenario("m", path, SITE, imu=imu, gimbal=GIMBAL)
    d = simulate(sc)
    dt = 0.01

    def measured_rate(t):
        h = 1e-5
        w, f = true_rates(sc, [t])
        wp, _ = true_rates(sc, [t + h])
        wm, _ = true_rates(sc, [t - h])
        ng, na = imu.measure(w[0], f[0], (wp[0] - wm[0]) / (2 * h))
        return ng, na

    seg = sc.path.segments()
    for k in (120, 152, 300, 333, 481):  # accelerating, cruising, decelerating samples
        a, b = d.time[k] - dt, d.time[k]
        brk = [a] + [t for t in seg.t1 if a < t < b] + [b]
        for c in range(3):
            ng = sum(quad(lambda t: measured_rate(t)[0][c], lo, hi, epsrel=1e-12)[0] for lo, hi in zip(brk[:-1], brk[1:]))
            na = sum(quad(lambda t: measured_rate(t)[1][c], lo, hi, epsrel=1e-12)[0] for lo, hi in zip(brk[:-1], brk[1:]))
            assert abs(d.dtheta[k, c] - ng) < 1e-13
            assert abs(d.dvel[k, c] - na) < 1e-11  # finite-difference w-dot limits the reference


def test_simulate_then_compensate_gives_back_truth():
    sc = Scenario("rt", tt.s16_table1(dwell_s=20.0), SITE, imu=s16_errors(), gimbal=GIMBAL)
    d = simulate(sc, keep_truth=True)
    w, f = true_rates(sc, d.time - 0.005)
    static = np.all(np.abs(w) < 1e-4, axis=1)  # dwell samples (rates = Earth rate only)
    cth, cdv = sc.imu.compensate_increments(0.01, d.dtheta[static], d.dvel[static])
    assert np.abs(cth - d.true_dtheta[static]).max() / (7.3e-5 * 0.01) < 1e-10
    assert np.abs(cdv - d.true_dvel[static]).max() / (9.8 * 0.01) < 1e-12


def test_chunking_does_not_change_results():
    noise = ImuNoise(arw=1e-5, vrw=1e-4, gyro_bias_instability=1e-7, accel_bias_instability=1e-5,
                     gyro_bias_tau=50.0, accel_bias_tau=20.0, gyro_quantization=1e-7, accel_quantization=1e-5, encoder_noise=1e-6)
    sc = Scenario("c", tt.n25_twelve(dwell_s=5.0, rate_tests=False), SITE, imu=s16_errors(), gimbal=GIMBAL, noise=noise)
    a = simulate(sc, np.random.default_rng(9), chunk_size=777)
    b = simulate(sc, np.random.default_rng(9))
    for name in ("dtheta", "dvel", "gimbal", "time"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    c = simulate(sc, np.random.default_rng(10))
    assert not np.array_equal(a.dtheta, c.dtheta)
    with pytest.raises(ValueError, match="seeded"):
        simulate(sc, None)


def test_quantization_carries_residual():
    q = 1e-6
    sc = Scenario("q", tt.static(20.0), SITE, noise=ImuNoise(gyro_quantization=q))
    d = simulate(sc, np.random.default_rng(0), chunk_size=333)
    exact = simulate(Scenario("q", tt.static(20.0), SITE))
    counts = d.dtheta / q
    assert np.abs(counts - np.round(counts)).max() < 1e-6
    assert np.abs(np.cumsum(d.dtheta - exact.dtheta, axis=0)).max() <= q * (1 + 1e-9)


def test_allan_recovers_arw_and_vrw_within_5_percent():
    arw, vrw = units.to_si(0.02, "deg/sqrt(h)"), units.to_si(20.0, "ug/sqrt(Hz)")
    sc = Scenario("a", tt.static(2000.0), SITE, noise=ImuNoise(arw=arw, vrw=vrw))
    d = simulate(sc, np.random.default_rng(2024))
    g = allan(d.dtheta, 100.0, white_tau_max=2.0)
    a = allan(d.dvel, 100.0, white_tau_max=2.0)
    assert g.white == pytest.approx(np.full(3, arw), rel=0.05)
    assert a.white == pytest.approx(np.full(3, vrw), rel=0.05)


def test_gauss_markov_bias_statistics():
    sigma, tau = 1e-6, 50.0
    sc = Scenario("gm", tt.static(20000.0), SITE, noise=ImuNoise(gyro_bias_instability=sigma, gyro_bias_tau=tau), rate_hz=1.0)
    d = simulate(sc, np.random.default_rng(1))
    b = d.dtheta - simulate(Scenario("gm", tt.static(20000.0), SITE, rate_hz=1.0)).dtheta  # rad per 1 s = rad/s
    assert b.std(axis=0) == pytest.approx(np.full(3, sigma), rel=0.15)
    lag = int(tau)
    r = np.mean([np.corrcoef(b[:-lag, c], b[lag:, c])[0, 1] for c in range(3)])
    assert r == pytest.approx(math.exp(-1), abs=0.1)
