"""The calibration certificate (:mod:`inscal.report.certificate`): every number it prints, in the HTML
(results table and every tagged number) and in the JSON copy, is the database's, exactly in the
``data-exact`` attributes and the JSON, and rounded at the place the certificate states in the
printed text (U rounded up to two significant digits, the value to U's decimal place); a parameter
held fixed reads "fixed, not estimated"; an inconsistent fit says that U may not cover the error."""

from __future__ import annotations

import datetime as dt
import json
import math
import re
import tomllib
from decimal import Decimal
from html.parser import HTMLParser

import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import lab
from inscal.calibrate.result import CalibrationResult
from inscal.cli.app import app
from inscal.core import units
from inscal.core.error_model import PARAMETERS, GimbalErrors, ImuErrors
from inscal.io.jsonfile import to_jsonable
from inscal.report.certificate import (
    certificate_data,
    certificate_html,
    expanded_texts,
    fixed_text,
    round_up_2,
)
from inscal.report.html import display_unit

ISSUED = dt.datetime(2025, 3, 1, 9, 30, tzinfo=dt.UTC)


# ------------------------------------------------------------------------------------- the checks
def dec(x: float) -> Decimal:
    """A stored double as its shortest round-trip decimal (how the database and the JSON print it)."""
    return Decimal(repr(float(x)))


def last_place(text: str) -> Decimal:
    """One unit of the last digit printed (``"20.14" -> 0.01``, ``"1.235e+04" -> 10``, ``"71818" -> 1``)."""
    return Decimal(1).scaleb(Decimal(text).as_tuple().exponent)


def rounds_to(text: str, exact: float) -> bool:
    """``text`` is ``exact`` rounded at its own last digit."""
    return abs(Decimal(text) - dec(exact)) <= last_place(text) / 2


def rounded_up_2(text: str, exact: float) -> bool:
    """``text`` is ``exact`` rounded up to two significant digits: at or above it, by less than one unit of
    its second significant digit, with no other digit after the second."""
    d = Decimal(text)
    unit2 = Decimal(1).scaleb(d.adjusted() - 1)
    return (Decimal(0) <= d - dec(exact) < unit2) and d % unit2 == 0


class Cert(HTMLParser):
    """The numbers of a certificate page: the results rows (label -> cells as (attrs, text)) and every tagged
    number (``<span class=n data-key data-exact>``)."""

    def __init__(self, text: str):
        super().__init__()
        self.rows: dict[str, list[tuple[dict, str]]] = {}
        self.nums: dict[str, tuple[str, str]] = {}
        self._row = self._cell = self._span = None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "tr" and "data-label" in a:
            self._row = self.rows.setdefault(a["data-label"], [])
        elif tag == "td" and self._row is not None:
            self._cell = [a, ""]
        elif tag == "span" and a.get("class") == "n":
            self._span = [a, ""]

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self._row.append((self._cell[0], self._cell[1].strip()))
            self._cell = None
        elif tag == "tr":
            self._row = None
        elif tag == "span" and self._span is not None:
            a, text = self._span
            self.nums[a["data-key"]] = (a["data-exact"], text)
            self._span = None

    def handle_data(self, data):
        for c in (self._cell, self._span):
            if c is not None:
                c[1] += data


def check_certificate(cal: lab.Calibration, doc: dict, page: str) -> Cert:
    """Every number of ``doc`` (the JSON) and ``page`` (the HTML) against calibration ``cal`` (the database)."""
    doc = json.loads(json.dumps(to_jsonable(doc), allow_nan=False))  # as the JSON file holds it
    cert = Cert(page)
    s = cal.session
    # the results: one row per parameter component, in the database's order
    want = [(p, k, label) for p in cal.parameters.values() for k, label in enumerate(p.labels)]
    assert [r["label"] for r in doc["results"]["rows"]] == [label for _, _, label in want] == list(cert.rows)
    for (p, k, label), row in zip(want, doc["results"]["rows"]):
        value, sigma = float(p.value.ravel()[k]), float(p.sigma.ravel()[k])
        assert row["value"] == value and row["unit"] == p.unit and row["parameter"] == p.name
        _, (_, comp), (va, vt), (ua, ut), (_, unit) = cert.rows[label]
        assert comp == (row["component"] or "—") and unit == display_unit(p.unit)
        assert float(va["data-exact"]) == value and vt == row["value_text"]
        if math.isnan(sigma):
            assert row["fixed"] and row["expanded_uncertainty"] is None and row["standard_uncertainty"] is None
            assert ut == "fixed, not estimated" and "data-exact" not in ua
            assert rounds_to(vt, value)
            continue
        assert not row["fixed"] and row["standard_uncertainty"] == sigma and row["expanded_uncertainty"] == 2 * sigma
        assert float(ua["data-exact"]) == 2 * sigma and ut == row["expanded_uncertainty_text"]
        assert rounded_up_2(ut, 2 * sigma), (label, ut, 2 * sigma)
        # the value at U's decimal place (never coarser than units), rounded to nearest
        assert -Decimal(vt).as_tuple().exponent == max(-Decimal(ut).as_tuple().exponent, 0), (vt, ut)
        assert rounds_to(vt, value), (label, vt, value)
        formal = None if p.sigma_formal is None else float(p.sigma_formal.ravel()[k])
        assert row["standard_uncertainty_formal"] == (None if formal is None or math.isnan(formal) else formal)
    # every other number: tagged with the database's value, printed rounded at its own last digit
    db = {"calibration.result_id": cal.id, "conditions.latitude_deg": s.latitude_deg,
          "conditions.longitude_deg": s.longitude_deg, "conditions.height_m": s.height_m,
          "conditions.g_site_m_s2": s.g_site_m_s2, "conditions.temperature_c": s.temperature_c,
          "fit.chi2": cal.fit_chi2, "fit.dof": cal.fit_dof, "fit.p_value": cal.fit_p,
          "fit.chi2_per_dof": None if cal.fit_chi2 is None else cal.fit_chi2 / cal.fit_dof,
          "traceability.supersedes": cal.supersedes}
    assert set(cert.nums) == {k for k, v in db.items() if v is not None}
    for key, (exact, text) in cert.nums.items():
        assert float(exact) == db[key] and rounds_to(text, db[key]), (key, exact, text)
        group, name = key.split(".")
        assert doc[group][name] == db[key], key
    # the rest of the JSON: the database's
    assert doc["id"] == f"INSCAL-{cal.serial}-{cal.id}" and doc["issued"] == "2025-03-01T09:30:00Z"
    assert doc["item"]["serial"] == cal.serial and doc["item"]["model"] == cal.unit_model
    assert doc["calibration"]["date"] == lab.model.iso(cal.date) and doc["calibration"]["current"] == cal.current
    assert doc["laboratory"]["station"] == s.station and doc["laboratory"]["operator"] == s.operator
    assert doc["conditions"]["path_name"] == s.path_name and doc["conditions"]["record_path"] == s.record_path
    tr = doc["traceability"]
    assert (tr["record_sha256"], tr["param_file_sha256"], tr["options_hash"], tr["inscal_version"]) == (
        s.record_sha256, cal.param_file_sha256, cal.options_hash, cal.inscal_version)
    assert doc["method"]["name"] == cal.method and doc["method"]["options"] == cal.options
    assert doc["results"]["coverage_factor"] == 2
    for text in (doc["id"], "Calibration certificate", "U (k = 2)", "coverage factor k = 2", "approximately 95 %",
                 s.record_sha256, cal.param_file_sha256, "relate only to the item calibrated", "End of certificate"):
        assert text in page, text
    return cert


# ------------------------------------------------------------------------------------- rounding rules
@pytest.mark.parametrize("u, text, decimals", [(1106.4, "1.2E+3", -2), (0.996, "1.0", 1), (0.1, "0.10", 2),
                                               (5.29, "5.3", 1), (2.0, "2.0", 1), (99.6, "1.0E+2", -1),
                                               (0.0034, "0.0034", 4)])
def test_expanded_uncertainty_is_rounded_up_to_two_digits(u, text, decimals):
    r, d = round_up_2(u)
    assert (str(r), d) == (text, decimals)


def test_value_and_uncertainty_texts():
    assert expanded_texts(71817.71274071457, 2 * 553.2339775332083) == ("71818", "1200")
    assert expanded_texts(20.14043919518141, 2 * 0.20667075667097526) == ("20.14", "0.42")
    assert expanded_texts(-0.03164535650497806, 0.0696) == ("-0.032", "0.070")
    assert expanded_texts(-0.00001, 0.5) == ("0.00", "0.50")  # no "-0.00"
    assert expanded_texts(0.125, 0.2) == ("0.12", "0.20") and expanded_texts(0.375, 0.2)[0] == "0.38"  # half to even
    assert expanded_texts(12.5, None) == ("12.5", None)  # held fixed: 6 significant digits
    assert expanded_texts(None, None) == ("not a finite number", None)
    assert fixed_text(30.686651, 7) == "30.686651" and fixed_text(0.0, 3) == "0"
    assert fixed_text(9.793788003455276, 7) == "9.793788" and fixed_text(None, 2) is None


def test_the_printed_texts_round_trip_at_their_stated_place():
    """Random values and uncertainties over twelve decades: U printed is at or above 2 sigma by less than a unit
    of its second digit, the value within half a unit of U's last decimal."""
    rng = np.random.default_rng(5)
    for _ in range(3000):
        u = float(10 ** rng.uniform(-7, 5))
        v = float(rng.normal() * 10 ** rng.uniform(-6, 6))
        vt, ut = expanded_texts(v, u)
        assert rounded_up_2(ut, u), (u, ut)
        assert -Decimal(vt).as_tuple().exponent == max(-Decimal(ut).as_tuple().exponent, 0)
        assert rounds_to(vt, v), (v, vt)


# ------------------------------------------------------------------------------------- real calibrations
runner = CliRunner()


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A database with unit FOG-7 calibrated (n25) from a short simulated record, and unit HAND-1 with a
    hand-made parameter file: one component held fixed (sigma nan) and an inconsistent fit."""
    tmp = tmp_path_factory.mktemp("cert")
    db = tmp / "lab.sqlite"

    def run(*args):
        r = runner.invoke(app, [str(a) for a in args])
        assert r.exit_code == 0, r.stderr
        return r

    run("simulate", "n25", "--out", tmp / "run.h5", "--seed", 7, "--rate-hz", 20)
    run("db", "add", "FOG-7", "--model", "FOG-IMU", "--db", db)
    run("calibrate", tmp / "run.h5", "--method", "n25", "--out", tmp / "run.toml", "--serial", "FOG-7", "--db", db,
        "--station", "T1", "--operator", "ana", "--temperature-c", 21.5, "--date", "2025-02-15")
    values = {"accel_bias": [12.5, -3.25, 100.0], "gimbal_nonorthogonality": 20.5}
    sigma = {"accel_bias": [0.5, float("nan"), 0.04], "gimbal_nonorthogonality": 0.3}
    imu = ImuErrors(accel_bias=units.to_si(np.array(values["accel_bias"]), "ug"))
    gim = GimbalErrors(nonorthogonality=units.to_si(values["gimbal_nonorthogonality"], "arcsec"))
    sig = {n: np.asarray(units.to_si(np.asarray(sigma[n], dtype=float), PARAMETERS[n][3], PARAMETERS[n][2]))
           for n in values}
    res = CalibrationResult("manual", imu, gim, sig, tuple(values))
    doc = tomllib.loads(lab.param_file_text(res, "bench.h5", "sha256:" + "ab" * 32, {"scenario": "bench"}))
    doc["fit"] = {"chi2": 512.25, "dof": 100, "p_value": 1.5e-40, "consistent": False,
                  "note": "fit inconsistent: chi2 = 512.2 on 100 dof"}
    with lab.open_database(db) as d:
        lab.add_unit(d, "HAND-1", "bench unit")
        lab.record_calibration(d, "HAND-1", tomli_w.dumps(doc),
                               lab.SessionInfo(record_sha256="sha256:" + "ab" * 32, date=lab.parse_date("2025-01-02")),
                               options={"method": "manual"})
    return db


def test_every_number_of_a_real_calibration_is_the_databases(calibrated):
    with lab.open_database(calibrated) as d:
        cal = lab.current_calibration(d, "FOG-7")
        unit = lab.get_unit(d, "FOG-7")
    doc = certificate_data(cal, unit, issued=ISSUED, laboratory="North lab, 1 Example Road", authorized_by="B. Boss")
    page = certificate_html(doc)
    cert = check_certificate(cal, doc, page)
    assert len(cert.rows) == 28 and not any(r["fixed"] for r in doc["results"]["rows"])
    assert doc["fit"]["consistent"] is True and "INCONSISTENT" not in page
    assert doc["conditions"]["temperature_c"] == 21.5 and "21.5</span> °C" in page
    assert doc["conditions"]["gravity_model"]["kind"] == "wgs84" and "WGS-84 normal gravity" in page
    assert [r["key"] for r in doc["method"]["references"]] == ["N25"] and "doi:10.33012/navi.726" in page
    assert "North lab, 1 Example Road" in page and "Authorized by: B. Boss" in page
    assert doc["calibration"]["date"] == "2025-02-15T00:00:00Z" and "2025-02-15 00:00 UTC" in page
    # the mount yaw (~20 deg = 72000 arcsec, U ~ 1000 arcsec): the value at units, U with two digits
    _, _, (_, vt), (_, ut), _ = cert.rows["mount_attitude[gamma0]"]
    assert re.fullmatch(r"7\d{4}", vt) and re.fullmatch(r"\d{2}0+", ut), (vt, ut)


def test_fixed_parameters_and_an_inconsistent_fit_are_said(calibrated):
    with lab.open_database(calibrated) as d:
        cal = lab.current_calibration(d, "HAND-1")
    doc = certificate_data(cal, None, issued=ISSUED)
    page = certificate_html(doc)
    cert = check_certificate(cal, doc, page)
    rows = {r["label"]: r for r in doc["results"]["rows"]}
    assert rows["accel_bias[y]"]["fixed"] and rows["accel_bias[y]"]["value_text"] == "-3.25"
    assert page.count("fixed, not estimated") == 2  # the row and the statement of U
    assert [t for _, t in cert.rows["accel_bias[x]"][2:4]] == ["12.5", "1.0"]
    assert [t for _, t in cert.rows["accel_bias[z]"][2:4]] == ["100.000", "0.080"]
    assert doc["fit"]["consistent"] is False and "INCONSISTENT" in page and "U may understate it" in page
    assert doc["fit"]["note"] in page and doc["method"]["references"] == []
    assert doc["conditions"]["temperature_c"] is None and "IMU temperature</th><td>not recorded" in page
    assert "Laboratory</th><td>not stated" in page and "Site latitude</th><td>not recorded" in page
