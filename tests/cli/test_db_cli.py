"""``inscal db`` and ``inscal calibrate --serial``: the lab workflow of the guide's database page runs as written (real simulated
records calibrated into the database; the exported parameter file is byte for byte calibrate's), a systematic
calibration keeps the filter's covariance, a record recalibrated is refused unless it supersedes, and every
bad input is one line, exit 2, nothing written."""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from forkserver import Shell
from typer.testing import CliRunner

from inscal import lab
from inscal.calibrate.result import CalibrationResult
from inscal.cli.app import app
from inscal.core.error_model import GimbalErrors, ImuErrors
from inscal.io.files import file_hash
from inscal.report.certificate import find_chromium

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def lab_block() -> str:
    """The first fenced block of docs/guide/database.md's "A lab's month" section."""
    text = (ROOT / "docs" / "guide" / "database.md").read_text(encoding="utf-8")
    sec = text[text.index("## A lab's month"):]
    return re.search(r"```bash\n(.*?)```", sec, re.DOTALL).group(1)


def run(*args, env=None):
    r = runner.invoke(app, [str(a) for a in args], env=env)
    return r


def one_line(r, *phrases):
    assert r.exit_code == 2, (r.exit_code, r.stdout, r.stderr)
    err = r.stderr.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    for p in phrases:
        assert p in err, (p, err)
    return err


@pytest.mark.slow
def test_the_guides_lab_workflow_runs_as_written(tmp_path, fork_servers):
    """The block as one shell runs it (it exports INSCAL_DB), then what it left: two results with their sessions, the
    exports identical to calibrate's files, the history of two calibrations."""
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "120"}
    env.pop("INSCAL_DB", None)
    block = lab_block()
    if find_chromium() is None:  # the certificate's PDF needs Chromium: its HTML and JSON are made without it
        block = block.replace("inscal db certificate ", "inscal db certificate --no-pdf ")
    # line by line as ``set -e`` runs it: the first failure ends the block (forkserver.Shell: the inscal lines as
    # bash would split them, in forks of one process, with the block's environment; the installed script's run
    # of a first line is the README block's, tests/cli/readme_block.py)
    shell = Shell(fork_servers.get(), tmp_path, env, tmp_path.parent / f"{tmp_path.name}-logs", script=False)
    for line in block.splitlines():
        if line.strip():
            r = shell.run(line)
            assert r.returncode == 0, f"{line}\n{r.stderr[-3000:]}"
            assert "Traceback" not in r.stderr, line
    assert (tmp_path / "current.toml").read_bytes() == (tmp_path / "feb.toml").read_bytes()
    assert (tmp_path / "history.png").stat().st_size > 10_000
    db = tmp_path / "lab.sqlite"
    with lab.open_database(db) as d:
        cals = lab.calibrations(d, "FOG-0042")
        assert [c.date.month for c in cals] == [1, 2] and cals[1].current
        jan, feb = cals
        assert jan.session.temperature_c == 21.5 and feb.session.temperature_c is None
        assert jan.session.record_sha256 == file_hash(tmp_path / "jan.h5") and jan.session.station == "T1"
        assert jan.session.path_name == "n25-twelve" and jan.session.g_site_m_s2 == pytest.approx(9.7937880)
        assert jan.param_text.encode() == (tmp_path / "jan.toml").read_bytes()
        assert jan.fit_dof > 0 and 0.0 <= jan.fit_p <= 1.0 and jan.method == "n25"
        assert jan.options == lab.calibration_options("n25")
        assert set(jan.parameters) >= {"gyro_scale_factor", "accel_bias", "gimbal_nonorthogonality", "mount_attitude"}
        assert jan.parameters["gimbal_nonorthogonality"].value == pytest.approx(20.0, abs=2.0)
    # the certificate of the current calibration: the database's numbers, the PDF where Chromium is installed
    name = f"INSCAL-FOG-0042-{feb.id}"
    cert = json.loads((tmp_path / "certs" / f"{name}.json").read_text(encoding="utf-8"))
    assert cert["id"] == name and cert["laboratory"]["name"] == "North lab, 1 Example Road"
    gn = feb.parameters["gimbal_nonorthogonality"]
    (row,) = [r for r in cert["results"]["rows"] if r["label"] == "gimbal_nonorthogonality"]
    assert row["value"] == float(gn.value) and row["expanded_uncertainty"] == 2 * float(gn.sigma)
    assert (tmp_path / "certs" / f"{name}.html").is_file()
    pdf = tmp_path / "certs" / f"{name}.pdf"
    assert (pdf.is_file() and pdf.read_bytes().startswith(b"%PDF")) == (find_chromium() is not None)
    # the history of the two: every component has its step test; no drift test with two calibrations
    r = run("db", "history", "FOG-0042", "--db", db, "--json")
    assert r.exit_code == 0, r.stderr
    h = json.loads(r.stdout)
    comps = [c for p in h["parameters"].values() for c in p["components"]]
    assert len(comps) == 28 and all(c["n"] == 2 and c["tests"] == 1 for c in comps)
    assert h["tests"] == 28 and h["month_days"] == pytest.approx(30.4375)
    ab = h["parameters"]["accel_bias"]["components"][0]
    assert ab["drift"]["rate_per_month"] == pytest.approx((ab["values"][1] - ab["values"][0]) / ab["months"][1])
    r = run("db", "export", "FOG-0042", "--db", db, "--result", jan.id, "--out", tmp_path / "jan-exported.toml")
    assert r.exit_code == 0 and (tmp_path / "jan-exported.toml").read_bytes() == (tmp_path / "jan.toml").read_bytes()
    # a parameter file recorded already is refused by db add; the JSON of show and list
    one_line(run("db", "add", "FOG-0042", tmp_path / "jan.toml", "--db", db), "recorded already", f"result {jan.id}")
    r = run("db", "show", "FOG-0042", "--db", db, "--result", jan.id, "--json")
    show = json.loads(r.stdout)
    assert show["id"] == jan.id and show["provenance"]["session"]["operator"] == "ana" and not show["current"]
    assert show["covariance"]["basis"] == "parameters" and len(show["covariance"]["labels"]) == 28
    r = run("db", "list", "--db", db, "--json")
    units = json.loads(r.stdout)["units"]
    assert [(u["serial"], u["model"], u["results"]) for u in units] == [
        ("FOG-0042", "FOG-IMU", 2), ("FOG-0043", "FOG-IMU", 1), ("FOG-0044", "FOG-IMU", 1)]
    assert units[0]["current"]["id"] == feb.id
    # the batch lines: each archive record once (the second batch skipped both), unit and date from its name
    with lab.open_database(db) as d:
        for serial in ("FOG-0043", "FOG-0044"):
            (c,) = lab.calibrations(d, serial, superseded=True)
            rec = tmp_path / f"{serial}_2025-03-01.h5"
            assert (c.session.record_sha256, c.session.station, c.session.date) == (
                file_hash(rec), "T2", lab.parse_date("2025-03-01"))
            assert c.options == jan.options and c.current


def synthetic_params(path: Path, record: Path, value: float) -> None:
    """A parameter file (method manual) of ``record`` with one parameter."""
    res = CalibrationResult("manual", ImuErrors(accel_scale_factor=np.array([value, 0.0, 0.0]) * 1e-6), GimbalErrors(),
                            {"accel_scale_factor": np.array([1e-6, 1e-6, 1e-6])}, ("accel_scale_factor",))
    path.write_text(lab.param_file_text(res, record.name, file_hash(record), {"scenario": "synthetic"}),
                    encoding="utf-8")


@pytest.fixture
def small_db(tmp_path):
    """A database with unit U1 and one recorded parameter file of a (fake) record."""
    rec = tmp_path / "run.h5"
    rec.write_bytes(b"not really a record, only its hash is used")
    synthetic_params(tmp_path / "p1.toml", rec, 10.0)
    db = tmp_path / "c.sqlite"
    assert run("db", "add", "U1", "--model", "M", "--db", db).exit_code == 0
    r = run("db", "add", "U1", tmp_path / "p1.toml", "--db", db, "--date", "2025-03-01", "--json")
    assert r.exit_code == 0, r.stderr
    assert json.loads(r.stdout)["current"]
    return tmp_path, db


def test_bad_input_is_one_line_and_writes_nothing(small_db):
    tmp, db = small_db
    before = sorted(p.name for p in tmp.iterdir())
    missing = tmp / "none.sqlite"
    one_line(run("db", "list", "--db", missing), "no calibration database", "inscal db init")
    one_line(run("db", "show", "U1", "--db", "mysql://u@h/x"), "unsupported database 'mysql'")
    one_line(run("db", "show", "NOPE", "--db", db), "unknown unit 'NOPE'")
    one_line(run("db", "show", "U1", "--db", db, "--result", 99), "no calibration result 99")
    one_line(run("db", "add", "U1", "--model", "other", "--db", db), "registered already with model 'M'")
    one_line(run("db", "add", "U2", tmp / "p1.toml", "--db", db), "unknown unit 'U2'", "inscal db add U2")
    one_line(run("db", "add", "U1", "--station", "T1", "--db", db), "give its parameter file")
    one_line(run("db", "add", "U1", tmp / "p1.toml", "--db", db, "--date", "yesterday"), "'yesterday' is not a date")
    one_line(run("db", "add", "U1", tmp / "nope.toml", "--db", db), "nope.toml")
    one_line(run("db", "add", "U1", tmp / "p1.toml", "--db", db, "--data", db), "calibrated from another record")
    one_line(run("db", "history", "U1", "--db", db, "--k", "0"), "--k must be > 0")
    one_line(run("db", "history", "U1", "--db", db, "--method", "n25"), "no n25 calibration", "manual")
    one_line(run("db", "history", "U1", "--db", db, "--plot", tmp / "h.txt"), ".png, .pdf or .svg")
    one_line(run("db", "export", "U1", "--db", db, "--out", tmp / "p1.toml"), "exists; use --force")
    one_line(run("db", "export", "U1", "--db", db, "--out", db, "--force"), "is the calibration database")
    one_line(run("db", "export", "U1", "--db", db, "--out", tmp / "nodir" / "x.toml"), "does not exist")
    one_line(run("calibrate", tmp / "run.h5", "--method", "n25", "--out", tmp / "o.toml", "--db", db),
             "--db", "give --serial")
    one_line(run("calibrate", tmp / "run.h5", "--method", "n25", "--out", tmp / "o.toml", "--serial", "U1", "--db",
                 missing), "no calibration database")
    one_line(run("calibrate", tmp / "run.h5", "--method", "n25", "--out", tmp / "o.toml", "--serial", "NOPE", "--db",
                 db), "unknown unit 'NOPE'")
    one_line(run("calibrate", tmp / "run.h5", "--method", "n25", "--out", tmp / "o.toml", "--serial", "U1", "--db",
                 db, "--supersedes", 99), "no calibration result 99")
    assert sorted(p.name for p in tmp.iterdir()) == before
    with lab.open_database(db) as d:
        assert lab.table_counts(d) == {"units": 1, "sessions": 1, "results": 1, "parameters": 3, "current": 1,
                                          "result_keys": 1, "publications": 0, "stations": 0, "budgets": 0}


def test_db_commands_and_their_json(small_db, monkeypatch):
    tmp, db = small_db
    monkeypatch.setenv("INSCAL_DB", str(db))  # the default database
    rec = tmp / "run2.h5"
    rec.write_bytes(b"another fake record")
    synthetic_params(tmp / "p2.toml", rec, 15.0)
    r = run("db", "add", "U1", tmp / "p2.toml", "--date", "2025-04-01", "--station", "T2", "--json")
    assert r.exit_code == 0, r.stderr
    rid = json.loads(r.stdout)["result_id"]
    r = run("db", "init", "--json")
    assert json.loads(r.stdout) == {"db": str(db), "created": False, "revision": lab.head_revision(), "schema": 5}
    r = run("db", "show", "U1")
    assert r.exit_code == 0 and f"result {rid}, manual" in r.stdout and "station T2" in r.stdout
    assert "accel_scale_factor       [15, 0, 0] +- [1, 1, 1] ppm" in r.stdout
    r = run("db", "history", "U1", "--plot", tmp / "h.svg", "--json")
    h = json.loads(r.stdout)
    c = h["parameters"]["accel_scale_factor"]["components"][0]
    assert c["last_step"]["change"] == pytest.approx(5.0) and c["last_step"]["z"] == pytest.approx(5.0 / np.sqrt(2))
    assert c["flags"] == ["step"] and h["flagged"][0]["label"] == "accel_scale_factor[x]"
    assert (tmp / "h.svg").stat().st_size > 5000 and h["plot"] == str(tmp / "h.svg")
    one_line(run("db", "history", "U1", "--plot", tmp / "h.svg"), "exists; use --force")
    r = run("db", "history", "U1", "--k", "5")
    assert r.exit_code == 0 and "0 flagged of 3 tests" in r.stdout
    r = run("db", "list", "--flagged", "--json")
    (u,) = json.loads(r.stdout)["units"]
    assert u["serial"] == "U1" and u["current"]["id"] == rid and u["tests"] == 3
    r = run("db", "list", "--flagged", "-k", "5")
    assert r.exit_code == 0 and "no unit raises a flag" in r.stdout
    r = run("db", "export", "U1", "--out", tmp / "e.toml", "--json")
    e = json.loads(r.stdout)
    assert e["result_id"] == rid and (tmp / "e.toml").read_bytes() == (tmp / "p2.toml").read_bytes()
    r = run("db", "export", "U1", "--out", tmp / "e.toml", "--result", rid - 1, "--force")
    assert r.exit_code == 0 and (tmp / "e.toml").read_bytes() == (tmp / "p1.toml").read_bytes()


def test_a_systematic_calibration_keeps_the_filter_covariance(tmp_path):
    """``calibrate --serial`` with the systematic filter: the state set, the innovation fit and the filter's full
    covariance of its parameter states (SI, labelled) are recorded with the result."""
    db = tmp_path / "c.sqlite"
    assert run("simulate", "psins19", "--out", tmp_path / "p19.h5", "--seed", 4).exit_code == 0
    assert run("db", "add", "PSINS-1", "--db", db).exit_code == 0
    r = run("calibrate", tmp_path / "p19.h5", "--method", "systematic30", "--states", "30", "--out", tmp_path / "s.toml",
            "--serial", "PSINS-1", "--db", db, "--operator", "bo")
    assert r.exit_code == 0, r.stderr
    assert "recorded in" in r.stdout and "now the current calibration" in r.stdout
    with lab.open_database(db) as d:
        cal = lab.current_calibration(d, "PSINS-1")
    cov = cal.covariance
    assert cov["basis"] == "states" and cov["units"] == "SI" and cov["correlations"]
    P = np.array(cov["matrix"], dtype=float)
    assert P.shape == (21, 21) and np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)
    assert cov["labels"][0] == "gyro_matrix[xx]" and cal.state_set == "30"
    assert cal.fit_dof > 0 and cal.fit["chi2"] == cal.fit_chi2 and 0.0 <= cal.fit_p <= 1.0
    assert cal.options == lab.calibration_options("systematic30", states="30")
    assert cal.param_text.encode() == (tmp_path / "s.toml").read_bytes()
    # the same record with the same options again: refused before calibrating, nothing written
    args = ("calibrate", tmp_path / "p19.h5", "--method", "systematic30", "--states", "30", "--out", tmp_path / "t.toml",
            "--serial", "PSINS-1", "--db", db)
    one_line(run(*args), "recorded already for PSINS-1", f"--supersedes {cal.id}")
    assert not (tmp_path / "t.toml").exists()
    # ... unless it supersedes the old result: it then replaces it in the history and as the current calibration
    r = run(*args, "--supersedes", cal.id, "--json")
    assert r.exit_code == 0, r.stderr
    new = json.loads(r.stdout)["db"]
    assert new["serial"] == "PSINS-1" and new["current"] and new["result_id"] != cal.id
    with lab.open_database(db) as d:
        assert [c.id for c in lab.calibrations(d, "PSINS-1")] == [new["result_id"]]
        assert lab.get_calibration(d, cal.id).superseded_by == (new["result_id"],)
    r = run("db", "export", "PSINS-1", "--db", db, "--out", tmp_path / "e.toml")
    assert r.exit_code == 0 and (tmp_path / "e.toml").read_bytes() == (tmp_path / "t.toml").read_bytes()


def test_a_serial_with_spaces_at_its_ends_is_stored_stripped_and_says_so(tmp_path):
    """The database stores serials without the spaces at their ends; the command says so instead of doing it silently."""
    from typer.testing import CliRunner

    from inscal.cli.app import app

    db = tmp_path / "lab.sqlite"
    r = CliRunner().invoke(app, ["db", "add", "  FOG-9 ", "--model", "FOG", "--db", str(db)])
    assert r.exit_code == 0, r.output
    assert "serial '  FOG-9 ' is stored as 'FOG-9' (spaces at its ends removed)" in r.stderr
    r = CliRunner().invoke(app, ["db", "list", "--db", str(db), "--json"])
    assert r.exit_code == 0 and "FOG-9" in r.stdout and "  FOG-9 " not in r.stdout
