"""The systematic filter's robust scheme against small input changes (the sweep of the converging-filter work).

For each record (the independent oracle's PSINS-like 19-position record, noise-free float32; inscal's s16 and
psins19 scenarios, noise-free and noisy) and each cell (gravity +-0.03 ppm and +10 ppm, latitude +0.001 and
+0.01 deg, trims of 1 s and 10 s, filter rates 0.5/1/2 Hz, --states auto/full), one calibration with the defaults:
whether it converged (or the one-line refusal), the passes, the model-error factors, the largest error/sigma
(the accelerometer scale factor left out of the gravity cells, where a gravity error is one by definition) and the
largest deviation from the base cell in sigma.  Usage: ``python bench/robust_sweep.py [--records oracle,s16,...]
[--seed N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))

import reference_imu as R  # noqa: E402
from adapter import inscal_site, to_inscal_truth  # noqa: E402

from inscal.calibrate.systematic import systematic51  # noqa: E402
from inscal.calibrate.windows import CalibrationError  # noqa: E402
from inscal.core.earth import Site  # noqa: E402
from inscal.core.error_model import GimbalErrors, ImuNoise, parameter_components  # noqa: E402
from inscal.sim import scenarios  # noqa: E402
from inscal.sim.simulate import simulate  # noqa: E402

CELLS = ["base", "g+0.03ppm", "g-0.03ppm", "g+10ppm", "lat+0.001", "lat+0.01", "trim1", "trim10", "fr0.5", "fr2",
         "full"]


def records(names, seed):
    out = {}
    if "oracle" in names:
        gen = R.generate(R.psins19(), R.Site(34.0 * R.DEG, 108.0 * R.DEG, 380.0, "psins"),
                         R.psins_truth(np.random.default_rng(seed)), dtype="float32")
        out["oracle (noise-free, float32)"] = (SimpleNamespace(time=gen.time, dtheta=gen.dtheta, dvel=gen.dvel,
                                                               gimbal=None, rate_hz=gen.rate_hz,
                                                               site=inscal_site(gen), path=None),
                                               to_inscal_truth(gen))
    for name in ("s16", "psins19"):
        if name not in names:
            continue
        for noisy in (False, True):
            sc = scenarios.build(name)
            if not noisy:
                sc = dataclasses.replace(sc, noise=ImuNoise())
            d = simulate(sc, np.random.default_rng(seed))
            out[f"{name} ({'noisy' if noisy else 'noise-free'})"] = (
                SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=None, rate_hz=sc.rate_hz,
                                site=sc.site, path=None), sc.imu)
    return out


def cell(rec, name):
    site = rec.site
    kw = {}
    n = len(rec.time)
    if name.startswith("g"):
        site = site.with_gravity(site.gravity * (1 + float(name[1:-3]) * 1e-6))
    elif name.startswith("lat"):
        site = Site(site.latitude + math.radians(float(name[3:])), site.longitude, site.height, site.gravity_model)
    elif name.startswith("trim"):
        n -= int(round(float(name[4:]) * rec.rate_hz))
    elif name.startswith("fr"):
        kw["filter_rate_hz"] = float(name[2:])
    kw["states"] = "51,async,lever9" if name == "full" else "auto"
    r = SimpleNamespace(time=rec.time[:n], dtheta=rec.dtheta[:n], dvel=rec.dvel[:n], gimbal=None,
                        rate_hz=rec.rate_hz, site=site, path=None)
    return r, kw


def flat(res, truth):
    out = {}
    for n, e in res.to_field((truth, GimbalErrors())).items():
        for c, v, s, err in zip(parameter_components(n), np.ravel(e["value"]), np.ravel(e["sigma"]),
                                np.ravel(e["error"])):
            out[f"{n}[{c}]" if c else n] = (float(v), float(s), float(err))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--records", default="oracle,s16,psins19")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    for label, (rec, truth) in records(a.records.split(","), a.seed).items():
        print(f"== {label}")
        print(f"  {'cell':10s} {'result':10s} {'passes':>6s} {'moving x':>9s} {'chosen':34s} {'max err/sigma':>22s} "
              f"{'max |dev from base| / sigma':>28s} {'s':>5s}")
        base = None
        for c in CELLS:
            r, kw = cell(rec, c)
            t0 = time.perf_counter()
            try:
                res = systematic51(r, **kw)
            except CalibrationError as exc:
                print(f"  {c:10s} REFUSED    {str(exc)[:150]}")
                continue
            dt = time.perf_counter() - t0
            d = res.diagnostics
            f = flat(res, truth)
            skip = ("accel_scale_factor",) if c.startswith(("g", "lat")) else ()
            zs = [(abs(err / s), k) for k, (v, s, err) in f.items() if np.isfinite(s) and s > 0
                  and k.split("[")[0] not in skip]
            zmax, zk = max(zs)
            dev = ""
            if base is None and c == "base":
                base, base_frame = f, d["frame"]
            elif base is not None and d["frame"] != base_frame:  # other axes: the values do not compare
                dev = "(other frame)"
            elif base is not None:
                dd = [(abs(f[k][0] - base[k][0]) / math.hypot(f[k][1], base[k][1]), k) for k in f
                      if k in base and np.isfinite(f[k][1]) and np.isfinite(base[k][1]) and f[k][1] > 0
                      and k.split("[")[0] not in skip]
                if dd:
                    m, mk = max(dd)
                    dev = f"{m:.2f} ({mk})"
            chosen = d.get("selection", {}).get("chosen", d["state_options"])
            print(f"  {c:10s} {'converged' if d['converged'] else 'NOT conv.':10s} {len(d['passes']):6d} "
                  f"{d['model_error']['group_factor'].get('moving', 1.0):9.3g} {chosen:34s} "
                  f"{zmax:6.2f} {zk[:15]:>15s} {dev:>28s} {dt:5.1f}")


if __name__ == "__main__":
    main()
