"""Fault injection of the calibration database's write path: SIGTERM and SIGKILL at seeded points of
``inscal calibrate --serial`` (around the staging of the result, its commit and the publication of the
parameter file) and of ``inscal batch --scheduler none`` (records being calibrated and committed), then
the check that the database and the files agree and that nothing is recorded twice.

Calibrate: each point is a fresh folder (a short N25 record at 10 Hz, a database with the unit); the signal
comes a seeded share (0 .. 1.5) of the measured window after the parameter file's temporary appears (the
window: from the temporary to the file published, unhindered).  Afterwards: the file published <=> its
result committed with the file's exact bytes ("both" / "neither"); the one state SIGKILL may leave besides
is "row" (committed in the microseconds before the rename: the publication journal holds the file owed);
never a file without its result, never two results.  Then one later command (a rerun of the calibration,
``db recover`` or ``db add`` of another unit, in turn): both or neither, nothing owed in the journal, the
record byte for byte as it was.

Then the signal sent by each step of the publication itself (the fault hooks of ``tests/cli/forkserver.py``):
as the journal is written before the commit, after the commit before the first rename (the window that
random times hardly hit), after the renames before the journal is cleared.

Batch: 3 records; the signal at a seeded time within the batch's measured duration; afterwards at most one
result per record, and a rerun of the same batch completes every record exactly once.

    python bench/bench_db_faults.py [--points 50] [--batch-points 10] [--step-points 5] [--seed 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import os
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "cli"))
from forkserver import FAULT_HOOKS, ForkServer  # noqa: E402

from inscal import lab  # noqa: E402
from inscal.core.turntable import n25_twelve  # noqa: E402
from inscal.sim.scenarios import build  # noqa: E402
from inscal.sim.simulate import write_simulation  # noqa: E402


def sha(path: Path) -> str:
    return "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()


def results(db: Path, serial: str = "U1") -> list:
    with lab.open_database(db, readonly=True) as d:
        return lab.calibrations(d, serial, superseded=True)


def calibrate_state(f: Path) -> str:
    """``both``, ``neither``, ``row`` (committed, its file owed to the journal), or a defect in capitals."""
    cals = results(f / "lab.sqlite")
    if len(cals) > 1:
        return "DUPLICATE"
    out = f / "p.toml"
    if out.exists():
        return "both" if cals and cals[0].param_file_sha256 == sha(out) else "FILE-WITHOUT-RESULT"
    return "row" if cals else "neither"


def settled(f: Path, record: str) -> str:
    """After one later command: both or neither, nothing owed, the record unchanged (else a defect in capitals)."""
    state = calibrate_state(f)
    with lab.open_database(f / "lab.sqlite", readonly=True) as d:
        owed = lab.pending_publications(d)
    if owed:
        return f"{state.upper()}-{owed}-OWED"
    if sha(f / "U1_2025-01-11.h5") != record:
        return "INPUT-CHANGED"
    return state if state in ("both", "neither") else state.upper()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=50, help="points per signal for calibrate")
    ap.add_argument("--batch-points", type=int, default=10, help="points per signal for batch")
    ap.add_argument("--step-points", type=int, default=5, help="runs per step and signal of the publication (journal "
                    "written before the commit, committed before the rename, renamed before the journal is cleared)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    base = Path(tempfile.mkdtemp(prefix="inscal-dbfaults-"))
    try:
        sc = dataclasses.replace(build("n25"), rate_hz=10.0, path=n25_twelve(dwell_s=25.0, rate_dps=20.0,
                                                                             rate_test_dps=20.0, rate_test_turns=1,
                                                                             accel_dps2=20.0))
        for k in range(3):
            write_simulation(base / f"U{k + 1}_2025-01-1{k + 1}.h5", sc, np.random.default_rng(k))
        rec = base / "U1_2025-01-11.h5"
        with lab.open_database(base / "template.sqlite", create=True) as db:
            for k in range(3):
                lab.add_unit(db, f"U{k + 1}")
        warm = ("from pathlib import Path\nfrom inscal.runs.calibration import CalibrationSetup, calibrate_record, "
                f"load_record\np = Path({str(rec)!r})\ncalibrate_record(load_record(p), p, CalibrationSetup('n25'))")
        with ForkServer(warm=warm + FAULT_HOOKS) as fs:
            def folder(name: str) -> Path:
                f = base / name
                f.mkdir()
                for r in base.glob("U*.h5"):
                    shutil.copy(r, f / r.name)
                shutil.copy(base / "template.sqlite", f / "lab.sqlite")
                return f

            cal = ["calibrate", rec.name, "--method", "n25", "--out", "p.toml", "--serial", "U1", "--db", "lab.sqlite"]

            def start(f: Path, fault: str = ""):
                proc = fs.start(cal, f, base / "logs", env={"INSCAL_TEST_FAULT": fault})
                while proc.poll() is None and not any(n.endswith(".part") for n in os.listdir(f)):
                    time.sleep(0.0005)
                return proc, time.monotonic()

            windows = []
            for k in range(3):
                f = folder(f"free{k}")
                proc, t0 = start(f)
                while proc.poll() is None and not (f / "p.toml").exists():
                    time.sleep(0.0005)
                windows.append(time.monotonic() - t0)
                proc.wait()
            window = float(np.median(windows))
            print(f"calibrate: window from the temporary to the file published {window * 1e3:.3g} ms (median of 3)")
            record = sha(rec)
            later = [cal, ["db", "recover", "--db", "lab.sqlite"], ["db", "add", "U9", "--model", "M", "--db", "lab.sqlite"]]
            for sig in (signal.SIGTERM, signal.SIGKILL):
                seen: Counter = Counter()
                after: Counter = Counter()
                codes: Counter = Counter()
                for k in range(args.points):
                    f = folder(f"c{sig}-{k}")
                    delay = float(rng.uniform(0.0, 1.5)) * window
                    proc, t0 = start(f)
                    time.sleep(max(0.0, delay - (time.monotonic() - t0)))
                    proc.send_signal(sig)
                    codes[proc.wait(60)] += 1
                    state = calibrate_state(f)
                    seen[state] += 1
                    fs.run(later[k % len(later)], f, base / "logs")
                    after[f"{state}->{settled(f, record)}"] += 1
                    shutil.rmtree(f)
                print(f"calibrate, {signal.Signals(sig).name} at {args.points} seeded points: right after {dict(seen)}; "
                      f"after one later command (calibrate again, db recover or db add) {dict(after)}; exit codes "
                      f"{dict(codes)}")
            for sig in (signal.SIGTERM, signal.SIGKILL):  # at each step of the publication, sent by the step itself
                table = []
                for step in ("journal", "rename", "clear"):
                    seen, after = Counter(), Counter()
                    for k in range(args.step_points):
                        f = folder(f"s{sig}-{step}-{k}")
                        proc, _ = start(f, f"{step}:{int(sig)}")
                        proc.wait(60)
                        state = calibrate_state(f)
                        seen[state] += 1
                        fs.run(later[k % len(later)], f, base / "logs")
                        after[f"{state}->{settled(f, record)}"] += 1
                        shutil.rmtree(f)
                    table.append(f"{step}: right after {dict(seen)}, after one later command {dict(after)}")
                print(f"calibrate, {signal.Signals(sig).name} at each step x {args.step_points}: " + "; ".join(table))
            batch = ["batch", ".", "--method", "n25", "--db", "lab.sqlite", "--scheduler", "none", "--no-progress"]
            f = folder("batch-free")
            t0 = time.monotonic()
            fs.run(batch, f, base / "logs")
            span = time.monotonic() - t0
            print(f"batch of 3 records: {span:.3g} s unhindered")
            for sig in (signal.SIGTERM, signal.SIGKILL):
                bad, partial = 0, Counter()
                for k in range(args.batch_points):
                    f = folder(f"b{sig}-{k}")
                    proc = fs.start(batch, f, base / "logs")
                    time.sleep(float(rng.uniform(0.0, 1.1)) * span)
                    proc.send_signal(sig)
                    proc.wait(60)
                    per = [len(results(f / "lab.sqlite", f"U{u}")) for u in (1, 2, 3)]
                    partial[sum(per)] += 1
                    rc = fs.run(batch, f, base / "logs")["rc"]
                    after = [len(results(f / "lab.sqlite", f"U{u}")) for u in (1, 2, 3)]
                    bad += max(per) > 1 or rc != 0 or after != [1, 1, 1]
                    shutil.rmtree(f)
                print(f"batch, {signal.Signals(sig).name} at {args.batch_points} seeded points: results recorded when "
                      f"cut {dict(sorted(partial.items()))}; after a rerun every record once: "
                      f"{args.batch_points - bad}/{args.batch_points}")
    finally:
        shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
