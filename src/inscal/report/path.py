"""Report section for a rotation path and its Cramér-Rao bound (path design and the report's path section).

Three panels (:func:`path_figure`), from a path and its :class:`~inscal.plan.bound.Bound`
(computed with its history):

1. gimbal angles (outer, inner) over time [deg];
2. the bound over time per parameter group: the RMS over the group of ``sigma_i(t) / t_i``
   (``t_i`` the targets when given, e.g. the bound of S16's path, else the prior), log scale; the
   filtered covariance after a step is the bound of the experiment cut there (constant
   parameters), so this is what stopping the path at ``t`` would give;
3. the information each move adds: per move (its turn and the dwell after it) and group,
   ``log10(rms before / rms after)`` of the group's bound (decades of reduction), as a heat map.

:func:`move_gains` gives the numbers of panel 3, :func:`write_path_report` writes the PNG and an
HTML fragment (a ``<section>`` with the figure inline and the per-move table) atomically.
"""

from __future__ import annotations

import base64
import html as _html
import io as _io
import math
from pathlib import Path as FsPath

import numpy as np

from inscal.core import units
from inscal.io.files import atomic_path


def _group_index(bound) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for k, g in enumerate(bound.setup.groups):
        out.setdefault(g, []).append(k)
    return out


def group_history(bound, targets: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Times ``[0, t_steps]`` and per group the RMS of ``sigma_i(t) / t_i`` (prior at ``t = 0``);
    ``targets`` default to the prior."""
    tg = bound.prior if targets is None else np.asarray(targets, float)
    s = np.vstack([bound.prior[None, :], bound.sigma_history()]) / tg
    t = np.concatenate([[0.0], bound.t_steps])
    return t, {g: np.sqrt(np.mean(s[:, idx] ** 2, axis=1)) for g, idx in _group_index(bound).items()}


def move_spans(path) -> list[tuple[int, float, float]]:
    """``(move index, start, end)`` [s] of each move, its dwell included (the initial dwell is -1)."""
    seg = path.segments()
    out = []
    for m in np.unique(seg.move_index):
        sel = seg.move_index == m
        out.append((int(m), float(seg.t0[sel].min()), float(seg.t1[sel].max())))
    return sorted(out, key=lambda r: r[1])


def move_gains(bound, path) -> list[dict]:
    """Per move (and the initial dwell): its time span, axis/angle/rate/dwell, and per group the
    bound reduction ``log10(rms(t0) / rms(t1))`` of the group's ``sigma / prior`` across it."""
    t, gh = group_history(bound)
    T = bound.setup.T
    rows = []
    for m, a, b in move_spans(path):
        ia = min(len(t) - 1, int(math.floor(a / T + 1e-9)))
        ib = min(len(t) - 1, int(math.floor(b / T + 1e-9)))
        mv = path.moves[m] if m >= 0 else None
        rows.append({"move": m + 1, "t0_s": a, "t1_s": b,
                     "axis": mv.axis if mv else "initial dwell",
                     "angle_deg": units.from_si(mv.angle, "deg") if mv else 0.0,
                     "rate_dps": units.from_si(mv.rate, "deg/s") if mv else 0.0,
                     "dwell_s": mv.dwell if mv else path.initial_dwell,
                     "gain_decades": {g: float(np.log10(h[ia] / h[ib])) if h[ib] > 0 else math.inf
                                      for g, h in gh.items()}})
    return rows


def path_figure(bound, path, targets: np.ndarray | None = None, title: str = "", target_label: str = "target"):
    """The three-panel figure of a path and its bound (module docstring).

    Parameters
    ----------
    bound : Bound
        The bound of the path, with its history (:func:`inscal.plan.bound.crlb`, ``keep_history``).
    path : RotationPath
        The path.
    targets : numpy.ndarray, optional
        Target sigma per parameter (SI), drawn against the bound.
    title : str
        The figure's title.
    target_label : str
        The targets' legend.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (the caller saves and closes it).

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from inscal.plan.bound import crlb
    >>> from inscal.report.path import path_figure
    >>> from inscal.sim.scenarios import build
    >>> sc = build("n25")
    >>> fig = path_figure(crlb(sc, "30"), sc.path, title="N25 path")
    >>> len(fig.axes) >= 3
    True
    >>> plt.close(fig)
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seg = path.segments()
    tt = np.linspace(0.0, float(seg.t1[-1]), 4000)
    th, _, _ = seg.angles(tt)
    t, gh = group_history(bound, targets)
    gains = move_gains(bound, path)
    groups = list(gh)
    fig, axes = plt.subplots(3, 1, figsize=(11, 11), gridspec_kw={"height_ratios": [1.0, 1.5, 1.3]})
    ax = axes[0]
    ax.plot(tt / 60, np.degrees(th[:, 0]), label="outer")
    ax.plot(tt / 60, np.degrees(th[:, 1]), label="inner")
    for r in gains:
        ax.axvline(r["t0_s"] / 60, color="0.85", lw=0.6, zorder=0)
    ax.set_ylabel("gimbal angle [deg]")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(title or f"path {path.name!r}: {path.duration / 60:.1f} min, {len(path.moves)} moves", fontsize=10)
    ax = axes[1]
    for k, g in enumerate(groups):
        ax.semilogy(t / 60, gh[g], label=g, color=f"C{k % 10}", ls="-" if k < 10 else "--")
    if targets is not None:
        ax.axhline(1.0, color="k", ls=":", lw=1, label=target_label)
    ax.set_ylabel("RMS σ / " + ("target" if targets is not None else "prior"))
    ax.set_xlabel("time [min]")
    ax.legend(fontsize=7, ncol=3, loc="upper right")
    ax.grid(alpha=0.3, which="both")
    ax = axes[2]
    G = np.array([[r["gain_decades"][g] for r in gains] for g in groups])
    G = np.where(np.isfinite(G), G, np.nan)
    im = ax.imshow(G, aspect="auto", cmap="viridis", interpolation="nearest", vmin=0.0)
    ax.set_yticks(range(len(groups)))
    ax.set_yticklabels(groups, fontsize=7)
    lab = ["init" if r["move"] == 0 else f"{r['move']}\n{r['axis'][0]}{r['angle_deg']:+.0f}" for r in gains]
    step = max(1, math.ceil(len(lab) / 24))
    ax.set_xticks(range(0, len(lab), step))
    ax.set_xticklabels(lab[::step], fontsize=6)
    ax.set_xlabel("move (axis, angle [deg]); each with the dwell after it")
    fig.colorbar(im, ax=ax, label="bound reduction [decades]")
    fig.tight_layout()
    return fig


def _table(rows: list[dict], groups: list[str]) -> str:
    esc = _html.escape
    head = "".join(f"<th>{esc(g)}</th>" for g in groups)
    out = ["<table class='path-gains'><thead><tr><th>move</th><th>axis</th><th>angle [deg]</th><th>rate [deg/s]</th>"
           f"<th>dwell [s]</th><th>t [min]</th>{head}</tr></thead><tbody>"]
    for r in rows:
        cells = "".join(f"<td>{r['gain_decades'][g]:.2f}</td>" for g in groups)
        out.append(f"<tr><td>{r['move']}</td><td>{esc(r['axis'])}</td><td>{r['angle_deg']:+.0f}</td>"
                   f"<td>{r['rate_dps']:.2f}</td><td>{r['dwell_s']:.1f}</td>"
                   f"<td>{r['t0_s'] / 60:.1f}-{r['t1_s'] / 60:.1f}</td>{cells}</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def html_fragment(fig, bound, path, title: str = "", summary: str = "") -> str:
    """An HTML ``<section>`` with the figure inline (PNG, base64) and the per-move gains table."""
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    b64 = base64.b64encode(buf.getvalue()).decode("ascii")
    rows = move_gains(bound, path)
    groups = list(dict.fromkeys(bound.setup.groups))
    t = _html.escape(title or f"Path {path.name}")
    return (f"<section class='path-report'>\n<h2>{t}</h2>\n"
            + (f"<p>{_html.escape(summary)}</p>\n" if summary else "")
            + f"<img alt='{t}' src='data:image/png;base64,{b64}'/>\n"
            "<p>Bound reduction per move and group: log10 of the group's RMS bound (σ / prior) before / "
            "after the move and its dwell (decades).</p>\n" + _table(rows, groups) + "\n</section>\n")


def write_path_report(out, bound, path, targets: np.ndarray | None = None, title: str = "", summary: str = "",
                      target_label: str = "target", overwrite: bool = False) -> tuple[FsPath, FsPath]:
    """Write ``out`` (PNG) and the HTML fragment beside it (``.html``), atomically; returns both paths."""
    import matplotlib.pyplot as plt


    png = FsPath(out)
    if png.suffix.lower() != ".png":
        png = png.with_suffix(png.suffix + ".png") if png.suffix else png.with_suffix(".png")
    htm = png.with_suffix(".html")
    fig = path_figure(bound, path, targets, title, target_label)
    try:
        frag = html_fragment(fig, bound, path, title, summary)
        with atomic_path(png, overwrite) as tmp:
            fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
        with atomic_path(htm, overwrite) as tmp:
            tmp.write_text(frag, encoding="utf-8")
    finally:
        plt.close(fig)
    return png, htm
