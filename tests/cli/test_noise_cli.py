"""``inscal noise``: a static record's identification end to end (JSON, noise.toml round trip, plot),
a curve from CSV, and the refusals (one line, exit 2, nothing written)."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal.cli.allan import run_allan
from inscal.cli.app import app
from inscal.core import noise_models as nm
from inscal.core import units
from inscal.core.earth import Site
from inscal.io.noisefile import read_noise

RATE = 100.0
DT = 1 / RATE
GX = nm.ChannelNoise("gx", "gyro", (nm.WhiteNoise(units.to_si(0.05, "deg/sqrt(h)")),
                                    nm.GaussMarkov(units.to_si(5.0, "deg/h"), 2.0)))


def _record(path, n=60_000, seed=0, edit=None):
    rng = np.random.default_rng(seed)
    dth = np.column_stack([GX.simulate(n, DT, rng)] + [rng.normal(0, 1e-6, n) for _ in range(2)]) * DT
    dv = rng.normal(0, 1e-4, (n, 3)) * DT + np.array([0, 0, 9.8]) * DT
    gim = np.zeros((n, 2))
    if edit:
        edit(dth, dv, gim)
    t = np.arange(1, n + 1) * DT
    io.write_record(path, io.Record(t, dth, dv, gim, RATE, Site(math.radians(45), 0.0, 0.0), scenario="noise"))
    return path


@pytest.fixture(scope="module")
def static(tmp_path_factory):
    return _record(tmp_path_factory.mktemp("noise") / "static.h5")


def test_identify_record_json_toml_plot(static, tmp_path):
    out, png = tmp_path / "noise.toml", tmp_path / "noise.png"
    r = CliRunner().invoke(app, ["noise", str(static), "--channels", "gx", "--model", "WN+GM", "--json",
                                 "--out", str(out), "--plot", str(png)])
    assert r.exit_code == 0, r.stderr
    res = json.loads(r.stdout)
    ch = res["channels"][0]
    assert ch["model"] == "WN+GM" and ch["why"] == "WN+GM: as asked (--model)"
    p = ch["parameters"]
    assert p["WN.n"]["unit"] == "deg/sqrt(h)" and p["GM1.sigma"]["unit"] == "deg/h" and p["GM1.tc"]["unit"] == "s"
    for key, truth in (("WN.n", 0.05), ("GM1.sigma", 5.0), ("GM1.tc", 2.0)):
        assert p[key]["lower_95"] < truth < p[key]["upper_95"], (key, p[key])
    assert len(ch["fit_scales"]["weights"]) == len(ch["fit_scales"]["m"]) == len(ch["fit_scales"]["scale_index_j"])
    assert ch["ieee_readoffs"]["WN"]["unit"] == "deg/sqrt(h)"
    assert png.stat().st_size > 1000
    model, meta = read_noise(out)
    (g,) = model.channels
    assert g.name == "gx" and g.model == "WN+GM" and model.rate_hz == RATE
    assert units.from_si(g.terms[0].n, "deg/sqrt(h)") == pytest.approx(p["WN.n"]["value"], rel=1e-12)
    assert units.from_si(g.terms[1].sigma, "deg/h") == pytest.approx(p["GM1.sigma"]["value"], rel=1e-12)
    # written once: a second run refuses to overwrite and writes nothing
    r = CliRunner().invoke(app, ["noise", str(static), "--channels", "gx", "--model", "WN", "--out", str(out)])
    assert r.exit_code == 2 and "exists" in r.stderr


def test_from_curve_csv(tmp_path):
    """An Allan variance curve handed over by another tool: the exact one of a known model is fitted back."""
    m = 2.0 ** np.arange(0, 13)
    av = GX.avar(m, DT)
    edf = np.maximum((60_000 - 2 * m + 1) / (2 * m), 1)
    from inscal.analysis.noise.intervals import chi2_bounds

    lo, hi = chi2_bounds(edf)
    csv = tmp_path / "curve.csv"
    csv.write_text("# dt_s = 0.01\ntau_s,avar,lower,upper\n"
                   + "".join(f"{t:.17g},{a:.17g},{a * lo_:.17g},{a * hi_:.17g}\n" for t, a, lo_, hi_ in zip(m * DT, av, lo, hi)))
    r = CliRunner().invoke(app, ["noise", "--from-curve", str(csv), "--model", "WN+GM", "--json"])
    assert r.exit_code == 0, r.stderr
    p = json.loads(r.stdout)["channels"][0]["parameters"]
    assert p["WN.n"]["value"] == pytest.approx(0.05, rel=1e-4)
    assert p["GM1.tc"]["value"] == pytest.approx(2.0, rel=1e-4)


def _moving(dth, dv, gim):
    dth[20_000:30_000, 2] += math.radians(10) * DT
    gim[20_000:30_000, 1] = np.cumsum(dth[20_000:30_000, 2])
    gim[30_000:, 1] = gim[29_999, 1]


def _nan(path):
    import h5py

    with h5py.File(path, "a") as h5:
        h5["dvel"][1234, 0] = np.nan


def _stuck(dth, dv, gim):
    dv[:, 1] = 9.8e-3


def _saturated(dth, dv, gim):
    dth[:, 0] = np.minimum(dth[:, 0], np.quantile(dth[:, 0], 0.9))


def _counts(dth, dv, gim):
    dv[:, 2] = np.round(dv[:, 2] / 1e-7)  # counts of 0.1 um/s


@pytest.mark.parametrize("edit, args, words", [
    (_moving, [], "moves in 1"),
    (_nan, [], "NaN"),
    (_stuck, [], "ay is stuck"),
    (_saturated, ["--channels", "gx"], "gx is saturated"),
    (_counts, [], "whole numbers"),
    (None, ["--model", "WN+FOO"], "unknown term"),
    (None, ["--model", "5GM"], "at most 4"),
    (None, ["--model", "auto", "--stop", "10"], "needs at least 10240"),
])
def test_refusals_are_one_line_and_write_nothing(tmp_path, static, edit, args, words):
    if edit is _nan:
        rec = _record(tmp_path / "bad.h5")
        _nan(rec)
    else:
        rec = static if edit is None else _record(tmp_path / "bad.h5", edit=edit)
    out, png = tmp_path / "n.toml", tmp_path / "n.png"
    r = CliRunner().invoke(app, ["noise", str(rec), "--model", "WN", "--out", str(out), "--plot", str(png)] + args)
    assert r.exit_code == 2, r.stdout
    assert words in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert not out.exists() and not png.exists()


def test_identify_simulate_identify(tmp_path):
    """A noise.toml as a scenario's [noise]: the simulator reproduces the unit, and identifying its
    record gives the model back within the intervals."""
    from inscal.io.noisefile import write_noise

    ax = nm.ChannelNoise("ax", "accel", (nm.WhiteNoise(units.to_si(50.0, "ug/sqrt(Hz)")),
                                         nm.GaussMarkov(units.to_si(40.0, "ug"), 2.0)))
    chans = [nm.ChannelNoise(n, c.kind, c.terms) for c in (GX, ax) for n in ((c.name[0] + a) for a in "xyz")]
    write_noise(tmp_path / "unit.toml", nm.NoiseModel(tuple(chans), RATE))
    (tmp_path / "scen.toml").write_text('base = "static"\n[scenario]\nduration_h = 0.06\n[noise]\nfile = "unit.toml"\n')
    rec = tmp_path / "r.h5"
    r = CliRunner().invoke(app, ["simulate", str(tmp_path / "scen.toml"), "--out", str(rec), "--seed", "4"])
    assert r.exit_code == 0, r.stderr
    r = CliRunner().invoke(app, ["noise", str(rec), "--channels", "gy,az", "--model", "WN+GM", "--json"])
    assert r.exit_code == 0, r.stderr
    gy, az = (c["parameters"] for c in json.loads(r.stdout)["channels"])
    for p, key, truth in ((gy, "WN.n", 0.05), (gy, "GM1.sigma", 5.0), (gy, "GM1.tc", 2.0),
                          (az, "WN.n", 50.0), (az, "GM1.sigma", 40.0), (az, "GM1.tc", 2.0)):
        se = math.log(p[key]["upper_95"] / p[key]["lower_95"]) / (2 * 1.96)  # the intervals are log-symmetric
        assert abs(math.log(p[key]["value"] / truth)) < 3.5 * se, (key, p[key])  # six checks: 3.5 sigma each
    # a term the simulator does not draw is refused in one line
    write_noise(tmp_path / "rw.toml", nm.NoiseModel(tuple(chans[:5]) + (nm.ChannelNoise("az", "accel", (nm.RandomWalk(1e-6),)),), RATE))
    (tmp_path / "scen2.toml").write_text('base = "static"\n[noise]\nfile = "rw.toml"\n')
    r = CliRunner().invoke(app, ["simulate", str(tmp_path / "scen2.toml"), "--out", str(tmp_path / "r2.h5")])
    assert r.exit_code == 2 and "az has RW" in r.stderr and not (tmp_path / "r2.h5").exists()


def _turns(k):
    """k turns of 90 deg about z, 1.5 s each (0.25 % of the 600-s record; 0.25-1 % in all)."""
    starts = np.linspace(100, 500, k)

    def edit(dth, dv, gim):
        for s in starts:
            i0, n = int(s * RATE), int(1.5 * RATE)
            dth[i0:i0 + n, 2] += math.radians(90) / n
    return starts, edit


@pytest.fixture(scope="module")
def clean_fit(static):
    r = CliRunner().invoke(app, ["noise", str(static), "--model", "WN+GM", "--channels", "gx", "--json"])
    assert r.exit_code == 0, r.stderr
    return json.loads(r.stdout)["channels"][0]["parameters"]


@pytest.mark.parametrize("k", [1, 2, 4])
def test_short_turns_are_cut_out_and_the_rest_fitted(tmp_path, clean_fit, k):
    """Each turn is caught and cut out with its margin (said in --json), and the model fitted on the
    static segments left is the clean record's (the same noise without the turns)."""
    starts, edit = _turns(k)
    rec = _record(tmp_path / "turns.h5", edit=edit)
    r = CliRunner().invoke(app, ["noise", str(rec), "--model", "WN+GM", "--channels", "gx", "--json"])
    assert r.exit_code == 0, r.stderr
    res = json.loads(r.stdout)
    cut = res["cut"]
    assert len(cut["spans_s"]) == k
    for s, (a, b) in zip(starts, cut["spans_s"]):  # each turn inside its cut, within margin + two blocks
        assert s - cut["margin_s"] - 1.01 <= a <= s and s + 1.5 <= b <= s + 1.5 + cut["margin_s"] + 2.01, (s, a, b)
    assert cut["share"] == pytest.approx(sum(b - a for a, b in cut["spans_s"]) / 600.0, rel=1e-9)
    assert cut["static_segments"] == k + 1 and cut["samples_used"] == round(60_000 * (1 - cut["share"]))
    got = res["channels"][0]["parameters"]
    for p in ("WN.n", "GM1.sigma", "GM1.tc"):  # the turn itself would put a GM of ~1e5 deg/h in the model
        assert got[p]["value"] == pytest.approx(clean_fit[p]["value"], rel=0.15 if p != "GM1.tc" else 0.4), p
    if k == 2:  # inscal allan cuts the same stretches: the same ARW, to the last digit
        al = run_allan(rec, model="WN+GM")
        assert al["cut"]["spans_s"] == cut["spans_s"] and al["arw_deg_rth"][0] == got["WN.n"]["value"]
        assert any(w.startswith("cut out: ") for w in al["warnings"])
