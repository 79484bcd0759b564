"""Batch calibration: many records calibrated with one method into the calibration database, on Dask
(a ``distributed.LocalCluster`` by default, an existing cluster by address) or in this process;
resumable, and a record that fails is one line while the rest go on.

Records and their units
    The records are the files named (``*.h5`` / ``*.hdf5`` of a folder, the files a glob matches, or
    the paths of a CSV manifest, :func:`read_manifest`).  A record's unit (serial) is, in this order:
    the manifest's ``serial`` column; ``--serial`` (every record is of that unit); the ``{serial}``
    field of its file name matched against a pattern (:func:`name_pattern`, by default
    ``{serial}_{date}.h5``: ``FOG-0042_2025-01-15.h5``); the record's ``imu_serial`` attribute.  A
    record with none of them fails.  Its date (when it was taken) is the manifest's ``date``, else the
    ``{date}`` of its name, else the record's ``created`` attribute (when the file was written).  A
    record whose ``imu_serial`` attribute names another unit than the one found fails.  Units are
    registered only when asked (``register``: with their first result, so that a unit whose records
    all fail is not registered); otherwise an unknown serial fails its records.

Resuming
    Before a record is calibrated, its sha256 and the canonical options
    (:meth:`~inscal.runs.calibration.CalibrationSetup.options`, the same as ``inscal calibrate
    --serial``'s) are looked up for its unit (:func:`~inscal.lab.queries.find_calibration`): a record
    recorded already is skipped.  Every result is committed in one transaction, so a batch killed at
    any moment leaves whole results only, and running it again calibrates exactly the records
    missing.  The look-up is repeated just before the result is written, under a lock per record
    (PostgreSQL: an advisory lock, released by the server if the process dies; SQLite: ``flock`` of
    ``.NAME.batch.lock`` beside the database file), so two batches over the same records never
    record one twice.  The workers of a local cluster exit with the process that started them
    (distributed's parent monitor), so none goes on writing after the batch is killed.

Execution
    ``scheduler="local"``: a LocalCluster of single-threaded worker processes (one per core unless
    ``workers`` says otherwise; the environment of :data:`inscal.core.parallel.LOCAL_WORKER_ENVIRON`); an address
    (``tcp://HOST:PORT``): that cluster, whose workers need ``inscal`` and must see the record files
    and the database at the same paths; ``"none"``: one record after another in this process.  The
    driver hashes the records and looks each up as it goes, submitting the ones to calibrate one task
    each while the workers calibrate (a local cluster starts at the first record to calibrate; one
    given by address is reached before anything is written).  A worker opens the database once
    (:func:`worker_database`): pooled connections do not cross processes.  An interrupted batch kills
    the workers of its local cluster at once (what they were calibrating is not committed).
"""

from __future__ import annotations

import contextlib
import csv
import datetime as dt
import fcntl
import glob
import hashlib
import math
import os
import re
import signal
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import sqlalchemy as sa

from inscal.core import parallel
from inscal.core.parallel import LOCAL_WORKER_ENVIRON
from inscal.io.files import file_hash, side_name
from inscal.io.records import record_attrs
from inscal.runs.calibration import (
    CalibrationSetup,
    RecordError,
    calibrate_record,
    load_record,
)
from inscal.lab.database import Database, DatabaseError, database_url
from inscal.lab.opening import open_database
from inscal.lab.model import parse_date
from inscal.lab.record import options_hash, session_from_record
from inscal.lab.queries import find_calibration, get_unit
from inscal.lab.store import (
    AlreadyRecorded,
    add_unit,
    check_serial,
    record_result,
)

#: the records of a folder
RECORD_SUFFIXES = (".h5", ".hdf5")
#: the file names of a lab's records: the unit's serial and the date of the run
DEFAULT_NAMES = "{serial}_{date}.h5"
#: the columns of a manifest (path and serial required)
MANIFEST_COLUMNS = ("path", "serial", "date", "station", "operator", "temperature_c")
#: a date in a file name: 2025-01-15 or 20250115, optionally with a time (T1030, T10:30:00Z)
DATE_PATTERN = r"(?P<date>\d{4}-?\d{2}-?\d{2}(?:T\d{2}(?::?\d{2}){0,2}Z?)?)"
#: how long to try to reach a Dask scheduler given by address
CONNECT_TIMEOUT = "15s"
#: the longest failure message kept
MAX_MESSAGE = 500


class BatchError(ValueError):
    """A batch that cannot start (no records, a bad manifest or pattern, no scheduler): one line."""


@dataclass(frozen=True)
class BatchItem:
    """One record of a batch: its file (``path``, absolute; ``label``: as named, for messages), unit,
    session metadata, and ``problem``: why it cannot be calibrated (None: it can)."""

    path: Path
    label: str
    serial: str | None
    date: dt.datetime | None = None
    station: str | None = None
    operator: str | None = None
    temperature_c: float | None = None
    problem: str | None = None


@dataclass(frozen=True)
class Outcome:
    """What became of one record: ``status`` ``done`` (calibrated and recorded as ``result_id``),
    ``skipped`` (recorded already, as ``result_id``) or ``failed`` (``error``: one line);
    ``elapsed_s``: the worker's time on it; ``registered``: its unit was registered with it."""

    path: str
    serial: str | None
    status: str
    result_id: int | None = None
    error: str | None = None
    elapsed_s: float = 0.0
    registered: bool = False

    def to_json(self) -> dict:
        """The record's outcome as JSON: path, serial, status, result id, seconds, and the error when it failed."""
        d = {"path": self.path, "serial": self.serial, "status": self.status, "result_id": self.result_id,
             "elapsed_s": round(self.elapsed_s, 3)}
        if self.error is not None:
            d["error"] = self.error
        return d


@dataclass
class BatchResult:
    """A batch's outcomes (in the order they came), its database (as printed), workers and wall time."""

    outcomes: list[Outcome]
    db: str = ""
    workers: int = 0
    wall_s: float = 0.0
    #: the publications of killed writers that opening the database rolled forward (:mod:`inscal.lab.journal`)
    recovered: tuple[str, ...] = ()

    @property
    def registered(self) -> list[str]:
        """The units registered by this batch (with their first result)."""
        return sorted({o.serial for o in self.outcomes if o.registered})

    def count(self, status: str) -> int:
        """How many records ended with ``status`` (``done``, ``skipped`` or ``failed``)."""
        return sum(o.status == status for o in self.outcomes)

    def calibration_s(self) -> float | None:
        """Mean worker time of a calibrated record [s] (None before any)."""
        t = [o.elapsed_s for o in self.outcomes if o.status == "done"]
        return sum(t) / len(t) if t else None

    def to_json(self) -> dict:
        """The batch as ``inscal batch --json`` prints it: the counts, workers, times, the failures and every record's outcome."""
        mean = self.calibration_s()
        return {"db": self.db, "records": len(self.outcomes), "done": self.count("done"), "skipped": self.count("skipped"),
                "failed": self.count("failed"), "registered": self.registered, "workers": self.workers,
                "wall_s": round(self.wall_s, 3), "seconds_per_record": None if mean is None else round(mean, 4),
                "failures": [{"path": o.path, "serial": o.serial, "error": o.error}
                             for o in self.outcomes if o.status == "failed"],
                "results": [o.to_json() for o in self.outcomes]} | ({"recovered": list(self.recovered)}
                                                                      if self.recovered else {})


# --------------------------------------------------------------------------- the records
def find_records(specs: Iterable[str]) -> list[tuple[Path, str]]:
    """``(absolute path, label)`` of the records named by ``specs``: a folder (its ``*.h5`` and
    ``*.hdf5`` files), a file, or a glob pattern (``'runs/FOG-*.h5'``), in sorted order, each file once.
    A spec that names nothing raises :class:`BatchError`."""
    out, seen = [], set()
    for spec in specs:
        p = Path(spec).expanduser()
        try:
            os.stat(p)
        except FileNotFoundError:
            pass
        except OSError as exc:  # a name too long for the file system, a file used as a folder ...
            shown = str(spec) if len(str(spec)) <= 200 else str(spec)[:199] + f"… ({len(str(spec))} characters)"
            raise BatchError(f"{shown}: {exc.strerror or exc}") from None
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in RECORD_SUFFIXES and q.is_file())
            why = f"folder {spec} holds no record (*.h5, *.hdf5)"
        elif p.is_file():
            found, why = [p], ""
        elif glob.has_magic(str(spec)):
            found = sorted(Path(q) for q in glob.glob(os.path.expanduser(str(spec))) if Path(q).is_file())
            why = f"{spec!r} matches no file"
        else:
            raise BatchError(f"{spec}: no such file or folder")
        if not found:
            raise BatchError(why)
        for q in found:
            key = q.resolve()
            if key not in seen:
                seen.add(key)
                out.append((q.absolute(), str(q)))
    return out


def name_pattern(pattern: str) -> re.Pattern:
    """The regular expression of a file-name pattern: ``{serial}`` (once: the longest part that lets the
    rest match), ``{date}`` (at most once: ``2025-01-15``, ``20250115``, optionally ``T10:30:00Z``), ``*``
    (any characters) and literal text, matched against the whole file name."""
    if pattern.count("{serial}") != 1 or pattern.count("{date}") > 1:
        raise BatchError(f"--names {pattern!r}: give {{serial}} once (and {{date}} at most once), e.g. {DEFAULT_NAMES}")
    rx = ""
    for tok in re.split(r"(\{serial\}|\{date\}|\*)", pattern):
        if tok == "{serial}":
            rx += r"(?P<serial>.+)"
        elif tok == "{date}":
            rx += DATE_PATTERN
        elif tok == "*":
            rx += ".*"
        elif "{" in tok or "}" in tok or "/" in tok:
            raise BatchError(f"--names {pattern!r}: only {{serial}}, {{date}} and * are fields of a file name")
        else:
            rx += re.escape(tok)
    return re.compile(rx)


def items_from_names(records: list[tuple[Path, str]], pattern: str = DEFAULT_NAMES, serial: str | None = None,
                     station: str | None = None, operator: str | None = None) -> list[BatchItem]:
    """The batch of ``records`` (:func:`find_records`) with their units and dates found by the rule of
    this module's docstring (``serial``: every record's; else the file name against ``pattern``, else
    the record's ``imu_serial`` attribute); ``station`` and ``operator`` of every session."""
    rx = name_pattern(pattern)
    out = []
    for path, label in records:
        m = rx.fullmatch(path.name)
        s = serial if serial is not None else (m["serial"] if m else record_attrs(path, ("imu_serial",))["imu_serial"])
        problem, when = None, None
        if s is None:
            problem = f"no serial: the name does not match --names {pattern} and the record has no imu_serial attribute"
        if m and m.groupdict().get("date"):
            try:
                when = parse_date(m["date"])
            except ValueError as exc:
                problem = f"the date in its name: {exc}"
        out.append(BatchItem(path, label, s, when, station, operator, None, problem))
    return out


def read_manifest(path: Path, station: str | None = None, operator: str | None = None) -> list[BatchItem]:
    """The batch of a CSV manifest: a header row, then one row per record with ``path`` (relative to the
    manifest's folder) and ``serial``, optionally ``date``, ``station``, ``operator`` and
    ``temperature_c`` (empty: the record's date; ``station`` / ``operator``; unknown).  A bad row raises
    :class:`BatchError` naming its line; a listed file that does not exist fails as a record."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise BatchError(f"--manifest {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        reader = csv.DictReader(text.splitlines())
        cols = [c.strip() for c in (reader.fieldnames or [])]
        rows = list(reader)
    except csv.Error as exc:
        raise BatchError(f"--manifest {path}: not a CSV file ({exc})") from None
    if len(set(cols)) != len(cols):
        raise BatchError(f"--manifest {path}: the header names a column twice ({', '.join(cols)})")
    missing = [c for c in ("path", "serial") if c not in cols]
    unknown = [c for c in cols if c not in MANIFEST_COLUMNS]
    if missing or unknown:
        raise BatchError(f"--manifest {path}: the header must name the columns path, serial (optionally "
                         f"{', '.join(MANIFEST_COLUMNS[2:])})" + (f"; unknown: {', '.join(unknown)}" if unknown else ""))
    out, seen = [], {}
    for k, raw in enumerate(rows, start=2):
        where = f"--manifest {path} line {k}"
        if raw.get(None):  # cells beyond the header's (csv.DictReader's restkey)
            raise BatchError(f"{where}: {len(cols) + len(raw[None])} cells, the header names {len(cols)}: quote a "
                             "path or serial that holds a comma (\"a,b.h5\"), or name the column in the header")
        row = {str(c).strip(): (v or "").strip() for c, v in raw.items() if c is not None}
        if not row.get("path") or not row.get("serial"):
            raise BatchError(f"{where}: give a path and a serial")
        p = Path(row["path"]).expanduser()
        p = (p if p.is_absolute() else path.parent / p).absolute()
        when = temp = None
        try:
            if row.get("date"):
                when = parse_date(row["date"])
            if row.get("temperature_c"):
                temp = float(row["temperature_c"])
                if not (math.isfinite(temp) and -100.0 < temp < 200.0):
                    raise ValueError(f"temperature_c {row['temperature_c']}: not an IMU temperature in deg C")
        except ValueError as exc:
            raise BatchError(f"{where}: {exc}") from None
        key = p.resolve()
        if key in seen:
            if seen[key] != row["serial"]:
                raise BatchError(f"{where}: {row['path']} is listed already as a record of {seen[key]}")
            continue
        seen[key] = row["serial"]
        problem = None if p.is_file() else "no such file"
        out.append(BatchItem(p, row["path"], row["serial"], when, row.get("station") or station,
                             row.get("operator") or operator, temp, problem))
    if not out:
        raise BatchError(f"--manifest {path} lists no record")
    return out


def check_units(db: Database, items: list[BatchItem], register: bool = False) -> list[BatchItem]:
    """The items with the ones of an unknown unit marked as failing, unless ``register`` (a unit is then
    registered with its first result, so a unit whose records all fail is not registered); a serial
    that cannot be one fails in any case."""
    bad = {}
    for s in sorted({i.serial for i in items if i.problem is None}):
        try:
            check_serial(s)
        except DatabaseError as exc:
            bad[s] = str(exc)
            continue
        if not register and get_unit(db, s) is None:
            bad[s] = f"unknown unit {s!r}: register it first (inscal db add {s} --model MODEL), or give --register"
    return [replace(i, problem=bad[i.serial]) if i.problem is None and i.serial in bad else i for i in items]


# ------------------------------------------------------------------------------ a worker
#: the databases a worker process opened, by URL (one engine per process)
_DATABASES: dict[str, Database] = {}


#: how long a batch's write waits for another writer (its sibling workers included) by default [s]
BATCH_WAIT_S = 10.0


def worker_database(target: str, wait_s: float = BATCH_WAIT_S) -> Database:
    """The database of URL ``target`` opened once in this process (its writes wait ``wait_s`` for another writer)."""
    db = _DATABASES.get(target)
    if db is None:
        db = _DATABASES[target] = open_database(target)
    db.wait_s = wait_s
    return db


def close_worker_databases() -> None:
    """Close the databases :func:`worker_database` opened in this process."""
    while _DATABASES:
        _DATABASES.popitem()[1].close()


@contextlib.contextmanager
def record_lock(db: Database, key: str) -> Iterator[None]:
    """Hold a lock on ``key`` (a unit, record and options) across processes: a PostgreSQL advisory lock
    (released by the server when the connection goes), or ``flock`` of ``.NAME.batch.lock`` beside an
    SQLite file (released by the kernel when the process goes)."""
    digest = hashlib.sha256(key.encode("utf-8")).digest()
    if db.dialect == "postgresql":
        k = int.from_bytes(digest[:8], "big", signed=True)
        with db.engine.connect() as conn:
            conn.execute(sa.text("SELECT pg_advisory_lock(:k)"), {"k": k})
            conn.commit()
            try:
                yield
            finally:
                conn.execute(sa.text("SELECT pg_advisory_unlock(:k)"), {"k": k})
                conn.commit()
        return
    file = Path(db.url.database)
    lock = file.with_name(side_name(file.name, ".batch.lock"))
    while True:
        fh = open(lock, "a")
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:  # its releasing holder removed the file between our open and flock: retry on a fresh one
            same = os.stat(lock).st_ino == os.fstat(fh.fileno()).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        fh.close()
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)  # while still locked: nothing left beside the database, a waiter retries
        fh.close()


def failure_text(exc: BaseException, path: Path | None = None) -> str:
    """One line for a failed record (the record's path, which the line names anyway, left out)."""
    if isinstance(exc, sa.exc.SQLAlchemyError):
        msg = str(getattr(exc, "orig", None) or exc)
    elif isinstance(exc, OSError) and exc.strerror:
        msg = exc.strerror + (f": {exc.filename}" if exc.filename and str(exc.filename) != str(path) else "")
    else:
        msg = str(exc)
    if not isinstance(exc, (ValueError, OSError, DatabaseError, sa.exc.SQLAlchemyError)):
        msg = f"{type(exc).__name__}: {msg}"
    msg = " ".join(msg.split())
    if path is not None and msg.startswith(f"{path}: "):
        msg = msg[len(str(path)) + 2:]
    return msg if len(msg) <= MAX_MESSAGE else msg[:MAX_MESSAGE - 1] + "…"


def calibrate_item(target: str, item: BatchItem, setup: CalibrationSetup, record_sha256: str,
                   register: bool = False, model: str | None = None, wait_s: float = BATCH_WAIT_S) -> Outcome:
    """Calibrate one record and record the result (the task of a worker): the record read, calibrated
    as ``inscal calibrate`` does (:func:`~inscal.runs.calibration.calibrate_record`) and recorded with its
    session, unless a result of the same record and options is there by then; its unit registered
    first (with ``model``) when ``register`` and it is not yet.  Never raises: a failure is an
    :class:`Outcome` with one line."""
    t0 = time.perf_counter()
    try:
        db = worker_database(target, wait_s)
        attr = record_attrs(item.path, ("imu_serial",))["imu_serial"]
        if attr is not None and attr != item.serial:
            raise RecordError(f"the record's imu_serial attribute is {attr!r}, not {item.serial!r}")
        cal = calibrate_record(load_record(item.path), item.path, setup)
        session = session_from_record(item.path, record_sha256=record_sha256, date=item.date, station=item.station,
                                      operator=item.operator, temperature_c=item.temperature_c, site=cal.record.site)
        options = setup.options()
        with record_lock(db, f"{item.serial}\n{record_sha256}\n{options_hash(options)}"):
            rid = find_calibration(db, record_sha256, options, item.serial)
            status, created = "skipped", False
            if rid is None:
                if register and get_unit(db, item.serial) is None:
                    created = add_unit(db, item.serial, model)[1]
                try:
                    rid, _ = record_result(db, item.serial, cal.result, session, data_file=item.path.name,
                                           metadata=cal.metadata, options=options)
                    status = "done"
                except AlreadyRecorded as exc:  # recorded meanwhile by a writer outside this lock (inscal calibrate)
                    rid = exc.result_id
        return Outcome(item.label, item.serial, status, rid, None, time.perf_counter() - t0, created)
    except Exception as exc:  # noqa: BLE001 - one line per failed record, the batch goes on
        return Outcome(item.label, item.serial, "failed", None, failure_text(exc, item.path), time.perf_counter() - t0)


# ------------------------------------------------------------------------------ the batch
def run_batch(db_text: str | None, items: list[BatchItem], setup: CalibrationSetup, *, scheduler: str = "local",
              workers: int | None = None, register: bool = False, model: str | None = None,
              on_outcome: Callable[[Outcome], None] | None = None,
              on_workers: Callable[[int], None] | None = None, wait_s: float = BATCH_WAIT_S) -> BatchResult:
    """Calibrate ``items`` with ``setup`` into the database ``db_text`` (a path or URL; None: ``INSCAL_DB``,
    else calib.sqlite; created when ``register``) on ``scheduler`` ("local", "none" or an address); see
    the module docstring.  ``on_outcome`` gets every record's :class:`Outcome` as it comes,
    ``on_workers`` the number of workers once they are known; ``wait_s``: how long a write waits for another
    writer (the sibling workers' commits take milliseconds) before the record fails naming it.  Raises :class:`BatchError` or
    :class:`~inscal.lab.database.DatabaseError` before anything is calibrated."""
    t0 = time.perf_counter()
    target = database_url(db_text).render_as_string(hide_password=False)
    # a cluster given by address is reached first (nothing is written if it cannot be); a local one is
    # started at the first record to calibrate
    remote = None if scheduler in ("none", "local") else start_client(scheduler, 0)[0]
    try:
        db = open_database(target, create=register)
    except BaseException:
        if remote is not None:
            remote.close()
        raise
    result = BatchResult([], db.where, recovered=tuple(db.recovery.done))

    def emit(o: Outcome) -> None:
        result.outcomes.append(o)
        if on_outcome is not None:
            on_outcome(o)

    try:
        items = check_units(db, items, register)
        for it in items:
            if it.problem is not None:
                emit(Outcome(it.label, it.serial, "failed", error=it.problem))
        options = setup.options()

        def pending() -> Iterator[tuple[BatchItem, str]]:
            for it in items:
                if it.problem is not None:
                    continue
                try:
                    h = file_hash(it.path)
                except OSError as exc:
                    emit(Outcome(it.label, it.serial, "failed", error=failure_text(exc, it.path)))
                    continue
                rid = find_calibration(db, h, options, it.serial)
                if rid is not None:
                    emit(Outcome(it.label, it.serial, "skipped", rid))
                    continue
                yield it, h

        if scheduler == "none":
            result.workers = 1
            if on_workers is not None:
                on_workers(1)
            for it, h in pending():
                emit(calibrate_item(target, it, setup, h, register, model, wait_s))
        else:
            n = sum(i.problem is None for i in items)
            result.workers = run_dask(target, pending(), setup, scheduler, min(workers or os.cpu_count() or 1, max(n, 1)),
                                      emit, on_workers, register, model, remote, wait_s)
    finally:
        db.close()
        close_worker_databases()
        if remote is not None:
            remote.close()
    result.wall_s = time.perf_counter() - t0
    return result


def start_client(scheduler: str, workers: int):
    """``(client, cluster)``: a LocalCluster of ``workers`` single-threaded processes for "local", else a
    client of the scheduler at that address (cluster None): :func:`inscal.core.parallel.start_client` with the
    batch's connection timeout, its error and the local workers' environment."""
    return parallel.start_client(scheduler, workers, CONNECT_TIMEOUT, BatchError, LOCAL_WORKER_ENVIRON)


def run_dask(target: str, pending: Iterable[tuple[BatchItem, str]], setup: CalibrationSetup, scheduler: str,
             workers: int, emit: Callable[[Outcome], None], on_workers: Callable[[int], None] | None = None,
             register: bool = False, model: str | None = None, client=None, wait_s: float = BATCH_WAIT_S) -> int:
    """Submit one task per record of ``pending`` as it comes, pass each outcome to ``emit`` as it
    completes; returns the number of workers (0: nothing to calibrate).  ``client``: of a cluster
    reached already (closed by the caller), else the cluster is started at the first record.  A task
    that dies with its worker fails its record."""
    from distributed import as_completed

    own = client is None
    cluster = ac = None
    futures: dict = {}
    n_workers = 0

    def collect(futs) -> None:
        for fut in futs:
            item = futures.pop(fut)
            try:
                emit(fut.result())
            except Exception as exc:  # noqa: BLE001 - the task itself died (worker lost): its record failed
                emit(Outcome(item.label, item.serial, "failed", error=f"the Dask task failed: {failure_text(exc)}"))

    try:
        for item, h in pending:
            if ac is None:
                if own:
                    client, cluster = start_client(scheduler, workers)
                n_workers = max(1, sum(client.nthreads().values()))
                if on_workers is not None:
                    on_workers(n_workers)
                ac = as_completed(loop=client.loop)
            fut = client.submit(calibrate_item, target, item, setup, h, register, model, wait_s, pure=False)
            futures[fut] = item
            ac.add(fut)
            collect(ac.next_batch(block=False))
        while ac is not None and not ac.is_empty():
            collect(ac.next_batch(block=True))
    except BaseException:
        if client is not None and futures:
            client.cancel(list(futures))
        if cluster is not None:
            stop_workers(cluster)
        raise
    finally:
        if own and client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    return n_workers


def stop_workers(cluster) -> None:
    """Kill the worker processes of a local cluster at once (an interrupted batch: a record being
    calibrated is not committed, and the next run calibrates it), so that closing the cluster does not
    wait for the records in flight; their nannies do not restart them."""
    for nanny in list(getattr(cluster, "workers", {}).values()):
        nanny.auto_restart = False
        pid = getattr(nanny, "pid", None)
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
