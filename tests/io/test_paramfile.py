"""Parameter files (TOML) and the ``inscal calibrate`` command."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation
from inscal import io
from inscal.sim import scenarios
from inscal.calibrate import calibrate
from inscal.cli.app import app
from inscal.core.error_model import ImuNoise
from inscal.io.paramfile import ParamFileError, load_params, save_params

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def h5(tmp_path_factory):
    p = tmp_path_factory.mktemp("cal") / "n25.h5"
    write_simulation(p, replace(scenarios.build("n25"), noise=ImuNoise()), None)
    return p


@pytest.fixture(scope="module")
def result(h5):
    return calibrate(io.read_record(h5), "n25")


def test_round_trip(tmp_path, h5, result):
    out = tmp_path / "p.toml"
    save_params(out, result, data_file=h5.name, data_hash=io.file_hash(h5))
    imu, gim, meta = load_params(out)
    assert meta["method"] == "n25" and meta["schema_version"] == 1
    assert meta["data_hash"] == io.file_hash(h5) and meta["data_hash"].startswith("sha256:")
    assert meta["created"].endswith("Z")
    assert set(meta["estimated"]) == set(result.estimated)
    for name in ("accel_bias", "gyro_misalignment", "mount_attitude"):
        assert np.allclose(getattr(imu if name != "mount_attitude" else gim, name), result.value(name), rtol=1e-12, atol=1e-20)
        assert np.allclose(meta["sigma"][name], result.sigma[name], rtol=1e-12)
    assert gim.nonorthogonality == pytest.approx(result.gimbal.nonorthogonality, rel=1e-12)
    text = out.read_text()
    assert 'unit = "ug"' in text and 'unit = "arcsec"' in text and 'unit = "deg/h"' in text and 'unit = "ppm"' in text


def test_no_overwrite_and_atomic(tmp_path, result):
    out = tmp_path / "p.toml"
    out.write_text("keep")
    with pytest.raises(FileExistsError):
        save_params(out, result)
    assert out.read_text() == "keep"
    save_params(out, result, overwrite=True)
    assert load_params(out)[2]["method"] == "n25"
    assert [p.name for p in tmp_path.iterdir()] == ["p.toml"]  # no temporary left behind


@pytest.mark.parametrize("text,msg", [
    ("not toml [", "not a valid TOML"),
    ('kind = "other"\n', "not an inscal parameter file"),
    ('kind = "inscal-parameters"\nmethod = "n25"\n', "schema_version"),
    ('kind = "inscal-parameters"\nschema_version = 99\nmethod = "n25"\n', "newer than this inscal"),
    ('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n', r"no \[parameters\]"),
    ('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n[parameters.foo]\nvalue = 1\nunit = "ppm"\n', "unknown parameter 'foo'"),
    ('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n[parameters.accel_bias]\nvalue = [1, 2]\nunit = "ug"\n', "shape"),
    ('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n[parameters.accel_bias]\nvalue = [1, 2, 3]\nunit = "ppm"\n', "accel_bias"),
])
def test_bad_files(tmp_path, text, msg):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ParamFileError, match=msg):
        load_params(p)
    with pytest.raises(ParamFileError, match="no such"):
        load_params(tmp_path / "missing.toml")


def test_cli_json_and_file(tmp_path, h5):
    out = tmp_path / "j.toml"
    r = CliRunner().invoke(app, ["calibrate", str(h5), "--method", "joint", "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["method"] == "joint"
    p = doc["parameters"]
    assert set(p) == {"gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
                      "accel_bias", "gimbal_nonorthogonality", "mount_attitude"}
    assert p["gimbal_nonorthogonality"]["unit"] == "arcsec"
    assert abs(p["gimbal_nonorthogonality"]["value"][0] - 20.0) < 1e-5
    assert max(abs(e) for e in p["accel_bias"]["error"]) < 1e-4  # ug, noise-free
    assert load_params(out)[2]["method"] == "joint"
    # refuses to overwrite, file untouched
    before = out.read_text()
    r = CliRunner().invoke(app, ["calibrate", str(h5), "--method", "n25", "--out", str(out)])
    assert r.exit_code == 2 and "exists" in r.output and out.read_text() == before


def test_cli_bad_input_writes_nothing(tmp_path, h5):
    rec = io.read_record(h5)
    # a record holding only the first positions (no rate tests)
    short = replace(rec, time=rec.time[:70000], dtheta=rec.dtheta[:70000], dvel=rec.dvel[:70000],
                    gimbal=rec.gimbal[:70000], path=None)
    sp = tmp_path / "short.h5"
    io.write_record(sp, short)
    for method, msg in (("twelve-position", "missing 6: (180, 90), (180, 270)"), ("six-position", "missing: z axis down"),
                        # n25 runs on the inner-symmetric pairs it has; it stops at what it truly lacks
                        ("n25", "no clockwise/counter-clockwise rate-test pair")):
        out = tmp_path / f"{method}.toml"
        r = CliRunner().invoke(app, ["calibrate", str(sp), "--method", method, "--out", str(out)])
        assert r.exit_code == 2 and msg in r.output, r.output
        assert not out.exists()
    # a gimbal channel with a jump
    g = rec.gimbal.copy()
    g[120000:, 1] += 1.0 * DEG
    jp = tmp_path / "jump.h5"
    io.write_record(jp, replace(rec, gimbal=g))
    out = tmp_path / "jump.toml"
    r = CliRunner().invoke(app, ["calibrate", str(jp), "--method", "joint", "--out", str(out)])
    assert r.exit_code == 2 and "the inner by 1 deg" in r.output and "a jump or glitch" in r.output, r.output
    assert not out.exists()
    r = CliRunner().invoke(app, ["calibrate", str(jp), "--method", "joint", "--out", str(out), "--skip-encoder-check"])
    assert r.exit_code == 2 and "inner (theta_z) jumps by 3600.0 arcsec" in r.output, r.output
    assert not out.exists()
    r = CliRunner().invoke(app, ["calibrate", str(h5), "--method", "eight-position", "--out", str(tmp_path / "x.toml")])
    assert r.exit_code == 2 and "unknown method" in r.output
