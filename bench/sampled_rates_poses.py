"""Still poses of hand-held logs through a ``sampled-rates`` import: how many perfectly still poses the
still-pose detector rejects, against the same sessions as increments (a ``rates`` / increments record).

Each session: the independent generator of the tests (tests/oracles/handheld_imu.py), a MEMS grade, 16
poses of 4 s, no tremor (the poses are perfectly still), 100 Hz with a clock jittered by ``--jitter`` of a
sample; its point readings at the (jittered) stamps integrated onto a uniform grid by the import's rule
(:func:`inscal.io.formats.rates.integrate_rates`), and its increments as they are.  Every candidate the
detector forms inside a true still pose is counted, with its reason.

    python bench/sampled_rates_poses.py [--sessions 19] [--jitter 0.0]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))
from handheld_imu import generate, grade  # noqa: E402

from inscal.calibrate.static_detect import detect_still  # noqa: E402
from inscal.io.formats.rates import integrate_rates  # noqa: E402


def poses(si, spans) -> Counter:
    """The fate of the candidates that lie inside a true still pose: kept, or the first word of the reason."""
    out = Counter()
    for c in si.candidates:
        mid = 0.5 * (c.t0 + c.t1)
        if any(a < mid < b for a, b in spans):
            out["kept" if c.kept else c.reason.split(",")[0]] += 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=19)
    ap.add_argument("--jitter", type=float, default=0.0)
    args = ap.parse_args()
    tot = {"sampled-rates": Counter(), "increments": Counter()}
    examples = []
    for s in range(args.sessions):
        kw = dict(n_poses=16, rate_hz=100.0, still_s=4.0, tremor_deg=0.0, jitter=args.jitter)
        rng = np.random.default_rng(1000 + s)
        Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
        state = rng.bit_generator.state
        lg = generate(rng, Mg, bg, Ma, ba, arw=arw, vrw=vrw, samples=True, **kw)
        ri = integrate_rates(lg.time, lg.dtheta, lg.dvel)
        si = detect_still(ri.time, ri.gyro, ri.accel)
        c = poses(si, lg.still)
        tot["sampled-rates"] += c
        examples += [x.reason for x in si.candidates if not x.kept and "tilted" in x.reason][:1]
        rng.bit_generator.state = state
        li = generate(rng, Mg, bg, Ma, ba, arw=arw, vrw=vrw, **kw)
        tot["increments"] += poses(detect_still(li.time, li.dtheta, li.dvel), li.still)
    for k, c in tot.items():
        n = sum(c.values())
        print(f"{k:14s} {n} candidates in still poses: {c['kept']} kept, {c['tilted']} rejected as tilted, "
              f"other rejections {dict((r, v) for r, v in c.items() if r not in ('kept', 'tilted'))}")
    for e in examples[:3]:
        print(f"  e.g. {e}")


if __name__ == "__main__":
    main()
