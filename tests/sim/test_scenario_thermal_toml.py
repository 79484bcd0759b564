"""[thermal] and [temperature] tables of custom scenario TOML files: the documented example loads, the
parameter file's [thermal] layout pastes as it is, a base scenario's thermal model, profile and sensor
carry over unless overridden, a simulated record carries what the file says, and bad input is one
ScenarioError line naming the file."""

import inspect
import math
import textwrap

import numpy as np
import pytest
import tomli_w

from inscal.core import units
from inscal.core.thermal import THERMAL_TERMS, thermal_to_field
from inscal import io
from inscal.sim import scenarios
from inscal.sim.scenarios import ScenarioError
from inscal.sim.simulate import write_simulation
from inscal.sim.thermal import TemperatureProfile, TemperatureSensor

SHORT = '[scenario]\nname = "t"\nrate_hz = 10\nduration_s = 120\n'
PROFILE = '[temperature]\nstart_c = -10.0\npieces = [{kind = "ramp", target_c = 10, rate_c_per_min = 20}]\n'
THERMAL = ('[thermal]\nt_ref = 20.0\n[[thermal.terms.accel_bias]]\norder = 1\nvalue = [5.0, -4.0, 6.0]\n'
           'unit = "ug/degC"\n')


def load(tmp_path, text: str, name: str = "sc.toml"):
    f = tmp_path / name
    f.write_text(text)
    return scenarios.build(str(f))


def same_model(a, b) -> bool:
    keys = ("t_ref", "t_min", "t_max", "out_of_range", "sensor")
    return all(getattr(a, k) == getattr(b, k) for k in keys) and all(
        np.array_equal(getattr(a, n), getattr(b, n)) for n in (*THERMAL_TERMS, "gyro_bias_rate"))


def test_the_documented_example_loads(tmp_path):
    doc = inspect.getdoc(scenarios)
    block = doc.split("Custom scenario files (TOML", 1)[1].split("::\n", 1)[1].split("\n\nA base scenario", 1)[0]
    sc = load(tmp_path, textwrap.dedent(block))
    assert sc.has_thermal and sc.name == "my-bench"
    assert np.allclose(sc.thermal.gyro_bias[0], units.to_si([0.002, -0.0015, 0.0025], "deg/h"), rtol=1e-15, atol=0)
    assert np.allclose(sc.thermal.gyro_bias_rate, units.to_si([0.02, -0.015, 0.025], "deg/h/(degC/min)"), rtol=1e-15)
    assert (sc.thermal.t_min, sc.thermal.t_max) == (-40.0, 60.0)
    assert [p.kind for p in sc.temperature.pieces] == ["hold", "ramp", "approach"]
    T, _ = sc.temperature.at(np.array([600.0, 600.0 + 50 * 60]))  # hold 10 min at -40, then +1 degC/min
    assert np.allclose(T, [-40.0, 10.0], rtol=0, atol=1e-12)
    assert sc.temperature_sensor == TemperatureSensor(("imu", "case"), 1.0, (0.0, -1.5), 0.01, 0.0625)


def test_a_parameter_file_thermal_table_pastes_as_it_is(tmp_path):
    """[thermal] as ``inscal calibrate`` writes it (thermal_to_field, with 1 sigma and [thermal.fit])."""
    model = scenarios.thermal_model()
    sigma = {name: np.full_like(np.asarray(getattr(model, name), dtype=float), 1e-12) for name in ("gyro_bias",)}
    table = thermal_to_field(model, sigma)
    table["fit"] = {"chi2": 3.2, "dof": 5}
    text = SHORT + tomli_w.dumps({"thermal": table}) + PROFILE
    sc = load(tmp_path, text)
    assert same_model(sc.thermal, model)


def test_a_base_scenario_carries_its_thermal_model_profile_and_sensor(tmp_path):
    base = scenarios.build("thermal-ramp")
    sc = load(tmp_path, 'base = "thermal-ramp"\n[scenario]\nname = "mine"\n')
    assert sc.name == "mine" and sc.has_thermal
    assert same_model(sc.thermal, base.thermal) and sc.temperature == base.temperature
    assert sc.temperature_sensor == base.temperature_sensor
    # the sensor's keys override one by one; the profile and the model stay
    sc = load(tmp_path, 'base = "thermal-ramp"\n[temperature.sensor]\nnoise_c = 0.02\n', "noise.toml")
    assert sc.temperature_sensor == TemperatureSensor(base.temperature_sensor.names, base.temperature_sensor.rate_hz,
                                                      base.temperature_sensor.offsets_c, 0.02, 0.0)
    assert sc.temperature == base.temperature and same_model(sc.thermal, base.thermal)
    # a new profile over the base's model
    sc = load(tmp_path, 'base = "thermal-warmup"\n' + PROFILE, "profile.toml")
    expect = TemperatureProfile.from_json(
        '{"start_c": -10.0, "pieces": [{"kind": "ramp", "target_c": 10, "rate_c_per_min": 20}]}')
    assert sc.temperature.to_json() == expect.to_json()
    assert same_model(sc.thermal, scenarios.build("thermal-warmup").thermal)
    # a new model over the base's profile
    sc = load(tmp_path, 'base = "thermal-ramp"\n' + THERMAL, "model.toml")
    assert sc.temperature == base.temperature and not np.any(sc.thermal.gyro_bias)
    assert np.allclose(sc.thermal.accel_bias[0], units.to_si([5.0, -4.0, 6.0], "ug"), rtol=1e-15, atol=0)
    # and new sensor names start with zero offsets
    sc = load(tmp_path, 'base = "thermal-ramp"\n[temperature.sensor]\nnames = ["a", "b"]\n', "names.toml")
    assert sc.temperature_sensor.names == ("a", "b") and sc.temperature_sensor.offsets_c == (0.0, 0.0)


def test_a_scenario_without_thermal_tables_has_none(tmp_path):
    sc = load(tmp_path, SHORT)
    assert sc.thermal is None and sc.temperature is None and not sc.has_thermal
    sc = load(tmp_path, SHORT + PROFILE, "profile_only.toml")  # readings without thermal errors
    assert sc.temperature is not None and sc.thermal is None and not sc.has_thermal


def test_the_simulated_record_carries_the_file_s_temperature_and_thermal_model(tmp_path):
    text = SHORT + THERMAL + PROFILE + '[temperature.sensor]\nnames = ["gyro", "case"]\noffsets_c = [0.5, -2.0]\n'
    sc = load(tmp_path, text)
    f = tmp_path / "sim.h5"
    write_simulation(f, sc, None)
    rec = io.read_record(f)
    assert same_model(rec.truth.thermal, sc.thermal)
    temp = rec.temperature
    assert temp.sensors == ("gyro", "case") and np.array_equal(temp.time, np.arange(121.0))
    # the profile written in the file, independently: -10 degC ramping at 20 degC/min to +10 (60 s), then held
    expect = np.clip(-10.0 + temp.time / 3.0, None, 10.0)
    assert np.allclose(temp.values, expect[:, None] + [0.5, -2.0], rtol=0, atol=1e-12)


#: file text -> words of the one-line error
BAD = {
    "thermal_without_profile": (SHORT + THERMAL, "[thermal] needs a temperature profile"),
    "thermal_unknown_term": (SHORT + PROFILE + '[thermal]\n[[thermal.terms.gyro_drift]]\norder = 1\nvalue = 1\n',
                             "unknown term(s) ['gyro_drift']"),
    "thermal_bad_unit": (SHORT + PROFILE + '[thermal]\n[[thermal.terms.gyro_bias]]\norder = 1\nvalue = 1\n'
                                           'unit = "ug/degC"\n', "thermal.terms.gyro_bias order 1"),
    "thermal_order_4": (SHORT + PROFILE + '[thermal]\n' + "".join(
        f'[[thermal.terms.gyro_bias]]\norder = {k}\nvalue = 1\n' for k in range(1, 5)), "expected 1 .. n with n <= 3"),
    "thermal_unknown_key": (SHORT + PROFILE + '[thermal]\nt_reference = 20\n',
                            "[thermal]: unknown key(s) ['t_reference']"),
    "thermal_sensor_not_recorded": (SHORT + PROFILE + THERMAL.replace("t_ref = 20.0\n", 't_ref = 20.0\nsensor = "x"\n'),
                                    "[thermal] sensor 'x' is not one of the recorded temperature sensors (imu"),
    "temperature_unknown_key": (SHORT + '[temperature]\nstart = 20\n', "[temperature]: unknown key(s) ['start']"),
    "pieces_without_start": (SHORT + '[temperature]\npieces = [{kind = "hold", duration_s = 5}]\n',
                             "[temperature] pieces need start_c"),
    "start_not_a_number": (SHORT + '[temperature]\nstart_c = "warm"\n', "start_c must be a number of degC"),
    "piece_unknown_key": (SHORT + '[temperature]\nstart_c = 0\npieces = [{kind = "hold", seconds = 5}]\n',
                          "[temperature.pieces[0]]: unknown key(s) ['seconds']"),
    "piece_without_kind": (SHORT + '[temperature]\nstart_c = 0\npieces = [{duration_s = 5}]\n',
                           "pieces[0] needs kind (one of hold, ramp, approach)"),
    "piece_unknown_kind": (SHORT + '[temperature]\nstart_c = 0\npieces = [{kind = "step", duration_s = 5}]\n',
                           "temperature piece 'step': expected one of hold, ramp, approach"),
    "ramp_rate_zero": (SHORT + '[temperature]\nstart_c = 0\npieces = [{kind = "ramp", target_c = 5, '
                               'rate_c_per_min = 0}]\n', "rate_c_per_min must be > 0"),
    "ramp_without_target": (SHORT + '[temperature]\nstart_c = 0\npieces = [{kind = "ramp", rate_c_per_min = 1}]\n',
                            "temperature ramp: target_c must be a finite number"),
    "pieces_not_a_list": (SHORT + '[temperature]\nstart_c = 0\npieces = 3\n', "pieces must be a list"),
    "sensor_unknown_key": (SHORT + PROFILE + '[temperature.sensor]\nrate = 1\n',
                           "[temperature.sensor]: unknown key(s) ['rate']"),
    "sensor_offsets_mismatch": (SHORT + PROFILE + '[temperature.sensor]\nnames = ["a", "b"]\noffsets_c = [1.0]\n',
                                "one offset per sensor name"),
    "sensor_rate_negative": (SHORT + PROFILE + '[temperature.sensor]\nrate_hz = -1\n', "rate_hz must be > 0"),
    "sensor_names_not_a_list": (SHORT + PROFILE + '[temperature.sensor]\nnames = "imu"\n',
                                "names must be a list of names"),
    "sensor_noise_text": (SHORT + PROFILE + '[temperature.sensor]\nnoise_c = "low"\n', "noise_c must be a number"),
    "temperature_not_a_table": ('temperature = 20\n' + SHORT, "[temperature] must be a table"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_thermal_tables_are_one_line(tmp_path, case):
    text, words = BAD[case]
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ScenarioError) as exc:
        scenarios.build(str(f))
    msg = str(exc.value)
    assert msg.startswith(f"{f}: ") and words in msg and "\n" not in msg, msg


def test_the_bad_cases_start_from_good_files(tmp_path):
    """The control: the pieces the bad files are cut from load."""
    for k, text in enumerate([SHORT, SHORT + PROFILE, SHORT + PROFILE + THERMAL,
                              SHORT + PROFILE + '[temperature.sensor]\nnames = ["a", "b"]\noffsets_c = [1.0, 2.0]\n']):
        sc = load(tmp_path, text, f"good{k}.toml")
        assert math.isclose(sc.path.duration, 120.0)
