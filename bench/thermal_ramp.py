"""The one-run thermal calibration (systematic filter with thermal states on a continuous chamber ramp)
against the plateau method, over seeds: error / 1 sigma of every thermal coefficient of both, their
agreement, and the accuracy each reaches for its chamber time.

Per seed: ``thermal-ramp`` (the ``s16`` IMU and noise, the S16 Table 1 path twice while the chamber holds
-40 degC for 10 min then ramps at 1 degC/min to +60 degC: 2.1 h; or ``--ramp thermal-cycle``, the path four
times while the chamber goes up to +60 degC and back at 1 degC/min: 4.1 h) calibrated in one run with
``systematic51`` and ``--states 51,thermal`` (method (b)); and ``thermal-plateaus-s16`` (the same IMU and
noise, the S16 path at five plateaus -40 .. +60 degC with 1 degC/min ramps and 30-min soaks between: 9.0 h)
calibrated with ``thermal-plateaus --per-plateau systematic51`` (method (a)), both with the truth's orders.
Each seed's two records are independent draws of the noise (seeds ``s`` and ``1000 + s``).

Printed per thermal coefficient (term and order, all three axes pooled over the seeds):

* ``RMS z`` of (b) and (a): ``z = (estimate - truth) / sigma`` (target 0.8 - 1.2; the 95 % band an RMS of
  that many standard normal numbers falls in beside it).  (a)'s truth is the truth polynomial projected on
  the fitted one (:func:`inscal.calibrate.thermal.thermal_truth`; the truth itself at the truth's orders).
* ``RMS d``: the agreement ``(b - a) / sqrt(sigma_b^2 + sigma_a^2)`` (target about 1).
* the median 1 sigma of each in field units and their ratio: (b) reaches (a)'s accuracy where
  ``sigma_b / sigma_a <= 1`` with 2.1 h of chamber time against 9.0 h.

    .venv/bin/python bench/thermal_ramp.py                 # 20 seeds, about 20 s per seed
    .venv/bin/python bench/thermal_ramp.py --seeds 3
    .venv/bin/python bench/thermal_ramp.py --ramp thermal-cycle   # up and down: 4.1 h of chamber time
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from inscal.calibrate import calibrate
from inscal.calibrate.thermal import thermal_truth
from inscal.core import units
from inscal.core.stats import chi2_ppf
from inscal.core.thermal import RATE_TERM, THERMAL_TERMS
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def rms_interval(n: int, level: float = 0.95) -> tuple[float, float]:
    """The interval the RMS of ``n`` standard normal numbers falls in with probability ``level``."""
    a = (1.0 - level) / 2.0
    return math.sqrt(chi2_ppf(a, n) / n), math.sqrt(chi2_ppf(1.0 - a, n) / n)


def rms(a) -> float:
    return math.sqrt(float(np.mean(np.square(a))))


def field_unit(name: str, k: int) -> tuple[str, str]:
    """The field unit of a coefficient of order ``k`` and the unit of its base quantity (per degC^k, the same
    factor from SI)."""
    if name == RATE_TERM[0]:
        return RATE_TERM[2], RATE_TERM[2]
    base = THERMAL_TERMS[name][2]
    return units.per_degree_unit(base, k), base


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--no-plateaus", action="store_true", help="only the ramp (b)")
    ap.add_argument("--ramp", default="thermal-ramp", help="the scenario of (b): thermal-ramp (one ramp, 2.1 h) or "
                    "thermal-cycle (up and down, 4.1 h)")
    args = ap.parse_args()
    ramp = scenarios.build(args.ramp)
    plat = scenarios.build("thermal-plateaus-s16")
    truth = ramp.thermal
    orders = {n: truth.order(n) for n in ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor")}
    zb, za, d, sb, sa = {}, {}, {}, {}, {}
    zbase = {}
    t_b = t_a = 0.0
    dur = {}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        rec = simulate(ramp, np.random.default_rng(seed)).to_record()
        dur["b"] = rec.duration
        t0 = time.perf_counter()
        rb = calibrate(rec, "systematic51", states="51,thermal")
        t_b += time.perf_counter() - t0
        for name in rb.estimated:
            e, s = np.atleast_1d(rb.error((ramp.imu, ramp.gimbal), name)), np.atleast_1d(rb.sigma[name])
            zbase.setdefault(name, []).append((e / s)[np.isfinite(s)])
        ra = ta = None
        if not args.no_plateaus:
            rec = simulate(plat, np.random.default_rng(1000 + seed)).to_record()
            dur["a"] = rec.duration
            t0 = time.perf_counter()
            ra = calibrate(rec, "thermal-plateaus", per_plateau="systematic51", orders=orders)
            t_a += time.perf_counter() - t0
            ta = thermal_truth(ra, plat.imu, plat.gimbal, plat.thermal)
        for name in (*orders, RATE_TERM[0]):
            tb = np.atleast_2d(getattr(truth, name))
            eb, sgb = np.atleast_2d(getattr(rb.thermal, name)), np.atleast_2d(rb.thermal_sigma[name])
            for k in range(tb.shape[0]):
                key = (name, k + 1)
                zb.setdefault(key, []).append((eb[k] - tb[k]) / sgb[k])
                sb.setdefault(key, []).append(sgb[k])
                if ra is None or name == RATE_TERM[0]:
                    continue
                ea, sga = getattr(ra.thermal, name)[k], ra.thermal_sigma[name][k]
                za.setdefault(key, []).append((ea - ta[name][k]) / sga)
                sa.setdefault(key, []).append(sga)
                d.setdefault(key, []).append((eb[k] - ea) / np.hypot(sgb[k], sga))
        print(f"seed {seed}: (b) {t_b:.1f} s, (a) {t_a:.1f} s so far", flush=True)
    n = args.seeds
    print(f"\n(b) {args.ramp}, one run of systematic51 --states 51,thermal: {dur['b'] / 3600:.2f} h of chamber time, "
          f"{t_b / n:.1f} s per calibration")
    if "a" in dur:
        print(f"(a) thermal-plateaus-s16, thermal-plateaus --per-plateau systematic51: {dur['a'] / 3600:.2f} h of chamber "
              f"time, {t_a / n:.1f} s per calibration")
    print(f"{n} seeds; z = (estimate - truth) / sigma, d = (b - a) / sqrt(sigma_b^2 + sigma_a^2), 3 axes pooled\n")
    print(f"{'coefficient':26s} {'RMS z (b)':>9s} {'RMS z (a)':>9s} {'RMS d':>6s} {'95% band':>10s}   "
          f"{'1 sigma (b), median':>34s} {'(a)':>30s} {'b/a':>5s}  unit")
    allb, alla, alld = [], [], []
    for key, zs in zb.items():
        name, k = key
        a = np.concatenate(zs)
        allb.append(a)
        lo, hi = rms_interval(a.size)
        u, ub = field_unit(name, k)
        smb = units.from_si(np.median(np.array(sb[key]), axis=0), ub)
        if key in za:
            az, ad = np.concatenate(za[key]), np.concatenate(d[key])
            alla.append(az)
            alld.append(ad)
            sma = units.from_si(np.median(np.array(sa[key]), axis=0), ub)
            cols = f"{rms(az):9.3f} {rms(ad):6.3f}"
            tail = f"[{', '.join(f'{x:.3g}' for x in sma)}] {np.median(smb / sma):5.2f}"
        else:
            cols = f"{'-':>9s} {'-':>6s}"
            tail = f"{'(invisible on plateaus)':>30s} {'-':>5s}"
        print(f"{name + f' order {k}':26s} {rms(a):9.3f} {cols} {f'{lo:.2f}-{hi:.2f}':>10s}   "
              f"[{', '.join(f'{x:.3g}' for x in smb)}] {tail}  {u}")
    a = np.concatenate(allb)
    lo, hi = rms_interval(a.size)
    line = f"{'all thermal coefficients':26s} {rms(a):9.3f}"
    if alla:
        line += f" {rms(np.concatenate(alla)):9.3f} {rms(np.concatenate(alld)):6.3f}"
    print(line + f" {f'{lo:.2f}-{hi:.2f}':>10s}")
    print("\n(b) base errors at T_ref: RMS z per parameter")
    for name, zs in zbase.items():
        a = np.concatenate(zs)
        lo, hi = rms_interval(a.size)
        print(f"  {name:26s} {a.size:4d} {rms(a):7.3f} {f'{lo:.2f}-{hi:.2f}':>10s} max |z| {np.max(np.abs(a)):.2f}")


if __name__ == "__main__":
    main()
