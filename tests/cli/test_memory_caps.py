"""No command may eat the machine's memory or hang.

(a) Every size option is estimated before anything grows with it, and an absurd value is refused in
one line: exit 2, exactly one stderr line ``inscal: error: ...`` (no traceback), nothing written, the
inputs unchanged, quickly, and the child's peak RSS (``os.wait4``) stays small.  The commands run in
child processes (``inscal.cli.main``: the real signal handlers and exit), forked from one that imported the
package once (:mod:`forkserver`).

(b) The long compiled loops (the bound's covariance pass, which ``design`` runs per candidate and
``observability --crlb`` once) return to Python every few tens of milliseconds, so SIGTERM ~1 s into a
long run ends it within 2 s: exit 143, one line ``inscal: interrupted (SIGTERM)``, nothing left."""

import hashlib
import math
import os
import signal
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import tomli_w

from inscal import io
from inscal.core.earth import Site
from inscal.core.turntable import Move, RotationPath

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="POSIX signals, os.wait4, /proc")

#: the child's peak resident memory must stay below this (a refusal: ~240 MB, the interpreter and imports)
MAX_RSS = 2 << 30
#: a refusal's run from the fork to the exit (well under 1 s on an idle 2-core machine; the interpreter's
#: start and the imports are the fork server's)
MAX_REFUSE_S = 5.0
#: the forked child's CPU time at which the long runs are surely inside the kernel loop (the interpreter's
#: start and the imports, ~2.2 s, are the fork server's; the setup and the kernels' load from numba's cache take
#: up to 0.6 s: ``design`` of 8 candidates forked takes 0.84 s, of 40 1.91 s), so that the signal comes ~1 s into
#: the computation
IN_KERNEL_CPU_S = 1.6
#: an interrupt must end the run within this long
MAX_LATENCY_S = 2.0


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (/proc/PID/stat)."""
    with open(f"/proc/{pid}/stat") as fh:
        rest = fh.read().rsplit(")", 1)[1].split()
    return (int(rest[11]) + int(rest[12])) / os.sysconf("SC_CLK_TCK")


def snapshot(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir" for p in folder.iterdir()}


# ----------------------------------------------------------------------------- inputs
def small_record(path: Path) -> None:
    n, rate = 7000, 10.0  # 700 s: long enough for navigate's alignment
    t = np.arange(1, n + 1) / rate
    dv = np.tile([0.0, 0.0, 9.8 / rate], (n, 1))
    io.write_record(path, io.Record(t, np.zeros((n, 3)), dv, np.zeros((n, 2)), rate, Site(0.7, 0.0, 0.0),
                                    scenario="caps"))


def huge_record(path: Path, n: int = 10**11) -> None:
    """A valid record header whose datasets claim ``n`` samples, never written (the file stays a few kB):
    ``allan --start -10`` takes them all (their time reads as -1 s)."""
    small_record(path)
    with h5py.File(path, "a") as h:
        for name, cols in (("time", None), ("dtheta", 3), ("dvel", 3), ("gimbal", 2)):
            del h[name]
            shape = (n,) if cols is None else (n, cols)
            h.create_dataset(name, shape=shape, dtype="f8", chunks=(1 << 14,) + shape[1:],
                             fillvalue=-1.0 if cols is None else 0.0)


def long_path_toml(path: Path) -> None:
    """A path TOML whose one dwell lasts 10^9 s (32 years)."""
    p = RotationPath("long", (Move("outer", math.pi / 2, math.radians(10), 1e9),), accel=math.radians(10),
                     initial_dwell=60.0, closed=False)
    path.write_text(tomli_w.dumps({"path": p.to_dict()}))


INPUTS = {"r.h5": small_record, "huge.h5": huge_record, "long.toml": long_path_toml}

# ----------------------------------------------------------------------------- (a) refusals
#: name -> (arguments, a fragment of the one-line message)
CASES = {
    "design --minutes (memory)": (["design", "--minutes", "1e6", "--candidates", "8", "--population", "4",
                                   "--scheduler", "none", "--out", "d.toml"], "--minutes 1e+06 (6e+07 filter steps"),
    "design --minutes (steps)": (["design", "--minutes", "2e5", "--scheduler", "none", "--out", "d.toml"],
                                 "filter steps per candidate"),
    "design --candidates": (["design", "--candidates", "1000000000000", "--scheduler", "none", "--out", "d.toml"],
                            "--candidates 1000000000000 x"),
    "design --population": (["design", "--minutes", "1.3", "--candidates", "10000000", "--population", "10000000",
                             "--scheduler", "none", "--out", "d.toml"], "--population 10000000"),
    "design --workers": (["design", "--workers", "1000000", "--out", "d.toml"], "--workers 1000000"),
    "observability --rate-hz": (["observability", "n25", "--rate-hz", "1e6"], "--rate-hz 1e+06 over the 2489 s path"),
    "observability long path": (["observability", "long.toml"], "--rate-hz 20 over the 1e+09 s path"),
    "observability --crlb --filter-rate-hz": (["observability", "n25", "--crlb", "--filter-rate-hz", "1e6"],
                                              "--filter-rate-hz 1e+06 over the 2489 s path"),
    "observability --crlb long path": (["observability", "long.toml", "--crlb"], "1e+09 filter steps"),
    "montecarlo --runs": (["montecarlo", "n25-fig5", "--runs", "1000000000000", "--out", "mc"], "--runs 1000000000000"),
    "montecarlo --set rate_hz": (["montecarlo", "n25-schemes", "--runs", "1", "--no-dask", "--set", "rate_hz=1e9",
                                  "--out", "mc"], "one run of n25-schemes"),
    "montecarlo --set dwell_s": (["montecarlo", "n25-fig5", "--runs", "1", "--no-dask", "--set", "dwell_s=1e12",
                                  "--out", "mc"], "one run of n25-fig5"),
    "montecarlo s16-table2 --set rate_hz": (["montecarlo", "s16-table2", "--runs", "1", "--set", "rate_hz=1e7",
                                             "--out", "mc"], "one run of s16-table2"),
    "montecarlo --workers": (["montecarlo", "n25-schemes", "--runs", "1", "--workers", "1000000", "--out", "mc"],
                             "--workers 1000000"),
    "allan window": (["allan", "huge.h5", "--start", "-10"], "the window of huge.h5 (100000000000 samples, 1e+10 s at 10 Hz)"),
    "simulate --duration-h": (["simulate", "static", "--duration-h", "1e9", "--out", "x.h5"], "not a sensible record"),
    "simulate --rate-hz": (["simulate", "n25", "--rate-hz", "1e12", "--out", "x.h5"], "not a sensible record"),
    "navigate --output-rate-hz": (["navigate", "r.h5", "--output-rate-hz", "1e9"], "above the sample rate"),
}


@pytest.fixture(scope="module")
def refused(tmp_path_factory, fork_servers):
    """Every case in its own folder holding every input, one after the other, each forked from a process
    that has imported the command line once (:mod:`forkserver`): a refusal is the command's own work."""
    root = tmp_path_factory.mktemp("caps")
    proto = root / "inputs"
    proto.mkdir()
    for name, make in INPUTS.items():
        make(proto / name)
    out = {}
    server = fork_servers.get()
    for i, name in enumerate(CASES):
        folder = root / f"case{i}"
        folder.mkdir()
        for f in proto.iterdir():
            (folder / f.name).write_bytes(f.read_bytes())
        before = snapshot(folder)
        logs = root / f"logs{i}"
        r = server.run(CASES[name][0], folder, logs, timeout=120, env={"COLUMNS": "200"})
        out[name] = {**r, "stderr": (logs / "stderr").read_text(), "stdout": (logs / "stdout").read_text(),
                     "before": before, "after": snapshot(folder)}
    return out


@pytest.mark.parametrize("name", CASES)
def test_absurd_size_refused_up_front(refused, name):
    r = refused[name]
    err = r["stderr"]
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert r["rc"] == 2, (r["rc"], err[-2000:])
    assert "Traceback" not in err and len(lines) == 1 and lines[0].startswith("inscal: error: "), err[-2000:]
    assert CASES[name][1] in lines[0], lines[0]
    assert r["after"] == r["before"], "something was written, or an input changed"
    assert r["rss"] < MAX_RSS, f"peak RSS {r['rss'] / 1e9:.2f} GB"
    assert r["seconds"] < MAX_REFUSE_S, f"{r['seconds']:.1f} s to refuse"


def test_memory_refusals_name_what_they_need(refused):
    """The memory refusals say how much they need and how much there is."""
    line = refused["design --minutes (memory)"]["stderr"].strip()
    assert "needs about" in line and "GB of memory (this machine has" in line and "available); shorten --minutes" in line


# ----------------------------------------------------------------------------- (b) interrupts
LONG = {
    # 5000 candidates of 1800 steps: ~4 min of CPU; the first progress line at 10 % (~20 s)
    "design": ["design", "--minutes", "30", "--candidates", "5000", "--population", "8", "--scheduler", "none",
               "--out", "d.toml", "--json"],
    # 2.5e6 filter steps: ~50 s of CPU, under the 1e7 cap
    "observability --crlb": ["observability", "n25", "--crlb", "--filter-rate-hz", "1000", "--json"],
}


@pytest.fixture(scope="module")
def warm_kernel():
    """Load (or compile and cache) the bound's kernel here, so that the children load it from numba's
    cache: a compilation, unlike the kernel, cannot be interrupted."""
    from inscal.plan.bound import crlb

    crlb("s16-table1", keep_history=False)


@pytest.mark.parametrize("name", LONG)
def test_sigterm_inside_the_kernel_loop_ends_the_run_promptly(name, tmp_path, warm_kernel, fork_servers):
    folder = tmp_path / "run"
    folder.mkdir()
    sigterm_when_busy(fork_servers.get(), LONG[name], folder, tmp_path / "logs", IN_KERNEL_CPU_S)
    assert list(folder.iterdir()) == []


def sigterm_when_busy(server, args, folder, logs, cpu_s: float) -> None:
    """Run ``inscal ARGS`` in ``folder`` (forked from ``server``: ``inscal.cli.main`` with its real handlers and
    exit), send SIGTERM once it has used ``cpu_s`` of CPU (inside its long loop), and check that it exits 143
    within :data:`MAX_LATENCY_S` with the one interrupt line."""
    proc = server.start(args, folder, logs, timeout=150, env={"COLUMNS": "200"})
    try:
        t_end = time.monotonic() + 120
        while proc.poll() is None and cpu_seconds(proc.pid) < cpu_s and time.monotonic() < t_end:
            time.sleep(0.02)
        assert proc.poll() is None, (logs / "stderr").read_text()[-2000:]
        t_sig = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(30)
        t_exit = time.monotonic()
    finally:
        if proc.returncode is None:
            proc.kill()
            proc.wait()
    err = (logs / "stderr").read_text()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 143, (rc, err[-2000:])
    assert t_exit - t_sig < MAX_LATENCY_S, f"{t_exit - t_sig:.2f} s from SIGTERM to exit"
    assert len(lines) == 1 and lines[0].startswith("inscal: interrupted (SIGTERM)") and "Traceback" not in err, err
