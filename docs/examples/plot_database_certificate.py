"""
A unit's drift in the database, and its certificate
===================================================

Four monthly calibrations of one unit go into a calibration database (SQLite here). Its gyro x
scale factor drifts by 10 ppm a month, which the history shows with its rate and flags; the
other components stay within their σ. The current calibration then gets its certificate
(ISO/IEC 17025 §7.8 contents; HTML, PDF and JSON with ``inscal db certificate``), whose first page
is drawn below.

The same with commands::

    inscal db add FOG-0042 --model FOG-IMU --db lab.sqlite
    inscal calibrate jan.h5 --method n25 --out jan.toml --serial FOG-0042 \
        --db lab.sqlite --date 2025-01-15
    ...
    inscal db history FOG-0042 --db lab.sqlite --plot history.png
    inscal db certificate FOG-0042 --db lab.sqlite --out certs
"""

# %%
# Four monthly runs into the database
# -----------------------------------
# Each run is simulated from the ``n25`` scenario with the unit's gyro x scale factor 10 ppm higher
# each month, calibrated by the N25 method and recorded with :func:`inscal.lab.record_result`.
import datetime as dt
import shutil
import subprocess
import tempfile
from dataclasses import replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io, lab
from inscal.calibrate import calibrate
from inscal.report.certificate import certificate_data, certificate_html, find_chromium
from inscal.report.history import history_figure
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

folder = Path(tempfile.mkdtemp())
db = lab.open_database(folder / "lab.sqlite", create=True)
lab.add_unit(db, "FOG-0042", model="FOG-IMU")
base = build("n25")
for month in range(4):
    sf = base.imu.gyro_scale_factor + np.array([10e-6 * month, 0.0, 0.0])
    scenario = replace(base, imu=replace(base.imu, gyro_scale_factor=sf))
    path = folder / f"FOG-0042_2025-{month + 1:02d}-15.h5"
    write_simulation(path, scenario, np.random.default_rng(10 + month))
    result = calibrate(io.read_record(path), "n25")
    date = f"2025-{month + 1:02d}-15"
    session = lab.session_from_record(path, date=date, station="T1", operator="ana")
    rid, _ = lab.record_result(db, "FOG-0042", result, session, data_file=path.name,
                               options=lab.calibration_options("n25"))
    print(f"result {rid}: {path.name}")

# %%
# The history and its drift chart
# -------------------------------
# :func:`inscal.lab.unit_history` gives, per component, the repeatability, the Birge ratio of the
# spread against the σ, the drift rate per month ± 1σ and the flags at k = 3; the figure is the one
# ``inscal db history --plot`` writes.
h = lab.unit_history(db, "FOG-0042")
gyro_sf = next(c for c in h.components if c.label == "gyro_scale_factor[x]")
print(f"gyro_scale_factor[x]: drift {gyro_sf.rate:+.2f} ± {gyro_sf.rate_sigma:.2f} "
      f"{gyro_sf.unit}/month (true +10)")
flagged = [f"{c.label} ({', '.join(c.flags)})" for c in h.flagged]
print("flagged:", ", ".join(flagged) or "none")
print(f"{h.tests} tests, {h.expected_false_alarms:.2f} flags expected by chance")
fig = history_figure(h)

# %%
# The certificate's first page
# ----------------------------
# :func:`inscal.report.certificate.certificate_data` builds the certificate from the database's
# numbers; headless Chromium renders its HTML (as it prints the PDF).
cal = lab.current_calibration(db, "FOG-0042")
issued = dt.datetime(2025, 4, 20, tzinfo=dt.timezone.utc)
doc = certificate_data(cal, lab.get_unit(db, "FOG-0042"), issued=issued,
                       laboratory="North lab, 1 Example Road",
                       authorized_by="A. Signer")
html = folder / "certificate.html"
html.write_text(certificate_html(doc), encoding="utf-8")
chromium = find_chromium()
if chromium is not None:
    png = folder / "page1.png"
    flags = ["--headless=new", "--disable-gpu", "--no-sandbox", "--no-first-run",
             "--hide-scrollbars", "--disable-background-networking",
             f"--user-data-dir={folder / 'profile'}", "--window-size=900,1270"]
    subprocess.run([chromium, *flags, f"--screenshot={png}", html.as_uri()],
                   capture_output=True, timeout=120, check=True)
    fig, ax = plt.subplots(figsize=(7, 9.9), layout="constrained")
    ax.imshow(plt.imread(png))
    ax.set_axis_off()
else:
    print("Chromium is not installed: the certificate's page is not drawn")
shutil.rmtree(folder / "profile", ignore_errors=True)
