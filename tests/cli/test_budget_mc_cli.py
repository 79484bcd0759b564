"""``inscal calibrate … --station FILE.toml --mc N``: the budget's JCGM 101 Monte Carlo in the report, stored with
the budget, printed by ``db budget`` and shown on the certificate; refused in one line without a station, below 100
trials or with a filter method.  (The per-stop coefficients are taken at two windows, as in test_budget_cli.py, to
keep the test short; the Monte Carlo itself is :mod:`tests.lab.test_budget_mc`'s.)"""

from __future__ import annotations

import json

from inscal import lab
from inscal.report.certificate import certificate_data, certificate_html

from budget_helpers import STATION, run


def test_monte_carlo_stored_printed_and_certified(tmp_path, two_windows):
    db = tmp_path / "lab.sqlite"
    assert run("db", "add", "U9", "--model", "FOG", "--db", db).exit_code == 0
    rec = tmp_path / "r.h5"
    assert run("simulate", "n25", "--out", rec, "--seed", 2, "--rate-hz", 20).exit_code == 0
    r = run("calibrate", rec, "-m", "n25", "-o", tmp_path / "p.toml", "--serial", "U9", "--db", db,
            "--station", STATION, "--mc", 100, "--mc-seed", 4, "--json")
    assert r.exit_code == 0, r.stderr
    b = json.loads(r.stdout)["budget"]
    mc = b["monte_carlo"]
    assert mc["runs"] == 100 and mc["seed"] == 4 and len(mc["components"]) == len(b["components"])
    for m, c in zip(mc["components"], b["components"]):
        assert m["label"] == c["label"] and m["U"] == c["U"] and m["low"] < m["value"] < m["high"]
        assert m["verdict"] in ("validated", "not validated", "undecided")
    got = json.loads(run("db", "budget", "U9", "--db", db, "--json").stdout)
    assert got["budget"]["monte_carlo"] == mc
    text = run("db", "budget", "U9", "--db", db).stdout
    assert "JCGM 101 Monte Carlo: 100 trials" in text and text.count("JCGM 101: [") == len(b["components"])
    with lab.open_database(db) as d:
        cal = lab.current_calibration(d, "U9")
        stored = lab.get_budget(d, cal.id)
    page = certificate_html(certificate_data(cal, None, issued=cal.recorded_at, budget=stored))
    first = mc["components"][0]
    assert f"data-mc='{first['label']}'" in page and f"data-exact='{first['low']!r}'" in page


def test_refusals(tmp_path):
    rec = tmp_path / "r.h5"
    rec.write_bytes(b"")
    for args, phrase in ((("--mc", 200), "give --station"),
                         (("--station", STATION, "--mc", 50), "between 100 and 10^7"),
                         (("--station", STATION, "--mc", 200, "-m", "systematic51"), "window-mean methods")):
        argv = ["calibrate", rec, "-o", tmp_path / "p.toml", *args]
        if "-m" not in args:
            argv += ["-m", "n25"]
        r = run(*argv)
        assert r.exit_code == 2 and phrase in r.stderr and "\n" not in r.stderr.strip(), r.stderr
        assert not (tmp_path / "p.toml").exists()
