"""The demo report: every method against the truth, S16 Table 2, the Allan deviation and navigation."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from inscal import __version__
from inscal.core import units
from inscal.core.error_model import PARAMETERS, parameter_components
from inscal.io.files import atomic_path
from inscal.report.figures import navigation_figure, new_figure, time_axis
from inscal.report.html import (
    display_unit,
    escape,
    fmt_num,
    html_table,
    png_file_base64,
    z_cell,
)
from inscal.sim.scenarios import S16_TABLE2


def _param_rows(methods: dict[str, dict], truth: dict[str, dict] | None = None):
    """Rows of the estimated-vs-true table.  ``methods``: ``{method: {name: {"value", "sigma",
    "error", "unit"}}}`` (field units, lists per component); the truth is value - error (or
    ``truth[name]["value"]``).  Angles of a parameter with a component of 1 degree or more
    (the mount yaw, ~20 deg) show their values in degrees, their errors in arcsec."""

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
        vunit = "°" if big else display_unit(unit)
        ulabel = f"{vunit} (errors in arcsec)" if big else vunit
        for i, comp in enumerate(comps):
            label = f"{name}.{comp}" if comp else name
            row = [label, ulabel, fmt_num(vconv(tv[i]), 7 if big else 4) if tv is not None and i < tv.size else "—"]
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
                row += [fmt_num(vconv(v[i]), 7 if big else 4) if i < v.size else "—",
                        ("html", "<i>fixed</i>", " class='na'") if fixed else fmt_num(ei), fmt_num(si), z_cell(ei, si)]
            rows.append(row)
    return rows


def _allan_figure(plt, allan_data: dict):
    """The Allan deviation of the gyros and accelerometers with the fitted white-noise lines."""
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
    return fig


def _table2_figure(plt, sysc: dict):
    """S16 Table 2's groups: each filter's mean |error| against the paper's."""
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
        ax.set(title=g.replace("_", " "), ylabel=f"mean |error| [{display_unit(unit)}]")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    handles, labels = [], []
    for ax in np.atleast_1d(axes):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.subplots_adjust(left=0.075, right=0.99, top=0.91, bottom=0.2, wspace=0.5)
    return fig


def _nav_comparison_figure(plt, nav_runs: dict):
    """Every navigation run's horizontal position and heading errors in one figure."""
    fig, ax = plt.subplots(2, 1, figsize=(10, 6.4), sharex=True)
    for i, (label, (nr, _)) in enumerate(nav_runs.items()):
        err = nr.errors
        t, tlab = time_axis(err.time)
        ax[0].plot(t, units.from_si(err.horizontal, "nmi"), color=f"C{i}", lw=1.1, label=label)
        if err.vehicle is not None:
            ax[1].plot(t, units.from_si(err.vehicle[:, 2], "arcsec"), color=f"C{i}", lw=1.0, label=label)
    ax[0].set(ylabel="horizontal position error [nmi]", title="Navigation with each calibration (rotation modulation)")
    ax[1].set(ylabel="yaw (heading) error [arcsec]", xlabel=tlab)
    for x in ax:
        x.grid(True, alpha=0.3)
        x.legend(fontsize=8)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.94, bottom=0.09, hspace=0.08)
    return fig


def _allan_section(allan_data: dict, figs: dict) -> str:
    """The HTML of the noise section: the Allan figure and the fitted white noise against the truth."""
    arw, vrw = np.asarray(allan_data["arw_deg_rth"], float), np.asarray(allan_data["vrw_ug_rthz"], float)
    ta, tv = allan_data.get("true_arw_deg_rth"), allan_data.get("true_vrw_ug_rthz")
    rows = [[f"gyro {c}", "°/√h", fmt_num(arw[k]), fmt_num(ta[k]) if ta is not None else "—",
             fmt_num(100 * (arw[k] / ta[k] - 1), 2) if ta is not None and ta[k] else "—"] for k, c in enumerate("xyz")]
    rows += [[f"accel {c}", "µg/√Hz", fmt_num(vrw[k]), fmt_num(tv[k]) if tv is not None else "—",
              fmt_num(100 * (vrw[k] / tv[k] - 1), 2) if tv is not None and tv[k] else "—"] for k, c in enumerate("xyz")]
    return ("<h2>1. Noise: Allan deviation of the N25 record's first dwell</h2>"
            f"<img alt='Allan deviation' src='data:image/png;base64,{figs['allan']}'/>"
            + html_table(["sensor", "unit", "fitted (white noise)", "true", "difference [%]"], rows))


def _table2_section(sysc: dict, figs: dict) -> list[str]:
    """The HTML of the S16 record's section: the groups against Table 2, the filters' diagnostics, every component."""
    parts = []
    methods = list(sysc)
    rows = []
    for g in S16_TABLE2:
        unit = next((sysc[m]["groups"][g]["unit"] for m in methods if g in sysc[m]["groups"]), "")
        row = [g.replace("_", " "), display_unit(unit), fmt_num(S16_TABLE2[g])]
        for m in methods:
            v = sysc[m]["groups"].get(g)
            if v is None:
                row.append("—")
            elif v["estimated"]:
                ok = v["mean_abs_error"] <= S16_TABLE2[g]
                row.append(("html", fmt_num(v["mean_abs_error"], 3) + (" ✓" if ok else ""), " class='good'" if ok else ""))
            else:
                row.append(("html", f"{fmt_num(v['mean_abs_error'], 3)} <i>(not estimated: the whole error)</i>", " class='na'"))
        rows.append(row)
    lin = []
    for g in ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor", "accel_misalignment"):
        if all(g in sysc[m]["groups"] for m in methods):
            lin.append([g.replace("_", " "), display_unit(sysc[methods[0]]["groups"][g]["unit"]), "—"]
                       + [fmt_num(sysc[m]["groups"][g]["mean_abs_error"], 3) for m in methods])
    diag = [[m, fmt_num(sysc[m]["nis_mean"], 3), str(sysc[m]["passes"]), fmt_num(sysc[m]["elapsed_s"], 3)] for m in methods]
    parts.append("<h2>3. S16 record: systematic calibration against S16 Table 2</h2>"
                 "<p>Mean |error| over each group's estimated components (truth mapped into the filter's "
                 "gyro-defined frame), against the paper's Table 2. A group the filter does not estimate "
                 "keeps its whole error (its mean |true value|).</p>"
                 f"<img alt='S16 Table 2 groups' src='data:image/png;base64,{figs['s16-table2']}'/>"
                 + html_table(["group", "unit", "S16 Table 2"] + [f"{m} mean |error|" for m in methods], rows + lin)
                 + html_table(["filter", "NIS mean (6 expected)", "passes", "time [s]"], diag))
    comp = {m: sysc[m].get("parameters") for m in methods if sysc[m].get("parameters")}
    if comp:
        head = ["parameter", "unit", "true (filter frame)"]
        for m in comp:
            head += ["estimate", "error", "σ", "error/σ"]
        parts.append("<details><summary>every component of the systematic estimates</summary>"
                     + html_table(head, _param_rows(comp), "params", [("", 3)] + [(m, 4) for m in comp]) + "</details>")
    return parts


def _navigation_section(nav: dict, nav_runs: dict, figs: dict) -> list[str]:
    """The HTML of the navigation section: each calibration's errors, the figures."""
    parts = []
    rows = []
    for label, v in nav.items():
        a = v.get("max_attitude_error_arcsec") or {}
        rows.append([label, fmt_num(v.get("max_position_error_m")),
                     fmt_num(units.from_si(v["max_position_error_m"], "nmi")) if v.get("max_position_error_m") is not None else "—",
                     fmt_num(v.get("final_position_error_m")), fmt_num(a.get("roll")), fmt_num(a.get("pitch")), fmt_num(a.get("yaw"))])
    hours = next((v["duration_h"] for v in nav.values() if v.get("duration_h") is not None), None)
    parts.append(f"<h2>4. Navigation: {fmt_num(hours, 3)} h of rotation modulation with each calibration</h2>"
                 "<p>Noise-free N25 IMU on a two-axis turntable (rotation modulation), pure inertial, vertical "
                 "channel held; initialised from the truth.</p>"
                 + html_table(["calibration", "max position error [m]", "[nmi]", "final [m]", "max roll error [arcsec]",
                           "max pitch error [arcsec]", "max yaw error [arcsec]"], rows))
    if "nav-comparison" in figs:
        parts.append(f"<img alt='navigation comparison' src='data:image/png;base64,{figs['nav-comparison']}'/>")
    for label in nav_runs:
        parts.append(f"<h3>{escape(label)}</h3><img alt='navigation {escape(label)}' "
                     f"src='data:image/png;base64,{figs['nav-' + label]}'/>")
    return parts


def demo_report(out_dir, res: dict, nav_runs: dict | None = None, allan_data: dict | None = None,
                overwrite: bool = False) -> dict[str, Path]:
    """Write the demo's report into ``out_dir``: the PNG figures and ``report.html`` (self-contained:
    every figure embedded as a base64 PNG).  ``res``: the demo's result dict (``inscal demo --json``);
    ``nav_runs``: ``{label: (NavResult, gimbal model)}`` of the navigation runs; ``allan_data``:
    the ``inscal allan`` result of the N25 first dwell (with ``true_arw_deg_rth``/``true_vrw_ug_rthz``).
    Returns ``{name: path}`` of the files written."""
    plt = new_figure()
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
        figs[name] = png_file_base64(path)

    # ---- Allan deviation with the fitted white-noise lines
    if allan_data is not None:
        save(_allan_figure(plt, allan_data), "allan")

    # ---- S16 Table 2 groups against the paper
    sysc = steps.get("systematic_s16", {})

    if sysc:
        save(_table2_figure(plt, sysc), "s16-table2")

    # ---- navigation runs
    nav_runs = nav_runs or {}
    if nav_runs:
        save(_nav_comparison_figure(plt, nav_runs), "nav-comparison")
        for label, (nr, gim) in nav_runs.items():
            fig = navigation_figure(nr, f"navigation, {label}: position and attitude errors", gim)
            save(fig, f"nav-{label}")

    # ---- HTML
    parts = [f"<h1>inscal demo report</h1><p class='meta'>inscal {escape(__version__)}, seed {res.get('seed')}, "
             f"{'quick' if res.get('quick') else 'full'} run, {res.get('elapsed_s', float('nan')):.1f} s, "
             f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}; files in {escape(res.get('out', ''))}</p>"]
    parts.append("<p>The demo simulates the S16 (Table 1 path, extended error model) and N25 (twelve "
                 "positions, gimbal non-orthogonality) scenarios, estimates the noise, calibrates with every "
                 "method, compares each estimate with the simulation's truth, and navigates a rotation-modulated "
                 "run with each calibration. Errors are estimate − truth; σ is each method's own 1σ; "
                 "|error/σ| &gt; 3 is shown in red.</p>")
    if allan_data is not None:
        parts.append(_allan_section(allan_data, figs))
    cal = steps.get("calibrate", {})
    if cal:
        head = ["parameter", "unit", "true"]
        for m in cal:
            head += ["estimate", "error", "σ", "error/σ"]
        parts.append("<h2>2. N25 record: estimated against true errors, per method</h2>"
                     "<p>Six-position: the traditional scheme (N25 scheme 2); n25: the proposed method (N25 eq. "
                     "38–44); joint: one fit of every position. Gimbal non-orthogonality true value 20 arcsec.</p>"
                     + html_table(head, _param_rows(cal), "params", [("", 3)] + [(m, 4) for m in cal]))
    if sysc:
        parts += _table2_section(sysc, figs)
    nav = steps.get("navigate", {})
    if nav:
        parts += _navigation_section(nav, nav_runs, figs)
    listed = sorted(p.name for p in out_dir.iterdir() if p.is_file() and p.suffix in (".h5", ".toml", ".png", ".json"))
    listed = sorted(set(listed) | {p.name for p in files.values()} | {"summary.json", "report.html"})
    parts.append("<h2>Files</h2><ul>" + "".join(f"<li>{escape(n)}</li>" for n in listed) + "</ul>")
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
