"""Seeded, resumable Monte Carlo studies, run locally or on Dask.

A study is an :class:`Experiment` (a list of configuration points and a function doing
one run at one point with one random generator) repeated ``runs`` times per point.

Seeds
    With ``P`` points and ``R`` runs per point, run ``i = r * P + p`` (repetition ``r``
    at point ``p``) draws every random number from ``np.random.default_rng(children[i])``,
    ``children = np.random.SeedSequence(seed).spawn(R * P)``.  Child ``i`` has spawn key
    ``(i,)`` whatever ``R`` is, so the mapping run -> seed never changes: a resumed study
    gives the same numbers as an uninterrupted one, and raising ``--runs`` later extends
    a study without changing the runs already done.

Results file
    ``DIR/runs.jsonl`` (JSON Lines).  Line 1 is a header (schema version, experiment name
    and version, resolved parameters, configuration points, seed); every further line is
    one run (``run``, ``point``, ``rep``, ``result`` or ``error``, ``elapsed_s``), written
    and flushed as soon as the run's batch returns.  On restart the completed runs are
    read back and skipped; a truncated last line (a killed writer) is cut off.  A run
    that raised is recorded with its error, left out of the summary (and counted there),
    and retried on the next restart; a study whose first 20 new runs all fail stops.  A file
    written for another experiment, other parameters or another seed is refused unless
    ``force`` (which discards it).  ``runs`` is not part of the identity (see Seeds).
    While a study runs it holds an exclusive lock on the file.

Execution
    ``scheduler=None`` or ``"local"``: a ``distributed.LocalCluster`` (one single-threaded
    worker process per core unless ``workers`` says otherwise); ``"synchronous"``: a plain
    loop in this process (tests, debugging, profiling); anything else: the address of a
    running Dask scheduler (its workers need ``inscal`` installed).  Runs are grouped in
    batches (same point, consecutive repetitions) to amortise the task overhead, and
    collected with ``distributed.as_completed``.  The experiment's ``warmup`` runs once
    in this process first, so the numba on-disk cache (``cache=True`` on every kernel) is
    populated before the workers start and they load compiled code instead of compiling.

Outputs
    :func:`write_outputs` writes ``summary.json``, ``summary.csv`` and ``summary.png``
    (matplotlib, Agg backend) next to the results file.
"""

from __future__ import annotations

import csv
import datetime as _dt
import fcntl
import json
import math
import os
import shutil
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from inscal import __version__ as inscal_version
from inscal.core.parallel import LOCAL_WORKER_ENVIRON, start_client
from inscal.core.progress import ProgressBar, duration
from inscal.core.stats import chi2_ppf
from inscal.io.jsonfile import to_jsonable

#: version of the layout of a study folder's run files
SCHEMA_VERSION = 1
RUNS_FILE = "runs.jsonl"
#: a study stops when its first this-many new runs all fail (a broken setup, not bad luck)
FAIL_FAST_RUNS = 20
#: how long to try to reach a Dask scheduler given by address
CONNECT_TIMEOUT = "15s"
SUMMARY_JSON = "summary.json"
SUMMARY_CSV = "summary.csv"
SUMMARY_PNG = "summary.png"


class StudyError(ValueError):
    """A study cannot be started or continued (mismatched folder, bad parameters...)."""


# ---------------------------------------------------------------------------- data types
@dataclass
class Summary:
    """A study's summary: a table (``columns`` = [(key, header)], ``rows`` = dicts) plus
    free-form ``data`` for plots and notes."""

    title: str
    columns: list[tuple[str, str]]
    rows: list[dict]
    notes: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"title": self.title, "columns": [{"key": k, "header": h} for k, h in self.columns],
                "rows": self.rows, "notes": self.notes, "data": self.data}


@dataclass(frozen=True)
class Experiment:
    """What a study repeats.

    ``run(experiment, point_index, rng) -> dict`` does one run and returns a
    JSON-serialisable dict; it must draw every random number from ``rng``.
    ``summarize(experiment, results) -> Summary`` gets, for each point, the list of the
    successful results in run order.  ``plot(experiment, summary, path)`` draws the
    summary (optional).  ``warmup(experiment)`` is called once in the driver before any
    worker starts (optional).  Every callable must be picklable (module-level) for Dask.
    """

    name: str
    params: dict
    points: tuple
    run: Callable[["Experiment", int, np.random.Generator], dict]
    summarize: Callable[["Experiment", list[list[dict]]], Summary]
    plot: Callable[["Experiment", Summary, Path], None] | None = None
    warmup: Callable[["Experiment"], None] | None = None
    version: int = 1
    description: str = ""

    def point_label(self, p: int) -> str:
        return ", ".join(f"{k}={v}" for k, v in self.points[p].items())


# -------------------------------------------------------------------------------- seeds
def run_layout(n_points: int, runs: int) -> list[tuple[int, int, int]]:
    """``(run id, point, repetition)`` for every run of a study, run-major
    (``id = rep * n_points + point``)."""
    return [(r * n_points + p, p, r) for r in range(runs) for p in range(n_points)]


def seed_children(seed: int, total: int) -> list[np.random.SeedSequence]:
    """``SeedSequence(seed).spawn(total)``: child ``i`` seeds run ``i``."""
    return np.random.SeedSequence(seed).spawn(total)


# ------------------------------------------------------------------------------ JSON I/O
def _canonical(o) -> str:
    return json.dumps(to_jsonable(o), sort_keys=True)


def make_header(experiment: Experiment, seed: int) -> dict:

    return {
        "type": "header",
        "schema": SCHEMA_VERSION,
        "experiment": experiment.name,
        "experiment_version": experiment.version,
        "params": to_jsonable(experiment.params),
        "points": to_jsonable(list(experiment.points)),
        "seed": int(seed),
        "seed_scheme": "run i = rep * n_points + point uses default_rng(SeedSequence(seed).spawn(total)[i])",
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "inscal_version": inscal_version,
    }


_IDENTITY = ("schema", "experiment", "experiment_version", "params", "points", "seed")


def _header_mismatch(old: dict, new: dict) -> list[str]:
    """What differs between two headers' identities (``points`` only if ``params`` agree,
    as the points follow from the parameters)."""
    diffs = []
    for k in _IDENTITY:
        a, b = old.get(k), new.get(k)
        if _canonical(a) == _canonical(b):
            continue
        if k == "params" and isinstance(a, dict) and isinstance(b, dict):
            diffs += [f"params.{p} ({_canonical(a.get(p))} here, {_canonical(b.get(p))} asked)"
                      for p in sorted(set(a) | set(b)) if _canonical(a.get(p)) != _canonical(b.get(p))]
        elif k == "points" and any(d.startswith("params.") for d in diffs):
            continue
        else:
            diffs.append(f"{k} ({_canonical(a)} here, {_canonical(b)} asked)")
    return diffs


def _keep(records: dict[int, dict], rec: dict) -> None:
    """Store a run's record: the first successful one wins; a success replaces an error
    (a failed run is retried when the study is resumed)."""
    old = records.get(rec["run"])
    if old is None or ("error" in old and "error" not in rec):
        records[rec["run"]] = rec


def read_results(path: Path, repair: bool = False) -> tuple[dict, dict[int, dict]]:
    """Header and ``{run id: record}`` of a results file.  A truncated (unparsable) last
    line is ignored, and cut off the file when ``repair``; a bad line elsewhere is an error."""
    path = Path(path)
    with open(path, "rb") as fh:
        raw = fh.read()
    lines = raw.split(b"\n")
    # the last element is b"" when the file ends with a newline
    good_end = 0
    header = None
    records: dict[int, dict] = {}
    pos = 0
    for k, line in enumerate(lines):
        end = pos + len(line) + 1
        is_last = k == len(lines) - 1 or (k == len(lines) - 2 and lines[-1] == b"")
        if line.strip():
            try:
                obj = json.loads(line)
                if not isinstance(obj, dict):
                    raise ValueError("not an object")
                complete = end <= len(raw)  # a newline follows
                if not complete:
                    raise ValueError("no newline")
            except ValueError:
                if is_last:
                    break
                raise StudyError(f"{path}: line {k + 1} is not valid JSON; the file is damaged") from None
            if header is None:
                if obj.get("type") != "header":
                    raise StudyError(f"{path}: first line is not a study header")
                header = obj
            else:
                rid = obj.get("run")
                if not isinstance(rid, int):
                    raise StudyError(f"{path}: line {k + 1} has no integer 'run'")
                _keep(records, obj)
        good_end = min(end, len(raw))
        pos = end
    if header is None:
        raise StudyError(f"{path}: no study header")
    if repair and good_end < len(raw):
        with open(path, "r+b") as fh:
            fh.truncate(good_end)
    return header, records


# ------------------------------------------------------------------------------ workers
def _run_one(experiment: Experiment, rid: int, point: int, rep: int, child: np.random.SeedSequence) -> dict:
    t0 = time.perf_counter()
    rec: dict[str, Any] = {"run": rid, "point": point, "rep": rep}
    try:
        rec["result"] = to_jsonable(experiment.run(experiment, point, np.random.default_rng(child)))
    except Exception as exc:  # a failed run is recorded, not fatal to the study
        rec["error"] = f"{type(exc).__name__}: {exc}"
    rec["elapsed_s"] = round(time.perf_counter() - t0, 4)
    return rec


def run_batch(experiment: Experiment, items: Sequence[tuple[int, int, int, np.random.SeedSequence]]) -> list[dict]:
    """Do a batch of runs (the Dask task)."""
    return [_run_one(experiment, *it) for it in items]


def make_batches(items: list[tuple[int, int, int, Any]], batch_size: int) -> list[list]:
    """Group runs by point into batches of consecutive repetitions, then interleave the
    points (so an interrupted study has covered every point about equally)."""
    by_point: dict[int, list] = {}
    for it in items:
        by_point.setdefault(it[1], []).append(it)
    per_point = [[v[i:i + batch_size] for i in range(0, len(v), batch_size)] for _, v in sorted(by_point.items())]
    out = []
    for k in range(max((len(b) for b in per_point), default=0)):
        out += [b[k] for b in per_point if k < len(b)]
    return out


def default_batch_size(n_pending: int, n_workers: int) -> int:
    """About 4 tasks per worker, at most 25 runs per task."""
    return max(1, min(25, math.ceil(n_pending / max(1, 4 * n_workers))))


# -------------------------------------------------------------------------------- study
@dataclass
class StudyResult:
    out: Path
    header: dict
    records: dict[int, dict]
    runs: int
    n_new: int
    elapsed_s: float
    stopped_early: bool = False

    @property
    def n_points(self) -> int:
        return len(self.header["points"])

    def complete(self) -> bool:
        return all(i in self.records for i in range(self.runs * self.n_points))


class _Appender:
    """Append records to the results file, flushed and fsync'ed after every batch."""

    def __init__(self, path: Path):
        self.fh = open(path, "a", encoding="utf-8")

    def write(self, records: Iterable[dict]) -> None:
        for rec in records:
            self.fh.write(json.dumps(rec) + "\n")
        self.fh.flush()
        os.fsync(self.fh.fileno())

    def close(self) -> None:
        self.fh.close()


class _FolderLock:
    """An exclusive lock on ``DIR/.lock`` for the duration of a study (released by the OS
    if the process dies), so two processes never append to the same study."""

    def __init__(self, out: Path):
        self.fh = open(out / ".lock", "a")
        try:

            fcntl.flock(self.fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # pragma: no cover - non-POSIX
            pass
        except OSError:
            self.fh.close()
            raise StudyError(f"{out} is in use by another running study") from None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.fh.close()


def open_study(experiment: Experiment, out: Path, seed: int, force: bool = False) -> tuple[Path, dict, dict[int, dict]]:
    """Create ``out/runs.jsonl`` or check the one there; return (path, header, records)."""
    out = Path(out)
    path = out / RUNS_FILE
    new = make_header(experiment, seed)
    if path.exists() and path.stat().st_size > 0 and not force:
        old, records = read_results(path, repair=True)
        diffs = _header_mismatch(old, new)
        if diffs:
            raise StudyError(
                f"{path} holds a different study (experiment {old.get('experiment')!r}, seed {old.get('seed')}); "
                f"it differs in: {'; '.join(diffs)}. Use another --out folder, or --force to discard it")
        return path, old, records
    for name in (RUNS_FILE, SUMMARY_JSON, SUMMARY_CSV, SUMMARY_PNG):
        if (out / name).exists():
            (out / name).unlink()
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(json.dumps(new) + "\n")
        fh.flush()
        os.fsync(fh.fileno())
    return path, new, {}


def run_study(experiment: Experiment, out, runs: int, seed: int = 0, *, scheduler: str | None = None,
              workers: int | None = None, batch_size: int | None = None, force: bool = False,
              progress: bool = False, max_new_runs: int | None = None, warmup: bool = True) -> StudyResult:
    """Run (or resume) a study; see the module docstring.

    ``max_new_runs`` stops after that many new runs (to spread a study over sessions, or
    to emulate an interruption in tests).
    """
    if not (isinstance(runs, (int, np.integer)) and runs >= 1):
        raise StudyError(f"runs must be a positive integer, got {runs!r}")
    if workers is not None and workers < 1:
        raise StudyError("workers must be >= 1")
    if batch_size is not None and batch_size < 1:
        raise StudyError("batch size must be >= 1")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise StudyError(f"seed must be a non-negative integer, got {seed!r}")
    t0 = time.perf_counter()
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise StudyError(f"{out} exists and is not a folder")
    created = _first_missing(out)  # the topmost folder this call creates (None: out exists)
    try:
        out.mkdir(parents=True, exist_ok=True)
        return _run_study_in(experiment, out, runs, seed, scheduler, workers, batch_size, force, progress,
                             max_new_runs, warmup, t0)
    except BaseException as exc:
        # a study that failed to start leaves no folder behind that it created (one with runs
        # recorded is kept, so that it can be resumed)
        if created is not None and not _has_finished_runs(out):
            shutil.rmtree(created, ignore_errors=True)
        if isinstance(exc, OSError) and not isinstance(exc, StudyError):
            raise StudyError(f"cannot write the study in {out}: {exc.strerror or exc}") from None
        raise


def _first_missing(out: Path) -> Path | None:
    """The topmost ancestor of ``out`` (or ``out`` itself) that does not exist, else None."""
    missing = None
    for p in [out, *out.parents]:
        if p.exists():
            break
        missing = p
    return missing


def _has_finished_runs(out: Path) -> bool:
    """Whether ``out`` holds a results file with at least one run (failed runs included: they
    show what went wrong and are retried on resume)."""
    path = out / RUNS_FILE
    try:
        with open(path, encoding="utf-8") as fh:
            for k, line in enumerate(fh):
                if k == 0 or not line.strip():
                    continue
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                if isinstance(rec, dict) and "run" in rec:
                    return True
    except OSError:
        pass
    return False


def _run_study_in(experiment, out, runs, seed, scheduler, workers, batch_size, force, progress, max_new_runs,
                  warmup, t0) -> StudyResult:
    with _FolderLock(out):
        path, header, records = open_study(experiment, out, int(seed), force)
        P = len(experiment.points)
        layout = run_layout(P, int(runs))
        children = seed_children(int(seed), len(layout))
        # runs not done yet, and failed runs (retried: the failure may have been fixed)
        pending = [(rid, p, r, children[rid]) for rid, p, r in layout if rid not in records or "error" in records[rid]]
        stopped = False
        if max_new_runs is not None and len(pending) > max_new_runs:
            pending = pending[:max_new_runs]
            stopped = True
        n_new = 0
        if pending:
            if warmup and experiment.warmup is not None:
                experiment.warmup(experiment)
            appender = _Appender(path)
            bar = _Progress(len(pending), experiment.name, enabled=progress)
            try:
                # fail fast on a broken setup: the first new (never tried) runs all failed
                fresh = {it[0] for it in pending if it[0] not in records}
                fresh_done = fresh_failed = 0
                fail_fast = min(FAIL_FAST_RUNS, len(fresh))

                def sink(recs):
                    nonlocal n_new, fresh_done, fresh_failed
                    appender.write(recs)
                    for rec in recs:  # new runs only: missing or previously failed
                        records[rec["run"]] = rec
                        if rec["run"] in fresh:
                            fresh_done += 1
                            fresh_failed += "error" in rec
                    n_new += len(recs)
                    bar.advance(len(recs), sum(1 for r in recs if "error" in r),
                                sum(float(r.get("elapsed_s") or 0.0) for r in recs))
                    if fail_fast and fresh_failed == fresh_done >= fail_fast:
                        first = next(r["error"] for r in recs if "error" in r)
                        raise StudyError(f"the first {fresh_done} new runs all failed, stopping the study; first error: {first}")

                if scheduler in ("synchronous", "sync"):
                    bar.workers = 1
                    for it in pending:
                        sink([_run_one(experiment, *it)])
                else:
                    _run_dask(experiment, pending, scheduler, workers, batch_size, sink, bar)
            finally:
                bar.close()
                appender.close()
    return StudyResult(out, header, records, int(runs), n_new, time.perf_counter() - t0, stopped)


@contextmanager
def dask_client(scheduler: str | None, workers: int | None):
    """The study's Dask client (:func:`inscal.core.parallel.start_client`: a local cluster of ``workers``
    single-threaded processes, default one per core, with :data:`LOCAL_WORKER_ENVIRON`, or the scheduler at an
    address, refused with :class:`StudyError`), closed with its cluster when the block ends."""
    client, cluster = start_client(scheduler, workers or os.cpu_count() or 1, CONNECT_TIMEOUT, StudyError,
                                   LOCAL_WORKER_ENVIRON)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


@contextmanager
def ordered_map(workers: int = 1, scheduler: str | None = None):
    """A map of the engine for work whose seeds the caller lays out itself (the JCGM 101 Monte Carlo of a budget,
    :mod:`inscal.uncertainty.montecarlo`): ``map_fn(fn, *iterables)`` yields ``fn``'s results in order, in this
    process (the builtin :func:`map`) for one worker and no scheduler, else as tasks on :func:`dask_client`'s
    cluster, started once for the block."""
    if workers <= 1 and scheduler in (None, "synchronous", "sync"):
        yield map
        return
    with dask_client(scheduler, workers) as client:
        def map_fn(fn, *iterables):
            return (f.result() for f in client.map(fn, *(list(x) for x in iterables), pure=False))

        yield map_fn


def _run_dask(experiment, pending, scheduler, workers, batch_size, sink, bar=None) -> None:

    from distributed import as_completed

    with dask_client(scheduler, workers) as client:
        n_workers = max(1, sum(client.nthreads().values()))
        if bar is not None:
            bar.workers = n_workers
        bs = batch_size or default_batch_size(len(pending), n_workers)
        exp_future = client.scatter(experiment, broadcast=True)
        futures = [client.submit(run_batch, exp_future, b, pure=False) for b in make_batches(pending, bs)]
        try:
            for fut in as_completed(futures):
                try:
                    recs = fut.result()
                except Exception as exc:  # the task itself died (worker lost, unpicklable...): runs raise inside
                    raise StudyError(f"a Dask task failed ({type(exc).__name__}: {exc}); the finished runs are "
                                     "saved, rerun the same command to resume") from exc
                sink(recs)
        except BaseException:
            client.cancel(futures)
            raise


class _Progress:
    """The study's progress (:class:`inscal.core.progress.ProgressBar`): a Rich bar on a terminal; otherwise (a
    log file, CI) a plain line at every 10 % and at least every 30 s.  Nothing when disabled.

    The time left is the mean run time so far (each run's own ``elapsed_s``) x the runs left /
    the workers (``workers``: set by the runner once the cluster is known), not the wall-clock
    rate, which the start of a cluster and the first (compiling) runs distort."""

    def __init__(self, total: int, name: str, enabled: bool, workers: int = 1):
        self.failed, self.done, self.run_s, self.workers, self.total, self.name = 0, 0, 0.0, workers, total, name
        self.bar = ProgressBar(name, total, enabled)

    def eta_s(self) -> float | None:
        """Seconds left: mean run time x runs left / workers (None before the first run)."""
        if self.done == 0:
            return None
        return self.run_s / self.done * (self.total - self.done) / max(1, self.workers)

    def advance(self, n: int, failed: int, run_seconds: float = 0.0) -> None:
        """``n`` more runs done, ``failed`` of them failed, ``run_seconds`` their own time."""
        self.failed += failed
        self.done += n
        self.run_s += run_seconds
        eta = self.eta_s()
        note = ", ".join(p for p in (f"{self.failed} failed" if self.failed else "",
                                     "" if eta is None else f"~{duration(eta)} left") if p)
        self.bar.update(self.done, note=note, line=self.plain_line)

    def plain_line(self) -> str:
        """The progress line of a log: runs done, time elapsed and left, failures."""
        pct = 100 * self.done / max(1, self.total)
        return (f"{self.name}: {self.done}/{self.total} runs ({pct:.0f} %), {duration(self.bar.elapsed_s)} elapsed, "
                f"about {duration(self.eta_s() or 0.0)} left ({self.run_s / max(1, self.done):.3g} s per run, "
                f"{self.workers} worker{'s' if self.workers != 1 else ''})"
                + (f", {self.failed} failed" if self.failed else ""))

    def close(self) -> None:
        """Stop the bar."""
        self.bar.close()


# ----------------------------------------------------------------------------- summary
def grouped_results(n_points: int, runs: int, records: dict[int, dict]) -> tuple[list[list[dict]], list[int], list[list[str]]]:
    """Per point: the successful results of runs ``0 .. runs-1`` in run order, the number
    of runs done, and the error messages."""
    res: list[list[dict]] = [[] for _ in range(n_points)]
    done = [0] * n_points
    errs: list[list[str]] = [[] for _ in range(n_points)]
    for rid, p, _ in run_layout(n_points, runs):
        rec = records.get(rid)
        if rec is None:
            continue
        done[p] += 1
        if "error" in rec:
            errs[p].append(rec["error"])
        else:
            res[p].append(rec["result"])
    return res, done, errs


def summarize(experiment: Experiment, result: StudyResult) -> Summary:
    """The experiment's summary of the first ``result.runs`` runs per point, with the
    run counts, failures and the total run time added to ``data``."""
    res, done, errs = grouped_results(len(experiment.points), result.runs, result.records)
    s = experiment.summarize(experiment, res)
    n_fail = sum(len(e) for e in errs)
    cpu = sum(rec.get("elapsed_s", 0.0) for rid, rec in result.records.items() if rid < result.runs * len(experiment.points))
    s.data.update({"runs_per_point": result.runs, "runs_done": done, "runs_failed": [len(e) for e in errs],
                   "seed": result.header["seed"], "experiment": experiment.name, "params": to_jsonable(experiment.params),
                   "run_seconds_total": round(cpu, 3)})
    if n_fail:
        first = next(e[0] for e in errs if e)
        s.notes.append(f"{n_fail} run(s) failed and are left out; first error: {first}")
    if not result.complete():
        s.notes.append(f"incomplete: {sum(done)} of {result.runs * len(experiment.points)} runs done; rerun the same command to resume")
    return s


def write_outputs(experiment: Experiment, summary: Summary, out) -> dict[str, Path]:
    """``summary.json``, ``summary.csv`` and (if the experiment draws one) ``summary.png``."""
    out = Path(out)
    paths = {"json": out / SUMMARY_JSON, "csv": out / SUMMARY_CSV}
    tmp = paths["json"].with_suffix(".json.tmp")
    tmp.write_text(json.dumps(to_jsonable(summary.to_dict()), indent=2) + "\n", encoding="utf-8")
    tmp.replace(paths["json"])
    with open(paths["csv"], "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow([k for k, _ in summary.columns])
        for row in summary.rows:
            w.writerow(["" if row.get(k) is None else row.get(k) for k, _ in summary.columns])
    if experiment.plot is not None:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot as plt

        paths["png"] = out / SUMMARY_PNG
        try:
            experiment.plot(experiment, summary, paths["png"])
        finally:
            plt.close("all")
    return paths


# ---------------------------------------------------------------------- small statistics
def std_ci(std: float, n: int, level: float = 0.95) -> tuple[float, float]:
    """Confidence interval of a standard deviation from ``n`` normal samples (chi-square)."""

    if n < 2 or not np.isfinite(std):
        return (math.nan, math.nan)
    a = (1 - level) / 2
    return (std * math.sqrt((n - 1) / chi2_ppf(1 - a, n - 1)), std * math.sqrt((n - 1) / chi2_ppf(a, n - 1)))
