"""The calibration database never duplicates a result, never writes when it only reads, and says at
once who holds it: the unique keys (schema v3) under 8 concurrent writer processes on SQLite and
PostgreSQL, a legacy duplicate kept but keyed once by the upgrade, read-only opening (no WAL switch
on a foreign or empty file, a read-only folder), a lock held by another writer named, and dates bounded."""

from __future__ import annotations

import datetime as dt
import multiprocessing as mp
import os
import sqlite3
import sys

import pytest
import sqlalchemy as sa
from lab_synthetic import synthetic_result

from inscal import lab
from inscal.lab import DatabaseError
from inscal.lab.record import param_file_text

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX processes and locks")

VALUES = {"accel_bias": [100.0, -50.0, 20.0]}
SIGMA = {"accel_bias": [0.5, 0.6, 0.7]}


def text_for(record: int, value: float = 100.0) -> str:
    """A parameter file of record number ``record`` (its hash in the file, as calibrate writes it)."""
    res = synthetic_result({"accel_bias": [value, -50.0, 20.0]}, SIGMA)
    return param_file_text(res, "run.h5", record_hash(record), {"imu_serial": "synthetic"})


def record_hash(record: int) -> str:
    return "sha256:" + f"{record:02d}" * 32


def session(record: int) -> lab.SessionInfo:
    return lab.SessionInfo(record_sha256=record_hash(record), date=dt.datetime(2025, 1, 1 + record))


def _writer(url: str, record: int, start, out) -> None:
    """One process: waits for the start, then records the calibration of ``record`` (no look-up first)."""
    start.wait(30)
    try:
        with lab.open_database(url, wait_s=60) as db:
            rid = lab.record_calibration(db, "U1", text_for(record), session(record),
                                         options={"method": "manual", "k": record})
        out.put(("done", record, rid))
    except lab.AlreadyRecorded as exc:
        out.put(("already", record, exc.result_id))
    except BaseException as exc:  # noqa: BLE001 - reported to the test
        out.put(("error", record, f"{type(exc).__name__}: {exc}"))


def test_eight_processes_record_each_calibration_once(db_url):
    """8 processes at once: 4 on record 1 (the same calibration), 4 on records 2..5: exactly one result per
    (record, options), nothing lost, the others told which result holds it."""
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
    ctx = mp.get_context("fork")
    start, out = ctx.Event(), ctx.Queue()
    records = [1, 1, 1, 1, 2, 3, 4, 5]
    procs = [ctx.Process(target=_writer, args=(db_url, r, start, out)) for r in records]
    for p in procs:
        p.start()
    start.set()
    got = [out.get(timeout=120) for _ in procs]
    for p in procs:
        p.join(60)
    assert not [g for g in got if g[0] == "error"], got
    done = {g[1]: g[2] for g in got if g[0] == "done"}
    assert sorted(done) == [1, 2, 3, 4, 5]
    assert all(g[2] == done[1] for g in got if g[0] == "already") and sum(g[0] == "already" for g in got) == 3
    with lab.open_database(db_url, readonly=True) as db:
        counts = lab.table_counts(db)
        cals = lab.calibrations(db, "U1", superseded=True)
    assert counts["results"] == 5 and counts["result_keys"] == 5 and counts["parameters"] == 5 * 3
    assert sorted(c.session.record_sha256 for c in cals) == [record_hash(r) for r in (1, 2, 3, 4, 5)]


def test_the_same_parameter_file_is_refused_and_superseding_is_keyed_once(db_url):
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        text = text_for(1)  # one text: a file made again carries another creation time (another hash)
        first = lab.record_calibration(db, "U1", text, session(1), options={"method": "manual"})
        before = lab.table_counts(db)
        with pytest.raises(lab.AlreadyRecorded, match=f"as result {first}") as info:
            lab.record_calibration(db, "U1", text_for(1), session(1), options={"method": "manual"})
        # the same file under other options (db add after calibrate): refused in the transaction when asked
        with pytest.raises(lab.AlreadyRecorded, match=f"parameter file is recorded already for U1, as result {first}"):
            lab.record_calibration(db, "U1", text, session(1), options={"method": "manual", "from": "file"},
                                   new_file=True)
        assert info.value.result_id == first and lab.table_counts(db) == before
        again = lab.record_calibration(db, "U1", text_for(1, 101.0), session(1), options={"method": "manual"},
                                       supersedes=first)
        with pytest.raises(lab.AlreadyRecorded, match="also superseding"):  # superseded twice: refused
            lab.record_calibration(db, "U1", text_for(1, 102.0), session(1), options={"method": "manual"},
                                   supersedes=first)
        assert lab.current_calibration(db, "U1").id == again
        for bad in (2**63, -1, 0):
            with pytest.raises(DatabaseError, match="no such result"):
                lab.record_calibration(db, "U1", text_for(2), session(2), supersedes=bad)
            with pytest.raises(DatabaseError, match="no calibration result"):
                lab.get_calibration(db, bad)


def test_a_legacy_duplicate_is_kept_and_keyed_once(tmp_path):
    """A v2 database holding the same calibration twice (an older inscal let two writers race) upgrades:
    both rows stay (append-only), the first holds the key, and no third copy can be added."""
    url = str(tmp_path / "old.sqlite")
    db, _ = lab.init_database(url, revision="0002_session_temperature")
    with db:
        lab.add_unit(db, "U1")
        t = lab.schema.results
        with db.engine.begin() as conn:  # what the v2 writer did: no key to stop the second copy
            for _ in range(2):
                conn.execute(sa.text("INSERT INTO sessions (unit_id, record_sha256, date, recorded_at) "
                                     "SELECT 1, :h, '2025-01-02', '2025-01-02' WHERE NOT EXISTS "
                                     "(SELECT 1 FROM sessions WHERE record_sha256 = :h)"), {"h": record_hash(1)})
                conn.execute(sa.insert(t).values(unit_id=1, session_id=1, method="manual", options={"method": "manual"},
                                                 options_hash=lab.options_hash({"method": "manual"}),
                                                 inscal_version="old", param_file=text_for(1),
                                                 param_file_sha256=lab.text_hash(text_for(1)),
                                                 recorded_at=dt.datetime(2025, 1, 3)))
    assert lab.upgrade_database(url)[1] == lab.head_revision()
    with lab.open_database(url) as db:
        with db.engine.connect() as conn:
            assert conn.execute(sa.text("SELECT result_id FROM result_keys")).scalars().all() == [1]
        assert lab.table_counts(db)["results"] == 2
        with pytest.raises(lab.AlreadyRecorded, match="as result 1"):
            lab.record_calibration(db, "U1", text_for(1), session(1), options={"method": "manual"})


def _file_state(path) -> tuple[bytes, list[str]]:
    return path.read_bytes(), sorted(p.name for p in path.parent.iterdir())


@pytest.mark.parametrize("kind", ["empty", "foreign"])
def test_a_refused_file_is_not_touched(tmp_path, kind):
    """An empty file or another application's SQLite database (rollback journal): every command refuses
    it in one line, and the file stays byte for byte (no switch to WAL, no -wal or -shm left)."""
    path = tmp_path / "other.sqlite"
    if kind == "empty":
        path.write_bytes(b"")
    else:
        with sqlite3.connect(path) as con:
            con.execute("CREATE TABLE notes (id INTEGER PRIMARY KEY, text TEXT)")
            con.execute("INSERT INTO notes (text) VALUES ('hello')")
        con.close()
    before = _file_state(path)
    for call in (lambda: lab.open_database(path, readonly=True), lambda: lab.open_database(path),
                 lambda: lab.upgrade_database(path)) + ((lambda: lab.init_database(path),) if kind == "foreign" else ()):
        with pytest.raises(DatabaseError, match="no calibration tables|not an inscal calibration database"):
            call()
        assert _file_state(path) == before


def test_read_only_opening_never_writes(tmp_path, monkeypatch):
    """A database read through ``readonly=True`` stays byte for byte (its journal mode included) and refuses a
    write saying read-only; a database whose file or folder cannot be written can still be read, and a
    write to it is refused before anything happens, saying read-only."""
    from inscal.lab import database

    path = tmp_path / "c.sqlite"
    with lab.open_database(path, create=True) as db:
        lab.add_unit(db, "U1")
        lab.record_calibration(db, "U1", text_for(1), session(1))
    before = _file_state(path)
    with lab.open_database(path, readonly=True) as db:
        assert [u.serial for u, _, _ in lab.list_units(db)] == ["U1"]
        with pytest.raises(DatabaseError, match="read-only"):
            lab.add_unit(db, "U2")
    assert _file_state(path) == before
    # the folder and the file not writable (faked: the tests may run as root, whom permissions do not stop)
    real = os.access
    monkeypatch.setattr(database.os, "access", lambda p, mode, **kw: False if mode & os.W_OK else real(p, mode, **kw))
    with lab.open_database(path, readonly=True) as db:
        assert lab.current_calibration(db, "U1").session.record_sha256 == record_hash(1)
    with pytest.raises(DatabaseError, match="read-only"):
        lab.open_database(path)
    assert lab.upgrade_database(path) == (lab.head_revision(),) * 2  # at the newest already: nothing to write
    assert _file_state(path) == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes a read-only folder")
def test_a_database_in_a_read_only_folder_is_read(tmp_path):
    folder = tmp_path / "archive"
    folder.mkdir()
    path = folder / "c.sqlite"
    with lab.open_database(path, create=True) as db:
        lab.add_unit(db, "U1")
    before = _file_state(path)
    folder.chmod(0o555)
    try:
        with lab.open_database(path, readonly=True) as db:
            assert lab.get_unit(db, "U1") is not None
        with pytest.raises(DatabaseError, match="read-only"):
            lab.open_database(path)
        assert _file_state(path) == before
    finally:
        folder.chmod(0o755)


def test_a_lock_held_by_another_writer_is_named_at_once(tmp_path):
    """Another process holds the write lock: a write is refused after the short grace, naming that process
    and --wait; nothing is written."""
    path = tmp_path / "c.sqlite"
    with lab.open_database(path, create=True) as db:
        lab.add_unit(db, "U1")
    ctx = mp.get_context("fork")
    held, release = ctx.Event(), ctx.Event()

    def holder():
        con = sqlite3.connect(path, isolation_level=None)
        con.execute("BEGIN IMMEDIATE")
        held.set()
        release.wait(30)
        con.execute("ROLLBACK")
        con.close()

    p = ctx.Process(target=holder)
    p.start()
    try:
        assert held.wait(30)
        with lab.open_database(path, wait_s=0.2) as db:
            counts = lab.table_counts(db)
            with pytest.raises(DatabaseError, match=rf"locked by another writer \(pid {p.pid}: .*--wait SECONDS"):
                lab.add_unit(db, "U2")
            assert lab.table_counts(db) == counts
        assert [pid for pid, _ in lab.lock_holders(path)] == [p.pid]
    finally:
        release.set()
        p.join(30)
    with pytest.raises(DatabaseError, match="--wait"):
        lab.check_wait(-1)


def test_dates_are_bounded():
    now = dt.datetime(2026, 1, 1, 12)
    assert lab.check_date(now + lab.CLOCK_SKEW, now=now) == now + lab.CLOCK_SKEW  # within the skew: taken
    for bad, phrase in ((now + lab.CLOCK_SKEW + dt.timedelta(seconds=1), "in the future"),
                        (dt.datetime(2999, 12, 31), "in the future"), (dt.datetime(1900, 1, 1), "before 1950")):
        with pytest.raises(ValueError, match=phrase):
            lab.check_date(bad, now=now)
    for text in ("0001-01-01T00:00:00+01:00", "9999-12-31T23:59:59-01:00"):  # out of range once in UTC
        with pytest.raises(ValueError, match="not a date between"):
            lab.parse_date(text)
    with pytest.raises(DatabaseError, match="in the future"):
        lab.record_calibration(None, "U1", text_for(1), lab.SessionInfo(record_sha256=record_hash(1),
                                                                        date=dt.datetime(2999, 12, 31)))
