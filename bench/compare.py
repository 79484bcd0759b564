"""Benchmarks of the code before a change beside the code now, in the same run.

``python bench/compare.py --base REV [SCRIPT ...]`` checks ``REV`` out into a git worktree (kept in
the system's temporary folder, so its numba cache survives between runs), then runs each benchmark
script alternately with the base's sources and with this tree's (base, now, base, now, ...: both
see the same machine load), and prints each figure line of both beside the ratio of their first
figure.  A script that the base does not have runs with this tree's copy on the base's sources
(``--same-script``: always so, for a benchmark written for the change).

Figures are read from the lines the scripts print: the first ``X M samples/s`` (higher is better)
or ``X s`` (lower is better) of each line.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RATE = re.compile(r"([0-9.]+(?:e[+-]?\d+)?) M samples/s")
SECONDS = re.compile(r"(?:in|took|=|:)\s+([0-9.]+(?:e[+-]?\d+)?) s\b")


def worktree(rev: str) -> Path:
    """A checkout of ``rev`` (commit hash resolved) beside the temporary folder; made once."""
    sha = subprocess.run(["git", "rev-parse", rev], cwd=ROOT, check=True, capture_output=True,
                         text=True).stdout.strip()
    dest = Path(tempfile.gettempdir()) / f"inscal-bench-{sha[:12]}"
    if not (dest / "src" / "inscal").is_dir():
        subprocess.run(["git", "worktree", "add", "--detach", "--force", str(dest), sha], cwd=ROOT, check=True,
                       capture_output=True)
    return dest


def run_script(tree: Path, script: Path, args: list[str]) -> list[str]:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    r = subprocess.run([sys.executable, str(script), *args], cwd=tree, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        return [f"FAILED ({r.returncode}): {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else ''}"]
    return [ln for ln in r.stdout.splitlines() if ln.strip()]


def figure(line: str) -> tuple[float, bool] | None:
    """``(value, higher_is_better)`` of a printed line, or None."""
    m = RATE.search(line)
    if m:
        return float(m.group(1)), True
    m = SECONDS.search(line)
    if m:
        return float(m.group(1)), False
    return None


def best(runs: list[list[str]]) -> list[str]:
    """Per line, the run with the best figure (the scripts' own best-of timing, over the repeats)."""
    out = []
    for lines in zip(*runs):
        figs = [(figure(ln), ln) for ln in lines]
        scored = [(f[0] if f[1] else -f[0], ln) for f, ln in figs if f is not None]
        out.append(max(scored)[1] if scored else lines[0])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--base", required=True, help="the git revision before the change")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each side, alternating (best kept)")
    ap.add_argument("--same-script", action="store_true", help="run this tree's scripts on both sides")
    ap.add_argument("scripts", nargs="*", help="bench scripts (default: bench_simulate.py bench_strapdown.py)")
    ap.add_argument("--args", default="", help="arguments passed to every script")
    a = ap.parse_args(argv)
    base = worktree(a.base)
    scripts = a.scripts or ["bench_simulate.py", "bench_strapdown.py"]
    for name in scripts:
        now_script = ROOT / "bench" / Path(name).name
        base_script = base / "bench" / Path(name).name
        if a.same_script or not base_script.is_file():
            base_script = now_script
        runs: dict[str, list[list[str]]] = {"base": [], "now": []}
        for _ in range(a.repeat):
            runs["base"].append(run_script(base, base_script, a.args.split()))
            runs["now"].append(run_script(ROOT, now_script, a.args.split()))
        print(f"== {Path(name).name} (base {a.base} at {base}, best of {a.repeat} alternating runs)")
        b, n = best(runs["base"]), best(runs["now"])
        for lb, ln in zip(b, n):
            fb, fn = figure(lb), figure(ln)
            ratio = ""
            if fb and fn and fb[0] > 0 and fn[0] > 0:
                ratio = f"  [x{fn[0] / fb[0] if fn[1] else fb[0] / fn[0]:.2f} faster]"
            print(f"  before: {lb}\n  now:    {ln}{ratio}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
