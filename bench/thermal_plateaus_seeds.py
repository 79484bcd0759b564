"""The plateau thermal calibration over seeds: error / 1 sigma of every thermal coefficient.

Simulates a built-in thermal scenario (default ``thermal-plateaus``: the n25 IMU and path at five
chamber plateaus, -40 .. +60 degC) with a different noise seed each run, calibrates it with
``thermal-plateaus`` (``--per-plateau``, default n25) and prints, per thermal term and order, the
spread of ``(estimate - truth) / sigma`` over the seeds and components: its RMS (target 0.8 - 1.2, and
the 95 % interval an RMS of that many standard normal numbers falls in), its mean, the largest
``|error| / sigma`` and the fits' chi^2 p-values.  The truth of a coefficient is the truth's own
polynomial projected on the fitted one (:func:`inscal.calibrate.thermal.thermal_truth`; the truth
itself when the fitted orders are at least the truth's).  Without ``--order`` the method's defaults run: each
term quadratic (misalignments constant), its order raised while the fit misfits the plateaus (the built-in
model's cubic accelerometer bias is found so); the orders chosen are printed.

    .venv/bin/python bench/thermal_plateaus_seeds.py                       # 20 seeds, n25, 100 Hz
    .venv/bin/python bench/thermal_plateaus_seeds.py --seeds 5 --rate-hz 20 --order accel_bias=3
    .venv/bin/python bench/thermal_plateaus_seeds.py --scenario thermal-plateaus-s16 --per-plateau systematic51 --seeds 1
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from inscal.calibrate import calibrate
from inscal.calibrate.thermal import thermal_truth
from inscal.core import units
from inscal.core.stats import chi2_ppf
from inscal.core.thermal import THERMAL_TERMS
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def rms_interval(n: int, level: float = 0.95) -> tuple[float, float]:
    """The interval the RMS of ``n`` standard normal numbers falls in with probability ``level``."""
    a = (1.0 - level) / 2.0
    return math.sqrt(chi2_ppf(a, n) / n), math.sqrt(chi2_ppf(1.0 - a, n) / n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="thermal-plateaus")
    ap.add_argument("--per-plateau", default="n25")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--rate-hz", type=float, default=None, help="sampling rate (default: the scenario's)")
    ap.add_argument("--order", action="append", default=None, help="NAME=K, an order kept as named (default: "
                    "the method's, raised while a fit misfits)")
    ap.add_argument("--t-ref", type=float, default=20.0)
    args = ap.parse_args()
    orders: dict[str, int] = {}
    for item in args.order or []:
        name, _, k = item.partition("=")
        orders[name] = int(k)
    sc = scenarios.build(args.scenario)
    if args.rate_hz:
        sc = dataclasses.replace(sc, rate_hz=args.rate_hz)
    z: dict[tuple[str, int], list[np.ndarray]] = {}
    zref: dict[str, list[np.ndarray]] = {}
    pvals: dict[str, list[float]] = {}
    sig_field: dict[tuple[str, int], list[np.ndarray]] = {}
    t0 = time.perf_counter()
    duration = None
    cov_source = set()
    orders_seen: dict[tuple, int] = {}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        rec = simulate(sc, np.random.default_rng(seed)).to_record()
        duration = rec.duration
        res = calibrate(rec, "thermal-plateaus", per_plateau=args.per_plateau, orders=orders, t_ref=args.t_ref)
        truth = thermal_truth(res, sc.imu, sc.gimbal, sc.thermal)
        cov_source.add(res.diagnostics["covariance_source"])
        chosen = tuple((n, res.thermal.order(n)) for n in THERMAL_TERMS if res.thermal.order(n))
        orders_seen[chosen] = orders_seen.get(chosen, 0) + 1
        for name, c in truth.items():
            est, sig = getattr(res.thermal, name), res.thermal_sigma[name]
            for k in range(c.shape[0]):
                ok = np.isfinite(sig[k])
                z.setdefault((name, k + 1), []).append(((est[k] - c[k]) / sig[k])[ok])
                sig_field.setdefault((name, k + 1), []).append(units.from_si(sig[k], THERMAL_TERMS[name][2]))
            pvals.setdefault(name, []).append(res.thermal_fit["terms"][name]["p_value"])
        for name in res.estimated:
            e = np.atleast_1d(res.error((sc.imu, sc.gimbal), name))
            s = np.atleast_1d(res.sigma[name])
            ok = np.isfinite(s)
            zref.setdefault(name, []).append((e / s)[ok])
        print(f"seed {seed}: {time.perf_counter() - t0:.1f} s", flush=True)
    n_seeds = args.seeds
    print(f"\n{args.scenario} ({duration / 3600:.2f} h of chamber time, {sc.rate_hz:g} Hz), per plateau "
          f"{args.per_plateau} (plateau covariance: {', '.join(sorted(cov_source))}), orders named {orders or 'none'}, "
          f"{n_seeds} seeds, {(time.perf_counter() - t0) / n_seeds:.1f} s per seed")
    for chosen, count in orders_seen.items():
        print(f"  orders fitted on {count} seed(s): {', '.join(f'{n} {k}' for n, k in chosen)}")
    print(f"{'thermal coefficient':28s} {'n':>4s} {'RMS z':>7s} {'95% band':>13s} {'mean z':>7s} {'max|z|':>7s}"
          f"  {'typical 1 sigma':>30s}")
    all_z = []
    for (name, k), zs in z.items():
        a = np.concatenate(zs)
        all_z.append(a)
        lo, hi = rms_interval(a.size)
        unit = units.per_degree_unit(THERMAL_TERMS[name][2], k)
        sf = np.median(np.array(sig_field[(name, k)]), axis=0)
        print(f"{name + f' order {k}':28s} {a.size:4d} {math.sqrt(np.mean(a ** 2)):7.3f} {f'{lo:.2f}-{hi:.2f}':>13s} "
              f"{np.mean(a):+7.3f} {np.max(np.abs(a)):7.2f}  [{', '.join(f'{x:.3g}' for x in sf)}] {unit}")
    a = np.concatenate(all_z)
    lo, hi = rms_interval(a.size)
    print(f"{'all thermal coefficients':28s} {a.size:4d} {math.sqrt(np.mean(a ** 2)):7.3f} {f'{lo:.2f}-{hi:.2f}':>13s} "
          f"{np.mean(a):+7.3f} {np.max(np.abs(a)):7.2f}")
    print("\nvalues at T_ref (result.imu / result.gimbal):")
    for name, zs in zref.items():
        a = np.concatenate(zs)
        lo, hi = rms_interval(a.size)
        print(f"  {name:26s} {a.size:4d} {math.sqrt(np.mean(a ** 2)):7.3f} {f'{lo:.2f}-{hi:.2f}':>13s} {np.mean(a):+7.3f} "
              f"{np.max(np.abs(a)):7.2f}")
    print("\nfit p-values per term (uniform on [0, 1] when the sigma are right):")
    for name, ps in pvals.items():
        p = np.array(ps)
        print(f"  {name:26s} median {np.median(p):.2f}, below 0.05: {np.sum(p < 0.05)}/{p.size}, "
              f"below 0.001 (sigma scaled): {np.sum(p < 1e-3)}/{p.size}")


if __name__ == "__main__":
    main()
