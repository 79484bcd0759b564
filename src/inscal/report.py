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
    from .analysis.allan import allan_of, first_dwell
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
    first = first_dwell(rec.gimbal, rec.n_samples)  # streamed: rec may be an on-disk io.open_record
    if first >= 2000:
        g, a = allan_of(rec.dtheta, first, rec.rate_hz), allan_of(rec.dvel, first, rec.rate_hz)
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
    path_section = _path_section(rec, summary)
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
    if path_section:
        parts.append(path_section)
    for label, method, rows in tables:
        parts.append(f"<h2>Parameters: {html.escape(label)} ({html.escape(method)})</h2><table><tr>"
                     + "".join(f"<th>{h}</th>" for h in head) + "</tr>"
                     + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows) + "</table>")
    doc = ("<!doctype html><html><head><meta charset='utf-8'><title>inscal report</title><style>"
           "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #bbb;padding:3px 8px;font-size:13px}section.path-report{overflow-x:auto}</style></head><body>"
           + "".join(parts) + "</body></html>")
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    summary["figures"] = [f[0] for f in figs]
    summary["parameter_tables"] = [t[0] for t in tables]
    return summary


def _path_section(rec, summary: dict) -> str | None:
    """The record's rotation path (issue 10 item 4): gimbal angles, the Cramér-Rao bound of the
    51-state systematic model over time and what each move makes observable
    (:mod:`inscal.report_path`), at the record's site, with the noise read from its first dwell
    (else its simulation truth, else S16's).  None (and a note in ``summary``) without a path."""
    path = getattr(rec, "path", None)
    if path is None:
        summary["path_bound"] = "no rotation path in the record"
        return None
    from .calibrate.crlb import BoundError, evaluate, make_setup
    from .report_path import html_fragment, path_figure

    arw = summary.get("arw_deg_rth")
    vrw = summary.get("vrw_ug_rthz")
    if arw is not None and vrw is not None and min(arw) > 0 and min(vrw) > 0:
        from . import units

        arw_si, vrw_si, src = units.to_si(np.asarray(arw), "deg/sqrt(h)"), units.to_si(np.asarray(vrw), "ug/sqrt(Hz)"), \
            "the first dwell's white noise"
    elif rec.truth is not None and not rec.truth.noise.is_zero:
        arw_si, vrw_si, src = rec.truth.noise.arw, rec.truth.noise.vrw, "the simulation's noise"
    else:
        arw_si = vrw_si = None
        src = "S16's noise (ARW 5e-5 deg/sqrt(h), VRW 1 ug/sqrt(Hz))"
    gim = rec.truth.gimbal if rec.truth is not None else None
    try:
        setup = make_setup("51", rec.site, gim, arw_si, vrw_si)
        bound = evaluate(setup, path)
    except (BoundError, ValueError) as exc:
        summary["path_bound"] = f"not computed: {exc}"
        return None
    plt = _figure()
    fig = path_figure(bound, path, title=f"Path {path.name}: what it observes (51-state model)")
    try:
        frag = html_fragment(fig, bound, path, title=f"Path {path.name}: what each move makes observable",
                             summary=f"Cramér-Rao bound of the 51-state systematic model on this path at the record's "
                                     f"site, with {src}; the bound is what a calibration of this record can reach.")
    finally:
        plt.close(fig)
    summary["path_bound"] = "51-state model, " + src
    return frag


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
    # fixed margins (tight_layout measures every text: a third of the drawing time)
    fig.subplots_adjust(left=0.09, right=0.91, top=0.955, bottom=0.065, hspace=0.1)
    return fig


def navigation_plot(path, res, title: str = "", gimbal_model=None, overwrite: bool = False) -> None:
    """Write :func:`navigation_figure` to ``path`` (PNG, PDF or SVG by its suffix; atomic)."""
    plt = _figure()
    fig = navigation_figure(res, title, gimbal_model)
    try:
        save_figure(fig, path, overwrite)
    finally:
        plt.close(fig)


# ------------------------------------------------------------------------------ demo report
#: display spellings of the field units (the files keep the ASCII ones)
DISPLAY_UNIT = {"deg/h": "°/h", "ug": "µg", "ug/g^2": "µg/g²", "deg/h/g": "°/h/g", "deg/sqrt(h)": "°/√h",
                "ug/sqrt(Hz)": "µg/√Hz", "arcsec": "arcsec", "ppm": "ppm", "cm": "cm", "ms": "ms", "deg": "°"}


def _u(unit: str) -> str:
    return DISPLAY_UNIT.get(unit, unit)


def _num(x, digits: int = 4) -> str:
    """A number for a table: ``digits`` significant digits, no exponent between 1e-4 and 10**digits."""
    if x is None:
        return "—"
    x = float(x)
    if not np.isfinite(x):
        return "—"
    if x == 0:
        return "0"
    a = abs(x)
    if a >= 10 ** digits:
        return f"{x:.0f}"
    if a >= 1e-4:
        s = f"{x:.{digits}g}"
        return s if "e" not in s else f"{x:.0f}"
    return f"{x:.{digits - 1}e}"


def _esc(s) -> str:
    import html

    return html.escape(str(s))


def _png_file_b64(path) -> str:
    import base64

    return base64.b64encode(Path(path).read_bytes()).decode("ascii")


def _table(head: list[str], rows: list[list[str]], cls: str = "", head2: list[tuple[str, int]] | None = None) -> str:
    """An HTML table; cells are escaped unless given as ``("html", text)``."""
    def cell(c, tag="td"):
        if isinstance(c, tuple):
            kind, text = c[0], c[1]
            attrs = c[2] if len(c) > 2 else ""
            return f"<{tag}{attrs}>{text if kind == 'html' else _esc(text)}</{tag}>"
        return f"<{tag}>{_esc(c)}</{tag}>"

    h = ""
    if head2:
        h += "<tr>" + "".join(f"<th colspan='{n}'>{_esc(t)}</th>" for t, n in head2) + "</tr>"
    h += "<tr>" + "".join(cell(c, "th") for c in head) + "</tr>"
    body = "".join("<tr>" + "".join(cell(c) for c in r) + "</tr>" for r in rows)
    return f"<table class='{cls}'>{h}{body}</table>"


def _z_cell(err, sig):
    if err is None or sig is None or not np.isfinite(err) or not np.isfinite(sig) or sig <= 0:
        return "—"
    z = err / sig
    return ("html", _num(z, 2), " class='bad'" if abs(z) > 3 else "")


def _param_rows(methods: dict[str, dict], truth: dict[str, dict] | None = None):
    """Rows of the estimated-vs-true table.  ``methods``: ``{method: {name: {"value", "sigma",
    "error", "unit"}}}`` (field units, lists per component); the truth is value - error (or
    ``truth[name]["value"]``).  Angles of a parameter with a component of 1 degree or more
    (the mount yaw, ~20 deg) show their values in degrees, their errors in arcsec."""
    from .analysis.experiments import parameter_components
    from .errors import PARAMETERS

    names = [n for n in PARAMETERS if any(n in m for m in methods.values())]
    rows = []
    for name in names:
        comps = parameter_components(name)
        unit = next(m[name]["unit"] for m in methods.values() if name in m)
        tv = None
        if truth is not None and name in truth:
            tv = np.ravel(np.asarray(truth[name]["value"], float))
        else:
            for m in methods.values():
                p = m.get(name)
                if p is not None and p.get("error") is not None:
                    tv = np.ravel(np.asarray(p["value"], float)) - np.ravel(np.asarray(p["error"], float))
                    break
        vals = [np.ravel(np.asarray(m[name]["value"], float)) for m in methods.values() if name in m]
        big = unit == "arcsec" and max(np.nanmax(np.abs(v)) for v in vals + ([tv] if tv is not None else [])) >= 3600.0
        vconv = (lambda v: v / 3600.0) if big else (lambda v: v)
        vunit = "°" if big else _u(unit)
        ulabel = f"{vunit} (errors in arcsec)" if big else vunit
        for i, comp in enumerate(comps):
            label = f"{name}.{comp}" if comp else name
            row = [label, ulabel, _num(vconv(tv[i]), 7 if big else 4) if tv is not None and i < tv.size else "—"]
            for m in methods.values():
                p = m.get(name)
                if p is None:
                    row += [("html", "<i>not estimated</i>", " class='na'"), "—", "—", "—"]
                    continue
                v = np.ravel(np.asarray(p["value"], float))
                e = None if p.get("error") is None else np.ravel(np.asarray(p["error"], float))
                s = None if p.get("sigma") is None else np.ravel(np.asarray(p["sigma"], float))
                ei = None if e is None or i >= e.size else float(e[i])
                si = None if s is None or i >= s.size else float(s[i])
                if si is not None and not np.isfinite(si):
                    si = None
                if ei is not None and not np.isfinite(ei):
                    ei = None
                # a component the method fixes (by its frame definition or model): no error, no sigma
                fixed = e is not None and ei is None and si is None
                row += [_num(vconv(v[i]), 7 if big else 4) if i < v.size else "—",
                        ("html", "<i>fixed</i>", " class='na'") if fixed else _num(ei), _num(si), _z_cell(ei, si)]
            rows.append(row)
    return rows


def demo_report(out_dir, res: dict, nav_runs: dict | None = None, allan_data: dict | None = None,
                overwrite: bool = False) -> dict[str, Path]:
    """Write the demo's report into ``out_dir``: the PNG figures and ``report.html`` (self-contained:
    every figure embedded as a base64 PNG).  ``res``: the demo's result dict (``inscal demo --json``);
    ``nav_runs``: ``{label: (NavResult, gimbal model)}`` of the navigation runs; ``allan_data``:
    the ``inscal allan`` result of the N25 first dwell (with ``true_arw_deg_rth``/``true_vrw_ug_rthz``).
    Returns ``{name: path}`` of the files written."""
    from datetime import datetime, timezone

    from . import __version__, units
    from .io import atomic_path

    plt = _figure()
    out_dir = Path(out_dir)
    steps = res.get("steps", {})
    files: dict[str, Path] = {}
    figs: dict[str, str] = {}

    def save(fig, name):
        # laid out by tight_layout already: no bbox_inches="tight" (a second full draw), fast zlib level
        path = out_dir / f"{name}.png"
        try:
            with atomic_path(path, overwrite) as tmp:
                fig.savefig(tmp, format="png", dpi=100, pil_kwargs={"compress_level": 2})
        finally:
            plt.close(fig)
        files[name] = path
        figs[name] = _png_file_b64(path)

    # ---- Allan deviation with the fitted white-noise lines
    if allan_data is not None:
        taus = np.asarray(allan_data["taus_s"], float)
        g = np.asarray(allan_data["gyro_adev_deg_h"], float)
        a = np.asarray(allan_data["accel_adev_ug"], float)
        arw, vrw = np.asarray(allan_data["arw_deg_rth"], float), np.asarray(allan_data["vrw_ug_rthz"], float)
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
        for k, lab in enumerate("xyz"):
            ax[0].loglog(taus, g[k], color=f"C{k}", lw=1.2, label=f"gyro {lab}")
            ax[0].loglog(taus, units.from_si(units.to_si(arw[k], "deg/sqrt(h)") / np.sqrt(taus), "deg/h"),
                         color=f"C{k}", lw=0.8, ls="--", label=f"ARW fit {arw[k]:.4f} °/√h")
            ax[1].loglog(taus, a[k], color=f"C{k}", lw=1.2, label=f"accel {lab}")
            ax[1].loglog(taus, units.from_si(units.to_si(vrw[k], "ug/sqrt(Hz)") / np.sqrt(taus), "ug"),
                         color=f"C{k}", lw=0.8, ls="--", label=f"VRW fit {vrw[k]:.1f} µg/√Hz")
        win = allan_data.get("window_s")
        ax[0].set(xlabel="τ [s]", ylabel="Allan deviation [°/h]",
                  title="Gyroscopes" + (f" (N25 first dwell, {win[1] - win[0]:.0f} s)" if win else ""))
        ax[1].set(xlabel="τ [s]", ylabel="Allan deviation [µg]", title="Accelerometers")
        for x in ax:
            x.grid(True, which="both", alpha=0.3)
            x.legend(fontsize=7, ncol=2)
        fig.subplots_adjust(left=0.07, right=0.985, top=0.92, bottom=0.12, wspace=0.2)
        save(fig, "allan")

    # ---- S16 Table 2 groups against the paper
    sysc = steps.get("systematic_s16", {})
    from .analysis.experiments import S16_TABLE2

    if sysc:
        methods = list(sysc)
        fig, axes = plt.subplots(1, len(S16_TABLE2), figsize=(3.1 * len(S16_TABLE2), 3.6))
        for ax, g in zip(np.atleast_1d(axes), S16_TABLE2):
            for i, m in enumerate(methods):
                v = sysc[m]["groups"].get(g)
                if v is None:
                    continue
                ax.bar(i, v["mean_abs_error"], 0.6, color=f"C{i}", hatch=None if v["estimated"] else "//",
                       edgecolor="k" if not v["estimated"] else None, label=m + ("" if v["estimated"] else " (not estimated)"))
            ax.axhline(S16_TABLE2[g], color="r", ls="--", lw=1.3, label="S16 Table 2")
            unit = next((sysc[m]["groups"][g]["unit"] for m in methods if g in sysc[m]["groups"]), "")
            ax.set_yscale("log")
            ax.set_xticks(range(len(methods)), [m.replace("systematic", "") + "-state" for m in methods])
            ax.set(title=g.replace("_", " "), ylabel=f"mean |error| [{_u(unit)}]")
            ax.grid(True, axis="y", which="both", alpha=0.3)
        handles, labels = [], []
        for ax in np.atleast_1d(axes):
            for h, lab in zip(*ax.get_legend_handles_labels()):
                if lab not in labels:
                    handles.append(h)
                    labels.append(lab)
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
        fig.subplots_adjust(left=0.075, right=0.99, top=0.91, bottom=0.2, wspace=0.5)
        save(fig, "s16-table2")

    # ---- navigation runs
    nav_runs = nav_runs or {}
    if nav_runs:
        fig, ax = plt.subplots(2, 1, figsize=(10, 6.4), sharex=True)
        for i, (label, (nr, _)) in enumerate(nav_runs.items()):
            err = nr.errors
            t, tlab = _time_axis(err.time)
            ax[0].plot(t, units.from_si(err.horizontal, "nmi"), color=f"C{i}", lw=1.1, label=label)
            if err.vehicle is not None:
                ax[1].plot(t, units.from_si(err.vehicle[:, 2], "arcsec"), color=f"C{i}", lw=1.0, label=label)
        ax[0].set(ylabel="horizontal position error [nmi]", title="Navigation with each calibration (rotation modulation)")
        ax[1].set(ylabel="yaw (heading) error [arcsec]", xlabel=tlab)
        for x in ax:
            x.grid(True, alpha=0.3)
            x.legend(fontsize=8)
        fig.subplots_adjust(left=0.09, right=0.98, top=0.94, bottom=0.09, hspace=0.08)
        save(fig, "nav-comparison")
        for label, (nr, gim) in nav_runs.items():
            fig = navigation_figure(nr, f"navigation, {label}: position and attitude errors", gim)
            save(fig, f"nav-{label}")

    # ---- HTML
    parts = [f"<h1>inscal demo report</h1><p class='meta'>inscal {_esc(__version__)}, seed {res.get('seed')}, "
             f"{'quick' if res.get('quick') else 'full'} run, {res.get('elapsed_s', float('nan')):.1f} s, "
             f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}; files in {_esc(res.get('out', ''))}</p>"]
    parts.append("<p>The demo simulates the S16 (Table 1 path, extended error model) and N25 (twelve "
                 "positions, gimbal non-orthogonality) scenarios, estimates the noise, calibrates with every "
                 "method, compares each estimate with the simulation's truth, and navigates a rotation-modulated "
                 "run with each calibration. Errors are estimate − truth; σ is each method's own 1σ; "
                 "|error/σ| &gt; 3 is shown in red.</p>")
    if allan_data is not None:
        ta, tv = allan_data.get("true_arw_deg_rth"), allan_data.get("true_vrw_ug_rthz")
        rows = [[f"gyro {c}", "°/√h", _num(arw[k]), _num(ta[k]) if ta is not None else "—",
                 _num(100 * (arw[k] / ta[k] - 1), 2) if ta is not None and ta[k] else "—"] for k, c in enumerate("xyz")]
        rows += [[f"accel {c}", "µg/√Hz", _num(vrw[k]), _num(tv[k]) if tv is not None else "—",
                  _num(100 * (vrw[k] / tv[k] - 1), 2) if tv is not None and tv[k] else "—"] for k, c in enumerate("xyz")]
        parts.append("<h2>1. Noise: Allan deviation of the N25 record's first dwell</h2>"
                     f"<img alt='Allan deviation' src='data:image/png;base64,{figs['allan']}'/>"
                     + _table(["sensor", "unit", "fitted (white noise)", "true", "difference [%]"], rows))
    cal = steps.get("calibrate", {})
    if cal:
        head = ["parameter", "unit", "true"]
        for m in cal:
            head += ["estimate", "error", "σ", "error/σ"]
        parts.append("<h2>2. N25 record: estimated against true errors, per method</h2>"
                     "<p>Six-position: the traditional scheme (N25 scheme 2); n25: the proposed method (N25 eq. "
                     "38–44); joint: one fit of every position. Gimbal non-orthogonality true value 20 arcsec.</p>"
                     + _table(head, _param_rows(cal), "params", [("", 3)] + [(m, 4) for m in cal]))
    if sysc:
        methods = list(sysc)
        rows = []
        for g in S16_TABLE2:
            unit = next((sysc[m]["groups"][g]["unit"] for m in methods if g in sysc[m]["groups"]), "")
            row = [g.replace("_", " "), _u(unit), _num(S16_TABLE2[g])]
            for m in methods:
                v = sysc[m]["groups"].get(g)
                if v is None:
                    row.append("—")
                elif v["estimated"]:
                    ok = v["mean_abs_error"] <= S16_TABLE2[g]
                    row.append(("html", _num(v["mean_abs_error"], 3) + (" ✓" if ok else ""), " class='good'" if ok else ""))
                else:
                    row.append(("html", f"{_num(v['mean_abs_error'], 3)} <i>(not estimated: the whole error)</i>", " class='na'"))
            rows.append(row)
        lin = []
        for g in ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor", "accel_misalignment"):
            if all(g in sysc[m]["groups"] for m in methods):
                lin.append([g.replace("_", " "), _u(sysc[methods[0]]["groups"][g]["unit"]), "—"]
                           + [_num(sysc[m]["groups"][g]["mean_abs_error"], 3) for m in methods])
        diag = [[m, _num(sysc[m]["nis_mean"], 3), str(sysc[m]["passes"]), _num(sysc[m]["elapsed_s"], 3)] for m in methods]
        parts.append("<h2>3. S16 record: systematic calibration against S16 Table 2</h2>"
                     "<p>Mean |error| over each group's estimated components (truth mapped into the filter's "
                     "gyro-defined frame), against the paper's Table 2. A group the filter does not estimate "
                     "keeps its whole error (its mean |true value|).</p>"
                     f"<img alt='S16 Table 2 groups' src='data:image/png;base64,{figs['s16-table2']}'/>"
                     + _table(["group", "unit", "S16 Table 2"] + [f"{m} mean |error|" for m in methods], rows + lin)
                     + _table(["filter", "NIS mean (6 expected)", "passes", "time [s]"], diag))
        comp = {m: sysc[m].get("parameters") for m in methods if sysc[m].get("parameters")}
        if comp:
            head = ["parameter", "unit", "true (filter frame)"]
            for m in comp:
                head += ["estimate", "error", "σ", "error/σ"]
            parts.append("<details><summary>every component of the systematic estimates</summary>"
                         + _table(head, _param_rows(comp), "params", [("", 3)] + [(m, 4) for m in comp]) + "</details>")
    nav = steps.get("navigate", {})
    if nav:
        rows = []
        for label, v in nav.items():
            a = v.get("max_attitude_error_arcsec") or {}
            rows.append([label, _num(v.get("max_position_error_m")),
                         _num(units.from_si(v["max_position_error_m"], "nmi")) if v.get("max_position_error_m") is not None else "—",
                         _num(v.get("final_position_error_m")), _num(a.get("roll")), _num(a.get("pitch")), _num(a.get("yaw"))])
        hours = next((v["duration_h"] for v in nav.values() if v.get("duration_h") is not None), None)
        parts.append(f"<h2>4. Navigation: {_num(hours, 3)} h of rotation modulation with each calibration</h2>"
                     "<p>Noise-free N25 IMU on a two-axis turntable (rotation modulation), pure inertial, vertical "
                     "channel held; initialised from the truth.</p>"
                     + _table(["calibration", "max position error [m]", "[nmi]", "final [m]", "max roll error [arcsec]",
                               "max pitch error [arcsec]", "max yaw error [arcsec]"], rows))
        if "nav-comparison" in figs:
            parts.append(f"<img alt='navigation comparison' src='data:image/png;base64,{figs['nav-comparison']}'/>")
        for label in nav_runs:
            parts.append(f"<h3>{_esc(label)}</h3><img alt='navigation {_esc(label)}' "
                         f"src='data:image/png;base64,{figs['nav-' + label]}'/>")
    listed = sorted(p.name for p in out_dir.iterdir() if p.is_file() and p.suffix in (".h5", ".toml", ".png", ".json"))
    listed = sorted(set(listed) | {p.name for p in files.values()} | {"summary.json", "report.html"})
    parts.append("<h2>Files</h2><ul>" + "".join(f"<li>{_esc(n)}</li>" for n in listed) + "</ul>")
    doc = ("<!doctype html><html lang='en'><head><meta charset='utf-8'><title>inscal demo report</title><style>"
           "body{font-family:sans-serif;max-width:1250px;margin:auto;padding:0 12px;color:#222}"
           "table{border-collapse:collapse;margin:8px 0 18px}td,th{border:1px solid #bbb;padding:2px 7px;font-size:12.5px}"
           "td{text-align:right;font-variant-numeric:tabular-nums}td:first-child{text-align:left;white-space:nowrap}"
           "th{background:#eef}.bad{color:#b00;font-weight:bold}.good{color:#060}.na{color:#777;text-align:center}"
           "img{max-width:100%;display:block;margin:8px 0}.meta{color:#555}h2{margin-top:28px;border-bottom:1px solid #ccc}"
           "</style></head><body>" + "".join(parts) + "</body></html>")
    path = out_dir / "report.html"
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    files["report.html"] = path
    return files
