"""The demo (the main job on built-in defaults) runs end to end and its results make sense."""

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.io.paramfile import load_params


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
    # S16: the 51-state systematic filter reaches the S16 Table 2 figures for the quadratic terms and the
    # lever arm; the 30-state filter leaves them (and, through them, the linear terms) uncompensated
    sysc = steps["systematic_s16"]
    g51, g30 = sysc["systematic51"]["groups"], sysc["systematic30"]["groups"]
    assert g51["accel_nonlinearity"]["mean_abs_error"] < g51["accel_nonlinearity"]["s16"] == 1.3
    assert g51["accel_cross_coupling"]["mean_abs_error"] < g51["accel_cross_coupling"]["s16"] == 1.5
    assert g51["accel_lever_arm"]["mean_abs_error"] < 0.03  # cm (S16: 0.01; sigma ~0.008 here)
    assert g51["gyro_g_sensitivity"]["mean_abs_error"] < 0.005 and g51["gyro_g_sensitivity"]["estimated"]
    for g, before in (("gyro_g_sensitivity", 0.001), ("accel_nonlinearity", 300.0), ("accel_cross_coupling", 300.0),
                      ("accel_lever_arm", 2.0)):
        assert not g30[g]["estimated"] and g30[g]["mean_abs_error"] == pytest.approx(before, rel=1e-6)
    assert g30["accel_bias"]["mean_abs_error"] > 100 * g51["accel_bias"]["mean_abs_error"]
    assert 4.0 < sysc["systematic51"]["nis_mean"] < 8.0 < sysc["systematic30"]["nis_mean"]
    for m in ("systematic51", "systematic30"):
        imu, _, meta = load_params(sysc[m]["out"])
        assert meta["method"] == m and meta["metadata"]["states"] == m[-2:]
    nav = steps["navigate"]
    assert nav["n25"]["max_position_error_m"] < nav["six-position"]["max_position_error_m"] < nav["uncalibrated"]["max_position_error_m"]
    # the report: self-contained HTML, the figures as PNG files, summary.json = the --json document
    rep = res["report"]
    html = Path(rep["html"]).read_text(encoding="utf-8")
    assert html.count("<img ") == len(rep["figures"]) == 7 and "data:image/png;base64," in html
    assert all(Path(f).stat().st_size > 10_000 for f in rep["figures"].values())
    summary = json.loads(Path(rep["summary"]).read_text(encoding="utf-8"))
    assert summary["steps"]["calibrate"] == cal and summary["steps"]["navigate"] == nav
    assert nav["n25"]["final_attitude_deg"]["heading"] == pytest.approx(
        (90.0 - nav["n25"]["final_attitude_deg"]["yaw"]) % 360.0)
    # a second run refuses to overwrite without --force
    r = CliRunner().invoke(app, ["demo", "--out", str(tmp_path / "d"), "--quick"])
    assert r.exit_code != 0 and "exists" in r.stderr
