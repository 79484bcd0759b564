"""The calibration certificate of one result in the calibration database, in the form ISO/IEC
17025:2017 §7.8 asks of calibration results (§7.8.2 common content, §7.8.4 calibration
certificates): an HTML page, its PDF (headless Chromium's print-to-PDF) and the same content as
machine-readable JSON.

One source: :func:`certificate_data` builds the JSON document from a
:class:`~inscal.lab.model.Calibration`; :func:`certificate_html` renders that document.  Every
number keeps the database's value in full precision in the JSON and in the ``data-exact`` attribute
of its HTML element; the printed text is that value (its shortest round-trip decimal, :func:`stored`) rounded at a stated
place:

- a result's expanded uncertainty ``U = 2 sigma`` (k = 2) rounded *up* to two significant digits
  (GUM, JCGM 100:2008, 7.2.6), its value rounded (half to even) to the same decimal place
  (never coarser than units), see :func:`expanded_texts`;
- other numbers at the digits given where they are printed (coordinates to 1e-7 deg, height to
  1 mm, gravity to 1e-7 m/s^2, temperature to 0.01 deg C, fit statistics to 4 significant digits
  or units, p to 3 significant digits), trailing zeros dropped.
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
import re
import shutil
import subprocess
import tempfile
from decimal import ROUND_CEILING, ROUND_HALF_EVEN, Decimal, localcontext
from pathlib import Path

from inscal import __version__
from inscal.calibrate.fit import P_INCONSISTENT
from inscal.lab.model import Calibration, Unit, iso
from inscal.report.budget import BUDGET_STATEMENT, budget_section
from inscal.report.html import display_unit, escape, fmt_num

#: what the JSON copy says it is
KIND = "inscal calibration certificate"
SCHEMA_VERSION = 1
TITLE = "Calibration certificate"
#: the coverage factor of the expanded uncertainties
K = 2
#: the papers the calibration methods implement
REFERENCES = {
    "N25": {"citation": "A self-calibration method for dual-axis rotational inertial navigation systems. "
                        "NAVIGATION: Journal of the Institute of Navigation 72(4), 2025, navi.726",
            "doi": "10.33012/navi.726"},
    "S16": {"citation": "Systematic calibration for ultra-high accuracy inertial measurement units. "
                        "Sensors 2016, 16, 940",
            "doi": None},
}
#: method -> (what it does, the papers it implements)
METHODS = {
    "n25": (("N25 scheme 1: multi-position least squares of the gimbal non-orthogonality and mounting attitude "
            "(N25 eq. 38, 40-44), then the accelerometer and gyro errors"), ("N25",)),
    "six-position": (("N25 scheme 2: six-position accelerometer calibration (N25 eq. 15-19), Earth-rate gyro bias "
                     "and CW/CCW rate tests (N25 eq. 28)"), ("N25",)),
    "twelve-position": ("N25 inner-symmetric twelve-position scheme (N25 eq. 24-26)", ("N25",)),
    "joint": (("one nonlinear least-squares fit of all IMU errors, the gimbal non-orthogonality and the mounting "
              "attitude of the N25 error model to every window mean; unobservable directions held fixed"), ("N25",)),
    "systematic51": (("S16 systematic calibration: 51-state Kalman filter and RTS smoother on the navigation "
                     "errors of the rotation sequence"), ("S16",)),
    "systematic30": (("the S16 systematic filter with the 30-state set (no g-sensitivity, quadratic, "
                     "cross-coupling or lever-arm states)"), ("S16",)),
    "unified": (("the S16 systematic filter with the N25 gimbal non-orthogonality and mounting attitude estimated "
                "from the encoder angles (58 states)"), ("N25", "S16")),
}
#: hand-made parameter files (:data:`inscal.io.paramfile.HAND_METHODS`): no inscal method computed them
HAND_METHOD = ("parameters entered from a parameter file that no inscal calibration method computed", ())
#: readable names of the parameters (field units and components: :data:`inscal.core.error_model.PARAMETERS`)
PARAMETER_TITLES = {
    "gyro_scale_factor": "Gyro scale factor", "gyro_misalignment": "Gyro misalignment", "gyro_bias": "Gyro bias",
    "gyro_g_sensitivity": "Gyro g-sensitivity", "accel_scale_factor": "Accelerometer scale factor",
    "accel_misalignment": "Accelerometer misalignment", "accel_bias": "Accelerometer bias",
    "accel_nonlinearity": "Accelerometer quadratic nonlinearity",
    "accel_cross_coupling": "Accelerometer cross-coupling", "accel_lever_arm": "Accelerometer lever arm (size effect)",
    "time_asynchrony": "Time asynchrony", "gimbal_nonorthogonality": "Gimbal non-orthogonality",
    "mount_attitude": "Mounting attitude",
}
GRAVITY_MODELS = {"wgs84": "WGS-84 normal gravity", "psins": "PSINS toolbox gravity formula"}
UNCERTAINTY_STATEMENT = (
    "The expanded uncertainty U is 2 × the standard uncertainty (1σ) the calibration reported for each result: "
    "coverage factor k = 2, which for a normal distribution corresponds to a coverage probability of "
    "approximately 95 %. U is rounded up to two significant digits (GUM, JCGM 100:2008, 7.2.6) and each value "
    "is rounded to the decimal place of its U; the JSON copy holds the unrounded numbers. U covers the "
    "estimate's error from the record's noise as the method propagates it; contributions the method does not "
    "model (the turntable's angle and rate errors, the gravity model, the item's stability after calibration) "
    "are not included. A result marked “fixed, not estimated” was held at the value shown and has no "
    "uncertainty.")
ONLY_ITEM = "The results relate only to the item calibrated, as calibrated from the record identified below."
IN_FULL = "This certificate shall not be reproduced except in full."
TRACEABILITY_STATEMENT = (
    "The results are computed by inscal from the record and with the options identified by the hashes below; "
    "the parameter file they are stored in is identified by its own hash. Metrological traceability of the "
    "references of the run (the turntable's angles and rates, local gravity, the Earth rate) is that of the "
    "station's equipment and is not established by this certificate.")


class CertificateError(Exception):
    """A certificate that cannot be made (one line)."""


def certificate_id(cal: Calibration) -> str:
    """The certificate's unique identification: ``INSCAL-<serial>-<result id>``."""
    return f"INSCAL-{cal.serial}-{cal.id}"


def file_stem(cal: Calibration) -> str:
    """:func:`certificate_id` with every character but letters, digits, ``.``, ``_`` and ``-`` as ``_``
    (a file name)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", certificate_id(cal))


# ------------------------------------------------------------------------------------------ numbers
def stored(x: float) -> Decimal:
    """``x`` as the database and the JSON copy print it: the shortest decimal that reads back as the same
    double (``repr``)."""
    return Decimal(repr(float(x)))


def decimal_text(d: Decimal, decimals: int) -> str:
    """``d`` with ``decimals`` digits after the point (none when ``decimals <= 0``; ``-0`` as ``0``)."""
    s = format(d, f".{max(decimals, 0)}f")
    return s[1:] if re.fullmatch(r"-0(\.0*)?", s) else s


def round_up_2(u: float) -> tuple[Decimal, int]:
    """``u > 0`` rounded up to two significant digits, and the decimal place of its second digit
    (``1106.4 -> (1.2E+3, -2)``, ``0.996 -> (1.0, 1)``)."""
    with localcontext() as ctx:
        ctx.prec = 1000
        d = stored(u)
        place = d.adjusted() - 1
        r = d.quantize(Decimal(1).scaleb(place), rounding=ROUND_CEILING)
        if r.adjusted() > d.adjusted():  # 99.6 -> 1.0E+2: two digits again at the new magnitude
            place += 1
            r = d.quantize(Decimal(1).scaleb(place), rounding=ROUND_CEILING)
        return r, -place


def expanded_texts(value: float | None, u: float | None) -> tuple[str, str | None]:
    """``(value text, U text)`` of a result with expanded uncertainty ``u`` (None: held fixed): U
    rounded up to two significant digits, the value rounded half to even at the same decimal place
    (at units when U is 100 or more); a fixed value to 6 significant digits, U None."""
    if value is None or not math.isfinite(value):
        return "not a finite number", None if u is None else "—"
    if u is None or not math.isfinite(u):
        return format(value, ".6g"), None
    if u <= 0:
        return repr(float(value)), "0"
    r, decimals = round_up_2(u)
    with localcontext() as ctx:
        ctx.prec = 1000
        v = stored(value).quantize(Decimal(1).scaleb(-max(decimals, 0)), rounding=ROUND_HALF_EVEN)
    return decimal_text(v, decimals), decimal_text(r, decimals)


def fixed_text(x: float | None, decimals: int) -> str | None:
    """``x`` rounded half to even at ``decimals`` decimals, trailing zeros dropped; None for None."""
    if x is None or not math.isfinite(x):
        return None
    with localcontext() as ctx:
        ctx.prec = 1000
        s = decimal_text(stored(x).quantize(Decimal(1).scaleb(-decimals), rounding=ROUND_HALF_EVEN), decimals)
    return s.rstrip("0").rstrip(".") if "." in s else s


# --------------------------------------------------------------------------------------- the document
def _finite(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def gravity_of(text: str | None) -> dict | None:
    """The gravity model of a session (its JSON text) as ``{"kind", "value", "height", "description"}``."""
    if not text:
        return None
    try:
        gm = json.loads(text)
    except ValueError:
        return {"kind": None, "value": None, "height": None, "description": str(text)}
    kind, value, height = gm.get("kind"), gm.get("value"), gm.get("height")
    if kind == "measured":
        desc = f"measured value {value!r} m/s²" + (f" at height {height!r} m (WGS-84 normal free-air gradient to "
                                                   "the site height)" if height is not None else " at the site")
    else:
        desc = GRAVITY_MODELS.get(kind, str(kind))
    return {"kind": kind, "value": value, "height": height, "description": desc}


def fit_verdict(cal: Calibration) -> bool | None:
    """Whether the calibration's fit is consistent with its noise model (None: no fit statistics): the fit's
    own verdict, else ``p >= P_INCONSISTENT`` (:data:`inscal.calibrate.fit.P_INCONSISTENT`)."""
    table = cal.fit if isinstance(cal.fit, dict) else {}
    if isinstance(table.get("consistent"), bool):
        return table["consistent"]
    if cal.fit_p is None:
        return None
    return cal.fit_p >= P_INCONSISTENT


def result_rows(cal: Calibration) -> list[dict]:
    """One row per parameter component: value, 1σ, U = 2σ (field unit), whether held fixed, the printed texts."""
    rows = []
    for name, p in cal.parameters.items():
        vals, sig = p.value.ravel(), p.sigma.ravel()
        formal = None if p.sigma_formal is None else p.sigma_formal.ravel()
        for k, label in enumerate(p.labels):
            comp = label[len(name) + 1:-1] if label.startswith(name + "[") else ""
            v, s = _finite(vals[k]), _finite(sig[k])
            u = None if s is None else K * s
            vt, ut = expanded_texts(v, u)
            rows.append({"label": label, "parameter": name, "title": PARAMETER_TITLES.get(name, name),
                         "component": comp, "unit": p.unit, "value": v, "standard_uncertainty": s,
                         "expanded_uncertainty": u, "fixed": s is None,
                         "standard_uncertainty_formal": None if formal is None else _finite(formal[k]),
                         "value_text": vt, "expanded_uncertainty_text": ut})
    return rows


def apply_budget(rows: list[dict], budget: dict) -> None:
    """Each row's expanded uncertainty from the stored budget (``budget["components"]``): ``U`` with its
    own ``k`` (95 %), the combined standard uncertainty, and the printed texts again."""
    comps = {(c["parameter"], int(c["index"])): c for c in budget["components"]}
    seen: dict[str, int] = {}
    for r in rows:
        i = seen[r["parameter"]] = seen.get(r["parameter"], -1) + 1
        c = comps.get((r["parameter"], i))
        if c is None or r["fixed"]:
            continue
        r.update({"expanded_uncertainty": c["U"], "coverage_factor": c["k"], "combined_standard_uncertainty": c["u_c"],
                  "budget_label": c["label"]})
        r["value_text"], r["expanded_uncertainty_text"] = expanded_texts(r["value"], c["U"])


def certificate_data(cal: Calibration, unit: Unit | None = None, *, issued: dt.datetime,
                     laboratory: str | None = None, authorized_by: str | None = None, budget: dict | None = None) -> dict:
    """The certificate of calibration ``cal`` as a JSON document (what the ``.json`` file holds and the
    HTML shows): every number the database's, unrounded, and the printed text of each result.  ``budget``:
    the result's stored uncertainty budget (:func:`inscal.lab.get_budget`: ``{"station", "budget"}``); then
    each U is the budget's (its own k for 95 %) and the certificate shows the budget."""
    s = cal.session
    description, refs = METHODS.get(cal.method, HAND_METHOD)
    consistent = fit_verdict(cal)
    table = cal.fit if isinstance(cal.fit, dict) else {}
    ratio = cal.fit_chi2 / cal.fit_dof if cal.fit_chi2 is not None and cal.fit_dof else None
    rows = result_rows(cal)
    if budget is not None:
        apply_budget(rows, budget["budget"])
    scaled = any(r["standard_uncertainty_formal"] is not None for r in rows)
    if consistent is None:
        statement = "The method reported no fit statistics: the consistency of the reported σ is not tested."
    elif consistent:
        statement = (f"The fit is consistent with the method's noise model (χ² test at p = {P_INCONSISTENT:g}): "
                     "the reported σ account for the record's noise.")
    else:
        statement = ("The fit is INCONSISTENT with the method's noise model: the reported σ may not cover the error "
                     "of the results, and U may understate it."
                     + (" The σ were scaled for the misfit (the formal σ are in the JSON copy)." if scaled else ""))
    return {
        "kind": KIND, "schema_version": SCHEMA_VERSION, "title": TITLE, "standard": "ISO/IEC 17025:2017 §7.8",
        "id": certificate_id(cal), "issued": iso(issued),
        "laboratory": {"name": laboratory, "station": s.station, "operator": s.operator,
                       "authorized_by": authorized_by},
        "item": {"serial": cal.serial, "model": cal.unit_model, "notes": None if unit is None else unit.notes},
        "calibration": {"result_id": cal.id, "date": iso(cal.date), "recorded_at": iso(cal.recorded_at),
                        "current": cal.current, "supersedes": cal.supersedes,
                        "superseded_by": list(cal.superseded_by)},
        "conditions": {"latitude_deg": s.latitude_deg, "longitude_deg": s.longitude_deg, "height_m": s.height_m,
                       "gravity_model": gravity_of(s.gravity_model), "g_site_m_s2": s.g_site_m_s2,
                       "temperature_c": s.temperature_c, "path_name": s.path_name, "record_path": s.record_path},
        "method": {"name": cal.method, "description": description, "state_set": cal.state_set,
                   "references": [{"key": r, **REFERENCES[r]} for r in refs], "options": cal.options},
        "results": ({"coverage_factor": K, "coverage_probability": "approximately 95 % (normal distribution)",
                     "uncertainty_statement": UNCERTAINTY_STATEMENT, "rows": rows} if budget is None else
                    {"coverage_factor": "per result (uncertainty budget)", "coverage_probability": "95 %",
                     "uncertainty_statement": BUDGET_STATEMENT, "rows": rows}),
        "budget": budget,
        "fit": {"chi2": cal.fit_chi2, "dof": cal.fit_dof, "chi2_per_dof": ratio, "p_value": cal.fit_p,
                "consistent": consistent, "statement": statement, "note": table.get("note"),
                "cause": table.get("cause")},
        "notes": list(cal.notes),
        "traceability": {"record_sha256": s.record_sha256, "param_file_sha256": cal.param_file_sha256,
                         "options_hash": cal.options_hash, "inscal_version": cal.inscal_version,
                         "certificate_inscal_version": __version__, "supersedes": cal.supersedes,
                         "statement": TRACEABILITY_STATEMENT},
        "statements": [ONLY_ITEM, IN_FULL],
    }


# ------------------------------------------------------------------------------------------ the HTML
CSS = """
@page { size: A4; margin: 18mm 14mm 18mm 14mm;
  @top-left { content: "%(title)s %(id)s"; font: 8pt sans-serif; color: #444; }
  @top-right { content: "Issued %(issued)s"; font: 8pt sans-serif; color: #444; }
  @bottom-center { content: "Page " counter(page) " of " counter(pages); font: 8pt sans-serif; } }
body { font-family: "DejaVu Sans", sans-serif; font-size: 10pt; max-width: 190mm; margin: 0 auto; color: #111; }
h1 { font-size: 18pt; margin: 0 0 2mm 0; } h2 { font-size: 11.5pt; margin: 5mm 0 1.5mm 0; break-after: avoid; }
p { margin: 1.5mm 0; } .small { font-size: 8.5pt; color: #333; }
table { border-collapse: collapse; width: 100%%; } thead { display: table-header-group; }
tr { break-inside: avoid; } th, td { border: 1px solid #bbb; padding: 1.2mm 2mm; text-align: left; vertical-align: top; }
table.kv th { width: 27%%; background: #f3f3f3; font-weight: normal; }
table.results th { background: #e8e8e8; } td.num, th.num { text-align: right; white-space: nowrap; font-variant-numeric: tabular-nums; }
td.fixed { font-style: italic; color: #555; } .hash { font-family: "DejaVu Sans Mono", monospace; font-size: 7.5pt; word-break: break-all; }
.bad { color: #a00; font-weight: bold; } .end { text-align: center; margin-top: 6mm; font-weight: bold; }
.sign { margin-top: 8mm; } table.kv, p { break-inside: avoid; } header { border-bottom: 2px solid #222; padding-bottom: 2mm; margin-bottom: 3mm; }
"""


def num(key: str, exact, text: str | None, suffix: str = "") -> str:
    """A number of the certificate: its printed ``text`` in a span that keeps the exact value."""
    if exact is None or text is None:
        return "not recorded"
    return (f"<span class='n' data-key='{escape(key)}' data-exact='{escape(repr(exact))}'>{escape(text)}</span>"
            + escape(suffix))


def kv(rows: list[tuple[str, str]]) -> str:
    """A two-column table of (label, HTML) rows."""
    return "<table class='kv'>" + "".join(f"<tr><th>{escape(k)}</th><td>{v}</td></tr>" for k, v in rows) + "</table>"


def text_or(v, absent: str = "not recorded") -> str:
    return escape(absent) if v is None or v == "" else escape(v)


def day(t: str | None) -> str:
    """``2025-01-15T08:30:00Z`` as ``2025-01-15 08:30 UTC``."""
    return "not recorded" if not t else escape(t[:10] + " " + t[11:16] + " UTC")


def results_table(rows: list[dict]) -> str:
    """The results: value and U per component (with the budget's k where a budget gave U)."""
    budget = any("coverage_factor" in r for r in rows)
    head = ("<thead><tr><th>Parameter</th><th>Component</th><th class='num'>Value</th>"
            + ("<th class='num'>U (95 %)</th><th class='num'>k</th>" if budget else "<th class='num'>U (k = 2)</th>")
            + "<th>Unit</th></tr></thead>")
    body = []
    for r in rows:
        value = (f"<td class='num value' data-exact='{escape(repr(r['value']))}'>{escape(r['value_text'])}</td>"
                 if r["value"] is not None else f"<td class='num value'>{escape(r['value_text'])}</td>")
        if r["fixed"]:
            u = "<td class='num fixed'>fixed, not estimated</td>"
        else:
            u = (f"<td class='num U' data-exact='{escape(repr(r['expanded_uncertainty']))}'>"
                 f"{escape(r['expanded_uncertainty_text'])}</td>")
        if budget:
            u += ("<td class='num'>—</td>" if "coverage_factor" not in r else
                  f"<td class='num k' data-exact='{escape(repr(r['coverage_factor']))}'>{r['coverage_factor']:.3f}</td>")
        body.append(f"<tr data-label='{escape(r['label'])}'><td>{escape(r['title'])}</td>"
                    f"<td>{escape(r['component'] or '—')}</td>{value}{u}<td>{escape(display_unit(r['unit']))}</td></tr>")
    return f"<table class='results'>{head}<tbody>{''.join(body)}</tbody></table>"


def certificate_html(doc: dict) -> str:
    """The certificate page of a certificate document: self-contained, A4 print layout with
    "Page x of y" in the footer of every printed page.

    Parameters
    ----------
    doc : dict
        The certificate document (:func:`certificate_data`).

    Returns
    -------
    str
        The HTML page.

    Examples
    --------
    >>> import datetime as dt
    >>> import numpy as np
    >>> from inscal import lab
    >>> from inscal.calibrate import CalibrationResult
    >>> from inscal.core.error_model import GimbalErrors, ImuErrors
    >>> from inscal.report.certificate import certificate_data, certificate_html
    >>> res = CalibrationResult("six-position", ImuErrors(), GimbalErrors(), {"gyro_bias": np.full(3, 1e-9)},
    ...                         ("gyro_bias",))
    >>> db, _ = lab.init_database("calib.sqlite")
    >>> unit, _ = lab.add_unit(db, "IMU-1", "nav-grade")
    >>> session = lab.SessionInfo(record_sha256="sha256:" + "1" * 64, date=dt.datetime(2025, 1, 31))
    >>> rid, _ = lab.record_result(db, "IMU-1", res, session)
    >>> doc = certificate_data(lab.get_calibration(db, rid), unit, issued=dt.datetime(2025, 2, 3))
    >>> page = certificate_html(doc)
    >>> "<html" in page, "IMU-1" in page
    (True, True)
    >>> db.close()
    """
    lab, item, cal, cond = doc["laboratory"], doc["item"], doc["calibration"], doc["conditions"]
    meth, res, fit, tr = doc["method"], doc["results"], doc["fit"], doc["traceability"]
    issued = doc["issued"][:10]
    css = CSS % {"title": doc["title"], "id": doc["id"], "issued": issued}
    status = "current calibration of the unit" if cal["current"] else "not the current calibration of the unit"
    if cal["superseded_by"]:
        status += "; superseded by result " + ", ".join(map(str, cal["superseded_by"]))
    g = cond["gravity_model"]
    refs = "".join(f"<li>[{escape(r['key'])}] {escape(r['citation'])}"
                   + (f", doi:{escape(r['doi'])}" if r["doi"] else "") + "</li>" for r in meth["references"])
    options = ", ".join(f"{k} = {v}" for k, v in meth["options"].items())
    temp = cond["temperature_c"]
    parts = [
        f"<header><h1>{escape(doc['title'])}</h1>"
        f"<p>Certificate number <b class='id'>{escape(doc['id'])}</b> · date of issue "
        f"<span class='issued'>{escape(issued)}</span></p>"
        + (f"<p>{escape(lab['name'])}</p>" if lab["name"] else "") + "</header>",
        "<h2>1. Item calibrated</h2>",
        kv([("Serial number", escape(item["serial"])), ("Model", text_or(item["model"], "not stated")),
            ("Description", "inertial measurement unit on a dual-axis turntable / rotational INS")]
           + ([("Notes", escape(item["notes"]))] if item["notes"] else [])),
        "<h2>2. Calibration</h2>",
        kv([("Laboratory", text_or(lab["name"], "not stated")), ("Station", text_or(lab["station"])),
            ("Operator", text_or(lab["operator"])),
            ("Date of calibration", day(cal["date"]) + " (the record)"),
            ("Result", (f"{num('calibration.result_id', cal['result_id'], str(cal['result_id']))} in the calibration "
                       f"database, recorded {day(cal['recorded_at'])}; {escape(status)}")),
            ("Date of issue", escape(issued))]),
        "<h2>3. Conditions</h2>",
        kv([("Site latitude", num("conditions.latitude_deg", cond["latitude_deg"],
                                  fixed_text(cond["latitude_deg"], 7), " °")),
            ("Site longitude", num("conditions.longitude_deg", cond["longitude_deg"],
                                   fixed_text(cond["longitude_deg"], 7), " °")),
            ("Site height", num("conditions.height_m", cond["height_m"], fixed_text(cond["height_m"], 3), " m")),
            ("Gravity model", text_or(None if g is None else g["description"])),
            ("Gravity at the site", num("conditions.g_site_m_s2", cond["g_site_m_s2"],
                                        fixed_text(cond["g_site_m_s2"], 7), " m/s²")),
            ("IMU temperature", num("conditions.temperature_c", temp, fixed_text(temp, 2), " °C")),
            ("Rotation path", text_or(cond["path_name"])), ("Record file", text_or(cond["record_path"]))]),
        "<h2>4. Method</h2>",
        kv([("Method", f"<b>{escape(meth['name'])}</b>: {escape(meth['description'])}"),
            ("Reference", f"<ul style='margin:0;padding-left:4mm'>{refs}</ul>" if refs else "none"),
            ("State set", text_or(meth["state_set"], "the method's own")),
            ("Options", escape(options) or "none")]),
        "<h2>5. Results</h2>",
        f"<p class='small'>{escape(res['uncertainty_statement'])}</p>",
        results_table(res["rows"]),
        ("" if doc.get("budget") is None else
         "<h2>5a. Uncertainty budget</h2>" + budget_section(doc["budget"]["budget"], doc["budget"]["station"])),
        "<h2>6. Fit</h2>",
        kv([("χ² / degrees of freedom", f"{num('fit.chi2', fit['chi2'], fmt_num(fit['chi2'], 4))} / "
                                       f"{num('fit.dof', fit['dof'], fmt_num(fit['dof'], 6))} = "
                                       f"{num('fit.chi2_per_dof', fit['chi2_per_dof'], fmt_num(fit['chi2_per_dof'], 4))}"
                                       if fit["chi2"] is not None else "not reported"),
            ("p-value", num("fit.p_value", fit["p_value"], fmt_num(fit["p_value"], 3))
             if fit["p_value"] is not None else "not reported"),
            ("Consistency", (f"<span class='{'bad' if fit['consistent'] is False else ''}'>"
                            f"{escape(fit['statement'])}</span>"))]
           + ([("Fit note", escape(fit["note"]))] if fit["note"] else [])
           + [("Note", escape(n)) for n in doc["notes"] if n != fit["note"]]),
        "<h2>7. Traceability</h2>",
        f"<p class='small'>{escape(tr['statement'])}</p>",
        kv([("Record sha256", f"<span class='hash'>{escape(tr['record_sha256'])}</span>"),
            ("Parameter file sha256", f"<span class='hash'>{escape(tr['param_file_sha256'])}</span>"),
            ("Options hash", f"<span class='hash'>{escape(tr['options_hash'])}</span>"),
            ("inscal version", escape(tr["inscal_version"])
             + ("" if tr["certificate_inscal_version"] == tr["inscal_version"]
                else f" (certificate made by inscal {escape(tr['certificate_inscal_version'])})")),
            ("Supersedes", "result " + num("traceability.supersedes", tr["supersedes"], str(tr["supersedes"]))
             if tr["supersedes"] is not None else "none")]),
        "<h2>8. Statements</h2>",
        "".join(f"<p>{escape(s)}</p>" for s in doc["statements"]),
        (f"<p class='small'>Sections 1 to 8 and {len(res['rows'])} results; printed copies are numbered "
        "“Page x of y”. Laid out after ISO/IEC 17025:2017 §7.8.2 and §7.8.4 (the content of calibration "
        "certificates); it does not state an accreditation.</p>"),
        (f"<p class='sign'>Authorized by: {escape(lab['authorized_by']) if lab['authorized_by'] else '&nbsp;' * 60}"
        " &nbsp; Signature: ______________________</p>"),
        f"<p class='end'>End of certificate {escape(doc['id'])}</p>",
    ]
    return (f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>{escape(doc['title'])} "
            f"{escape(doc['id'])}</title><style>{css}</style></head><body>" + "".join(parts) + "</body></html>")


# ------------------------------------------------------------------------------------------- the PDF
#: where to look for headless Chromium (``$INSCAL_CHROMIUM`` first)
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
CHROMIUM_ENV = "INSCAL_CHROMIUM"


def find_chromium() -> str | None:
    """The Chromium executable: ``$INSCAL_CHROMIUM`` (None if it is set but not executable), else the first
    of :data:`CHROMIUM_NAMES` on PATH."""
    given = os.environ.get(CHROMIUM_ENV)
    if given:
        return shutil.which(given)
    return next((p for n in CHROMIUM_NAMES if (p := shutil.which(n))), None)


def pdf_pages(data: bytes) -> int:
    """The number of pages of a PDF (its ``/Type /Page`` objects)."""
    return len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", data))


def print_pdf(html_text: str, chromium: str, timeout: float = 120.0) -> bytes:
    """The PDF of page ``html_text`` printed by headless Chromium (no browser header or footer: the page's
    own ``@page`` boxes number the pages), in a private folder and profile.  Raises
    :class:`CertificateError` (one line) when Chromium fails."""
    with tempfile.TemporaryDirectory(prefix="inscal-cert-") as tmp:
        page, pdf = Path(tmp) / "certificate.html", Path(tmp) / "certificate.pdf"
        page.write_text(html_text, encoding="utf-8")
        cmd = [chromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
               "--no-pdf-header-footer", f"--user-data-dir={Path(tmp) / 'profile'}", f"--print-to-pdf={pdf}",
               page.as_uri()]
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False,
                               env={**os.environ, "LANG": "C"})
        except subprocess.TimeoutExpired:
            raise CertificateError(f"{chromium} did not print the PDF within {timeout:g} s") from None
        except OSError as exc:
            raise CertificateError(f"cannot run {chromium}: {exc.strerror or exc}") from None
        data = pdf.read_bytes() if pdf.exists() else b""
        if r.returncode != 0 or not data.startswith(b"%PDF") or pdf_pages(data) < 1:
            last = next((ln for ln in reversed(r.stderr.splitlines()) if ln.strip()), "no output")
            raise CertificateError(f"{chromium} failed to print the PDF (exit {r.returncode}): {last[-300:]}")
        return data
