"""Benchmark: peak memory and wall time of ``inscal allan`` (and ``inscal report``) on a long
static record (default 24 h at 100 Hz, 8.64 M samples, 622 MB), which they stream in chunks.

The record is written synthetically in the record format (white noise on the Earth rate and
gravity, chunk by chunk with :func:`inscal.io.write_stream`: much faster than simulating it) to
a temporary folder, removed afterwards.  Each command runs in its own subprocess; its peak
resident memory is the ``ru_maxrss`` of that child (``os.wait4``, the per-child form of
``resource.getrusage(RUSAGE_CHILDREN)``).  Target: < 1 GB for a 120-h record.

    python bench/bench_allan.py [--hours 24] [--rate-hz 100] [--no-report]
"""

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from inscal import io
from inscal.core.earth import Site


def write_static_record(path: Path, hours: float, rate_hz: float, chunk: int = 1 << 19, seed: int = 0) -> int:
    n = int(round(hours * 3600 * rate_hz))
    dt = 1.0 / rate_hz
    rng = np.random.default_rng(seed)
    arw = 0.002 * math.pi / 180 / 60  # rad/sqrt(s): 0.002 deg/sqrt(h)
    vrw = 10e-6 * 9.80665  # m/s/sqrt(s): 10 ug/sqrt(Hz)
    w = np.array([0.0, 7.292115e-5 * math.cos(math.radians(45)), 7.292115e-5 * math.sin(math.radians(45))])
    f = np.array([0.0, 0.0, 9.80])

    def chunks():
        for k0 in range(0, n, chunk):
            m = min(chunk, n - k0)
            t = (np.arange(k0, k0 + m) + 1) * dt
            dth = w * dt + rng.normal(0, arw * math.sqrt(dt), (m, 3))
            dv = f * dt + rng.normal(0, vrw * math.sqrt(dt), (m, 3))
            yield t, dth, dv, np.zeros((m, 2))

    info = io.RecordInfo(n, rate_hz, Site(math.radians(45), 0.0, 0.0), None, None, "bench-static", True)
    return io.write_stream(path, info, chunks())


def measure(args: list[str]) -> tuple[float, float, int, str]:
    """(wall s, peak RSS MB, exit code, stderr) of ``inscal ARGS`` in a subprocess."""
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace")
    return wall, ru.ru_maxrss / 1024.0, proc.returncode, err  # ru_maxrss: kB on Linux


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--no-report", action="store_true", help="measure inscal allan only")
    a = ap.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="inscal-bench-allan-"))
    rc = 0
    try:
        rec = folder / "static.h5"
        t0 = time.perf_counter()
        n = write_static_record(rec, a.hours, a.rate_hz)
        size_mb = rec.stat().st_size / 1e6
        print(f"record: {n} samples ({a.hours:g} h at {a.rate_hz:g} Hz), {size_mb:.0f} MB, written in "
              f"{time.perf_counter() - t0:.1f} s", flush=True)
        runs = [("allan", ["allan", str(rec), "--json"])]
        if not a.no_report:
            runs.append(("report", ["report", str(rec), "--out", str(folder / "r.html")]))
        for name, args in runs:
            wall, rss, code, err = measure(args)
            ok = code == 0 and rss < 1024
            rc |= 0 if ok else 1
            print(f"inscal {name} on {a.hours:g} h: {wall:.1f} s, peak RSS {rss:.0f} MB (target < 1024 MB)"
                  + ("" if code == 0 else f"; FAILED (exit {code}): {err.strip()[:300]}"), flush=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
