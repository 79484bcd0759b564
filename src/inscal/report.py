"""Plots and reports (matplotlib, Agg backend).  Files are written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, overwrite: bool = False) -> None:
    from .io import atomic_path

    path = Path(path)
    with atomic_path(path, overwrite) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", dpi=120, bbox_inches="tight")


def allan_plot(path, taus, gyro_adev_deg_h, accel_adev_ug, overwrite: bool = False) -> None:
    plt = _figure()
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, lab in enumerate("xyz"):
        ax[0].loglog(taus, np.asarray(gyro_adev_deg_h)[k], label=f"gyro {lab}")
        ax[1].loglog(taus, np.asarray(accel_adev_ug)[k], label=f"accel {lab}")
    ax[0].set(xlabel="tau [s]", ylabel="Allan deviation [deg/h]", title="Gyroscopes")
    ax[1].set(xlabel="tau [s]", ylabel="Allan deviation [ug]", title="Accelerometers")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend()
    save_figure(fig, path, overwrite)
    plt.close(fig)
