"""``inscal calibrate --method systematic51 --states 51,thermal=GSABR``: the thermal states from the command line
on a short record simulated from a scenario file, the parameter file's [thermal] against the JSON, compensation
and the report with the (b) parameter file, and the one-line refusals."""

from __future__ import annotations

import dataclasses
import json
import tomllib

import h5py
import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core import units
from inscal.core.error_model import ImuNoise
from inscal.core.thermal import RATE_TERM, thermal_from_field
from inscal.io.paramfile import load_params
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

runner = CliRunner()
TERMS = ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor")
#: the psins19 IMU and path (17 min) at 50 Hz, errors linear in the temperature (no dT/dt term), while the
#: temperature holds 0 degC for 2 min, ramps to 40 degC at 5 degC/min and holds
SCENARIO = """
base = "psins19"
[scenario]
name = "psins19-thermal"
rate_hz = 50
[thermal]
t_ref = 20.0
t_min = -40.0
t_max = 60.0
[[thermal.terms.gyro_bias]]
order = 1
value = [0.002, -0.0015, 0.0025]
unit = "deg/h/degC"
[[thermal.terms.gyro_scale_factor]]
order = 1
value = [0.5, -0.3, 0.4]
unit = "ppm/degC"
[[thermal.terms.accel_bias]]
order = 1
value = [5.0, -4.0, 6.0]
unit = "ug/degC"
[[thermal.terms.accel_scale_factor]]
order = 1
value = [2.0, -1.5, 1.0]
unit = "ppm/degC"
[temperature]
start_c = 0.0
pieces = [{kind = "hold", duration_s = 120}, {kind = "ramp", target_c = 40, rate_c_per_min = 5}]
"""


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def one_line_error(code, stderr) -> str:
    assert code == 2, stderr
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inscal: error: "), stderr
    return lines[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("systematic-thermal")
    toml = d / "scenario.toml"
    toml.write_text(SCENARIO, encoding="utf-8")
    rec, params = d / "rec.h5", d / "p.toml"
    code, _, stderr = invoke("simulate", toml, "--out", rec, "--no-noise")
    assert code == 0, stderr
    code, stdout, stderr = invoke("calibrate", rec, "--method", "systematic51", "--states", "51,thermal=11110",
                                  "--out", params, "--json")
    assert code == 0, stderr
    return {"dir": d, "scenario": toml, "rec": rec, "params": params, "report": json.loads(stdout)}


def test_parameter_file_holds_the_jsons_thermal_model(files):
    rep = files["report"]
    th = rep["thermal"]
    assert rep["state_options"] == "51,thermal=11110" and rep["states"] == 9 + 42 + 12
    assert (th["t_ref"], th["t_min"], th["t_max"], th["sensor"]) == (20.0, 0.0, 40.0, "")
    assert set(th["terms"]) == set(TERMS)  # order 0 of the dT/dt term: not in the model
    assert all(len(rows) == 1 and rows[0]["order"] == 1 for rows in th["terms"].values())
    assert th["fit"]["method"] == "thermal states of the systematic filter (one run)"
    model, sig = thermal_from_field({k: v for k, v in th.items() if k != "fit"})
    imu, _, meta = load_params(files["params"])
    pm, ps = meta["thermal"], meta["thermal_sigma"]
    assert (pm.t_ref, pm.t_min, pm.t_max, pm.sensor, pm.out_of_range) == (20.0, 0.0, 40.0, "", "warn")
    assert set(ps) == set(sig) == set(TERMS)
    for name in TERMS:
        np.testing.assert_allclose(getattr(pm, name), getattr(model, name), rtol=1e-12, atol=0, err_msg=name)
        np.testing.assert_allclose(ps[name], sig[name], rtol=1e-12, atol=0, err_msg=name)
        assert np.all(ps[name] > 0)
    assert not pm.has_rate and RATE_TERM[0] not in ps
    assert meta["thermal_fit"]["method"] == th["fit"]["method"] and meta["thermal_fit"]["dof"] == th["fit"]["dof"]
    assert meta["metadata"]["states"] == "51,thermal=11110"
    # the values at T_ref are the parameters of the file
    np.testing.assert_allclose(units.from_si(imu.accel_bias, "ug"), rep["parameters"]["accel_bias"]["value"],
                               rtol=1e-12)
    # noise-free: the coefficients against the record's truth
    truth = io.read_record(files["rec"]).truth.thermal
    for name in TERMS:
        rel = np.abs(getattr(pm, name) - getattr(truth, name)) / np.abs(getattr(truth, name))
        assert np.all(rel < 2e-3), (name, rel)


def test_compensate_with_the_calibrated_thermal_model(files):
    d = files["dir"]
    out = d / "c.h5"
    code, stdout, stderr = invoke("compensate", files["rec"], "--params", files["params"], "--out", out, "--json")
    assert code == 0, stderr
    used = json.loads(stdout)["thermal"]
    assert used["t_ref_c"] == 20.0 and used["range_c"] == [0.0, 40.0] and used["samples_outside"] == 0
    with h5py.File(out) as h5:
        assert json.loads(h5.attrs["compensated_with"])["thermal"]["t_ref_c"] == 20.0
    # the same parameter file without [thermal]: the thermal errors stay in
    doc = tomllib.loads(files["params"].read_text(encoding="utf-8"))
    del doc["thermal"]
    base = d / "base.toml"
    base.write_bytes(tomli_w.dumps(doc).encode())
    out0 = d / "c0.h5"
    assert invoke("compensate", files["rec"], "--params", base, "--out", out0)[0] == 0
    sc = dataclasses.replace(scenarios.load_toml(files["scenario"]), noise=ImuNoise())  # as --no-noise
    truth = simulate(sc, keep_truth=True)
    c, c0 = io.read_record(out), io.read_record(out0)
    left = np.max(np.abs(c.dvel - truth.true_dvel))
    thermal = np.max(np.abs(c0.dvel - truth.true_dvel))
    assert thermal > 1e-8 and left < 1e-2 * thermal, (left, thermal)
    assert np.max(np.abs(c.dtheta - truth.true_dtheta)) < 1e-2 * np.max(np.abs(c0.dtheta - truth.true_dtheta))


def test_report_with_the_parameter_file(files):
    html = files["dir"] / "r.html"
    code, stdout, stderr = invoke("report", files["rec"], "--params", files["params"], "--out", html, "--json")
    assert code == 0, stderr
    s = json.loads(stdout)
    th = s["thermal"][str(files["params"])]
    assert (th["t_ref"], th["t_min"], th["t_max"]) == (20.0, 0.0, 40.0)
    assert set(th["terms"]) == set(TERMS)
    text = html.read_text(encoding="utf-8")
    assert "Gyro bias over temperature" in text and "Accelerometer scale factor" in text


def test_refusals(files):
    d = files["dir"]
    out = d / "bad.toml"
    line = one_line_error(*invoke("calibrate", files["rec"], "--method", "systematic51", "--states", "51,thermal=9",
                                  "--out", out)[::2])
    assert "thermal=9: expected five digits" in line and not out.exists()
    line = one_line_error(*invoke("calibrate", files["rec"], "--method", "systematic51", "--states",
                                  "51,thermal=40000", "--out", out)[::2])
    assert "the polynomial orders go up to 3" in line and not out.exists()
    plain = d / "plain.h5"
    assert invoke("simulate", "psins19", "--out", plain, "--no-noise", "--rate-hz", 20)[0] == 0
    line = one_line_error(*invoke("calibrate", plain, "--method", "systematic51", "--states", "51,thermal",
                                  "--out", out)[::2])
    assert "need the record's temperature" in line and not out.exists()
