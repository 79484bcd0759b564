"""
The uncertainty budget of a calibration
=======================================

A calibration's own σ covers the record's noise; a certificate also owes the station's
contributions: the table's angle and rate accuracy, the wobble and orthogonality of its axes, the
encoder, the site's gravity, latitude and height, the clock and the chamber. Calibrate the
simulated ``n25`` record by the N25 method, then propagate a station's ten inputs through the
estimator itself (:func:`inscal.uncertainty.sensitivity.calibration_budget`, JCGM 100 GUM) and look at what
each contributes to each parameter component's combined standard uncertainty.

The same with commands (``station.toml``: the station file of the guide's budget page)::

    inscal simulate n25 --out n25.h5 --seed 1
    inscal calibrate n25.h5 --method n25 --out n25.toml --station station.toml --json
"""

# %%
# The station and the calibration
# -------------------------------
# The station file of the guide's budget page; :func:`inscal.uncertainty.station.station_from_dict` reads
# its tables as ``inscal calibrate --station station.toml`` does.
import textwrap
import tomllib

import matplotlib.pyplot as plt
import numpy as np

from inscal.calibrate import calibrate
from inscal.uncertainty.sensitivity import calibration_budget
from inscal.uncertainty.station import station_from_dict
from inscal.sim.scenarios import build
from inscal.sim.simulate import simulate

STATION = """
[station]
name = "T-2, lab 3"

[inputs.table_angle]
unit = "arcsec"
distribution = "normal"
uncertainty = 2.0
source = "table certificate"

[inputs.table_rate]
unit = "ppm"
distribution = "rectangular"
half_width = 17.32
source = "table data sheet"

[inputs.axis_wobble]
unit = "arcsec"
distribution = "normal"
uncertainty = 1.0
source = "table certificate"

[inputs.axis_nonorthogonality]
unit = "arcsec"
distribution = "normal"
uncertainty = 2.0
source = "table certificate"

[inputs.encoder_resolution]
unit = "arcsec"
distribution = "rectangular"
half_width = 0.18
source = "encoder data sheet"

[inputs.gravity]
value = 9.793788
unit = "m/s^2"
uncertainty_unit = "mGal"
distribution = "normal"
uncertainty = 1.0
source = "relative gravimeter survey tied to the national network"

[inputs.latitude]
value = 30.686
unit = "deg"
uncertainty_unit = "arcsec"
distribution = "normal"
uncertainty = 1.0
source = "GNSS survey of the pier"

[inputs.height]
value = 50.0
unit = "m"
distribution = "normal"
uncertainty = 1.0
source = "GNSS survey of the pier"

[inputs.time_base]
unit = "ppm"
distribution = "rectangular"
half_width = 1.0
source = "acquisition oscillator data sheet"

[inputs.temperature_stability]
unit = "K"
distribution = "arcsine"
half_width = 0.1
source = "chamber controller"
"""
station = station_from_dict(tomllib.loads(STATION))
record = simulate(build("n25"), np.random.default_rng(1)).to_record()
result = calibrate(record, "n25")
budget = calibration_budget(result, station)
for c in budget.components[:6]:
    top = max(c.contributions, key=lambda x: x.contribution)
    print(f"{c.label:22s} u_c {c.u_c:.3g} {c.unit}, k {c.k:.2f}, U {c.U:.3g}; "
          f"largest: {top.input}")
for note in budget.notes:
    print(textwrap.fill("note: " + note, 80, subsequent_indent="  "))

# %%
# The contributions
# -----------------
# Each bar is one parameter component; its segments are the shares of u_c² (GUM: the squared
# contributions add up), so the input that dominates a component is the one to improve. Here the
# table's rate accuracy dominates the gyro scale factors, gravity the accelerometer scale factors,
# the table's angles the misalignments and the accelerometer biases, and the record's own noise
# (the estimator's Type A σ) the gyro biases.
inputs = sorted({x.input for c in budget.components for x in c.contributions})
shares = np.array([[sum(x.share for x in c.contributions if x.input == name)
                    for name in inputs] for c in budget.components])
keep = shares.max(axis=0) > 0.01  # inputs that reach 1 % of some component
fig, ax = plt.subplots(figsize=(9, 7), layout="constrained")
left = np.zeros(len(budget.components))
colors = plt.get_cmap("tab10")
for j, name in enumerate(n for n, k in zip(inputs, keep) if k):
    col = shares[:, inputs.index(name)]
    ax.barh(range(len(col)), col, left=left, color=colors(j), label=name)
    left += col
ax.barh(range(len(left)), 1 - left, left=left, color="0.85", label="others (< 1 %)")
ax.set_yticks(range(len(left)), [c.label for c in budget.components], fontsize=7)
ax.invert_yaxis()
ax.set_xlim(0, 1)
ax.set_xlabel("share of the combined variance u_c²")
fig.legend(fontsize=7, loc="outside lower center", ncol=4)
ax.set_title(f"GUM budget of the N25 calibration at station {budget.station!r}")
