"""The publication journal on SQLite and PostgreSQL: a result committed with the journal of its files, the
writer gone before its renames (as SIGKILL leaves it); a read-only open only counts what is owed, the next
write-open rolls every entry forward (from its temporary, or from the database's copy of the parameter
file), leaves a file another program put in place, and leaves alone the entries of a writer at work (its
target's lock held) and of another host."""

from __future__ import annotations

import datetime as dt
import hashlib
import os
import subprocess
import sys

import sqlalchemy as sa
from test_database import SIGMA, VALUES, session

from inscal import lab
from inscal.io.files import lock_path
from inscal.lab import journal, schema


def snapshot(folder) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def test_a_publication_cut_after_its_commit_is_rolled_forward_by_the_next_write(db_url, synthetic_text, tmp_path):
    text = synthetic_text(VALUES, SIGMA)
    out = tmp_path / "out"
    out.mkdir()
    names = ("a.toml", "b.toml", "c.toml", "d.toml", "e.png")
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        staged = lab.stage_calibration(db, "U1", text, session())
        rid = staged.value["result_id"]
        outputs = []
        for name in names:
            tmp = out / f".{name}.abcd1234.part"
            tmp.write_text(text if name.endswith(".toml") else "a plot")
            outputs.append((tmp, out / name, False))
        journal.add(staged.conn, rid, outputs)
        staged.conn.execute(sa.insert(schema.publications).values(  # a writer on another machine
            result_id=rid, target="/elsewhere/f.toml", temporary="/elsewhere/.f.toml.abcd1234.part",
            sha256=lab.text_hash(text), overwrite=False, host="another-host", pid=1, created_at=dt.datetime(2025, 1, 1)))
        staged.commit()
    # what the killed writer left, then changed: b's and e's temporaries gone, another program's file at c
    (out / ".b.toml.abcd1234.part").unlink()
    (out / ".e.png.abcd1234.part").unlink()
    (out / "c.toml").write_text("theirs")
    before = snapshot(out)
    with lab.open_database(db_url, readonly=True) as db:  # a reader only counts what is owed
        assert lab.pending_publications(db) == 6 and db.recovery.done == []
    assert snapshot(out) == before
    hold = ("import fcntl, sys, time; f = open(sys.argv[1], 'a'); fcntl.flock(f, fcntl.LOCK_EX); print('held', flush=True); "
            "time.sleep(30)")
    holder = subprocess.Popen([sys.executable, "-S", "-c", hold, str(lock_path(out / "d.toml"))], stdout=subprocess.PIPE,
                              text=True)  # a writer of d.toml at work (between its commit and its renames)
    try:
        assert holder.stdout.readline().strip() == "held"
        with lab.open_database(db_url) as db:
            rec = db.recovery
            assert lab.pending_publications(db) == 2
    finally:
        holder.kill()
        holder.wait()
    done = {line.split(": ", 1)[1].split(" ", 1)[0].rsplit("/", 1)[-1]: line for line in rec.done}
    assert "published from its temporary" in done["a.toml"] and "written again from the database" in done["b.toml"]
    assert "another file" in done["c.toml"] and "lost" in done["e.png"], rec.done
    assert (out / "a.toml").read_text() == text == (out / "b.toml").read_text() and (out / "c.toml").read_text() == "theirs"
    assert not (out / "e.png").exists() and not (out / "d.toml").exists()
    assert sorted(rec.waiting) == sorted([f"result {rid}: {out / 'd.toml'} (being published by pid "
                                          f"{os.getpid()})",
                                          f"result {rid}: /elsewhere/f.toml (on host another-host)"])
    with lab.open_database(db_url) as db:  # the writer of d.toml gone: the next write-open completes it
        assert [line.endswith("published from its temporary") for line in db.recovery.done] == [True]
        assert lab.pending_publications(db) == 1 and len(lab.calibrations(db, "U1")) == 1
    assert (out / "d.toml").read_text() == text
    assert sorted(p.name for p in out.iterdir()) == ["a.toml", "b.toml", "c.toml", "d.toml"]
