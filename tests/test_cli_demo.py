"""The demo (the main job on built-in defaults) runs end to end and its results make sense."""

import json

from typer.testing import CliRunner

from inscal.cli import app


def test_demo_quick_json(tmp_path):
    r = CliRunner().invoke(app, ["demo", "--out", str(tmp_path / "d"), "--quick", "--json"])
    assert r.exit_code == 0, r.stderr
    res = json.loads(r.stdout)
    steps = res["steps"]
    assert steps["simulate_s16"]["samples"] == 386100
    cal = steps["calibrate"]
    # the proposed method estimates the 20" non-orthogonality within a few tenths of an arcsecond
    assert abs(cal["n25"]["gimbal_nonorthogonality"]["error"][0]) < 1.0
    # the six-position scheme's z accelerometer bias error is the eq. 21 leveling/non-orthogonality term
    assert abs(cal["six-position"]["accel_bias"]["error"][2]) > 100 * abs(cal["n25"]["accel_bias"]["error"][2])
    nav = steps["navigate"]
    assert nav["n25"]["max_position_error_m"] < nav["six-position"]["max_position_error_m"] < nav["uncalibrated"]["max_position_error_m"]
    # a second run refuses to overwrite without --force
    r = CliRunner().invoke(app, ["demo", "--out", str(tmp_path / "d"), "--quick"])
    assert r.exit_code != 0 and "exists" in r.stderr
