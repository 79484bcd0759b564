"""The report of an identified noise model (``inscal report noise.toml``): per channel its terms in IEEE 952-2020
/ 1293-2018 field units (with the 95 % intervals the file carries) and their discrete per-sample forms, and the
model's theoretical Allan deviation with each term's contribution (the exact discrete-time variances of
:mod:`inscal.core.noise_models`), one panel per sensor kind."""

from __future__ import annotations

import html
import math

import numpy as np

from inscal.core import noise_models as nm
from inscal.core import units
from inscal.io.files import atomic_path
from inscal.io.noisefile import CLASSES
from inscal.report.figures import new_figure, png_base64
from inscal.report.html import display_unit, fmt_num, html_table

#: the Allan deviation plot spans tau = 1/rate .. this many seconds (at least 10 decades of the sample interval)
TAU_MAX_S = 1e5


def model_tables(doc: dict) -> list[dict]:
    """Per channel ``{"channel", "kind", "model", "rows": [[term, parameter, value, unit, lower, upper], ...]}`` from
    a noise.toml document (field units, as written)."""
    out = []
    for ch in doc.get("channel", []):
        rows = []
        for t in ch.get("term", []):
            for p in CLASSES[t["type"]].params:
                rows.append([t["type"], p, t[p], t.get(f"{p}_unit", ""), t.get(f"{p}_lower_95"), t.get(f"{p}_upper_95")])
        out.append({"channel": ch["name"], "kind": ch["kind"], "model": ch.get("model", ""), "rows": rows})
    return out


def allan_figure(model: nm.NoiseModel):
    """The figure of the model's Allan deviation: one panel per sensor kind (field units: deg/h, ug), each
    channel's model (solid) and its terms (dashed, the same colour)."""
    plt = new_figure()
    dt = 1.0 / model.rate_hz
    m = np.unique(np.round(np.logspace(0, math.log10(max(TAU_MAX_S / dt, 10.0)), 40)))
    tau = m * dt
    kinds = [k for k in ("gyro", "accel") if any(c.kind == k for c in model.channels)]
    fig, axes = plt.subplots(1, len(kinds), figsize=(6.0 * len(kinds), 4.2), squeeze=False)
    for ax, kind in zip(axes[0], kinds):
        unit = "deg/h" if kind == "gyro" else "ug"
        for i, ch in enumerate(c for c in model.channels if c.kind == kind):
            col = f"C{i}"
            ax.loglog(tau, units.from_si(np.sqrt(ch.avar(m, dt)), unit), "-", color=col, lw=1.5,
                      label=f"{ch.name} {ch.model}")
            for t in ch.terms:
                ax.loglog(tau, units.from_si(np.sqrt(t.avar(m, dt)), unit), "--", color=col, lw=0.7)
        ax.set(xlabel="tau [s]", ylabel=f"Allan deviation [{display_unit(unit)}]",
               title=f"{kind}: model (solid) and its terms (dashed)")
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.12, top=0.9, wspace=0.25)
    return fig


def noise_model_report(path, model: nm.NoiseModel, doc: dict, source: str, overwrite: bool = False) -> dict:
    """Write the HTML report of ``model`` (read from ``doc``, the file ``source``) to ``path`` (atomic); returns
    its summary (the per-channel tables)."""
    plt = new_figure()
    fig = allan_figure(model)
    img = png_base64(fig)
    plt.close(fig)
    tables = model_tables(doc)
    parts = [f"<h1>Noise model {html.escape(source)}</h1>",
             f"<p>Identified at {model.rate_hz:g} Hz; units of IEEE Std 952-2020 (gyros) and 1293-2018 "
             "(accelerometers); 95 % intervals where the file has them.</p>"]
    for t in tables:
        rows = [[r[0], r[1], fmt_num(r[2]), display_unit(r[3]), fmt_num(r[4]), fmt_num(r[5])] for r in t["rows"]]
        parts.append(f"<h2>{html.escape(t['channel'])} ({html.escape(t['kind'])}): {html.escape(t['model'])}</h2>"
                     + html_table(["term", "parameter", "value", "unit", "lower 95 %", "upper 95 %"], rows))
    parts.append(f"<h2>Allan deviation of the model</h2><img src='data:image/png;base64,{img}'>")
    doc_html = ("<!doctype html><html><head><meta charset='utf-8'><title>inscal noise model</title><style>"
                "body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
                "td,th{border:1px solid #bbb;padding:3px 8px;font-size:13px}img{max-width:100%}</style></head><body>"
                + "".join(parts) + "</body></html>")
    with atomic_path(path, overwrite) as tmp:
        tmp.write_text(doc_html, encoding="utf-8")
    return {"noise_model": source, "rate_hz": model.rate_hz, "channels": tables}
