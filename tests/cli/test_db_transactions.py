"""``inscal calibrate --serial`` and ``inscal db``: a result and its parameter file are published together or
not at all whatever signal arrives when (fault injection at each step of the publication and at seeded
times, then one later command), an output that is the database or an input is refused before any work, the options are
refused up front for ``calibrate`` as for ``batch``, dates are bounded, and a calibration or parameter
file recorded already is refused.  Every refusal: exit 2, one line, every file byte for byte as it was.

The commands run in a fork server warmed with one calibration of the record (tests/cli/forkserver.py), so
a command costs its own work, not the interpreter's start nor numba's cache."""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import signal
import sqlite3
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from forkserver import FAULT_HOOKS, ForkServer

from inscal import lab
from inscal.core.turntable import n25_twelve
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and fork")

#: seeded signal points of the fault injection (each a calibration of the record)
#: the signal comes at a seeded share, up to this, of the time a run takes from its parameter file's temporary
#: to the file published (measured first: the staging of the result, the commit and the renames lie in it)
SPREAD = 3.0


@pytest.fixture(scope="module")
def lab_dir(tmp_path_factory):
    """A short N25 record at 10 Hz, a database with unit U1 (a template copied per test), and a fork server
    that has calibrated the record once."""
    d = tmp_path_factory.mktemp("dbtx")
    sc = dataclasses.replace(build("n25"), rate_hz=10.0, path=n25_twelve(dwell_s=25.0, rate_dps=20.0,
                                                                         rate_test_dps=20.0, rate_test_turns=1,
                                                                         accel_dps2=20.0))
    write_simulation(d / "r.h5", sc, np.random.default_rng(7))
    with lab.open_database(d / "template.sqlite", create=True) as db:
        lab.add_unit(db, "U1", model="M")
    warm = ("from pathlib import Path\nfrom inscal.runs.calibration import CalibrationSetup, calibrate_record, "
            f"load_record\np = Path({str(d / 'r.h5')!r})\ncalibrate_record(load_record(p), p, CalibrationSetup('n25'))")
    with ForkServer(warm=warm + FAULT_HOOKS) as fs:
        yield d, fs


def fresh(lab_dir, tmp_path, name="lab.sqlite") -> Path:
    """A folder with the record and a copy of the template database (unit U1 registered)."""
    d, _ = lab_dir
    shutil.copy(d / "r.h5", tmp_path / "r.h5")
    shutil.copy(d / "template.sqlite", tmp_path / name)
    return tmp_path


def run(lab_dir, folder: Path, *args):
    _, fs = lab_dir
    logs = folder.parent / f"{folder.name}-logs"
    r = fs.run([str(a) for a in args], folder, logs)
    return r["rc"], (logs / "stdout").read_text(), (logs / "stderr").read_text()


def snapshot(folder: Path) -> dict[str, str]:
    """Every file of ``folder`` (hidden ones too) with the sha256 of its bytes."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()} | {
        p.name + "/": "" for p in folder.iterdir() if p.is_dir()}


def refused(result, *phrases) -> str:
    rc, out, err = result
    assert rc == 2, (rc, out, err)
    err = err.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    for p in phrases:
        assert p in err, (p, err)
    return err


def results(db: Path) -> list:
    with lab.open_database(db, readonly=True) as d:
        return lab.calibrations(d, "U1", superseded=True)


def file_hash(path: Path) -> str:
    return "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()


def test_outputs_that_are_the_database_or_an_input_are_refused_before_any_work(lab_dir, tmp_path):
    f = fresh(lab_dir, tmp_path)
    shutil.copy(f / "lab.sqlite", f / "lab.png")  # a database that a careless name makes look like a plot
    shutil.copy(f / "lab.sqlite", f / "lab.html")
    (f / "link.toml").symlink_to(f / "lab.sqlite")
    (f / "folder").mkdir()
    before = snapshot(f)
    cal = ["calibrate", "r.h5", "--method", "n25", "--serial", "U1", "--force"]
    refused(run(lab_dir, f, *cal, "--out", "lab.sqlite", "--db", "lab.sqlite"), "is the calibration database")
    refused(run(lab_dir, f, *cal, "--out", "link.toml", "--db", "lab.sqlite"), "is the calibration database")
    refused(run(lab_dir, f, *cal, "--out", "lab.sqlite-wal", "--db", "lab.sqlite"), "calibration database file")
    refused(run(lab_dir, f, *cal, "--out", "lab.sqlite", "--db", "sqlite:///" + str(f / "lab.sqlite")),
            "is the calibration database")
    refused(run(lab_dir, f, *cal, "--out", "r.h5", "--db", "lab.sqlite"), "must differ from the input")
    refused(run(lab_dir, f, *cal, "--out", "folder", "--db", "lab.sqlite"), "is a folder")
    refused(run(lab_dir, f, "calibrate", "r.h5", "--method", "n25", "--out", "folder", "--force"), "is a folder")
    refused(run(lab_dir, f, "simulate", "psins19", "--out", "folder", "--force"), "is a folder")
    refused(run(lab_dir, f, *cal, "--out", "x" * 251 + ".toml", "--db", "lab.sqlite"), "255")
    refused(run(lab_dir, f, "db", "history", "U1", "--plot", "lab.png", "--force", "--db", "lab.png"),
            "is the calibration database")
    refused(run(lab_dir, f, "db", "export", "U1", "--out", "lab.sqlite", "--force", "--db", "lab.sqlite"),
            "is the calibration database")
    refused(run(lab_dir, f, "db", "export", "U1", "--out", "folder", "--force", "--db", "lab.sqlite"), "is a folder")
    refused(run(lab_dir, f, "db", "certificate", "U1", "--out", "lab.html", "--no-pdf", "--force", "--db",
                "lab.html"), "is the calibration database")
    refused(run(lab_dir, f, "db", "list", "--db", "d" * 300 + ".sqlite"), "File name too long")
    refused(run(lab_dir, f, "db", "show", "U1", "--result", str(2**63), "--db", "lab.sqlite"), "no calibration result")
    refused(run(lab_dir, f, "batch", "b" * 5000, "--method", "n25", "--db", "lab.sqlite", "--scheduler", "none"),
            "File name too long")
    refused(run(lab_dir, f, "db", "add", "U3", "--model", "M" * 300, "--db", "lab.sqlite"), "at most 200")
    refused(run(lab_dir, f, "calibrate", "r.h5", "--method", "n25", "--out", "p.toml", "--serial", "U1", "--db",
                "lab.sqlite", "--station", "T" * 201), "at most 200")
    assert snapshot(f) == before


def test_options_are_refused_up_front_for_calibrate_and_batch(lab_dir, tmp_path):
    f = fresh(lab_dir, tmp_path)
    before = snapshot(f)
    cases = [
        (["--method", "systematic51", "--states", ""], "empty"),
        (["--method", "systematic51", "--states", ",,,"], "empty"),
        (["--method", "systematic51", "--states", "51,,lever9"], "empty option"),
        (["--method", "systematic51", "--states", "bogus"], "unknown state option 'bogus'"),
        (["--method", "systematic51", "--states", "30,auto"], "not that of --method systematic51"),
        (["--method", "systematic30", "--states", "51"], "not that of --method systematic30"),
        (["--method", "n25", "--settle-s", "-1"], "--settle-s must be"),
        (["--method", "n25", "--settle-s", "10"], "drops 20 s of every window"),
        (["--method", "n25", "--min-static-s", "nan"], "--min-static-s must be"),
        (["--method", "systematic51", "--filter-rate-hz", "1e9"], "--filter-rate-hz must be"),
        (["--method", "unified", "--encoder-sigma", "1e300"], "--encoder-sigma must be"),
        (["--method", "systematic51", "--arw", "1e300"], "--arw must be"),
    ]
    for k, (opts, phrase) in enumerate(cases):
        refused(run(lab_dir, f, "calibrate", "r.h5", "--out", "p.toml", *opts), phrase)
        if k % 3 == 0:  # batch checks them in the same place (CalibrationSetup.problem): a share suffices
            refused(run(lab_dir, f, "batch", "r.h5", "--serial", "U1", "--db", "lab.sqlite", "--scheduler", "none",
                        *opts), phrase)
    # the filter rate above the record's (10 Hz): refused, not run at the record's rate and stored as asked
    refused(run(lab_dir, f, "calibrate", "r.h5", "--out", "p.toml", "--method", "systematic30", "--states", "30",
                "--filter-rate-hz", "50"), "above the rate of r.h5 (10 Hz)")
    refused(run(lab_dir, f, "import", "r.h5", "--format", "psins", "--rate-hz", "100", "--out", "x.h5",
                "--encoder-latency", "1e6"), "--encoder-latency must be")
    assert snapshot(f) == before


def test_dates_and_duplicates(lab_dir, tmp_path):
    f = fresh(lab_dir, tmp_path)
    cal = ["calibrate", "r.h5", "--method", "n25", "--serial", "U1", "--db", "lab.sqlite"]
    before = snapshot(f)
    refused(run(lab_dir, f, *cal, "--out", "p.toml", "--date", "2999-12-31"), "lies in the future")
    refused(run(lab_dir, f, *cal, "--out", "p.toml", "--date", "0001-01-01T00:00:00+01:00"), "not a date between")
    refused(run(lab_dir, f, *cal, "--out", "p.toml", "--date", "1900-01-01"), "before 1950")
    assert snapshot(f) == before
    rc, out, err = run(lab_dir, f, *cal, "--out", "p.toml", "--date", "2025-03-01")
    assert rc == 0, err
    (rid,) = [c.id for c in results(f / "lab.sqlite")]
    before = snapshot(f)
    refused(run(lab_dir, f, *cal, "--out", "q.toml"), "recorded already", f"result {rid}")
    refused(run(lab_dir, f, "db", "add", "U1", "p.toml", "--db", "lab.sqlite"), "recorded already", f"result {rid}")
    # the same record with other options, given another date: a record has one date
    refused(run(lab_dir, f, *cal, "--out", "q.toml", "--min-static-s", "15", "--date", "2025-04-01"),
            "stored already with the date 2025-03-01")
    refused(run(lab_dir, f, "db", "certificate", "U1", "--out", "cert", "--no-pdf", "--issued", "1991-01-01",
                "--db", "lab.sqlite"), "before the calibration it certifies")
    refused(run(lab_dir, f, "db", "certificate", "U1", "--out", "cert", "--no-pdf", "--issued", "2999-01-01",
                "--db", "lab.sqlite"), "in the future")
    assert snapshot(f) == before
    assert [c.id for c in results(f / "lab.sqlite")] == [rid]


def test_impossible_estimates_are_refused_whatever_was_skipped(lab_dir, tmp_path):
    """A record whose x gyro reads with the wrong sign, the encoder check skipped: the fit is -200 % in scale
    factor; refused with the likely cause, nothing written or recorded."""
    import h5py

    f = fresh(lab_dir, tmp_path)
    with h5py.File(f / "r.h5", "r+") as h5:
        h5["dtheta"][:, 0] *= -1.0
    before = snapshot(f)
    refused(run(lab_dir, f, "calibrate", "r.h5", "--method", "n25", "--out", "p.toml", "--skip-encoder-check",
                "--serial", "U1", "--db", "lab.sqlite"),
            "implausible estimates, gyro_scale_factor[0] = -2", "--skip-encoder-check", "flipped sign")
    rc, _, err = run(lab_dir, f, "batch", "r.h5", "--method", "n25", "--skip-encoder-check", "--serial", "U1", "--db",
                     "lab.sqlite", "--scheduler", "none", "--no-progress")
    assert rc == 1 and "implausible estimates, gyro_scale_factor[0] = -2" in err, (rc, err)  # the record failed
    assert snapshot(f) == before and results(f / "lab.sqlite") == []


def _state(folder: Path) -> str:
    """What the database and the parameter file say right after a signal: ``both``, ``neither``, or ``row``
    (committed, its file owed: the journal holds it); never a file without its result, never two results."""
    cals = results(folder / "lab.sqlite")
    assert len(cals) <= 1, [c.id for c in cals]  # never a duplicate
    out = folder / "p.toml"
    if out.exists():  # a file published: its result is committed, byte for byte
        assert len(cals) == 1 and cals[0].param_file_sha256 == file_hash(out)
        return "both"
    return "row" if cals else "neither"


def _agree(folder: Path) -> str:
    """After one later command: the result in both or neither, nothing owed, no temporary of the result left."""
    state = _state(folder)
    assert state in ("both", "neither"), state
    with lab.open_database(folder / "lab.sqlite", readonly=True) as d:
        assert lab.pending_publications(d) == 0
    if state == "both":
        assert not [p.name for p in folder.iterdir() if p.name.startswith(".p.toml.") and p.name.endswith(".part")]
    return state


def test_signals_at_every_step_then_one_command_leave_the_database_and_the_files_agreeing(lab_dir, tmp_path):
    """SIGTERM and SIGKILL at each step of ``calibrate --serial``'s publication (before the commit, between the
    commit and the rename, between the rename and the journal's clearing) and at seeded times after the
    parameter file's temporary appears; a SIGKILL of the recovery itself.  Right after: never a file without
    its result nor two results.  After one later command (``db recover``, a rerun, ``db add`` of another
    unit; ``db list`` only says what is owed and changes nothing): both or neither, nothing owed, the record
    byte for byte as it was.  ``batch`` killed at seeded times, then rerun: the record recorded once."""
    d, fs = lab_dir
    rng = np.random.default_rng(20261127)
    cal = ["calibrate", "r.h5", "--method", "n25", "--out", "p.toml", "--serial", "U1", "--db", "lab.sqlite"]
    record = file_hash(d / "r.h5")
    recover = ["db", "recover", "--db", "lab.sqlite"]
    later = [cal, recover, ["db", "add", "U2", "--model", "M", "--db", "lab.sqlite"]]  # (a rerun: refused or done)

    def start(f: Path, logs: Path, fault: str = ""):
        """The calibration running in ``f`` once its parameter file's temporary is there: (run, when)."""
        proc = fs.start(cal, f, logs, env={"INSCAL_TEST_FAULT": fault})
        t_end = time.monotonic() + 60
        while proc.poll() is None and not any(n.endswith(".part") for n in os.listdir(f)):
            assert time.monotonic() < t_end
            time.sleep(0.0005)
        return proc, time.monotonic()

    def folder(name: str) -> Path:
        (tmp_path / name).mkdir()
        return fresh(lab_dir, tmp_path / name)

    f = folder("free")
    t0 = time.monotonic()
    proc, t_part = start(f, tmp_path / "free-logs")
    while proc.poll() is None and not (f / "p.toml").exists():
        time.sleep(0.0005)
    window = time.monotonic() - t_part  # from the temporary to the file published, unhindered
    assert proc.wait(60) == 0 and _agree(f) == "both"
    span = time.monotonic() - t0  # a whole calibration (that of a batch of the one record, but for its start)
    # (step, signal, the state right after); a step's signal is sent by the step itself
    points = [("journal", signal.SIGTERM, "both"), ("journal", signal.SIGKILL, "neither"),
              ("rename", signal.SIGTERM, "both"), ("rename", signal.SIGKILL, "row"),
              ("clear", signal.SIGTERM, "both"), ("clear", signal.SIGKILL, "both")]
    points += [(float(rng.uniform(0.0, SPREAD)) * window, sig, None) for sig in (signal.SIGTERM, signal.SIGKILL)]
    seen: dict[str, int] = {}
    for k, (at, sig, expect) in enumerate(points):
        f = folder(f"p{k}")
        proc, t_part = start(f, tmp_path / f"p{k}-logs", f"{at}:{int(sig)}" if expect else "")
        if expect is None:
            time.sleep(max(0.0, at - (time.monotonic() - t_part)))
            proc.send_signal(sig)
        rc = proc.wait(60)
        assert rc in (0, 128 + sig, -sig), (rc, proc.communicate())
        state = _state(f)
        assert state == expect or expect is None and (state != "row" or sig == signal.SIGKILL), (at, sig, state)
        if state == "row":
            before = snapshot(f)  # a read-only command says what is owed and changes nothing
            rc, out, err = run(lab_dir, f, "db", "list", "--db", "lab.sqlite")
            assert rc == 0 and "1 file of results recorded" in err and "inscal db recover" in err, err
            assert snapshot(f) == before
            # the recovery itself killed in its rename: the next one completes it
            r = fs.run(recover, f, tmp_path / f"p{k}-rk", env={"INSCAL_TEST_FAULT": f"rename:{int(signal.SIGKILL)}"})
            assert r["rc"] == -signal.SIGKILL and _state(f) == "row", r
        rc, out, err = run(lab_dir, f, *later[k % len(later)])
        assert rc in (0, 2) and "Traceback" not in err, (rc, err)
        if state == "row":
            assert "published from its temporary" in out + err, (out, err)
        after = _agree(f)
        seen[f"{state}->{after}"] = seen.get(f"{state}->{after}", 0) + 1
        assert file_hash(f / "r.h5") == record
    print(f"signal points: {seen} (window {window * 1e3:.3g} ms)")
    # batch: killed at seeded times, then one rerun records the record exactly once
    batch = ["batch", "r.h5", "--method", "n25", "--serial", "U1", "--db", "lab.sqlite", "--scheduler", "none",
             "--no-progress"]
    for k, sig in enumerate((signal.SIGTERM, signal.SIGKILL)):
        f = folder(f"b{k}")
        proc = fs.start(batch, f, tmp_path / f"b{k}-logs")
        time.sleep(float(rng.uniform(0.3, 1.2)) * span)
        proc.send_signal(sig)
        proc.wait(60)
        assert len(results(f / "lab.sqlite")) <= 1
        assert fs.run(batch, f, tmp_path / f"b{k}-logs2")["rc"] == 0
        assert len(results(f / "lab.sqlite")) == 1 and file_hash(f / "r.h5") == record


def test_a_held_lock_is_reported_at_once_with_its_holder(lab_dir, tmp_path):
    """Another program holds the database's write lock: a write is refused after the short grace (not ~150 s),
    naming the holder's pid and --wait; with --wait it waits the time given; nothing is written."""
    f = fresh(lab_dir, tmp_path)
    with lab.open_database(f / "lab.sqlite", readonly=True) as db:
        before = lab.table_counts(db)
    con = sqlite3.connect(f / "lab.sqlite", isolation_level=None)
    try:  # (no file of the database opened by this process meanwhile: a close would drop its POSIX locks)
        con.execute("BEGIN IMMEDIATE")
        t0 = time.monotonic()
        refused(run(lab_dir, f, "db", "add", "U2", "--model", "M", "--db", "lab.sqlite"),
                f"locked by another writer (pid {os.getpid()}: ", "--wait SECONDS")
        refused(run(lab_dir, f, "db", "add", "U2", "--model", "M", "--db", "lab.sqlite", "--wait", "0.5"),
                "waited 0.5 s")
        assert time.monotonic() - t0 < 20
        refused(run(lab_dir, f, "db", "add", "U2", "--model", "M", "--db", "lab.sqlite", "--wait", "-1"), "--wait -1")
        refused(run(lab_dir, f, "calibrate", "r.h5", "--method", "n25", "--out", "p.toml", "--wait", "5"),
                "give --serial")
    finally:
        con.execute("ROLLBACK")
        con.close()
    with lab.open_database(f / "lab.sqlite", readonly=True) as db:
        assert lab.table_counts(db) == before


def test_a_read_only_database_is_read_and_a_write_refused_saying_so(lab_dir, tmp_path):
    """``db list/show/export/history`` open the database read-only: a foreign SQLite file is refused without
    its journal mode switched; an immutable copy is read."""
    f = fresh(lab_dir, tmp_path)
    with sqlite3.connect(f / "other.sqlite") as con:
        con.execute("CREATE TABLE t (x)")
    con.close()
    (f / "empty.sqlite").write_bytes(b"")
    before = snapshot(f)
    for db in ("other.sqlite", "empty.sqlite"):
        refused(run(lab_dir, f, "db", "list", "--db", db))
        refused(run(lab_dir, f, "db", "init", "--db", db) if db == "other.sqlite" else run(lab_dir, f, "db", "list",
                                                                                          "--db", db))
    rc, out, err = run(lab_dir, f, "db", "list", "--db", "lab.sqlite")
    assert rc == 0 and "U1" in out, err
    assert snapshot(f) == before
