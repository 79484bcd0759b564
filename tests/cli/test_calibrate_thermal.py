"""``inscal calibrate --method thermal-plateaus``: the parameter file's [thermal] section, the JSON's
thermal coefficients with sigma in field units, the printed model, and one-line refusals."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core import units
from inscal.core.thermal import RATE_TERM, THERMAL_TERMS
from inscal.io.paramfile import load_params

runner = CliRunner()


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("thermal")
    rec = d / "plateaus.h5"
    assert run("simulate", "thermal-plateaus", "--out", rec, "--seed", 3, "--rate-hz", 20)[0] == 0
    return d, rec


def test_parameter_file_and_json(records):
    d, data = records
    out = d / "p.toml"
    code, stdout, stderr = run("calibrate", data, "--method", "thermal-plateaus", "--per-plateau", "n25",
                               "--thermal-order", "accel_bias=3", "--t-ref", 20, "--out", out, "--json")
    assert code == 0, stderr
    rep = json.loads(stdout)
    th = rep["thermal"]
    assert (th["t_ref"], th["t_min"], th["t_max"]) == (20.0, -40.0, 60.0)
    assert set(th["terms"]) == {"gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor", RATE_TERM[0]}
    assert [r["unit"] for r in th["terms"]["accel_bias"]] == ["ug/degC", "ug/degC^2", "ug/degC^3"]
    assert th["terms"]["gyro_bias"][1]["unit"] == "deg/h/degC^2"
    assert th["terms"][RATE_TERM[0]][0]["sigma"] == [None, None, None]  # not estimated on plateaus
    fit = th["fit"]
    assert fit["per_plateau"] == "n25" and len(fit["plateaus"]) == 5
    assert fit["terms"]["accel_bias"]["dof"] == 3 * (5 - 4) and fit["terms"]["gyro_bias"]["dof"] == 3 * (5 - 3)
    # the coefficients in field units against the record's truth: within 4.5 sigma
    truth = io.read_record(data).truth.thermal
    for name, rows in th["terms"].items():
        if name == RATE_TERM[0]:
            continue
        unit = THERMAL_TERMS[name][2]
        for r in rows:
            k = r["order"]
            tru = units.from_si(getattr(truth, name)[k - 1], unit)
            z = (np.array(r["value"]) - tru) / np.array(r["sigma"])
            assert np.all(np.abs(z) < 4.5) and np.all(np.array(r["sigma"]) > 0), (name, k, z)
    # the parameter file holds the same model and sigma
    imu, _, meta = load_params(out)
    model, sig = meta["thermal"], meta["thermal_sigma"]
    assert meta["method"] == "thermal-plateaus"
    for name, rows in th["terms"].items():
        if name == RATE_TERM[0]:
            continue
        for r in rows:
            k = r["order"]
            si = units.thermal_to_si(np.array(r["value"]), r["unit"], THERMAL_TERMS[name][1], k)
            assert np.allclose(getattr(model, name)[k - 1], si, rtol=1e-12)
            assert np.allclose(sig[name][k - 1], units.thermal_to_si(np.array(r["sigma"]), r["unit"],
                                                                     THERMAL_TERMS[name][1], k), rtol=1e-12)
    assert RATE_TERM[0] not in sig and not model.has_rate  # written with NaN sigma: not estimated
    assert meta["thermal_fit"]["terms"]["accel_bias"]["order"] == 3
    assert meta["thermal_fit"]["gyro_bias_rate"].startswith("not estimated")
    assert meta["metadata"]["per_plateau"] == "n25" and meta["metadata"]["plateaus"] == 5
    # the values at T_ref: the parameters table
    assert rep["parameters"]["accel_bias"]["unit"] == "ug"
    assert np.allclose(units.from_si(imu.accel_bias, "ug"), rep["parameters"]["accel_bias"]["value"], rtol=1e-12)


def test_printed_model(records):
    d, data = records
    code, stdout, stderr = run("calibrate", data, "--method", "thermal-plateaus", "--thermal-order", "accel_bias=3",
                               "--thermal-order", "gyro_scale_factor=1", "--out", d / "q.toml")
    assert code == 0, stderr
    assert "thermal model: T_ref 20 degC, range -40 .. 60 degC, 5 plateaus at -40, -15, 10, 35, 60 degC (n25 on each)" \
        in stdout
    lines = [ln for ln in stdout.splitlines() if ln.strip().startswith("gyro_scale_factor") and "order" in ln]
    assert len(lines) == 1 and "order 1" in lines[0] and "ppm/degC" in lines[0]  # order 1 only
    # the truth's quadratic term is seen: the linear fit is flagged and its sigma widened
    assert "note: gyro_scale_factor: the order-1 fit over 5 plateaus is inconsistent" in stdout
    assert "treated as systematic" in stdout
    assert "INCONSISTENT, sigma scaled" in stdout and "gyro_bias_rate" in stdout


@pytest.mark.parametrize("args, text", [
    (["--method", "n25", "--per-plateau", "n25"], "--per-plateau: for --method thermal-plateaus, not n25"),
    (["--method", "thermal-plateaus", "--thermal-order", "gyro_bias"], "expected NAME=ORDER"),
    (["--method", "thermal-plateaus", "--thermal-order", "accel_bias=5"], "thermal order of accel_bias: 5, expected 0 .. 3"),
    (["--method", "thermal-plateaus", "--thermal-order", "gyro_bias_rate=1"], "cannot be seen on plateaus"),
    (["--method", "thermal-plateaus", "--per-plateau", "thermal-plateaus"], "not a method to run on each plateau"),
    (["--method", "thermal-plateaus", "--states", "51"], "apply to the systematic methods, not n25"),
    (["--method", "thermal-plateaus", "--t-ref", "90"], "outside the plateaus' range -40 .. 60 degC"),
    (["--method", "thermal-plateaus", "--plateau-tol", "0"], "--plateau-tol must be > 0"),
])
def test_refusals(records, args, text):
    d, data = records
    out = d / "bad.toml"
    code, stdout, stderr = run("calibrate", data, *args, "--out", out)
    assert code == 2 and text in stderr, stderr
    assert len(stderr.strip().splitlines()) == 1 and not out.exists()


def test_record_without_temperature(tmp_path):
    rec = tmp_path / "n25.h5"
    assert run("simulate", "n25", "--out", rec, "--rate-hz", 20, "--no-noise")[0] == 0
    code, _, stderr = run("calibrate", rec, "--method", "thermal-plateaus", "--out", tmp_path / "p.toml")
    assert code == 2 and "has no temperature" in stderr and len(stderr.strip().splitlines()) == 1
    assert not (tmp_path / "p.toml").exists()
