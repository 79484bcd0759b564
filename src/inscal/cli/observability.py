"""``inscal observability``: which systematic-filter states a rotation path makes observable,
from the path alone (no data).  See :mod:`inscal.plan.observability`."""

from __future__ import annotations

import math
import os
from pathlib import Path

import typer

from inscal.cli.common import CliError, fail, print_json, short
from inscal.cli.limits import check_count, check_mc_trials, check_memory, human_seconds

#: width of the observability table when the output is no terminal (thermal group names and units are long)
WIDE = 120


def run_observability(source: str, states: str = "51", rate_hz: float = 20.0, arw: float | None = None,
                      vrw: float | None = None, t_ref: float | None = None):
    """The :class:`~inscal.plan.observability.ObservabilityReport` of ``source``; ``arw`` in
    deg/sqrt(h), ``vrw`` in ug/sqrt(Hz) (field units, converted here); ``t_ref`` [degC] the reference
    temperature of thermal states."""
    from inscal.calibrate.systematic.states import StateSet
    from inscal.calibrate.windows import CalibrationError
    from inscal.core import units
    from inscal.plan.observability import (
        MAX_SAMPLES,
        ObservabilityError,
        load_source,
        observability,
        observability_bytes,
    )

    for name, v in (("--rate-hz", rate_hz), ("--arw", arw), ("--vrw", vrw)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise CliError(f"{name} must be a positive number, got {v:g}")
    try:  # the size first: the simulation is held in memory, and the filter's per-step stores
        sc, _, label = load_source(source)
        st = StateSet.parse(states)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None
    except CalibrationError:
        st = None  # observability() names the bad state set
    _check_t_ref(t_ref, st)
    if st is not None:
        dur = sc.path.duration
        what = f"--rate-hz {rate_hz:g} over the {dur:.4g} s path of {short(label, 60)} ({dur * rate_hz:.3g} samples)"
        hint = "lower --rate-hz (the default 20 Hz is enough for the filter) or take a shorter path"
        check_memory(observability_bytes(dur * rate_hz, dur, st), what, hint)
        check_count(dur * rate_hz, MAX_SAMPLES, what, hint)
    try:
        return observability(source, states, rate_hz=rate_hz,
                             arw=None if arw is None else units.to_si(arw, "deg/sqrt(h)"),
                             vrw=None if vrw is None else units.to_si(vrw, "ug/sqrt(Hz)"), t_ref=t_ref)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None


def run_crlb(source: str, states: str = "51", arw: float | None = None, vrw: float | None = None,
             filter_rate_hz: float = 1.0, gyro_bi: float | None = None, accel_bi: float | None = None,
             bi_tau: float = 3600.0, gyro_rrw: float | None = None, accel_rrw: float | None = None,
             t_ref: float | None = None, noise=None, station=None):
    """The Cramér-Rao bound (:func:`inscal.plan.bound.crlb`) of ``source``.  Field units:
    ``arw`` deg/sqrt(h), ``vrw`` ug/sqrt(Hz); bias instability as a Gauss-Markov process
    ``gyro_bi`` deg/h, ``accel_bi`` ug with correlation time ``bi_tau`` s, or a random walk
    ``gyro_rrw`` deg/h/sqrt(h), ``accel_rrw`` ug/sqrt(s); ``t_ref`` degC (thermal states).  ``noise``: a
    noise.toml whose white, Gauss-Markov and random-walk terms are the bound's noise
    (:func:`inscal.plan.noise_model.bound_noise`), instead of those options.  ``station``: a station
    (:class:`inscal.uncertainty.station.Station`): the bound at its site, carrying the site and clock sensitivities."""
    from inscal.calibrate.systematic.states import StateSet
    from inscal.calibrate.windows import CalibrationError
    from inscal.core import units
    from inscal.plan.bound import MAX_STEPS, STEP_SECONDS, bound_steps, crlb
    from inscal.plan.observability import ObservabilityError, load_source
    from inscal.plan.rows import BiasNoise, BoundError

    for name, v in (("--arw", arw), ("--vrw", vrw), ("--filter-rate-hz", filter_rate_hz), ("--bi-tau", bi_tau)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise CliError(f"{name} must be a positive number, got {v:g}")
    for name, v in (("--gyro-bi", gyro_bi), ("--accel-bi", accel_bi), ("--gyro-rrw", gyro_rrw),
                    ("--accel-rrw", accel_rrw)):
        if v is not None and not (math.isfinite(v) and v >= 0):
            raise CliError(f"{name} must be a number >= 0, got {v:g}")
    model_noise = None
    if noise is not None:
        model_noise = _model_noise(noise, arw, vrw, gyro_bi, accel_bi, gyro_rrw, accel_rrw)
    try:  # the size first: memory does not grow with the steps (no history kept), the time does
        sc, _, label = load_source(source)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None
    try:
        st = StateSet.parse(states)
    except CalibrationError:
        st = None  # crlb() names the bad state set
    _check_t_ref(t_ref, st)
    dur = sc.path.duration
    steps = bound_steps(dur, filter_rate_hz)
    check_count(steps, MAX_STEPS, f"--filter-rate-hz {filter_rate_hz:g} over the {dur:.4g} s path of {short(label, 60)} "
                f"is {steps:.3g} filter steps, about {human_seconds(steps * STEP_SECONDS)} of CPU",
                "lower --filter-rate-hz (1 Hz is the systematic filter's rate) or take a shorter path")
    bias = None
    if any(v is not None for v in (gyro_bi, accel_bi, gyro_rrw, accel_rrw)):
        per_sqrt_h = 1.0 / math.sqrt(3600.0)  # x per sqrt(h) = x / 60 per sqrt(s)
        bias = BiasNoise(gyro_rw=units.to_si(gyro_rrw or 0.0, "deg/h") * per_sqrt_h,
                         accel_rw=units.to_si(accel_rrw or 0.0, "ug"),
                         gyro_gm=units.to_si(gyro_bi or 0.0, "deg/h"), gyro_tau=bi_tau,
                         accel_gm=units.to_si(accel_bi or 0.0, "ug"), accel_tau=bi_tau)
    arw_si = None if arw is None else units.to_si(arw, "deg/sqrt(h)")
    vrw_si = None if vrw is None else units.to_si(vrw, "ug/sqrt(Hz)")
    if model_noise is not None:
        arw_si, vrw_si, bias, _ = model_noise
    extra = {}
    if station is not None:
        from inscal.uncertainty.before_run import consider_u, station_site

        extra = {"consider": consider_u(station), "site": station_site(sc.site, station)}
    try:
        return crlb(source, states, arw=arw_si, vrw=vrw_si, bias_noise=bias,
                    filter_rate_hz=filter_rate_hz, keep_history=False, t_ref=t_ref, **extra)
    except BoundError as exc:
        raise CliError(str(exc)) from None


def _model_noise(noise, arw, vrw, gyro_bi, accel_bi, gyro_rrw, accel_rrw):
    """The bound's noise of the noise.toml ``noise`` (:func:`inscal.plan.noise_model.bound_noise`); CliError
    (one line) for an unreadable file, a model the bound cannot take, or other noise options beside it."""
    from inscal.calibrate.windows import CalibrationError
    from inscal.io.noisefile import NoiseFileError, read_noise
    from inscal.plan.noise_model import bound_noise
    from inscal.plan.rows import BoundError

    if any(v is not None for v in (arw, vrw, gyro_bi, accel_bi, gyro_rrw, accel_rrw)):
        raise CliError("--noise gives the white and bias noise: drop --arw, --vrw, --gyro-bi, --accel-bi, --gyro-rrw "
                       "and --accel-rrw, or drop --noise")
    try:
        return bound_noise(read_noise(noise)[0])
    except (NoiseFileError, OSError) as exc:
        raise CliError(f"--noise: {exc}") from None
    except (CalibrationError, BoundError) as exc:
        raise CliError(f"--noise {noise}: {exc}") from None


def _check_t_ref(t_ref: float | None, st) -> None:
    if t_ref is None:
        return
    if not math.isfinite(t_ref):
        raise CliError(f"--t-ref must be a temperature in degC, got {t_ref:g}")
    if st is not None and not st.thermal:
        raise CliError("--t-ref is the reference temperature of the thermal states: add them (--states 51,thermal)")


def _temperature_line(t: dict) -> str:
    return (f"temperature: {t['t_min']:.4g} .. {t['t_max']:.4g} degC, up to {t['rate_max_c_per_min']:.3g} degC/min "
            f"({t['input']}); thermal coefficients about T_ref {t['t_ref']:g} degC, each prior spread over the span "
            f"{t['span']:.4g} degC")


def _print_crlb(source: str, b) -> None:
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
        con.print(_temperature_line(d["temperature"]))


def _simulated(source: str, st, method: str, seed: int, full: bool, json_: bool, mc: int | None = None,
               mc_workers: int = 1) -> None:
    """``--crlb --station --method M``: the budget of a window-mean method from one simulated run (and its JCGM 101
    Monte Carlo with ``mc`` trials at most)."""
    from inscal.calibrate.windows import CalibrationError
    from inscal.uncertainty.before_run import dominant_inputs, simulated_budget
    from inscal.uncertainty.sensitivity import WINDOW_METHODS
    from inscal.plan.observability import ObservabilityError, load_source

    if st is None:
        raise fail("--method needs --station (the budget of a window-mean method at a station)")
    if method not in WINDOW_METHODS:
        raise fail(f"--method must be a window-mean method ({', '.join(WINDOW_METHODS)}); the systematic filter's "
                   "budget is the bound's (leave --method out)")
    try:
        check_mc_trials(mc)
    except CliError as exc:
        raise fail(str(exc)) from None
    try:
        sc, _, _ = load_source(source)
        bud, res = simulated_budget(sc, st, method, seed)
    except (ObservabilityError, CalibrationError, ValueError) as exc:
        raise fail(f"{source} with --method {method}: {exc}") from None
    doc = bud.to_dict()
    if mc is not None:
        from inscal.cli.budget_mc import run_budget_mc

        try:
            doc["monte_carlo"] = run_budget_mc(res, st, bud, mc, seed, mc_workers)
        except CliError as exc:
            raise fail(str(exc)) from None
    if json_:
        print_json({"source": source, "method": method, "seed": seed, "station": st.to_dict(), "budget": doc,
                    "dominant_inputs": dominant_inputs(bud)})
        return
    _print_budget(source, None, bud, full, f"{method} on one simulated run (seed {seed})", doc)


def _print_budget(source: str, b, bud, full: bool, what: str | None = None, doc: dict | None = None) -> None:
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


def _print_report(rep) -> None:
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
        _print_partners(con, rep)
    wt = Table(title="weakest directions (right singular vectors, scaled parameters)")
    wt.add_column("σ / σmax", justify="right")
    wt.add_column("dominant combination")
    for d in rep.weakest:
        wt.add_row(f"{d.singular_value:.2e}", escape(d.describe()))
    con.print(wt)
    for n in rep.notes:
        con.print(f"note: {escape(n)}")
    con.print(f"({rep.timing_s['total']:.2f} s)")


def _print_partners(con, rep) -> None:
    """Per thermal coefficient: the state it is most correlated with a posteriori."""
    from rich.markup import escape
    from rich.table import Table

    con.print(_temperature_line(rep.thermal))
    tab = Table(title="thermal coefficients: the state each is most correlated with (posterior)")
    for col in ("coefficient", "most correlated with", "correlation"):
        tab.add_column(col, justify="right" if col == "correlation" else "left", no_wrap=True)
    for lab, p in rep.thermal["partners"].items():
        tab.add_row(escape(lab), escape(p["with"]), f"{p['correlation']:+.3f}")
    con.print(tab)


def register(app: typer.Typer) -> None:
    @app.command("observability")
    def observability_cmd(
        source: str = typer.Argument(..., metavar="PATH_OR_SCENARIO",
                                     help="built-in scenario (s16, psins19, n25, ...) or path (s16-table1, "
                                          "n25-twelve, ...), a scenario TOML, or a path TOML (a [path] table)"),
        states: str = typer.Option("51", "--states", help="state set: 51 | 30, options ,lever9 ,async ,psins, "
                                                          ",thermal (or ,thermal=GSABR: needs a temperature profile)"),
        rate_hz: float = typer.Option(20.0, "--rate-hz", help="rate of the noise-free simulation [Hz]"),
        arw: float = typer.Option(None, "--arw", help="gyro angle random walk [deg/sqrt(h)] (default: the "
                                                      "scenario's, else S16's 5e-5)"),
        vrw: float = typer.Option(None, "--vrw", help="accelerometer velocity random walk [ug/sqrt(Hz)] (default: "
                                                      "the scenario's, else S16's 1)"),
        crlb: bool = typer.Option(False, "--crlb", help="print the Cramér-Rao bound of every parameter (fast, "
                                                        "from the path kinematics; no simulation)"),
        filter_rate_hz: float = typer.Option(1.0, "--filter-rate-hz", help="filter rate of the bound [Hz]"),
        gyro_bi: float = typer.Option(None, "--gyro-bi", help="with --crlb: gyro bias instability, Gauss-Markov "
                                                              "sigma [deg/h]"),
        accel_bi: float = typer.Option(None, "--accel-bi", help="with --crlb: accelerometer bias instability, "
                                                                "Gauss-Markov sigma [ug]"),
        bi_tau: float = typer.Option(3600.0, "--bi-tau", help="with --crlb: correlation time of the bias "
                                                              "instability [s]"),
        gyro_rrw: float = typer.Option(None, "--gyro-rrw", help="with --crlb: gyro bias random walk [deg/h/sqrt(h)]"),
        accel_rrw: float = typer.Option(None, "--accel-rrw", help="with --crlb: accelerometer bias random walk "
                                                                  "[ug/sqrt(s)]"),
        t_ref: float = typer.Option(None, "--t-ref", help="reference temperature of the thermal states [degC] "
                                                          "(default: the scenario's thermal model's, else 20)"),
        noise: Path = typer.Option(None, "--noise", help="with --crlb: an identified noise model (noise.toml of "
                                   "inscal noise): its white, Gauss-Markov and random-walk terms are the bound's noise"),
        station: Path = typer.Option(None, "--station", help="with --crlb: a station description (station.toml): "
                                     "the bound at its site, and the uncertainty budget the path promises with its "
                                     "inputs (which dominate, before the run)"),
        full: bool = typer.Option(False, "--full", help="with --station: every component's budget table"),
        method: str = typer.Option(None, "--method", help="with --station: a window-mean method (n25, six-position, "
                                   "twelve-position, joint): its budget from one run simulated on the path at the "
                                   "station (the scenario's unit and noise) instead of the systematic filter's bound"),
        seed: int = typer.Option(0, "--seed", help="with --method: seed of the simulated run"),
        mc: int = typer.Option(None, "--mc", help="with --method: the JCGM 101 Monte Carlo of that budget, at most N "
                               "trials (does the linear budget hold for this path at this station?)"),
        mc_workers: int = typer.Option(1, "--mc-workers", help="with --mc: Dask workers (1: this process)"),
        json_: bool = typer.Option(False, "--json", help="print the results as JSON"),
    ):
        """Observability of the systematic filter's states on a rotation path, without data: posterior /
        prior σ per state and the SVD of the observability matrix."""
        if crlb:
            from inscal.cli.bound_budget import read_station_option

            st = read_station_option(station)
            if method is not None:
                _simulated(source, st, method, seed, full, json_, mc, mc_workers)
                return
            if mc is not None:
                raise fail("--mc needs --method (the Monte Carlo of a window-mean method's budget; the filter's site "
                           "and clock enter it linearly)")
            try:
                b = run_crlb(source, states, arw, vrw, filter_rate_hz, gyro_bi, accel_bi, bi_tau, gyro_rrw, accel_rrw,
                             t_ref, noise, st)
            except CliError as exc:
                raise fail(str(exc)) from None
            bud = None
            if st is not None:
                from inscal.uncertainty.before_run import bound_budget, dominant_inputs
                from inscal.plan.observability import load_source

                bud = bound_budget(b, st, scenario=load_source(source)[0])
            if json_:
                doc = {"source": source, "crlb": b.to_dict()}
                if bud is not None:
                    doc.update(station=st.to_dict(), budget=bud.to_dict(), dominant_inputs=dominant_inputs(bud))
                print_json(doc)
            elif bud is not None:
                _print_budget(source, b, bud, full)
            else:
                _print_crlb(source, b)
            return
        if station is not None or full or method is not None or mc is not None:
            raise fail("--station, --full, --method and --mc apply to the bound (--crlb)")
        if noise is not None:
            raise fail("--noise applies to the bound (--crlb)")
        if any(v is not None for v in (gyro_bi, accel_bi, gyro_rrw, accel_rrw)):
            raise fail("--gyro-bi, --accel-bi, --gyro-rrw and --accel-rrw need --crlb (the systematic filter has no "
                       "bias process noise)")
        if filter_rate_hz != 1.0 or bi_tau != 3600.0:
            raise fail("--filter-rate-hz and --bi-tau apply to the bound (--crlb); the observability analysis runs at "
                       "--rate-hz")
        try:
            rep = run_observability(source, states, rate_hz, arw, vrw, t_ref)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(rep.to_dict())
            return
        _print_report(rep)
