"""
The S16 systematic filter converging on the S16 path
====================================================

Simulate the S16 experiment (the extended error model of S16 §4.1 on the 18-rotation Table 1
path, 1.07 h at 100 Hz) and calibrate it with the 51-state Kalman filter and RTS smoother of S16
§3. The filter sees no encoder angle: every parameter comes from the navigation errors of a
static site. The figure is S16 Fig. 4's: for four groups, the filtered error (estimate − truth)
of each component as the path runs, with its 1σ envelope, and the smoothed error.

The same with commands::

    inscal simulate s16 --out s16.h5 --seed 1
    inscal calibrate s16.h5 --method systematic51 --states 51 --out s16.toml \
        --plots plots/
"""

# %%
# Simulate and calibrate
# ----------------------
# :func:`inscal.calibrate.calibrate` with ``"systematic51"`` keeps S16's fixed 51-state model
# (``states="auto"`` would choose the terms from the record).
import matplotlib.pyplot as plt
import numpy as np

from inscal.calibrate import calibrate
from inscal.sim.scenarios import build
from inscal.sim.simulate import simulate

record = simulate(build("s16"), np.random.default_rng(1)).to_record()
result = calibrate(record, "systematic51")
field = result.to_field(record.truth)
z = np.concatenate([np.ravel(e["error"]) / np.ravel(e["sigma"]) for e in field.values()
                    if np.all(np.isfinite(e["sigma"]))])
rms = np.sqrt(np.mean(z ** 2))
print(f"{record.time.size} samples; {z.size} components, RMS error/σ {rms:.2f}, "
      f"largest |error/σ| {np.abs(z).max():.2f}")
for name in ("gyro_g_sensitivity", "accel_nonlinearity", "accel_lever_arm"):
    e = field[name]
    print(f"{name:20s} mean |error| {np.mean(np.abs(e['error'])):.3g} {e['unit']}")

# %%
# Convergence (S16 Fig. 4)
# ------------------------
# :func:`inscal.report.figures.convergence_plots` writes one figure per parameter group, as
# ``inscal calibrate --plots DIR`` does: the filtered error (estimate − truth) of every component
# against time with its 1σ band (solid), and the smoothed error (dashed). Four of them:
import tempfile
from pathlib import Path

from inscal.report.figures import convergence_plots

folder = Path(tempfile.mkdtemp())
written = convergence_plots(folder, result, record.truth)
files = {f.stem.removeprefix("convergence-"): f for f in written}
print(f"{len(files)} figures drawn, one per parameter group")
fig, axes = plt.subplots(2, 2, figsize=(12, 5.8), layout="constrained")
groups = ("gyro_bias", "gyro_g_sensitivity", "accel_nonlinearity", "accel_lever_arm")
for ax, name in zip(axes.flat, groups):
    ax.imshow(plt.imread(files[name]))
    ax.set_axis_off()

# %%
# Only the smoothed values (dashed) are the result. The forward filter shows when each group becomes
# observable (the steps at the moves that excite it); alone, it ends some components farther from
# the smoothed value than its own band (the accelerometer nonlinearity here), which is what the
# smoother and its iterations are for.
