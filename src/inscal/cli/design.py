"""``inscal design``: search a calibration path that minimises a function of its Cramér-Rao
bound within a time budget and the turntable's limits.  See :mod:`inscal.plan.design`."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Annotated

import typer

from inscal.cli.common import CliError, check_output, check_scheduler, fail, print_json, short
from inscal.cli.limits import DASK_WORKER_BYTES, check_count, check_memory, human_seconds
from inscal.cli.options import (
    ForceOption,
    JsonOption,
    SeedOption,
    arw_option,
    option,
    options_of,
    out_option,
    plot_option,
    scheduler_option,
    states_option,
    station_option,
    vrw_option,
    with_options,
)


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


@dataclass(frozen=True)
class DesignOptions:
    """What ``inscal design`` is asked: a path of ``minutes`` written to ``out`` (``force``: over an existing
    file) for the ``states`` set, minimising ``objective`` against ``targets`` over the parameter ``groups``;
    the turntable's limits (``axes`` it may turn, ``max_rate`` [deg/s], ``max_accel`` [deg/s^2], the angle
    ranges ``outer_range``/``inner_range`` "LO,HI" [deg], ``cable_wrap`` [deg], ``min_dwell``,
    ``initial_dwell`` [s], ``max_moves``); the search (``seed``, ``candidates``, ``population`` survivors, on
    ``scheduler`` with ``workers``, ``progress`` on standard error); the scenario ``base`` of the file written
    and its noise ``arw`` [deg/sqrt(h)], ``vrw`` [ug/sqrt(Hz)]; the path report ``plot``; ``station`` (a
    :class:`inscal.uncertainty.station.Station`): the path is designed at its site for the combined
    uncertainty."""

    out: out_option("output scenario TOML with the designed [path]")
    minutes: Annotated[float, typer.Option("--minutes", help="time budget of the path [min]")] = 30.0
    states: states_option("error-state model: 51 | 30 | unified (options ,lever9 ,async ,psins)") = "51"
    objective: Annotated[str, typer.Option("--objective", metavar="OBJECTIVE", help=(
        "worst-normalised (max of σ/target) | weighted (mean of (σ/target)^2)"))] = "worst-normalised"
    targets: Annotated[str, typer.Option("--targets", metavar="TARGETS", help=(
        "s16-path (bound of S16's own 1-h path) | s16-table2 (S16 Table 2 figures for its groups)"))] = "s16-path"
    groups: Annotated[str, typer.Option("--groups", metavar="GROUPS", help=(
        "parameter groups in the objective: all | table2 | a comma list"))] = "all"
    axes: Annotated[str, typer.Option("--axes", help="gimbal axes the path may turn")] = "outer,inner"
    max_rate: Annotated[float, typer.Option("--max-rate", metavar="DEG/S", help=(
        "largest turntable rate [deg/s]"))] = 10.0
    max_accel: Annotated[float, typer.Option("--max-accel", metavar="DEG/S^2", help=(
        "angular acceleration of the moves [deg/s^2]"))] = 10.0
    outer_range: option("--outer-range", "outer angle limits LO,HI [deg] (start = 0)", str, "LO,HI") = None
    inner_range: option("--inner-range", "inner angle limits LO,HI [deg] (start = 0)", str, "LO,HI") = None
    cable_wrap: option("--cable-wrap", "largest net rotation of each axis [deg]", metavar="DEG") = None
    min_dwell: Annotated[float, typer.Option("--min-dwell", metavar="SECONDS", help=(
        "shortest dwell after a move [s]"))] = 5.0
    initial_dwell: Annotated[float, typer.Option("--initial-dwell", metavar="SECONDS", help=(
        "dwell at the start (alignment) [s]"))] = 60.0
    max_moves: Annotated[int, typer.Option("--max-moves", metavar="N", help="most moves in a path")] = 40
    seed: SeedOption = 0
    candidates: Annotated[int, typer.Option("--candidates", help="candidate paths to evaluate")] = 256
    population: Annotated[int, typer.Option("--population", help="survivors per generation")] = 16
    scheduler: scheduler_option("a LocalCluster of --workers") = None
    workers: Annotated[int, typer.Option("--workers", help="workers of the local Dask cluster")] = 2
    base: Annotated[str, typer.Option("--base", metavar="SCENARIO", help=(
        "built-in scenario for the site, gimbal, noise and IMU of the written file"))] = "s16"
    arw: arw_option("the base scenario's") = None
    vrw: vrw_option("the base scenario's") = None
    plot: plot_option("write the path report: FILE.png and FILE.html") = None
    force: ForceOption = False
    progress: bool = True
    station: object = None  # a Station (read from --station FILE.toml)


def run_design(o: DesignOptions):
    """Run the search of ``o`` (:class:`DesignOptions`) and write the path; returns ``(DesignResult, document)``."""
    import tomli_w

    from inscal.core import units
    from inscal.io.files import atomic_path
    from inscal.plan.bound import make_setup
    from inscal.plan.rows import BiasNoise, BoundError
    from inscal.plan.design import DesignError, Limits, design
    from inscal.sim.scenarios import BUILTIN, ScenarioError, scenario_from_dict

    scheduler = check_scheduler(o.scheduler, ("local", "none", "synchronous", "sync", ""))
    out = FsPath(o.out)
    if out.suffix != ".toml":
        raise CliError(f"--out must be a .toml file, got {short(out)}")
    check_output(out, o.force)
    plot = None if o.plot is None else FsPath(o.plot)
    if plot is not None:
        check_output(plot, o.force)
    if o.base not in BUILTIN:
        raise CliError(f"--base must be a built-in scenario ({', '.join(BUILTIN)}), got {short(o.base)!r}")
    ax = tuple(a.strip() for a in o.axes.split(",") if a.strip())
    try:
        limits = Limits(axes=ax, max_rate=units.to_si(o.max_rate, "deg/s"),
                        max_accel=units.to_si(o.max_accel, "deg/s"), outer_range=_range("--outer-range", o.outer_range),
                        inner_range=_range("--inner-range", o.inner_range),
                        cable_wrap=None if o.cable_wrap is None else units.to_si(o.cable_wrap, "deg"),
                        min_dwell=o.min_dwell, initial_dwell=o.initial_dwell, max_moves=o.max_moves)
    except DesignError as exc:
        raise CliError(str(exc)) from None
    name = out.stem
    # the scenario the file will hold (without its path): its site, gimbal and noise set the bound
    try:
        from inscal.core.turntable import static

        probe = scenario_doc(o.base, name, static(60.0), o.arw, o.vrw, o.station)
        sc = scenario_from_dict(probe)
        consider = None
        if o.station is not None:
            from inscal.uncertainty.before_run import consider_u

            consider = consider_u(o.station)
        setup = make_setup(o.states, sc.site, sc.gimbal, sc.noise.arw, sc.noise.vrw,
                           BiasNoise.from_imu_noise(sc.noise),
                           consider=consider)
    except (BoundError, ScenarioError, ValueError) as exc:
        raise CliError(str(exc)) from None
    check_size(o.minutes, o.candidates, o.population, o.workers, scheduler, setup)
    from inscal.core.progress import ProgressBar

    label = f"design {o.minutes:g} min"
    bar = ProgressBar(label, o.candidates, o.progress, every_s=None)

    def update(done: int, total: int, best: float) -> None:  # the best score so far beside the bar
        bar.update(done, total, f"best {best:.4g}", f"{label}: {done}/{total} candidates, best score {best:.4g}")

    try:
        res = design(o.minutes, o.states, o.objective, o.targets, o.groups, limits, o.seed, o.candidates,
                     o.population, scheduler, o.workers, setup, update if o.progress else None, name)
    except (DesignError, BoundError) as exc:
        raise CliError(str(exc)) from None
    finally:
        bar.close()
    doc = scenario_doc(o.base, name, res.path, o.arw, o.vrw, o.station)
    d = res.to_dict()
    what = "" if o.station is None else f" of the combined uncertainty at station {o.station.name!r}"
    head = [f"# inscal design: {o.minutes:g} min, states {o.states}, objective {o.objective}{what} over {o.groups} "
            f"(targets {o.targets}) = {res.value:.4g} (S16's own 1-h path: {res.reference_value:.4g})",
            f"# seed {o.seed}, {res.evaluations} candidates; limits {d['limits']}",
            "# the bound of this file: inscal observability THIS.toml --crlb"]
    text = "\n".join(head) + "\n" + tomli_w.dumps(doc)
    try:
        with atomic_path(out, o.force) as tmp:
            tmp.write_text(text, encoding="utf-8")
    except (OSError, FileExistsError) as exc:
        raise CliError(f"cannot write {short(out)}: {exc}") from None
    if plot is not None:
        from inscal.report.path import write_path_report

        g = res.groups()
        summ = (f"{o.minutes:g}-minute path designed for {o.objective} over {o.groups} (targets {o.targets}): "
                f"{res.value:.3g} (S16's 1-h path: {res.reference_value:.3g}); per S16 Table 2 group, worst "
                "bound / S16-path bound: " + ", ".join(f"{k} {g[k]['worst_ratio']:.2f}" for k in d["table2_groups"]))
        try:
            write_path_report(plot, res.bound, res.path, res.objective.targets,
                              title=f"Designed path {name} ({o.minutes:g} min)", summary=summ,
                              target_label=f"target ({o.targets})", overwrite=o.force)
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
    @with_options(DesignOptions, before="station")
    def design_cmd(
        station: station_option("a station description (station.toml): design at its site for the combined "
                                "uncertainty (the bound with the site's gravity, latitude, height and the time "
                                "base; GUM)", FsPath) = None,
        json_: JsonOption = False,
        **options,
    ):
        """Design a calibration path from its Cramér-Rao bound: an evolutionary search over sequences of
        turns (axis, angle, rate, dwell) within the time budget and the turntable's limits."""
        from inscal.cli.bound_budget import read_station_option

        st = read_station_option(station)
        try:
            res, _ = run_design(options_of(DesignOptions, options, progress=True, station=st))
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            d = res.to_dict()
            d["out"] = str(options["out"])
            d.pop("bound", None)
            d["bound"] = {"parameters": res.bound.table(), "group_rms": res.bound.group_rms()}
            if st is not None:
                from inscal.uncertainty.before_run import bound_budget, dominant_inputs

                bud = bound_budget(res.bound, st)
                d.update(station=st.name, budget=bud.to_dict(), dominant_inputs=dominant_inputs(bud))
            print_json(d)
            return
        _print(res, options["out"], st)
