"""The history figure of a unit (``inscal db history --plot``): every parameter component over time
with its 1 sigma bars and the weighted least-squares drift line and rate of :mod:`inscal.lab.drift`;
flagged components are drawn in red with their flags."""

from __future__ import annotations

import numpy as np

from inscal.lab.drift import History
from inscal.report.figures import hide_unused, new_figure, save_figure

#: panels per row of the figure
COLUMNS = 3


def history_figure(h: History):
    """The figure of a unit's calibration history.

    One panel per parameter component (each on its own scale), the calibrations with their 1 sigma
    bars against months since the first, the drift line and its rate; flagged components in red.

    Parameters
    ----------
    h : History
        The history (:func:`inscal.lab.unit_history`).

    Returns
    -------
    matplotlib.figure.Figure
        One panel a component, in rows of :data:`COLUMNS` (the caller saves and closes it).

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from inscal import lab
    >>> from inscal.report.history import history_figure
    >>> db, ids = lab.example_history("calib.sqlite", (0.010, 0.020, 0.030))  # three six-position results
    >>> fig = history_figure(lab.unit_history(db, "IMU-1"))
    >>> db.close()
    >>> fig.axes[0].get_title().startswith("gyro_bias[x]")
    True
    >>> plt.close(fig)
    """
    plt = new_figure()
    comps = [c for c in h.components if c.n > 0]
    rows = max(1, -(-len(comps) // COLUMNS))
    fig, axes = plt.subplots(rows, COLUMNS, figsize=(11.5, 1.0 + 1.9 * rows), sharex=True, squeeze=False)
    for ax, c in zip(axes.ravel(), comps):
        colour = "tab:red" if c.flags else "tab:blue"
        ax.errorbar(c.months, c.values, yerr=c.sigma, fmt="o", ms=3.5, capsize=2.5, color=colour)
        title = c.label
        if np.isfinite(c.rate):
            w = 1.0 / c.sigma**2
            tbar = float(np.sum(w * c.months) / np.sum(w))
            tt = np.array([c.months[0], c.months[-1]])
            ax.plot(tt, c.mean + c.rate * (tt - tbar), color=colour, lw=1.0, alpha=0.7)
            title += f"\n{c.rate:+.3g} ± {c.rate_sigma:.2g} {c.unit}/month"
        if c.flags:
            title += f" [{', '.join(c.flags)}]"
        ax.set_title(title, fontsize=7.5, color=colour)
        ax.set_ylabel(c.unit, fontsize=7)
        ax.tick_params(labelsize=6.5)
        ax.grid(True, alpha=0.3)
    start = f"{h.dates[0]:%Y-%m-%d}" if h.dates else "the first calibration"
    for j in range(COLUMNS):  # the time axis under the lowest panel of each column
        col = [ax for i, ax in enumerate(axes[:, j]) if i * COLUMNS + j < len(comps)] or [axes[0, j]]
        col[-1].xaxis.set_tick_params(labelbottom=True)
        col[-1].set_xlabel(f"months since {start}", fontsize=7)
    hide_unused(axes, len(comps))
    fig.suptitle(f"{h.serial} ({h.method}): {len(h.ids)} calibrations; 1 sigma bars, weighted least-squares drift "
                 f"(1 month = 365.25/12 days); flags at k = {h.k:g}", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    return fig


def history_plot(path, h: History, overwrite: bool = False) -> None:
    """Write :func:`history_figure` to ``path`` (PNG, PDF or SVG by its suffix; atomic)."""
    plt = new_figure()
    fig = history_figure(h)
    try:
        save_figure(fig, path, overwrite, laid_out=True)
    finally:
        plt.close(fig)
