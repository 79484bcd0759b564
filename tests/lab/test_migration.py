"""Schema migrations (Alembic): a v1 database with rows is refused by this inscal with the command
that upgrades it; ``inscal db upgrade`` takes it to v2 (``sessions.temperature_c``) keeping every row;
a database from a newer inscal is refused in one line, by the library and by every command."""

from __future__ import annotations

import datetime as dt
import json

import pytest
import sqlalchemy as sa
from typer.testing import CliRunner

from inscal import lab
from inscal.cli.app import app
from inscal.lab import DatabaseError

runner = CliRunner()
V1 = "0001_initial"
T0 = dt.datetime(2025, 1, 15, 9, 0)


def fill_v1(db: lab.Database) -> None:
    """Rows of every table, written with v1's columns (as an inscal of schema v1 wrote them)."""
    with db.engine.begin() as conn:
        for uid, serial in ((1, "FOG-1"), (2, "FOG-2")):
            conn.execute(sa.text("INSERT INTO units (id, serial, model, notes, created_at) VALUES (:i, :s, 'M', NULL, :t)"),
                         {"i": uid, "s": serial, "t": T0})
        for sid, uid, day in ((1, 1, 1), (2, 1, 2), (3, 2, 3)):
            conn.execute(sa.text(
                "INSERT INTO sessions (id, unit_id, record_sha256, record_path, station, operator, date, latitude_deg, "
                "longitude_deg, height_m, gravity_model, g_site_m_s2, path_name, recorded_at) VALUES (:i, :u, :h, "
                "'r.h5', 'T1', 'ana', :d, 30.0, 120.0, 0.0, NULL, 9.79, 'n25-twelve', :t)"),
                {"i": sid, "u": uid, "h": f"sha256:{sid:064x}", "d": T0 + dt.timedelta(days=30 * day), "t": T0})
        for rid, sid, uid in ((1, 1, 1), (2, 2, 1), (3, 3, 2), (4, 2, 1)):
            conn.execute(sa.text(
                "INSERT INTO results (id, unit_id, session_id, method, state_set, options, options_hash, fit_chi2, "
                "fit_dof, fit_p, fit, notes, covariance, inscal_version, param_file, param_file_sha256, supersedes, "
                "recorded_at) VALUES (:i, :u, :s, 'n25', NULL, :o, 'sha256:x', 1.0, 2.0, 0.5, NULL, :n, NULL, '0.1.0', "
                ":p, 'sha256:y', :sup, :t)"),
                {"i": rid, "u": uid, "s": sid, "o": json.dumps({"method": "n25"}), "n": json.dumps([]),
                 "p": f"kind = 'inscal-parameters'  # {rid}\n", "sup": 2 if rid == 4 else None, "t": T0})
            for k in range(3):
                conn.execute(sa.text(
                    "INSERT INTO parameters (result_id, name, component, label, value, sigma, sigma_formal, unit) "
                    "VALUES (:r, 'accel_bias', :k, :lab, :v, 0.5, NULL, 'ug')"),
                    {"r": rid, "k": k, "lab": f"accel_bias[{'xyz'[k]}]", "v": 10.0 * rid + k})
            conn.execute(sa.text("INSERT INTO current (unit_id, result_id, set_at) VALUES (:u, :r, :t)"),
                         {"u": uid, "r": rid, "t": T0})


def dump(db: lab.Database) -> dict:
    out = {}
    with db.engine.connect() as conn:
        for table in ("units", "sessions", "results", "parameters", "current"):
            rows = conn.execute(sa.text(f'SELECT * FROM "{table}" ORDER BY id')).mappings().all()
            out[table] = [{k: v for k, v in r.items() if k != "temperature_c"} for r in rows]
    return out


def one_line(result) -> str:
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    err = result.stderr.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    return err


def test_v1_database_upgrades_keeping_every_row(db_url):
    db, created = lab.init_database(db_url, revision=V1)
    with db:
        assert created and lab.revision_of(db) == V1
        fill_v1(db)
        before = dump(db)
        assert {t: len(r) for t, r in before.items()} == {"units": 2, "sessions": 3, "results": 4, "parameters": 12,
                                                          "current": 4}
    # this inscal refuses it, saying how to upgrade; nothing is changed by the refusal
    with pytest.raises(DatabaseError, match=r"schema v1 \(0001_initial\) is older than this inscal's v5 .*inscal db "
                                            r"upgrade --db"):
        lab.open_database(db_url)
    err = one_line(runner.invoke(app, ["db", "list", "--db", db_url]))
    assert "inscal db upgrade" in err
    r = runner.invoke(app, ["db", "upgrade", "--db", db_url, "--json"])
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert (rep["from"], rep["to"], rep["schema_from"], rep["schema_to"]) == (V1, lab.head_revision(), 1, 5)
    assert rep["rows"] == {"units": 2, "sessions": 3, "results": 4, "parameters": 12, "current": 4, "result_keys": 4,
                           "publications": 0, "stations": 0, "budgets": 0}
    with lab.open_database(db_url) as db:
        assert dump(db) == before  # every row, every value kept
        with db.engine.connect() as conn:
            assert conn.execute(sa.text("SELECT count(*) FROM sessions WHERE temperature_c IS NULL")).scalar() == 3
        # the v1 rows read through the library
        cals = lab.calibrations(db, "FOG-1")
        assert [c.id for c in cals] == [1, 4] and cals[1].supersedes == 2
        assert cals[0].parameters["accel_bias"].value.tolist() == [10.0, 11.0, 12.0]
        assert lab.current_calibration(db, "FOG-2").id == 3
    r = runner.invoke(app, ["db", "upgrade", "--db", db_url])
    assert r.exit_code == 0 and "already at schema v5" in r.stdout


def test_a_database_of_a_newer_inscal_is_refused(db_url):
    lab.init_database(db_url)[0].close()
    with lab.open_database(db_url) as db, db.engine.begin() as conn:
        conn.execute(sa.text("UPDATE alembic_version SET version_num = '0007_from_the_future'"))
    with pytest.raises(DatabaseError, match="schema revision '0007_from_the_future' is newer than this inscal knows"):
        lab.open_database(db_url)
    for args in (["db", "list"], ["db", "upgrade"], ["db", "init"], ["db", "show", "X"], ["db", "history", "X"],
                 ["db", "add", "X", "--model", "M"]):
        err = one_line(runner.invoke(app, args + ["--db", db_url]))
        assert "newer" in err, (args, err)
