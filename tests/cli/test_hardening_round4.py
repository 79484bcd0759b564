"""Hardening, round four: every case of the corpus run against the commands added last round, each as a
test: exit 2 with one line naming the real cause and a remedy that exists (or exit 0 with a correct
result), nothing left behind, every input byte-identical.  Classes: bounded inputs (a curve's points and
bytes, its values' range, a bag's messages), tracebacks on odd input, options that do not apply (one
table, :mod:`inscal.cli.applies`), the station's site and degrees of freedom, messages and their remedies
(every ``--option`` a message names is one the command line accepts), a dead writer's lock."""

from __future__ import annotations

import ast
import hashlib
import json
import math
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from inscal import io
from inscal.analysis.noise.identify import MAX_CURVE_POINTS
from inscal.cli.app import app
from inscal.io.recordfile import read_record

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()
SITE = ["--lat", "30", "--lon", "114", "--height", "20"]


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def snapshot(folder: Path) -> dict:
    return {p.relative_to(folder): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def refused(folder: Path, *args, needle: str | tuple = ()) -> str:
    """Run; exit 2, one line, the folder unchanged (nothing left, every input byte-identical)."""
    before = snapshot(folder)
    code, out, err = run(*args)
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("inscal: error: "), (code, out, err)
    for n in (needle,) if isinstance(needle, str) else needle:
        assert n in lines[0], (n, lines[0])
    assert snapshot(folder) == before
    return lines[0]


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A folder with a hand-held record (20 Hz), a curve, a station file at the record's site."""
    d = tmp_path_factory.mktemp("round4")
    assert run("simulate", "handheld-mems", "--rate-hz", "20", "--seed", "3", "--out", d / "h.h5")[0] == 0
    curve(d / "c.csv", 8)
    site = read_record(d / "h.h5").site
    st = (ROOT / "tests/data/station.toml").read_text()
    st = st.replace("value = 30.686\n", f"value = {math.degrees(site.latitude)!r}\n").replace(
        "value = 50.0\n", f"value = {site.height!r}\n").replace("value = 9.793788\n", f"value = {site.gravity!r}\n")
    (d / "st.toml").write_text(st)
    return d


def curve(path: Path, n: int, dt_lines=("# dt_s = 0.01",), row=None, quantity="avar") -> Path:
    """An octave curve of white noise (n points) in SI; ``row(k, tau, v)`` -> a row's text to replace."""
    lines = list(dt_lines) + [f"tau_s,{quantity},lower,upper"]
    for k in range(n):
        tau = 0.01 * 2 ** k
        v = 1e-10 / tau
        lines.append(row(k, tau, v) if row else f"{tau!r},{v!r},{0.8 * v!r},{1.25 * v!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------ bounded inputs and tracebacks (noise curves)
def test_a_curve_of_twenty_thousand_points_is_refused_up_front(lab, tmp_path):
    # the 0.9 MB file: 20,000 points (all tau, not octaves); refused after the 64th row
    lines = ["# dt_s = 0.01", "tau_s,avar,lower,upper"] + [f"{0.01 * m!r},{1e-10 / m!r},{0.8e-10 / m!r},{1.25e-10 / m!r}"
                                                           for m in range(1, 20001)]
    (tmp_path / "big.csv").write_text("\n".join(lines)[:900_000].rsplit("\n", 1)[0])
    refused(tmp_path, "noise", "--from-curve", tmp_path / "big.csv", needle=f"more than {MAX_CURVE_POINTS} points")
    (tmp_path / "huge.csv").write_text("\n".join(lines * 2))  # more bytes than a curve holds
    refused(tmp_path, "noise", "--from-curve", tmp_path / "huge.csv", needle="bytes, more than a curve's")
    curve(tmp_path / "c65.csv", MAX_CURVE_POINTS + 1)  # found here: an octave curve past the limit
    refused(tmp_path, "noise", "--from-curve", tmp_path / "c65.csv", needle=f"more than {MAX_CURVE_POINTS} points")


@pytest.mark.parametrize("case, needle", [
    ("zero-width", "the interval has zero width"),
    ("1e-302", "outside the adev values inscal fits"),
    ("1e283", "outside the adev values inscal fits"),
    ("two-dt", "a second '# dt_s' line"),
    ("dt-0", "dt_s = 0 s is not one of an IMU"),
    ("dt-negative", "dt_s = -0.01 s is not one of an IMU"),
    ("dt-nan", "dt_s = nan s is not one of an IMU"),
    ("dt-1e-302", "dt_s = 1e-302 s is not one of an IMU"),  # found here
    ("tau-0", "tau > 0"),  # found here
])
def test_odd_curves_are_one_line(tmp_path, case, needle):
    if case == "zero-width":
        curve(tmp_path / "c.csv", 6, row=lambda k, t, v: f"{t!r},{v!r},{v!r},{v!r}" if k == 2 else
              f"{t!r},{v!r},{0.8 * v!r},{1.25 * v!r}")
    elif case in ("1e-302", "1e283"):
        x = float(case)
        curve(tmp_path / "c.csv", 4, quantity="adev", row=lambda k, t, v: f"{t!r},{x!r},{0.9 * x!r},{1.1 * x!r}")
    elif case == "two-dt":
        curve(tmp_path / "c.csv", 6, dt_lines=("# dt_s = 0.01", "# dt_s = 0.02"))
    elif case.startswith("dt-"):
        dt = {"dt-0": "0", "dt-negative": "-0.01", "dt-nan": "nan", "dt-1e-302": "1e-302"}[case]
        curve(tmp_path / "c.csv", 6, dt_lines=(f"# dt_s = {dt}",))
    else:
        curve(tmp_path / "c.csv", 6, row=lambda k, t, v: f"0,{v!r},{0.8 * v!r},{1.25 * v!r}" if k == 0 else
              f"{t!r},{v!r},{0.8 * v!r},{1.25 * v!r}")
    refused(tmp_path, "noise", "--from-curve", tmp_path / "c.csv", needle=needle)


def test_monte_carlo_trials_and_station_files_are_bounded_up_front(lab, tmp_path, monkeypatch):
    from inscal.cli import limits

    monkeypatch.setattr(limits, "available_memory", lambda: 2e9)
    refused(lab, "calibrate", lab / "h.h5", "--method", "n25", "--out", lab / "p.toml", "--station", lab / "st.toml",
            "--mc", "5000000", needle=("--mc 5000000 (the budget's Monte Carlo keeps every trial) needs about 5.76 GB",
                                       "lower --mc"))
    big = tmp_path / "big.toml"  # found here: a station file of 5 MB (tomllib would read it all)
    big.write_text((lab / "st.toml").read_text() + "# " + "x" * 5_000_000 + "\n")
    refused(tmp_path, "calibrate", lab / "h.h5", "--method", "multi-position", "--station", big, "--out",
            tmp_path / "p.toml", needle="bytes, more than a station file holds")
    deep = tmp_path / "deep.toml"  # found here: nesting that would exhaust tomllib's recursion
    deep.write_text("[station]\nname = 'x'\n[inputs.gravity]\nvalue = " + "[" * 5000 + "]" * 5000 + "\n")
    refused(tmp_path, "calibrate", lab / "h.h5", "--method", "multi-position", "--station", deep, "--out",
            tmp_path / "p.toml", needle="nested more than 64 deep")


def test_a_negative_seed_is_named_by_its_option(lab):
    refused(lab, "noise", "--from-curve", lab / "c.csv", "--seed", "-1", needle="--seed must be a seed >= 0, got -1")
    line = refused(lab, "calibrate", lab / "h.h5", "--method", "n25", "--out", lab / "p.toml", "--station",
                   lab / "st.toml", "--mc", "1000", "--mc-seed", "-1", needle="--mc-seed must be a seed >= 0")
    assert "--mc " not in line
    refused(lab, "simulate", "static", "--seed", "-3", "--out", lab / "s.h5", needle="--seed must be a seed >= 0")


def test_a_curve_within_the_limits_is_identified(lab):
    code, out, err = run("noise", "--from-curve", lab / "c.csv", "--model", "WN", "--json")
    assert code == 0, err
    ch = json.loads(out)["channels"][0]
    # AVAR = N^2 / tau for white noise (IEEE 952): N = 1e-5 rad/sqrt(s) = 0.0343775 deg/sqrt(h)
    assert ch["model"] == "WN"
    n = ch["parameters"]["WN.n"]
    assert n["unit"] == "deg/sqrt(h)" and n["lower_95"] <= n["value"] <= n["upper_95"]
    assert n["value"] == pytest.approx(1e-5 * 180 / math.pi * 60, rel=1e-3)


@pytest.fixture(scope="module")
def recorded(lab, tmp_path_factory):
    """A database with unit U1 and its multi-position calibration of the hand-held record (result 1, p.toml)."""
    d = tmp_path_factory.mktemp("recorded")
    db = d / "lab.sqlite"
    assert run("db", "init", "--db", db)[0] == 0
    assert run("db", "add", "U1", "--model", "M", "--db", db)[0] == 0
    code, _, err = run("calibrate", lab / "h.h5", "--method", "multi-position", "--serial", "U1", "--db", db,
                       "--out", d / "p.toml")
    assert code == 0, err
    return d


# ------------------------------------------------------------------ db budget of a stored budget that is not one
@pytest.mark.parametrize("stored", ["{}", "null", '{"station": "x", "method": "n25", "coverage": 0.95, '
                                                  '"components": [{"parameter": "gyro_bias"}]}'])
def test_a_stored_budget_that_is_not_one_is_one_line(recorded, tmp_path, stored):
    db = tmp_path / "lab.sqlite"
    shutil.copy(recorded / "lab.sqlite", db)
    con = sqlite3.connect(db)  # an edited database: a budget row for the result, written by hand
    con.execute("INSERT INTO stations (name, document, document_sha256, recorded_at) VALUES ('x', '{}', 'h', "
                "'2026-01-01 00:00:00')")
    con.execute(f"INSERT INTO budgets VALUES (1, 1, 0.95, '{stored}', '2026-01-01 00:00:00')")
    con.commit()
    con.close()
    for args in (("db", "budget", "U1", "--db", db), ("db", "budget", "U1", "--db", db, "--json"),
                 ("db", "certificate", "U1", "--db", db, "--out", tmp_path / "cert")):
        refused(tmp_path, *args, needle=("is not a budget", "--supersedes 1"))


# ------------------------------------------------------------------ options that do not apply: one table
def test_options_that_do_not_apply_are_refused(lab, tmp_path):
    refused(lab, "noise", lab / "h.h5", "--kind", "accel", needle="--kind applies to --from-curve")
    refused(lab, "noise", "--from-curve", lab / "c.csv", "--kind", "gyro", "--channels", "az",
            needle="--channels az names an accelerometer channel, --kind gyro")
    refused(lab, "noise", "--from-curve", lab / "c.csv", "--kind", "accel", "--channels", "gx",  # found here
            needle="--channels gx names an gyro channel")
    refused(lab, "calibrate", lab / "h.h5", "--method", "ferraris", "--filter-rate-hz", "2", "--out", lab / "f.toml",
            needle="--filter-rate-hz applies to the systematic methods")
    refused(lab, "calibrate", lab / "h.h5", "--method", "multi-position", "--skip-encoder-check",  # found here
            "--out", lab / "f.toml", needle="--skip-encoder-check applies to a turntable record")
    refused(lab, "batch", lab / "h.h5", "--method", "multi-position", "--encoder-sigma", "1", "--serial", "U",
            "--db", lab / "x.sqlite", needle="--encoder-sigma applies to the systematic methods")  # found here
    t = np.arange(1, 301) * 0.01
    np.savetxt(tmp_path / "imu.txt", np.column_stack([t, np.full((300, 3), 1e-6), np.tile([0, 0, 0.098], (300, 1))]),
               fmt="%.9f")
    refused(tmp_path, "import", tmp_path / "imu.txt", "--format", "kf-gins", "--rates", "--out", tmp_path / "k.h5",
            *SITE, needle="--rates applies to --format psins or mat")


def test_an_output_named_for_another_format_is_refused(lab, tmp_path):
    refused(lab, "calibrate", lab / "h.h5", "--method", "multi-position", "--out", lab / "p.h5",
            needle="writes a TOML parameter file, and the name says .h5")
    refused(tmp_path, "simulate", "static", "--duration-h", "0.01", "--out", tmp_path / "s.txt",
            needle="writes an HDF5 record, and the name says .txt")
    t = np.arange(1, 301) * 0.01
    np.savetxt(tmp_path / "imu.txt", np.column_stack([t, np.full((300, 3), 1e-6), np.tile([0, 0, 0.098], (300, 1))]),
               fmt="%.9f")
    refused(tmp_path, "import", tmp_path / "imu.txt", "--format", "kf-gins", "--out", tmp_path / "k.toml", *SITE,
            needle="writes an HDF5 record, and the name says .toml")  # found here


def test_a_manifest_row_with_more_cells_than_its_header(lab, tmp_path):
    (tmp_path / "m.csv").write_text(f"path,serial\n{lab / 'h.h5'},U1,extra\n")
    refused(tmp_path, "batch", "--manifest", tmp_path / "m.csv", "--method", "multi-position", "--db",
            tmp_path / "x.sqlite", "--scheduler", "none", needle=("line 2: 3 cells, the header names 2", "quote"))
    (tmp_path / "m.csv").write_text(f"path,serial,serial\n{lab / 'h.h5'},U1,U2\n")  # found here
    refused(tmp_path, "batch", "--manifest", tmp_path / "m.csv", "--method", "multi-position", "--db",
            tmp_path / "x.sqlite", "--scheduler", "none", needle="names a column twice")


def test_db_add_of_a_second_result_of_the_same_record_and_method(lab, recorded, tmp_path):
    db = tmp_path / "lab.sqlite"
    shutil.copy(recorded / "lab.sqlite", db)
    # another parameter file of the same record and method (a later run: its text differs)
    (tmp_path / "q.toml").write_text((recorded / "p.toml").read_text() + "# calibrated again\n")
    refused(tmp_path, "db", "add", "U1", tmp_path / "q.toml", "--data", lab / "h.h5", "--db", db,
            needle=("multi-position calibration of the same record already (result 1)", "--supersedes 1"))
    refused(tmp_path, "db", "add", "U1", tmp_path / "q.toml", "--db", db,  # without --data: found here
            needle="--supersedes 1")
    code, out, err = run("db", "add", "U1", tmp_path / "q.toml", "--data", lab / "h.h5", "--db", db, "--supersedes",
                         "1")
    assert code == 0 and "result 2" in out, err


# ------------------------------------------------------------------ the station: site, dof, ranges
def station_variant(lab: Path, tmp_path: Path, old: str, new: str) -> Path:
    text = (lab / "st.toml").read_text()
    assert old in text
    (tmp_path / "s.toml").write_text(text.replace(old, new, 1))
    return tmp_path / "s.toml"


@pytest.mark.parametrize("edit, needle", [
    ("latitude", "latitude: the record's 30.68"),
    ("height", "input height: 1e+09 m is not a site on the Earth's surface"),
    ("dof", "dof must be >= 1, got 1e-300"),
    ("gravity", "input gravity: 20 m/s^2 is not a site on the Earth's surface"),  # found here
    ("height-other-site", "height: the record's"),  # found here: 500 m off, 1 m stated
])
def test_a_station_of_another_site_or_with_absurd_dof(lab, tmp_path, edit, needle):
    text = (lab / "st.toml").read_text()
    lat = re.search(r"\[inputs.latitude\]\nvalue = (\S+)", text).group(1)
    h = re.search(r"\[inputs.height\]\nvalue = (\S+)", text).group(1)
    g = re.search(r"\[inputs.gravity\]\nvalue = (\S+)", text).group(1)
    st = {"latitude": lambda: station_variant(lab, tmp_path, f"value = {lat}\n", "value = 60.0\n"),
          "height": lambda: station_variant(lab, tmp_path, f"value = {h}\n", "value = 1e9\n"),
          "dof": lambda: station_variant(lab, tmp_path, 'source = "GNSS survey of the pier"\n',
                                         'source = "GNSS survey of the pier"\ndof = 1e-300\n'),
          "gravity": lambda: station_variant(lab, tmp_path, f"value = {g}\n", "value = 20.0\n"),
          "height-other-site": lambda: station_variant(lab, tmp_path, f"value = {h}\n", "value = 500.0\n")}[edit]()
    refused(tmp_path, "calibrate", lab / "h.h5", "--method", "multi-position", "--station", st, "--out",
            tmp_path / "p.toml", needle=needle)


def test_a_station_a_few_sigma_off_is_noted_not_refused(lab, tmp_path, monkeypatch):
    """2 m off a height stated to 1 m (within the 100 m of another site): the budget is computed, with a note."""
    from inscal.uncertainty import sensitivity as S

    text = (lab / "st.toml").read_text()
    h = re.search(r"\[inputs.height\]\nvalue = (\S+)", text).group(1)
    st = station_variant(lab, tmp_path, f"value = {h}\n", f"value = {float(h) + 5.0!r}\n")
    monkeypatch.setattr(S, "record_sensitivities", lambda record, x, kinds, nwin=1: S.Sensitivities(
        {k: np.zeros(24) for k in S.GLOBAL_INPUTS}, {k: np.zeros((1, 2, 24)) for k in S.STOP_INPUTS}))
    code, out, err = run("calibrate", lab / "h.h5", "--method", "multi-position", "--station", st, "--out",
                         tmp_path / "p.toml")
    assert code == 0, err
    assert "note: height: the record's" in out and "5 u apart" in out, out[-800:]


# ------------------------------------------------------------------ messages: the real cause, a remedy that exists
def test_a_dead_gyro_is_named_not_the_motion(lab, tmp_path):
    rec = read_record(lab / "h.h5")
    d = np.array(rec.dtheta)
    d[:, 0] = 0.0
    io.write_record(tmp_path / "dead.h5", io.Record(rec.time, d, rec.dvel, None, rec.rate_hz, rec.site,
                                                    scenario="dead"))
    line = refused(tmp_path, "calibrate", tmp_path / "dead.h5", "--method", "multi-position", "--out",
                   tmp_path / "p.toml", needle="gyro x reads the same increment throughout the record")
    assert "move about" not in line


def test_a_kfgins_config_rate_is_named_as_the_configs(tmp_path):
    t = np.arange(1, 301) * 0.01
    np.savetxt(tmp_path / "imu.txt", np.column_stack([t, np.full((300, 3), 1e-6), np.tile([0, 0, 0.098], (300, 1))]),
               fmt="%.9f")
    (tmp_path / "kf.yaml").write_text(
        "imudatarate: 200\nimunoise:\n  arw: [0.003, 0.003, 0.004]\n  vrw: [0.03, 0.03, 0.03]\n"
        "  gbstd: [0.027, 0.027, 0.027]\n  abstd: [15.0, 15.0, 15.0]\n  gsstd: [300.0, 300.0, 300.0]\n"
        "  asstd: [300.0, 300.0, 300.0]\n  corrtime: 4.0\n")
    line = refused(tmp_path, "import", tmp_path / "imu.txt", "--format", "kf-gins", "--out", tmp_path / "k.h5",
                   *SITE, "--config", tmp_path / "kf.yaml", needle="the rate 200 Hz (imudatarate of --config")
    assert "--rate-hz 200" not in line
    # the same rate given as --rate-hz is named as the option (found here: both ways)
    refused(tmp_path, "import", tmp_path / "imu.txt", "--format", "kf-gins", "--out", tmp_path / "k.h5", *SITE,
            "--rate-hz", "200", needle="--rate-hz 200 is inconsistent")


def test_a_bags_gap_does_not_recommend_a_mapping(tmp_path):
    sys.path.insert(0, str(ROOT / "tests/io"))
    try:
        from test_import_bags import _gap_bag
    finally:
        sys.path.remove(str(ROOT / "tests/io"))
    bag = _gap_bag(tmp_path / "gap")
    line = refused(tmp_path, "import", bag, "--format", "rosbag", "--out", tmp_path / "o.h5", *SITE,
                   needle=("3 message(s) dropped", "the rosbag import bridges no gap"))
    assert "max_gap_s" not in line and "mapping bridges" not in line


def test_the_same_bag_imported_twice_gives_the_same_record(tmp_path):
    sys.path.insert(0, str(ROOT / "tests/io"))
    try:
        from test_import_bags import EPOCH, H_NS, RATE, rates, write_bag
    finally:
        sys.path.remove(str(ROOT / "tests/io"))
    from inscal.io.files import file_hash
    from inscal.io.records import record_attrs

    bag = write_bag(tmp_path / "b", "mcap", EPOCH + np.arange(200) * H_NS, *rates(np.arange(200) / RATE))
    before = snapshot(bag)
    for name in ("one.h5", "two.h5"):
        code, _, err = run("import", bag, "--format", "rosbag", "--out", tmp_path / name, *SITE)
        assert code == 0, err
    assert file_hash(tmp_path / "one.h5") == file_hash(tmp_path / "two.h5")
    assert record_attrs(tmp_path / "one.h5", ("created",))["created"] == "2023-11-14T22:13:20+00:00"  # EPOCH
    assert snapshot(bag) == before


TOKEN = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
#: strings that name other programs' options (a browser's command line; the warm-up script's argparse)
OTHER_PROGRAMS = {"src/inscal/report/certificate.py", "src/inscal/cli/warmup.py"}


def message_options() -> dict[str, set[str]]:
    """Every ``--option`` in a string (not a docstring) of the package -> the files naming it."""
    found: dict[str, set[str]] = {}
    for f in sorted((ROOT / "src/inscal").rglob("*.py")):
        rel = str(f.relative_to(ROOT))
        if rel in OTHER_PROGRAMS:
            continue
        tree = ast.parse(f.read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)) and n.body
                and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
                for t in TOKEN.findall(node.value):
                    found.setdefault(t, set()).add(rel)
    return found


def command_options() -> dict[tuple, set[str]]:
    def walk(c, prefix=()):
        if hasattr(c, "commands"):
            out = {}
            for n, sub in c.commands.items():
                out.update(walk(sub, prefix + (n,)))
            return out
        return {prefix: {o for p in c.params for o in list(getattr(p, "opts", [])) + list(getattr(p, "secondary_opts",
                                                                                                      [])) if o.startswith("--")}}
    return walk(typer.main.get_command(app))


def test_every_option_a_message_suggests_is_one_a_command_accepts():
    cmds = command_options()
    every = set().union(*cmds.values()) | {"--version", "--help"}
    found = message_options()
    assert "--method" in found and "--station" in found  # the walk sees the messages
    unknown = {t: sorted(fs) for t, fs in found.items() if t not in every}
    assert not unknown, unknown
    # the commands an option is named for in "inscal CMD ... --option" accept it
    for f in sorted((ROOT / "src/inscal").rglob("*.py")):
        for m in re.finditer(r"inscal ((?:db )?[a-z-]+)((?: (?:\.\.\.|[A-Z][A-Z.]*|--[a-z0-9-]+(?: [A-Z0-9.]+)?))+)",
                             f.read_text()):
            key = tuple(m.group(1).split())
            if key in cmds:
                for t in TOKEN.findall(m.group(2)):
                    assert t in cmds[key] | {"--help"}, (str(f), m.group(0), t)


# ------------------------------------------------------------------ a dead writer's lock
def test_a_sigkilled_writers_lock_is_taken_over_and_said(tmp_path):
    out = tmp_path / "s.h5"
    code = ("import os, signal, sys; from inscal.io.files import claim_output; claim_output(sys.argv[1]); "
            "os.kill(os.getpid(), signal.SIGKILL)")
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    p = subprocess.run([sys.executable, "-c", code, str(out)], env=env, timeout=60)
    assert p.returncode == -signal.SIGKILL
    lock = tmp_path / ".s.h5.lock"
    assert lock.exists()
    pid = lock.read_text().strip()
    code_, stdout, err = run("simulate", "static", "--duration-h", "0.01", "--rate-hz", "10", "--out", out)
    assert code_ == 0, err
    assert f".s.h5.lock: the lock of process {pid}, which has ended, taken over" in err
    assert out.exists() and not lock.exists()
