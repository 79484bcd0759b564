"""The simulator with a thermal model: exact against the thermal model applied to a run at T_ref,
chunk-independent, reproducible, and the built-in thermal scenarios' structure."""

import dataclasses

import numpy as np
import pytest

from inscal.core.error_model import ImuNoise
from inscal.core.turntable import static
from inscal.io.recordfile import read_record
from inscal.sim.scenarios import CHAMBER_LABEL, THERMAL_PLATEAUS_C, build, thermal_model
from inscal.sim.simulate import Scenario, simulate, write_simulation
from inscal.sim.thermal import Piece, TemperatureProfile, TemperatureSensor, plateaus


def _short_ramp(noise=True):
    """The ramp scenario cut to 10 minutes of the S16 path with a fast ramp."""
    sc = build("thermal-ramp")
    path = dataclasses.replace(sc.path, moves=sc.path.moves[:3], closed=False)
    prof = TemperatureProfile(-10.0, (Piece("hold", duration_s=60.0), Piece("ramp", target_c=30.0, rate_c_per_min=5.0)))
    return dataclasses.replace(sc, path=path, temperature=prof, noise=sc.noise if noise else ImuNoise())


def test_thermal_run_is_the_reference_run_moved_to_each_temperature():
    sc = _short_ramp(noise=False)
    hot = simulate(sc, keep_truth=True)
    ref = simulate(dataclasses.replace(sc, thermal=None), keep_truth=True)
    dt = 1.0 / sc.rate_hz
    T, rate = sc.temperature.at(hot.time - 0.5 * dt)
    assert T.min() == -10.0 and T.max() == 30.0
    ng, na = sc.thermal.to_temperature(sc.imu, dt, ref.dtheta, ref.dvel, T, rate)
    np.testing.assert_array_equal(hot.dtheta, ng)
    np.testing.assert_array_equal(hot.dvel, na)
    # and back: simulate then compensate with the true model gives the run at T_ref
    g0, a0 = sc.thermal.to_reference(sc.imu, dt, hot.dtheta, hot.dvel, T, rate)
    np.testing.assert_allclose(g0, ref.dtheta, rtol=0, atol=1e-18)
    np.testing.assert_allclose(a0, ref.dvel, rtol=0, atol=1e-16)
    # the thermal errors are there: accelerometer bias moves 5 ug/degC x 30 degC on x
    assert np.max(np.abs(hot.dvel - ref.dvel)) > 1e-6


def test_thermal_noise_is_chunk_independent_and_seeded():
    sc = _short_ramp()
    a = simulate(sc, np.random.default_rng(11), chunk_size=1 << 19)
    b = simulate(sc, np.random.default_rng(11), chunk_size=7777)
    np.testing.assert_array_equal(a.dtheta, b.dtheta)
    np.testing.assert_array_equal(a.dvel, b.dvel)
    c = simulate(sc, np.random.default_rng(12))
    assert not np.array_equal(a.dtheta, c.dtheta)


def test_thermal_noise_is_the_same_noise_as_without_thermal():
    """The thermal path adds the noise in NumPy from the same draws as the compiled pass: with a zero thermal
    model the record equals the plain scenario's bit for bit."""
    sc = _short_ramp()
    zero = dataclasses.replace(sc.thermal, gyro_bias=np.zeros((0, 3)), gyro_scale_factor=np.zeros((0, 3)),
                               accel_bias=np.zeros((0, 3)), accel_scale_factor=np.zeros((0, 3)),
                               gyro_bias_rate=np.full(3, 1e-30))
    plain = simulate(dataclasses.replace(sc, thermal=None), np.random.default_rng(5))
    tiny = simulate(dataclasses.replace(sc, thermal=zero), np.random.default_rng(5))
    np.testing.assert_allclose(tiny.dtheta, plain.dtheta, rtol=0, atol=1e-18)
    np.testing.assert_allclose(tiny.dvel, plain.dvel, rtol=0, atol=1e-15)


def test_record_keeps_temperature_truth_and_profile(tmp_path):
    sc = dataclasses.replace(_short_ramp(), temperature_sensor=TemperatureSensor(("gyro", "accel"), 2.0, (0.0, 0.5),
                                                                                 0.01, 0.0625))
    p = tmp_path / "r.h5"
    write_simulation(p, sc, np.random.default_rng(2))
    rec = read_record(p)
    assert rec.temperature.sensors == ("gyro", "accel")
    assert rec.temperature.time[1] == 0.5
    assert np.all(np.abs(rec.temperature.values / 0.0625 - np.round(rec.temperature.values / 0.0625)) < 1e-9)
    T, _ = sc.temperature.at(rec.temperature.time)
    assert np.max(np.abs(rec.temperature.values[:, 1] - 0.5 - T)) < 0.1  # offset, noise 0.01, quantum 1/16
    assert rec.truth.thermal is not None
    np.testing.assert_array_equal(rec.truth.thermal.accel_bias, sc.thermal.accel_bias)
    np.testing.assert_array_equal(rec.truth.thermal.gyro_bias_rate, sc.thermal.gyro_bias_rate)
    # the sensor's child generator is spawned only when the sensor has noise: with an ideal sensor the IMU
    # noise is the plain simulation's
    ideal = dataclasses.replace(sc, temperature_sensor=TemperatureSensor())
    plain = dataclasses.replace(ideal, temperature=None, thermal=None)
    quiet = ImuNoise()
    noise_thermal = simulate(ideal, np.random.default_rng(2)).dvel - simulate(dataclasses.replace(ideal, noise=quiet)).dvel
    noise_plain = simulate(plain, np.random.default_rng(2)).dvel - simulate(dataclasses.replace(plain, noise=quiet)).dvel
    assert np.std(noise_plain) > 1e-7
    np.testing.assert_allclose(noise_thermal, noise_plain, rtol=0, atol=1e-15)


def test_scenario_with_thermal_model_needs_a_profile():
    with pytest.raises(ValueError, match="needs a temperature profile"):
        Scenario("x", static(10.0), build("n25").site, thermal=thermal_model())


def test_plateau_scenario_paths_line_up_with_the_chamber():
    """Each copy of the base path runs while the chamber holds its plateau."""
    sc = build("thermal-plateaus")
    base = build("n25").path
    assert sc.path.duration == pytest.approx(sc.temperature.duration, abs=1e-9)
    seg = sc.path.segments()
    chamber = [m for m in sc.path.moves if m.label.startswith(CHAMBER_LABEL)]
    assert len(chamber) == len(THERMAL_PLATEAUS_C) - 1 and all(m.axis == "none" for m in chamber)
    d = base.duration
    _, windows = plateaus(THERMAL_PLATEAUS_C, 1800.0, 1.0, dwell_s=d)
    first = windows[0][0]
    for (a, b), lev in zip(windows, THERMAL_PLATEAUS_C):
        a, b = a - first, b - first
        T, rate = sc.temperature.at(np.linspace(a + 1e-6, b, 50))
        np.testing.assert_allclose(T, lev, atol=1e-9)
        np.testing.assert_array_equal(rate, 0.0)
        # the gimbal moves inside the window as in the base path (same angles at the same offsets)
        tt = np.linspace(0.0, d, 200)
        diff = np.asarray(seg.angles(a + tt)) - np.asarray(base.segments().angles(tt))
        np.testing.assert_allclose(np.remainder(diff + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-9)  # whole turns apart


def test_warmup_profile_is_the_exponential():
    sc = build("thermal-warmup", duration_s=3600.0)
    t = np.array([0.0, 1200.0, 3600.0])
    T, rate = sc.temperature.at(t)
    np.testing.assert_allclose(T, 45.0 - 25.0 * np.exp(-t / 1200.0), rtol=1e-14)
    np.testing.assert_allclose(rate[1:], 25.0 / 1200.0 * np.exp(-t[1:] / 1200.0), rtol=1e-12)
