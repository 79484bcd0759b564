"""The thermal error model (core.thermal): the forward and inverse maps against the error model evaluated
at each temperature, exact round trips, field units, and the temperature helpers."""

import math

import numpy as np
import pytest

from inscal.core import units
from inscal.core.error_model import ImuErrors
from inscal.core.thermal import (
    RATE_TERM,
    THERMAL_TERMS,
    ThermalError,
    ThermalModel,
    sample_temperature,
    select_sensor,
    temperature_rate,
    thermal_from_field,
    thermal_to_field,
)

BASE = ImuErrors(
    gyro_scale_factor=[50e-6, -40e-6, 30e-6], gyro_misalignment=np.array([20, -15, 10, -25, 15, -10]) * units.ARCSEC,
    gyro_bias=units.to_si(np.array([0.02, -0.03, 0.015]), "deg/h"),
    accel_scale_factor=[80e-6, -60e-6, 100e-6], accel_misalignment=np.array([30, -20, 25, -35, 20, -15]) * units.ARCSEC,
    accel_bias=units.to_si(np.array([50.0, -80.0, 100.0]), "ug"),
)
MODEL = ThermalModel(
    t_ref=20.0, t_min=-40.0, t_max=60.0,
    gyro_bias=units.to_si(np.array([[0.002, -0.0015, 0.0025], [2e-5, -1e-5, 1.5e-5]]), "deg/h"),
    gyro_scale_factor=np.array([[0.5, -0.3, 0.4], [0.005, 0.004, -0.003]]) * 1e-6,
    gyro_misalignment=np.array([[0.05, -0.04, 0.03, 0.06, -0.05, 0.02]]) * units.ARCSEC,
    accel_bias=units.to_si(np.array([[5.0, -4.0, 6.0], [0.05, 0.03, -0.04], [5e-4, -3e-4, 4e-4]]), "ug"),
    accel_scale_factor=np.array([[2.0, -1.5, 1.0], [0.02, -0.01, 0.015]]) * 1e-6,
    accel_misalignment=np.array([[-0.1, 0.2, 0.05, -0.05, 0.1, 0.3]]) * units.ARCSEC,
    gyro_bias_rate=units.to_si(np.array([0.02, -0.015, 0.025]), "deg/h/(degC/min)"),
)


def _inputs(n=500, seed=3):
    rng = np.random.default_rng(seed)
    dt = 0.01
    dth = rng.normal(size=(n, 3)) * 1e-3
    dv = rng.normal(size=(n, 3)) * 0.1 + np.array([0.0, 0.0, 9.8 * dt])
    T = rng.uniform(-40.0, 60.0, n)
    rate = rng.normal(size=n) * 0.02
    return dt, dth, dv, T, rate


def test_forward_equals_the_error_model_at_each_temperature():
    """to_temperature(measured at T_ref) == ImuErrors at T applied to the true input, sample by sample."""
    dt, dth, dv, T, rate = _inputs(40)
    # the true inputs u of increments measured at T_ref: N0 = M0 u + b0 dt
    u_g = np.linalg.solve(BASE.M_g, (dth - BASE.gyro_bias * dt).T).T
    u_a = np.linalg.solve(BASE.M_a, (dv - BASE.accel_bias * dt).T).T
    ng, na = MODEL.to_temperature(BASE, dt, dth, dv, T, rate)
    for k in range(len(T)):
        e = MODEL.errors_at(BASE, T[k], rate[k])
        g, a = e.measure_increments(dt, u_g[k], u_a[k])
        np.testing.assert_allclose(ng[k], g, rtol=0, atol=1e-17)
        np.testing.assert_allclose(na[k], a, rtol=0, atol=1e-15)


def test_errors_at_reference_are_the_base_errors():
    e = MODEL.errors_at(BASE, MODEL.t_ref)
    for name in ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_misalignment"):
        np.testing.assert_array_equal(getattr(e, name), getattr(BASE, name))
    # one degree above: bias moves by the sum of its coefficients
    e1 = MODEL.errors_at(BASE, MODEL.t_ref + 1.0, dTdt=0.5)
    np.testing.assert_allclose(e1.gyro_bias - BASE.gyro_bias, MODEL.gyro_bias.sum(axis=0) + 0.5 * MODEL.gyro_bias_rate,
                               rtol=1e-12)
    np.testing.assert_allclose(e1.accel_bias - BASE.accel_bias, MODEL.accel_bias.sum(axis=0), rtol=1e-12)


def test_inverse_undoes_forward_to_round_off():
    dt, dth, dv, T, rate = _inputs()
    ng, na = MODEL.to_temperature(BASE, dt, dth, dv, T, rate)
    assert np.max(np.abs(ng - dth)) > 1e-9  # the model does something
    g0, a0 = MODEL.to_reference(BASE, dt, ng, na, T, rate)
    np.testing.assert_allclose(g0, dth, rtol=0, atol=1e-17)
    np.testing.assert_allclose(a0, dv, rtol=0, atol=1e-15)


def test_linear_model_without_misalignment_terms_round_trips():
    m = MODEL.replace(gyro_misalignment=np.zeros((0, 6)), accel_misalignment=np.zeros((0, 6)))
    dt, dth, dv, T, rate = _inputs()
    ng, na = m.to_temperature(BASE, dt, dth, dv, T, rate)
    g0, a0 = m.to_reference(BASE, dt, ng, na, T, rate)
    np.testing.assert_allclose(g0, dth, rtol=0, atol=1e-17)
    np.testing.assert_allclose(a0, dv, rtol=0, atol=1e-15)


def test_zero_model_is_identity_and_delta_is_horner():
    z = ThermalModel()
    assert z.is_zero and not MODEL.is_zero
    dt, dth, dv, T, rate = _inputs(20)
    ng, na = z.to_temperature(BASE, dt, dth, dv, T, rate)
    np.testing.assert_allclose(ng, dth, atol=1e-19)
    dT = np.array([-60.0, 0.0, 1.0, 40.0])
    c = MODEL.accel_bias
    expect = np.stack([c[0] * d + c[1] * d**2 + c[2] * d**3 for d in dT])
    np.testing.assert_allclose(MODEL.delta("accel_bias", dT), expect, rtol=1e-14)


def test_field_round_trip_and_units():
    sig = {"gyro_bias": np.full((2, 3), 1e-9), RATE_TERM[0]: np.full(3, 1e-7)}
    d = thermal_to_field(MODEL, sig)
    assert d["terms"]["accel_bias"][2]["unit"] == "ug/degC^3"
    assert d["terms"]["gyro_bias"][0]["unit"] == "deg/h/degC"
    np.testing.assert_allclose(d["terms"]["gyro_bias"][0]["value"], [0.002, -0.0015, 0.0025], rtol=1e-12)
    m2, s2 = thermal_from_field(d)
    for name in THERMAL_TERMS:
        np.testing.assert_allclose(getattr(m2, name), getattr(MODEL, name), rtol=1e-14, atol=0)
    np.testing.assert_allclose(m2.gyro_bias_rate, MODEL.gyro_bias_rate, rtol=1e-14)
    np.testing.assert_allclose(s2["gyro_bias"], sig["gyro_bias"], rtol=1e-14)
    assert (m2.t_ref, m2.t_min, m2.t_max) == (20.0, -40.0, 60.0)
    # another unit of the same kind, and K for the degree
    m3, _ = thermal_from_field({"t_ref": 25, "terms": {"accel_bias": [{"order": 1, "value": 1.0, "unit": "mg/K"}]}})
    np.testing.assert_allclose(m3.accel_bias, [[units.to_si(1.0, "mg")] * 3])


@pytest.mark.parametrize("doc, message", [
    ({"terms": {"accel_bias": [{"order": 2, "value": 1.0, "unit": "ug/degC^2"}]}}, "orders"),
    ({"terms": {"accel_bias": [{"order": 1, "value": 1.0, "unit": "ug/degC^2"}]}}, r"per degree\^2, expected per degree\^1"),
    ({"terms": {"accel_bias": [{"order": 1, "value": 1.0, "unit": "deg/h/degC"}]}}, "rate unit"),
    ({"terms": {"accel_bias": [{"order": 1, "value": 1.0, "unit": "ug"}]}}, "not a per-degree unit"),
    ({"terms": {"gyro_misalignment": [{"order": 1, "value": 1.0, "unit": "arcsec/degC"},
                                      {"order": 2, "value": 1.0, "unit": "arcsec/degC^2"}]}}, "n <= 1"),
    ({"terms": {"gyro_drift": []}}, "unknown term"),
    ({"t_ref": 70, "t_min": -40, "t_max": 60}, "does not contain t_ref"),
    ({"out_of_range": "extrapolate"}, "out_of_range"),
    ({"t_ref": "warm"}, "not a number"),
])
def test_field_errors_are_one_line(doc, message):
    with pytest.raises(ValueError, match=message) as exc:
        thermal_from_field(doc)
    assert "\n" not in str(exc.value)


def test_out_of_range_policies():
    T = np.array([-50.0, 0.0, 70.0])
    assert MODEL.outside(T) == 2
    np.testing.assert_array_equal(MODEL.replace(out_of_range="clamp").effective(T), [-40.0, 0.0, 60.0])
    np.testing.assert_array_equal(MODEL.effective(T), T)
    with pytest.raises(ThermalError, match="outside the calibrated range"):
        MODEL.replace(out_of_range="error").effective(T)


def test_temperature_rate_exact_on_a_ramp_and_averages_noise():
    t = np.arange(0.0, 600.0, 1.0)
    np.testing.assert_allclose(temperature_rate(t, 20.0 + 0.05 * t), 0.05, rtol=1e-10)
    rng = np.random.default_rng(7)
    noisy = 20.0 + 0.05 * t + rng.normal(size=t.size) * 0.01
    r = temperature_rate(t, noisy)
    # least-squares slope of ~61 points 1 s apart: sigma = 0.01 / sqrt(sum (t - mean)^2) ~ 4.4e-5 degC/s
    assert np.std(r[60:-60] - 0.05) < 1e-4
    # irregular grid
    ti = np.sort(rng.uniform(0, 600, 400))
    np.testing.assert_allclose(temperature_rate(ti, 3.0 - 0.01 * ti), -0.01, rtol=1e-9)


def test_sample_temperature_is_at_the_middle_of_the_interval():
    rate = 100.0
    ts = np.arange(1, 1001) / rate
    tt = np.arange(0.0, 11.0, 1.0)
    T, r = sample_temperature(ts, rate, tt, 20.0 + 0.5 * tt)
    np.testing.assert_allclose(T, 20.0 + 0.5 * (ts - 0.005), rtol=1e-14)
    np.testing.assert_allclose(r, 0.5, rtol=1e-10)


@pytest.mark.parametrize("tt, T, message", [
    (np.arange(0.0, 5.0), 20.0 + np.arange(5.0), "covers"),
    (np.array([0.0, 2.0, 2.0, 12.0]), np.full(4, 20.0), "does not increase"),
    (np.arange(0.0, 12.0), np.r_[20.0, math.nan, np.full(10, 20.0)], "NaN"),
])
def test_sample_temperature_refuses_bad_series(tt, T, message):
    with pytest.raises(ThermalError, match=message):
        sample_temperature(np.arange(1, 1001) / 100.0, 100.0, tt, T)


def test_select_sensor():
    v = np.array([[20.0, 22.0], [21.0, 23.0]])
    np.testing.assert_array_equal(select_sensor(v, ["gyro", "accel"]), [21.0, 22.0])
    np.testing.assert_array_equal(select_sensor(v, ["gyro", "accel"], "accel"), [22.0, 23.0])
    with pytest.raises(ThermalError, match="no temperature sensor 'board'"):
        select_sensor(v, ["gyro", "accel"], "board")


def test_units_of_temperature():
    assert units.to_celsius(273.15, "K") == pytest.approx(0.0)
    assert units.to_celsius(212.0, "degF") == pytest.approx(100.0)
    assert units.to_celsius(25.0, "°C") == 25.0
    with pytest.raises(units.UnitError):
        units.to_celsius(1.0, "rankine")
    assert units.split_per_degree("ppm/degC^2") == ("ppm", 2)
    assert units.split_per_degree("deg/h/°C") == ("deg/h", 1)
    assert units.to_si(1.0, "deg/h/(degC/min)") == pytest.approx(units.DEG / 3600.0 * 60.0)
