"""Ferraris sessions (six faces, three whole turns) through a ``sampled-rates`` import: how many calibrate
with ``--method ferraris`` and its defaults, and why the others fail.

Each session: the independent generator of the tests (tests/oracles/handheld_imu.py), a MEMS grade with
its noise, the faces and turns of tests/oracles/test_handheld_ferraris.py, 50 Hz, a clock jittered by
``--jitter`` of a sample; its point readings at the stamps integrated onto a uniform grid by the import's
rule (:func:`inscal.io.formats.rates.integrate_rates`).

    python bench/sampled_rates_ferraris.py [--sessions 10] [--jitter 0.3]
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import Counter
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))
from handheld_imu import generate, grade, rot  # noqa: E402

from inscal.calibrate import calibrate  # noqa: E402
from inscal.calibrate.windows import CalibrationError  # noqa: E402
from inscal.core.earth import Site  # noqa: E402
from inscal.io.formats.rates import integrate_rates  # noqa: E402


def face(axis, sign, heading):
    up = np.zeros(3)
    up[axis] = sign
    a = np.array([0.3, 0.5, 0.7])
    x = a - up * (a @ up)
    x /= np.linalg.norm(x)
    return (rot(up, heading) @ np.column_stack([x, np.cross(up, x), up])).T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=10)
    ap.add_argument("--jitter", type=float, default=0.3)
    args = ap.parse_args()
    poses = [face(2, 1, 0.1), face(2, 1, 0.1), face(0, 1, 0.2), face(0, 1, 0.2), face(1, 1, 0.3), face(1, 1, 0.3),
             face(0, -1, 0.4), face(1, -1, 0.5), face(2, -1, 0.6)]
    turns = {0: ([0, 0, 1.0], 2 * math.pi), 2: ([1.0, 0, 0], -2 * math.pi), 4: ([0, 1.0, 0], 2 * math.pi)}
    fates = Counter()
    for s in range(args.sessions):
        rng = np.random.default_rng(500 + s)
        Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
        lg = generate(rng, Mg, bg, Ma, ba, poses=poses, turns=turns, rate_hz=50.0, lat=0.8, g=9.8, arw=arw, vrw=vrw,
                      move_s=4.0, jitter=args.jitter, samples=True)
        ri = integrate_rates(lg.time, lg.dtheta, lg.dvel)
        rec = SimpleNamespace(time=ri.time, dtheta=ri.gyro, dvel=ri.accel, site=Site(0.8, gravity_model=9.8))
        try:
            calibrate(rec, "ferraris")
            fates["calibrated"] += 1
        except CalibrationError as exc:
            fates["tilted" if "tilted" in str(exc) else "other"] += 1
            print(f"  session {s}: {str(exc)[:300]}")
    print(f"{args.sessions} Ferraris sessions through sampled-rates (jitter {args.jitter:g}): {dict(fates)}")


if __name__ == "__main__":
    main()
