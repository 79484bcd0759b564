"""The report of one record: what it holds, its temperature (when it has one), its Allan deviation,
the parameter sets given (each thermal model with its curves), and the path section (gimbal angles
and the Cramer-Rao bound) when it has a path."""

from __future__ import annotations

import html

import numpy as np

from inscal.analysis.allan import allan_of, first_dwell
from inscal.core import units
from inscal.core.error_model import PARAMETERS, errors_to_field
from inscal.io.files import atomic_path
from inscal.plan.bound import evaluate, make_setup
from inscal.plan.rows import BoundError
from inscal.report.figures import new_figure, png_base64
from inscal.report.html import fmt_value
from inscal.report.noise_model import noise_model_section
from inscal.report.path import html_fragment, path_figure
from inscal.report.thermal import STYLE as THERMAL_STYLE
from inscal.report.thermal import params_thermal, temperature_section, thermal_section


def record_report(path, rec, param_sets: list[tuple[str, object, object, dict]] | None = None,
                  overwrite: bool = False, max_points: int = 20000, noise_models: list | None = None) -> dict:
    """Write a self-contained HTML report of a record (plots embedded) and return its summary.

    ``param_sets``: ``[(label, ImuErrors, GimbalErrors, metadata)]`` from parameter files; each
    is tabulated in field units with its 1 sigma and, for simulated records, its error.  A record with
    /temperature gets its temperature and dT/dt (``summary["temperature"]``); a parameter set with a
    thermal model (``metadata["thermal"]``) gets each thermal parameter's curve over its calibrated
    range with its 1-sigma band (:mod:`inscal.report.thermal`; ``summary["thermal"][label]``).
    ``noise_models``: ``[(label, NoiseModel, document)]`` from noise.toml files; each gets its table and its
    Allan-deviation figure over the first dwell's (:mod:`inscal.report.noise_model`; ``summary["noise_model"]``).
    """

    plt = new_figure()
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
        figs.append(("Gimbal motion", png_base64(fig)))
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
    figs.append(("Sensor outputs", png_base64(fig)))
    plt.close(fig)
    summary: dict = {"samples": rec.n_samples, "duration_s": rec.duration, "rate_hz": rec.rate_hz,
                     "scenario": rec.scenario, "simulated": rec.truth is not None}
    # Allan deviation of the first dwell (static window at the start), if long enough
    first = first_dwell(rec.gimbal, rec.n_samples)  # streamed: rec may be an on-disk io.open_record
    measured = {}
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
        figs.append(("Noise of the first dwell", png_base64(fig)))
        plt.close(fig)
        summary["arw_deg_rth"] = units.from_si(g.white, "deg/sqrt(h)").tolist()
        summary["vrw_ug_rthz"] = units.from_si(a.white, "ug/sqrt(Hz)").tolist()
        for k, lab in enumerate("xyz"):
            measured[f"g{lab}"] = (g.taus, g.adev[:, k])
            measured[f"a{lab}"] = (a.taus, a.adev[:, k])
    noise_parts = []
    for label, model, doc in noise_models or []:
        frag, data = noise_model_section(label, model, doc, measured)
        noise_parts.append(frag)
        summary.setdefault("noise_model", {})[label] = data
    temp_section, span = None, None
    if getattr(rec, "temperature", None) is not None:
        temp_section, temp_data = temperature_section(rec.temperature)
        summary["temperature"] = temp_data
        span = temp_data["range_c"]
    path_section = _path_section(rec, summary)
    tables = []
    truth_thermal = None
    if rec.truth is not None and getattr(rec.truth, "thermal", None) is not None:
        truth_thermal = (rec.truth.imu, rec.truth.thermal)
    truth = errors_to_field(rec.truth.imu, rec.truth.gimbal) if rec.truth is not None else None
    for label, imu, gim, meta in param_sets or []:
        est = errors_to_field(imu, gim)
        sig = meta.get("sigma", {})
        names = meta.get("estimated") or list(est)
        rows = []
        for name in names:
            unit = PARAMETERS[name].unit
            row = [name, unit, fmt_value(est[name]["value"])]
            s = sig.get(name)
            row.append(fmt_value(units.from_si(np.asarray(s, dtype=float), unit)) if s is not None else "")
            if truth is not None:
                row.append(fmt_value(np.asarray(est[name]["value"]) - np.asarray(truth[name]["value"])))
            rows.append(row)
        tdata = params_thermal(meta, imu, truth_thermal, span)
        if tdata is not None:
            summary.setdefault("thermal", {})[label] = tdata
        tables.append((label, meta.get("method", ""), rows, tdata))
    head = ["parameter", "unit", "value", "1σ"] + (["error (estimate − truth)"] if truth is not None else [])
    # the record in a few sentences (the same facts as the summary's scalars, read by a person)
    minutes = f" ({rec.duration / 60:.1f} min)" if rec.duration >= 120 else ""
    about = [f"{rec.n_samples:,} samples over {rec.duration:.1f} s{minutes} at {rec.rate_hz:g} Hz."]
    if rec.truth is not None:
        about.append(f"Simulated (scenario {html.escape(rec.scenario or 'unnamed')}): the errors the simulator "
                     "put in are known, so a parameter table (--params) also gives each estimate's error.")
    else:
        about.append("A measured record (not simulated): no truth to compare the estimates with.")
    if "arw_deg_rth" in summary:
        about.append(f"The noise figure: the Allan deviation of the first dwell ({first * dt:.0f} s at rest).")
    else:
        about.append(f"No noise figure: the first dwell ({first * dt:.1f} s) is shorter than the 2000 samples "
                         "an Allan deviation takes.")
    bound = summary.get("path_bound", "")
    if bound == "no rotation path in the record":
        about.append("Path: no rotation path in the record, so no Cramér-Rao bound is drawn (a log imported "
                     "with --path path.toml, or a simulated record, carries its path).")
    elif bound.startswith("not computed"):
        about.append(f"Path: its Cramér-Rao bound was {html.escape(bound)}.")
    elif bound:
        about.append(f"Path: the section below gives the Cramér-Rao bound on it ({html.escape(bound)}).")
    parts = [f"<h1>inscal report: {html.escape(rec.source or rec.scenario)}</h1>", "<p>" + " ".join(about) + "</p>"]
    for title, b64 in figs:
        parts.append(f"<h2>{title}</h2><img src='data:image/png;base64,{b64}'/>")
    parts += noise_parts
    if temp_section:
        parts.append(temp_section)
    if path_section:
        parts.append(path_section)
    for label, method, rows, tdata in tables:
        parts.append(f"<h2>Parameters: {html.escape(label)} ({html.escape(method)})</h2><table><tr>"
                     + "".join(f"<th>{h}</th>" for h in head) + "</tr>"
                     + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows) + "</table>")
        if tdata is not None:
            parts.append(thermal_section(label, tdata))
    doc = ("<!doctype html><html><head><meta charset='utf-8'><title>inscal report</title><style>"
           "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
           "td,th{border:1px solid #bbb;padding:3px 8px;font-size:13px}section.path-report{overflow-x:auto}"
           + THERMAL_STYLE + "</style></head><body>"
           + "".join(parts) + "</body></html>")
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(doc, encoding="utf-8")
    summary["figures"] = [f[0] for f in figs] + (["Temperature"] if temp_section else [])
    summary["parameter_tables"] = [t[0] for t in tables]
    summary["noise_models"] = [label for label, _, _ in noise_models or []]
    return summary


def _path_section(rec, summary: dict) -> str | None:
    """The record's rotation path: gimbal angles, the Cramér-Rao bound of the
    51-state systematic model over time and what each move makes observable
    (:mod:`inscal.report.path`), at the record's site, with the noise read from its first dwell
    (else its simulation truth, else S16's).  None (and a note in ``summary``) without a path."""
    path = getattr(rec, "path", None)
    if path is None:
        summary["path_bound"] = "no rotation path in the record"
        return None

    arw = summary.get("arw_deg_rth")
    vrw = summary.get("vrw_ug_rthz")
    if arw is not None and vrw is not None and min(arw) > 0 and min(vrw) > 0:

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
    plt = new_figure()
    fig = path_figure(bound, path, title=f"Path {path.name}: what it observes (51-state model)")
    try:
        frag = html_fragment(fig, bound, path, title=f"Path {path.name}: what each move makes observable",
                             summary=f"Cramér-Rao bound of the 51-state systematic model on this path at the record's "
                                     f"site, with {src}; the bound is what a calibration of this record can reach.")
    finally:
        plt.close(fig)
    summary["path_bound"] = "51-state model, " + src
    return frag
