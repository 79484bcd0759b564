"""The report of an identified noise model, alone (``inscal report noise.toml``) or as a section of a record's
report (``inscal report RECORD --noise noise.toml``): the model (``noise.toml``, :mod:`inscal.io.noisefile`) per
channel, as a table of its processes in IEEE Std 952-2020 / 1293-2018 units (continuous form, the 95 % interval
of the identification when the file has it, and the per-sample form at the model's rate) and a figure of the
model's exact Allan deviation with each process's contribution, over the record's own Allan deviation of its
first dwell where the report has one.

The curves are the processes' exact discrete-time Allan variances (:mod:`inscal.core.noise_models`), not their
asymptotic slopes, at the model's rate; a record's curve at another rate is drawn on its own scales."""

from __future__ import annotations

import math

import numpy as np

from inscal.core import noise_models as nm
from inscal.core import units
from inscal.io.files import atomic_path
from inscal.io.noisefile import intervals_of
from inscal.report.figures import allan_panel, hide_unused, new_figure, png_base64
from inscal.report.html import display_unit, escape, fmt_num, html_table

#: field unit of a channel's Allan deviation (a rate: the gyro's in deg/h, the accelerometer's in ug)
ADEV_UNIT = {"gyro": "deg/h", "accel": "ug"}
#: field unit of each per-sample form (:func:`inscal.core.noise_models.discrete`), per sensor kind
DISCRETE_UNIT = {
    "gyro": {"phase_std": "arcsec", "std": "deg/h", "step_std": "deg/h", "step": "deg/h", "innovation_std": "deg/h",
             "b": "deg/h", "phi": "", "nu0": ""},
    "accel": {"phase_std": "ug*s", "std": "ug", "step_std": "ug", "step": "ug", "innovation_std": "ug", "b": "ug",
              "phi": "", "nu0": ""},
}
#: what each per-sample form is
DISCRETE_WHAT = {"phase_std": "phase error std", "std": "std per sample", "step_std": "random-walk step std",
                 "step": "ramp step per sample", "innovation_std": "AR(1) innovation std", "phi": "AR(1) phi",
                 "b": "B", "nu0": "cut-off [cycles/sample]"}
#: the Allan-deviation grid of the figure: points per decade, and the longest tau [s] without a record curve
POINTS_PER_DECADE = 12
TAU_MAX_S = 1e4


def model_rows(model: nm.NoiseModel, doc: dict) -> tuple[list[list[str]], list[dict]]:
    """The table rows (channel, model, process, parameter, value, unit, 95 % interval, per-sample form) and the
    same numbers for the JSON, one entry per channel."""
    dt = 1.0 / model.rate_hz
    iv = intervals_of(doc)
    rows, data = [], []
    for ch in model.channels:
        fu = nm.FIELD_UNITS[ch.kind]
        terms = []
        for i, t in enumerate(ch.terms):
            disc = nm.discrete(t, dt)
            disc_field = {k: (float(units.from_si(v, DISCRETE_UNIT[ch.kind][k])) if DISCRETE_UNIT[ch.kind][k] else
                              float(v)) for k, v in disc.items()}
            disc_text = "; ".join(f"{DISCRETE_WHAT[k]} {fmt_num(v)} {DISCRETE_UNIT[ch.kind][k]}".rstrip()
                                  for k, v in disc_field.items())
            params = {}
            for j, p in enumerate(t.params):
                value = float(units.from_si(float(getattr(t, p)), fu[p]))
                lo_hi = iv.get(ch.name, {}).get(i, {}).get(p)
                params[p] = {"value": value, "unit": fu[p],
                             "interval_95": None if lo_hi is None else [float(lo_hi[0]), float(lo_hi[1])]}
                rows.append([ch.name if i == 0 and j == 0 else "", ch.model if i == 0 and j == 0 else "",
                             t.code if j == 0 else "", p, fmt_num(value), display_unit(fu[p]),
                             "—" if lo_hi is None else f"{fmt_num(lo_hi[0])} .. {fmt_num(lo_hi[1])}",
                             disc_text if j == 0 else ""])
            terms.append({"type": t.code, "params": params, "per_sample": disc_field})
        data.append({"channel": ch.name, "kind": ch.kind, "model": ch.model, "terms": terms})
    return rows, data


def model_figure(model: nm.NoiseModel, measured: dict | None = None):
    """The figure: per channel the model's exact Allan deviation (field units), each process dashed, and the
    record's own curve (``measured[channel] = (tau [s], adev [SI])``) as points where given."""
    plt = new_figure()
    k = len(model.channels)
    cols = min(3, k)
    rows = int(math.ceil(k / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.6 * rows), squeeze=False)
    dt = 1.0 / model.rate_hz
    for ax, ch in zip(axes.ravel(), model.channels):
        unit = ADEV_UNIT[ch.kind]
        got = (measured or {}).get(ch.name)
        tmax = max(TAU_MAX_S, float(np.max(got[0])) if got is not None else 0.0)
        m = np.unique(np.round(np.logspace(0, math.log10(tmax / dt), POINTS_PER_DECADE * 8)).astype(np.int64))
        tau = m * dt
        if got is not None:
            ax.loglog(got[0], units.from_si(np.asarray(got[1]), unit), "k.", ms=3, label="record (first dwell)")
        ax.loglog(tau, units.from_si(np.sqrt(ch.avar(m, dt)), unit), "r-", lw=1.5, label=f"model {ch.model}")
        for t in ch.terms:
            ax.loglog(tau, units.from_si(np.sqrt(np.maximum(t.avar(m, dt), 0.0)), unit), "--", lw=0.8, label=t.code)
        allan_panel(ax, unit, f"{ch.name} ({ch.kind})")
    hide_unused(axes, k)
    fig.tight_layout()
    return fig


def noise_model_section(label: str, model: nm.NoiseModel, doc: dict, measured: dict | None = None) -> tuple[str, dict]:
    """The HTML section of one noise model and its JSON summary (field units; the figure embedded)."""
    rows, data = model_rows(model, doc)
    fig = model_figure(model, measured)
    try:
        b64 = png_base64(fig)
    finally:
        new_figure().close(fig)
    head = ["channel", "model", "process", "parameter", "value", "unit", "95 % interval", f"per sample at "
            f"{fmt_num(model.rate_hz)} Hz"]
    html = (f"<h2>Noise model: {escape(label)}</h2><p>Identified at {fmt_num(model.rate_hz)} Hz; IEEE Std 952-2020 "
            "(gyro) and 1293-2018 (accelerometer) units; a Gauss-Markov process as its sigma and correlation time. "
            "The curves are the processes' exact Allan deviations"
            + (", the points the record's own of its first dwell" if measured else "") + ".</p>"
            + html_table(head, rows) + f"<img src='data:image/png;base64,{b64}'/>")
    return html, {"rate_hz": float(model.rate_hz), "channels": data, "meta": doc.get("meta", {})}


def noise_model_report(path, model: nm.NoiseModel, doc: dict, source: str, overwrite: bool = False) -> dict:
    """Write the HTML report of ``model`` alone (read from ``doc``, the file ``source``) to ``path`` (atomic):
    its section (:func:`noise_model_section`) with no record's curve; returns its summary."""
    section, data = noise_model_section(source, model, doc)
    page = ("<!doctype html><html><head><meta charset='utf-8'><title>inscal noise model</title><style>"
            "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
            "td,th{border:1px solid #bbb;padding:3px 8px;font-size:13px}img{max-width:100%}</style></head><body>"
            f"<h1>inscal noise model: {escape(source)}</h1>" + section + "</body></html>")
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return {"noise_model": source} | data
