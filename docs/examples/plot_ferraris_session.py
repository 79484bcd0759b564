"""
A Ferraris session: six faces and three whole turns
===================================================

Simulate a Ferraris session of a MEMS IMU in a box (Ferraris 1995, laid out like imucal's example):
the six faces held 4–7 s, each tilted by 0.3° rms as a box on a table is, then a whole turn about
the vertical on the +x, +y and +z faces between short still poses. Calibrate it with
``--method ferraris`` and draw what the method found: each face it used (labelled), the turns it
integrated (with the angle turned), and the estimates' errors against the truth in units of their σ,
which hold the stated face tilt and turn closure.

The same with commands::

    inscal simulate ferraris-mems --out fe.h5 --seed 1
    inscal calibrate fe.h5 --method ferraris --out fe.toml
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io
from inscal.calibrate import calibrate
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

folder = Path(tempfile.mkdtemp())
write_simulation(folder / "fe.h5", build("ferraris-mems"), np.random.default_rng(1))
record = io.read_record(folder / "fe.h5")
result = calibrate(record, "ferraris")

# %%
# ``diagnostics`` names the pose the method took for each face and the poses at the ends of each turn.
diag = result.diagnostics
poses = {p["pose"]: p for p in diag["still"]}
for face, number in diag["faces"].items():
    pose = poses[number]
    print(f"face {face}: pose {number} ({pose['t0_s']:.1f}-{pose['t1_s']:.1f} s)")
for axis, turn in diag["turns"].items():
    print(f"turn about {axis}: {turn['degrees']:.2f} deg in {turn['seconds']:.2f} s, "
          f"between poses {turn['poses']}")

# %%
# The errors against the truth (:meth:`~inscal.calibrate.result.CalibrationResult.error`, in the frame the
# method reports: the accelerometers' own), over the σ.
names = ("accel_scale_factor", "accel_misalignment", "accel_bias",
         "gyro_scale_factor", "gyro_misalignment", "gyro_bias")
z, labels = [], []
for name in names:
    err = result.error(record.truth, name) / result.sigma[name]
    comps = "xyz" if err.size == 3 else ("xy", "xz", "yx", "yz", "zx", "zy")
    for c, e in zip(comps, err):
        if np.isfinite(e):
            z.append(e)
            short = name.replace("_misalignment", " mis")
            short = short.replace("_scale_factor", " sf")
            labels.append(f"{short}.{c}")
z = np.array(z)
print(f"{z.size} estimated terms, rms error / sigma = {np.sqrt(np.mean(z ** 2)):.2f}")

dt = np.diff(record.time, prepend=record.time[0] - np.median(np.diff(record.time)))
gyro = np.degrees(record.dtheta / dt[:, None])
accel = record.dvel / dt[:, None]
fig, (ax1, ax2, ax3) = plt.subplots(3, 1, figsize=(9, 9), layout="constrained")
for k in range(3):
    ax1.plot(record.time, accel[:, k], lw=0.6, label="xyz"[k])
    ax2.plot(record.time, gyro[:, k], lw=0.6, label="xyz"[k])
for face, number in diag["faces"].items():
    p = poses[number]
    ax1.axvspan(p["t0_s"], p["t1_s"], color="tab:green", alpha=0.2, lw=0)
    ax1.text((p["t0_s"] + p["t1_s"]) / 2, 10.5, face, ha="center", fontsize=9)
for axis, turn in diag["turns"].items():
    a, b = poses[turn["poses"][0]]["t1_s"], poses[turn["poses"][1]]["t0_s"]
    ax2.axvspan(a, b, color="tab:orange", alpha=0.2, lw=0)
    ax2.text((a + b) / 2, 0.04, f"{axis}: {turn['degrees']:.1f}°", ha="center",
             fontsize=8, transform=ax2.get_xaxis_transform(),
             bbox={"fc": "white", "ec": "none", "alpha": 0.8})
ax1.set_ylim(-11.5, 12.5)
ax1.set_ylabel("specific force [m/s²]")
ax1.set_title("the six faces the method used (green)")
ax1.legend(ncol=3, loc="lower left", fontsize=8)
ax2.set_ylabel("rate [deg/s]")
ax2.set_xlabel("time [s]")
ax2.set_title("the three whole turns about the vertical (orange)")
colors = ["tab:blue" if s.startswith("accel") else "tab:purple" for s in labels]
ax3.bar(np.arange(z.size), z, color=colors)
ax3.axhline(1, color="k", ls="--", lw=0.8)
ax3.axhline(-1, color="k", ls="--", lw=0.8)
ax3.set_xticks(np.arange(z.size), labels, rotation=70, fontsize=7)
ax3.set_ylabel("(estimate − truth) / σ")
ax3.set_title("errors over their σ (face tilt 0.3°, turn closure 0.2° in the σ)")
