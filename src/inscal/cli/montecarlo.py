"""``inscal montecarlo``: seeded, resumable Monte Carlo studies (locally or on Dask)."""

from __future__ import annotations

import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from inscal.analysis.montecarlo import Summary

from inscal.cli.common import CliError, check_scheduler, fail, print_json, short
from inscal.cli.limits import DASK_WORKER_BYTES, check_count, check_memory
from inscal.cli.options import JsonOption, NoProgressOption, WorkersOption, option, options_of, out_option, with_options

#: most runs of a study, all configuration points together (10^6: weeks of CPU at 1-10 s a run)
MAX_RUNS = 10**6
#: memory the driver holds per run: its seed and place in the layout (~0.6 kB) and its result, parsed
#: (about twice its runs.jsonl line: 4.6 kB for n25-schemes, 7.3 kB for s16-table2)
RUN_BYTES = 16e3
#: memory of one run per sample of its record: the simulation in memory and the calibrations (measured:
#: 161 B for n25-schemes at 100-400 Hz), and per second of the path (the systematic filter's stores at 1 Hz)
RUN_BYTES_PER_SAMPLE = 256
RUN_BYTES_PER_SECOND = 16e3
#: most samples of one run's record (10^9: about 250 GB in memory)
MAX_RUN_SAMPLES = 10**9


def parse_set(items: list[str] | None) -> dict:
    """``KEY=VALUE`` pairs; VALUE is JSON when it parses (numbers, lists), else a string."""
    out = {}
    for it in items or []:
        if "=" not in it:
            raise CliError(f"--set expects KEY=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        k = k.strip().replace("-", "_")
        if not k:
            raise CliError(f"--set expects KEY=VALUE, got {it!r}")
        try:
            out[k] = json.loads(v)
        except ValueError:
            out[k] = v
    return out


def run_scenario(exp):
    """The scenario one run of ``exp`` simulates (the built-in studies: N25's twelve positions with the
    study's dwell and rate, or a named scenario at the study's rate), or None for one it cannot tell."""
    from inscal.analysis.studies.common import n25_scenario
    from inscal.sim.scenarios import build

    params = exp.params
    if "rate_hz" not in params:
        return None
    if "dwell_s" in params:
        return n25_scenario(params)
    name = exp.points[0].get("scenario") if exp.points else None
    return None if name is None else build(name, rate_hz=float(params["rate_hz"]))


def check_size(exp, runs: int, scheduler: str | None, workers: int | None) -> None:
    """Refuse (one line) a study whose size asks for more memory than there is, or more runs than
    :data:`MAX_RUNS`, before anything is written: the driver's runs, one run's record per worker process
    (``--set rate_hz=`` / ``dwell_s=``) and the processes of a local Dask cluster."""
    P = len(exp.points)
    total = runs * P
    what = f"--runs {runs} x {P} configuration point{'s' if P > 1 else ''} ({total} runs)"
    hint = "lower --runs (a study resumes: raise --runs later to extend it)"
    check_memory(total * RUN_BYTES, what, hint)
    check_count(total, MAX_RUNS, what, hint)
    local = scheduler in (None, "local")
    procs = 1 if scheduler in ("synchronous", "sync") else (workers or os.cpu_count() or 1) if local else 0
    if local and procs > 1:
        check_memory(procs * DASK_WORKER_BYTES, f"--workers {procs}{' (the default: one per core)' if workers is None else ''}"
                     f" (a local Dask cluster of {procs} processes)", "lower --workers")
    try:
        sc = run_scenario(exp)
    except ValueError:  # the study's own checks name a bad parameter when it runs
        sc = None
    if sc is None:
        return
    dur, rate = sc.path.duration, sc.rate_hz
    n = dur * rate
    what = f"one run of {exp.name} ({n:.3g} samples: {dur:.4g} s at {rate:g} Hz)"
    hint = "lower --set rate_hz=" + (" or dwell_s=" if "dwell_s" in exp.params else "")
    if procs:
        need = n * RUN_BYTES_PER_SAMPLE + dur * RUN_BYTES_PER_SECOND
        check_memory(procs * need, what + (f" in each of {procs} worker processes" if procs > 1 else ""),
                     hint + (" or --workers" if procs > 1 else ""))
    check_count(n, MAX_RUN_SAMPLES, f"{what} is too long a record", hint)


@dataclass(frozen=True)
class MonteCarloOptions:
    """What ``inscal montecarlo`` is asked: ``runs`` runs per configuration point of the study ``experiment``
    (its parameters ``params`` over its defaults) in the folder ``out`` (``force``: discard a different study
    found there), run ``i`` seeded by ``SeedSequence(seed).spawn(total)[i]``; on ``scheduler`` (local,
    synchronous or an address) with ``workers`` and ``batch_size`` runs per task, or in this process
    (``no_dask``); ``progress`` on standard error; at most ``max_new_runs`` new runs (None: all).  The
    experiment, ``runs`` and ``out`` are required (None only for ``inscal montecarlo --list``)."""

    experiment: Annotated[str | None, typer.Argument(help=(
        "built-in experiment (n25-fig5, n25-schemes); --list shows them"))] = None
    runs: Annotated[int | None, typer.Option("--runs", "-n", help="runs per configuration point")] = None
    out: out_option("study folder (results, summary, plot); rerun to resume", required=False) = None
    seed: Annotated[int, typer.Option("--seed", metavar="SEED", help=(
        "root seed: run i uses SeedSequence(seed).spawn(total)[i]"))] = 0
    params: dict | None = None  # --set KEY=VALUE (parse_set)
    scheduler: option("--scheduler", "Dask scheduler address, 'local' (default: a LocalCluster) or 'synchronous'",
                      str) = None
    workers: WorkersOption = None
    batch_size: option("--batch-size", "runs per Dask task (default: about 4 tasks per worker, at most 25)", int) = None
    no_dask: Annotated[bool, typer.Option("--no-dask", help="run in this process, one run after another")] = False
    force: Annotated[bool, typer.Option("--force", help="discard a different study found in --out")] = False
    progress: bool = True
    max_new_runs: int | None = None


def run_montecarlo(o: MonteCarloOptions) -> tuple[dict, object, object]:
    """Run or resume the study of ``o`` (:class:`MonteCarloOptions`) and write its summary; returns (summary
    dict, Summary, paths)."""
    from inscal.analysis import montecarlo as mc
    from inscal.analysis import studies

    scheduler = check_scheduler(o.scheduler, ("local", "synchronous", "sync"))
    if o.no_dask:
        if scheduler not in (None, "synchronous", "sync"):
            raise CliError("--no-dask and --scheduler ADDRESS contradict each other")
        scheduler = "synchronous"
    if o.workers is not None and scheduler not in (None, "local"):
        raise CliError("--workers applies to the default LocalCluster only")
    try:
        exp = studies.get_experiment(o.experiment, o.params)
    except mc.StudyError as exc:
        raise CliError(str(exc)) from None
    check_size(exp, o.runs, scheduler, o.workers)
    try:
        res = mc.run_study(exp, o.out, o.runs, o.seed, scheduler=scheduler, workers=o.workers,
                           batch_size=o.batch_size, force=o.force, progress=o.progress, max_new_runs=o.max_new_runs)
        summ = mc.summarize(exp, res)
        paths = mc.write_outputs(exp, summ, o.out)
    except mc.StudyError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write the study in {short(o.out)}: {exc.strerror or exc}") from None
    d = summ.to_dict()
    d["out"] = str(o.out)
    d["files"] = {k: str(v) for k, v in {**paths, "runs": Path(o.out) / mc.RUNS_FILE}.items()}
    d["new_runs"] = res.n_new
    d["wall_s"] = round(res.elapsed_s, 3)
    d["complete"] = res.complete()
    return d, summ, paths


def register(app: typer.Typer) -> None:
    @app.command()
    @with_options(MonteCarloOptions, before="set_")
    def montecarlo(
        set_: Annotated[list[str] | None, typer.Option("--set", metavar="NAME=VALUE", help=(
            "experiment parameter KEY=VALUE (VALUE as JSON), repeatable"))] = None,
        json_: JsonOption = False,
        no_progress: NoProgressOption = False,
        list_: bool = typer.Option(False, "--list", help="list the built-in experiments and their parameters"),
        **options,
    ):
        """Seeded Monte Carlo study of a calibration experiment, resumable, on Dask."""
        from inscal.analysis import studies

        if list_:
            exps = studies.available_experiments()
            info = {k: {"description": d, "defaults": studies.get_experiment(k).params} for k, d in exps.items()}
            if json_:
                print_json(info)
            else:
                for k, v in info.items():
                    typer.echo(f"{k}: {v['description']}\n    defaults: {json.dumps(v['defaults'])}")
            return
        if None in (options["experiment"], options["runs"], options["out"]):
            raise fail("EXPERIMENT, --runs and --out are required (or --list)")
        try:
            d, summ, _ = run_montecarlo(options_of(MonteCarloOptions, options, params=parse_set(set_),
                                                   progress=not (no_progress or json_)))
        except CliError as exc:
            raise fail(str(exc)) from None
        except KeyboardInterrupt:
            typer.echo("inscal: interrupted; finished runs are saved, rerun the same command to resume", err=True)
            raise typer.Exit(130) from None
        if json_:
            print_json(d)
        else:
            format_table(summ, file=sys.stdout)
            typer.echo(f"{d['new_runs']} new run(s) in {d['wall_s']:.1f} s; files: "
                       + ", ".join(f"{v}" for v in d["files"].values()))


def format_table(summary: "Summary", file=None, width: int | None = None):
    """Print the summary as Rich table(s) (stdout by default) that fit ``width`` columns (default:
    ``$COLUMNS``, else the terminal's width, else 80) without cutting a number: numbers with 4
    significant digits, headers wrap at spaces, and a table too wide is split into parts that
    repeat the leading label columns (parameter, unit)."""
    import shutil

    from rich import box
    from rich.console import Console
    from rich.table import Table

    f = file or sys.stdout
    if width is None:
        width = shutil.get_terminal_size((80, 24)).columns
    width = max(40, int(width))
    con = Console(file=f, width=width, soft_wrap=False, highlight=False)
    cols = list(summary.columns)
    cells = [[format_cell(row.get(k)) for k, _ in cols] for row in summary.rows]
    # leading label columns (no numbers in them): repeated in every part
    nkey = 0
    for i, (k, _) in enumerate(cols[:-1]):
        if i >= 2 or any(isinstance(row.get(k), (int, float)) and not isinstance(row.get(k), bool) for row in summary.rows):
            break
        nkey = i + 1

    import io as _io

    def need(i) -> int:  # a column's width: its widest cell, or its header's longest word
        words = cols[i][1].split()
        return max([len(c[i]) for c in cells] + [max((len(w) for w in words), default=1)])

    def table(idx, title=None):
        t = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False, title_justify="left")
        for i in idx:
            t.add_column(cols[i][1], justify="left" if i < nkey else "right", width=need(i), overflow="fold")
        for c in cells:
            t.add_row(*[c[i] for i in idx])
        return t

    def fits(idx) -> bool:
        buf = _io.StringIO()
        Console(file=buf, width=10 * width, soft_wrap=False).print(table(idx))
        return max((len(line) for line in buf.getvalue().splitlines()), default=0) <= width

    keys = list(range(nkey))
    parts, cur = [], []
    for i in range(nkey, len(cols)):
        if cur and not fits(keys + cur + [i]):
            parts.append(cur)
            cur = []
        cur.append(i)
    parts.append(cur)
    for n, part in enumerate(parts):
        title = summary.title if len(parts) == 1 else f"{summary.title} (part {n + 1} of {len(parts)})"
        con.print(table(keys + part, title))
    for n in summary.notes:
        con.print(f"note: {n}")


def format_cell(v) -> str:
    """A table cell: 4 significant digits (an exponent only outside 1e-3 .. 1e5, as ``1.23e-5``)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        if v == 0 or 1e-3 <= abs(v) < 1e5:
            return f"{v:.4g}"
        m, e = f"{v:.3g}".split("e") if "e" in f"{v:.3g}" else (f"{v:.3g}", "")
        return m + (f"e{int(e)}" if e else "")
    return str(v)
