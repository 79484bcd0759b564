"""inscal report: an HTML report with plots and parameter tables compared with the truth."""

import json

from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation
from inscal.cli.app import app

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
    # three figures plus the path section's (gimbal angles, bound over time, gain per move)
    assert text.count("data:image/png;base64,") == 4
    assert "what each move makes observable" in text and "Bound reduction per move" in text
    assert s["path_bound"] == "51-state model, the first dwell's white noise"
    assert "gimbal_nonorthogonality" in text and "error (estimate − truth)" in text
    r = runner.invoke(app, ["report", str(rec), "--out", str(html)])
    assert r.exit_code != 0 and "exists" in r.stderr
    r = runner.invoke(app, ["report", str(tmp_path / "none.h5"), "--out", str(tmp_path / "x.html")])
    assert r.exit_code != 0 and "no such file" in r.stderr and not (tmp_path / "x.html").exists()


def test_report_path_section_and_its_absence(tmp_path):
    """The path section is computed for a record with a path (the bound at its site and noise is finite and below the prior); a record
    without a path (imported without --path) gets no section and says why."""
    from dataclasses import replace

    import numpy as np

    from inscal import io
    from inscal.sim import scenarios
    from inscal.plan.bound import evaluate, make_setup
    from inscal.report.record import record_report

    sc = scenarios.build("psins19", rate_hz=20.0)
    write_simulation(tmp_path / "p.h5", sc, np.random.default_rng(1))
    rec = io.read_record(tmp_path / "p.h5")
    s = record_report(tmp_path / "p.html", rec)
    assert s["path_bound"].startswith("51-state model")
    b = evaluate(make_setup("51", rec.site, rec.truth.gimbal, rec.truth.noise.arw, rec.truth.noise.vrw), rec.path)
    assert np.all(np.isfinite(b.sigma)) and np.all(b.sigma < b.prior)
    s = record_report(tmp_path / "q.html", replace(rec, path=None))
    assert s["path_bound"] == "no rotation path in the record"
    assert "what each move makes observable" not in (tmp_path / "q.html").read_text()
