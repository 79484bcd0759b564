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

#: the records of the warm-up: name -> (base scenario, path builder and its arguments, extra TOML tables)
RECORDS = {
    "s16": ("s16", ("s16_table1", {"rate_dps": 20.0, "dwell_s": 10.0, "accel_dps2": 20.0}), {}),
    "s16-gimbal": ("s16-gimbal", ("s16_table1", {"rate_dps": 20.0, "dwell_s": 10.0, "accel_dps2": 20.0}), {}),
    "n25": ("n25", ("n25_twelve", {"dwell_s": 25.0, "rate_dps": 20.0, "rate_test_dps": 20.0, "rate_test_turns": 1,
                                   "accel_dps2": 20.0}), {}),
    "n25-rotmod": ("n25", ("rotmod16", {"duration_s": 60.0, "dwell_s": 5.0}), {}),
    "n25-static": ("n25", ("static", {"duration_s": 200.0}), {}),
    "asynchrony": ("s16", ("static", {"duration_s": 2.0}),
                   {"errors": {"time_asynchrony": {"value": 0.1, "unit": "ms"}}}),
}
#: the steps of the warm-up, in order; "systematic" may run in a second process
STEPS = ("records", "systematic", "observability", "n25-methods", "bound", "navigate", "library")
#: the steps the second process runs (the systematic filter, then the observability report that reuses it)
SECOND = ("systematic", "observability")


def scenario_files(folder: Path) -> dict[str, Path]:
    """Write the scenario TOML files of :data:`RECORDS` into ``folder``; returns name -> file."""
    import tomli_w

    from inscal import SCHEMA_VERSION
    from inscal.core import turntable

    files = {}
    for name, (base, (builder, kw), extra) in RECORDS.items():
        path = getattr(turntable, builder)(**kw)
        doc = {"schema_version": SCHEMA_VERSION, "base": base, "scenario": {"name": f"warmup-{name}"}, **extra,
               "path": path.to_dict()}
        files[name] = folder / f"{name}.toml"
        files[name].write_text(tomli_w.dumps(doc), encoding="utf-8")
    return files


def _records(tmp: Path) -> None:
    from inscal.cli.simulate import run_simulate

    for name, toml in scenario_files(tmp).items():
        run_simulate(str(toml), tmp / f"{name}.h5", seed=1, force=True, show_progress=False)


def _systematic(tmp: Path) -> None:
    from inscal.cli.calibrate import run_calibrate
    from inscal.cli.calibrate_setup import CalibrateOptions

    run_calibrate(CalibrateOptions(tmp / "s16.h5", "systematic51", tmp / "s16-51.toml", force=True))
    run_calibrate(CalibrateOptions(tmp / "s16.h5", "systematic30", tmp / "s16-30.toml", force=True))
    run_calibrate(CalibrateOptions(tmp / "s16-gimbal.h5", "unified", tmp / "unified.toml", force=True))


def _observability(tmp: Path) -> None:
    from inscal.cli.observability import run_observability

    run_observability(str(tmp / "s16.toml"))


def _n25_methods(tmp: Path) -> None:
    from inscal.cli.calibrate import run_calibrate
    from inscal.cli.calibrate_setup import CalibrateOptions

    for method in ("six-position", "twelve-position", "n25", "joint"):
        run_calibrate(CalibrateOptions(tmp / "n25.h5", method, tmp / f"params-{method}.toml", force=True))


def _bound(tmp: Path) -> None:
    from inscal.cli.design import run_design
    from inscal.cli.observability import run_crlb

    run_crlb(str(tmp / "s16.toml"))
    run_design(tmp / "designed.toml", 3.0, candidates=2, population=2, scheduler="none", force=True, progress=False)


def _navigate(tmp: Path) -> None:
    from inscal.cli.navigate import run_navigate

    rm = tmp / "n25-rotmod.h5"
    run_navigate(rm)
    params = tmp / "params-n25.toml"
    run_navigate(rm, params=params if params.is_file() else None, vertical="damped", height_ref="0")
    run_navigate(tmp / "n25-static.h5", init="align", align_coarse_s=60.0, align_fine_s=60.0)


def _library(tmp: Path) -> None:
    """What no command above reaches: the PSINS gravity formula (``--gravity psins``, a site table's
    ``gravity = "psins"``) and the normal gravity called from Python at a latitude alone, the
    covariance-form Kalman steps (tests and benchmark), the square-root and smoother steps called from Python
    (the filters call them from their compiled passes, which caches other entries) and the bias-instability
    recursion of the noise-only simulation (``montecarlo --set simulation=reuse``), the streamed Allan variance's kernels, with the argument types
    their callers use."""
    import numpy as np

    from inscal.analysis.noise.estimators import StreamingScaleVariance
    from inscal.core import kalman
    from inscal.core.earth import normal_gravity, parse_gravity
    from inscal.sim.kernel import gauss_markov_filter

    acc = StreamingScaleVariance(4096, 100.0, 2, [1, 2], piece=1024)  # the streamed Allan variance (inscal
    acc.update(np.zeros((4096, 2)))  # noise), in pieces that shift its history
    parse_gravity("psins").g(0.5, 10.0)
    normal_gravity(0.5)
    gauss_markov_filter(np.zeros((2, 3)), 0.5, np.zeros(3))
    n, N = 9, 12
    P = np.eye(N)
    kalman.predict(P, n, np.eye(n), np.zeros((n, N - n)), np.eye(n) * 1e-6, np.zeros(N - n))
    idx = np.arange(3, dtype=np.int64)
    K, Sinv, x = np.empty((N, 3)), np.empty((3, 3)), np.empty(N)
    kalman.update(P, idx, np.ones(3), np.zeros(3), K, Sinv, x)
    kalman.update_dense(P, np.eye(N)[:3].copy(), np.eye(3), np.zeros(3), K, Sinv, x)
    U = np.eye(N)
    kalman.sr_predict(U, n, np.eye(n), np.zeros((n, N - n)), np.eye(n) * 1e-6)
    kalman.sr_update(U, idx, np.ones(3), np.zeros(3), K, Sinv, x)
    lam, Lam = np.zeros(N), np.zeros((N, N))
    kalman.smoother_step(lam, Lam, idx, K, Sinv, np.zeros(3))
    kalman.adjoint_back(lam, Lam, n, np.eye(n), np.zeros((n, N - n)))
    kalman.smoothed_constant(np.eye(N), lam, Lam, n, np.zeros(N - n), np.eye(N - n))
    kalman.smoothed(np.eye(N), lam, Lam)  # the plain form (the benchmark's replay and the tests use it)
    Rb = np.zeros((N, N))  # the square-root information smoother's steps (tests and bench/smoother_positivity.py)
    kalman.info_rows(Rb, idx, np.ones(3))
    kalman.info_rows_dense(Rb, np.eye(N)[:3].copy(), np.eye(3))
    kalman.info_back(Rb, n, np.eye(n), np.zeros((n, N - n)), kalman.noise_factor(np.eye(n) * 1e-6))
    kalman.sr_smoothed(np.eye(N), Rb, n, np.eye(N - n))


STEP_FUNCTIONS = {"records": _records, "systematic": _systematic, "observability": _observability,
                  "n25-methods": _n25_methods, "bound": _bound, "navigate": _navigate, "library": _library}


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
