"""``inscal calibrate`` neither eats the machine's memory nor ignores an interrupt.

(a) Before the record is read, its size (:func:`inscal.io.record_info`) and the systematic filter's
per-step stores (:func:`inscal.calibrate.systematic.driver.systematic_bytes`) are compared with the
available memory: a record too big to read, or a filter rate that would fill the memory, is refused in
one line (exit 2, nothing written, the child's peak RSS small; the child forked from a process that imported
the package once, :mod:`forkserver`).

(b) The systematic filter and smoother run in slices of steps (:mod:`inscal.core.slices`), so SIGTERM
inside a long pass (--filter-rate-hz 50 on the 1-h s16 record: ~7 s a pass, one numba call each before the
slices, when such a signal waited up to that long) ends the run within 2 s: exit 143, one line
``inscal: interrupted (SIGTERM)``, nothing written."""

import os
import sys
from pathlib import Path

import h5py
import pytest
from test_memory_caps import (
    MAX_REFUSE_S,
    MAX_RSS,
    sigterm_when_busy,
    small_record,
    snapshot,
)

from inscal.cli.calibrate import run_calibrate
from inscal.cli.calibrate_setup import CalibrateOptions
from inscal.cli.limits import available_memory
from inscal.cli.simulate import run_simulate

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="POSIX signals, os.wait4, /proc")

#: the forked child's CPU time by which it is surely inside the first filter pass (the interpreter's start and
#: the imports, ~2.2 s, are the fork server's; reading the record, the encoder check and the noise estimate take
#: ~0.3 s; the pass ~7 s more)
IN_FILTER_CPU_S = 2.8
#: the filter rate of the interrupted calibration: 193,050 steps of 61 states (~1.5 GB of per-step stores)
LONG_FILTER_HZ = 50


def unwritten_record(path: Path, n: int, rate_hz: float) -> None:
    """A valid record header whose datasets claim ``n`` samples at ``rate_hz``, never written (a few kB)."""
    small_record(path)
    with h5py.File(path, "a") as h:
        h.attrs["rate_hz"] = rate_hz
        for name, cols in (("time", None), ("dtheta", 3), ("dvel", 3), ("gimbal", 2)):
            del h[name]
            shape = (n,) if cols is None else (n, cols)
            h.create_dataset(name, shape=shape, dtype="f8", chunks=(1 << 14,) + shape[1:],
                             fillvalue=-1.0 if cols is None else 0.0)


@pytest.fixture()
def server(fork_servers):
    """The refusals fork from one process that imported the package (:mod:`forkserver`), as in
    ``test_memory_caps``: each is the command's own run, so it is held to the same :data:`MAX_REFUSE_S`."""
    return fork_servers.get()


def refuse(server, folder: Path, logs: Path, args) -> str:
    before = snapshot(folder)
    r = server.run(args, folder, logs, timeout=120, env={"COLUMNS": "200"})
    err = (logs / "stderr").read_text()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert r["rc"] == 2, (r["rc"], err[-2000:])
    assert "Traceback" not in err and len(lines) == 1 and lines[0].startswith("inscal: error: "), err[-2000:]
    assert snapshot(folder) == before, "something was written, or an input changed"
    assert r["rss"] < MAX_RSS, f"peak RSS {r['rss'] / 1e9:.2f} GB"
    assert r["seconds"] < MAX_REFUSE_S, f"{r['seconds']:.1f} s to refuse"
    return lines[0]


@pytest.mark.parametrize("method", ["systematic51", "n25"])
def test_a_record_too_big_to_read_is_refused_up_front(server, tmp_path, method):
    folder = tmp_path / "run"
    folder.mkdir()
    unwritten_record(folder / "huge.h5", 10**11, 10.0)
    line = refuse(server, folder, tmp_path / "logs", ["calibrate", "huge.h5", "--method", method, "--out", "p.toml"])
    assert "reading huge.h5 (100000000000 samples, 1e+10 s at 10 Hz) needs about" in line, line
    assert "TB of memory (this machine has" in line and "calibrate a shorter record" in line, line


def test_a_filter_rate_that_fills_the_memory_is_refused_up_front(server, tmp_path):
    """A record that fits in memory (about 5 % of what is available) whose filter at the sample rate does not
    (its per-step stores take ~40 times the record's bytes)."""
    avail = available_memory()
    if avail is None:
        pytest.skip("the available memory is unknown here")
    n = int(0.05 * avail / 176)
    folder = tmp_path / "run"
    folder.mkdir()
    unwritten_record(folder / "long.h5", n, 100.0)
    line = refuse(server, folder, tmp_path / "logs", ["calibrate", "long.h5", "--method", "systematic51",
                                                      "--filter-rate-hz", "100", "--out", "p.toml"])
    assert f"the 61-state filter's {n} steps at --filter-rate-hz 100 over long.h5 ({n} samples" in line, line
    assert "lower --filter-rate-hz" in line, line


@pytest.fixture(scope="module")
def s16(tmp_path_factory):
    """The 1-h s16 record (``inscal simulate s16``'s, written here: the record, not its command, is the input),
    and the systematic kernels loaded (or compiled and cached) here by one calibration, so that the child loads
    them from numba's cache: a compilation, unlike the kernels, cannot be interrupted."""
    folder = tmp_path_factory.mktemp("s16")
    run_simulate("s16", folder / "s16.h5")
    run_calibrate(CalibrateOptions(folder / "s16.h5", "systematic51", folder / "warm.toml", states="51"))
    return folder / "s16.h5"


def test_sigterm_inside_the_filter_ends_the_calibration_promptly(tmp_path, s16, server):
    if (available_memory() or 0.0) < 4e9:
        pytest.skip("less than 4 GB of memory available for the filter's stores")
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "s16.h5").write_bytes(s16.read_bytes())
    before = snapshot(folder)
    sigterm_when_busy(server, ["calibrate", "s16.h5", "--method", "systematic51", "--filter-rate-hz",
                               str(LONG_FILTER_HZ), "--out", "p.toml"], folder, tmp_path / "logs", IN_FILTER_CPU_S)
    assert snapshot(folder) == before, "something was written"
    assert not os.path.exists(folder / "p.toml")
