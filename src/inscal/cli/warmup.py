"""``python -m inscal.cli.warmup``: compile every numba kernel of the package once, so that no command
pays the compilation on its first use (``make demo`` and ``make test`` run it after the install).

numba's on-disk cache (``@njit(cache=True)``, ``__pycache__/*.nbi, *.nbc`` beside the sources unless
``NUMBA_CACHE_DIR`` says otherwise) holds one entry per kernel and argument-type signature, written the first
time a kernel runs with those types.  The warm-up therefore drives the commands' own code (the ``run_*``
functions of :mod:`inscal.cli`) on short records in a temporary folder, so the entries are exactly the ones a
first command loads: the same array ranks, dtypes and layouts, the same scalar types, reached through the same
Python.  Then it checks that every dispatcher of the package has a signature, compiled here or found in the cache.

A kernel declared ``inline="always"`` is compiled into its callers, never on its own: it is counted as inlined.

The records are the built-in scenarios on shortened paths (the S16 Table 1 sequence with 10 s dwells, the N25
twelve positions with short dwells, one cycle of the rotation modulation, a static base) plus a custom scenario
with gyro-accelerometer asynchrony (its kernel runs only for such an IMU).  The Kalman building blocks that no
command calls (``predict``, ``update``, ``update_dense``: the tests and the benchmark use them) run directly, and
so do the square-root and smoother steps, whose entries for a call from Python are not the ones the compiled
filter passes leave.

With four or more CPUs the systematic filter (the longest compilation by far) compiles in a second process
beside the rest.  Ctrl-C (or SIGTERM) stops it within a second or so, removing its temporary folder; what
was compiled by then stays in the cache.
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

from inscal.cli.interrupts import (
    Interrupted,
    catch_interrupts,
    pending_signal,
    release_interrupts,
)
from inscal.cli.warmup_steps import STEP_FUNCTIONS

#: the steps of the warm-up, in order; "systematic" may run in a second process
STEPS = ("records", "systematic", "observability", "n25-methods", "bound", "navigate", "library")
#: the steps the second process runs (the systematic filter, then the observability report that reuses it)
SECOND = ("systematic", "observability")


def dispatchers(errors: dict | None = None) -> dict:
    """Every numba dispatcher of the package, ``module.qualname`` -> dispatcher (every module imported;
    a module that fails to import is skipped, and named in ``errors`` when given)."""
    from numba.core.registry import CPUDispatcher

    import inscal

    found = {}
    for info in pkgutil.walk_packages(inscal.__path__, "inscal.", onerror=lambda name: None):
        if info.name.endswith(".__main__"):
            continue
        try:
            mod = importlib.import_module(info.name)
        except Exception as exc:  # noqa: BLE001 - reported, the other modules are still checked
            if errors is not None:
                errors[f"import {info.name}"] = f"{type(exc).__name__}: {exc}"
            continue
        for obj in vars(mod).values():
            if isinstance(obj, CPUDispatcher):
                found[f"{obj.py_func.__module__}.{obj.py_func.__qualname__}"] = obj
    return found


def _cached_signatures(disp) -> int:
    """Entries of ``disp``'s on-disk index valid for its current source (numba's own check), 0 when
    unknown.  A kernel called only from other kernels gets no signature in a process that loads its
    callers from the cache: its own index says whether it was compiled."""
    try:
        return len(disp._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals: absent in another version
        return 0


def coverage(extra: dict[str, list[str]] | None = None, errors: dict | None = None) -> dict:
    """Which dispatchers have a signature: compiled in this process, loaded from the cache, or found in
    the cache index; ``extra``: name -> signatures compiled in another process.  Returns ``{"kernels":
    name -> state ("compiled", "loaded", "cached", "inlined" or "missing"), "signatures": name -> [signature],
    "ready": kernels with a signature, "total": kernels not inlined, "inlined", "missing": [name]}``."""
    extra = extra or {}
    state, sigs = {}, {}
    for name, d in sorted(dispatchers(errors).items()):
        sigs[name] = sorted({str(s) for s in d.signatures} | set(extra.get(name, ())))
        if d.targetoptions.get("inline") == "always":
            state[name] = "inlined"
        elif sigs[name]:
            state[name] = "compiled" if any(d.stats.cache_misses.values()) or name in extra else "loaded"
        elif _cached_signatures(d):
            state[name] = "cached"
        else:
            state[name] = "missing"
    own = [k for k, v in state.items() if v != "inlined"]
    return {"kernels": state, "signatures": sigs, "total": len(own), "inlined": len(state) - len(own),
            "ready": sum(state[k] != "missing" for k in own), "missing": [k for k in own if state[k] == "missing"]}


def _run_steps(steps, tmp: Path, progress, times: dict, errors: dict) -> None:
    for name in steps:
        t0 = time.perf_counter()
        if progress is not None:
            progress(name, "start")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                STEP_FUNCTIONS[name](tmp)
        except Exception as exc:  # noqa: BLE001 - a step that fails leaves its kernels to the coverage check
            if pending_signal() is not None:  # an interrupt numba turned into another error
                raise Interrupted(pending_signal()) from None
            errors[name] = f"{type(exc).__name__}: {exc}"
        times[name] = time.perf_counter() - t0
        if progress is not None:
            progress(name, f"{times[name]:.1f} s" + (f" ({errors[name]})" if name in errors else ""))


def _second_process(tmp: Path, steps) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "inscal.cli.warmup", "--steps", ",".join(steps), "--folder", str(tmp),
           "--report", str(tmp / "second.json"), "--quiet"]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def default_jobs() -> int:
    """2 processes with 4 or more CPUs, else 1: on 2 virtual CPUs (hyper-threads of one core) the second
    process made the warm-up slower (79 s against 69 s), the compilations competing for one core."""
    n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return 2 if n >= 4 else 1


def warm_up(progress=None, jobs: int | None = None, steps=STEPS, folder: Path | None = None) -> dict:
    """Run ``steps`` (default all of :data:`STEPS`) in a temporary folder (or ``folder``, whose records
    the steps read), then :func:`coverage`.  ``progress(step, text)`` is called at the start and the end
    of each step; ``jobs``: processes (default :func:`default_jobs`).  Returns the coverage dict with
    ``seconds``, ``step_seconds``, ``errors`` (step -> message), ``cache`` (:func:`cache_root`) and ``jobs``.
    SIGINT and SIGTERM raise :class:`~inscal.cli.interrupts.Interrupted`, after the temporary folder and the second
    process are gone."""
    t0 = time.perf_counter()
    jobs = jobs if jobs is not None else default_jobs()
    times: dict = {}
    errors: dict = {}
    extra: dict = {}
    old = catch_interrupts()
    second = None
    try:
        with tempfile.TemporaryDirectory(prefix="inscal-warmup-") as tmpd:
            tmp = Path(folder) if folder is not None else Path(tmpd)
            try:
                own = list(steps)
                if "records" in own:
                    _run_steps(["records"], tmp, progress, times, errors)
                    own.remove("records")
                apart = [s for s in own if s in SECOND]
                if jobs > 1 and apart and len(apart) < len(own):
                    second = _second_process(tmp, apart)
                    own = [s for s in own if s not in SECOND]
                _run_steps(own, tmp, progress, times, errors)
                if second is not None:
                    _, err = second.communicate()
                    rep = tmp / "second.json"
                    if second.returncode != 0 or not rep.is_file():
                        errors["second process"] = f"exit {second.returncode}: {(err or '').strip()[-500:]}"
                    else:
                        d = json.loads(rep.read_text())
                        extra = {k: v for k, v in d["signatures"].items() if d["kernels"][k] == "compiled"}
                        times.update(d["step_seconds"])
                        errors.update(d["errors"])
                    second = None
            except (Interrupted, KeyboardInterrupt):
                release_interrupts(old)
                old = {}
                raise
            finally:
                if second is not None:  # interrupted: the second process stops too
                    second.terminate()
                    try:
                        second.wait(10)
                    except subprocess.TimeoutExpired:
                        second.kill()
                        second.wait()
    finally:
        release_interrupts(old)
    cov = coverage(extra, errors)
    return cov | {"seconds": time.perf_counter() - t0, "step_seconds": times, "errors": errors, "cache": cache_root(),
                  "jobs": jobs}


def cache_root() -> str | None:
    """The folder holding the package's numba cache: ``NUMBA_CACHE_DIR`` when set, else the package
    (its ``__pycache__`` folders); None when numba does not say."""
    paths = [getattr(getattr(d, "_cache", None), "_cache_path", None) for d in dispatchers().values()]
    paths = [p for p in paths if p]
    return os.path.commonpath(paths) if paths else None


def summary_line(res: dict) -> str:
    """The one-line summary of :func:`warm_up`'s result."""
    n = res["kernels"]
    counts = {s: sum(v == s for v in n.values()) for s in ("compiled", "loaded", "cached")}
    line = (f"inscal warm-up: {res['ready']} of {res['total']} numba kernels ready ({counts['compiled']} compiled, "
            f"{counts['loaded'] + counts['cached']} already cached; {res['inlined']} more inlined into them) in "
            f"{res['seconds']:.1f} s, cache {res['cache']}")
    if res["missing"]:
        line += f"; NOT compiled: {', '.join(res['missing'])}"
    if res["errors"]:
        line += "; failed steps: " + "; ".join(f"{k}: {v}" for k, v in res["errors"].items())
    return line


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m inscal.cli.warmup", description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=None, help="processes (default: 2 with 4 or more CPUs, else 1)")
    ap.add_argument("--steps", default=",".join(STEPS), help=f"comma list of steps (default: {','.join(STEPS)})")
    ap.add_argument("--folder", type=Path, default=None, help="read and write the records here (default: a temporary "
                                                               "folder)")
    ap.add_argument("--report", type=Path, default=None, help="write the result as JSON")
    ap.add_argument("--verbose", action="store_true", help="a line per step")
    ap.add_argument("--quiet", action="store_true", help="no summary line")
    ap.add_argument("--check", action="store_true", help="exit 1 unless every kernel has a signature")
    args = ap.parse_args(argv)
    steps = [s.strip() for s in args.steps.split(",") if s.strip()]
    unknown = [s for s in steps if s not in STEP_FUNCTIONS]
    if unknown:
        ap.error(f"unknown step(s) {unknown}; steps: {', '.join(STEPS)}")
    progress = (lambda step, text: print(f"  {step}: {text}", file=sys.stderr, flush=True)) if args.verbose else None
    t0 = time.perf_counter()
    try:
        res = warm_up(progress, args.jobs, steps, args.folder)
    except (Interrupted, KeyboardInterrupt):
        print(f"inscal warm-up: interrupted after {time.perf_counter() - t0:.1f} s (what was compiled stays cached)",
              file=sys.stderr)
        return 128 + (pending_signal() or 2)  # 130 for SIGINT, 143 for SIGTERM
    if args.report is not None:
        args.report.write_text(json.dumps(res, indent=1), encoding="utf-8")
    if not args.quiet:
        print(summary_line(res))
    return 1 if args.check and (res["missing"] or res["errors"]) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
