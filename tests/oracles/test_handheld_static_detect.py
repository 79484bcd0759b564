"""The still-pose detector on hand-held logs from the independent generator (tests/oracles/handheld_imu.py):
tremor in the moves, a jittered clock, a fixture knock, a too-short pose, a pose that turns, a pose that
tilts: the right windows, and every rejection named."""

import math

import numpy as np
import pytest
from handheld_imu import generate, grade

from inscal.calibrate.static_detect import detect_still
from inscal.calibrate.windows import CalibrationError


@pytest.fixture(scope="module")
def log():
    rng = np.random.default_rng(11)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    still = [5.0] * 10
    still[3] = 1.2  # too short
    still[5] = 9.0  # knocked in the middle: both halves usable
    return generate(rng, Mg, bg, Ma, ba, n_poses=10, rate_hz=100.0, still_s=still, tremor_deg=0.8, arw=arw, vrw=vrw,
                    jitter=0.3), arw, vrw


def test_noise_densities_are_the_record_s_own_despite_jitter_and_moves(log):
    lg, arw, vrw = log
    si = detect_still(lg.time, lg.dtheta, lg.dvel)
    # at the scale of a pose: batch means of 0.25 s over the poses, about 130 dof per axis (6 % standard error)
    assert np.allclose(si.gyro_density, arw, rtol=0.2)
    assert np.allclose(si.accel_density, vrw, rtol=0.2)


def test_the_right_windows_and_each_rejection_named(log):
    lg, arw, vrw = log
    dth, dv, t = lg.dtheta.copy(), lg.dvel.copy(), lg.time
    dt = np.diff(np.concatenate([[0.0], t]))
    # a fixture knock in the middle of pose 6 (0.1 s of a 2 m/s^2, 20 deg/s jolt)
    t0, t1 = lg.still[5]
    knock = (t > 0.5 * (t0 + t1)) & (t < 0.5 * (t0 + t1) + 0.1)
    dv[knock] += 2.0 * dt[knock, None]
    dth[knock] += math.radians(20) * dt[knock, None]
    # pose 8 turns slowly about the gravity direction (gyro only, 0.8 deg/s), pose 9 tilts (accelerometer ramp)
    a, b = lg.still[7]
    m8 = (t > a + 0.5) & (t < b - 0.5)
    dth[m8] += math.radians(0.8) * dt[m8, None] * np.array([0.0, 0.0, 1.0])
    a, b = lg.still[8]
    m9 = (t > a + 0.5) & (t < b - 0.5)
    dv[m9, 0] += 0.02 * (t[m9] - t[m9][0]) * dt[m9]
    si = detect_still(t, dth, dv)
    kept = si.kept
    # every kept window lies inside a true still pose, away from the knock
    for c in kept:
        assert any(s0 - 1e-9 <= c.t0 and c.t1 <= s1 + 1e-9 for s0, s1 in lg.still), c.describe()
        assert not np.any(knock[c.i0:c.i1])
    covered = {next(j for j, (s0, s1) in enumerate(lg.still) if s0 <= c.t0 and c.t1 <= s1) for c in kept}
    assert covered == {0, 1, 2, 4, 5, 6, 9}  # pose 4 short, 8 turns, 9 tilts
    assert sum(1 for c in kept if lg.still[5][0] <= c.t0 and c.t1 <= lg.still[5][1]) == 2  # both sides of the knock
    reasons = " | ".join(c.reason for c in si.rejected)
    assert "too short" in reasons and "turned, gyro 0.8" in reasons and "tilted" in reasons, reasons
    with pytest.raises(CalibrationError) as exc:
        si.require(9, "the model")
    msg = str(exc.value)
    assert msg.startswith(f"found {len(kept)} still poses, the model needs 9: pose ") and "\n" not in msg


def test_a_moving_record_is_named_as_such():
    rng = np.random.default_rng(3)
    Mg, bg, Ma, ba, arw, vrw = grade("tactical", rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=6, rate_hz=100.0, still_s=0.0, tremor_deg=1.0, arw=arw, vrw=vrw)
    si = detect_still(lg.time, lg.dtheta, lg.dvel)
    with pytest.raises(CalibrationError, match="found 0 still poses"):
        si.require(9)


def test_gaps_in_the_clock_are_not_used_and_named():
    rng = np.random.default_rng(4)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=4, rate_hz=100.0, arw=arw, vrw=vrw)
    keep = np.ones(lg.time.size, bool)
    keep[150:160] = False  # ten samples lost inside pose 1
    si = detect_still(lg.time[keep], lg.dtheta[keep], lg.dvel[keep])
    assert si.notes and "gap" in si.notes[0]
    assert all(not si.gap[c.i0:c.i1].any() for c in si.candidates)
