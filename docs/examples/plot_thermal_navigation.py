"""
Navigation during a warm-up, with and without the thermal model
===============================================================

A navigation-grade IMU warms from 20 °C towards 45 °C after it is switched on (the built-in
``thermal-warmup`` scenario: the ``s16`` IMU with an illustrative thermal model, time constant
20 min, here without noise and for 30 min). Its errors are known exactly at 20 °C; navigating with
those alone leaves every bias and scale-factor change of the warm-up in the solution, while the
thermal model maps each sample back to 20 °C at its own temperature and dT/dt.

The same with commands (a parameter file ``p.toml`` with a ``[thermal]`` table)::

    inscal simulate thermal-warmup --out warm.h5 --seed 1
    inscal navigate warm.h5 --params p.toml --json           # with the thermal model
    inscal navigate warm.h5 --params p.toml --temperature 20  # stays at 20 degC
"""

# %%
# Simulate the warm-up
# --------------------
# :func:`inscal.sim.scenarios.build` gives the scenario; its ``imu`` holds the errors at the thermal
# model's reference temperature and ``thermal`` the model itself.
import matplotlib.pyplot as plt
import numpy as np

from dataclasses import replace

from inscal.core.error_model import ImuNoise
from inscal.nav.run import navigate
from inscal.sim.scenarios import build
from inscal.sim.simulate import simulate

scenario = replace(build("thermal-warmup", duration_s=1800.0), noise=ImuNoise())
sim = simulate(scenario, np.random.default_rng(1))
record = sim.to_record()
temp = record.temperature
t_ref = scenario.thermal.t_ref
print(f"{record.time.size} samples, {record.time[-1] / 60:.0f} min, temperature "
      f"{temp.values.min():.1f} -> {temp.values.max():.1f} degC (T_ref {t_ref:g} degC)")

# %%
# Navigate twice
# --------------
# :func:`inscal.nav.run.navigate` applies the errors at T_ref (``params``) and, when given, the thermal
# model at the record's temperature.
def run(thermal):
    chunks = [(record.time, record.dtheta, record.dvel, record.gimbal)]
    return navigate(chunks, record.rate_hz, record.site, init="truth",
                    scenario=scenario, params=scenario.imu, thermal=thermal,
                    temperature=temp if thermal is not None else None)


runs = {"errors at 20 °C only": run(None),
        "with the thermal model": run(scenario.thermal)}
for label, res in runs.items():
    print(f"{label:24s} max horizontal error {res.errors.horizontal.max():.1f} m")

# %%
# The figure
# ----------
# The horizontal position error of both runs, and the IMU temperature that drives the difference.
fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, layout="constrained",
                               gridspec_kw={"height_ratios": [2, 1]})
for label, res in runs.items():
    err = np.maximum(res.errors.horizontal, 1e-3)
    ax0.semilogy(res.errors.time / 60, err, label=label)
ax0.set_ylabel("horizontal position error [m]")
ax0.legend()
ax0.grid(alpha=0.3, which="both")
ax1.plot(temp.time / 60, temp.values[:, 0], color="tab:red")
ax1.set_ylabel("IMU temperature [°C]")
ax1.set_xlabel("time [min]")
ax1.grid(alpha=0.3)
fig.suptitle("thermal-warmup, no noise: navigation with and without the thermal model")
