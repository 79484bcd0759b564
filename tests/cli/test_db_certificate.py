"""``inscal db certificate``: the HTML, PDF and JSON of a real calibration, written together; the HTML is
what :mod:`inscal.report.certificate` renders from the JSON (whose numbers ``tests/report/test_certificate.py``
checks against the database), it renders in headless Chromium (screenshot), the PDF is a valid PDF whose
pages say "Page x of y" and whose text holds the certificate number and the values; every bad input is one
line, exit 2, nothing written.  The browser parts are skipped, with the reason, where Chromium is absent."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import lab
from inscal.cli.app import app
from inscal.report.certificate import (
    certificate_data,
    certificate_html,
    find_chromium,
    pdf_pages,
)

runner = CliRunner()
CHROMIUM = find_chromium()
NEEDS_CHROMIUM = "chromium not installed: apt-get install chromium (Debian) to print and render the certificate"
LAB = "North lab, 1 Example Road"


def run(*args, env=None):
    return runner.invoke(app, [str(a) for a in args], env=env)


def one_line(r, *phrases):
    assert r.exit_code == 2, (r.exit_code, r.stdout, r.stderr)
    err = r.stderr.strip()
    assert err.startswith("inscal: error: ") and "\n" not in err and "Traceback" not in err, err
    for p in phrases:
        assert p in err, (p, err)
    return err


@pytest.fixture(scope="module")
def lab_db(tmp_path_factory):
    """A database with unit FOG-7 calibrated twice (n25, short simulated records) and unit FOG-8 once."""
    tmp = tmp_path_factory.mktemp("certcli")
    db = tmp / "lab.sqlite"
    for serial in ("FOG-7", "FOG-8"):
        assert run("db", "add", serial, "--model", "FOG-IMU", "--db", db).exit_code == 0
    for seed, serial, date in ((1, "FOG-7", "2025-01-15"), (2, "FOG-7", "2025-02-15"), (3, "FOG-8", "2025-02-20")):
        rec = tmp / f"{serial}-{seed}.h5"
        assert run("simulate", "n25", "--out", rec, "--seed", seed, "--rate-hz", 20).exit_code == 0
        r = run("calibrate", rec, "--method", "n25", "--out", tmp / f"{serial}-{seed}.toml", "--serial", serial,
                "--db", db, "--station", "T1", "--operator", "ana", "--date", date)
        assert r.exit_code == 0, r.stderr
    return db


def chromium(*args, timeout=120):
    if CHROMIUM is None:
        pytest.skip(NEEDS_CHROMIUM)
    return subprocess.run([CHROMIUM, "--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run",
                           "--hide-scrollbars", *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "LANG": "C"}, check=False)


def test_the_certificate_files(lab_db, tmp_path):
    """HTML + PDF + JSON in a new folder; the JSON is the library's document, the HTML its rendering."""
    if CHROMIUM is None:
        pytest.skip(NEEDS_CHROMIUM)
    out = tmp_path / "certs"
    r = run("db", "certificate", "FOG-7", "--db", lab_db, "--out", out, "--issued", "2025-03-01", "--lab", LAB,
            "--authorized-by", "B. Boss", "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    with lab.open_database(lab_db) as d:
        cal = lab.current_calibration(d, "FOG-7")
        unit = lab.get_unit(d, "FOG-7")
    name = f"INSCAL-FOG-7-{cal.id}"
    assert rep["certificate"] == name and rep["result_id"] == cal.id and rep["fit_consistent"] is True
    assert sorted(p.name for p in out.iterdir()) == [f"{name}.html", f"{name}.json", f"{name}.pdf"]
    doc = certificate_data(cal, unit, issued=lab.parse_date("2025-03-01"), laboratory=LAB, authorized_by="B. Boss")
    stored = json.loads((out / f"{name}.json").read_text(encoding="utf-8"))
    assert stored == json.loads(json.dumps(doc))  # every number exactly the library's (the database's)
    assert (out / f"{name}.html").read_text(encoding="utf-8") == certificate_html(doc)
    pdf = (out / f"{name}.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and rep["pages"] == pdf_pages(pdf) and 2 <= rep["pages"] <= 4
    # the text of the PDF: the number on every page, "Page k of n", the values of the results table
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext not installed (apt-get install poppler-utils): the PDF's text is not checked")
    text = subprocess.run(["pdftotext", "-layout", str(out / f"{name}.pdf"), "-"], capture_output=True, text=True,
                          check=True).stdout
    pages = text.split("\f")
    pages = [p for p in pages if p.strip()]
    assert len(pages) == rep["pages"]
    for k, page in enumerate(pages, 1):
        assert f"Calibration certificate {name}" in page and f"Page {k} of {len(pages)}" in page, k
    flat = " ".join(text.split())
    rows = stored["results"]["rows"]
    for row in rows:
        assert f"{row['value_text']} {row['expanded_uncertainty_text']}" in flat, row["label"]
    for needle in ("Calibration certificate", "End of certificate " + name, "2025-03-01", LAB, "navi.726",
                   cal.session.record_sha256[:40], "relate only to the item calibrated"):
        assert needle in flat, needle


def test_the_certificate_renders_in_chromium(lab_db, tmp_path):
    """A screenshot of the HTML in headless Chromium (kept in the test's tmp folder, fog8.png): a page with
    text (not blank) down to the end of the certificate."""
    if CHROMIUM is None:
        pytest.skip(NEEDS_CHROMIUM)
    r = run("db", "certificate", "FOG-8", "--db", lab_db, "--out", tmp_path / "fog8.html", "--no-pdf")
    assert r.exit_code == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fog8.html", "fog8.json"]
    shot = tmp_path / "fog8.png"
    r = chromium(f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}", "--window-size=900,2600",
                 (tmp_path / "fog8.html").as_uri())
    assert r.returncode == 0 and shot.exists(), r.stderr[-2000:]
    import matplotlib.image as mpimg

    a = mpimg.imread(shot)[..., :3]
    assert a.shape[:2] == (2600, 900)
    ink = a.mean(axis=2) < 0.5  # dark pixels: text and rules
    rows_with_ink = np.flatnonzero(ink.any(axis=1))
    assert ink.mean() > 0.01 and rows_with_ink[-1] > 1500  # text down the page: all 28 results and the end


def test_options_and_overwrites(lab_db, tmp_path):
    """--result picks an older result; --out NAME.json names the three files; an existing certificate is refused
    without --force and replaced with it."""
    with lab.open_database(lab_db) as d:
        jan, feb = lab.calibrations(d, "FOG-7")
    r = run("db", "certificate", "FOG-7", "--db", lab_db, "--result", jan.id, "--out", tmp_path / "jan.json",
            "--no-pdf", "--issued", "2025-03-02T10:00:00Z", "--json")
    assert r.exit_code == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["result_id"] == jan.id and rep["pdf"] is None and rep["issued"] == "2025-03-02T10:00:00Z"
    doc = json.loads((tmp_path / "jan.json").read_text(encoding="utf-8"))
    assert doc["calibration"]["result_id"] == jan.id and not doc["calibration"]["current"]
    assert doc["calibration"]["date"] == "2025-01-15T00:00:00Z"
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    one_line(run("db", "certificate", "FOG-7", "--db", lab_db, "--result", jan.id, "--out", tmp_path / "jan.html",
                 "--no-pdf"), "jan.html exists; use --force")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    r = run("db", "certificate", "FOG-7", "--db", lab_db, "--out", tmp_path / "jan.html", "--no-pdf", "--force")
    assert r.exit_code == 0, r.stderr
    assert json.loads((tmp_path / "jan.json").read_text(encoding="utf-8"))["calibration"]["result_id"] == feb.id
    assert f"(result {feb.id}, n25, record of 2025-02-15)" in r.stdout


def test_bad_input_is_one_line_and_writes_nothing(lab_db, tmp_path):
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "c.pdf").write_bytes(b"%PDF an earlier certificate")
    (tmp_path / "afile").write_text("x")
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    out = tmp_path / "certs"
    with lab.open_database(lab_db) as d:
        other = lab.current_calibration(d, "FOG-8").id
    no_chromium = {"INSCAL_CHROMIUM": str(tmp_path / "no-such-chromium")}
    cases = [
        (("NOPE", "--out", out, "--no-pdf"), None, ("unknown unit 'NOPE'",)),
        (("FOG-7", "--out", out, "--result", 999, "--no-pdf"), None, ("no calibration result 999",)),
        (("FOG-7", "--out", out, "--result", other, "--no-pdf"), None, (f"result {other} is a calibration of FOG-8",)),
        (("FOG-7", "--out", out), no_chromium, ("headless Chromium", "apt-get install chromium", "--no-pdf")),
        (("FOG-7", "--out", out), {"INSCAL_CHROMIUM": "false"}, ("failed to print the PDF (exit 1)",)),
        (("FOG-7", "--out", tmp_path / "nodir" / "c.html", "--no-pdf"), None, ("does not exist",)),
        (("FOG-7", "--out", tmp_path / "nodir" / "sub", "--no-pdf"), None, ("does not exist",)),
        (("FOG-7", "--out", tmp_path / "afile", "--no-pdf"), None, ("not a folder",)),
        (("FOG-7", "--out", out, "--issued", "yesterday", "--no-pdf"), None, ("'yesterday' is not a date",)),
        (("FOG-7", "--out", tmp_path / "old" / "c.html", "--no-pdf", "--force"), None,
         ("c.pdf exists from an earlier certificate",)),
        (("FOG-7", "--out", lab_db.with_suffix(".html"), "--no-pdf", "--db", tmp_path / "none.sqlite"), None,
         ("no calibration database",)),
    ]
    for args, env, phrases in cases:
        if env is not None and "false" in env.values() and shutil.which("false") is None:
            continue
        full = ("db", "certificate", *args) + (() if "--db" in args else ("--db", lab_db))
        one_line(run(*full, env=env), *phrases)
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before
