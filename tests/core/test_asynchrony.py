"""Gyro-accelerometer time asynchrony: exact delayed simulation, compensation, units, files."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad

from inscal.sim.simulate import write_simulation, scenario_from_record
from inscal import io
from inscal.sim import simulate as sim
from inscal.core import units
from inscal.core import turntable as tt
from inscal.calibrate.result import CalibrationResult
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise, errors_from_field, errors_to_field
from inscal.io.paramfile import load_params, save_params
from inscal.sim.scenarios import load_toml, s16_errors
from inscal.sim.simulate import Scenario, simulate
from inscal.core.earth import Site
from inscal.core.kinematics import true_rates

DEG = math.pi / 180
SITE = Site(30.686651 * DEG, 120.664265 * DEG, 12.0)
GIMBAL = GimbalErrors(20 / 3600 * DEG, np.array([0.1, 0.1, 20]) * DEG)
DT = 0.01


def _path():
    """Dwell 1 s, outer +47 deg, inner -60 deg at 10 deg/s with 50 deg/s^2 (trapezoids), dwell 1 s."""
    return tt.RotationPath("a", (tt.Move("outer", 47 * DEG, 10 * DEG, 0.5), tt.Move("inner", -60 * DEG, 10 * DEG, 1.0)),
                   accel=50 * DEG, initial_dwell=1.0, closed=False)


def _breaks(seg, a, b):
    lo, hi = min(a, b), max(a, b)
    return [lo] + [t for t in np.concatenate([[0.0], seg.t1]) if lo < t < hi] + [hi]


def _quad_window(sc, fun, a, b):
    seg = sc.path.segments()
    br = _breaks(seg, a, b)
    return sum(quad(fun, lo, hi, epsabs=1e-18, epsrel=1e-14, limit=200)[0] for lo, hi in zip(br[:-1], br[1:]))


def _picks(sc, d, tau):
    """Samples in the first dwell, acceleration, cruise, deceleration (both moves), straddling breakpoints."""
    seg = sc.path.segments()
    moving = np.flatnonzero(seg.move_index >= 0)
    picks = {0, 1, 2, d.time.size - 1, d.time.size - 2}
    for s in moving:
        mid = 0.5 * (seg.t0[s] + seg.t1[s])
        picks.add(int(round(mid / DT)))
        for tb in (seg.t0[s], seg.t1[s]):  # the shifted window straddles the breakpoint
            picks.add(int(math.floor((tb + tau) / DT)))
    return sorted(k for k in picks if 0 <= k < d.time.size)


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
@pytest.mark.parametrize("tau", [3e-3, -7e-3, 15e-3])
def test_delayed_velocity_increments_exact_against_adaptive_quadrature(tau):
    """Pure asynchrony: the measured dv of sample k is int f over [t_{k-1} - tau, t_k - tau]."""
    sc = Scenario("a", _path(), SITE, imu=ImuErrors(time_asynchrony=tau), gimbal=GIMBAL)
    d = simulate(sc, keep_truth=True)
    ref_free = simulate(replace(sc, imu=ImuErrors()))
    assert np.array_equal(d.dtheta, ref_free.dtheta)  # gyro increments not delayed
    worst = 0.0
    for k in _picks(sc, d, tau):
        a, b = d.time[k] - DT - tau, d.time[k] - tau
        for c in range(3):
            fun = lambda t: true_rates(sc, [max(t, 0.0)])[1][0, c]  # noqa: E731 (static before t = 0)
            ref = _quad_window(sc, fun, a, b)
            worst = max(worst, abs(d.dvel[k, c] - ref))
    assert worst < 1e-12, worst  # m/s


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
def test_delayed_measurement_with_all_error_terms_exact():
    """Nonlinear terms, cross-coupling, full lever arms (w x w x p and w-dot x p) on the delayed
    accelerometer time base, g-sensitivity on the gyro time base."""
    tau = 4e-3
    imu = s16_errors().replace(
        accel_lever_arm=np.array([[0.02, 0.01, -0.015], [0.005, 0.03, 0.01], [-0.01, 0.02, 0.025]]),
        time_asynchrony=tau)
    sc = Scenario("a", _path(), SITE, imu=imu, gimbal=GIMBAL)
    d = simulate(sc)

    def rates(t):
        h = 1e-5
        w, f = true_rates(sc, [t])
        wp, _ = true_rates(sc, [t + h])
        wm, _ = true_rates(sc, [t - h])
        return w[0], f[0], (wp[0] - wm[0]) / (2 * h)

    def ng(t, c):
        w, f, _ = rates(t)
        return imu.measure(w, f)[0][c]

    def na(t, c):  # accelerometer output at its own time t
        wa, fa, wda = rates(t)
        return imu.measure(wa, fa, wda)[1][c]

    for k in (130, 175, 300, 345, 600, 700, 880):
        a, b = d.time[k] - DT, d.time[k]
        for c in range(3):
            assert abs(d.dtheta[k, c] - _quad_window(sc, lambda t: ng(t, c), a, b)) < 1e-13
            assert abs(d.dvel[k, c] - _quad_window(sc, lambda t: na(t, c), a - tau, b - tau)) < 1e-11


def test_chunk_size_independent():
    noise = ImuNoise(arw=1e-5, vrw=1e-4, accel_quantization=1e-5)
    for tau in (2.5e-3, -12e-3):
        imu = s16_errors().replace(time_asynchrony=tau)
        sc = Scenario("c", _path(), SITE, imu=imu, gimbal=GIMBAL, noise=noise)
        a = simulate(sc, np.random.default_rng(3), chunk_size=77)
        b = simulate(sc, np.random.default_rng(3))
        for name in ("dtheta", "dvel", "gimbal", "time"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_zero_asynchrony_is_the_old_code_path(monkeypatch):
    """tau = 0: the asynchrony kernel never runs and the output is bit-identical to the
    pre-asynchrony formula (kernel integrals fed to measure_increments without dv_gyro)."""
    def boom(*a, **k):
        raise AssertionError("asynchrony kernel called with tau = 0")

    imu = s16_errors()
    assert imu.time_asynchrony == 0.0 and not imu.has_asynchrony
    sc = Scenario("z", _path(), SITE, imu=imu, gimbal=GIMBAL)
    monkeypatch.setattr(sim, "_asynchrony_kernel", boom)
    d = simulate(sc, chunk_size=300)
    seg = sc.path.segments()
    n = sc.n_samples
    dth, dv, f2, fx, dw = (np.empty((n, 3)) for _ in range(5))
    ww = np.empty((n, 6))
    sim._simulate_kernel(0, n, DT, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, tt.outer_axis(GIMBAL.nonorthogonality),
                         np.ascontiguousarray(tt.C_b_n(GIMBAL.mount_attitude)), SITE.earth_rate_n, SITE.gravity,
                         sim._GL_X, sim._GL_W, True, dth, dv, f2, fx, ww, dw)
    mdth, mdv = imu.measure_increments(DT, dth, dv, f2, fx, ww, dw)
    assert np.array_equal(d.dtheta, mdth) and np.array_equal(d.dvel, mdv)


@pytest.mark.parametrize("tau", [2e-3, -5e-3])
def test_simulate_then_compensate_within_bound(tau):
    """Linear errors + g-sensitivity + tau.  The compensation interpolates the integrated
    accelerometer output quadratically across the neighbouring samples (ImuErrors.compensate);
    it is exact for a force quadratic in time, so its error comes only from the jumps of f'' at
    the acceleration onsets.  Reference: the first-order bound |tau (dt + tau)| / 2 * dt * max|f''|
    with |f''| <= (alpha + w^2) g (turn of rate w, angular acceleration alpha); measured 0.17 and
    0.13 of it for the two taus."""
    base = s16_errors().replace(accel_nonlinearity=np.zeros(3), accel_cross_coupling=np.zeros(6),
                                accel_lever_arm=np.zeros(3))
    imu = base.replace(time_asynchrony=tau)
    sc = Scenario("rt", _path(), SITE, imu=imu, gimbal=GIMBAL)
    d = simulate(sc, keep_truth=True)
    cth, cdv = imu.compensate_increments(DT, d.dtheta, d.dvel)
    alpha, w = 50 * DEG, 10 * DEG
    bound = abs(tau * (DT + abs(tau))) / 2 * DT * (alpha + w * w) * SITE.gravity
    err = np.abs(cdv - d.true_dvel)[1:-1].max()  # first/last rows lack a neighbour
    assert err < 0.25 * bound, (err, bound)
    # uncorrected: ~ |tau| dt |f'| = |tau| dt w g per sample, much larger
    _, raw = base.compensate_increments(DT, d.dtheta, d.dvel)
    assert np.abs(raw - d.true_dvel).max() > 50 * err
    # residuals do not accumulate
    assert np.abs(np.sum(cdv - d.true_dvel, axis=0)).max() < 1e-12
    # the gyros see the g-sensitivity of the corrected force
    assert np.abs(cth - d.true_dtheta)[1:-1].max() < 1e-15
    # chunked compensation with the raw neighbouring samples equals one piece
    a1, b1 = imu.compensate_increments(DT, d.dtheta[:400], d.dvel[:400], next=(d.dtheta[400], d.dvel[400]))
    a2, b2 = imu.compensate_increments(DT, d.dtheta[400:], d.dvel[400:], prev=(d.dtheta[399], d.dvel[399]))
    assert np.allclose(np.vstack([b1, b2]), cdv, rtol=0, atol=1e-18)
    assert np.allclose(np.vstack([a1, a2]), cth, rtol=0, atol=1e-18)


def test_rate_compensation_with_dt():
    imu = ImuErrors(time_asynchrony=3e-3, accel_bias=[1e-3, 0, 0])
    t = np.arange(50) * DT
    f = np.stack([np.sin(t), np.cos(t), 9.8 + 0 * t], axis=1)
    fa = np.stack([np.sin(t - 3e-3), np.cos(t - 3e-3), 9.8 + 0 * t], axis=1)  # sampled at t - tau
    _, na = imu.measure(np.zeros_like(fa), fa)
    _, fc = imu.compensate(np.zeros_like(fa), na, dt=DT)
    assert np.abs(fc - f)[1:-1].max() < 3e-3 * DT**2  # quadratic interpolation: tau dt^2 |f'''| with |f'''| ~ 1
    _, f0 = imu.compensate(np.zeros_like(fa), na)  # without dt: left in
    assert np.abs(f0 - fa).max() < 1e-15


def test_validation_and_units():
    assert ImuErrors(time_asynchrony=np.float32(1e-3)).time_asynchrony == pytest.approx(1e-3)
    assert isinstance(ImuErrors(time_asynchrony=np.array(2e-3)).time_asynchrony, float)
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="time_asynchrony"):
            ImuErrors(time_asynchrony=bad)
    with pytest.raises(ValueError, match="time_asynchrony"):
        ImuErrors(time_asynchrony=[1e-3, 2e-3])
    assert units.to_si(1.5, "ms", "time") == pytest.approx(1.5e-3)
    imu, _ = errors_from_field({"time_asynchrony": 1.5})
    assert imu.time_asynchrony == pytest.approx(1.5e-3, rel=1e-15)
    imu2, _ = errors_from_field({"time_asynchrony": {"value": -0.002, "unit": "s"}})
    assert imu2.time_asynchrony == -0.002
    field = errors_to_field(imu)
    assert field["time_asynchrony"] == {"value": pytest.approx(1.5, rel=1e-15), "unit": "ms"}
    back, _ = errors_from_field({k: v for k, v in field.items() if k in ("time_asynchrony",)})
    assert back.time_asynchrony == imu.time_asynchrony
    full, _ = errors_from_field(errors_to_field(s16_errors().replace(time_asynchrony=-0.7e-3), GIMBAL))
    assert full.time_asynchrony == pytest.approx(-0.7e-3, rel=1e-15)
    with pytest.raises(ValueError, match="time_asynchrony"):
        errors_from_field({"time_asynchrony": {"value": 1.0, "unit": "deg"}})


def test_scenario_toml_and_parameter_file(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('base = "n25"\n[errors]\ntime_asynchrony = 0.25\n')
    sc = load_toml(p)
    assert sc.imu.time_asynchrony == pytest.approx(0.25e-3, rel=1e-15)
    res = CalibrationResult("test", ImuErrors(time_asynchrony=0.8e-3, accel_bias=[1e-4, 0, 0]), GimbalErrors(),
                            {"time_asynchrony": 1e-5, "accel_bias": np.full(3, 1e-6)}, ("time_asynchrony", "accel_bias"))
    out = tmp_path / "p.toml"
    save_params(out, res)
    assert 'unit = "ms"' in out.read_text()
    imu, _, meta = load_params(out)
    assert imu.time_asynchrony == pytest.approx(0.8e-3, rel=1e-14)
    assert meta["sigma"]["time_asynchrony"] == pytest.approx(1e-5, rel=1e-14)


def test_hdf5_truth_round_trip(tmp_path):
    imu = s16_errors().replace(time_asynchrony=-1.25e-3)
    sc = Scenario("h", _path(), SITE, imu=imu, gimbal=GIMBAL)
    f = tmp_path / "r.h5"
    write_simulation(f, sc, None)
    rec = io.read_record(f)
    assert rec.truth.imu.time_asynchrony == -1.25e-3
    assert np.array_equal(rec.dvel, simulate(sc).dvel)
    sc2 = scenario_from_record(rec)
    assert sc2.imu.time_asynchrony == -1.25e-3
