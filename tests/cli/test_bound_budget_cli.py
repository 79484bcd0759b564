"""``inscal observability --crlb --station`` and ``inscal design --station``: the budget a path promises before
it runs (the bound with the site and clock carried through it, :mod:`inscal.plan.consider`), combined as the GUM
budget; checked against closed forms: the accelerometer scale factors carry ``u(g)/g`` and the time base 1:1,
the table's inputs nothing; the design's objective is that combined uncertainty; a bad station is one line."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest
import tomli_w

from inscal.uncertainty.station import read_station
from inscal.plan import bound as B
from inscal.core.turntable import s16_table1
from inscal.plan.rows import BiasNoise
from inscal.sim.scenarios import load_toml

from budget_helpers import STATION, one_line, run


@pytest.fixture(scope="module")
def promised():
    r = run("observability", "s16", "--crlb", "--station", STATION, "--json")
    assert r.exit_code == 0, r.stderr
    return json.loads(r.stdout)


def test_the_budget_before_the_run(promised):
    st = read_station(STATION)
    b = promised["budget"]
    plain = {p["label"]: p for p in run_json("observability", "s16", "--crlb")["crlb"]["parameters"]}
    assert plain and promised["station"]["station"]["name"] == st.name
    comps = {c["label"]: c for c in b["components"]}
    g = st["gravity"].value
    u_g, u_t = st["gravity"].u, st["time_base"].u
    for i in range(3):
        c = comps[f"accel_scale_factor[{i}]"]
        lines = {x["input"]: x for x in c["contributions"]}
        assert lines["gravity"]["contribution"] == pytest.approx(u_g / g * 1e6, rel=1e-3)  # ppm
        assert lines["time_base"]["contribution"] == pytest.approx(u_t * 1e6, rel=1e-3)
        for k in ("table_angle", "table_rate", "axis_wobble", "axis_nonorthogonality", "encoder_resolution"):
            assert lines[k]["contribution"] == 0.0
        est = lines["estimator (Type A)"]["contribution"]
        others = sum(x["contribution"] ** 2 for k, x in lines.items() if k != "estimator (Type A)")
        assert c["u_c"] == pytest.approx(math.sqrt(est**2 + others), rel=1e-9)
        assert lines["gravity"]["share"] > 0.5  # 1 mGal is 1 ppm: more than the path's own bound
    # the gyro bias: the bound itself (at the station's site) carries it; the latitude's share is small at 1 arcsec
    c = comps["gyro_bias[0]"]
    assert c["contributions"][0]["share"] > 0.9
    dom = {r["input"]: r for r in promised["dominant_inputs"]}
    assert dom["gravity"]["largest_in"] == [f"accel_scale_factor[{i}]" for i in range(3)]
    assert dom["estimator (Type A)"]["n_largest"] == len(comps) - 3


def run_json(*args):
    r = run(*args, "--json")
    assert r.exit_code == 0, r.stderr
    return json.loads(r.stdout)


def test_the_text_names_what_dominates():
    r = run("observability", "s16", "--crlb", "--station", STATION)
    assert r.exit_code == 0, r.stderr
    assert "which inputs dominate" in r.stdout and "site gravity" in r.stdout
    assert "accel_scale_factor[0]" in r.stdout and "largest: gravity" in r.stdout


def test_bad_station_and_misuse_are_one_line(tmp_path):
    doc = tomllib.loads(STATION.read_text())
    doc["inputs"]["gravity"]["distribution"] = "lognormal"


    bad = tmp_path / "bad.toml"
    bad.write_text(tomli_w.dumps(doc))
    one_line(run("observability", "s16", "--crlb", "--station", bad), "unknown distribution 'lognormal'")
    one_line(run("observability", "s16", "--station", STATION), "apply to the bound (--crlb)")
    one_line(run("design", "--out", tmp_path / "d.toml", "--minutes", "10", "--station", bad), "--station")
    assert not (tmp_path / "d.toml").exists()


def test_design_for_the_combined_uncertainty(tmp_path):
    """The design's objective is the combined uncertainty at the station's site: its value is the worst ratio of
    the designed path's combined sigma to S16's own path's combined sigma, and the written scenario is at the
    station's latitude, height and gravity."""
    st = read_station(STATION)
    out = tmp_path / "d.toml"
    d = run_json("design", "--out", out, "--minutes", "12", "--candidates", "8", "--population", "4",
                 "--scheduler", "none", "--station", STATION)
    sc = load_toml(out)
    assert sc.site.latitude == pytest.approx(st["latitude"].value, abs=1e-12)
    assert sc.site.gravity == pytest.approx(st["gravity"].value, abs=1e-9)
    u = {k: st[k].u for k in ("gravity", "latitude", "height", "time_base")}
    setup = B.make_setup("51", sc.site, sc.gimbal, sc.noise.arw, sc.noise.vrw, BiasNoise.from_imu_noise(sc.noise),
                         consider=u)
    mine = B.evaluate(setup, sc.path, keep_history=False)

    ref = B.evaluate(setup, s16_table1(), keep_history=False)
    assert d["objective"]["value"] == pytest.approx(float(np.max(mine.combined_sigma / ref.combined_sigma)), rel=1e-9)
    # the combination moved the objective: the accelerometer scale factors are held by the gravity on both paths
    k = [i for i, g in enumerate(setup.groups) if g == "accel_matrix"]
    assert np.all(mine.combined_sigma[k] > mine.sigma[k])
    assert d["station"] == st.name and d["budget"]["components"]
    assert out.read_text().splitlines()[0].startswith("# inscal design") and "combined uncertainty" in out.read_text()


def test_a_window_method_from_a_simulated_run():
    """``--method n25``: the budget of one simulated N25 run at the station, where the table's inputs (read by the
    method through its angles and rates) dominate; the gravity still gives u(g)/g on the accelerometer scale
    factors; ``--mc``: its JCGM 101 Monte Carlo finds nothing the linear budget misses at a typical station; the filter
    methods are the bound's, and a method needs a station."""
    st = read_station(STATION)
    d = run_json("observability", "n25", "--crlb", "--station", STATION, "--method", "n25", "--mc", 100)
    dom = {r["input"]: r for r in d["dominant_inputs"]}
    assert dom["table_angle"]["n_largest"] >= 5 and dom["table_angle"]["max_share"] > 0.5
    comps = {c["label"]: c for c in d["budget"]["components"]}
    lines = {x["input"]: x for x in comps["accel_scale_factor[0]"]["contributions"]}
    assert lines["gravity"]["contribution"] == pytest.approx(st["gravity"].u / st["gravity"].value * 1e6, rel=1e-3)
    mc = d["budget"]["monte_carlo"]  # does the linear budget hold on this path at this station
    assert mc["runs"] == 100 and [m["label"] for m in mc["components"]] == list(comps)
    assert "not validated" not in {m["verdict"] for m in mc["components"]}
    one_line(run("observability", "n25", "--crlb", "--station", STATION, "--mc", 100), "--mc needs --method")
    one_line(run("observability", "n25", "--crlb", "--station", STATION, "--method", "systematic51"),
             "window-mean method")
    one_line(run("observability", "n25", "--crlb", "--method", "n25"), "needs --station")


def test_the_chamber_through_the_scenarios_thermal_model():
    """On thermal-ramp the unit has a thermal model: without thermal states the chamber's stability enters every
    bias through its slope at the path's mean temperature (the line's u is the station's arcsine 0.1 K / sqrt 2);
    with thermal states the filter measures and models the temperature: sensitivity 0, said in a note."""
    from inscal.uncertainty.budget import thermal_slope
    from inscal.sim.scenarios import build

    st = read_station(STATION)
    d = run_json("observability", "thermal-ramp", "--crlb", "--station", STATION)
    comps = {c["label"]: c for c in d["budget"]["components"]}
    line = {x["input"]: x for x in comps["accel_bias[0]"]["contributions"]}["temperature_stability"]
    assert line["u"] == pytest.approx(st["temperature_stability"].u, rel=1e-12)  # K
    sc = build("thermal-ramp")
    t = np.linspace(0.0, d["crlb"]["path"]["duration_s"], 2001)
    slope = thermal_slope(sc.thermal, "accel_bias", float(np.mean(sc.temperature.at(t)[0])))[0]  # m/s^2 per K
    assert line["sensitivity"] == pytest.approx(abs(slope) / 9.80665e-6, rel=1e-6)  # ug per K
    assert line["share"] > 0.5
    d = run_json("observability", "thermal-ramp", "--crlb", "--station", STATION, "--states", "51,thermal")
    assert any("sensitivity 0" in n for n in d["budget"]["notes"])
    assert all(x["contribution"] == 0.0 for c in d["budget"]["components"] for x in c["contributions"]
               if x["input"] == "temperature_stability")
