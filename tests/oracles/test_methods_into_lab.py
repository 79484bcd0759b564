"""Every calibration method's result goes through the lab's paths: ``calibrate --serial`` (with a station
description: the GUM budget stored), ``db budget``, ``db certificate``, ``db add`` of its parameter file and
``batch``.  The table-free methods (``multi-position`` on a simulated hand-held record, ``ferraris`` on the
independent generator's six faces and three turns) and the fast window-mean methods (six-position,
twelve-position, joint on a short N25 path) run every path here; every other method names the tests
that run its paths, so that a new method in :data:`inscal.calibrate.METHODS` fails this file until it has
them.  The budget's gravity coefficient is checked against its closed form (a gravity error ``dg`` is an
accelerometer scale factor error ``dg/g``, 1:1)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import tomllib
from test_handheld_ferraris import session
from typer.testing import CliRunner

from inscal import io
from inscal.calibrate import METHODS, NO_TABLE_METHODS
from inscal.cli.app import app
from inscal.core.error_model import parameter_components
from inscal.core.turntable import n25_twelve
from inscal.io.recordfile import record_info
from inscal.uncertainty import sensitivity as S
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()

#: the methods run through every path here (the window-mean ones on a short N25 twelve-position path)
HERE = tuple(sorted(NO_TABLE_METHODS)) + ("six-position", "twelve-position", "joint")
#: the other methods: the tests that run their --serial, batch, db add and certificate paths
TABLE_METHOD_TESTS = {
    "n25": ["tests/cli/test_db_cli.py", "tests/lab/test_batch.py", "tests/cli/test_db_certificate.py"],
    "systematic51": ["tests/cli/test_budget_mc_cli.py", "tests/cli/test_db_transactions.py"],
    "systematic30": ["tests/cli/test_db_cli.py", "tests/cli/test_db_transactions.py"],
    "unified": ["tests/cli/test_budget_cli.py", "tests/cli/test_db_transactions.py"],
    "thermal-plateaus": ["tests/cli/test_budget_thermal_cli.py"],
}
#: the methods without a GUM budget, and why
NO_BUDGET = {"unified": "the encoder-aided filter's budget is not derived",
             "thermal-plateaus": "a budget per plateau is not derived"}


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def test_every_method_has_its_lab_paths_and_a_budget_or_a_reason():
    for m in METHODS:
        assert (m in HERE) != (m in TABLE_METHOD_TESTS), f"{m}: no test runs its lab paths"
        assert (m in S.BUDGET_METHODS) != (m in NO_BUDGET), f"{m}: a budget, or a reason for none"
    for m, files in TABLE_METHOD_TESTS.items():
        assert m in METHODS
        for f in files:
            assert f'"{m}"' in (ROOT / f).read_text(), (m, f)


@pytest.fixture()
def gravity_only(monkeypatch):
    """The record route's differences for the gravity alone (two calibrations, not eight): the site's other
    inputs get coefficient 0 here; bench and the library tests run them all."""
    full = S.record_sensitivities

    def short(record, x, kinds, nwin=1):
        monkeypatch.setattr(S, "GLOBAL_INPUTS", ("table_rate", "axis_nonorthogonality", "gravity"))
        sens = full(record, x, kinds, nwin)
        n = sens.glob["gravity"].size
        sens.glob.update({k: np.zeros(n) for k in ("latitude", "height", "time_base")})
        return sens

    monkeypatch.setattr(S, "record_sensitivities", short)
    full_windows = S.sensitivities

    def two(ws, geo, x, kinds, stop_inputs=tuple(S.STOP_INPUTS), windows=None):  # the per-stop loop at two windows
        static = [k for k, w in enumerate(ws.windows) if w.kind == "static"]
        rate = [k for k, w in enumerate(ws.windows) if w.kind == "rate"]
        return full_windows(ws, geo, x, kinds, stop_inputs, [static[0], rate[0]])

    monkeypatch.setattr(S, "sensitivities", two)


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("methods")
    code, _, err = run("simulate", "handheld-mems", "--rate-hz", "20", "--seed", "3", "--out", d / "mp.h5")
    assert code == 0, err
    rec, _ = session("mems", 1, 1.0)
    io.write_record(d / "fe.h5", io.Record(rec.time, rec.dtheta, rec.dvel, None, 50.0, rec.site, scenario="ferraris"))
    sc = dataclasses.replace(build("n25"), rate_hz=20.0, path=n25_twelve(
        dwell_s=25.0, rate_dps=20.0, rate_test_dps=20.0, rate_test_turns=1, accel_dps2=20.0))
    write_simulation(d / "tt.h5", sc, np.random.default_rng(1))
    return {"multi-position": d / "mp.h5", "ferraris": d / "fe.h5", "six-position": d / "tt.h5",
            "twelve-position": d / "tt.h5", "joint": d / "tt.h5"}


def station_for(record: Path, out: Path) -> Path:
    """tests/data/station.toml at the record's own site."""
    doc = tomllib.loads((ROOT / "tests/data/station.toml").read_text())
    site = record_info(record).site
    doc["inputs"]["gravity"]["value"] = float(site.gravity)
    doc["inputs"]["latitude"]["value"] = math.degrees(site.latitude)
    doc["inputs"]["height"]["value"] = float(site.height)
    out.write_text(tomli_w.dumps(doc))
    return out


@pytest.mark.parametrize("method", HERE)
def test_a_table_free_result_goes_through_every_lab_path(method, records, tmp_path, gravity_only):
    rec = records[method]
    before = rec.read_bytes()
    db = tmp_path / "lab.sqlite"
    assert run("db", "init", "--db", db)[0] == 0
    assert run("db", "add", "U1", "--model", "M", "--db", db)[0] == 0
    st = station_for(rec, tmp_path / "st.toml")
    code, out, err = run("calibrate", rec, "--method", method, "--serial", "U1", "--db", db, "--station", st,
                         "--out", tmp_path / "p.toml", "--json")
    assert code == 0, err
    assert json.loads(out)["db"]["result_id"] == 1
    code, out, err = run("db", "budget", "U1", "--db", db, "--json")
    assert code == 0, err
    bud = json.loads(out)["budget"]
    g = record_info(rec).site.gravity
    sf = [c for c in bud["components"] if c["parameter"] == "accel_scale_factor"]
    assert len(sf) == 3
    for c in sf:  # ppm per mGal: 1e-5 / g * 1e6 (the closed form, 1:1)
        line = next(x for x in c["contributions"] if x["input"] == "gravity")
        assert abs(abs(line["sensitivity"]) - 10.0 / g) < 0.02 * 10.0 / g, line
    code, out, err = run("db", "show", "U1", "--db", db, "--json")
    assert code == 0, err
    shown = json.loads(out)
    labels = shown["covariance"]["labels"]
    assert shown["covariance"]["correlations"] == (method in NO_TABLE_METHODS)  # the window means: 1 sigma only
    assert all(re.fullmatch(r"[a-z_]+(\[[a-z0-9]+\])?", lab) for lab in labels), labels
    cov = np.array(shown["covariance"]["matrix"], float)
    for i, lab in enumerate(labels):  # the diagonal in field units is the stored 1 sigma squared
        name, comp = lab[:-1].split("[") if "[" in lab else (lab, "")
        sig = np.ravel(shown["parameters"][name]["sigma"])[parameter_components(name).index(comp)]
        assert math.isclose(math.sqrt(cov[i, i]), sig, rel_tol=1e-6), (lab, math.sqrt(cov[i, i]), sig)
    code, out, err = run("db", "certificate", "U1", "--db", db, "--out", tmp_path / "cert")
    assert code == 0, err
    assert "uncertainty" in (tmp_path / "cert" / "INSCAL-U1-1.json").read_text()
    assert run("db", "add", "U2", "--model", "M", "--db", db)[0] == 0
    code, out, err = run("db", "add", "U2", tmp_path / "p.toml", "--data", rec, "--db", db)
    assert code == 0, err
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "U3_2026-01-02.h5").write_bytes(before)
    code, out, err = run("batch", runs, "--method", method, "--db", db, "--scheduler", "none", "--register",
                         "--model", "M")
    assert code == 0 and "1 calibrated" in out + err and "0 failed" in out + err, out + err
    assert rec.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cert", "lab.sqlite", "p.toml", "runs", "st.toml"]
