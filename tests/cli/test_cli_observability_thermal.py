"""``inscal observability --states 51,thermal`` (and ``--crlb``) on a scenario file with a temperature profile:
the thermal coefficient groups in field units in the table and the JSON, the temperature, and one-line errors."""

import json

import pytest
from typer.testing import CliRunner

from inscal.cli.app import app

runner = CliRunner()

#: the 17-min PSINS path while the chamber holds 0 degC for 3 min, then ramps at 4 degC/min to 40 degC and holds
SCENARIO = """base = "psins19"
[temperature]
start_c = 0.0
pieces = [{kind = "hold", duration_s = 180}, {kind = "ramp", target_c = 40, rate_c_per_min = 4}]
"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    f = tmp_path_factory.mktemp("thermal") / "chamber.toml"
    f.write_text(SCENARIO)
    return str(f)


def test_json_has_the_thermal_groups_and_the_temperature(scenario):
    r = runner.invoke(app, ["observability", scenario, "--states", "51,thermal=11101", "--json"])
    assert r.exit_code == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["n_states"] == 51 + 12 and d["states"] == "51,thermal=11101"
    par = {p["label"]: p for p in d["parameters"]}
    assert par["gyro_bias_dT1[x]"]["unit"] == "deg/h/degC" and par["gyro_bias_dT1[x]"]["prior"] == pytest.approx(0.05)
    assert par["accel_bias_dT1[z]"]["unit"] == "ug/degC" and par["accel_bias_dT1[z]"]["prior"] == pytest.approx(150)
    assert par["gyro_bias_rate[y]"]["unit"] == "deg/h/(degC/min)" and 0 < par["gyro_bias_rate[y]"]["ratio"] < 0.1
    assert "gyro_scale_factor_dT1[x]" in par and not any(k.startswith(("accel_scale_factor", "gyro_bias_dT2")) for k in par)
    t = d["temperature"]
    assert (t["t_ref"], t["t_min"], t["t_max"], t["span"]) == (20.0, 0.0, 40.0, 20.0)
    assert t["profile"]["pieces"][1] == {"kind": "ramp", "target_c": 40.0, "rate_c_per_min": 4.0}
    assert t["partners"]["gyro_bias_rate[x]"]["with"] == "gyro_bias[x]"
    assert d["groups"]["gyro_bias_dT1"]["unit"] == "deg/h/degC"


def test_table_prints_the_thermal_groups(scenario):
    # a wide console whatever the caller's COLUMNS (the units are long; an 80-column run truncates them)
    r = runner.invoke(app, ["observability", scenario, "--states", "51,thermal"], env={"COLUMNS": "160"})
    assert r.exit_code == 0, r.stderr
    for word in ("gyro_bias_dT2", "deg/h/degC^2", "accel_bias_dT3", "ug/degC^3", "gyro_bias_rate",
                 "deg/h/(degC/min)", "most correlated", "gyro_bias_rate[x]", "T_ref 20 degC", "weakest directions"):
        assert word in r.stdout, word


def test_crlb_json_and_table(scenario):
    r = runner.invoke(app, ["observability", scenario, "--states", "51,thermal", "--crlb", "--json"])
    assert r.exit_code == 0, r.stderr
    d = json.loads(r.stdout)["crlb"]
    assert d["n_params"] == 72 and d["temperature"]["span"] == 20.0
    lab = {p["label"]: p for p in d["parameters"]}
    assert lab["accel_bias_dT3[x]"]["unit"] == "ug/degC^3" and lab["accel_bias_dT3[x]"]["prior"] == pytest.approx(3000 / 8000)
    assert 0 < lab["accel_bias_dT3[x]"]["bound"] < lab["accel_bias_dT3[x]"]["prior"]
    r = runner.invoke(app, ["observability", scenario, "--states", "51,thermal", "--crlb", "--t-ref", "10"])
    assert r.exit_code == 0, r.stderr
    assert "gyro_scale_factor_dT2" in r.stdout and "ppm/degC^2" in r.stdout and "T_ref 10 degC" in r.stdout


@pytest.mark.parametrize("args,msg", [
    (["psins19", "--states", "51,thermal"], "temperature history"),
    (["psins19", "--states", "51,thermal", "--crlb"], "temperature history"),
    (["{scenario}", "--states", "51,thermal", "--t-ref", "50"], "t_ref 50 degC lies outside"),
    (["{scenario}", "--states", "51", "--t-ref", "20"], "--t-ref is the reference temperature"),
    (["{scenario}", "--states", "51,thermal=4"], "five digits"),
])
def test_errors_are_one_line(scenario, args, msg):
    r = runner.invoke(app, ["observability", *[a.format(scenario=scenario) for a in args]])
    assert r.exit_code == 2, r.stdout
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("inscal: error:") and msg in r.stderr, r.stderr
