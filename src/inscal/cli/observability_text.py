"""The printed outputs of ``inscal observability``: the observability table, the Cramér-Rao bound and the budget
a path promises, as Rich tables on standard output (the whole width in a file or a pipe)."""

from __future__ import annotations

import os

#: width of the observability table when the output is no terminal (thermal group names and units are long)
WIDE = 120


def temperature_line(t: dict) -> str:
    """The line of the thermal states: the temperature span and rate of the path, and the priors' span."""
    return (f"temperature: {t['t_min']:.4g} .. {t['t_max']:.4g} degC, up to {t['rate_max_c_per_min']:.3g} degC/min "
            f"({t['input']}); thermal coefficients about T_ref {t['t_ref']:g} degC, each prior spread over the span "
            f"{t['span']:.4g} degC")


def print_crlb(source: str, b) -> None:
    """The Cramér-Rao bound ``b`` of ``source``: a table per parameter group (prior, bound, ratio), then the
    noise, site and filter rate it assumes."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    con = Console()
    d = b.to_dict()
    tab = Table(title=f"Cramér-Rao bound of {source} (path {b.path_name!r}, {b.duration_s:.0f} s), "
                      f"{b.setup.states.n_states}-state model ({d['states']})", box=box.SIMPLE_HEAD, pad_edge=False)
    for col in ("parameter", "unit", "prior 1σ", "bound 1σ", "ratio"):
        tab.add_column(col, justify="left" if col in ("parameter", "unit") else "right", no_wrap=True)
    rms = b.group_rms()
    current = None
    for r in d["parameters"]:
        if r["group"] != current:
            current = r["group"]
            tab.add_row(f"[bold]{current}[/bold]", r["unit"], f"{r['prior']:.4g}", f"RMS {rms[current]:.3g}", "")
        tab.add_row(f"  {r['label'][len(current):].strip('[]') or current}", "", "", f"{r['bound']:.3g}",
                    f"{r['ratio']:.2g}")
    con.print(tab)
    n = d["noise"]
    con.print("ratio = bound / prior 1σ")
    arw = ", ".join(f"{x:.3g}" for x in sorted(set(n["arw_deg_sqrt_h"])))
    vrw = ", ".join(f"{x:.3g}" for x in sorted(set(n["vrw_ug_sqrt_hz"])))
    site = d["site"]
    con.print(f"bound = posterior 1σ of the linear-Gaussian error-state model (smoothed = final filtered for "
              f"constants); site {site['latitude_deg']:.4g} N {site['longitude_deg']:.4g} E "
              f"{site['height_m']:.4g} m; ARW {arw} deg/√h, VRW {vrw} µg/√Hz"
              + ("; bias instability as process noise" if n["bias"] else "")
              + f"; {b.steps} steps at {d['filter_rate_hz']:g} Hz ({b.seconds:.3f} s)")
    if "temperature" in d:
        con.print(temperature_line(d["temperature"]))


def print_budget(source: str, b, bud, full: bool, what: str | None = None, doc: dict | None = None) -> None:
    """The budget the path promises: one line per component (or its table with ``full``), then the inputs by how
    many components they dominate."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from inscal.uncertainty.before_run import dominant_inputs
    from inscal.report.budget import INPUT_TITLES, budget_lines

    con = Console()
    if not con.is_terminal and "COLUMNS" not in os.environ:
        con = Console(width=WIDE + 40)
    if b is None:
        con.print(f"Uncertainty budget of {escape(source)} before the run: {escape(what)}")
    else:
        con.print(f"Uncertainty budget of {escape(source)} before the run (path {escape(b.path_name)!r}, "
                  f"{b.duration_s:.0f} s, {b.setup.states.n_states}-state filter, {b.steps} steps at "
                  f"{1.0 / b.setup.T:g} Hz, {b.seconds:.3f} s)")
    lines = budget_lines(doc or bud.to_dict(), full=full)
    notes = [x for x in lines if x.startswith("  note: ")]
    for x in lines:
        if not x.startswith("  note: "):
            con.print(escape(x), highlight=False)
    tab = Table(title="which inputs dominate (share of u_c²)")
    for col in ("input", "largest in", "largest share", "median share"):
        tab.add_column(col, justify="left" if col == "input" else "right")
    for r in dominant_inputs(bud):
        tab.add_row(escape(INPUT_TITLES.get(r["input"], r["input"])), f"{r['n_largest']} of {len(bud.components)}",
                    f"{r['max_share'] * 100:.1f} %", f"{r['median_share'] * 100:.1f} %")
    con.print(tab)
    for x in notes:
        con.print(escape(x.strip()), highlight=False)


def print_report(rep) -> None:
    """The observability report ``rep``: a table per state group with the verdicts, the observability matrix's
    rank and singular values, the weakest directions and the notes."""
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from inscal.plan.observability import RANK_TOL, THRESHOLDS

    con = Console()
    if not con.is_terminal and "COLUMNS" not in os.environ:  # a file or a pipe: the whole table, not 80 columns of it
        con = Console(width=WIDE)
    noise = rep.noise
    arw = ", ".join(f"{x:.3g}" for x in sorted(set(noise["arw_deg_sqrt_h"])))
    vrw = ", ".join(f"{x:.3g}" for x in sorted(set(noise["vrw_ug_sqrt_hz"])))
    site = rep.site
    tab = Table(title=f"Observability of {rep.source} ({rep.kind} {rep.path_name!r}, {rep.duration_s:.0f} s), "
                      f"{rep.n_states}-state filter ({rep.state_spec})", box=box.SIMPLE_HEAD)
    for col, just in (("state", "left"), ("prior 1σ", "right"), ("posterior 1σ", "right"), ("ratio", "right"),
                      ("verdict", "left")):
        tab.add_column(col, justify=just, no_wrap=True, min_width=13 if col == "verdict" else None)
    style = {"well observed": "green", "observed": "green", "weak": "yellow", "unobservable": "red"}
    groups = rep.groups()
    current = None
    for s in rep.states:
        if s.group != current:
            current = s.group
            g = groups[current]
            tab.add_row(f"[bold]{current}[/bold]", f"{s.prior:.4g} {s.unit}", "worst:", f"[bold]{g['max_ratio']:.3g}[/bold]",
                        f"[bold {style[g['verdict']]}]{g['verdict']}[/]")
        tab.add_row(f"  {s.component or s.group}", "", f"{s.posterior:.3g}", f"{s.ratio:.3g}",
                    f"[{style[s.verdict]}]{s.verdict}[/]")
    con.print(tab)
    lim = ", ".join(f"{n} < {v:g}" for n, v in THRESHOLDS)
    con.print(f"ratio = posterior / prior 1σ; {lim}, else unobservable.  Site {site['latitude_deg']:.4g} N "
              f"{site['longitude_deg']:.4g} E {site['height_m']:.4g} m; ARW {arw} deg/√h, VRW {vrw} µg/√Hz "
              f"({noise['source']}); {rep.steps} filter steps at {rep.filter_rate_hz:g} Hz from a noise-free "
              f"{rep.rate_hz:g} Hz simulation.")
    sv = rep.singular_values
    con.print(f"\n[bold]Observability matrix[/bold] (whitened, states scaled by their prior σ; parameter block after "
              f"projecting out the initial navigation state): rank {rep.rank} of {rep.n_params} at tolerance "
              f"{RANK_TOL:g} x largest (full state: {rep.full_rank} of {rep.n_states}); singular values / largest, "
              f"smallest 10: " + " ".join(f"{x:.1e}" for x in sv[-10:]))
    if rep.thermal:
        print_partners(con, rep)
    wt = Table(title="weakest directions (right singular vectors, scaled parameters)")
    wt.add_column("σ / σmax", justify="right")
    wt.add_column("dominant combination")
    for d in rep.weakest:
        wt.add_row(f"{d.singular_value:.2e}", escape(d.describe()))
    con.print(wt)
    for n in rep.notes:
        con.print(f"note: {escape(n)}")
    con.print(f"({rep.timing_s['total']:.2f} s)")


def print_partners(con, rep) -> None:
    """Per thermal coefficient: the state it is most correlated with a posteriori."""
    from rich.markup import escape
    from rich.table import Table

    con.print(temperature_line(rep.thermal))
    tab = Table(title="thermal coefficients: the state each is most correlated with (posterior)")
    for col in ("coefficient", "most correlated with", "correlation"):
        tab.add_column(col, justify="right" if col == "correlation" else "left", no_wrap=True)
    for lab, p in rep.thermal["partners"].items():
        tab.add_row(escape(lab), escape(p["with"]), f"{p['correlation']:+.3f}")
    con.print(tab)
