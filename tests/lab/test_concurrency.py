"""Concurrent writers and crashes, on an SQLite file and on a real PostgreSQL server: 4 processes
recording calibrations at once (racing for the same unit and sessions) lose nothing; a writer
killed (SIGKILL) inside its transaction leaves no half result and the database takes the next write."""

from __future__ import annotations

import datetime as dt
import multiprocessing
import os
import signal
import sys
import time

import pytest

from inscal import lab

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

WRITERS = 4
PER_WRITER = 25
RECORDS = 5  # the writers share these records (sessions), so they race for the same session rows
VALUES = {"gyro_scale_factor": [50.0, -30.0, 20.0], "accel_bias": [100.0, -80.0, 40.0]}
SIGMA = {"gyro_scale_factor": [1.0, 1.1, 1.2], "accel_bias": [0.5, 0.6, 0.7]}
#: fork where there is one: the children start in milliseconds instead of importing inscal again (each
#: opens its own database connections; the parent holds none when it forks)
START = "fork" if sys.platform.startswith("linux") else "spawn"


def session(k: int) -> lab.SessionInfo:
    return lab.SessionInfo(record_sha256=f"sha256:{k:064x}", date=dt.datetime(2025, 1, 1) + dt.timedelta(days=k))


def writer(url: str, wid: int, text: str, barrier, out) -> None:
    """One process: register the shared unit (a race too), then record PER_WRITER calibrations."""
    try:
        db = lab.open_database(url)
        lab.add_unit(db, "SHARED", model="FOG")
        barrier.wait(timeout=60)
        ids = []
        for i in range(PER_WRITER):
            ids.append(lab.record_calibration(db, "SHARED", text, session(i % RECORDS),
                                              options={"method": "manual", "writer": wid, "i": i}, make_current=True))
        db.close()
        out.put((wid, ids, None))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        out.put((wid, [], f"{type(exc).__name__}: {exc}"))


def test_four_writers_lose_nothing(db_url, synthetic_text):
    text = synthetic_text(VALUES, SIGMA)
    lab.init_database(db_url)[0].close()
    ctx = multiprocessing.get_context(START)
    barrier, out = ctx.Barrier(WRITERS), ctx.Queue()
    procs = [ctx.Process(target=writer, args=(db_url, w, text, barrier, out)) for w in range(WRITERS)]
    t0 = time.perf_counter()
    for p in procs:
        p.start()
    got = [out.get(timeout=240) for _ in procs]
    for p in procs:
        p.join(timeout=60)
    elapsed = time.perf_counter() - t0
    assert all(err is None for _, _, err in got), got
    ids = sorted(i for _, w_ids, _ in got for i in w_ids)
    total = WRITERS * PER_WRITER
    assert len(ids) == len(set(ids)) == total
    with lab.open_database(db_url) as db:
        assert lab.table_counts(db) == {"units": 1, "sessions": RECORDS, "results": total, "parameters": total * 6,
                                        "current": total, "result_keys": total,
                                        "publications": 0, "stations": 0, "budgets": 0}
        cals = lab.calibrations(db, "SHARED")
        assert sorted(c.id for c in cals) == ids
        seen = {(c.options["writer"], c.options["i"]) for c in cals}
        assert seen == {(w, i) for w in range(WRITERS) for i in range(PER_WRITER)}
        assert all(c.param_text == text and len(c.parameters) == 2 for c in cals)
    print(f"{db_url.split(':')[0]}: {WRITERS} processes x {PER_WRITER} results, all {total} kept, {elapsed:.1f} s")


def killed_writer(url: str, text: str) -> None:
    """Record a calibration, killed by SIGKILL after its parameter rows are written, before the commit."""
    from inscal.lab import store

    original = store.write_parameters

    def die(conn, rid, rows):
        original(conn, rid, rows)
        os.kill(os.getpid(), signal.SIGKILL)

    store.write_parameters = die
    db = lab.open_database(url)
    lab.record_calibration(db, "U1", text, session(7))


def test_a_writer_killed_in_its_transaction_leaves_nothing(db_url, synthetic_text):
    text = synthetic_text(VALUES, SIGMA)
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        first = lab.record_calibration(db, "U1", text, session(1))
        before = lab.table_counts(db)
    p = multiprocessing.get_context(START).Process(target=killed_writer, args=(db_url, text))
    p.start()
    p.join(timeout=120)
    assert p.exitcode == -signal.SIGKILL
    with lab.open_database(db_url) as db:
        assert lab.table_counts(db) == before
        assert [c.id for c in lab.calibrations(db, "U1")] == [first]
        rid = lab.record_calibration(db, "U1", text, session(7))  # the lock died with the writer
        assert lab.get_calibration(db, rid).session.record_sha256 == session(7).record_sha256
        if db.dialect == "sqlite":
            with db.engine.connect() as conn:
                assert conn.exec_driver_sql("PRAGMA integrity_check").scalar() == "ok"
