"""The temperature and the thermal model in ``inscal report``: the record's temperature and dT/dt, and each
thermal parameter's curve over the calibrated range with its 1-sigma band.  The curves and bands are
checked against the polynomial and the propagated sigma written out by hand from the field-unit
coefficients of the parameter file, and the figures against the numbers the report gives."""

from __future__ import annotations

import copy
import dataclasses
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.calibrate.result import IMU_LINEAR, CalibrationResult
from inscal.cli.app import app
from inscal.core import units
from inscal.core.thermal import thermal_from_field
from inscal.io.paramfile import save_params
from inscal.report.figures import new_figure
from inscal.report.thermal import (
    PlateauError,
    result_thermal,
    thermal_data,
    thermal_figure,
    thermal_section,
)
from inscal.sim.scenarios import THERMAL_ERRORS, build
from inscal.sim.simulate import write_simulation
from inscal.sim.thermal import TemperatureSensor

runner = CliRunner()

#: field-unit 1 sigma of each coefficient (same layout as THERMAL_ERRORS' rows) and of the values at T_ref
COEF_SIGMA = {
    "gyro_bias": [[2e-4, 1e-4, 3e-4], [3e-6, 2e-6, 1e-6]],
    "gyro_scale_factor": [[0.05, 0.04, 0.03], [1e-3, 2e-3, 5e-4]],
    "accel_bias": [[0.4, 0.2, 0.3], [4e-3, 3e-3, 2e-3], [2e-5, 1e-5, 3e-5]],
    "accel_scale_factor": [[0.1, 0.2, 0.15], [2e-3, 1e-3, 1.5e-3]],
    "gyro_misalignment": [[0.02, 0.03, 0.01, 0.02, 0.04, 0.01]],
    "gyro_bias_rate": [[0.002, 0.001, 0.003]],
}
BASE_SIGMA = {"gyro_bias": [0.004, 0.003, 0.005], "gyro_scale_factor": [1.0, 2.0, 1.5], "accel_bias": [8.0, 6.0, 7.0],
              "accel_scale_factor": [3.0, 2.0, 4.0], "gyro_misalignment": [0.5] * 6, "accel_misalignment": [0.6] * 6}
FIELD_UNIT = {"gyro_bias": "deg/h", "gyro_scale_factor": "ppm", "accel_bias": "ug", "accel_scale_factor": "ppm",
              "gyro_misalignment": "arcsec", "accel_misalignment": "arcsec"}
FIT = {"gyro_bias": {"chi2": 3.2, "dof": 2, "p_value": 0.2019},
       "terms": {"accel_bias": {"chi2": [1.0, 2.5, 0.4], "dof": [1, 1, 1], "p_value": [0.32, 0.11, 0.53]}}}
PLATEAU_T = (-40.0, 10.0, 60.0)
#: field-unit offsets of the per-plateau points from the true curve
PLATEAU_OFFSET = {"gyro_bias": [0.01, -0.02, 0.005], "accel_bias": [5.0, -3.0, 2.0]}


def field_doc() -> dict:
    """THERMAL_ERRORS with a linear gyro misalignment term and a sigma on every coefficient row."""
    doc = copy.deepcopy(THERMAL_ERRORS)
    doc["terms"]["gyro_misalignment"] = [{"order": 1, "value": [0.1, -0.2, 0.3, 0.05, -0.1, 0.2], "unit": "arcsec/degC"}]
    for name, rows in doc["terms"].items():
        for row, s in zip(rows, COEF_SIGMA[name]):
            row["sigma"] = s
    return doc


def curve(name: str, base_field, T) -> np.ndarray:
    """``p0 + sum_k c_k dT^k`` written out in field units: (len(T), size)."""
    dT = np.asarray(T, float)[:, None] - THERMAL_ERRORS["t_ref"]
    out = np.array(base_field, float)[None, :] + 0.0 * dT
    for row in field_doc()["terms"].get(name, []):
        out = out + np.asarray(row["value"])[None, :] * dT ** row["order"]
    return out


def band(name: str, T) -> np.ndarray:
    """``sqrt(sigma_0^2 + sum_k (sigma_k dT^k)^2)`` written out in field units."""
    dT = np.asarray(T, float)[:, None] - THERMAL_ERRORS["t_ref"]
    var = np.asarray(BASE_SIGMA[name], float)[None, :] ** 2 + 0.0 * dT
    for k, s in enumerate(COEF_SIGMA[name], start=1):
        var = var + (np.asarray(s)[None, :] * dT ** k) ** 2
    return np.sqrt(var)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A 10-min warm-up record (two temperature sensors, 1.5 degC apart) and a parameter file holding its
    truth, the thermal model with every sigma, per-term fits and per-plateau points."""
    tmp = tmp_path_factory.mktemp("thermal-report")
    model, tsig = thermal_from_field(field_doc())
    sc = dataclasses.replace(build("thermal-warmup", duration_s=600.0), thermal=model,
                             temperature_sensor=TemperatureSensor(names=("imu", "case"), offsets_c=(0.0, 1.5)))
    rec = tmp / "warmup.h5"
    write_simulation(rec, sc, np.random.default_rng(7))
    base_field = {n: units.from_si(np.asarray(getattr(sc.imu, n), float), FIELD_UNIT[n]) for n in FIELD_UNIT}
    plats = []
    for T in PLATEAU_T:
        vals = {n: units.to_si(curve(n, base_field[n], [T])[0] + PLATEAU_OFFSET[n], FIELD_UNIT[n]) for n in PLATEAU_OFFSET}
        sig = {n: units.to_si(band(n, [T])[0], FIELD_UNIT[n]) for n in PLATEAU_OFFSET}
        plats.append({"temperature_c": T, "values": vals, "sigma": sig})
    sigma = {n: units.to_si(np.asarray(BASE_SIGMA[n], float), FIELD_UNIT[n]) for n in BASE_SIGMA}
    res = CalibrationResult("six-position", sc.imu, sc.gimbal, sigma, IMU_LINEAR, thermal=model, thermal_sigma=tsig,
                            thermal_fit={**FIT, "plateaus": plats}, diagnostics={"plateaus": plats})
    params = tmp / "thermal.toml"
    save_params(params, res)
    return {"rec": rec, "params": params, "tmp": tmp, "sc": sc, "base_field": base_field, "result": res}


@pytest.fixture(scope="module")
def report(files):
    out = files["tmp"] / "report.html"
    r = runner.invoke(app, ["report", str(files["rec"]), "--params", str(files["params"]), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.stderr
    return json.loads(r.stdout), out.read_text(encoding="utf-8")


def test_temperature_section(report):
    """Range and dT/dt of each sensor against the warm-up's closed form 45 - 25 exp(-t / 1200 s)."""
    s, text = report
    assert s["figures"][-1] == "Temperature" and "<h2>Temperature</h2>" in text
    temp = s["temperature"]
    hi = 45.0 - 25.0 * math.exp(-600.0 / 1200.0)
    for name, off in (("imu", 0.0), ("case", 1.5)):
        assert temp["sensors"][name]["min_c"] == pytest.approx(20.0 + off, abs=1e-9)
        assert temp["sensors"][name]["max_c"] == pytest.approx(hi + off, abs=1e-9)
        # the largest slope is the 60-s window's at the start: between the rate at t = 30 s and at t = 0
        r0 = 25.0 / 1200.0 * 60.0
        assert r0 * math.exp(-30.0 / 1200.0) <= temp["sensors"][name]["max_abs_rate_c_per_min"] <= r0
        t = np.asarray(temp["series"]["time_s"])
        rate = np.asarray(temp["series"]["rate_c_per_min"][name])
        mid = (t > 40) & (t < 560)
        np.testing.assert_allclose(rate[mid], r0 * np.exp(-t[mid] / 1200.0), rtol=1e-3)
    assert temp["range_c"] == pytest.approx([20.0, hi + 1.5], abs=1e-9)
    assert f"{hi + 1.5:.2f} degC" in temp["summary"] and "max |dT/dt| 1.2" in temp["summary"]
    assert temp["summary"] in text


def test_thermal_curves_and_bands(report, files):
    """Every term's curve is base + the polynomial and its band the propagated sigma, at every plotted
    temperature; solid over -40 .. 60 degC, extended (dashed) beyond; the dT/dt term and the fits as given."""
    s, text = report
    th = s["thermal"][str(files["params"])]
    assert sorted(th["terms"]) == sorted(["gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor",
                                          "gyro_misalignment"])
    assert th["constant"] == ["accel_misalignment"]
    for name, term in th["terms"].items():
        T = np.asarray(term["temperature_c"])
        assert T.min() < -40.0 and T.max() > 60.0 and {-40.0, 20.0, 60.0} <= set(T)
        np.testing.assert_array_equal(term["in_range"], (T >= -40.0) & (T <= 60.0))
        np.testing.assert_allclose(term["value"], curve(name, files["base_field"][name], T), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(term["sigma"], band(name, T), rtol=1e-9)
        np.testing.assert_allclose(term["truth"], term["value"], rtol=1e-9, atol=1e-12)
        at_ref = T == 20.0
        np.testing.assert_allclose(np.asarray(term["sigma"])[at_ref][0], BASE_SIGMA[name], rtol=1e-9)
        assert "correlations not included" in term["caption"] and term["caption"] in text.replace("&#x27;", "'")
        for row, s_row in zip(term["coefficients"], COEF_SIGMA[name]):
            np.testing.assert_allclose(row["sigma"], s_row, rtol=1e-9)
    rate = th["rate"]
    assert rate["unit"] == "deg/h/(degC/min)"
    np.testing.assert_allclose(rate["value"], THERMAL_ERRORS["terms"]["gyro_bias_rate"][0]["value"], rtol=1e-12)
    np.testing.assert_allclose(rate["sigma"], COEF_SIGMA["gyro_bias_rate"][0], rtol=1e-12)
    assert th["terms"]["gyro_bias"]["fit"] == {"chi2": 3.2, "dof": 2, "p_value": 0.2019}
    assert th["terms"]["accel_bias"]["fit"]["chi2"] == [1.0, 2.5, 0.4]
    assert "χ²/dof = 3.2/2, p = 0.202" in text and "y: χ²/dof = 2.5/1, p = 0.11" in text
    # the plateau points, in field units: the true curve plus the offsets
    for name, off in PLATEAU_OFFSET.items():
        pts = th["terms"][name]["plateaus"]
        assert [p["temperature_c"] for p in pts] == list(PLATEAU_T)
        np.testing.assert_allclose([p["value"] for p in pts],
                                   curve(name, files["base_field"][name], PLATEAU_T) + np.asarray(off), rtol=1e-9)
        np.testing.assert_allclose([p["sigma"] for p in pts], band(name, PLATEAU_T), rtol=1e-9)
    # one figure per term in the thermal section
    assert text.count("over temperature' src='data:image/png;base64,") == len(th["terms"])
    assert "Thermal model: " in text


def test_figure_draws_the_numbers(files):
    """The figure of a term draws its curve solid inside the range and dashed beyond, and its band
    exactly value +- sigma; plateau points as error bars."""
    res = files["result"]
    data = result_thermal(res, span=(20.0, 31.5))
    term = data["terms"]["accel_bias"]
    assert len(term["plateaus"]) == len(PLATEAU_T)
    term["t_ref"] = data["t_ref"]
    plt = new_figure()
    fig = thermal_figure(term, data["record_span_c"])
    try:
        ax = fig.axes[0]
        T, v, s = (np.asarray(term[k]) for k in ("temperature_c", "value", "sigma"))
        inside = np.asarray(term["in_range"])
        solid = next(ln for ln in ax.get_lines() if ln.get_linestyle() == "-" and ln.get_label() == "x")
        y = np.asarray(solid.get_ydata(), float)
        np.testing.assert_array_equal(np.isnan(y), ~inside)
        np.testing.assert_allclose(y[inside], v[inside, 0])
        dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
        assert len(dashed) == 3  # one per component, beyond the range
        assert np.all(np.isnan(np.asarray(dashed[0].get_ydata(), float))[inside & (T > -40) & (T < 60)])
        # the first band drawn is component x inside the range: its polygon is value +- sigma at the grid points
        poly = next(c for c in ax.collections if c.__class__.__name__ in ("PolyCollection", "FillBetweenPolyCollection"))
        verts = np.concatenate([p.vertices for p in poly.get_paths()])
        x = verts[:, 0]
        assert x.min() == pytest.approx(-40.0) and x.max() == pytest.approx(60.0)
        idx = np.searchsorted(T, x)
        ok = np.isclose(verts[:, 1], v[idx, 0] + s[idx, 0], rtol=1e-12) | np.isclose(verts[:, 1], v[idx, 0] - s[idx, 0], rtol=1e-12)
        assert ok.all()
        # error bars: one container per component, at the plateau temperatures
        bars = ax.containers
        assert len(bars) == 3
        np.testing.assert_allclose(np.asarray(bars[0].lines[0].get_xdata(), float), PLATEAU_T)
    finally:
        plt.close(fig)


def test_covariance_band_and_bad_plateaus(files):
    """With a covariance the band is sqrt(J C J^T) (a correlation between the T_ref value and the slope
    narrows it on one side of T_ref and widens it on the other); malformed plateau points are one line."""
    res = files["result"]
    model = res.thermal
    s0, s1, rho = 2e-6, 1e-7, -0.6  # SI: m/s^2 and m/s^2/degC
    cov = np.tile(np.array([[s0 ** 2, rho * s0 * s1], [rho * s0 * s1, s1 ** 2]]), (6, 1, 1))
    data = thermal_data(model, res.thermal_sigma, res.imu, res.sigma, covariance={"gyro_misalignment": cov})
    term = data["terms"]["gyro_misalignment"]
    dT = np.asarray(term["temperature_c"]) - 20.0
    expect = units.from_si(np.sqrt(s0 ** 2 + 2 * rho * s0 * s1 * dT + (s1 * dT) ** 2), "arcsec")
    np.testing.assert_allclose(np.asarray(term["sigma"])[:, 2], expect, rtol=1e-9)
    assert term["correlations"] and "correlations not included" not in term["caption"]
    assert "correlations not included" in data["terms"]["gyro_bias"]["caption"]
    # an open range and no sigma at all: the curve over T_ref +- 20 degC (and the record's span), no band
    open_model = model.replace(t_min=-math.inf, t_max=math.inf)
    bare = thermal_data(open_model, None, res.imu, None, span=(15.0, 47.0))
    term = bare["terms"]["accel_bias"]
    T = np.asarray(term["temperature_c"])
    assert term["sigma"] is None and "no 1σ given" in term["caption"] and all(term["in_range"])
    assert T.min() == pytest.approx(0.0 - 0.1 * 47.0) and T.max() == pytest.approx(47.0 + 0.1 * 47.0)
    assert "<h2>Thermal model: bare</h2>" in thermal_section("bare", bare)
    with pytest.raises(PlateauError, match="plateau 1: temperature_c"):
        thermal_data(model, res.thermal_sigma, res.imu, plateaus=[{"temperature_c": 5.0}, {"values": {}}])
    with pytest.raises(PlateauError, match="plateau 0: values.gyro_bias is not 3 numbers"):
        thermal_data(model, res.thermal_sigma, res.imu, plateaus=[{"temperature_c": 5.0, "values": {"gyro_bias": [1, 2]}}])


def test_bad_plateaus_in_a_parameter_file(files):
    """Malformed per-plateau points in a parameter file's [thermal.fit] are one line naming that file, and
    no report is written."""
    res = dataclasses.replace(files["result"], thermal_fit={"plateaus": [{"temperature_c": "warm"}]})
    bad, out = files["tmp"] / "bad.toml", files["tmp"] / "bad.html"
    save_params(bad, res)
    r = runner.invoke(app, ["report", str(files["rec"]), "--params", str(bad), "--out", str(out)])
    assert r.exit_code != 0 and not out.exists()
    line = r.stderr.strip()
    assert "\n" not in line and str(bad) in line and "plateau 0: temperature_c missing or not a number" in line
