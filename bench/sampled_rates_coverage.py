"""Coverage of the multi-position sigma on hand-held logs through a ``sampled-rates`` import: RMS of
error / sigma per parameter group and how many fits are consistent, over ``--sessions`` logs.

Each session: the independent generator of the tests (tests/oracles/handheld_imu.py), a MEMS grade with its
noise, 12 poses, a 0.3 deg hand tremor in the moves, 100 Hz with a clock jittered by ``--jitter`` of a
sample; its point readings at the stamps integrated onto a uniform grid by the import's rule
(:func:`inscal.io.formats.rates.integrate_rates`), then ``calibrate(..., "multi-position")``.

    python bench/sampled_rates_coverage.py [--sessions 20] [--jitter 0.3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))
from handheld_imu import canonical_truth, generate, grade  # noqa: E402

from inscal.calibrate import calibrate  # noqa: E402
from inscal.calibrate.windows import CalibrationError  # noqa: E402
from inscal.core.earth import Site  # noqa: E402
from inscal.io.formats.rates import integrate_rates  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--jitter", type=float, default=0.3)
    args = ap.parse_args()
    z = {}
    consistent = failed = 0
    for s in range(args.sessions):
        rng = np.random.default_rng(700 + s)
        Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
        lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=100.0, lat=0.8, g=9.80, arw=arw, vrw=vrw,
                      jitter=args.jitter, tremor_deg=0.3, samples=True)
        ri = integrate_rates(lg.time, lg.dtheta, lg.dvel)
        rec = SimpleNamespace(time=ri.time, dtheta=ri.gyro, dvel=ri.accel, site=Site(0.8, gravity_model=9.80))
        try:
            res = calibrate(rec, "multi-position", min_static=2.0, settle=0.25)
        except CalibrationError as exc:
            failed += 1
            print(f"  session {s}: {str(exc)[:200]}")
            continue
        consistent += bool(res.fit["consistent"])
        for name, want in canonical_truth(Mg, bg, Ma, ba).items():
            sig = res.sigma[name]  # the reported sigma
            free = np.isfinite(sig) & (sig > 0)
            z.setdefault(name, []).extend(((res.value(name) - want)[free] / sig[free]).tolist())
    print(f"{args.sessions} sessions (jitter {args.jitter:g}): {failed} failed, {consistent} of "
          f"{args.sessions - failed} fits consistent")
    for name, v in z.items():
        print(f"  {name:22s} RMS(error/sigma) {float(np.sqrt(np.mean(np.square(v)))):.3f} over {len(v)} values")


if __name__ == "__main__":
    main()
