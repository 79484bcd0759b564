"""The simulate/allan CLI and the HDF5 record format: outputs, JSON, and bad input."""

import json
import math
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app

runner = CliRunner()


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def test_simulate_s16_json_and_read_back(tmp_path):
    out = tmp_path / "s16.h5"
    code, stdout, _ = run("simulate", "s16", "--out", out, "--seed", 3, "--json")
    assert code == 0
    s = json.loads(stdout)
    assert s["samples"] == 386100 and s["rate_hz"] == 100 and s["path"] == "s16-table1"
    assert s["duration_s"] == pytest.approx(3861.0)
    rec = io.read_record(out)
    assert rec.n_samples == 386100 and rec.truth is not None and rec.path.name == "s16-table1"
    assert rec.truth.imu.accel_lever_arm[0, 0] == pytest.approx(0.02)
    assert rec.gimbal.shape == (386100, 2)
    # the same seed reproduces the file's samples; another seed does not
    out2 = tmp_path / "again.h5"
    assert run("simulate", "s16", "--out", out2, "--seed", 3)[0] == 0
    assert np.array_equal(io.read_record(out2).dtheta, rec.dtheta)


def test_simulate_n25_and_duration_option(tmp_path):
    code, stdout, _ = run("simulate", "static-24h", "--duration-h", 0.01, "--rate-hz", 50, "--out", tmp_path / "s.h5", "--json")
    assert code == 0 and json.loads(stdout)["samples"] == 1800
    code, stdout, _ = run("simulate", "n25", "--out", tmp_path / "n25.h5", "--json")
    assert code == 0 and json.loads(stdout)["path"] == "n25-twelve"
    rec = io.read_record(tmp_path / "n25.h5")
    assert rec.truth.gimbal.nonorthogonality == pytest.approx(20 / 3600 * math.pi / 180)


def _one_line_error(code, stderr):
    assert code != 0
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inscal: error:"), stderr
    return lines[0]


@pytest.mark.parametrize("toml, msg", [
    ("[scenario\nname = 'x'", "malformed TOML"),
    ("[scenario]\nrate_hz = -100\n", "rate_hz must be positive"),
    ("[path]\nmoves = [{axis = 'outer', angle_deg = 90, rate_dps = 5, dwell_s = 10}]\n", "not at its start"),
    ("[path]\nmoves = [{axis = 'outer', angle_deg = 90, rate_dps = -5}, {axis = 'outer', angle_deg = -90, rate_dps = 5}]\n", "rate must be > 0"),
    ("[errors]\ngyro_bias = {value = [1, 1, 1], unit = 'arcsec'}\n", "angle unit"),
    ("[errors]\ngyro_drift = [1, 1, 1]\n", "unknown parameter"),
    ("[site]\nlatitude = 30\n", "unknown key"),
    ("schema_version = 99\n", "schema_version 99"),
])
def test_bad_scenario_files_exit_nonzero_and_write_nothing(tmp_path, toml, msg):
    f = tmp_path / "bad.toml"
    f.write_text(toml)
    out = tmp_path / "out.h5"
    code, _, stderr = run("simulate", f, "--out", out)
    line = _one_line_error(code, stderr)
    assert msg in line
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out.h5")]


def test_bad_arguments(tmp_path):
    out = tmp_path / "o.h5"
    assert "unknown scenario" in _one_line_error(*run("simulate", "s17", "--out", out)[::2])
    assert "--rate-hz must be positive" in _one_line_error(*run("simulate", "n25", "--rate-hz", -5, "--out", out)[::2])
    assert "fixed path" in _one_line_error(*run("simulate", "s16", "--duration-h", 2, "--out", out)[::2])
    assert "does not exist" in _one_line_error(*run("simulate", "n25", "--out", tmp_path / "nope" / "o.h5")[::2])
    assert not out.exists()
    out.write_bytes(b"user data")
    assert "exists" in _one_line_error(*run("simulate", "n25", "--out", out)[::2])
    assert out.read_bytes() == b"user data"  # never overwritten without --force
    assert run("simulate", "static", "--duration-h", 0.001, "--out", out, "--force")[0] == 0
    assert io.read_record(out).n_samples == 360


def test_custom_toml_scenario(tmp_path):
    f = tmp_path / "my.toml"
    f.write_text("""
base = "n25"
[scenario]
name = "bench-7"
rate_hz = 200
[site]
latitude_deg = 45.0
[errors]
gimbal_nonorthogonality = {value = 0.01, unit = "deg"}
accel_bias = [10, 20, 30]
[noise]
arw = 0.001
[path]
accel_dps2 = 20
moves = [{axis = "inner", angle_deg = 180, rate_dps = 10, dwell_s = 5},
         {axis = "inner", angle_deg = -180, rate_dps = 10, dwell_s = 5}]
""")
    out = tmp_path / "c.h5"
    code, stdout, stderr = run("simulate", f, "--out", out, "--json")
    assert code == 0, stderr
    s = json.loads(stdout)
    assert s["scenario"] == "bench-7" and s["rate_hz"] == 200
    rec = io.read_record(out)
    assert rec.site.latitude == pytest.approx(math.radians(45))
    assert rec.truth.gimbal.nonorthogonality == pytest.approx(math.radians(0.01))
    assert rec.truth.imu.accel_bias[2] == pytest.approx(30e-6 * 9.80665)
    assert rec.truth.imu.gyro_scale_factor[0] == pytest.approx(50e-6)  # inherited from base n25
    assert rec.truth.noise.arw[0] == pytest.approx(0.001 * math.pi / 180 / 60)


@pytest.fixture(scope="module")
def small_record(tmp_path_factory):
    p = tmp_path_factory.mktemp("rec") / "r.h5"
    assert run("simulate", "static", "--duration-h", 0.01, "--out", p)[0] == 0
    return p


def _copy_and_edit(src, dst, fn):
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as h5:
        fn(h5)
    return dst


def test_reader_refuses_bad_files(small_record, tmp_path):
    p = _copy_and_edit(small_record, tmp_path / "nan.h5", lambda h: h["dvel"].__setitem__((10, 1), np.nan))
    with pytest.raises(io.DataFileError, match="NaN.*sample 10"):
        io.read_record(p)

    def gap(h):
        t = h["time"][()]
        t[100:] += 0.5
        h["time"][:] = t
    with pytest.raises(io.DataFileError, match="not uniform"):
        io.read_record(_copy_and_edit(small_record, tmp_path / "gap.h5", gap))
    with pytest.raises(io.DataFileError, match="schema version 7"):
        io.read_record(_copy_and_edit(small_record, tmp_path / "v.h5", lambda h: h.attrs.__setitem__("schema_version", 7)))
    with pytest.raises(io.DataFileError, match="in 'deg'"):
        io.read_record(_copy_and_edit(small_record, tmp_path / "u.h5",
                                      lambda h: h.attrs.__setitem__("units", json.dumps({**io.UNITS, "dtheta": "deg"}))))
    trunc = tmp_path / "trunc.h5"
    data = small_record.read_bytes()
    trunc.write_bytes(data[: len(data) // 2])
    with pytest.raises(io.DataFileError, match="truncated"):
        io.read_record(trunc)
    with pytest.raises(io.DataFileError, match="no such file"):
        io.read_record(tmp_path / "missing.h5")


def test_iter_chunks_matches_read_record(small_record):
    rec = io.read_record(small_record)
    parts = list(io.iter_chunks(small_record, chunk_size=1000))
    assert np.array_equal(np.concatenate([p[1] for p in parts]), rec.dtheta)
    assert np.array_equal(np.concatenate([p[0] for p in parts]), rec.time)


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "x.h5"
    with pytest.raises(RuntimeError):
        with io.atomic_path(target) as tmp:
            tmp.write_bytes(b"partial")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_allan_cli(tmp_path):
    f = tmp_path / "n.toml"
    f.write_text("[scenario]\nduration_s = 600\n[noise]\narw = 0.02\nvrw = 20\n")
    rec = tmp_path / "n.h5"
    assert run("simulate", f, "--out", rec)[0] == 0
    code, stdout, stderr = run("allan", rec, "--json", "--plot", tmp_path / "a.png", "--model", "WN")
    assert code == 0, stderr
    r = json.loads(stdout)
    assert r["arw_deg_rth"] == pytest.approx([0.02] * 3, rel=0.1)
    assert r["vrw_ug_rthz"] == pytest.approx([20] * 3, rel=0.1)
    assert (tmp_path / "a.png").stat().st_size > 1000
    assert "exists" in _one_line_error(*run("allan", rec, "--plot", tmp_path / "a.png")[::2])


def test_console_script_installed():
    exe = os.path.join(os.path.dirname(sys.executable), "inscal")
    r = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "simulate" in r.stdout
