"""
Monte Carlo: are the reported σ right?
======================================

A σ is only useful if it is the spread the estimate really has. Simulate the N25 experiment 200
times with different noise (seeds 0–199; the same IMU, the record at 10 Hz to keep the example
short: the window means and their σ depend on the noise densities, not on the rate), calibrate each
record by the N25 method, and compare the spread of the estimates with the σ the method reports.
The σ (a numerical Jacobian through the estimator, most of a calibration's time) are computed on
the first 3 runs and averaged; they change little between runs, since they follow the noise each
record measures.
``inscal montecarlo`` runs such studies at scale (seeded, resumable, on Dask); the guide's Monte
Carlo page lists them.

The same with commands (the N25 schemes' study, 2 runs)::

    inscal montecarlo n25-schemes --runs 2 --no-dask --out mc-schemes
"""

# %%
# Two hundred calibrations
# ------------------------
# Every random draw comes from a generator seeded with the run's number.
import matplotlib.pyplot as plt
import numpy as np

from inscal.calibrate import calibrate
from inscal.sim.scenarios import build
from inscal.sim.simulate import simulate

scenario = build("n25", rate_hz=10.0)
RUNS, WITH_SIGMA = 200, 3
errors, sigmas = {}, {}
for seed in range(RUNS):
    record = simulate(scenario, np.random.default_rng(seed)).to_record()
    result = calibrate(record, "n25", uncertainty=seed < WITH_SIGMA)
    field = result.to_field(record.truth)
    for name, e in field.items():
        errors.setdefault(name, []).append(np.ravel(e["error"]))
        if seed < WITH_SIGMA:
            sigmas.setdefault(name, []).append(np.ravel(e["sigma"]))
units_of = {name: e["unit"] for name, e in field.items()}
sigma = {name: np.mean(s, axis=0) for name, s in sigmas.items()}
for name in ("gimbal_nonorthogonality", "gyro_bias", "accel_bias"):
    spread = np.std(errors[name], axis=0, ddof=1)
    reported = sigma[name]
    print(f"{name:24s} spread {np.array2string(spread, precision=3)} reported σ "
          f"{np.array2string(reported, precision=3)} {units_of[name]}")

# %%
# Histograms against the reported σ
# ---------------------------------
# Four components' errors (estimate − truth) over the 200 runs, with the normal density of the
# mean reported σ: the histograms should fill the curves. The last panel pools every component's
# error/σ against the standard normal.
picks = [("gimbal_nonorthogonality", 0), ("gyro_bias", 2), ("accel_scale_factor", 0),
         ("gyro_misalignment", 1)]
fig, axes = plt.subplots(1, 5, figsize=(14, 3.2), layout="constrained")
for ax, (name, i) in zip(axes, picks):
    e = np.array(errors[name])[:, i]
    s = float(sigma[name][i])
    x = np.linspace(-4 * s, 4 * s, 200)
    ax.hist(e, bins=20, range=(-4 * s, 4 * s), density=True, alpha=0.6)
    ax.plot(x, np.exp(-0.5 * (x / s) ** 2) / (s * np.sqrt(2 * np.pi)), color="k")
    spread = np.std(e, ddof=1)
    title = f"{name}[{i}]\nσ {s:.3g}, spread {spread:.3g} {units_of[name]}"
    ax.set_title(title, fontsize=8)
    ax.set_yticks([])
z = np.concatenate([(np.array(errors[n]) / sigma[n]).ravel() for n in errors
                    if np.all(np.isfinite(sigma[n]))])
x = np.linspace(-4, 4, 200)
axes[-1].hist(z, bins=40, range=(-4, 4), density=True, color="tab:green", alpha=0.6)
axes[-1].plot(x, np.exp(-0.5 * x ** 2) / np.sqrt(2 * np.pi), color="k")
rms = np.sqrt(np.mean(z ** 2))
axes[-1].set_title(f"all components: error/σ\nRMS {rms:.2f} over {z.size}", fontsize=8)
axes[-1].set_yticks([])
print(f"pooled error/σ: RMS {np.sqrt(np.mean(z ** 2)):.3f}, "
      f"{np.mean(np.abs(z) > 2) * 100:.1f} % beyond 2 (4.6 % for a normal)")
