"""Benchmark: ``inscal batch`` of 100 simulated units x 3 calibrations (300 short records) into SQLite
and into PostgreSQL on a local Dask cluster of 2 workers.  Target: < 5 min each on 2 cores.

The records: the ``n25`` scenario on its twelve positions with 25-s dwells, 20 deg/s moves and one
turn of each rate test (800 s at 100 Hz, 80,000 samples, 9.5 MB: what the warm-up calibrates, and what
the ``n25`` method calibrates well), named ``U000_2025-01-15.h5`` (unit and date, the batch's default
``--names``).  Each unit has its own errors, drawn around the N25 ones (every component with a
standard deviation of half its N25 size, the mount attitude within 0.05/0.05/1 deg); every fifth unit's
x gyro scale factor drifts by +15 ppm per month between its monthly calibrations (15 Jan, 15 Feb,
15 Mar).  Every draw (errors, noise) comes from ``numpy.random.default_rng(SeedSequence(seed))``
children, so the records are the same on every run.

Each back-end gets a fresh database; the batch runs as the command line does, in a subprocess
(``inscal batch DIR --method n25 --db URL --register --workers 2 --json``), and its wall time includes
the start of the cluster.  PostgreSQL: ``--pg URL`` of an empty database, else a server started for the
run in a temporary folder (``initdb`` / ``pg_ctl`` from PATH or /usr/lib/postgresql/*/bin; as root as
the ``postgres`` user), stopped afterwards.  After each batch ``inscal db list --flagged`` says how many
of the drifting and of the stable units are flagged.  Then (unless ``--no-kill``) the batch runs again
into a second fresh database, is killed with SIGKILL once half the records are in it, and is run once
more: every record must then be in the database exactly once.

    python bench/bench_batch.py [--units 100] [--calibrations 3] [--workers 2] [--seed 2025] [--backends sqlite,postgresql] [--no-kill]
"""

from __future__ import annotations

import argparse
import dataclasses
import glob
import json
import os
import pwd
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sqlalchemy as sa

from inscal import lab
from inscal.core.error_model import errors_from_field
from inscal.core.turntable import n25_twelve
from inscal.sim.scenarios import N25_ERRORS, build
from inscal.sim.simulate import write_simulation

DRIFT_EVERY = 5  # every fifth unit drifts
DRIFT_PPM_PER_MONTH = 15.0
TARGET_S = 300.0
INSCAL = str(Path(sys.executable).parent / "inscal")


def unit_errors(rng: np.random.Generator) -> dict:
    """The field-unit errors of one unit: each N25 component with a spread of half its size."""
    out = {}
    for name, base in N25_ERRORS.items():
        if name == "mount_attitude":
            v = np.asarray(base["value"]) + rng.normal(0.0, [0.05, 0.05, 1.0])
            out[name] = {"value": v.tolist(), "unit": "deg"}
        else:
            b = np.asarray(base, dtype=float)
            out[name] = (b + rng.normal(0.0, 0.5 * np.abs(b) + 1e-9)).tolist()
    return out


def generate(folder: Path, units: int, calibrations: int, seed: int) -> tuple[int, list[str]]:
    """Write the records; returns (bytes written, serials of the drifting units)."""
    base = dataclasses.replace(build("n25"), path=n25_twelve(dwell_s=25.0, rate_dps=20.0, rate_test_dps=20.0,
                                                             rate_test_turns=1, accel_dps2=20.0))
    seeds = np.random.SeedSequence(seed).spawn(units * (1 + calibrations))
    nbytes, drifting = 0, []
    for u in range(units):
        serial = f"U{u:03d}"
        errs = unit_errors(np.random.default_rng(seeds[u * (1 + calibrations)]))
        drifts = u % DRIFT_EVERY == 0
        if drifts:
            drifting.append(serial)
        for k in range(calibrations):
            e = json.loads(json.dumps(errs))
            if drifts:
                e["gyro_scale_factor"][0] += DRIFT_PPM_PER_MONTH * k  # one month between calibrations
            imu, gim = errors_from_field(e)
            sc = dataclasses.replace(base, imu=imu, gimbal=gim)
            path = folder / f"{serial}_2025-{k + 1:02d}-15.h5"  # monthly
            write_simulation(path, sc, np.random.default_rng(seeds[u * (1 + calibrations) + 1 + k]))
            nbytes += path.stat().st_size
    return nbytes, drifting


def start_postgres(base: Path):
    """A throw-away PostgreSQL server in ``base``: (URL of its empty database, stop())."""
    found = shutil.which("pg_ctl")
    cands = [str(Path(found).resolve().parent)] if found else sorted(
        (str(Path(p).parent) for p in glob.glob("/usr/lib/postgresql/*/bin/pg_ctl")),
        key=lambda p: int(re.search(r"/postgresql/(\d+)", p).group(1)))
    if not cands:
        raise RuntimeError("no PostgreSQL server binaries (pg_ctl): give --pg URL")
    bindir = Path(cands[-1])
    prefix = []
    if os.geteuid() == 0:  # initdb refuses to run as root
        pw = pwd.getpwnam("postgres")
        os.chown(base, pw.pw_uid, pw.pw_gid)
        prefix = [shutil.which("runuser"), "-u", "postgres", "--"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    data, env = base / "data", {**os.environ, "LC_ALL": "C", "LANG": "C"}
    subprocess.run(prefix + [str(bindir / "initdb"), "-D", str(data), "-U", "postgres", "-A", "trust", "--no-sync",
                             "-E", "UTF8"], check=True, capture_output=True, env=env)
    subprocess.run(prefix + [str(bindir / "pg_ctl"), "-D", str(data), "-l", str(base / "log"), "-w", "-o",
                             f"-p {port} -k {base} -c listen_addresses=127.0.0.1", "start"],
                   check=True, capture_output=True, env=env)

    def stop():
        subprocess.run(prefix + [str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate", "-w", "stop"],
                       capture_output=True, env=env, check=False)
        shutil.rmtree(base, ignore_errors=True)

    return f"postgresql://postgres@127.0.0.1:{port}/postgres", stop  # the server's own, empty database


def run_batch(folder: Path, url: str, workers: int) -> tuple[float, dict]:
    t0 = time.perf_counter()
    r = subprocess.run([INSCAL, "batch", str(folder), "--method", "n25", "--db", url, "--register", "--model", "BENCH",
                        "--workers", str(workers), "--json"], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"inscal batch exited {r.returncode}: {r.stderr[-2000:]}")
    return wall, json.loads(r.stdout)


def per_record(url: str) -> dict[tuple[str, str], int]:
    """(serial, record sha256) -> number of results in the database."""
    out: dict[tuple[str, str], int] = {}
    with lab.open_database(url) as db:
        for unit, _, _ in lab.list_units(db):
            for c in lab.calibrations(db, unit.serial, superseded=True):
                key = (unit.serial, c.session.record_sha256)
                out[key] = out.get(key, 0) + 1
    return out


def killed_halfway(folder: Path, url: str, workers: int, n: int) -> str:
    """SIGKILL a batch once half the records are in the database, run it again; what came of it."""
    cmd = [INSCAL, "batch", str(folder), "--method", "n25", "--db", url, "--register", "--workers", str(workers),
           "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    done = 0
    while proc.poll() is None:
        try:
            with lab.open_database(url) as db:
                done = lab.table_counts(db)["results"]
        except lab.DatabaseError:  # not created yet
            done = 0
        if done >= n // 2:
            os.kill(proc.pid, signal.SIGKILL)
            break
        time.sleep(0.2)
    proc.wait()
    before = sum(per_record(url).values())
    wall, rep = run_batch(folder, url, workers)
    counts = per_record(url)
    whole = len(counts) == n and set(counts.values()) == {1}
    return (f"killed (SIGKILL) with {before} of {n} results in the database; run again: {rep['done']} calibrated, "
            f"{rep['skipped']} skipped, {rep['failed']} failed in {wall:.1f} s; {len(counts)} records with "
            f"{sum(counts.values())} results: {'each exactly once' if whole else 'NOT each exactly once'}")


def second_database(url: str) -> str:
    """A new, empty database beside ``url``'s on its PostgreSQL server."""
    eng = sa.create_engine(lab.database_url(url), isolation_level="AUTOCOMMIT")
    with eng.connect() as conn:
        conn.execute(sa.text("CREATE DATABASE bench_killed"))
    eng.dispose()
    return url.rsplit("/", 1)[0] + "/bench_killed"


def flagged(url: str, drifting: list[str]) -> tuple[int, int]:
    r = subprocess.run([INSCAL, "db", "list", "--db", url, "--flagged", "--json"], capture_output=True, text=True,
                       check=True)
    serials = {u["serial"] for u in json.loads(r.stdout)["units"]}
    return len(serials & set(drifting)), len(serials - set(drifting))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--units", type=int, default=100)
    ap.add_argument("--calibrations", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=2025)
    ap.add_argument("--backends", default="sqlite,postgresql")
    ap.add_argument("--pg", default=None, help="URL of an empty PostgreSQL database (default: a server started here)")
    ap.add_argument("--no-kill", action="store_true", help="skip the batch killed halfway and run again")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="inscal-bench-batch-"))
    stop = None
    try:
        folder = tmp / "records"
        folder.mkdir()
        t0 = time.perf_counter()
        nbytes, drifting = generate(folder, args.units, args.calibrations, args.seed)
        n = args.units * args.calibrations
        print(f"generated {n} records ({args.units} units x {args.calibrations}; {len(drifting)} drifting) in "
              f"{time.perf_counter() - t0:.1f} s, {nbytes / 1e6:.0f} MB", flush=True)
        ok = True
        for backend in args.backends.split(","):
            if backend == "sqlite":
                url = str(tmp / "bench.sqlite")
            else:
                if args.pg is None:
                    pg = Path(tempfile.mkdtemp(prefix="inscal-bench-pg-"))  # its own: the server's user enters it
                    url, stop = start_postgres(pg)
                else:
                    url = args.pg
            wall, rep = run_batch(folder, url, args.workers)
            met = wall < TARGET_S and rep["done"] == n and rep["failed"] == 0
            ok &= met
            fd, fs = flagged(url, drifting)
            print(f"batch of {n} records into {backend} in {wall:.1f} s ({rep['workers']} workers; "
                  f"{rep['seconds_per_record']:.3g} s per record in a worker, {wall / n:.3g} s of wall time per record; "
                  f"{rep['done']} calibrated, {rep['failed']} failed): {'met' if met else 'NOT met'} (< {TARGET_S:.0f} s)",
                  flush=True)
            print(f"  flagged: {fd} of {len(drifting)} drifting units, {fs} of {args.units - len(drifting)} stable ones",
                  flush=True)
            if not args.no_kill:
                other = str(tmp / "killed.sqlite") if backend == "sqlite" else second_database(url)
                line = killed_halfway(folder, other, args.workers, n)
                ok &= "NOT" not in line
                print(f"  {line}", flush=True)
        return 0 if ok else 1
    finally:
        if stop is not None:
            stop()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
