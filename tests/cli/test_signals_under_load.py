"""SIGTERM under load: 20 signals at random times (a seeded generator) during ``simulate``,
``calibrate --method systematic51 --plots``, ``design``, ``observability --crlb`` and
``navigate --out``, two commands at a time, with two busy processes on the cores beside them.  Every command exits within
2 s of its signal (exit 143, one line) and leaves the folder as it was; a command that finished
before its signal left whole outputs."""

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

#: the most a command may take to exit after SIGTERM [s]
LATENCY_S = 2.0
#: a plain progress line of a long command ("design 60 min: 6/8 candidates, best score 1.156")
PROGRESS = re.compile(r": \d+/\d+ \w+")
#: command -> (arguments, outputs when it finishes, signal delays [s] after the start)
COMMANDS = {
    "simulate": (["simulate", "static-24h", "--duration-h", "24", "--out", "x.h5"], ["x.h5"], (0.1, 2.0)),
    "calibrate": (["calibrate", "{p19}", "--method", "systematic51", "--out", "p.toml", "--plots", "plots"],
                  ["p.toml", "plots"], (0.1, 5.0)),
    "design": (["design", "--minutes", "60", "--candidates", "8", "--population", "4", "--scheduler", "none",
                "--out", "d.toml"], ["d.toml"], (0.1, 4.0)),
    "observability": (["observability", "s16", "--crlb"], [], (0.1, 1.0)),
    "navigate": (["navigate", "{s4}", "--init", "truth", "--out", "n.h5"], ["n.h5"], (0.1, 2.5)),
}


def handles_sigterm(pid: int) -> bool:
    """Whether process ``pid`` has installed a SIGTERM handler (bit 15 of SigCgt in /proc/PID/status): the
    command line's handler is in place, so a signal now is the command's interrupt, not Python's default."""
    with open(f"/proc/{pid}/status") as fh:
        for line in fh:
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    return False


def started(proc, timeout: float = 60.0) -> None:
    """Wait until ``proc`` has installed its SIGTERM handler (on a loaded machine the wall time of its
    start-up says nothing) or has ended."""
    t_end = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < t_end:
        try:
            if handles_sigterm(proc.pid):
                return
        except OSError:  # ended between the poll and the read
            return
        time.sleep(0.01)


def _launch(args, cwd):
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("load-in")
    for args in (["simulate", "psins19", "--out", d / "p19.h5"],
                 ["simulate", "static-24h", "--duration-h", "4", "--out", d / "s4.h5"]):
        p = _launch(args, d)
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
    return {"p19": d / "p19.h5", "s4": d / "s4.h5"}


def one_signal(name: str, delay: float, records, folder) -> tuple:
    """Run command ``name`` in ``folder``, SIGTERM ``delay`` s after its handler is in place, check what it
    did; returns ``(name, outcome, latency)``."""
    args, outputs, _ = COMMANDS[name]
    folder.mkdir()
    proc = _launch([a.format(**records) for a in args], folder)
    try:
        started(proc)
        time.sleep(delay)
        if proc.poll() is not None:  # finished before its signal
            _, err = proc.communicate()
            assert proc.returncode == 0, (name, err)
            assert sorted(p.name for p in folder.iterdir()) == sorted(outputs), name
            return name, "finished", None
        sent = time.monotonic()
        proc.terminate()
        _, err = proc.communicate(timeout=30)
        latency = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    names = sorted(p.name for p in folder.iterdir())
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert latency < LATENCY_S, (name, latency, err)
    if proc.returncode == 0 or "after its outputs were complete" in err:  # the signal came at the very end
        assert names == sorted(outputs), (name, names, err)
        return name, "complete", round(latency, 2)
    assert proc.returncode == 143, (name, proc.returncode, err)
    # one line says so, after the progress lines the command printed by then (stderr is not a terminal)
    said = [ln for ln in lines if not PROGRESS.search(ln)]
    assert len(said) == 1 and lines[-1] == said[0], (name, err)
    assert said[0].startswith("inscal: interrupted (SIGTERM)"), (name, err)
    assert names == [], (name, names, err)
    shutil.rmtree(folder)
    return name, 143, round(latency, 2)


def test_twenty_sigterms_under_load(records, tmp_path):
    """The 20 (command, delay) pairs of the seeded generator, two commands at a time beside the two busy
    processes (the load on each command is higher than with one at a time, and the busy processes run half
    as long)."""
    rng = np.random.default_rng(20261124)
    runs = []
    for i in range(20):
        name = list(COMMANDS)[i % len(COMMANDS)]
        lo, hi = COMMANDS[name][2]
        runs.append((name, rng.uniform(lo, hi), records, tmp_path / f"{i:02d}-{name}"))
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        with ThreadPoolExecutor(max_workers=2) as pool:
            report = list(pool.map(lambda run: one_signal(*run), runs))
    finally:
        for b in busy:
            b.kill()
            b.wait()
    assert sum(outcome == 143 for _, outcome, _ in report) >= 10, report
