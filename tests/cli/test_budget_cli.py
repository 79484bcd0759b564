"""``inscal calibrate --station FILE.toml`` and ``inscal db budget``: the budget computed with the
calibration, stored with the result, printed and as JSON equal to the database's (the repeatability
from a unit's history: ``tests/lab/test_budget.py``); the certificate's U and k are the stored budget's; a bad station file or a
method without a budget is one line, exit 2, nothing written or recorded.  (The per-stop coefficients
are computed here for two windows only, to keep the test short: the full loop runs in
``bench/budget_mc.py`` and the library tests check its pieces.)"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import pytest
import tomli_w

from inscal import lab
from inscal.uncertainty import budget as gum
from inscal.report.certificate import certificate_data, certificate_html

from budget_helpers import STATION, one_line, run


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("budgetcli")
    db = tmp / "lab.sqlite"
    assert run("db", "add", "U1", "--model", "FOG", "--db", db).exit_code == 0
    rec = tmp / "r1.h5"
    assert run("simulate", "n25", "--out", rec, "--seed", 1, "--rate-hz", 20).exit_code == 0
    return tmp, db, [rec]


def test_budget_stored_printed_and_certified(setup, two_windows):
    tmp, db, recs = setup
    r = run("calibrate", recs[0], "-m", "n25", "-o", tmp / "p2.toml", "--serial", "U1", "--db", db,
            "--station", STATION, "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    b = rep["budget"]
    assert b["station"] == "T-2, lab 3" and len(b["components"]) == 28
    inputs = {x["input"] for x in b["components"][0]["contributions"]}
    assert {"estimator (Type A)", "table_angle", "gravity", "time_base"} <= inputs
    assert "repeatability (Type A)" not in inputs  # no history yet
    for c in b["components"]:  # the reported sigma is the Type-A line; U = k u_c
        est = next(x for x in c["contributions"] if x["input"] == "estimator (Type A)")
        name, i = c["parameter"], c["index"]
        assert est["u"] == pytest.approx(rep["parameters"][name]["sigma"][i], rel=1e-12)
        assert c["U"] == pytest.approx(c["k"] * c["u_c"], rel=1e-12) and c["u_c"] >= est["u"]
    # field units: gravity 1 mGal -> 1e-5 / g = 1.021 ppm on the accelerometer scale factors; the encoder's
    # rounding shares the table angle's coefficients (rectangular, a / sqrt(3)); the table's non-orthogonality
    # does not enter the dth that N25 estimates; the JSON form reads back equal
    g = rep["gravity"]["g_site_m_s2"]
    lines = {x["input"]: x for x in b["components"][12]["contributions"]}
    assert b["components"][12]["label"] == "accel_scale_factor[0]"
    assert lines["gravity"]["sensitivity"] == pytest.approx(1e-5 / g * 1e6, rel=1e-3)
    assert lines["gravity"]["contribution"] == pytest.approx(1e-5 / g * 1e6, rel=1e-3)
    assert lines["encoder_resolution"]["sensitivity"] == pytest.approx(lines["table_angle"]["sensitivity"])
    assert lines["encoder_resolution"]["u"] == pytest.approx(0.18 / 3 ** 0.5)
    assert sum(x["share"] for x in lines.values()) == pytest.approx(1.0)
    dth = {x["input"]: x for x in b["components"][24]["contributions"]}
    assert b["components"][24]["label"] == "gimbal_nonorthogonality" and dth["axis_nonorthogonality"]["sensitivity"] < 1e-3
    assert any("temperature_stability" in n for n in b["notes"])
    assert gum.Budget.from_dict(b).to_dict() == json.loads(json.dumps(b))
    # the database holds exactly what the command reported
    got = json.loads(run("db", "budget", "U1", "--db", db, "--json").stdout)
    assert got["budget"] == b and got["station"]["station"]["name"] == "T-2, lab 3"
    text = run("db", "budget", "U1", "--db", db).stdout
    assert "accel_scale_factor[0]" in text and "table_rate" in text and "9.793788 m/s^2" in text
    with lab.open_database(db) as d:  # a result recorded without a station
        lab.record_calibration(d, "U1", (tmp / "p2.toml").read_text(), lab.SessionInfo(
            record_sha256="sha256:" + "ab" * 32, date=lab.parse_date("2025-01-02")), make_current=False)
    one_line(run("db", "budget", "U1", "--db", db, "--result", got["result_id"] + 1), "without a station description")
    # the certificate: every U and k the stored budget's, in the JSON and in the page's data-exact
    with lab.open_database(db) as d:
        cal = lab.current_calibration(d, "U1")
        stored = lab.get_budget(d, cal.id)
    doc = certificate_data(cal, None, issued=cal.recorded_at, budget=stored)
    page = certificate_html(doc)
    comps = {(c["parameter"], c["index"]): c for c in b["components"]}
    seen = {}
    for row in doc["results"]["rows"]:
        i = seen[row["parameter"]] = seen.get(row["parameter"], -1) + 1
        c = comps[(row["parameter"], i)]
        assert row["expanded_uncertainty"] == c["U"] and row["coverage_factor"] == c["k"]
        cells = re.search(rf"<tr data-label='{re.escape(row['label'])}'>(.*?)</tr>", page).group(1)
        assert f"data-exact='{c['U']!r}'" in cells and f"data-exact='{c['k']!r}'" in cells
        assert f"data-key='U' data-exact='{c['U']!r}'" in page
    assert "5a. Uncertainty budget" in page and "U (95 %)" in page
    # the command writes the same: its JSON copy holds the database's budget
    r = run("db", "certificate", "U1", "--db", db, "--out", tmp / "cert", "--no-pdf", "--json")
    assert r.exit_code == 0, r.stderr
    cert = json.loads((tmp / "cert" / Path(json.loads(r.stdout)["json"]).name).read_text())
    assert cert["budget"] == json.loads(json.dumps(stored)) and cert["results"]["coverage_probability"] == "95 %"


@pytest.mark.parametrize("edit, phrase", [
    (lambda d: d["inputs"]["gravity"].pop("uncertainty"), "input gravity: missing field 'uncertainty'"),
    (lambda d: d["inputs"]["table_angle"].update(uncertainty=-2.0), "input table_angle: negative uncertainty"),
    (lambda d: d["inputs"]["table_rate"].update(distribution="cauchy"), "unknown distribution 'cauchy'"),
])
def test_bad_station_files_are_one_line(setup, tmp_path, edit, phrase):
    _, db, recs = setup
    doc = tomllib.loads(STATION.read_text())
    edit(doc)
    bad = tmp_path / "station.toml"
    bad.write_text(tomli_w.dumps(doc))
    with lab.open_database(db) as d:
        before = lab.table_counts(d)
    one_line(run("calibrate", recs[0], "-m", "n25", "-o", tmp_path / "p.toml", "--serial", "U1", "--db", db,
                 "--station", bad), phrase)
    one_line(run("calibrate", recs[0], "-m", "n25", "-o", tmp_path / "q.toml", "--station", bad), phrase)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["station.toml"]
    with lab.open_database(db) as d:
        assert lab.table_counts(d) == before


def test_a_method_without_a_budget_is_refused(setup, tmp_path):
    one_line(run("calibrate", setup[2][0], "-m", "unified", "-o", tmp_path / "p.toml", "--station", STATION),
             "an uncertainty budget needs one of the methods n25, six-position")
    assert not (tmp_path / "p.toml").exists()
