"""The 2-h warm-up navigation (``thermal-warmup``: n25 IMU on a static base, 20 -> 45 degC, tau 20 min):
the maximum horizontal position error compensated (a) with the errors at 20 degC only (a calibration at
one temperature) and (b) with them and the thermal model at the record's temperature readings.

Four tables:

1. true parameters, noise-free navigation record (the model itself), init truth and init align, and (b)
   without the dT/dt term (what a model calibrated on plateaus alone, where dT/dt = 0, misses);
2. true parameters, navigation record with the scenario's noise (x ``--nav-noise-scales``) over seeds;
3. calibrated parameters (the honest version): ``calibrate(record, "thermal-plateaus", per_plateau="n25")`` on
   a ``thermal-plateaus`` record per seed (its noise x ``--cal-noise-scale``), navigation record
   noise-free, init align; also (a') an ``n25`` calibration at 20 degC (the ``n25`` scenario, no thermal
   errors) and (b') the calibrated model with the true dT/dt term added (separates the missing term from
   the calibration noise);
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

    print("\n2. true parameters, record with the n25 noise (ARW 0.02 deg/sqrt(h), VRW 20 ug/sqrt(Hz)) x scale, "
          "init align")
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
        print(f"\n3. calibrated parameters (thermal-plateaus, per plateau n25; calibration noise x {a.cal_noise_scale:g}), "
              "noise-free navigation record, init align")
        print(f"{'seed':>4s} {'(a) base':>9s} {'(a) n25@20':>10s} {'(b)':>9s} {'(b)+true D':>10s} {'ratio a/b':>9s} "
              f"{'a(n25)/b':>8s} {'a/(b+D)':>8s}")
        plate, n25 = scenarios.build("thermal-plateaus"), scenarios.build("n25")
        plate = replace(plate, noise=scaled(plate.noise, a.cal_noise_scale))
        n25 = replace(n25, noise=scaled(n25.noise, a.cal_noise_scale))
        out["calibrated"] = []
        for seed in range(1, a.seeds + 1):
            t0 = time.perf_counter()
            res = calibrate(simulate(plate, np.random.default_rng(seed)).to_record(), "thermal-plateaus",
                            per_plateau="n25")
            one = calibrate(simulate(n25, np.random.default_rng(1000 + seed)).to_record(), "n25")
            ea, e20 = max_error(d0, quiet, res.imu), max_error(d0, quiet, one.imu)
            eb = max_error(d0, quiet, res.imu, res.thermal)
            ed = max_error(d0, quiet, res.imu, res.thermal.replace(gyro_bias_rate=model.gyro_bias_rate))
            out["calibrated"].append({"seed": seed, "a": ea, "a_n25_at_20": e20, "b": eb, "b_true_rate_term": ed,
                                      "seconds": time.perf_counter() - t0})
            print(f"{seed:4d} {ea:9.1f} {e20:10.1f} {eb:9.1f} {ed:10.1f} {ea / eb:9.2f} {e20 / eb:8.2f} {ea / ed:8.2f}")

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
