"""Thermal compensation in the navigator's streams (nav.stream.ThermalCompensation) and the 2-h
warm-up navigation: the thermal model applied at the record's temperature against the
single-temperature calibration.

The round trip is checked against the simulator's true increments (keep_truth), which the
thermal model never touches: the simulator moves its reference-temperature increments to each
temperature with the forward model, compensation must undo it and then the base errors."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from inscal import nav as nv
from inscal.core.error_model import ImuNoise
from inscal.core.thermal import ThermalError
from inscal.io.records import Temperature
from inscal.sim import scenarios
from inscal.sim.simulate import simulate
from inscal.sim.thermal import Piece, TemperatureProfile

#: hold at -10 degC for 120 s, ramp to +50 degC at 3 degC/min (corners at 120 s and 1320 s), then hold
RAMP = TemperatureProfile(-10.0, (Piece("hold", duration_s=120.0), Piece("ramp", target_c=50.0, rate_c_per_min=3.0)))
CORNERS = (120.0, 1320.0)


@pytest.fixture(scope="module")
def ramp_run():
    """The N25 twelve-position path (2489 s, rotations about every axis), noise-free, while the
    temperature ramps through the thermal model's range."""
    sc = replace(scenarios.build("n25"), noise=ImuNoise(), thermal=scenarios.thermal_model(), temperature=RAMP)
    return sc, simulate(sc, keep_truth=True)


def compensate(d, sc, temperature, chunk=1 << 19, model=None):
    comp = nv.ThermalCompensation(model or sc.thermal, sc.imu, temperature, sc.rate_hz)
    out = list(nv.compensated_chunks(nv.thermal_chunks(nv.chunks_of(d, chunk), comp), sc.imu, 1.0 / sc.rate_hz))
    return np.concatenate([o[1] for o in out]), np.concatenate([o[2] for o in out]), comp


def errors(d, dth, dv):
    return np.abs(dth - d.true_dtheta).max(axis=1), np.abs(dv - d.true_dvel).max(axis=1)


# ----------------------------------------------------------------------------- exactness
def test_true_base_and_thermal_model_give_back_the_true_increments(ramp_run):
    sc, d = ramp_run
    # ideal sensor: the profile's own T and dT/dt at the middle of each sample -> round-off, every sample
    eth, ev = errors(d, *compensate(d, sc, RAMP.at)[:2])
    assert eth.max() < 1e-16  # rad per sample (the thermal-free round trip's bound, tests/cli/test_cli_compensate.py)
    assert ev.max() < 1e-14  # m/s per sample
    # without the thermal model the same compensation misses by the thermal errors, orders of magnitude more
    c0 = list(nv.compensated_chunks(nv.chunks_of(d), sc.imu, 1.0 / sc.rate_hz))
    e0th, e0v = errors(d, np.concatenate([c[1] for c in c0]), np.concatenate([c[2] for c in c0]))
    assert e0th.max() > 1e-9 and e0v.max() > 1e-6


def test_record_readings_are_exact_where_the_interpolation_is(ramp_run):
    """The record's 1-Hz readings: linear interpolation and the 60-s least-squares slope are exact on a
    ramp and a hold, so compensation from the record is round-off there; only near the profile's corners
    (the slope's window straddles them) does the dT/dt term differ."""
    sc, d = ramp_run
    assert d.temperature.time[1] - d.temperature.time[0] == pytest.approx(1.0)
    eth, ev = errors(d, *compensate(d, sc, d.temperature)[:2])
    far = np.all([np.abs(d.time - c) > 32.0 for c in CORNERS], axis=0)
    assert far.sum() > 0.9 * d.time.size
    assert eth[far].max() < 1e-16 and ev.max() < 1e-14
    assert eth[~far].max() > 1e-12  # the slope's window across a corner: the rate term is visible


def test_chunking_does_not_change_the_numbers(ramp_run):
    sc, d = ramp_run
    one = compensate(d, sc, d.temperature, chunk=d.time.size)
    for chunk in (65536, 9973):
        other = compensate(d, sc, d.temperature, chunk=chunk)
        np.testing.assert_array_equal(one[0], other[0])
        np.testing.assert_array_equal(one[1], other[1])
    assert one[2].n_samples == d.time.size


def test_navigation_is_chunk_independent_with_the_thermal_model():
    sc = replace(scenarios.build("thermal-warmup", duration_s=900.0), noise=ImuNoise())
    d = simulate(sc)
    runs = [nv.navigate(nv.chunks_of(d, k), sc.rate_hz, sc.site, scenario=sc, params=sc.imu, thermal=sc.thermal,
                        temperature=d.temperature) for k in (1 << 19, 12345)]
    np.testing.assert_array_equal(runs[0].output.position, runs[1].output.position)
    np.testing.assert_array_equal(runs[0].output.quaternion, runs[1].output.quaternion)
    assert runs[0].thermal["samples"] == d.time.size and runs[0].thermal["samples_outside"] == 0


# ----------------------------------------------------------------------------- temperature source and range
def test_the_models_sensor_drives_it(ramp_run):
    sc, d = ramp_run
    t = d.temperature
    two = Temperature(t.time, np.column_stack([t.values[:, 0] + 7.0, t.values[:, 0]]), ("case", "gyro"))
    a = compensate(d, sc, t)[:2]
    b = compensate(d, sc, two, model=sc.thermal.replace(sensor="gyro"))[:2]
    np.testing.assert_array_equal(a[0], b[0])
    c = compensate(d, sc, two)[:2]  # no sensor named: the mean, 3.5 degC off
    assert np.abs(c[1] - a[1]).max() > 1e-9
    with pytest.raises(ThermalError, match="no temperature sensor 'board'.*case, gyro"):
        nv.ThermalCompensation(sc.thermal.replace(sensor="board"), sc.imu, two, sc.rate_hz)


def test_out_of_range_policies(ramp_run):
    sc, d = ramp_run
    narrow = sc.thermal.replace(t_min=-20.0, t_max=30.0)
    T, rate = RAMP.at(d.time - 0.5 / sc.rate_hz)
    n_out = int(np.count_nonzero(T > 30.0))
    assert n_out > 1000
    # warn: extrapolated (the same numbers as the unbounded model), counted, one warning from navigate
    w = compensate(d, sc, RAMP.at, model=narrow)
    np.testing.assert_array_equal(w[0], compensate(d, sc, RAMP.at)[0])
    assert w[2].n_outside == n_out and f"{n_out} of {d.time.size} samples" in w[2].message()
    assert "-20 .. 30 degC" in w[2].message() and "extrapolated" in w[2].message()
    # clamp: the model evaluated at the range ends (computed here with the core model directly)
    c = compensate(d, sc, RAMP.at, model=narrow.replace(out_of_range="clamp"))
    ref = narrow.to_reference(sc.imu, 1.0 / sc.rate_hz, d.dtheta, d.dvel, np.clip(T, -20.0, 30.0), rate)
    ref = sc.imu.compensate_increments(1.0 / sc.rate_hz, *ref)
    np.testing.assert_allclose(c[0], ref[0], rtol=0, atol=1e-18)
    assert "range ends" in c[2].message()
    # error: refused, before any sample when surveyed, and while streaming otherwise
    strict = narrow.replace(out_of_range="error")
    comp = nv.ThermalCompensation(strict, sc.imu, d.temperature, sc.rate_hz, where="r.h5")
    with pytest.raises(ThermalError, match=r"r\.h5: \d+ of \d+ samples lie outside .* -20 \.\. 30 degC"):
        comp.survey(float(d.time[0]), d.time.size)
    with pytest.raises(ThermalError, match="outside"):
        compensate(d, sc, RAMP.at, model=strict)
    # navigate: the warning names the count
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, scenario=sc, params=sc.imu, thermal=narrow,
                    temperature=RAMP.at)
    assert any(f"{n_out} of" in str(x.message) for x in caught)


def test_a_thermal_model_needs_a_temperature(ramp_run):
    sc, d = ramp_run
    with pytest.raises(ThermalError, match="needs the temperature"):
        nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, scenario=sc, params=sc.imu, thermal=sc.thermal)
    with pytest.raises(ValueError, match="without a thermal model"):
        nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, scenario=sc, params=sc.imu, temperature=25.0)
    with pytest.raises(ThermalError, match="finite"):
        nv.ThermalCompensation(sc.thermal, sc.imu, float("nan"), sc.rate_hz)
    # a constant temperature: the errors at that temperature, dT/dt = 0
    comp = nv.ThermalCompensation(sc.thermal, sc.imu, 35.0, sc.rate_hz)
    a, b = comp.apply(d.time[:10], d.dtheta[:10], d.dvel[:10])
    at35 = sc.thermal.errors_at(sc.imu, 35.0)
    ref = at35.compensate_increments(1.0 / sc.rate_hz, d.dtheta[:10], d.dvel[:10])
    got = sc.imu.compensate_increments(1.0 / sc.rate_hz, a, b)
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-18)
    np.testing.assert_allclose(got[1], ref[1], rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------- the warm-up navigation
def test_warmup_navigation_thermal_model_beats_single_temperature_calibration():
    """thermal-warmup (n25 IMU, static, 2 h, 20 -> 45 degC, tau 20 min), aligned on the spot (60 s coarse +
    600 s fine, while the IMU warms 11 degC), then free navigation: compensated (a) with the errors at
    20 degC only (what a calibration at one temperature gives) and (b) with them and the thermal model at
    the record's 1-Hz temperature readings.  The record is noise-free: the n25 sensor noise (0.02 deg/sqrt(h))
    alone drives a 2-h navigation 7-20 km off, which no calibration removes (bench/thermal_warmup_nav.py
    measures it, and the ratio with calibrated parameters)."""
    sc = replace(scenarios.build("thermal-warmup"), noise=ImuNoise())
    assert sc.path.duration == pytest.approx(7200.0)
    d = simulate(sc)
    kw = {"init": "align", "scenario": sc, "params": sc.imu}
    a = nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, **kw).summary["max_position_error_m"]
    b = nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, thermal=sc.thermal, temperature=d.temperature,
                    **kw).summary["max_position_error_m"]
    assert a > 2000.0  # the warm-up alone: km
    assert b * 5.0 < a
    assert b < 10.0  # left: the interpolation of the 1-Hz readings and the start of the 60-s slope window
