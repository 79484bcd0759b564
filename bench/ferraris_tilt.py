"""Monte Carlo of the Ferraris calibration on tilted faces, side by side with imucal's method on the same data.

Sessions of the independent generator of tests/oracles/handheld_imu.py (``ferraris_session``: laid out like
imucal's example: six faces held 4-7 s, three whole turns about the vertical between poses of 1.0-1.5 s,
each closing within ``--closure`` deg rms (default 0.2: by hand against a stop), 102.4 Hz, every placement
tilted by ``--tilt`` deg rms (default 0.3) at a random heading, the ``mems`` grade
of errors and noise; ``--lsb``: the rates rounded to a consumer chip's counts, 0.061 deg/s and 0.0048 m/s^2).
Each is calibrated by ``inscal.calibrate.calibrate(rec, "ferraris", **options)`` (the inscal on the path:
run it on another tree to compare; ``--min-static``/``--settle``/``--face-tilt`` override the method's defaults) and by
imucal's equations (``imucal_estimates`` of the generator module, written from imucal's published code) on
the true regions (the faces trimmed by 0.25 s at both ends, the turns' moves).  Printed per parameter group:
the share calibrated, RMS(error / sigma) (target 0.8-1.2) and the median |error| of inscal and of imucal.

Run: ``PYTHONPATH=src python bench/ferraris_tilt.py [--seeds 50] [--tilt 0.3] [--closure 0.2] [--lsb]
[--min-static S] [--face-tilt DEG] [--turn-closure DEG]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "oracles"))
from handheld_imu import canonical_truth, ferraris_session, grade, imucal_estimates  # noqa: E402

from inscal.calibrate import calibrate  # noqa: E402
from inscal.core.earth import Site  # noqa: E402

NAMES = ("accel_bias", "accel_scale_factor", "accel_misalignment", "gyro_bias", "gyro_scale_factor",
         "gyro_misalignment")
UNITS = {"accel_bias": (1e6 / 9.80665, "ug"), "accel_scale_factor": (1e6, "ppm"),
         "accel_misalignment": (180 / math.pi * 3600, "arcsec"), "gyro_bias": (180 / math.pi * 3600, "deg/h"),
         "gyro_scale_factor": (1e6, "ppm"), "gyro_misalignment": (180 / math.pi * 3600, "arcsec")}
LSB = (math.radians(0.061035), 0.0047900)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--tilt", type=float, default=0.3)
    ap.add_argument("--closure", type=float, default=0.2)
    ap.add_argument("--lsb", action="store_true")
    ap.add_argument("--min-static", type=float, default=None)
    ap.add_argument("--settle", type=float, default=None)
    ap.add_argument("--face-tilt", type=float, default=None, help="the stated face tilt [deg] (default: the method's)")
    ap.add_argument("--turn-closure", type=float, default=None, help="the stated turn closure [deg] (default: the "
                    "method's)")
    args = ap.parse_args()
    opts = {k: v for k, v in (("min_static", args.min_static), ("settle", args.settle),
                              ("face_tilt", None if args.face_tilt is None else math.radians(args.face_tilt)),
                              ("turn_closure", None if args.turn_closure is None else math.radians(args.turn_closure)))
            if v is not None}
    fs = 102.4
    z = {n: [] for n in NAMES}
    err = {n: [] for n in NAMES}
    err_imucal = {n: [] for n in NAMES}
    fails = []
    t0 = time.process_time()
    for seed in range(args.seeds):
        rng = np.random.default_rng(5000 + seed)
        Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
        lg = ferraris_session(rng, Mg, bg, Ma, ba, tilt_deg=args.tilt, rate_hz=fs, arw=arw, vrw=vrw,
                              lsb=LSB if args.lsb else None, closure_deg=args.closure)
        truth = canonical_truth(Mg, bg, Ma, ba)
        im = imucal_estimates(lg, fs)
        for n in NAMES:
            free = np.ones(6, bool) if n != "accel_misalignment" else np.isin(np.arange(6), (2, 4, 5))
            err_imucal[n].append((im[n] - truth[n])[free[: truth[n].size]])
        rec = SimpleNamespace(time=lg.time, dtheta=lg.dtheta, dvel=lg.dvel, site=Site(0.8, gravity_model=9.80))
        try:
            res = calibrate(rec, "ferraris", **opts)
        except Exception as exc:  # noqa: BLE001 - a failed session is a figure of the study
            fails.append(f"seed {5000 + seed}: {exc}")
            continue
        for n in NAMES:
            e, s = res.value(n) - truth[n], res.sigma[n]
            free = np.isfinite(s)
            z[n].append(e[free] / s[free])
            err[n].append(e[free])
    cpu = time.process_time() - t0
    ok = args.seeds - len(fails)
    print(f"{args.seeds} Ferraris sessions, faces tilted {args.tilt:g} deg rms, turns closing within {args.closure:g} "
          f"deg rms{', counts' if args.lsb else ''}, "
          f"options {opts or 'defaults'}: {ok} calibrated ({100.0 * ok / args.seeds:.0f} %), {cpu:.1f} s CPU")
    for f in fails[:5]:
        print("  failed:", f)
    print(f"{'group':20s} {'RMS(e/s)':>9s} {'max|e/s|':>9s} {'median|e| inscal':>17s} {'imucal':>10s} "
          f"{'ratio':>6s}")
    for n in NAMES:
        sc, unit = UNITS[n]
        mi = np.median(np.abs(np.concatenate(err_imucal[n]))) * sc
        if not z[n]:
            print(f"{n:20s} {'-':>9s} {'-':>9s} {'-':>17s} {mi:10.4g} {unit}")
            continue
        zz = np.concatenate(z[n])
        me = np.median(np.abs(np.concatenate(err[n]))) * sc
        print(f"{n:20s} {np.sqrt(np.mean(zz**2)):9.3f} {np.max(np.abs(zz)):9.2f} {me:17.4g} {mi:10.4g} "
              f"{me / mi:6.2f}  {unit}")


if __name__ == "__main__":
    main()
