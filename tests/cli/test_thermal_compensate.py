"""``inscal compensate`` / ``inscal navigate`` with a parameter file that has a thermal model: the
record's temperature drives it; the refusals are one line and leave nothing behind."""

from __future__ import annotations

import json
from dataclasses import replace

import h5py
import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import ImuNoise, errors_to_field
from inscal.core.thermal import thermal_to_field
from inscal.sim import scenarios
from inscal.sim.simulate import simulate, write_simulation
from inscal.sim.thermal import Piece, TemperatureProfile

runner = CliRunner()
#: static 300 s: 15 degC for 60 s, a ramp to 35 degC at 10 degC/min (60 .. 180 s), then 35 degC
PROFILE = TemperatureProfile(15.0, (Piece("hold", duration_s=60.0), Piece("ramp", target_c=35.0, rate_c_per_min=10.0)))
CORNERS = (60.0, 180.0)


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def one_line_error(code, stderr):
    assert code == 2, stderr
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inscal: error: "), stderr
    return lines[0]


def params_file(path, imu, thermal=None):
    doc = {"kind": "inscal-parameters", "schema_version": 1, "method": "truth", "parameters": errors_to_field(imu)}
    if thermal is not None:
        doc["thermal"] = thermal_to_field(thermal)
    path.write_text(tomli_w.dumps(doc))
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("thermal")
    sc = replace(scenarios.build("n25-static", duration_s=300.0), noise=ImuNoise(), thermal=scenarios.thermal_model(),
                 temperature=PROFILE)
    rec = d / "ramp.h5"
    write_simulation(rec, sc, None)
    cold = d / "plain.h5"  # no /temperature
    write_simulation(cold, scenarios.build("n25-static", duration_s=30.0), np.random.default_rng(1))
    return {"dir": d, "sc": sc, "rec": rec, "plain": cold,
            "thermal": params_file(d / "thermal.toml", sc.imu, sc.thermal),
            "base": params_file(d / "base.toml", sc.imu)}


def test_compensate_applies_the_thermal_model_at_the_records_temperature(files):
    sc, out = files["sc"], files["dir"] / "comp.h5"
    code, stdout, stderr = invoke("compensate", files["rec"], "--params", files["thermal"], "--out", out, "--json")
    assert code == 0, stderr
    rep = json.loads(stdout)
    assert rep["thermal"]["samples_outside"] == 0 and rep["thermal"]["temperature"] == "/temperature sensor imu"
    c = io.read_record(out)
    truth = simulate(sc, keep_truth=True)
    far = np.all([np.abs(c.time - t) > 32.0 for t in CORNERS], axis=0)
    assert far.sum() > 0.5 * c.n_samples
    assert np.abs(c.dtheta - truth.true_dtheta)[far].max() < 1e-16  # rad per sample: round-off
    assert np.abs(c.dvel - truth.true_dvel).max() < 1e-14  # m/s per sample
    # the compensated record keeps its readings and says a thermal model was applied
    src = io.read_record(files["rec"])
    np.testing.assert_array_equal(c.temperature.values, src.temperature.values)
    np.testing.assert_array_equal(c.temperature.time, src.temperature.time)
    with h5py.File(out) as h5:
        used = json.loads(h5.attrs["compensated_with"])
    assert used["thermal"]["t_ref_c"] == 20.0 and used["thermal"]["range_c"] == [-40.0, 60.0]
    # the base errors alone leave the thermal errors in (more than a thousand times the round-off above)
    out0 = files["dir"] / "comp0.h5"
    assert invoke("compensate", files["rec"], "--params", files["base"], "--out", out0)[0] == 0
    assert np.abs(io.read_record(out0).dvel - truth.true_dvel).max() > 1e-7


def test_a_record_without_temperature_is_refused_or_given_a_constant(files):
    out = files["dir"] / "c1.h5"
    line = one_line_error(*invoke("compensate", files["plain"], "--params", files["thermal"], "--out", out)[::2])
    assert "no /temperature" in line and "--temperature" in line
    assert not out.exists()
    line = one_line_error(*invoke("navigate", files["plain"], "--params", files["thermal"])[::2])
    assert "no /temperature" in line
    code, stdout, stderr = invoke("compensate", files["plain"], "--params", files["thermal"], "--out", out,
                                  "--temperature", "25", "--json")
    assert code == 0, stderr
    rep = json.loads(stdout)
    assert rep["thermal"]["temperature"] == "constant 25 degC" and rep["thermal"]["seen_c"] == [25.0, 25.0]
    # the same as compensating with the errors at 25 degC (dT/dt = 0)
    src, c = io.read_record(files["plain"]), io.read_record(out)
    at25 = files["sc"].thermal.errors_at(files["sc"].imu, 25.0)
    ref = at25.compensate_increments(1.0 / src.rate_hz, src.dtheta, src.dvel)
    np.testing.assert_allclose(c.dtheta, ref[0], rtol=0, atol=1e-18)
    np.testing.assert_allclose(c.dvel, ref[1], rtol=0, atol=1e-15)
    with h5py.File(out) as h5:
        assert "temperature" not in h5  # nothing invented
    line = one_line_error(*invoke("compensate", files["plain"], "--params", files["base"], "--out",
                                  files["dir"] / "c2.h5", "--temperature", "25")[::2])
    assert "no [thermal]" in line
    line = one_line_error(*invoke("compensate", files["plain"], "--params", files["thermal"], "--out",
                                  files["dir"] / "c3.h5", "--temperature", "400")[::2])
    assert "plausible" in line


def test_out_of_range_warns_clamps_or_refuses(files):
    d, sc = files["dir"], files["sc"]
    n_out = int(np.count_nonzero(PROFILE.at(np.arange(1, 30001) / 100.0 - 0.005)[0] > 30.0))
    for policy in ("warn", "clamp", "error"):
        p = params_file(d / f"{policy}.toml", sc.imu, sc.thermal.replace(t_min=0.0, t_max=30.0, out_of_range=policy))
        out = d / f"{policy}.h5"
        code, stdout, stderr = invoke("compensate", files["rec"], "--params", p, "--out", out)
        if policy == "error":
            line = one_line_error(code, stderr)
            assert not out.exists()
        else:
            assert code == 0, stderr
            line = stderr.strip()
            assert len(line.splitlines()) == 1 and line.startswith("inscal: warning: ")
        assert f"{n_out} of 30000 samples" in line and "0 .. 30 degC" in line and "15.00 .. 35.00 degC" in line
        assert {"warn": "extrapolated", "clamp": "range ends", "error": "not compensated"}[policy] in line
    code, stdout, stderr = invoke("navigate", files["rec"], "--params", d / "error.toml")
    assert "not compensated" in one_line_error(code, stderr)
    code, stdout, stderr = invoke("navigate", files["rec"], "--params", d / "warn.toml", "--json")
    assert code == 0 and stderr.count("extrapolated") == 1  # surveyed once, not repeated by the navigator
    assert json.loads(stdout)["thermal"]["samples_outside"] == n_out


def test_unknown_sensor_is_refused(files):
    sc = files["sc"]
    p = params_file(files["dir"] / "sensor.toml", sc.imu, sc.thermal.replace(sensor="case"))
    out = files["dir"] / "s.h5"
    line = one_line_error(*invoke("compensate", files["rec"], "--params", p, "--out", out)[::2])
    assert "no temperature sensor 'case'" in line and not out.exists()


def test_navigate_with_the_thermal_model(files):
    code, stdout, stderr = invoke("navigate", files["rec"], "--params", files["thermal"], "--json")
    assert code == 0, stderr
    rep = json.loads(stdout)
    assert rep["thermal"]["samples"] == 30000 and rep["thermal"]["temperature"] == "/temperature sensor imu"
    base = json.loads(invoke("navigate", files["rec"], "--params", files["base"], "--json")[1])
    assert base["thermal"] is None and base["max_position_error_m"] > 3.0
    # noise-free, truth init, true errors and model: left, the 60-s slope's smoothing at the ramp's corners
    assert rep["max_position_error_m"] < 0.05 * base["max_position_error_m"]
