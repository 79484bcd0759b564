"""``inscal batch``: many records calibrated into the calibration database.

- a batch's stored parameter file is byte for byte what ``inscal calibrate --serial`` stores for the same
  record and options (the clock frozen), and calibrate then finds the record recorded already;
- the units and dates of the records: file names (``{serial}_{date}.h5``), ``--serial``, the record's
  ``imu_serial`` attribute, a CSV manifest; a failed record is one line and the rest go on (exit 1);
- a bad invocation is one line, exit 2, and writes nothing;
- killed with SIGKILL once about half the records are in the database (a real subprocess on a local Dask
  cluster of 2 workers on SQLite; in one process on PostgreSQL) and run again: every record exactly once;
  the workers die with the batch (bench/bench_batch.py does the same with 300 records, both back-ends on
  a local cluster).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import lab
from inscal.analysis.montecarlo import LOCAL_WORKER_ENVIRON
from inscal.cli.app import app
from inscal.core.turntable import n25_twelve
from inscal.io import paramfile
from inscal.io.files import file_hash
from inscal.io.records import record_attrs
from inscal.runs import batch as lb
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
runner = CliRunner()
UNITS = ("FOG-0001", "FOG-0002", "FOG_0003")  # an underscore in a serial: the date decides where it ends
DATES = ("2025-01-15", "2025-02-15")


def short_n25():
    """The N25 scenario on its twelve positions with 25-s dwells and 20 deg/s moves (800 s at 100 Hz)."""
    return dataclasses.replace(build("n25"), path=n25_twelve(dwell_s=25.0, rate_dps=20.0, rate_test_dps=20.0,
                                                             rate_test_turns=1, accel_dps2=20.0))


@pytest.fixture(scope="module")
def records(tmp_path_factory) -> Path:
    """A folder of 6 short records, ``SERIAL_DATE.h5``: 3 units, 2 dates each (seeded noise)."""
    folder = tmp_path_factory.mktemp("records")
    sc = short_n25()
    for k, (u, d) in enumerate((u, d) for u in UNITS for d in DATES):
        write_simulation(folder / f"{u}_{d}.h5", sc, np.random.default_rng(100 + k))
    return folder


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def one_line(r, *phrases):
    assert r.exit_code == 2, (r.exit_code, r.stdout, r.stderr)
    err = r.stderr.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    for p in phrases:
        assert p in err, (p, err)


def results_by_record(url: str) -> dict[tuple[str, str], int]:
    """(serial, record sha256) -> number of results in the database."""
    out: dict[tuple[str, str], int] = {}
    with lab.open_database(url) as db:
        for unit, _, _ in lab.list_units(db):
            for c in lab.calibrations(db, unit.serial, superseded=True):
                key = (unit.serial, c.session.record_sha256)
                out[key] = out.get(key, 0) + 1
    return out


def expected(folder: Path) -> set[tuple[str, str]]:
    return {(p.name.rsplit("_", 1)[0], file_hash(p)) for p in folder.glob("*.h5")}


class FrozenDatetime(dt.datetime):
    @classmethod
    def now(cls, tz=None):
        return cls(2025, 3, 1, 12, 0, 0, tzinfo=tz)


def test_the_stored_parameter_file_is_calibrates(records, tmp_path, monkeypatch):
    monkeypatch.setattr(paramfile, "_dt", SimpleNamespace(datetime=FrozenDatetime, timezone=dt.timezone))
    rec = records / f"{UNITS[0]}_{DATES[0]}.h5"
    one, many = tmp_path / "one.sqlite", tmp_path / "many.sqlite"
    assert invoke("db", "add", UNITS[0], "--db", one).exit_code == 0
    r = invoke("calibrate", rec, "--method", "n25", "--out", tmp_path / "p.toml", "--serial", UNITS[0], "--db", one,
               "--station", "T1", "--date", DATES[0])
    assert r.exit_code == 0, r.stderr
    r = invoke("batch", rec, "--method", "n25", "--db", many, "--register", "--station", "T1", "--scheduler", "none",
               "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert (rep["done"], rep["skipped"], rep["failed"], rep["registered"]) == (1, 0, 0, [UNITS[0]])
    with lab.open_database(one) as d1, lab.open_database(many) as d2:
        a, b = lab.current_calibration(d1, UNITS[0]), lab.current_calibration(d2, UNITS[0])
    assert b.id == rep["results"][0]["result_id"]
    assert b.param_text.encode() == a.param_text.encode() == (tmp_path / "p.toml").read_bytes()
    assert (b.options, b.options_hash, b.covariance) == (a.options, a.options_hash, a.covariance)
    assert (b.session.date, b.session.station, b.session.record_sha256) == (a.session.date, "T1", file_hash(rec))
    # the same canonical options: calibrate finds the batch's result, a second batch skips it
    r = invoke("calibrate", rec, "--method", "n25", "--out", tmp_path / "q.toml", "--serial", UNITS[0], "--db", many)
    one_line(r, "recorded already", f"result {b.id}")
    r = invoke("batch", rec, "--method", "n25", "--db", many, "--scheduler", "none", "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["skipped"] == 1


def test_units_dates_and_one_line_per_failed_record(records, tmp_path):
    folder = tmp_path / "in"
    folder.mkdir()
    good = records / f"{UNITS[1]}_{DATES[1]}.h5"
    (folder / good.name).symlink_to(good)
    (folder / "NEW-1_20250301.h5").symlink_to(records / f"{UNITS[2]}_{DATES[0]}.h5")  # an unknown unit
    (folder / "ZZ-9_2025-03-01.h5").write_bytes(b"not a record")
    (folder / "run7.h5").symlink_to(records / f"{UNITS[0]}_{DATES[1]}.h5")  # no serial anywhere
    tagged = folder / "bench-run.h5"  # no serial in the name, but in the record
    tagged.write_bytes((records / f"{UNITS[0]}_{DATES[0]}.h5").read_bytes())
    with h5py.File(tagged, "a") as h5:
        h5.attrs["imu_serial"] = UNITS[0]
    liar = folder / f"{UNITS[1]}_2025-03-02.h5"  # the name says one unit, the record another
    liar.write_bytes(tagged.read_bytes())
    db = tmp_path / "c.sqlite"
    for u in (UNITS[0], UNITS[1], "ZZ-9"):
        assert invoke("db", "add", u, "--db", db).exit_code == 0
    r = invoke("batch", folder, "--method", "n25", "--db", db, "--scheduler", "none", "--json", "--operator", "ana")
    assert r.exit_code == 1, r.stderr
    rep = json.loads(r.stdout)
    assert (rep["records"], rep["done"], rep["failed"]) == (6, 2, 4)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 4 and all(ln.startswith("inscal: failed: ") for ln in lines), lines
    why = {Path(f["path"]).name: f["error"] for f in rep["failures"]}
    assert "unknown unit 'NEW-1'" in why["NEW-1_20250301.h5"] and "--register" in why["NEW-1_20250301.h5"]
    assert "HDF5" in why["ZZ-9_2025-03-01.h5"]
    assert "no serial" in why["run7.h5"]
    assert f"imu_serial attribute is '{UNITS[0]}', not '{UNITS[1]}'" in why[liar.name]
    for name, err in why.items():
        assert f"inscal: failed: {folder / name}: {err}" in lines
    with lab.open_database(db) as d:
        c = lab.calibrations(d, UNITS[1])
        assert [x.session.date for x in c] == [dt.datetime(2025, 2, 15)] and c[0].session.operator == "ana"
        c = lab.calibrations(d, UNITS[0])  # from the attribute; the date: when the file was written
        written = lab.parse_date(record_attrs(tagged, ("created",))["created"])
        assert len(c) == 1 and c[0].session.record_path == str(tagged) and c[0].session.date == written
        assert lab.get_unit(d, "NEW-1") is None and lab.calibrations(d, "ZZ-9") == []
    # --register: the new unit registered with its first result
    r = invoke("batch", folder, "--method", "n25", "--db", db, "--scheduler", "none", "--json", "--register",
               "--model", "FOG-IMU")
    rep = json.loads(r.stdout)
    assert r.exit_code == 1 and (rep["done"], rep["skipped"], rep["failed"], rep["registered"]) == (1, 2, 3, ["NEW-1"])
    with lab.open_database(db) as d:
        assert lab.get_unit(d, "NEW-1").model == "FOG-IMU"
        assert [x.session.date for x in lab.calibrations(d, "NEW-1")] == [dt.datetime(2025, 3, 1)]


def test_a_manifest_and_serial(records, tmp_path):
    db = tmp_path / "m.sqlite"
    man = tmp_path / "runs.csv"
    man.write_text("path,serial,date,station,operator,temperature_c\n"
                   f"{records / (UNITS[0] + '_' + DATES[0] + '.h5')},SN-A,2024-12-01,T3,bo,22.5\n"
                   f"{os.path.relpath(records / (UNITS[1] + '_' + DATES[0] + '.h5'), tmp_path)},SN-B,,,,\n"
                   "missing.h5,SN-C,,,,\n", encoding="utf-8")
    r = invoke("batch", "--manifest", man, "--method", "n25", "--db", db, "--register", "--scheduler", "none",
               "--station", "T9", "--json")
    rep = json.loads(r.stdout)
    assert r.exit_code == 1 and (rep["done"], rep["failed"]) == (2, 1), r.stderr
    assert rep["failures"] == [{"path": "missing.h5", "serial": "SN-C", "error": "no such file"}]
    with lab.open_database(db) as d:
        a, b = lab.current_calibration(d, "SN-A"), lab.current_calibration(d, "SN-B")
    assert (a.session.date, a.session.station, a.session.operator, a.session.temperature_c) == (
        dt.datetime(2024, 12, 1), "T3", "bo", 22.5)
    assert (b.session.station, b.session.operator, b.session.temperature_c) == ("T9", None, None)
    # --serial: every record of one unit; the dates still from the names
    r = invoke("batch", str(records / f"{UNITS[2]}_*.h5"), "--method", "n25", "--db", db, "--serial", "SN-D",
               "--register", "--scheduler", "none", "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["done"] == 2, r.stderr
    with lab.open_database(db) as d:
        assert [c.session.date.month for c in lab.calibrations(d, "SN-D")] == [1, 2]


def test_bad_invocations_are_one_line_and_write_nothing(records, tmp_path):
    db = tmp_path / "none.sqlite"
    rec = records / f"{UNITS[0]}_{DATES[0]}.h5"
    one_line(invoke("batch", rec, "--method", "n25", "--db", db), "no calibration database")
    one_line(invoke("batch", tmp_path / "nothing-*.h5", "--method", "n25", "--db", db, "--register"), "matches no file")
    one_line(invoke("batch", tmp_path / "absent", "--method", "n25", "--db", db, "--register"), "no such file or folder")
    one_line(invoke("batch", "--method", "n25", "--db", db), "--manifest")
    one_line(invoke("batch", rec, "--method", "n26", "--db", db, "--register"), "unknown method 'n26'")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--model", "X"), "give --register")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--scheduler", "none", "--workers", "2"),
             "--workers applies to the default local cluster")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--scheduler", "my-cluster"),
             "not a Dask scheduler address")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--names", "{date}.h5"),
             "{serial} once")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--names", "{serial}_{run}.h5"),
             "only {serial}, {date} and *")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--states", "51"),
             "apply to the systematic methods")
    one_line(invoke("batch", rec, "--method", "n25", "--db", db, "--register", "--gravity", "lunar"), "--gravity")
    man = tmp_path / "bad.csv"
    man.write_text("path,unit\nx.h5,A\n", encoding="utf-8")
    one_line(invoke("batch", "--manifest", man, "--method", "n25", "--db", db, "--register"), "path, serial")
    man.write_text("path,serial,date\nx.h5,A,yesterday\n", encoding="utf-8")
    one_line(invoke("batch", "--manifest", man, "--method", "n25", "--db", db, "--register"), "line 2", "yesterday")
    one_line(invoke("batch", rec, "--manifest", man, "--method", "n25", "--db", db, "--register"), "not both")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_names_and_the_worker_environment():
    rx = lb.name_pattern(lb.DEFAULT_NAMES)
    assert rx.fullmatch("FOG_0003_2025-01-15.h5")["serial"] == "FOG_0003"
    assert rx.fullmatch("FOG-1_20250115T1030Z.h5")["date"] == "20250115T1030Z"
    assert rx.fullmatch("FOG-1.h5") is None and rx.fullmatch("FOG-1_2025-01-15.h5.part") is None
    m = lb.name_pattern("cal-{serial}-*.h5").fullmatch("cal-AB12-run3.h5")
    assert m["serial"] == "AB12" and "date" not in m.groupdict()
    assert lb.LOCAL_WORKER_ENVIRON == LOCAL_WORKER_ENVIRON  # the workers keep glibc's allocator, as the Monte Carlo's


def children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (Linux /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(d.name))
            except (OSError, IndexError, ValueError):
                continue
    return out


def alive(pid: int) -> bool:
    try:
        state = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_killed_halfway_and_run_again_records_each_record_once(records, tmp_path, backend, request):
    url = str(tmp_path / "k.sqlite") if backend == "sqlite" else request.getfixturevalue("pg_url")
    n = len(list(records.glob("*.h5")))
    # SQLite: a local Dask cluster of 2 workers; PostgreSQL: in the process (the same transactions)
    how = ["--workers", "2"] if backend == "sqlite" else ["--scheduler", "none"]
    cmd = [str(Path(sys.executable).parent / "inscal"), "batch", str(records), "--method", "n25", "--db", url, "--register",
           "--no-progress", *how]
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    deadline = time.monotonic() + 120
    done, kids = 0, set()
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            kids |= set(children(proc.pid))
            try:
                with lab.open_database(url) as db:
                    done = lab.table_counts(db)["results"]
            except lab.DatabaseError:  # not created yet
                done = 0
            if done >= n // 2:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the batch ended before it was killed"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()
    assert n // 2 <= done < n
    if backend == "sqlite":  # the workers of the local cluster exit with the batch
        assert len(kids) >= 2
        t = time.monotonic()
        while any(alive(k) for k in kids) and time.monotonic() - t < 15:
            time.sleep(0.1)
        assert not any(alive(k) for k in kids)
    before = results_by_record(url)
    assert all(v == 1 for v in before.values()) and len(before) >= n // 2
    # run again, the same command in this process (--scheduler none: the skip is the driver's, whatever runs the
    # calibrations; what the kill left is the killed process's, not this one's; the benchmark runs the same command
    # again on a local cluster for both back-ends, bench/bench_batch.py)
    r = invoke(*cmd[1:-len(how)], "--scheduler", "none", "--json")
    assert r.exit_code == 0, r.stderr[-2000:]
    rep = json.loads(r.stdout)
    assert (rep["records"], rep["failed"]) == (n, 0) and rep["skipped"] >= len(before)
    assert rep["done"] + rep["skipped"] == n
    after = results_by_record(url)
    assert set(after) == expected(records) and all(v == 1 for v in after.values()), after
