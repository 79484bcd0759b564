"""Benchmark: start-up time of the command line (median wall time of 5 runs each, subprocesses):
``inscal --help``, ``inscal --version`` and a small command (``inscal allan`` on a 1-minute
record, ``--json``).  Target: < 1 s each.  The CLI imports its heavy dependencies (scipy, numba,
matplotlib, dask, h5py) only inside the commands that need them."""

import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RUNS = 5


def timed(args: list[str]) -> tuple[float, int]:
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0, r.returncode


def small_record(path: Path) -> None:
    import numpy as np

    from inscal import io
    from inscal.core.earth import Site

    n, dt = 6000, 0.01  # 1 minute at 100 Hz
    rng = np.random.default_rng(0)
    t = np.arange(1, n + 1) * dt
    dth = rng.normal(0, 1e-7, (n, 3)) + np.array([0, 5e-5, 5e-5]) * dt
    dv = rng.normal(0, 1e-6, (n, 3)) + np.array([0, 0, 9.8]) * dt
    io.write_record(path, io.Record(t, dth, dv, np.zeros((n, 2)), 100.0, Site(math.radians(45), 0, 0)))


def main() -> int:
    folder = Path(tempfile.mkdtemp(prefix="inscal-bench-startup-"))
    rc = 0
    try:
        rec = folder / "small.h5"
        small_record(rec)
        timed(["--version"])  # warm the file cache (and numba/pyc caches) once
        for label, args in (("inscal --help", ["--help"]), ("inscal --version", ["--version"]),
                            ("inscal allan small.h5 --json (1 min at 100 Hz)", ["allan", str(rec), "--json"])):
            runs = [timed(args) for _ in range(RUNS)]
            med = statistics.median(t for t, _ in runs)
            bad = [c for _, c in runs if c != 0]
            rc |= 1 if bad else 0
            print(f"{label}: median {med:.3f} s over {RUNS} runs (min {min(t for t, _ in runs):.3f} s); target < 1 s"
                  + (f"; FAILED exit {bad[0]}" if bad else ""), flush=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
