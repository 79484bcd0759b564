"""``inscal calibrate --method multi-position`` on hand-held records from the independent generator: a good
record gives a parameter file (and JSON); bad inputs (too few poses, all poses about one axis, a moving log,
gravity far from the site's, saturated accelerometers) give one line, exit 2, and write nothing."""

import json
import math

import numpy as np
import pytest
from handheld_imu import generate, grade, rot
from typer.testing import CliRunner

from inscal import io
from inscal.calibrate import calibrate
from inscal.core import units
from inscal.cli.app import app
from inscal.core.earth import Site

runner = CliRunner()
RATE = 50.0
ARGS = ("--method", "multi-position", "--min-static-s", "2", "--settle-s", "0.25")


def write(path, lg, scale=1.0, clip=None):
    dv = lg.dvel * scale
    if clip is not None:  # an accelerometer that saturates at +-clip m/s^2
        dt = np.diff(np.concatenate([[0.0], lg.time]))[:, None]
        dv = np.clip(dv / dt, -clip, clip) * dt
    io.write_record(path, io.Record(lg.time, lg.dtheta, dv, None, RATE, Site(0.8, gravity_model=9.80),
                                    scenario="handheld"))
    return path


def log(seed=1, **kw):
    rng = np.random.default_rng(seed)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    return generate(rng, Mg, bg, Ma, ba, rate_hz=RATE, lat=0.8, g=9.80, arw=arw, vrw=vrw, **kw)


def refused(tmp_path, rec):
    out = tmp_path / "p.toml"
    r = runner.invoke(app, ["calibrate", str(rec), *ARGS, "--out", str(out)])
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("inscal: error:"), r.stderr
    assert not out.exists() and not any(p.name.startswith("p.toml") for p in tmp_path.iterdir())
    return lines[0]


def test_a_hand_held_record_calibrates_into_a_parameter_file(tmp_path):
    rec = write(tmp_path / "h.h5", log(n_poses=10, tremor_deg=0.5))
    out = tmp_path / "p.toml"
    r = runner.invoke(app, ["calibrate", str(rec), *ARGS, "--out", str(out), "--json"])
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["method"] == "multi-position" and out.exists()
    assert set(rep["parameters"]) >= {"gyro_scale_factor", "gyro_misalignment", "accel_bias"}
    assert rep["fit"]["consistent"]
    # the parameter file compensates the record (inscal compensate): calibrated again, it holds nothing more
    comp = tmp_path / "c.h5"
    r = runner.invoke(app, ["compensate", str(rec), "--params", str(out), "--out", str(comp)])
    assert r.exit_code == 0, r.stderr
    again = calibrate(io.read_record(comp), "multi-position", min_static=2.0, settle=0.25)
    for name, e in rep["parameters"].items():
        v, s = again.value(name), np.array([np.nan if x is None else x for x in e["sigma"]], float)
        ok = np.isfinite(s)
        assert np.all(np.abs(v[ok]) < 0.02 * units.to_si(s[ok], e["unit"])), (name, v)


@pytest.mark.parametrize("case", ["few", "one-axis", "moving", "gravity", "saturated"])
def test_bad_hand_held_records_are_refused_in_one_line(tmp_path, case):
    if case == "few":
        rec, want = write(tmp_path / "r.h5", log(n_poses=6)), "found 6 still poses, the accelerometer model needs 9"
    elif case == "one-axis":
        poses = [rot([0.0, 0.0, 1.0], 0.3) @ rot([1.0, 0.0, 0.0], 2 * math.pi * j / 10) for j in range(10)]
        rec, want = write(tmp_path / "r.h5", log(poses=poses)), "all poses turn about one axis"
    elif case == "moving":
        rec, want = write(tmp_path / "r.h5", log(n_poses=8, still_s=0.0, tremor_deg=1.0)), "found 0 still poses"
    elif case == "gravity":  # the accelerometers written in g, read as m/s^2
        rec, want = write(tmp_path / "r.h5", log(n_poses=10), scale=1 / 9.80665), "far from the site's gravity"
    else:
        rec, want = write(tmp_path / "r.h5", log(n_poses=10), clip=7.0), "saturated (flat at"
    assert want in refused(tmp_path, rec)
