"""The calibration database on SQLite and on a real PostgreSQL server: opening and refusing, one
calibration written and read back whole, the "already recorded" query, supersedes and the current
calibration, append-only tables, and a failed write that leaves nothing."""

from __future__ import annotations

import datetime as dt
import sqlite3
import types

import numpy as np
import pytest
import sqlalchemy as sa
from lab_synthetic import synthetic_result

from inscal import lab
from inscal.io.paramfile import ParamFileError
from inscal.lab import DatabaseError

VALUES = {"gyro_scale_factor": [50.0, -30.0, 20.0], "accel_bias": [100.0, -80.0, 40.0],
          "gimbal_nonorthogonality": 20.0}
SIGMA = {"gyro_scale_factor": [1.0, 1.1, 1.2], "accel_bias": [0.5, 0.6, np.nan], "gimbal_nonorthogonality": 0.2}


def session(h: str = "sha256:" + "ab" * 32, day: int = 15, **kw) -> lab.SessionInfo:
    return lab.SessionInfo(record_sha256=h, date=dt.datetime(2025, 1, day, 8, 30), record_path="run.h5",
                           station="T1", operator="ana", latitude_deg=30.0, longitude_deg=120.0, height_m=5.0,
                           gravity_model='{"kind": "wgs84", "value": null}', g_site_m_s2=9.79, path_name="n25-twelve",
                           **kw)


def test_urls_and_refusals(tmp_path, monkeypatch):
    p = tmp_path / "calib.sqlite"
    assert lab.database_url(str(p)).render_as_string() == f"sqlite:///{p}"
    assert lab.database_url("postgresql://u@h/db").drivername == "postgresql+psycopg"
    monkeypatch.setenv("INSCAL_DB", str(p))
    assert lab.database_url(None).database == str(p)
    for bad, phrase in (("mysql://u@h/db", "unsupported database 'mysql'"), ("sqlite:///:memory:", "keeps nothing"),
                        ("postgresql+asyncpg://u@h/db", "not supported")):
        with pytest.raises(DatabaseError, match=phrase):
            lab.database_url(bad)
    # a missing file is not created by a reader
    with pytest.raises(DatabaseError, match="no calibration database at .*inscal db init"):
        lab.open_database(p)
    assert not p.exists()
    # a file that is not SQLite, an SQLite file of something else
    (tmp_path / "x.sqlite").write_text("hello")
    with pytest.raises(DatabaseError, match="not an SQLite database"):
        lab.open_database(tmp_path / "x.sqlite", create=True)
    con = sqlite3.connect(tmp_path / "other.sqlite")
    con.execute("create table stuff (a)")
    con.commit()
    con.close()
    with pytest.raises(DatabaseError, match="not an inscal calibration database .*stuff"):
        lab.open_database(tmp_path / "other.sqlite", create=True)
    # created at the newest schema, idempotent
    db, created = lab.init_database(p)
    with db:
        assert created and lab.revision_of(db) == lab.head_revision() and lab.revision_number(lab.head_revision()) == 5
    db, created = lab.init_database(p)
    db.close()
    assert not created


def test_one_calibration_round_trip(db_url, synthetic_text):
    text = synthetic_text(VALUES, SIGMA)
    opts = lab.calibration_options("manual", systematic=False)
    with lab.open_database(db_url, create=True) as db:
        unit, created = lab.add_unit(db, "FOG-0042", model="FOG-IMU", notes="test unit")
        assert created and unit.model == "FOG-IMU"
        assert lab.add_unit(db, "FOG-0042") == (unit, False)  # registered already, same description
        with pytest.raises(DatabaseError, match="registered already with model 'FOG-IMU'"):
            lab.add_unit(db, "FOG-0042", model="other")
        rid = lab.record_calibration(db, "FOG-0042", text, session(temperature_c=21.5), options=opts)
        cal = lab.get_calibration(db, rid)
        assert cal.serial == "FOG-0042" and cal.method == "manual" and cal.current and cal.unit_model == "FOG-IMU"
        assert cal.param_text == text and cal.param_file_sha256 == lab.text_hash(text)
        for name, v in VALUES.items():
            p = cal.parameters[name]
            assert p.unit == {"gyro_scale_factor": "ppm", "accel_bias": "ug", "gimbal_nonorthogonality": "arcsec"}[name]
            np.testing.assert_allclose(p.value, v, rtol=1e-12)
            np.testing.assert_allclose(p.sigma, SIGMA[name], rtol=1e-12)  # NaN (held fixed) kept as NaN
            assert p.value.shape == np.shape(v)
        assert cal.parameters["gyro_scale_factor"].labels == ("gyro_scale_factor[x]", "gyro_scale_factor[y]",
                                                              "gyro_scale_factor[z]")
        cov = cal.covariance
        assert cov["basis"] == "parameters" and cov["units"] == "field" and not cov["correlations"]
        assert len(cov["labels"]) == 7 and cov["matrix"][0][0] == pytest.approx(1.0) and cov["matrix"][5][5] is None
        s = cal.session
        assert (s.record_sha256, s.station, s.operator, s.temperature_c, s.path_name) == (
            "sha256:" + "ab" * 32, "T1", "ana", 21.5, "n25-twelve")
        assert s.date == dt.datetime(2025, 1, 15, 8, 30)
        assert cal.options == opts and cal.inscal_version == lab.get_calibration(db, rid).inscal_version
        js = cal.to_json()
        assert js["provenance"]["session"]["date"] == "2025-01-15T08:30:00Z"
        assert js["parameters"]["accel_bias"]["sigma"] == [0.5, 0.6, None]
        # the "already recorded" query: same record and options only
        assert lab.find_calibration(db, s.record_sha256, opts) == rid
        assert lab.find_calibration(db, s.record_sha256, opts, "FOG-0042") == rid
        assert lab.find_calibration(db, s.record_sha256, opts | {"settle_s": 2.0}) is None
        assert lab.find_calibration(db, "sha256:" + "cd" * 32, opts) is None
        assert lab.find_calibration(db, s.record_sha256, opts, "OTHER") is None
        assert lab.current_calibration(db, "FOG-0042").id == rid


def test_supersedes_current_and_order(db_url, synthetic_text):
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        lab.add_unit(db, "U2")
        feb = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "02" * 32, 20))
        # an older record recorded afterwards joins the history but does not become current
        jan = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "01" * 32, 10))
        assert lab.current_calibration(db, "U1").id == feb and not lab.get_calibration(db, jan).current
        assert [c.id for c in lab.calibrations(db, "U1")] == [jan, feb]  # by the records' dates
        # the same record recalibrated: the new result replaces the old in the history and as current
        again = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "02" * 32, 20),
                                       options={"method": "manual", "settle_s": 2.0}, supersedes=feb)
        assert [c.id for c in lab.calibrations(db, "U1")] == [jan, again]
        assert [c.id for c in lab.calibrations(db, "U1", superseded=True)] == [jan, feb, again]
        assert lab.get_calibration(db, feb).superseded_by == (again,)
        assert lab.current_calibration(db, "U1").id == again
        assert lab.table_counts(db)["sessions"] == 2  # one session per record
        lab.set_current(db, "U1", jan)
        assert lab.current_calibration(db, "U1").id == jan
        counts = lab.table_counts(db)
        for bad, phrase in (({"supersedes": 999}, "no such result"), ({"supersedes": jan}, None)):
            if phrase is None:  # a result of another unit
                with pytest.raises(DatabaseError, match="another unit"):
                    lab.record_calibration(db, "U2", synthetic_text(VALUES, SIGMA), session(), **bad)
            else:
                with pytest.raises(DatabaseError, match=phrase):
                    lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session(), **bad)
        with pytest.raises(DatabaseError, match="not a calibration of U2"):
            lab.set_current(db, "U2", jan)
        with pytest.raises(DatabaseError, match="unknown unit 'NOPE'.*inscal db add NOPE"):
            lab.record_calibration(db, "NOPE", synthetic_text(VALUES, SIGMA), session())
        with pytest.raises(ParamFileError):
            lab.record_calibration(db, "U1", "kind = 'something else'\n", session())
        with pytest.raises(DatabaseError, match="options are of method"):
            lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session(), options={"method": "n25"})
        assert lab.table_counts(db) == counts  # a refused write leaves nothing


def test_tables_are_append_only(db_url, synthetic_text):
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session())
        for stmt in ("UPDATE results SET method = 'x'", "DELETE FROM parameters", "UPDATE units SET model = 'm'",
                     "DELETE FROM current", "UPDATE sessions SET station = 's'"):
            with pytest.raises(sa.exc.DBAPIError, match="append-only"), db.engine.begin() as conn:
                conn.exec_driver_sql(stmt)
        assert lab.table_counts(db) == {"units": 1, "sessions": 1, "results": 1, "parameters": 7, "current": 1,
                                          "result_keys": 1, "publications": 0, "stations": 0, "budgets": 0}


def test_a_failure_inside_the_transaction_leaves_no_half_result(tmp_path, synthetic_text, monkeypatch):
    """The parameter rows fail after the session and result rows are inserted: nothing stays."""
    from inscal.lab import store

    with lab.open_database(tmp_path / "c.sqlite", create=True) as db:
        lab.add_unit(db, "U1")

        def broken(conn, rid, rows):
            conn.execute(sa.insert(lab.schema.parameters), [{"result_id": rid, **rows[0]}])
            raise RuntimeError("disk on fire")

        monkeypatch.setattr(store, "write_parameters", broken)
        with pytest.raises(RuntimeError, match="disk on fire"):
            lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session())
        assert lab.table_counts(db) == {"units": 1, "sessions": 0, "results": 0, "parameters": 0, "current": 0,
                                          "result_keys": 0, "publications": 0, "stations": 0, "budgets": 0}


def test_covariance_of_a_result():
    P = np.diag([1e-12, 4e-12])
    filt = types.SimpleNamespace(covariance={"labels": ["gyro_matrix[xx]", "gyro_bias[x]"], "P": P}, diagnostics={})
    c = lab.covariance_of(filt)
    assert c["basis"] == "states" and c["units"] == "SI" and c["correlations"] and c["matrix"][1][1] == 4e-12
    ppm = 1e-6
    par = types.SimpleNamespace(diagnostics={"covariance": {"labels": ["gyro_scale_factor[x]", "accel_scale_factor[x]"],
                                                            "P": [[4 * ppm**2, ppm**2], [ppm**2, 9 * ppm**2]]}})
    c = lab.covariance_of(par)
    assert c["basis"] == "parameters" and c["units"] == "field"
    np.testing.assert_allclose(c["matrix"], [[4.0, 1.0], [1.0, 9.0]])
    assert lab.covariance_of(types.SimpleNamespace(diagnostics={})) is None


def test_the_commands_on_both_backends(db_url, tmp_path, synthetic_text):
    """``inscal db init / add / show / export`` on an SQLite file and on a PostgreSQL database by URL."""
    import json

    from typer.testing import CliRunner

    from inscal.cli.app import app

    runner = CliRunner()

    def run(*args):
        return runner.invoke(app, [str(a) for a in args] + ["--db", db_url])

    r = run("db", "show", "U1")
    assert r.exit_code == 2 and r.stderr.startswith("inscal: error: ") and r.stderr.count("\n") == 1
    r = run("db", "init", "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["created"] and json.loads(r.stdout)["schema"] == 5
    assert run("db", "add", "U1", "--model", "FOG").exit_code == 0
    text = synthetic_text(VALUES, SIGMA, data_hash="sha256:" + "ab" * 32)
    (tmp_path / "p.toml").write_text(text, encoding="utf-8")
    r = run("db", "add", "U1", tmp_path / "p.toml", "--station", "T9", "--json")
    assert r.exit_code == 0, r.stderr
    show = json.loads(run("db", "show", "U1", "--json").stdout)
    assert show["provenance"]["session"]["station"] == "T9" and show["parameters"]["gyro_scale_factor"]["unit"] == "ppm"
    assert show["provenance"]["session"]["record_sha256"] == "sha256:" + "ab" * 32
    r = run("db", "export", "U1", "--out", tmp_path / "e.toml")
    assert r.exit_code == 0 and (tmp_path / "e.toml").read_bytes() == text.encode()


def test_record_result_from_a_calibration_result(tmp_path):
    """What a batch of calibrations calls with a CalibrationResult: the text it records is the parameter file
    save_params writes (but its creation time), the values read back in SI are the result's."""
    from inscal.io.paramfile import load_params

    res = synthetic_result(VALUES, SIGMA, "manual")
    with lab.open_database(tmp_path / "c.sqlite", create=True) as db:
        lab.add_unit(db, "U1")
        rid, text = lab.record_result(db, "U1", res, session(), data_file="run.h5", metadata={"scenario": "x"},
                                      options={"method": "manual", "batch": 1})
        cal = lab.get_calibration(db, rid)
        assert lab.find_calibration(db, session().record_sha256, {"method": "manual", "batch": 1}) == rid
    assert cal.param_text == text and 'data_hash = "sha256:' + "ab" * 32 + '"' in text
    (tmp_path / "p.toml").write_text(text, encoding="utf-8")
    imu, gim, _ = load_params(tmp_path / "p.toml")
    value, sigma = cal.parameters["gyro_scale_factor"].si()
    np.testing.assert_allclose(value, imu.gyro_scale_factor, rtol=1e-12)
    np.testing.assert_allclose(value, res.imu.gyro_scale_factor, rtol=1e-12)
    np.testing.assert_allclose(sigma, res.sigma["gyro_scale_factor"], rtol=1e-12)
    assert cal.parameters["gimbal_nonorthogonality"].si()[0] == pytest.approx(gim.nonorthogonality, rel=1e-12)
