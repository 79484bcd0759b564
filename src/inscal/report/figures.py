"""Figures: Allan deviation, convergence of the systematic filter, navigation errors (matplotlib,
imported on first use)."""

from __future__ import annotations

import base64
import io as _io
from pathlib import Path

import numpy as np

from inscal.calibrate.result import param_value
from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.io.files import atomic_path


def new_figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def allan_panel(ax, unit: str, title: str) -> None:
    """Label an Allan deviation panel (tau [s] against the deviation in ``unit``), with its grid and legend."""
    ax.set(xlabel="tau [s]", ylabel=f"Allan deviation [{unit}]", title=title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)


def hide_unused(axes, used: int) -> None:
    """Hide the panels of the grid ``axes`` after its first ``used``."""
    for ax in axes.ravel()[used:]:
        ax.set_visible(False)


def save_figure(fig, path, overwrite: bool = False, laid_out: bool = False) -> None:
    """Write ``fig`` to ``path`` (the format by its suffix; atomic), cropped to what it draws, unless it is
    ``laid_out`` already (``tight_layout`` or fixed margins): the crop is a second full drawing."""
    path = Path(path)
    with atomic_path(path, overwrite) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", dpi=120,
                    bbox_inches=None if laid_out else "tight")


def allan_plot(path, taus, gyro_adev_deg_h, accel_adev_ug, overwrite: bool = False) -> None:
    plt = new_figure()
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


def png_base64(fig) -> str:

    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def convergence_plots(out_dir, result, truth=None, overwrite: bool = False) -> list[Path]:
    """S16 Fig. 4-style convergence plots of a systematic calibration, one PNG per parameter
    group: the filtered estimate (minus the truth when given, else the estimate) of every
    component against time, with its 1-sigma envelope, and the smoothed (final) value.
    Values in the field units of :data:`inscal.core.error_model.PARAMETERS`.  Returns the files written."""

    h = result.history
    if h is None:
        raise ValueError(f"method {result.method!r} has no convergence history")
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"plot folder {out_dir} does not exist")
    t = np.asarray(h["time_s"]) / 60.0
    ref = None
    if truth is not None:
        ti, tg = result._truth(truth)
        ref = np.concatenate([np.ravel(param_value(ti, tg, n)) for n in h["names"]])
    plt = new_figure()
    files, k = [], 0
    for name in h["names"]:
        shape = PARAMETERS[name].shape
        size = int(np.prod(shape)) if shape else 1
        unit = PARAMETERS[name].unit
        sl = slice(k, k + size)
        k += size
        sig = np.ravel(result.sigma[name])
        comps = [i for i in range(size) if np.isfinite(sig[i])]
        if not comps:
            continue
        conv = lambda v: units.from_si(np.asarray(v, dtype=float), unit)  # noqa: E731
        est = h["filtered"][:, sl] - (ref[sl] if ref is not None else 0.0)
        fin = h["smoothed"][:, sl] - (ref[sl] if ref is not None else 0.0)
        s = h["filtered_sigma"][:, sl]
        fig, ax = plt.subplots(figsize=(9, 4.2))
        for i in comps:
            line, = ax.plot(t, conv(est[:, i]), lw=1.0, label=f"[{i}]")
            ax.fill_between(t, conv(est[:, i] - s[:, i]), conv(est[:, i] + s[:, i]), color=line.get_color(),
                            alpha=0.12, lw=0)
            ax.plot(t, conv(fin[:, i]), color=line.get_color(), lw=0.8, ls="--")
        span = [conv(fin[-1, i]) for i in comps]
        ss = [conv(h["smoothed_sigma"][-1, sl][i]) for i in comps]
        lo, hi = min(span) - 8 * max(ss), max(span) + 8 * max(ss)
        lo = min(lo, *(conv(est[len(t) // 3:, i]).min() for i in comps))
        hi = max(hi, *(conv(est[len(t) // 3:, i]).max() for i in comps))
        ax.set_ylim(lo, hi)
        what = "error (estimate - truth)" if ref is not None else "estimate"
        ax.set(xlabel="time [min]", ylabel=f"{what} [{unit}]",
               title=f"{result.method}: {name} - filtered +- 1 sigma (solid), smoothed (dashed)")
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=min(len(comps), 9), fontsize=8, loc="upper right")
        path = out_dir / f"convergence-{name}.png"
        save_figure(fig, path, overwrite)
        plt.close(fig)
        files.append(path)
    return files


# ------------------------------------------------------------------------------ navigation
def heading_deg(yaw_rad):
    """Heading (clockwise from North, degrees in [0, 360)) from the code's yaw (counter-clockwise
    from East, radians): ``heading = 90 deg - yaw``, wrapped."""
    return np.mod(90.0 - np.degrees(np.asarray(yaw_rad, dtype=float)), 360.0)


def time_axis(t_s):
    t = np.asarray(t_s, dtype=float)
    span = float(t[-1] - t[0]) if t.size else 0.0
    if span > 3 * 3600:
        return t / 3600.0, "time [h]"
    if span > 600:
        return t / 60.0, "time [min]"
    return t, "time [s]"


def navigation_figure(res, title: str = "", gimbal_model=None, max_points: int = 4000):
    """Figure of one navigation run (:class:`inscal.nav.run.NavResult`): position error East,
    North, Up [m]; the horizontal position error [nmi] (and m); the attitude error roll, pitch,
    yaw [arcsec] when the run has a truth, else the attitude (roll, pitch [deg] and the heading,
    clockwise from North [deg]).  Returns the matplotlib figure (the caller saves and closes it)."""

    plt = new_figure()
    err = res.errors
    out = res.output
    step = max(1, out.time.size // max_points)
    t, tlabel = time_axis(out.time[::step])
    fig, ax = plt.subplots(3, 1, figsize=(10, 8.4), sharex=True)
    if err is not None:
        pos = err.position[::step]
        for k, (lab, c) in enumerate(zip(("East", "North", "Up"), ("C0", "C1", "C2"))):
            ax[0].plot(t, pos[:, k], color=c, lw=1.0, label=lab)
        ax[0].set(ylabel="position error [m]")
        hor = units.from_si(err.horizontal[::step], "nmi")
        ax[1].plot(t, hor, color="C3", lw=1.2, label="horizontal")
        ax[1].set(ylabel="horizontal error [nmi]")
        sec = ax[1].secondary_yaxis("right", functions=(lambda x: x * 1852.0, lambda m: m / 1852.0))
        sec.set_ylabel("[m]")
    if err is not None and err.vehicle is not None:
        att = units.from_si(err.vehicle[::step], "arcsec")
        for k, lab in enumerate(("roll", "pitch", "yaw")):
            ax[2].plot(t, att[:, k], lw=1.0, label=lab)
        ax[2].set(ylabel="attitude error [arcsec]")
    else:
        att = out.vehicle_attitude(gimbal_model)[::step]
        ax[2].plot(t, np.degrees(att[:, 0]), lw=1.0, label="roll")
        ax[2].plot(t, np.degrees(att[:, 1]), lw=1.0, label="pitch")
        ax[2].set(ylabel="roll, pitch [deg]")
        tw = ax[2].twinx()
        tw.plot(t, heading_deg(att[:, 2]), color="C3", lw=1.0, label="heading (cw from North)")
        tw.set_ylabel("heading [deg]")
        tw.legend(loc="upper right", fontsize=8)
    ax[2].set(xlabel=tlabel)
    for a in ax:
        a.grid(True, alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="upper left", fontsize=8, ncol=3)
    if title:
        ax[0].set_title(title)
    # fixed margins (tight_layout measures every text: a third of the drawing time)
    fig.subplots_adjust(left=0.09, right=0.91, top=0.955, bottom=0.065, hspace=0.1)
    return fig


def navigation_plot(path, res, title: str = "", gimbal_model=None, overwrite: bool = False) -> None:
    """Write :func:`navigation_figure` to ``path`` (PNG, PDF or SVG by its suffix; atomic)."""
    plt = new_figure()
    fig = navigation_figure(res, title, gimbal_model)
    try:
        save_figure(fig, path, overwrite, laid_out=True)
    finally:
        plt.close(fig)
