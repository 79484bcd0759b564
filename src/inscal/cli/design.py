"""``inscal design``: search a calibration path that minimises a function of its Cramér-Rao
bound within a time budget and the turntable's limits.  See :mod:`inscal.plan.design`."""

from __future__ import annotations

import math
import os
from pathlib import Path as FsPath

import typer

from inscal.cli.common import CliError, check_output, check_scheduler, fail, print_json, short
from inscal.cli.limits import DASK_WORKER_BYTES, check_count, check_memory, human_seconds
from inscal.cli.options import ForceOption, JsonOption, SeedOption


def _range(opt: str, v: str | None):
    from inscal.core import units

    if v is None:
        return None
    try:
        lo, hi = (float(x) for x in v.split(","))
    except ValueError:
        raise CliError(f"{opt} must be LO,HI in degrees, got {short(v)!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= 0 <= hi and lo < hi):
        raise CliError(f"{opt} must be LO,HI with LO <= 0 <= HI (the path starts at 0 deg), got {short(v)!r}")
    return (float(units.to_si(lo, "deg")), float(units.to_si(hi, "deg")))


def scenario_doc(base: str, name: str, path, arw: float | None, vrw: float | None, station=None) -> dict:
    """The scenario TOML document of a designed path: ``base`` (a built-in scenario: IMU errors,
    site, gimbal, noise) with the designed ``[path]``; ``[noise]`` only when ARW/VRW are overridden
    (field units: deg/sqrt(h), ug/sqrt(Hz)); ``[site]`` at a ``station``'s latitude, height and gravity."""
    from inscal import SCHEMA_VERSION
    from inscal.core import units
    from inscal.sim.scenarios import build

    doc = {"schema_version": SCHEMA_VERSION, "base": base, "scenario": {"name": name}}
    if arw is not None or vrw is not None:
        sc = build(base)
        a = arw if arw is not None else float(units.from_si(sc.noise.arw, "deg/sqrt(h)").mean())
        v = vrw if vrw is not None else float(units.from_si(sc.noise.vrw, "ug/sqrt(Hz)").mean())
        doc["noise"] = {"arw": a, "vrw": v}
    if station is not None:
        sc = build(base)
        doc["site"] = {"latitude_deg": float(units.from_si(station["latitude"].value, "deg")),
                       "longitude_deg": float(units.from_si(sc.site.longitude, "deg")),
                       "height_m": float(station["height"].value),
                       "gravity": {"value": float(station["gravity"].value), "unit": "m/s^2"}}
    doc["path"] = path.to_dict()
    return doc


def check_size(minutes: float, candidates: int, population: int, workers: int, scheduler: str | None, setup) -> None:
    """Refuse (one line) a search whose size options ask for more memory than there is or more filter
    steps than :data:`~inscal.plan.design.MAX_SEARCH_STEPS`, before anything runs."""
    from inscal.plan.bound import MAX_STEPS, STEP_SECONDS
    from inscal.plan.design import MAX_SEARCH_STEPS, search_size

    local = scheduler in (None, "", "local")
    size = search_size(minutes, candidates, population, setup, workers if local else 1)
    rate = f"{1.0 / setup.T:g} Hz"
    check_memory(size.history_bytes, f"--minutes {minutes:g} ({size.steps:.3g} filter steps at {rate})",
                 "shorten --minutes")
    check_count(size.steps, MAX_STEPS, f"--minutes {minutes:g} is {size.steps:.3g} filter steps per candidate at {rate}",
                "shorten --minutes")
    check_count(size.total_steps, MAX_SEARCH_STEPS,
                f"--candidates {candidates} x {size.steps:.3g} steps is {size.total_steps:.3g} filter steps, about "
                f"{human_seconds(size.total_steps * STEP_SECONDS)} of CPU", "lower --candidates or --minutes")
    if local:
        check_memory(workers * DASK_WORKER_BYTES, f"--workers {workers} (a local Dask cluster of {workers} processes)",
                     "lower --workers")
    check_memory(size.population_bytes, f"--population {population} with --candidates {candidates} ({size.members} "
                 "paths held at once)", "lower --population")
    check_memory(size.memory + (workers * DASK_WORKER_BYTES if local else 0.0),
                 f"--minutes {minutes:g} with --population {population} and --workers {workers}",
                 "shorten --minutes or lower --population or --workers")


def run_design(out: FsPath, minutes: float, states: str = "51", objective: str = "worst-normalised",
               targets: str = "s16-path", groups: str = "all", axes: str = "outer,inner", max_rate: float = 10.0,
               max_accel: float = 10.0, outer_range: str | None = None, inner_range: str | None = None,
               cable_wrap: float | None = None, min_dwell: float = 5.0, initial_dwell: float = 60.0,
               max_moves: int = 40, seed: int = 0, candidates: int = 256, population: int = 16, scheduler: str | None = None,
               workers: int = 2, base: str = "s16", arw: float | None = None, vrw: float | None = None,
               plot: FsPath | None = None, force: bool = False, progress: bool = True, station=None):
    """Run the search and write the path; returns ``(DesignResult, document)``.  ``station``: a station
    (:class:`inscal.uncertainty.station.Station`): the path is designed at its site for the combined uncertainty."""
    import tomli_w

    from inscal.core import units
    from inscal.io.files import atomic_path
    from inscal.plan.bound import make_setup
    from inscal.plan.rows import BiasNoise, BoundError
    from inscal.plan.design import DesignError, Limits, design
    from inscal.sim.scenarios import BUILTIN, ScenarioError, scenario_from_dict

    scheduler = check_scheduler(scheduler, ("local", "none", "synchronous", "sync", ""))
    out = FsPath(out)
    if out.suffix != ".toml":
        raise CliError(f"--out must be a .toml file, got {short(out)}")
    check_output(out, force)
    if plot is not None:
        plot = FsPath(plot)
        check_output(plot, force)
    for name, v in (("--minutes", minutes), ("--max-rate", max_rate), ("--max-accel", max_accel),
                    ("--arw", arw), ("--vrw", vrw)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise CliError(f"{name} must be a positive number, got {v:g}")
    if candidates < 2 or population < 2 or workers < 1:
        raise CliError("--candidates and --population must be >= 2, --workers >= 1")
    if base not in BUILTIN:
        raise CliError(f"--base must be a built-in scenario ({', '.join(BUILTIN)}), got {short(base)!r}")
    ax = tuple(a.strip() for a in axes.split(",") if a.strip())
    try:
        limits = Limits(axes=ax, max_rate=units.to_si(max_rate, "deg/s"), max_accel=units.to_si(max_accel, "deg/s"),
                        outer_range=_range("--outer-range", outer_range), inner_range=_range("--inner-range", inner_range),
                        cable_wrap=None if cable_wrap is None else units.to_si(cable_wrap, "deg"),
                        min_dwell=min_dwell, initial_dwell=initial_dwell, max_moves=max_moves)
    except DesignError as exc:
        raise CliError(str(exc)) from None
    name = out.stem
    # the scenario the file will hold (without its path): its site, gimbal and noise set the bound
    try:
        from inscal.core.turntable import static

        probe = scenario_doc(base, name, static(60.0), arw, vrw, station)
        sc = scenario_from_dict(probe)
        consider = None
        if station is not None:
            from inscal.uncertainty.before_run import consider_u

            consider = consider_u(station)
        setup = make_setup(states, sc.site, sc.gimbal, sc.noise.arw, sc.noise.vrw, BiasNoise.from_imu_noise(sc.noise),
                           consider=consider)
    except (BoundError, ScenarioError, ValueError) as exc:
        raise CliError(str(exc)) from None
    check_size(minutes, candidates, population, workers, scheduler, setup)
    from inscal.core.progress import ProgressBar

    label = f"design {minutes:g} min"
    bar = ProgressBar(label, candidates, progress, every_s=None)

    def update(done: int, total: int, best: float) -> None:  # the best score so far beside the bar
        bar.update(done, total, f"best {best:.4g}", f"{label}: {done}/{total} candidates, best score {best:.4g}")

    try:
        res = design(minutes, states, objective, targets, groups, limits, seed, candidates, population,
                     scheduler, workers, setup, update if progress else None, name)
    except (DesignError, BoundError) as exc:
        raise CliError(str(exc)) from None
    finally:
        bar.close()
    doc = scenario_doc(base, name, res.path, arw, vrw, station)
    d = res.to_dict()
    what = "" if station is None else f" of the combined uncertainty at station {station.name!r}"
    head = [f"# inscal design: {minutes:g} min, states {states}, objective {objective}{what} over {groups} "
            f"(targets {targets}) = {res.value:.4g} (S16's own 1-h path: {res.reference_value:.4g})",
            f"# seed {seed}, {res.evaluations} candidates; limits {d['limits']}",
            "# the bound of this file: inscal observability THIS.toml --crlb"]
    text = "\n".join(head) + "\n" + tomli_w.dumps(doc)
    try:
        with atomic_path(out, force) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except (OSError, FileExistsError) as exc:
        raise CliError(f"cannot write {short(out)}: {exc}") from None
    if plot is not None:
        from inscal.report.path import write_path_report

        g = res.groups()
        summ = (f"{minutes:g}-minute path designed for {objective} over {groups} (targets {targets}): "
                f"{res.value:.3g} (S16's 1-h path: {res.reference_value:.3g}); per S16 Table 2 group, worst "
                "bound / S16-path bound: " + ", ".join(f"{k} {g[k]['worst_ratio']:.2f}" for k in d["table2_groups"]))
        try:
            write_path_report(plot, res.bound, res.path, res.objective.targets,
                              title=f"Designed path {name} ({minutes:g} min)", summary=summ,
                              target_label=f"target ({targets})", overwrite=force)
        except (OSError, FileExistsError) as exc:
            raise CliError(f"cannot write {short(plot)}: {exc}") from None
    return res, doc


def _print(res, out, station=None) -> None:
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    con = Console()
    if not con.is_terminal and "COLUMNS" not in os.environ:  # a file or a pipe: whole group names, not 80 columns
        con = Console(width=120)
    d = res.to_dict()
    if station is not None:
        con.print(f"objective on the combined standard uncertainty at station {escape(station.name)!r}: the bound "
                  "with the site's and the clock's contributions (\"bound RMS\" below is that combination)")
    tab = Table(title=f"Designed path {out} ({res.path.duration / 60:.1f} min, {len(res.path.moves)} moves): "
                      f"{d['objective']['kind']} = {res.value:.4g} (S16's 1-h path: {res.reference_value:.4g})",
                box=box.SIMPLE_HEAD)
    for col in ("group", "unit", "bound RMS", "S16 path RMS", "worst σ / S16", "S16 Table 2"):
        tab.add_column(col, justify="left" if col in ("group", "unit") else "right")
    for g, v in d["groups"].items():
        tab.add_row(g, v["unit"], f"{v['bound_rms']:.3g}", f"{v['s16_path_rms']:.3g}", f"{v['worst_ratio']:.2f}",
                    "" if v["s16_table2"] is None else f"{v['s16_table2']:g}")
    con.print(tab)
    con.print(f"{res.evaluations} candidates in {res.generations} generations, seed {res.seed}, {res.seconds:.1f} s; "
              f"best score (objective + tie-break) per generation: {res.trace[0]:.3g} -> {res.trace[-1]:.3g}")
    if station is not None:
        from inscal.uncertainty.before_run import bound_budget, dominant_inputs
        from inscal.report.budget import INPUT_TITLES

        rows = [r for r in dominant_inputs(bound_budget(res.bound, station)) if r["n_largest"]]
        con.print("largest input per component of the designed path: " + ", ".join(
            f"{INPUT_TITLES.get(r['input'], r['input'])} in {r['n_largest']}" for r in rows)
            + f" (the whole budget: inscal observability {out} --crlb --station FILE)")


def register(app: typer.Typer) -> None:
    @app.command("design")
    def design_cmd(
        out: FsPath = typer.Option(..., "--out", help="output scenario TOML with the designed [path]"),
        minutes: float = typer.Option(30.0, "--minutes", help="time budget of the path [min]"),
        states: str = typer.Option("51", "--states", help="error-state model: 51 | 30 | unified (options ,lever9 "
                                                          ",async ,psins)"),
        objective: str = typer.Option("worst-normalised", "--objective", metavar="OBJECTIVE", help="worst-normalised (max of σ/target) "
                                                                              "| weighted (mean of (σ/target)^2)"),
        targets: str = typer.Option("s16-path", "--targets", metavar="TARGETS", help="s16-path (bound of S16's own 1-h path) | "
                                                                  "s16-table2 (S16 Table 2 figures for its groups)"),
        groups: str = typer.Option("all", "--groups", metavar="GROUPS", help="parameter groups in the objective: all | table2 | a "
                                                           "comma list"),
        axes: str = typer.Option("outer,inner", "--axes", help="gimbal axes the path may turn"),
        max_rate: float = typer.Option(10.0, "--max-rate", metavar="DEG/S", help="largest turntable rate [deg/s]"),
        max_accel: float = typer.Option(10.0, "--max-accel", metavar="DEG/S^2", help="angular acceleration of the moves [deg/s^2]"),
        outer_range: str = typer.Option(None, "--outer-range", metavar="LO,HI", help="outer angle limits LO,HI [deg] (start = 0)"),
        inner_range: str = typer.Option(None, "--inner-range", metavar="LO,HI", help="inner angle limits LO,HI [deg] (start = 0)"),
        cable_wrap: float = typer.Option(None, "--cable-wrap", metavar="DEG", help="largest net rotation of each axis [deg]"),
        min_dwell: float = typer.Option(5.0, "--min-dwell", metavar="SECONDS", help="shortest dwell after a move [s]"),
        initial_dwell: float = typer.Option(60.0, "--initial-dwell", metavar="SECONDS", help="dwell at the start (alignment) [s]"),
        max_moves: int = typer.Option(40, "--max-moves", metavar="N", help="most moves in a path"),
        seed: SeedOption = 0,
        candidates: int = typer.Option(256, "--candidates", help="candidate paths to evaluate"),
        population: int = typer.Option(16, "--population", help="survivors per generation"),
        scheduler: str = typer.Option(None, "--scheduler", help="Dask scheduler ADDRESS, 'local' (default: a "
                                                               "LocalCluster of --workers) or 'none' (in-process)"),
        workers: int = typer.Option(2, "--workers", help="workers of the local Dask cluster"),
        base: str = typer.Option("s16", "--base", metavar="SCENARIO", help="built-in scenario for the site, gimbal, noise and IMU of "
                                                       "the written file"),
        arw: float = typer.Option(None, "--arw", metavar="DEG/SQRT(H)", help="gyro ARW [deg/sqrt(h)] (default: the base scenario's)"),
        vrw: float = typer.Option(None, "--vrw", metavar="UG/SQRT(HZ)", help="accelerometer VRW [ug/sqrt(Hz)] (default: the base's)"),
        plot: FsPath = typer.Option(None, "--plot", metavar="PATH", help="write the path report: FILE.png and FILE.html"),
        station: FsPath = typer.Option(None, "--station", metavar="STATION.toml", help="a station description (station.toml): design at its "
                                       "site for the combined uncertainty (the bound with the site's gravity, "
                                       "latitude, height and the time base; GUM)"),
        force: ForceOption = False,
        json_: JsonOption = False,
    ):
        """Design a calibration path from its Cramér-Rao bound: an evolutionary search over sequences of
        turns (axis, angle, rate, dwell) within the time budget and the turntable's limits."""
        from inscal.cli.bound_budget import read_station_option

        st = read_station_option(station)
        try:
            res, _ = run_design(out, minutes, states, objective, targets, groups, axes, max_rate, max_accel,
                                outer_range, inner_range, cable_wrap, min_dwell, initial_dwell, max_moves, seed,
                                candidates,
                                population, scheduler, workers, base, arw, vrw, plot, force, progress=True, station=st)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            d = res.to_dict()
            d["out"] = str(out)
            d.pop("bound", None)
            d["bound"] = {"parameters": res.bound.table(), "group_rms": res.bound.group_rms()}
            if st is not None:
                from inscal.uncertainty.before_run import bound_budget, dominant_inputs

                bud = bound_budget(res.bound, st)
                d.update(station=st.name, budget=bud.to_dict(), dominant_inputs=dominant_inputs(bud))
            print_json(d)
            return
        _print(res, out, st)
