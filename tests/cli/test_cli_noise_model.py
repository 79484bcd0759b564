"""``--noise noise.toml`` of ``calibrate``, ``batch`` and ``observability --crlb``: a file that cannot be used, or
noise options beside it, is one line (exit 2) with nothing written; the bound reads the model's white,
Gauss-Markov and random-walk terms (inscal.plan.noise_model)."""

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.core import noise_models as nm
from inscal.core import units
from inscal.io.noisefile import write_noise
from inscal.plan.noise_model import bound_noise
from inscal.plan.rows import BoundError


def _model(taus=(300.0,) * 6, bi=False):
    chans = []
    for name, tc in zip(("gx", "gy", "gz", "ax", "ay", "az"), taus):
        g = name[0] == "g"
        terms = [nm.WhiteNoise(units.to_si(0.002, "deg/sqrt(h)") if g else units.to_si(5.0, "ug/sqrt(Hz)")),
                 nm.GaussMarkov(units.to_si(0.003, "deg/h") if g else units.to_si(10.0, "ug"), tc),
                 nm.RandomWalk(1e-9 if g else 1e-7)]
        if bi and name == "az":
            terms.append(nm.BiasInstability(1e-6, 50.0))
        chans.append(nm.ChannelNoise(name, "gyro" if g else "accel", tuple(terms)))
    return nm.NoiseModel(tuple(chans), 100.0)


def test_bound_noise_reads_the_model():
    arw, vrw, bias, left = bound_noise(_model(bi=True))
    assert np.allclose(units.from_si(arw, "deg/sqrt(h)"), 0.002) and np.allclose(units.from_si(vrw, "ug/sqrt(Hz)"), 5)
    assert np.allclose(units.from_si(bias.gyro_gm, "deg/h"), 0.003) and np.allclose(units.from_si(bias.accel_gm, "ug"), 10)
    assert bias.gyro_tau == 300.0 and bias.accel_tau == 300.0
    assert np.allclose(bias.gyro_rw, 1e-9) and np.allclose(bias.accel_rw, 1e-7) and left == ["az: BI"]
    with pytest.raises(BoundError, match="one per sensor"):
        bound_noise(_model(taus=(300.0, 600.0, 300.0, 100.0, 100.0, 100.0)))
    white = nm.NoiseModel(tuple(nm.ChannelNoise(c.name, c.kind, c.terms[:1]) for c in _model().channels), 100.0)
    assert bound_noise(white)[2] is None and math.isfinite(bound_noise(white)[0][0])


@pytest.mark.parametrize("case", ["missing", "arw", "window", "nocrlb", "crlb-arw", "crlb-missing"])
def test_noise_refusals_are_one_line(tmp_path, case):
    good = tmp_path / "noise.toml"
    write_noise(good, _model())
    out = tmp_path / "p.toml"
    args = {
        "missing": ["calibrate", "rec.h5", "--method", "systematic51", "--noise", str(tmp_path / "no.toml")],
        "arw": ["calibrate", "rec.h5", "--method", "systematic51", "--noise", str(good), "--arw", "0.01"],
        "window": ["calibrate", "rec.h5", "--method", "multi-position", "--noise", str(good)],
        "nocrlb": ["observability", "s16", "--noise", str(good)],
        "crlb-arw": ["observability", "s16", "--crlb", "--noise", str(good), "--gyro-bi", "0.01"],
        "crlb-missing": ["observability", "s16", "--crlb", "--noise", str(tmp_path / "no.toml")],
    }[case]
    if args[0] == "calibrate":
        args += ["--out", str(out)]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and "--noise" in r.stderr, r.output
    assert not out.exists()


def test_report_of_a_noise_model(tmp_path):
    """``inscal report noise.toml``: each channel's terms in field units and the model's Allan deviation; a file
    that is not a noise model, or --params beside it, is one line with nothing written."""
    import json

    src = tmp_path / "noise.toml"
    write_noise(src, _model())
    out = tmp_path / "r.html"
    r = CliRunner().invoke(app, ["report", str(src), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    gx = rep["channels"][0]
    assert gx["channel"] == "gx" and gx["model"] == "WN+RW+GM"
    (gm,) = [t for t in gx["terms"] if t["type"] == "GM"]
    assert gm["type"] == "GM" and gm["params"]["sigma"] == {"value": pytest.approx(0.003), "unit": "deg/h",
                                                             "interval_95": None}
    assert "exact Allan deviations" in out.read_text() and "°/√h" in out.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text("format = 'other'\n")
    for args in (["report", str(bad), "--out", str(tmp_path / "b.html")],
                 ["report", str(src), "--out", str(tmp_path / "b.html"), "--params", str(src)]):
        r = CliRunner().invoke(app, args)
        assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.output
    assert not (tmp_path / "b.html").exists()
