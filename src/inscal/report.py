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


def _png_base64(fig) -> str:
    import base64
    import io as _io

    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _fmt(v) -> str:
    a = np.atleast_1d(np.asarray(v, dtype=float)).ravel()
    return ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a)


def record_report(path, rec, param_sets: list[tuple[str, object, object, dict]] | None = None,
                  overwrite: bool = False, max_points: int = 20000) -> dict:
    """Write a self-contained HTML report of a record (plots embedded) and return its summary.

    ``param_sets``: ``[(label, ImuErrors, GimbalErrors, metadata)]`` from parameter files; each
    is tabulated in field units with its 1 sigma and, for simulated records, its error.
    """
    import html

    from . import units
    from .analysis.allan import allan
    from .errors import PARAMETERS, errors_to_field
    from .io import atomic_path

    plt = _figure()
    figs = []
    step = max(1, rec.n_samples // max_points)
    t = rec.time[::step]
    dt = 1.0 / rec.rate_hz
    if rec.gimbal is not None:
        fig, ax = plt.subplots(figsize=(10, 3))
        ax.plot(t, np.degrees(rec.gimbal[::step, 0]), label="outer")
        ax.plot(t, np.degrees(rec.gimbal[::step, 1]), label="inner")
        ax.set(xlabel="time [s]", ylabel="gimbal angle [deg]", title="Gimbal angles")
        ax.legend()
        ax.grid(alpha=0.3)
        figs.append(("Gimbal motion", _png_base64(fig)))
        plt.close(fig)
    fig, ax = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    for k, lab in enumerate("xyz"):
        ax[0].plot(t, units.from_si(rec.dtheta[::step, k] / dt, "deg/s"), label=f"gyro {lab}", lw=0.6)
        ax[1].plot(t, rec.dvel[::step, k] / dt / units.G0, label=f"accel {lab}", lw=0.6)
    ax[0].set(ylabel="rate [deg/s]", title="Sensor outputs")
    ax[1].set(xlabel="time [s]", ylabel="specific force [g]")
    for a in ax:
        a.legend(loc="upper right", fontsize=8)
        a.grid(alpha=0.3)
    figs.append(("Sensor outputs", _png_base64(fig)))
    plt.close(fig)
    summary: dict = {"samples": rec.n_samples, "duration_s": rec.duration, "rate_hz": rec.rate_hz,
                     "scenario": rec.scenario, "simulated": rec.truth is not None}
    # Allan deviation of the first dwell (static window at the start), if long enough
    still = np.all(np.abs(np.diff(rec.gimbal, axis=0)) < 1e-9, axis=1) if rec.gimbal is not None else np.ones(rec.n_samples - 1, bool)
    first = int(np.argmin(still)) if not still.all() else still.size
    if first >= 2000:
        g, a = allan(rec.dtheta[:first], rec.rate_hz), allan(rec.dvel[:first], rec.rate_hz)
        fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
        for k, lab in enumerate("xyz"):
            ax[0].loglog(g.taus, units.from_si(g.adev[:, k], "deg/h"), label=lab)
            ax[1].loglog(a.taus, units.from_si(a.adev[:, k], "ug"), label=lab)
        ax[0].set(xlabel="tau [s]", ylabel="ADEV [deg/h]", title=f"Gyro Allan deviation (first {first * dt:.0f} s)")
        ax[1].set(xlabel="tau [s]", ylabel="ADEV [ug]", title="Accelerometer Allan deviation")
        for x in ax:
            x.grid(True, which="both", alpha=0.3)
            x.legend()
        figs.append(("Noise of the first dwell", _png_base64(fig)))
        plt.close(fig)
        summary["arw_deg_rth"] = units.from_si(g.white, "deg/sqrt(h)").tolist()
        summary["vrw_ug_rthz"] = units.from_si(a.white, "ug/sqrt(Hz)").tolist()
    tables = []
    truth = errors_to_field(rec.truth.imu, rec.truth.gimbal) if rec.truth is not None else None
    for label, imu, gim, meta in param_sets or []:
        est = errors_to_field(imu, gim)
        sig = meta.get("sigma", {})
        names = meta.get("estimated") or list(est)
        rows = []
        for name in names:
            unit = PARAMETERS[name][3]
            row = [name, unit, _fmt(est[name]["value"])]
            s = sig.get(name)
            row.append(_fmt(units.from_si(np.asarray(s, dtype=float), unit)) if s is not None else "")
            if truth is not None:
                row.append(_fmt(np.asarray(est[name]["value"]) - np.asarray(truth[name]["value"])))
            rows.append(row)
        tables.append((label, meta.get("method", ""), rows))
    head = ["parameter", "unit", "value", "1σ"] + (["error (estimate − truth)"] if truth is not None else [])
    parts = [f"<h1>inscal report: {html.escape(rec.source or rec.scenario)}</h1>",
             "<p>" + ", ".join(f"{k}: {html.escape(str(v))}" for k, v in summary.items() if not isinstance(v, list)) + "</p>"]
    for title, b64 in figs:
        parts.append(f"<h2>{title}</h2><img src='data:image/png;base64,{b64}'/>")
    for label, method, rows in tables:
        parts.append(f"<h2>Parameters: {html.escape(label)} ({html.escape(method)})</h2><table><tr>"
                     + "".join(f"<th>{h}</th>" for h in head) + "</tr>"
                     + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows) + "</table>")
    doc = ("<!doctype html><html><head><meta charset='utf-8'><title>inscal report</title><style>"
           "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #bbb;padding:3px 8px;font-size:13px}</style></head><body>"
           + "".join(parts) + "</body></html>")
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    summary["figures"] = [f[0] for f in figs]
    summary["parameter_tables"] = [t[0] for t in tables]
    return summary


def convergence_plots(out_dir, result, truth=None, overwrite: bool = False) -> list[Path]:
    """S16 Fig. 4-style convergence plots of a systematic calibration, one PNG per parameter
    group: the filtered estimate (minus the truth when given, else the estimate) of every
    component against time, with its 1-sigma envelope, and the smoothed (final) value.
    Values in the field units of :data:`inscal.errors.PARAMETERS`.  Returns the files written."""
    from . import units
    from .calibrate.result import param_value
    from .errors import PARAMETERS

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
    plt = _figure()
    files, k = [], 0
    for name in h["names"]:
        shape = PARAMETERS[name][4]
        size = int(np.prod(shape)) if shape else 1
        unit = PARAMETERS[name][3]
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


def _time_axis(t_s):
    t = np.asarray(t_s, dtype=float)
    span = float(t[-1] - t[0]) if t.size else 0.0
    if span > 3 * 3600:
        return t / 3600.0, "time [h]"
    if span > 600:
        return t / 60.0, "time [min]"
    return t, "time [s]"


def navigation_figure(res, title: str = "", gimbal_model=None, max_points: int = 4000):
    """Figure of one navigation run (:class:`inscal.navigation.NavResult`): position error East,
    North, Up [m]; the horizontal position error [nmi] (and m); the attitude error roll, pitch,
    yaw [arcsec] when the run has a truth, else the attitude (roll, pitch [deg] and the heading,
    clockwise from North [deg]).  Returns the matplotlib figure (the caller saves and closes it)."""
    from . import units

    plt = _figure()
    err = res.errors
    out = res.output
    step = max(1, out.time.size // max_points)
    t, tlabel = _time_axis(out.time[::step])
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
    fig.tight_layout()
    return fig


def navigation_plot(path, res, title: str = "", gimbal_model=None, overwrite: bool = False) -> None:
    """Write :func:`navigation_figure` to ``path`` (PNG, PDF or SVG by its suffix; atomic)."""
    plt = _figure()
    fig = navigation_figure(res, title, gimbal_model)
    try:
        save_figure(fig, path, overwrite)
    finally:
        plt.close(fig)
