"""``inscal report --noise noise.toml``: the identified model in the report, in IEEE 952/1293 units with its
intervals and per-sample forms (checked against closed forms, not the code's own conversions), and the
refusal of a bad noise file (one line, exit 2, nothing written)."""

import json
import math

import numpy as np
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core import noise_models as nm
from inscal.core.earth import Site
from inscal.io.noisefile import write_noise

RATE = 100.0
DT = 1.0 / RATE
DEG_H = math.pi / 180.0 / 3600.0  # 1 deg/h in rad/s


def _record(path, n=6000, seed=0):
    rng = np.random.default_rng(seed)
    dth = rng.normal(0.0, 1e-6, (n, 3)) * DT
    dv = rng.normal(0.0, 1e-4, (n, 3)) * DT + np.array([0.0, 0.0, 9.8]) * DT
    t = np.arange(1, n + 1) * DT
    io.write_record(path, io.Record(t, dth, dv, np.zeros((n, 2)), RATE, Site(math.radians(45), 0.0, 0.0),
                                    scenario="noise"))
    return path


def _model():
    # N = 0.05 deg/sqrt(h) = 0.05 * (pi/180) / 60 rad/sqrt(s); GM 5 deg/h, 2 s; accelerometer N 20 ug/sqrt(Hz)
    gx = nm.ChannelNoise("gx", "gyro", (nm.WhiteNoise(0.05 * math.pi / 180.0 / 60.0), nm.GaussMarkov(5.0 * DEG_H, 2.0)))
    az = nm.ChannelNoise("az", "accel", (nm.WhiteNoise(20e-6 * 9.80665),))
    return nm.NoiseModel((gx, az), RATE)


def test_report_shows_the_noise_model_in_field_units(tmp_path):
    rec = _record(tmp_path / "static.h5")
    noise, out = tmp_path / "noise.toml", tmp_path / "r.html"
    iv = {"gx": {0: {"n": (0.049 * math.pi / 180.0 / 60.0, 0.051 * math.pi / 180.0 / 60.0)}}}
    write_noise(noise, _model(), iv)
    r = CliRunner().invoke(app, ["report", str(rec), "--noise", str(noise), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    res = json.loads(r.stdout)
    assert res["noise_models"] == [str(noise)]
    gx, az = res["noise_model"][str(noise)]["channels"]
    wn, gm = gx["terms"]
    assert gx["model"] == "WN+GM" and wn["params"]["n"]["unit"] == "deg/sqrt(h)"
    assert math.isclose(wn["params"]["n"]["value"], 0.05, rel_tol=1e-12)
    assert np.allclose(wn["params"]["n"]["interval_95"], [0.049, 0.051], rtol=1e-12)
    assert math.isclose(gm["params"]["sigma"]["value"], 5.0, rel_tol=1e-12) and gm["params"]["tc"]["value"] == 2.0
    # per sample at 100 Hz: white std N / sqrt(dt) = 60 N / sqrt(dt) deg/h (N in deg/sqrt(h)) = 30 deg/h;
    # AR(1) phi = exp(-dt / tc), innovation std sigma sqrt(1 - phi^2)
    assert math.isclose(wn["per_sample"]["std"], 60 * 0.05 / math.sqrt(DT), rel_tol=1e-9)
    phi = math.exp(-DT / 2.0)
    assert math.isclose(gm["per_sample"]["phi"], phi, rel_tol=1e-12)
    assert math.isclose(gm["per_sample"]["innovation_std"], 5.0 * math.sqrt(1 - phi * phi), rel_tol=1e-9)
    # accelerometer: 20 ug/sqrt(Hz) -> per sample 20 / sqrt(dt) ug = 200 ug
    assert az["terms"][0]["params"]["n"]["unit"] == "ug/sqrt(Hz)"
    assert math.isclose(az["terms"][0]["per_sample"]["std"], 200.0, rel_tol=1e-9)
    html = out.read_text()
    assert "Noise model:" in html and "0.049 .. 0.051" in html and "the record's own of its first dwell" in html
    assert html.count("data:image/png;base64,") >= 3  # sensor outputs, the first dwell, the noise model


def test_report_refuses_a_bad_noise_file_before_any_work(tmp_path):
    rec = _record(tmp_path / "static.h5", n=3000)
    bad, out = tmp_path / "noise.toml", tmp_path / "r.html"
    bad.write_text('format = "inscal-noise"\nversion = 1\nrate_hz = 100.0\n[[channel]]\nname = "gx"\nkind = "gyro"\n'
                   '[[channel.term]]\ntype = "XX"\n')
    r = CliRunner().invoke(app, ["report", str(rec), "--noise", str(bad), "--out", str(out)])
    assert r.exit_code == 2 and not out.exists()
    line = r.output.strip()
    assert "\n" not in line and "unknown term type 'XX'" in line, line
