"""
A hand-held session: its still poses and the fitted model's residuals
=====================================================================

Simulate a hand-held session of a MEMS IMU (12 still poses of 4 s joined by 3-s rotations, with
tremor), let the detector find the still poses, and calibrate it with the multi-position model
(Tedaldi 2014, with the Earth rate). The figure is what to look at after such a session: where the
poses were found in the record (kept in green, rejected in red), and the normalised residual of every
pose and every move of the fit, which should scatter about 1 with no pose standing out.

The same with commands::

    inscal simulate handheld-mems --out hh.h5 --seed 1
    inscal calibrate hh.h5 --method multi-position --out mp.toml
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io
from inscal.calibrate import calibrate
from inscal.calibrate.static_detect import detect_still
from inscal.core import units
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

folder = Path(tempfile.mkdtemp())
write_simulation(folder / "hh.h5", build("handheld-mems"), np.random.default_rng(1))
record = io.read_record(folder / "hh.h5")

# %%
# The detector (:func:`inscal.calibrate.static_detect.detect_still`, with the defaults of
# ``--method multi-position``: 2-s poses, 0.25 s settled at each end) decides on every quiet stretch
# and says why.
still = detect_still(record.time, record.dtheta, record.dvel,
                     min_still=2.0, settle=0.25)
for c in still.candidates:
    print(c.describe())

# %%
# The calibration uses the same decisions; its ``fit`` holds the χ² and the residual rows the CLI prints.
result = calibrate(record, "multi-position")
fit = result.diagnostics["fit"]
print(f"fit: chi2 {fit['chi2']:.4g} on {fit['dof']} dof, p = {fit['p_value']:.3g}")
for name in ("gyro_bias", "accel_bias"):
    unit = "deg/h" if name.startswith("gyro") else "ug"
    print(name, np.round(units.from_si(getattr(result.imu, name), unit), 1), "+-",
          np.round(units.from_si(result.sigma[name], unit), 1), unit)

dt = np.diff(record.time, prepend=record.time[0] - np.median(np.diff(record.time)))
gyro = np.degrees(np.linalg.norm(record.dtheta / dt[:, None], axis=1))
accel = record.dvel / dt[:, None]

fig, (ax1, ax2, ax3) = plt.subplots(3, 1, figsize=(9, 8), layout="constrained",
                                    gridspec_kw={"height_ratios": [1, 1, 1.1]})
ax1.plot(record.time, gyro, lw=0.6, color="k")
ax1.set_ylabel("|gyro| [deg/s]")
for k in range(3):
    ax2.plot(record.time, accel[:, k], lw=0.6, label="xyz"[k])
ax2.set_ylabel("specific force [m/s²]")
ax2.set_xlabel("time [s]")
ax2.legend(ncol=3, loc="lower right")
for c in still.candidates:
    for ax in (ax1, ax2):
        color = "tab:green" if c.kept else "tab:red"
        ax.axvspan(c.t0, c.t1, color=color, alpha=0.2, lw=0)
ax1.set_title(f"{len(still.kept)} still poses kept (green), "
              f"{len(still.rejected)} rejected (red)")

rows = fit["residuals"]
poses = [r for r in rows if r["label"].startswith("pose")]
moves = [r for r in rows if r["label"].startswith("move")]
x = np.arange(len(poses))
ax3.bar(x - 0.2, [r["gyro"] for r in poses], 0.4,
        label="pose: gyro (Earth rate + bias)")
ax3.bar(x + 0.2, [r["accel"] for r in poses], 0.4,
        label="pose: accelerometer (|f| = g)")
xm = len(poses) + 1 + np.arange(len(moves))
ax3.bar(xm, [r["gyro"] for r in moves], 0.6, color="tab:purple",
        label="move: gravity direction")
ax3.axhline(1.0, color="k", lw=0.8, ls="--")
ticks = [str(r["window"]) for r in poses]
ticks += [f"{k + 1}→{k + 2}" for k in range(len(moves))]
ax3.set_xticks(np.r_[x, xm], ticks, fontsize=7)
ax3.set_ylabel("normalised residual (RMS)")
ax3.set_title(f"residuals of the fit: χ² {fit['chi2']:.1f} on {fit['dof']} dof, "
              f"p = {fit['p_value']:.2f}")
ax3.legend(fontsize=8, loc="upper right")
