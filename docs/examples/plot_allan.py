"""
Allan deviation of a static record
==================================

Simulate 30 minutes of the N25 IMU on a static base and read its white noise off the Allan
deviation: the angle random walk (ARW) of the gyros and the velocity random walk (VRW) of the
accelerometers, against the values the simulator used.

The same with commands::

    inscal simulate n25-static --out st.h5 --duration-h 0.5 --seed 2
    inscal allan st.h5 --plot allan.png --json
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io
from inscal.analysis.allan import allan
from inscal.core import units
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

scenario = build("n25-static", duration_s=1800.0)
folder = Path(tempfile.mkdtemp())
write_simulation(folder / "st.h5", scenario, np.random.default_rng(2))
record = io.read_record(folder / "st.h5")

# %%
# :func:`inscal.analysis.allan.allan` takes the increments (rad or m/s per sample) and the rate;
# its ``white`` is the white-noise coefficient in SI, converted by :func:`inscal.core.units.from_si`.
gyro = allan(record.dtheta, record.rate_hz)
accel = allan(record.dvel, record.rate_hz)
arw = units.from_si(gyro.white, "deg/sqrt(h)")
vrw = units.from_si(accel.white, "ug/sqrt(Hz)")
print("ARW [deg/sqrt(h)]:", np.round(arw, 4), " simulated:", units.from_si(scenario.noise.arw, "deg/sqrt(h)"))
print("VRW [ug/sqrt(Hz)]:", np.round(vrw, 2), " simulated:", units.from_si(scenario.noise.vrw, "ug/sqrt(Hz)"))

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 4), layout="constrained")
for ax, res, scale, unit, what in ((ax1, gyro, 180 / np.pi * 3600, "deg/h", "gyro"),
                                   (ax2, accel, 1e6 / units.G0, "ug", "accelerometer")):
    for axis in range(3):
        ax.loglog(res.taus, res.adev[:, axis] * scale, label="xyz"[axis])
    ax.set_xlabel("τ [s]")
    ax.set_ylabel(f"Allan deviation [{unit}]")
    ax.set_title(what)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
