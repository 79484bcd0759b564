"""``inscal observability``: which systematic-filter states a rotation path makes observable,
from the path alone (no data).  See :mod:`inscal.calibrate.observability`."""

from __future__ import annotations

import math

import typer

from .cliutil import CliError, fail, print_json


def run_observability(source: str, states: str = "51", rate_hz: float = 20.0, arw: float | None = None,
                      vrw: float | None = None):
    """The :class:`~inscal.calibrate.observability.ObservabilityReport` of ``source``; ``arw`` in
    deg/sqrt(h), ``vrw`` in ug/sqrt(Hz) (field units, converted here)."""
    from . import units
    from .calibrate.observability import ObservabilityError, observability

    for name, v in (("--rate-hz", rate_hz), ("--arw", arw), ("--vrw", vrw)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise CliError(f"{name} must be a positive number, got {v:g}")
    try:
        return observability(source, states, rate_hz=rate_hz,
                             arw=None if arw is None else units.to_si(arw, "deg/sqrt(h)"),
                             vrw=None if vrw is None else units.to_si(vrw, "ug/sqrt(Hz)"))
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None


def _print_report(rep) -> None:
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from .calibrate.observability import RANK_TOL, THRESHOLDS

    con = Console()
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
    wt = Table(title="weakest directions (right singular vectors, scaled parameters)")
    wt.add_column("σ / σmax", justify="right")
    wt.add_column("dominant combination")
    for d in rep.weakest:
        wt.add_row(f"{d.singular_value:.2e}", escape(d.describe()))
    con.print(wt)
    for n in rep.notes:
        con.print(f"note: {escape(n)}")
    con.print(f"({rep.timing_s['total']:.2f} s)")


def register(app: typer.Typer) -> None:
    @app.command("observability")
    def observability_cmd(
        source: str = typer.Argument(..., metavar="PATH_OR_SCENARIO",
                                     help="built-in scenario (s16, psins19, n25, ...) or path (s16-table1, "
                                          "n25-twelve, ...), a scenario TOML, or a path TOML (a [path] table)"),
        states: str = typer.Option("51", "--states", help="state set: 51 | 30, options ,lever9 ,async ,psins"),
        rate_hz: float = typer.Option(20.0, "--rate-hz", help="rate of the noise-free simulation [Hz]"),
        arw: float = typer.Option(None, "--arw", help="gyro angle random walk [deg/sqrt(h)] (default: the "
                                                      "scenario's, else S16's 5e-5)"),
        vrw: float = typer.Option(None, "--vrw", help="accelerometer velocity random walk [ug/sqrt(Hz)] (default: "
                                                      "the scenario's, else S16's 1)"),
        json_: bool = typer.Option(False, "--json", help="print the results as JSON"),
    ):
        """Observability of the systematic filter's states on a rotation path, without data: posterior /
        prior σ per state and the SVD of the observability matrix."""
        try:
            rep = run_observability(source, states, rate_hz, arw, vrw)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(rep.to_dict())
            return
        _print_report(rep)
