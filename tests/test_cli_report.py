"""inscal report: an HTML report with plots and parameter tables compared with the truth."""

import json

from typer.testing import CliRunner

from inscal.cli import app

runner = CliRunner()


def test_report_with_calibration(tmp_path):
    rec, params, html = tmp_path / "n25.h5", tmp_path / "p.toml", tmp_path / "r.html"
    assert runner.invoke(app, ["simulate", "n25", "--out", str(rec)]).exit_code == 0
    r = runner.invoke(app, ["calibrate", str(rec), "--method", "n25", "--out", str(params)])
    assert r.exit_code == 0, r.stderr
    r = runner.invoke(app, ["report", str(rec), "--params", str(params), "--out", str(html), "--json"])
    assert r.exit_code == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["figures"] == ["Gimbal motion", "Sensor outputs", "Noise of the first dwell"]
    assert abs(s["arw_deg_rth"][0] - 0.02) < 0.004 and abs(s["vrw_ug_rthz"][2] - 20) < 4
    text = html.read_text()
    assert text.count("data:image/png;base64,") == 3
    assert "gimbal_nonorthogonality" in text and "error (estimate − truth)" in text
    r = runner.invoke(app, ["report", str(rec), "--out", str(html)])
    assert r.exit_code != 0 and "exists" in r.stderr
    r = runner.invoke(app, ["report", str(tmp_path / "none.h5"), "--out", str(tmp_path / "x.html")])
    assert r.exit_code != 0 and "no such file" in r.stderr and not (tmp_path / "x.html").exists()
