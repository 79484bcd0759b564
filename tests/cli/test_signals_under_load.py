"""SIGTERM under load: 20 signals at random times (a seeded generator) during ``simulate``,
``calibrate --method systematic51 --plots``, ``design``, ``observability --crlb`` and
``navigate --out``, two commands at a time, with two busy processes on the cores beside them.  Every command exits within
2 s of its signal (exit 143, one line) and leaves the folder as it was; a command that finished
before its signal left whole outputs.

The 20 commands fork from two processes that imported the package once (``forkserver``): each runs
``inscal.cli.main`` with its real handlers, and its delay counts from the moment its SIGTERM handler is in
place.  Five more, one per command, start their own interpreter as a user's command does and get their
signal 0 to 0.3 s after the handler is in place: inside the imports each command makes on its own
(a signal raised in a module's body, which Python may report as another error)."""

import os
import queue
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


@pytest.fixture(scope="module")
def servers(fork_servers):
    """Two fork servers, one per command running at a time."""
    pool: queue.Queue = queue.Queue()
    for k in range(2):
        pool.put(fork_servers.get(k))
    return pool


@pytest.fixture(scope="module")
def records(servers, tmp_path_factory):
    d = tmp_path_factory.mktemp("load-in")
    server = servers.get()
    try:
        for i, args in enumerate((["simulate", "psins19", "--out", d / "p19.h5"],
                                  ["simulate", "static-24h", "--duration-h", "4", "--out", d / "s4.h5"])):
            r = server.run(args, d, d.parent / f"{d.name}-logs-{i}", timeout=300)
            assert r["rc"] == 0, (d.parent / f"{d.name}-logs-{i}" / "stderr").read_text()
    finally:
        servers.put(server)
    return {"p19": d / "p19.h5", "s4": d / "s4.h5"}


def _launch(args, cwd):
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))


def one_signal(name: str, delay: float, records, folder, servers, fresh: bool = False) -> tuple:
    """Run command ``name`` in ``folder`` (forked from one of ``servers``, or with ``fresh`` in an interpreter
    of its own), SIGTERM ``delay`` s after its handler is in place, check what it did; returns
    ``(name, outcome, latency)``."""
    args, outputs, _ = COMMANDS[name]
    args = [a.format(**records) for a in args]
    folder.mkdir()
    server = None if fresh else servers.get()
    if fresh:
        proc = _launch(args, folder)
    else:
        proc = server.start(args, folder, folder.parent / f"{folder.name}-logs", timeout=60)
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
        if server is not None:
            servers.put(server)
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


def test_sigterms_under_load(records, servers, tmp_path):
    """The 20 (command, delay) pairs of the seeded generator, then the five fresh interpreters, two commands
    at a time beside the two busy processes (the load on each command is higher than with one at a time)."""
    rng = np.random.default_rng(20261124)
    runs = []
    for i in range(20):
        name = list(COMMANDS)[i % len(COMMANDS)]
        lo, hi = COMMANDS[name][2]
        runs.append((name, rng.uniform(lo, hi), records, tmp_path / f"{i:02d}-{name}", servers))
    for i, name in enumerate(COMMANDS, start=20):
        runs.append((name, rng.uniform(0.0, 0.3), records, tmp_path / f"{i:02d}-{name}-fresh", servers, True))
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        with ThreadPoolExecutor(max_workers=2) as pool:
            report = list(pool.map(lambda run: one_signal(*run), runs))
    finally:
        for b in busy:
            b.kill()
            b.wait()
    assert sum(outcome == 143 for _, outcome, _ in report[:20]) >= 10, report
    assert all(outcome == 143 for _, outcome, _ in report[20:]), report  # no command ends in 0.3 s
