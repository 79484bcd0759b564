"""``inscal calibrate --method systematic51|systematic30``: parameter file, JSON, plots, bad input."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.core import units
from inscal.cli.app import app
from inscal.io.paramfile import load_params

runner = CliRunner()


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def psins19(tmp_path_factory):
    d = tmp_path_factory.mktemp("sys")
    out = d / "p19.h5"
    assert run("simulate", "psins19", "--out", out, "--seed", 4)[0] == 0
    return d, out


@pytest.mark.slow
def test_systematic51_json_parameter_file_and_plots(psins19):
    d, data = psins19
    plots = d / "plots"
    plots.mkdir()
    code, stdout, _ = run("calibrate", data, "--method", "systematic51", "--out", d / "p.toml", "--plots", plots,
                          "--json")
    assert code == 0, stdout
    rep = json.loads(stdout)
    # the default state set is chosen from the data: psins19 has no asynchrony, a diagonal lever arm and
    # off-diagonal g-sensitivities (1e-4 deg/h/g) far below this record's noise
    sel = rep["selection"]
    assert rep["method"] == "systematic51" and sel["base"] == "51" and sel["full"] == "51,lever9,async,levtime"
    assert sel["chosen"] == rep["state_options"] == "51,gdiag" and rep["states"] == 45 and "gyro-defined" in rep["frame"]
    assert {t["term"]: t["accepted"] for t in sel["tests"]} == {"async": False, "lever9": False, "levtime": False,
                                                                "gdiag": True, "nocross": False}
    inn = rep["innovations"]
    assert {"nis_mean", "chi2", "dof", "p_value"} <= set(inn) and 4.0 < inn["nis_mean"] < 8.0
    par = rep["parameters"]
    for name, unit in (("gyro_g_sensitivity", "deg/h/g"), ("accel_nonlinearity", "ug/g^2"),
                       ("accel_cross_coupling", "ug/g^2"), ("accel_lever_arm", "cm")):
        assert par[name]["unit"] == unit
    # errors against the simulated truth stay within a few sigma
    e = np.array(par["accel_bias"]["error"])
    s = np.array(par["accel_bias"]["sigma"])
    assert np.all(np.abs(e) < 5 * s)
    assert len(rep["plots"]) == 10 and all((plots / p.split("/")[-1]).stat().st_size > 5000 for p in rep["plots"])
    imu, gim, meta = load_params(d / "p.toml")
    assert imu.accel_nonlinearity[0] == pytest.approx(units.to_si(par["accel_nonlinearity"]["value"][0], "ug/g^2"))
    assert meta["metadata"]["states"] == "51,gdiag" and meta["metadata"]["dof"] == inn["dof"]
    assert par["gyro_g_sensitivity"]["sigma"][0][1] is None  # not estimated: off-diagonal fixed at zero (JSON null)


@pytest.mark.slow
def test_systematic30_and_options(psins19):
    d, data = psins19
    code, stdout, _ = run("calibrate", data, "--method", "systematic30", "--out", d / "p30.toml", "--json")
    assert code == 0
    rep = json.loads(stdout)
    assert rep["states"] == 30 and "accel_nonlinearity" not in rep["parameters"]
    code, stdout, _ = run("calibrate", data, "--method", "systematic51", "--states", "lever9",
                          "--out", d / "p57.toml", "--json", "--arw", 0.002, "--vrw", 5)
    assert code == 0
    rep = json.loads(stdout)
    assert rep["states"] == 57 and not rep["noise"]["estimated_from_data"]
    assert np.isfinite(rep["parameters"]["accel_lever_arm"]["sigma"]).all()


def test_bad_options_exit_2_and_write_nothing(psins19, tmp_path):
    d, data = psins19
    out = tmp_path / "x.toml"
    for args, msg in (((data, "--method", "systematic51", "--states", "51,bogus"), "unknown state option"),
                      ((data, "--method", "joint", "--states", "51"), "apply to the systematic methods"),
                      ((data, "--method", "systematic51", "--plots", tmp_path / "no" / "pe"), "nor one that can be created")):
        code, stdout, stderr = run("calibrate", *args, "--out", out)
        assert code == 2, stdout
        assert msg in (stdout + stderr)
        assert not out.exists()
