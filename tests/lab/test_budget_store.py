"""A budget stored with its result (schema v5: stations, budgets), on SQLite and PostgreSQL:
read back equal, the station stored once per content, append-only, and written in the result's
own transaction."""

from __future__ import annotations

import datetime as dt
import math
from pathlib import Path

import pytest
import sqlalchemy as sa

from inscal import lab
from inscal.uncertainty import budget as gum
from inscal.uncertainty.station import read_station

STATION = Path(__file__).resolve().parents[1] / "data" / "station.toml"
VALUES = {"accel_bias": [100.0, -80.0, 40.0]}
SIGMA = {"accel_bias": [0.5, 0.6, 0.7]}


def session(h: str) -> lab.SessionInfo:
    return lab.SessionInfo(record_sha256=h, date=dt.datetime(2025, 1, 15, 8, 30), record_path="run.h5",
                           station="T-2, lab 3", operator="ana", latitude_deg=30.0, longitude_deg=120.0, height_m=5.0,
                           gravity_model='{"kind": "wgs84", "value": null}', g_site_m_s2=9.79, path_name="n25-twelve")


def small_budget() -> gum.Budget:
    lines = [gum.Contribution.line(gum.ESTIMATOR, None, "ug", "normal", 0.5, 1.0, 30.0),
             gum.Contribution.line("gravity", 9.793788, "mGal", "normal", 1.0, 1.02, math.inf)]
    return gum.Budget("T-2, lab 3", "n25", 0.95, tuple(gum.combine("accel_bias", i, 1e-4 * i, lines) for i in range(3)),
                      ("a note",))


def test_budget_round_trip(db_url, synthetic_text):
    st = read_station(STATION)
    b = small_budget()
    with lab.open_database(db_url, create=True) as db:
        lab.add_unit(db, "U1")
        r1 = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "ab" * 32),
                                    budget=(st.to_dict(), b.to_dict()))
        r2 = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "cd" * 32),
                                    budget=(st.to_dict(), b.to_dict()))
        r3 = lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "ef" * 32))
        got = lab.get_budget(db, r1)
        assert gum.Budget.from_dict(got["budget"]) == b
        assert got["station"] == st.to_dict()
        assert lab.get_budget(db, r3) is None and lab.get_budget(db, r2)["budget"] == got["budget"]
        counts = lab.table_counts(db)
        assert counts["stations"] == 1 and counts["budgets"] == 2  # one station, by its content
        for stmt in ("UPDATE budgets SET coverage = 0.5", "DELETE FROM stations"):
            with pytest.raises(sa.exc.DBAPIError, match="append-only"), db.engine.begin() as conn:
                conn.exec_driver_sql(stmt)
        # a budget that cannot be stored takes its result with it
        with pytest.raises(Exception):
            lab.record_calibration(db, "U1", synthetic_text(VALUES, SIGMA), session("sha256:" + "99" * 32),
                                   budget=(st.to_dict(), {"no": "coverage"}))
        assert lab.table_counts(db) == counts
