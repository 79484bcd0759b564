"""The Ferraris method (six faces, three whole turns) against the independent hand-held generator: the
accelerometers exact on noise-free faces, the gyros within the sigma that holds the horizontal Earth
rate the method leaves in, noisy logs within 3 sigma; a missing face or turn is refused in one line."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade, rot

from inscal.calibrate import calibrate
from inscal.calibrate.windows import CalibrationError
from inscal.core.earth import Site


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
