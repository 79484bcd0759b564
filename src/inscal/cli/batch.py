"""``inscal batch``: calibrate many records into the calibration database, on Dask (a LocalCluster by
default, an existing cluster by address) or in this process; resumable, one line per failed record.

Exit status: 0 every record calibrated or recorded already, 1 some record failed (one line each on
stderr; the others are recorded), 2 a bad invocation (nothing calibrated), 130 / 143 interrupted
(the results committed by then stay; run the same command again to finish)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.calibrate_setup import SetupOptions
from inscal.cli.common import CliError, call, check_scheduler, fail, print_json, short
from inscal.cli.guards import recovery_note
from inscal.cli.limits import DASK_WORKER_BYTES, check_count, check_memory
from inscal.cli.options import (
    DbOption,
    JsonOption,
    NoProgressOption,
    OperatorOption,
    WorkersOption,
    method_option,
    option,
    options_of,
    scheduler_option,
    station_option,
    with_options,
)

#: most records of one batch (10^6: months of calibrations at a few seconds each)
MAX_RECORDS = 10**6


class BatchProgress:
    """The batch's progress (:class:`inscal.core.progress.ProgressBar`): a Rich bar on a terminal; otherwise a
    plain line at every 10 % of the records and at least every 30 s; nothing when disabled.  A failed record's
    line is printed in any case.

    The time left is the mean worker time of a calibrated record so far x the records left / the
    workers (set once the cluster is known): the start of the cluster and the records skipped as
    recorded already do not distort it."""

    def __init__(self, total: int, enabled: bool):
        self.total, self.done, self.skipped, self.failed, self.calibrated = total, 0, 0, 0, 0
        from inscal.core.progress import ProgressBar  # rich: loaded for a batch only (fast start)

        self.work_s, self.workers = 0.0, 1
        self.bar = ProgressBar("batch", total, enabled)

    def eta_s(self) -> float | None:
        """Seconds left (None before the first record calibrated)."""
        if self.calibrated == 0:
            return None
        return self.work_s / self.calibrated * (self.total - self.done) / max(1, self.workers)

    def counts(self) -> str:
        """The records skipped and failed so far, in words."""
        parts = [f"{self.skipped} skipped" if self.skipped else "", f"{self.failed} failed" if self.failed else ""]
        return ", ".join(p for p in parts if p)

    def advance(self, outcome) -> None:
        """One more record done (:class:`inscal.runs.batch.Outcome`)."""
        self.done += 1
        self.skipped += outcome.status == "skipped"
        self.failed += outcome.status == "failed"
        if outcome.elapsed_s > 0:  # calibrated (or failed) in a worker
            self.calibrated += 1
            self.work_s += outcome.elapsed_s
        if outcome.status == "failed":
            self.bar.print(f"inscal: failed: {short(outcome.path)}: {outcome.error}")
        from inscal.core.progress import duration

        eta = self.eta_s()
        note = ", ".join(p for p in (self.counts(), "" if eta is None else f"~{duration(eta)} left") if p)
        self.bar.update(self.done, note=note, line=self.plain_line)

    def plain_line(self) -> str:
        """The progress line of a log: records done, skipped and failed, time elapsed and left."""
        from inscal.core.progress import duration

        eta = self.eta_s()
        per = "" if eta is None else (f", about {duration(eta)} left ({self.work_s / self.calibrated:.3g} s per "
                                      f"record, {self.workers} worker{'s' if self.workers != 1 else ''})")
        counts = self.counts()
        return (f"batch: {self.done}/{self.total} record{'s' if self.total != 1 else ''} "
                f"({100 * self.done / max(1, self.total):.0f} %){', ' + counts if counts else ''}; "
                f"{duration(self.bar.elapsed_s)} elapsed{per}")

    def close(self) -> None:
        """Stop the bar."""
        self.bar.close()


def batch_items(records: list[str] | None, serial: str | None, names: str | None, manifest: Path | None,
                station: str | None, operator: str | None):
    """The records of the batch with their units (see :mod:`inscal.runs.batch`)."""
    from inscal.runs import batch as lb

    if manifest is not None:
        if records:
            raise CliError("give the records either as arguments or in --manifest, not both")
        if serial is not None or names is not None:
            raise CliError("--manifest gives each record's serial: --serial and --names do not apply")
        return lb.read_manifest(manifest, station, operator)
    if not records:
        raise CliError("give the records (folders, files or glob patterns) or --manifest FILE.csv")
    return lb.items_from_names(lb.find_records(records), names or lb.DEFAULT_NAMES, serial, station, operator)


def check_batch_size(items, setup, scheduler: str, workers: int | None) -> None:
    """Refuse up front (one line) a batch of more than :data:`MAX_RECORDS` records, a local cluster larger
    than the memory, and a largest record that the workers calibrating it at once would not fit in."""
    from inscal import io

    check_count(len(items), MAX_RECORDS, f"{len(items)} records", "split the batch")
    local = scheduler == "local"
    procs = min(workers or os.cpu_count() or 1, len(items)) if local else (1 if scheduler == "none" else 0)
    if local and procs > 1:
        check_memory(procs * DASK_WORKER_BYTES, f"--workers {procs}{' (the default: one per core)' if workers is None else ''}"
                     f" (a local Dask cluster of {procs} processes)", "lower --workers")
    sizes = []
    for it in items:
        try:
            sizes.append((it.path.stat().st_size, it))
        except OSError:
            continue
    if not sizes or not procs:
        return
    big = max(sizes, key=lambda s: s[0])[1]
    try:
        info = io.record_info(big.path)
    except (io.DataFileError, OSError, KeyError, TypeError, ValueError):
        return  # the record fails with its reason
    for need, what, hint in setup.memory_needs(info, f"the largest record, {short(big.label, 60)},"):
        many = f" in each of {procs} workers at once" if procs > 1 else ""
        check_memory(procs * need, what + many, hint + (" or lower --workers" if procs > 1 else ""))


@dataclass(frozen=True)
class BatchOptions(SetupOptions):
    """What ``inscal batch`` is asked: calibrate ``records`` (files, folders, glob patterns; or a ``manifest``)
    with ``method`` into the database ``db``, on ``scheduler`` (local, none or an address) with ``workers``; the
    units from ``serial`` or the file ``names``, registered (as ``model``) when ``register_units``; the session's
    ``station`` and ``operator``; the calibration's options as for ``inscal calibrate`` (:class:`SetupOptions`);
    ``progress`` on standard error; ``wait`` [s] for another writer of the database."""

    method: method_option("six-position | twelve-position | n25 | joint | systematic51 | systematic30 | unified | "
                          "multi-position | ferraris")
    records: Annotated[list[str] | None, typer.Argument(help=(
        "records: folders (their *.h5 and *.hdf5), files or glob patterns (quoted: 'runs/FOG-*.h5'); or "
        "--manifest"))] = None
    db: DbOption = None
    scheduler: scheduler_option("local; its workers must see the records and the database") = None
    workers: WorkersOption = None
    serial: option("--serial", "every record is of this unit", str, "SERIAL") = None
    names: option("--names", "file-name pattern giving each record's unit and date, with {serial}, {date} (2025-01-15 "
                  "or 20250115) and * (default: {serial}_{date}.h5; a name that does not match: the record's "
                  "imu_serial attribute and creation time)", str, "PATTERN") = None
    manifest: option("--manifest", "CSV with a header and columns path,serial and optionally "
                     "date,station,operator,temperature_c (paths relative to it)", Path, "FILE.csv") = None
    register_units: Annotated[bool, typer.Option("--register", help=(
        "register the units not in the database yet (else their records fail)"))] = False
    model: option("--model", "with --register: the model of the units registered", str, "MODEL") = None
    station: station_option("the turntable / station of the runs (a manifest's column wins)") = None
    operator: OperatorOption = None
    progress: bool = True
    wait: option("--wait", "seconds a record's write waits for another writer of the database before it fails naming "
                 "it (default 10)", metavar="SECONDS") = None


def run_batch(o: BatchOptions) -> dict:
    """Calibrate the records of ``o`` (:class:`BatchOptions`) into its database and return the JSON report
    (counts, failures, every record's outcome); a bad invocation raises :class:`CliError` before anything is
    calibrated.  ``o.noise``: a noise.toml for the systematic filter, as ``inscal calibrate --noise``."""
    import sqlalchemy

    from inscal.lab import DatabaseError, check_wait
    from inscal.runs import batch as lb

    setup = o.calibration_setup(o.method, None if o.noise is None else str(o.noise.resolve()))
    if (msg := setup.problem()) is not None:
        raise CliError(msg)
    scheduler, workers = check_scheduler(o.scheduler or "local", ("local", "none")), o.workers
    if workers is not None and (workers < 1 or scheduler != "local"):
        raise CliError(f"--workers {workers}: a number >= 1 of processes of the default local cluster"
                       if workers < 1 else "--workers applies to the default local cluster only")
    if o.model is not None and not o.register_units:
        raise CliError("--model is the model of the units --register registers: give --register")
    try:
        wait_s = lb.BATCH_WAIT_S if o.wait is None else check_wait(o.wait)
    except DatabaseError as exc:
        raise CliError(str(exc)) from None
    try:
        items = batch_items(list(o.records or ()), o.serial, o.names, o.manifest, o.station, o.operator)
        check_batch_size(items, setup, scheduler, workers)
        bar = BatchProgress(len(items), o.progress)

        def workers_known(n: int) -> None:
            bar.workers = n

        try:
            res = lb.run_batch(o.db, items, setup, scheduler=scheduler, workers=workers, register=o.register_units,
                               model=o.model, on_outcome=bar.advance, on_workers=workers_known, wait_s=wait_s)
        finally:
            bar.close()
    except (lb.BatchError, DatabaseError) as exc:
        raise CliError(str(exc)) from None
    except sqlalchemy.exc.SQLAlchemyError as exc:
        raise CliError(f"database: {' '.join(str(getattr(exc, 'orig', None) or exc).split())[:400]}") from None
    return {"method": o.method, "options": setup.options(), "scheduler": scheduler} | res.to_json()


def summary_line(rep: dict) -> str:
    """The batch's summary in one line: records calibrated, skipped and failed, units registered, time."""
    from inscal.core.progress import duration

    per = "" if rep["seconds_per_record"] is None else f", {rep['seconds_per_record']:.3g} s per record"
    reg = f"; registered {len(rep['registered'])} unit{'s' if len(rep['registered']) != 1 else ''}" if rep["registered"] \
        else ""
    on = f" on {rep['workers']} worker{'s' if rep['workers'] != 1 else ''}" if rep["workers"] else ""
    return (f"batch of {rep['records']} record{'s' if rep['records'] != 1 else ''} into {rep['db']}: {rep['done']} calibrated, {rep['skipped']} skipped "
            f"(recorded already), {rep['failed']} failed{reg}; {duration(rep['wall_s'])}{on}{per}")


def register(app: typer.Typer) -> None:
    @app.command()
    @with_options(BatchOptions, before="json_")
    def batch(
        json_: JsonOption = False,
        no_progress: NoProgressOption = False,
        **options,
    ):
        """Calibrate many records into the calibration database (Dask), skipping the ones recorded already."""
        opts = options_of(BatchOptions, options, progress=not (no_progress or json_))
        rep = call(run_batch, opts)
        for line in rep.get("recovered", []):
            recovery_note(line)
        if json_:
            print_json(rep)
        else:
            typer.echo(summary_line(rep))
        if rep["failed"]:
            raise typer.Exit(1)
