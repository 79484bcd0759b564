"""The Ferraris method (six faces, three whole turns) against the independent hand-held generator: the
accelerometers exact on noise-free faces, the gyros within the sigma that holds the horizontal Earth
rate the method leaves in, noisy logs within 3 sigma; a missing face or turn is refused in one line; the
command line with the method's defaults, and the result exported in imucal's convention."""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade, rot
from typer.testing import CliRunner

from inscal import io
from inscal.calibrate import calibrate
from inscal.calibrate.windows import CalibrationError
from inscal.cli.app import app
from inscal.core.earth import Site
from inscal.io.paramfile import load_params


def face(axis, sign, heading):
    up = np.zeros(3)
    up[axis] = sign
    a = np.array([0.3, 0.5, 0.7])
    x = a - up * (a @ up)
    x /= np.linalg.norm(x)
    return (rot(up, heading) @ np.column_stack([x, np.cross(up, x), up])).T  # C_b^n, the face up


def session(kind, seed, noise, drop=None):
    rng = np.random.default_rng(seed)
    Mg, bg, Ma, ba, arw, vrw = grade(kind, rng)
    poses = [face(2, 1, 0.1), face(2, 1, 0.1), face(0, 1, 0.2), face(0, 1, 0.2), face(1, 1, 0.3), face(1, 1, 0.3),
             face(0, -1, 0.4), face(1, -1, 0.5), face(2, -1, 0.6)]
    turns = {0: ([0, 0, 1.0], 2 * math.pi), 2: ([1.0, 0, 0], -2 * math.pi), 4: ([0, 1.0, 0], 2 * math.pi)}
    if drop is not None:
        poses = poses[:drop] + poses[drop + 1:]
        turns = {k: v for k, v in turns.items() if k < drop - 1}
    lg = generate(rng, Mg, bg, Ma, ba, poses=poses, turns=turns, rate_hz=50.0, lat=0.8, g=9.8, arw=arw * noise,
                  vrw=vrw * noise, move_s=4.0)
    rec = SimpleNamespace(time=lg.time, dtheta=lg.dtheta, dvel=lg.dvel, site=Site(0.8, gravity_model=9.8))
    return rec, canonical_truth(Mg, bg, Ma, ba)


@pytest.mark.parametrize("kind,noise", [("mems", 0.0), ("tactical", 0.0), ("mems", 1.0)])
def test_ferraris_recovers_the_truth_within_its_sigma(kind, noise):
    rec, truth = session(kind, 1, noise)
    res = calibrate(rec, "ferraris", min_static=2.0, settle=0.25)
    for name, v in truth.items():
        e, s = res.value(name) - v, res.sigma[name]
        free = np.isfinite(s)
        assert np.all(np.abs(e[free]) < 3 * s[free]), (name, e / s)
        if noise == 0 and name.startswith("accel"):
            assert np.all(np.abs(e) <= 1e-9 * np.max(np.abs(v))), (name, e)


def test_a_missing_face_is_refused():
    rec, _ = session("mems", 2, 1.0, drop=8)  # no -z face (and so no third turn is needed to fail first)
    with pytest.raises(CalibrationError, match=r"no pose with -z up"):
        calibrate(rec, "ferraris", min_static=2.0, settle=0.25)


def test_ferraris_on_the_command_line_with_its_defaults_and_the_imucal_export(tmp_path):
    """``inscal calibrate --method ferraris`` with no --settle-s / --min-static-s (the method's 0.25 s and
    2 s), then ``inscal export --format imucal``: imucal's compensation (Ferraris 1995, written here from its
    documentation) gives inscal's compensated increments back to 1e-12."""
    rec, truth = session("mems", 1, 1.0)
    path = tmp_path / "f.h5"
    io.write_record(path, io.Record(rec.time, rec.dtheta, rec.dvel, None, 50.0, rec.site, scenario="ferraris"))
    r = CliRunner().invoke(app, ["calibrate", str(path), "--method", "ferraris", "--out", str(tmp_path / "p.toml")])
    assert r.exit_code == 0, r.stderr
    r = CliRunner().invoke(app, ["export", str(tmp_path / "p.toml"), "--format", "imucal", "--out",
                                 str(tmp_path / "cal.json"), "--json"])
    assert r.exit_code == 0 and json.loads(r.stdout)["dropped"] == [], r.stderr
    doc = json.loads((tmp_path / "cal.json").read_text())
    K_a, R_a, b_a, K_g, R_g, K_ga, b_g = (np.array(doc[k]) for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g"))
    imu, _, _ = load_params(tmp_path / "p.toml")
    assert np.allclose(imu.accel_bias, truth["accel_bias"], rtol=0, atol=0.01)  # the file holds the calibration
    rng = np.random.default_rng(4)
    dt = 0.02
    dth, dv = rng.uniform(-2, 2, (200, 3)) * dt, (rng.normal(0, 1, (200, 3)) + [0, 0, 9.8]) * dt
    # imucal: acc = R_a^-1 K_a^-1 (acc_raw - b_a); gyr = R_g^-1 K_g^-1 (gyr_raw - K_ga acc - b_g) [deg/s]
    acc = np.linalg.solve(K_a @ R_a, (dv / dt - b_a).T).T
    gyr = np.radians(np.linalg.solve(K_g @ R_g, (dth / dt - acc @ K_ga.T - b_g).T).T)
    cdth, cdv = imu.compensate_increments(dt, dth, dv)
    assert np.abs(gyr * dt - cdth).max() <= 1e-12 * np.abs(cdth).max()
    assert np.abs(acc * dt - cdv).max() <= 1e-12 * np.abs(cdv).max()
