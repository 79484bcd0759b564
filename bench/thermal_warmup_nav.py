"""The 2-h warm-up navigation (``thermal-warmup``: the s16 IMU on a static base, 20 -> 45 degC, tau 20 min):
the maximum horizontal position error compensated (a) with the errors at 20 degC only (a calibration at
one temperature) and (b) with them and the thermal model at the record's temperature readings.

Four tables:

1. true parameters, noise-free navigation record (the model itself), init truth and init align, and (b)
   without the dT/dt term (what a model calibrated on plateaus alone, where dT/dt = 0, misses);
2. true parameters, navigation record with the scenario's noise (x ``--nav-noise-scales``) over seeds;
3. calibrated parameters (the honest version), per seed: (a) ``systematic51`` on an ``s16`` record (the
   same IMU at 20 degC: a single-temperature calibration), (b) ``systematic51 --states 51,thermal`` on a
   ``thermal-cycle`` record (one run, the whole thermal model with its dT/dt term) and (c)
   ``thermal-plateaus --per-plateau systematic51`` on ``thermal-plateaus-s16`` (no dT/dt term), each
   calibration record with its noise x ``--cal-noise-scale``; navigation of a ``thermal-warmup`` record
   with the scenario's noise and of the noise-free one, init align;
4. the speed of the thermal compensation.

    .venv/bin/python bench/thermal_warmup_nav.py [--seeds 5] [--nav-noise-scales 1,0.1,0.03]
                                                 [--cal-noise-scale 1] [--skip-calibrated] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from dataclasses import replace

import numpy as np

from inscal import nav as nv
from inscal.calibrate import calibrate
from inscal.core.error_model import ImuNoise
from inscal.io.jsonfile import to_jsonable
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def max_error(d, sc, params, thermal=None, init="align") -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r = nv.navigate(nv.chunks_of(d), sc.rate_hz, sc.site, init=init, scenario=sc, params=params, thermal=thermal,
                        temperature=d.temperature if thermal is not None else None)
    return float(r.summary["max_position_error_m"])


def scaled(noise: ImuNoise, k: float) -> ImuNoise:
    return replace(noise, arw=noise.arw * k, vrw=noise.vrw * k)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python bench/thermal_warmup_nav.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--nav-noise-scales", default="1,0.1,0.03", help="factors on the navigation record's ARW/VRW")
    ap.add_argument("--cal-noise-scale", type=float, default=1.0, help="factor on the calibration record's ARW/VRW")
    ap.add_argument("--skip-calibrated", action="store_true")
    ap.add_argument("--json", help="also write the figures to this JSON file")
    a = ap.parse_args(argv)
    out: dict = {}
    warm = scenarios.build("thermal-warmup")
    quiet = replace(warm, noise=ImuNoise())
    d0 = simulate(quiet)
    model = warm.thermal
    no_rate = model.replace(gyro_bias_rate=np.zeros(3))

    print(f"thermal-warmup: {warm.path.duration / 3600:g} h, 20 -> 45 degC; max horizontal position error [m]")
    print("\n1. true parameters, noise-free record")
    print(f"{'init':6s} {'(a) 20 degC only':>17s} {'(b) + thermal':>14s} {'ratio':>10s} {'(b) without dT/dt':>18s}")
    out["true_noise_free"] = {}
    for init in ("truth", "align"):
        ea, eb, ec = (max_error(d0, quiet, warm.imu, th, init) for th in (None, model, no_rate))
        out["true_noise_free"][init] = {"a": ea, "b": eb, "b_without_rate_term": ec}
        print(f"{init:6s} {ea:17.1f} {eb:14.3f} {ea / eb:10.0f} {ec:18.1f}")

    print("\n2. true parameters, record with the scenario's noise (the s16 IMU's) x scale, init align")
    print(f"{'scale':>6s} {'seed':>4s} {'(a)':>9s} {'(b)':>9s} {'ratio':>6s}")
    out["true_noisy"] = []
    for k in (float(x) for x in a.nav_noise_scales.split(",")):
        ratios = []
        for seed in range(1, a.seeds + 1):
            sc = replace(warm, noise=scaled(warm.noise, k))
            d = simulate(sc, np.random.default_rng(seed))
            ea, eb = max_error(d, sc, sc.imu), max_error(d, sc, sc.imu, model)
            ratios.append(ea / eb)
            out["true_noisy"].append({"scale": k, "seed": seed, "a": ea, "b": eb})
            print(f"{k:6g} {seed:4d} {ea:9.1f} {eb:9.1f} {ea / eb:6.2f}")
        print(f"{k:6g}  min ratio {min(ratios):.2f}, median {float(np.median(ratios)):.2f}")

    if not a.skip_calibrated:
        print(f"\n3. calibrated parameters (calibration noise x {a.cal_noise_scale:g}), navigation record with the "
              "scenario's noise (seed 2000 + s) and noise-free, init align")
        print("   (a) single temperature: systematic51 on an s16 record (20 degC throughout)")
        print("   (b) one run: systematic51 --states 51,thermal on a thermal-cycle record (-40 -> 60 -> -40 degC)")
        print("   (c) plateaus: thermal-plateaus --per-plateau systematic51 on thermal-plateaus-s16 (no dT/dt term)")
        print(f"{'seed':>4s} {'(a) noisy':>10s} {'(b) noisy':>10s} {'a/b':>6s} {'(c) noisy':>10s}   "
              f"{'(a) quiet':>10s} {'(b) quiet':>10s} {'a/b':>6s} {'(c) quiet':>10s}")
        single, cycle = scenarios.build("s16"), scenarios.build("thermal-cycle")
        plate = scenarios.build("thermal-plateaus-s16")
        single, cycle, plate = (replace(x, noise=scaled(x.noise, a.cal_noise_scale)) for x in (single, cycle, plate))
        out["calibrated"] = []
        ratios = []
        for seed in range(1, a.seeds + 1):
            t0 = time.perf_counter()
            one = calibrate(simulate(single, np.random.default_rng(1000 + seed)).to_record(), "systematic51")
            res = calibrate(simulate(cycle, np.random.default_rng(seed)).to_record(), "systematic51",
                            states="51,thermal")
            pl = calibrate(simulate(plate, np.random.default_rng(3000 + seed)).to_record(), "thermal-plateaus",
                           per_plateau="systematic51", orders={"accel_bias": 3})
            dn = simulate(warm, np.random.default_rng(2000 + seed))
            row = {"seed": seed}
            for tag, d, sc in (("noisy", dn, warm), ("quiet", d0, quiet)):
                row[f"a_{tag}"] = max_error(d, sc, one.imu)
                row[f"b_{tag}"] = max_error(d, sc, res.imu, res.thermal)
                row[f"c_{tag}"] = max_error(d, sc, pl.imu, pl.thermal)
            row["seconds"] = time.perf_counter() - t0
            out["calibrated"].append(row)
            ratios.append(row["a_noisy"] / row["b_noisy"])
            print(f"{seed:4d} {row['a_noisy']:10.1f} {row['b_noisy']:10.1f} {row['a_noisy'] / row['b_noisy']:6.1f} "
                  f"{row['c_noisy']:10.1f}   {row['a_quiet']:10.1f} {row['b_quiet']:10.1f} "
                  f"{row['a_quiet'] / row['b_quiet']:6.1f} {row['c_quiet']:10.1f}", flush=True)
        print(f"noisy navigation: ratio (a)/(b) min {min(ratios):.1f}, median {float(np.median(ratios)):.1f}")

    print("\n4. speed")
    comp = nv.ThermalCompensation(model, warm.imu, d0.temperature, warm.rate_hz)
    t0 = time.perf_counter()
    for c in nv.thermal_chunks(nv.chunks_of(d0), comp):
        pass
    dt_th = time.perf_counter() - t0
    t0 = time.perf_counter()
    max_error(d0, quiet, warm.imu, None, "truth")
    dt_nav = time.perf_counter() - t0
    n = d0.time.size
    out["speed"] = {"samples": n, "thermal_s": dt_th, "navigate_s": dt_nav}
    print(f"thermal compensation {n / dt_th / 1e6:.1f} M samples/s; navigation (truth init, with the error analysis) "
          f"{n / dt_nav / 1e6:.1f} M samples/s")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(to_jsonable(out), fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
