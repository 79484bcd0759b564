"""The chamber's temperature stability in ``inscal calibrate --station FILE.toml``, end to end through the
database: the unit's newest earlier result with a thermal model is found and named, its slope at the
session's ``--temperature-c`` is the closed form ``k1 + 2 k2 dT``, and the line is stored, printed by
``inscal db budget`` and shown by the certificate; the simulator's unit held 0.5 K off calibrates to
estimates that move by exactly that slope; ``--thermal-model PARAMS.toml`` without a database;
a file without a thermal model, or none at all, is one line, exit 2, nothing written or recorded.  (The
per-stop coefficients are computed for two windows only, as in ``test_budget_cli.py``.)"""

from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from inscal import lab
from inscal.core import units
from inscal.core.thermal import ThermalModel, thermal_to_field
from inscal.report.certificate import certificate_data, certificate_html

from budget_helpers import STATION, one_line, run

U_T = 0.1 / math.sqrt(2)  # the station's arcsine +-0.1 K
DEG_H, PPM = float(units.to_si(1.0, "deg/h")), float(units.to_si(1.0, "ppm"))
# the newest thermal result: gyro bias linear + quadratic (deg/h/degC, deg/h/degC^2), accel scale factor linear
K1, K2, KA = np.array([0.02, -0.015, 0.025]), np.array([1e-3, -2e-3, 5e-4]), np.array([0.5, -0.3, 0.2])
OLD_K1 = np.array([9.0, 9.0, 9.0])  # an older thermal result, which must not be used


def thermal_text(base: str, k1_gb, k2_gb=None) -> str:
    """A parameter file of method thermal-plateaus: ``base``'s parameters with a thermal model."""
    doc = tomllib.loads(base)
    gb = np.array([k1_gb] if k2_gb is None else [k1_gb, k2_gb]) * DEG_H
    m = ThermalModel(t_ref=20.0, t_min=-40.0, t_max=60.0, gyro_bias=gb, accel_scale_factor=np.array([KA]) * PPM)
    doc.update(method="thermal-plateaus", thermal=thermal_to_field(m))
    return tomli_w.dumps(doc)


def warm_record(folder: Path, t_c: float) -> Path:
    """A noise-free N25 record (20 Hz) of a unit with the thermal model K1, K2, KA held at ``t_c`` [degC]."""
    rows = [("gyro_bias", 1, K1, "deg/h/degC"), ("gyro_bias", 2, K2, "deg/h/degC^2"),
            ("accel_scale_factor", 1, KA, "ppm/degC")]
    scen = {"base": "n25", "scenario": {"name": "n25-warm", "rate_hz": 20},
            "thermal": {"t_ref": 20.0, "t_min": -40.0, "t_max": 60.0, "terms": {}},
            "temperature": {"start_c": t_c, "pieces": [{"kind": "hold", "duration_s": 1e5}]}}
    for name, k, v, unit in rows:
        scen["thermal"]["terms"].setdefault(name, []).append({"order": k, "value": v.tolist(), "unit": unit})
    (folder / f"warm{t_c:g}.toml").write_text(tomli_w.dumps(scen))
    rec = folder / f"warm{t_c:g}.h5"
    r = run("simulate", folder / f"warm{t_c:g}.toml", "--out", rec, "--no-noise")
    assert r.exit_code == 0, r.stderr
    return rec


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("budgetthermal")
    db = tmp / "lab.sqlite"
    assert run("db", "add", "U7", "--model", "FOG", "--db", db).exit_code == 0
    rec = warm_record(tmp, 35.5)  # the run half a kelvin above the 35 degC it is stated at
    base = tmp / "base.toml"  # a parameter file without a thermal model (and the base of the thermal ones)
    assert run("calibrate", rec, "-m", "n25", "-o", base).exit_code == 0
    ids = []
    with lab.open_database(db) as d:  # two earlier thermal results: the newer one (by its record's date) counts
        for day, text in (("2025-03-01", thermal_text(base.read_text(), K1, K2)),
                          ("2025-01-01", thermal_text(base.read_text(), OLD_K1))):
            ids.append(lab.record_calibration(d, "U7", text, lab.SessionInfo(
                record_sha256="sha256:" + day[5:7] * 32, date=lab.parse_date(day)), options={"day": day}))
    return tmp, db, rec, base, ids


def line(comp: dict) -> dict:
    return next(x for x in comp["contributions"] if x["input"] == "temperature_stability")


def test_the_units_thermal_result_is_found_named_and_stored(setup, two_windows):
    tmp, db, rec, _, ids = setup
    r = run("calibrate", rec, "-m", "n25", "-o", tmp / "p.toml", "--serial", "U7", "--db", db, "--station", STATION,
            "--temperature-c", 35, "--json")
    assert r.exit_code == 0, r.stderr
    b = json.loads(r.stdout)["budget"]
    comps = {c["label"]: c for c in b["components"]}
    dT = 35.0 - 20.0
    for i in range(3):  # closed form in field units: c = k1 + 2 k2 dT (deg/h per K), u_i = |c| u(T)
        x = line(comps[f"gyro_bias[{i}]"])
        c = abs(K1[i] + 2 * K2[i] * dT)
        assert x["sensitivity"] == pytest.approx(c, rel=1e-9) and x["unit"] == "K" and x["distribution"] == "arcsine"
        assert x["u"] == pytest.approx(U_T, rel=1e-12) and x["contribution"] == pytest.approx(c * U_T, rel=1e-9)
        assert line(comps[f"accel_scale_factor[{i}]"])["sensitivity"] == pytest.approx(abs(KA[i]), rel=1e-9)
        assert line(comps[f"gyro_scale_factor[{i}]"])["sensitivity"] == 0.0  # constant in that model
    assert sum(x["share"] for x in comps["gyro_bias[0]"]["contributions"]) == pytest.approx(1.0)
    note = next(n for n in b["notes"] if n.startswith("temperature_stability:"))
    assert f"result {ids[0]} of U7 (thermal-plateaus, 2025-03-01)" in note and "35 degC" in note, note
    assert "mean temperature 35.5 degC is 0.5 K from the stated 35 degC, more than 3 u(T)" in note, note
    # stored as computed: db budget's JSON and its table; the certificate's row
    got = json.loads(run("db", "budget", "U7", "--db", db, "--json").stdout)
    assert got["budget"] == b
    text = run("db", "budget", "U7", "--db", db).stdout
    rows = re.findall(r"^ +temperature_stability +arcsine +(\S+) +K +(\S+) +(\S+) +(\S+)%$", text, re.M)
    assert len(rows) == len(b["components"]) and f"result {ids[0]} of U7" in text
    assert float(rows[9][1]) == pytest.approx(abs(K1[0] + 2 * K2[0] * dT), rel=1e-3)  # gyro_bias[0]: 4 digits
    with lab.open_database(db) as d:
        cal = lab.current_calibration(d, "U7")
        page = certificate_html(certificate_data(cal, None, issued=cal.recorded_at, budget=lab.get_budget(d, cal.id)))
    x = line(comps["gyro_bias[0]"])
    assert page.count("data-input='temperature_stability'") == len(b["components"])
    assert f"data-exact='{x['contribution']!r}'" in page and "chamber temperature stability" in page


def test_an_explicit_model_and_files_without_one(setup, two_windows, tmp_path):
    tmp, db, rec, base, _ = setup
    model = tmp_path / "thermal.toml"
    model.write_text(thermal_text(base.read_text(), K1, K2))
    r = run("calibrate", rec, "-m", "n25", "-o", tmp_path / "q.toml", "--station", STATION, "--thermal-model", model,
            "--temperature-c", 5, "--json")  # no database: the file's model, at the given temperature
    assert r.exit_code == 0, r.stderr
    b = json.loads(r.stdout)["budget"]
    x = line(next(c for c in b["components"] if c["label"] == "gyro_bias[1]"))
    assert x["sensitivity"] == pytest.approx(abs(K1[1] + 2 * K2[1] * (5.0 - 20.0)), rel=1e-9)
    assert any("thermal.toml (--thermal-model)" in n for n in b["notes"])
    # a parameter file without a thermal model, one that is not there, one that is not TOML: one line, exit 2
    bad = tmp_path / "bad.toml"
    bad.write_text("kind = [")
    with lab.open_database(db) as d:
        before = lab.table_counts(d)
    for f, phrase in ((base, "has no thermal model"), (tmp_path / "none.toml", "--thermal-model"),
                      (bad, "not a valid TOML file")):
        one_line(run("calibrate", rec, "-m", "n25", "-o", tmp_path / "o.toml", "--serial", "U7", "--db", db,
                     "--station", STATION, "--thermal-model", f, "--supersedes", 1), phrase, str(f.name))
    one_line(run("calibrate", rec, "-m", "n25", "-o", tmp_path / "o.toml", "--thermal-model", model),
             "give --station FILE.toml")
    one_line(run("calibrate", rec, "-m", "n25", "-o", tmp_path / "o.toml", "--station", STATION, "--temperature-c",
                 500), "--temperature-c 500.0: not an IMU temperature")
    assert not (tmp_path / "o.toml").exists()
    with lab.open_database(db) as d:
        assert lab.table_counts(d) == before


def test_the_slope_is_what_the_estimate_moves_by(setup, tmp_path):
    """The simulator's unit at 35.5 and 34.5 degC (noise-free), calibrated by N25: the estimates move by the
    slope the budget uses, k1 + 2 k2 (35 - 20) per K (a quadratic: the central difference is exact)."""
    tmp, _, _, base, _ = setup
    r = run("calibrate", warm_record(tmp_path, 34.5), "-m", "n25", "-o", tmp_path / "cold.toml", "--json")
    assert r.exit_code == 0, r.stderr
    cold = json.loads(r.stdout)["parameters"]
    warm = tomllib.loads(base.read_text())["parameters"]
    moved = {n: np.array(warm[n]["value"]) - np.array(cold[n]["value"]) for n in cold}
    np.testing.assert_allclose(moved["gyro_bias"], K1 + 2 * K2 * (35.0 - 20.0), rtol=1e-6)
    np.testing.assert_allclose(moved["accel_scale_factor"], KA, rtol=1e-6)
    for n in ("gyro_scale_factor", "accel_bias", "gyro_misalignment", "accel_misalignment"):  # constant in the model
        assert np.all(np.abs(moved[n]) < 1e-6), (n, moved[n])


#: a short thermal-states run (the psins19 path at 20 Hz; the temperature holds 0 degC, then ramps to 40 degC)
SCENARIO = """
base = "psins19"
[scenario]
name = "psins19-thermal"
rate_hz = 20
[site]  # the station's site (tests/data/station.toml): the budget refuses another site's station file
latitude_deg = 30.686
longitude_deg = 120.66
height_m = 50.0
gravity = {value = 9.793788, unit = "m/s^2"}
[thermal]
t_ref = 20.0
t_min = -40.0
t_max = 60.0
[[thermal.terms.gyro_bias]]
order = 1
value = [0.002, -0.0015, 0.0025]
unit = "deg/h/degC"
[[thermal.terms.accel_bias]]
order = 1
value = [5.0, -4.0, 6.0]
unit = "ug/degC"
[temperature]
start_c = 0.0
pieces = [{kind = "hold", duration_s = 120}, {kind = "ramp", target_c = 40, rate_c_per_min = 5}]
"""


def test_a_result_with_thermal_states_has_sensitivity_zero(setup, tmp_path):
    tmp, _, _, base, _ = setup
    scen = tmp_path / "scenario.toml"
    scen.write_text(SCENARIO)
    rec = tmp_path / "th.h5"
    assert run("simulate", scen, "--out", rec, "--seed", 2).exit_code == 0
    model = tmp_path / "thermal.toml"
    model.write_text(thermal_text(base.read_text(), K1, K2))
    # the filter's differences rerun the state set the run used (51,thermal=11110: 63 states)
    r = run("calibrate", rec, "-m", "systematic51", "--states", "51,thermal=11110", "-o", tmp_path / "p.toml",
            "--station", STATION, "--thermal-model", model, "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["states"] == 63 and "thermal" in rep
    b = rep["budget"]
    for c in b["components"]:
        x = line(c)
        assert x["sensitivity"] == 0.0 and x["contribution"] == 0.0 and x["u"] == pytest.approx(U_T)
    note = next(n for n in b["notes"] if n.startswith("temperature_stability:"))
    assert "sensitivity 0" in note and "measured" in note and "T_ref 20 degC" in note
    assert "--thermal-model thermal.toml not used" in note
    gb = next(c for c in b["components"] if c["label"] == "gyro_bias[0]")  # the site's inputs are still there
    assert {x["input"] for x in gb["contributions"] if x["sensitivity"] > 0} >= {"estimator (Type A)", "latitude"}
