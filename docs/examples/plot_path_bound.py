"""
A rotation path and its bound
=============================

What a path can observe is known before the turntable turns: the Cramér-Rao bound of every
parameter of the S16 51-state model, from the path's kinematics and the IMU's noise alone
(:func:`inscal.plan.bound.crlb`). The figure is the one ``inscal design --plot`` and
``inscal report`` draw for a path: the gimbal angles, each Table 2 group's bound against its prior
as the path runs, and how much each move lowers each group's bound.

The same with commands::

    inscal observability s16 --states 51 --crlb
    inscal design --minutes 20 --candidates 32 --scheduler none --out p20.toml --plot p20.html
"""

# %%
# The bound of the S16 Table 1 path
# ---------------------------------
# :func:`inscal.plan.observability.load_source` reads a built-in scenario, a scenario TOML or a bare
# path; :func:`~inscal.plan.bound.crlb` returns the bound and its history over the path.
import numpy as np

from inscal.plan.bound import crlb
from inscal.plan.observability import load_source
from inscal.report.path import path_figure

scenario, _, _ = load_source("s16")
bound = crlb("s16", "51")
path = scenario.path
print(f"path {path.name!r}: {path.duration / 60:.1f} min, {len(path.moves)} moves")
for row in bound.table():
    if row["group"] in ("gyro_bias", "accel_bias", "gyro_g_sensitivity"):
        print(f"{row['label']:24s} {row['bound']:9.3g} {row['unit']:8s}"
              f" (prior {row['prior']:.3g})")

# %%
# The figure
# ----------
# Top: the outer and inner gimbal angles. Middle: each group's RMS bound over its prior as time
# goes on; a group falls when a move makes it observable (the g-sensitivity is seen only through
# heading drift, so its bound keeps falling slowly). Bottom: the decades each move takes off each
# group's bound.
fig = path_figure(bound, path)
