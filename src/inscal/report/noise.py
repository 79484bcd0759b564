"""The noise identification figure: per channel, the Allan deviation with its 95 % intervals, the
fitted model and each process's contribution (field units), one panel per channel."""

from __future__ import annotations

import math

import numpy as np

from inscal.report.figures import allan_panel, hide_unused, new_figure, save_figure


def noise_plot(path, channels: list[dict], overwrite: bool = False) -> None:
    """``channels``: the per-channel dicts of :func:`inscal.analysis.noise.identify.channel_summary`."""
    plt = new_figure()
    k = len(channels)
    cols = min(3, k)
    rows = int(math.ceil(k / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.8 * rows), squeeze=False)
    for ax, ch in zip(axes.ravel(), channels):
        c = ch["curve"]
        tau, ad = np.asarray(c["tau_s"]), np.asarray(c["adev"])
        ax.fill_between(tau, c["adev_lower_95"], c["adev_upper_95"], color="0.8", label="95 % interval")
        ax.loglog(tau, ad, "k.", ms=3, label="Allan deviation")
        ax.loglog(tau, c["adev_fit"], "r-", lw=1.5, label=f"fit {ch['model']}")
        for name, v in c["adev_terms"].items():
            ax.loglog(tau, v, "--", lw=0.8, label=name)
        top = float(np.max(ad)) * 3
        ax.set_ylim(float(np.min(c["adev_lower_95"])) / 3, top)
        allan_panel(ax, c["unit"], f"{ch['channel']} ({ch['kind']})")
    hide_unused(axes, k)
    fig.tight_layout()
    save_figure(fig, path, overwrite, laid_out=True)
    plt.close(fig)
