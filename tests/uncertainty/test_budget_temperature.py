"""The chamber's temperature stability in the GUM budget: the coefficient dy/dT of a unit with a known
linear + quadratic (+ cubic) thermal model against the closed form ``k1 + 2 k2 dT + 3 k3 dT^2`` in field
units, and against central differences of the model's own values; the budget line (u of the arcsine
input, sensitivity, contribution, share), a stability given in degF, the notes of a curved model without
a stated temperature and of a result with thermal states, and the record's mean temperature."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from inscal.core import units
from inscal.core.thermal import ThermalModel
from inscal.io.records import Temperature
from inscal.uncertainty import budget as gum
from inscal.uncertainty.station import read_station, station_from_dict

STATION = Path(__file__).resolve().parents[1] / "data" / "station.toml"
NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias", "gimbal_nonorthogonality", "mount_attitude")
N = 28  # 3 + 6 + 3 + 3 + 6 + 3 + 1 + 3
GB, ASF, GMIS = slice(9, 12), slice(12, 15), slice(3, 9)
# the unit's thermal model in field units: gyro bias linear + quadratic, accel scale factor up to cubic,
# gyro misalignment linear; every other term constant
K1_GB, K2_GB = np.array([0.002, -0.0015, 0.0025]), np.array([1e-4, -2e-4, 5e-5])  # deg/h/degC, deg/h/degC^2
K1_ASF, K2_ASF, K3_ASF = np.array([0.5, -0.3, 0.2]), np.array([0.01, 0.02, -0.01]), np.array([1e-4, -3e-4, 2e-4])
K1_GMIS = np.array([0.1, -0.2, 0.05, 0.0, 0.3, -0.1])  # arcsec/degC
T_REF, T_C = 20.0, 35.0


def model() -> ThermalModel:
    deg_h, ppm, arcsec = (float(units.to_si(1.0, u)) for u in ("deg/h", "ppm", "arcsec"))
    return ThermalModel(t_ref=T_REF, t_min=-40.0, t_max=60.0, gyro_bias=np.array([K1_GB, K2_GB]) * deg_h,
                        accel_scale_factor=np.array([K1_ASF, K2_ASF, K3_ASF]) * ppm,
                        gyro_misalignment=np.array([K1_GMIS]) * arcsec, gyro_bias_rate=np.full(3, 1e-6))


def closed_form() -> np.ndarray:
    """dy/dT at T_C in field units per K, flat over NAMES."""
    dT = T_C - T_REF
    c = np.zeros(N)
    c[GB] = K1_GB + 2 * K2_GB * dT
    c[ASF] = K1_ASF + 2 * K2_ASF * dT + 3 * K3_ASF * dT ** 2
    c[GMIS] = K1_GMIS
    return c


def field_factors() -> np.ndarray:
    f = np.ones(N)
    for sl, u in ((slice(0, 3), "ppm"), (GMIS, "arcsec"), (GB, "deg/h"), (ASF, "ppm"), (slice(15, 21), "arcsec"),
                  (slice(21, 24), "ug"), (slice(24, 28), "arcsec")):
        f[sl] = float(units.to_si(1.0, u))
    return f


def test_slope_is_the_closed_form_and_the_models_own_difference():
    m = model()
    c = gum.temperature_coefficients(m, NAMES, T_C) / field_factors()
    np.testing.assert_allclose(c, closed_form(), rtol=1e-12, atol=0.0)
    assert np.all(c[24:] == 0) and np.all(c[:3] == 0) and np.all(c[15:24] == 0)  # constant in the model
    h = 1e-3  # central differences of the model's values (a cubic: error k3 h^2, far below the tolerance)
    for name, sl in (("gyro_bias", GB), ("accel_scale_factor", ASF), ("gyro_misalignment", GMIS)):
        fd = (m.delta(name, T_C + h - T_REF) - m.delta(name, T_C - h - T_REF)) / (2 * h)
        np.testing.assert_allclose(gum.thermal_slope(m, name, T_C), fd, rtol=1e-7)
        assert np.allclose(gum.temperature_coefficients(m, NAMES, T_C)[sl], fd, rtol=1e-7)


def fake_budget(station, temperature):
    values, sigma = np.zeros(N), np.full(N, 1e-9)
    glob = {k: np.zeros(N) for k in ("table_rate", "axis_nonorthogonality", "gravity", "latitude", "height", "time_base")}
    per = {k: np.zeros((2, 2, N)) for k in ("table_angle", "axis_wobble")}
    return gum.budget("n25", NAMES, values, sigma, math.inf, station, glob, per, temperature=temperature)


def test_the_budget_line_of_the_temperature_stability():
    st = read_station(STATION)  # arcsine, half-width 0.1 K
    temp = gum.temperature_from_model(model(), NAMES, T_C, "the thermal model of result 7", "the session's --temperature-c")
    b = fake_budget(st, temp)
    u = 0.1 / math.sqrt(2)
    cf = closed_form()
    for comp in b.components:
        flat = {"gyro_bias": 9, "accel_scale_factor": 12, "gyro_misalignment": 3}.get(comp.parameter)
        line = next(x for x in comp.contributions if x.input == "temperature_stability")
        assert (line.unit, line.distribution, line.value, line.stops) == ("K", "arcsine", None, 1)
        assert line.u == pytest.approx(u, rel=1e-12)
        want = 0.0 if flat is None else abs(cf[flat + comp.index])
        assert line.sensitivity == pytest.approx(want, rel=1e-12, abs=1e-300)
        assert line.contribution == pytest.approx(want * u, rel=1e-12, abs=1e-300)
        est = comp.contributions[0].contribution
        assert line.share == pytest.approx(line.contribution ** 2 / (line.contribution ** 2 + est ** 2), rel=1e-9)
    gb0 = b.component("gyro_bias[0]")
    assert gb0.u_c == pytest.approx(math.hypot(abs(cf[9]) * u, 1e-9 / float(units.to_si(1.0, "deg/h"))), rel=1e-12)
    note = next(n for n in b.notes if n.startswith("temperature_stability:"))
    assert "result 7" in note and "35 degC" in note and "T_ref 20 degC" in note and "gimbal_nonorthogonality" in note
    assert gum.Budget.from_dict(b.to_dict()) == b
    # the same stability in degF: u and the sensitivity in that unit, the contribution unchanged
    doc = st.to_dict()
    doc["inputs"]["temperature_stability"] = {"unit": "degF", "distribution": "arcsine", "half_width": 0.18,
                                              "source": "controller"}
    bf = fake_budget(station_from_dict(doc), temp)
    lf = next(x for x in bf.component("gyro_bias[0]").contributions if x.input == "temperature_stability")
    assert lf.unit == "degF" and lf.u == pytest.approx(0.18 / math.sqrt(2), rel=1e-12)
    assert lf.sensitivity == pytest.approx(abs(cf[9]) * 5 / 9, rel=1e-12)
    assert lf.contribution == pytest.approx(abs(cf[9]) * 0.1 / math.sqrt(2), rel=1e-12)


def test_without_a_model_or_a_temperature_and_with_thermal_states():
    st = read_station(STATION)
    b = fake_budget(st, None)  # no model: no line, the note says so
    assert all(x.input != "temperature_stability" for c in b.components for x in c.contributions)
    assert any(n.startswith("temperature_stability:") and "not propagated" in n for n in b.notes)
    curved = gum.temperature_from_model(model(), NAMES, None, "the thermal model of p.toml", "")
    assert curved.c is None and "not known" in curved.note and "gyro_bias" in curved.note
    lin = model().replace(gyro_bias=model().gyro_bias[:1], accel_scale_factor=model().accel_scale_factor[:1])
    t = gum.temperature_from_model(lin, NAMES, None, "the thermal model of p.toml", "")
    assert np.allclose(t.c[GB] / float(units.to_si(1.0, "deg/h")), K1_GB, rtol=1e-12)
    out = gum.temperature_from_model(model(), NAMES, 75.0, "m", "the record's mean temperature")
    assert "outside the model's range" in out.note
    meas = gum.temperature_measured(NAMES, 20.0)
    bm = fake_budget(st, meas)
    line = next(x for x in bm.component("gyro_bias[0]").contributions if x.input == "temperature_stability")
    assert line.sensitivity == 0.0 and line.contribution == 0.0 and line.u > 0
    assert any("sensitivity 0" in n and "measured" in n for n in bm.notes)
    with pytest.raises(ValueError, match="coefficients for 28 parameters"):
        fake_budget(st, gum.TemperatureSensitivity(np.zeros(3), "short"))


def test_the_records_mean_temperature():
    t = np.array([0.0, 1.0, 3.0, 7.0])  # uneven grid: a ramp's time-weighted mean is its middle value
    temp = Temperature(t, np.column_stack([20.0 + 0.5 * t, 30.0 + 0.5 * t]), ("a", "b"))
    assert gum.mean_temperature(temp, "b") == pytest.approx(31.75, rel=1e-14)
    assert gum.mean_temperature(temp, "") == pytest.approx(26.75, rel=1e-14)
    assert gum.mean_temperature(temp, "not-there") == pytest.approx(26.75, rel=1e-14)


def test_a_record_far_from_the_stated_temperature_is_noted():
    u = 0.1 / math.sqrt(2)
    near = gum.temperature_from_model(model(), NAMES, T_C, "m", "w", measured_c=T_C + 2.9 * u, u_t=u)
    far = gum.temperature_from_model(model(), NAMES, T_C, "m", "w", measured_c=T_C - 3.1 * u, u_t=u)
    assert "more than 3 u(T)" not in near.note and "more than 3 u(T)" in far.note
    np.testing.assert_array_equal(near.c, far.c)  # the slope stays the one at the stated temperature
