"""
Noise identification of a static record
=======================================

Simulate 15 minutes of the N25 FOG on a static base with a Gauss–Markov bias on every channel
(0.5 °/h and 50 µg, correlation time 30 s), the record of the guide's "Identifying the noise";
identify each channel's noise model with ``--model auto``, and draw the Allan deviation with its
95 % intervals, the fitted model and each term's part.

The same with commands (``bench.toml`` as on the guide page)::

    inscal simulate bench.toml --out bench.h5 --seed 1
    inscal noise bench.h5 --out noise.toml --plot noise.png
    inscal allan bench.h5
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from inscal import io
from inscal.analysis.noise import identify as idf
from inscal.sim.scenarios import scenario_from_dict
from inscal.sim.simulate import write_simulation

# %%
# The record
# ----------
# A scenario is a dict (or a TOML file) over a built-in one; its ``[noise]`` adds the
# Gauss–Markov biases (stationary σ in deg/h and µg, correlation time in s).
bench = {
    "base": "n25-static",
    "scenario": {"name": "fog-bench", "duration_h": 0.25},
    "noise": {"arw": 0.02, "vrw": 20,
              "gyro_bias_instability": 0.5, "gyro_bias_tau": 30,
              "accel_bias_instability": 50, "accel_bias_tau": 30},
}
scenario = scenario_from_dict(bench)
folder = Path(tempfile.mkdtemp())
n = write_simulation(folder / "bench.h5", scenario, np.random.default_rng(1))
print(f"{n} samples, {n / scenario.rate_hz:g} s at {scenario.rate_hz:g} Hz")

# %%
# Identify
# --------
# :func:`~inscal.analysis.noise.identify.scan_window` reads the window once (the Allan and
# Haar wavelet variances of the six channels); for each channel,
# :func:`~inscal.analysis.noise.identify.identify_curve` chooses the model on the octave scales
# and :func:`~inscal.analysis.noise.identify.channel_summary` gives what ``inscal noise``
# prints, in field units, with the curves drawn below.
win = io.record_window(folder / "bench.h5", 0.0, None)
scan = idf.scan_window(folder / "bench.h5", win)
rng = np.random.default_rng(0)  # the multi-start solver's draws (inscal noise --seed 0)
summaries = []
for c, name in enumerate(idf.CHANNELS):
    sel = idf.identify_curve(idf.octave_curve(scan.sv, c), "auto", rng)
    summaries.append(idf.channel_summary(name, sel, scan.sv, c))
for ch in summaries:
    print(f"{ch['channel']} ({ch['kind']}): {ch['model']}")
    for k, p in ch["parameters"].items():
        interval = f"[{p['lower_95']:.3g}, {p['upper_95']:.3g}]"
        print(f"    {k:10s} {p['value']:<8.4g} {interval:16s} {p['unit']}")

# %%
# The white noise is found on every channel to half a percent (0.02 °/√h and 20 µg/√Hz were
# simulated). The accelerometers' Gauss–Markov biases are found; the gyros' 0.5 °/h at 30 s
# lies barely above the white noise at the longest scales of 15 minutes, where a random walk, a
# flicker floor and a Gauss–Markov bias look alike, and ``auto`` keeps the simpler term (the
# guide page reads its reasons).
fig, axes = plt.subplots(2, 3, figsize=(12, 7), layout="constrained")
for ax, ch in zip(axes.ravel(), summaries):
    cv = ch["curve"]
    tau = np.asarray(cv["tau_s"])
    ax.fill_between(tau, cv["adev_lower_95"], cv["adev_upper_95"], color="0.85",
                    label="95 % interval")
    ax.loglog(tau, cv["adev"], "k.", ms=3, label="Allan deviation")
    ax.loglog(tau, cv["adev_fit"], "r-", lw=1.5, label=f"fit {ch['model']}")
    for term, v in cv["adev_terms"].items():
        ax.loglog(tau, v, "--", lw=0.9, label=term)
    ax.set_xlabel("τ [s]")
    ax.set_ylabel(f"Allan deviation [{cv['unit']}]")
    ax.set_title(f"{ch['channel']} ({ch['kind']}): {ch['model']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
