"""
N25 calibration of a simulated turntable record
===============================================

Simulate the N25 turntable experiment (twelve positions and clockwise/counter-clockwise rate tests
of a FOG-grade IMU, dθ = 20″, 0.69 h at 100 Hz), calibrate it with the N25 method (scheme 1) and
compare every estimate with the true error the simulator put in, in units of its own 1σ.

The same with commands::

    inscal simulate n25 --out n25.h5 --seed 1
    inscal calibrate n25.h5 --method n25 --out n25.toml --json
"""

# %%
# Simulate
# --------
# :func:`inscal.sim.scenarios.build` gives the built-in scenario, and
# :func:`inscal.sim.simulate.write_simulation` writes its record chunk by chunk into an HDF5 file,
# every random draw from the generator passed in.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io
from inscal.calibrate import calibrate
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

scenario = build("n25")
folder = Path(tempfile.mkdtemp())
n = write_simulation(folder / "n25.h5", scenario, np.random.default_rng(1))
record = io.read_record(folder / "n25.h5")
print(f"{n} samples at {record.rate_hz:g} Hz, {record.time[-1] / 3600:.2f} h")

# %%
# Calibrate
# ---------
# :func:`inscal.calibrate.calibrate` runs any method on a record; the result holds the estimates in
# SI and :meth:`~inscal.calibrate.result.CalibrationResult.to_field` gives them in field units with
# their 1σ and, given the truth, their errors.
result = calibrate(record, "n25")
field = result.to_field(record.truth)
for name, entry in field.items():
    values = ", ".join(f"{v:.4g}" for v in entry["value"])
    sigmas = ", ".join(f"{s:.2g}" for s in entry["sigma"])
    print(f"{name:24s} [{values}] ± [{sigmas}] {entry['unit']}")

# %%
# Error against 1σ
# ----------------
# A σ that covers the error gives normalised errors of about ±1 (and a few beyond ±2 among many
# components).
labels, z = [], []
for name, entry in field.items():
    for k, (e, s) in enumerate(zip(entry["error"], entry["sigma"])):
        if np.isfinite(s) and s > 0:
            labels.append(f"{name} {k}" if len(entry["error"]) > 1 else name)
            z.append(e / s)
fig, ax = plt.subplots(figsize=(8, 6), layout="constrained")
ax.barh(range(len(z)), z, color=["tab:blue" if abs(v) <= 2 else "tab:red" for v in z])
ax.set_yticks(range(len(z)), labels, fontsize=7)
ax.axvline(-2, color="grey", ls=":")
ax.axvline(2, color="grey", ls=":")
ax.set_xlabel("(estimate − truth) / σ")
ax.set_title("N25 calibration of the simulated n25 record (seed 1)")
ax.invert_yaxis()
rms = np.sqrt(np.mean(np.square(z)))
print(f"RMS normalised error {rms:.2f} over {len(z)} components")
