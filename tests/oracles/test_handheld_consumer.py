"""Consumer-MEMS hand-held sessions from the independent generator (handheld_imu.consumer_log: int16 counts of
+-250 deg/s and +-2 g behind a low-pass filter, turn-on gyro biases of degrees per second, hand tremor in the
poses, a drifting gyro bias, a turn fast enough to pin a gyro at its range), imported from a logger's csv with
the units declared (rates in counts with their scales) and calibrated by ``calibrate --method
multi-position`` with its defaults.

- The tremor log (1.5 deg/s rms in every pose; the accelerometers quiet, the gyros 10-50 times their white
  noise) has every pose found (the detector that judged poses by the gyros' white noise found only the still
  start), each candidate with the figure and threshold of its decision.
- The turn that pins a gyro is marked at import (not refused) and costs that rotation only: the note names
  it, the rest calibrates, every parameter within 4.5 sigma of the truth.
- Too few usable poses: the refusal names the best rejected ones and what would make them usable."""

import math

import numpy as np
import pytest
from handheld_imu import consumer_log

from inscal.calibrate.static_detect import detect_still
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.earth import Site
from inscal.io.importers import import_file
from inscal.io.recordfile import read_record
from inscal.runs.calibration import CalibrationSetup, calibrate_record

LAT = 0.8  # rad
GROUPS = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
          "accel_bias")


def _mapping(scales) -> str:
    return ('kind = "rates"\nheader_rows = 1\n[columns]\ntime = "time"\ngx = "gx"\ngy = "gy"\ngz = "gz"\nax = "ax"\n'
            f'ay = "ay"\naz = "az"\n[units]\ntime = "s"\ngyro = "counts"\ngyro_scale = "{math.degrees(float(scales[0]))!r} '
            f'deg/s"\naccel = "counts"\naccel_scale = {float(scales[1])!r}\n[site]\nlatitude_deg = {math.degrees(LAT)!r}\n'
            "longitude_deg = 10.0\nheight_m = 0.0\n")


def _session(tmp_path_factory, seed, tremor, fast_turn):
    g = Site(LAT, math.radians(10.0), 0.0).gravity  # the site's gravity, as the mapping's [site] gives it
    lg = consumer_log(np.random.default_rng(seed), tremor_dps=tremor, fast_turn=fast_turn, lat=LAT, g=g)
    d = tmp_path_factory.mktemp(f"consumer{seed}")
    (d / "log.csv").write_text(lg["csv"])
    (d / "map.toml").write_text(_mapping(lg["scales"]))
    summary = import_file(d / "log.csv", d / "rec.h5", "csv", mapping_file=d / "map.toml")
    return lg, d / "rec.h5", summary


@pytest.fixture(scope="module")
def tremor_log(tmp_path_factory):
    return _session(tmp_path_factory, 5, 1.5, True)


def test_every_pose_is_found_under_tremor(tremor_log):
    lg, rec_path, _ = tremor_log
    assert lg["pinned"] > 0  # the fast turn pins a gyro
    rec = read_record(rec_path)
    si = detect_still(rec.time, rec.dtheta, rec.dvel, min_still=1.0)
    for t0, t1 in lg["still"]:  # every true pose holds a kept candidate, and nothing kept lies outside the poses
        assert any(t0 - 1e-6 <= c.t0 and c.t1 <= t1 + 1e-6 for c in si.kept), (t0, t1, [c.describe() for c in si.candidates])
    assert all(any(t0 - 1e-6 <= c.t0 and c.t1 <= t1 + 1e-6 for t0, t1 in lg["still"]) for c in si.kept)
    # the gyros tremble far above their white noise, and every decision says its figure and threshold
    hand = [c for c in si.kept if c.t0 > lg["still"][0][1]]
    scatter = [float(c.reason.split("gyro scatter ")[1].split(" ")[0]) for c in hand]
    white = units.from_si(float(np.max(si.gyro_density)), "deg/s") * math.sqrt(100.0)  # per sample at 100 Hz
    assert min(scatter) > 10 * white
    assert all("threshold" in c.reason for c in si.candidates)
    assert any(n.startswith("noise from the still start") for n in si.notes)


def test_a_pinned_gyro_is_marked_and_costs_only_its_turn(tremor_log):
    lg, rec_path, summary = tremor_log
    sat = summary["saturated"]
    assert sat and sat[0]["channel"] in ("gx", "gy", "gz") and abs(sat[0]["level"]) >= 32767
    cal = calibrate_record(read_record(rec_path), rec_path, CalibrationSetup("multi-position"))
    res = cal.result
    assert any("saturates a gyro: that rotation is not used" in n for n in res.notes), res.notes
    _within(res, lg["truth"], 4.5)


def test_a_second_session_calibrates_within_its_sigma(tmp_path_factory):
    lg, rec_path, summary = _session(tmp_path_factory, 8, 0.3, False)
    assert "saturated" not in summary
    _within(calibrate_record(read_record(rec_path), rec_path, CalibrationSetup("multi-position")).result, lg["truth"], 4.5)


def test_too_few_usable_poses_name_the_best_rejected_and_the_fix(tremor_log):
    _, rec_path, _ = tremor_log
    rec = read_record(rec_path)
    si = detect_still(rec.time, rec.dtheta, rec.dvel, min_still=6.0)
    with pytest.raises(CalibrationError) as exc:
        si.require(9, "the accelerometer model")
    msg = str(exc.value)
    assert "too short" in msg and "to use them: --min-static-s" in msg and "\n" not in msg, msg
    # a stated tremor below the hand's: the poses are rejected for it, and the option that accepts them is named
    si = detect_still(rec.time, rec.dtheta, rec.dvel, min_still=1.0, tremor=math.radians(0.2))
    with pytest.raises(CalibrationError) as exc:
        si.require(9, "the accelerometer model")
    assert "above the stated tremor level 0.2 deg/s" in str(exc.value) and "--tremor-dps" in str(exc.value)


def _within(res, truth, k):
    for g in GROUPS:
        v, s, t = np.asarray(getattr(res.imu, g)), np.asarray(res.sigma[g]), np.asarray(truth[g])
        m = np.isfinite(s)
        z = (v - t)[m] / s[m]
        assert np.all(np.abs(z) < k), (g, z)
