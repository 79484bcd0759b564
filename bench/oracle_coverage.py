"""Monte Carlo coverage of the systematic filter's sigma on the independent oracle's noisy 19-position records.

The records of ``bench/oracle_misfit.py``'s ``noisy`` kind (tests/oracles/reference_imu.py, PSINS conventions, a
navigation-grade unit with 0.002 deg/sqrt(h) and 5 ug/sqrt(Hz), float32, the lever-arm timing misfit of the PSINS
asynchrony form), one per seed: truth and noise both drawn from the seed.  Per state request and group, over every
seed and component: the RMS of error/sigma (1 when the sigma are right), the largest |error/sigma| with its seed,
the share beyond 2 and 3 (4.6 % and 0.27 % for a normal), and the probability that the largest of that many normal
draws reaches the largest seen (``1 - (1 - 2 Phi(-z_max))^n``).  Usage: ``python bench/oracle_coverage.py
[--seeds 1-20] [--states "51,async,lever9;51,lever9,async,levtime,psins"] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))

from oracle_misfit import record  # noqa: E402

from adapter import to_inscal_truth, to_record  # noqa: E402

from inscal.calibrate.systematic import systematic51  # noqa: E402
from inscal.core.error_model import GimbalErrors  # noqa: E402


def seeds_of(text: str) -> list[int]:
    """``"1-20"`` or ``"1,3,5"``."""
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def normalised(res, truth) -> dict:
    """Per group: the error/sigma of every estimated component."""
    out = {}
    for name, e in res.to_field((truth, GimbalErrors())).items():
        err, sig = np.ravel(np.asarray(e["error"], float)), np.ravel(np.asarray(e["sigma"], float))
        ok = np.isfinite(sig) & (sig > 0)
        out[name] = (err[ok] / sig[ok]).tolist()
    return out


def summary(zs: dict, seeds: list[int]) -> dict:
    """Per group, the coverage figures of the module docstring (``zs``: group -> per-seed lists)."""
    out = {}
    for name, per_seed in zs.items():
        z = np.concatenate([np.asarray(v, float) for v in per_seed])
        if not z.size:
            continue
        k = int(np.argmax(np.abs(z)))
        width = len(per_seed[0])
        zmax = float(abs(z[k]))
        tail = math.erfc(zmax / math.sqrt(2.0))  # two-sided P(|N(0,1)| > zmax)
        out[name] = {"n": int(z.size), "rms": float(np.sqrt(np.mean(z ** 2))), "max": zmax,
                     "max_seed": seeds[k // max(width, 1)], "beyond_2": float(np.mean(np.abs(z) > 2.0)),
                     "beyond_3": float(np.mean(np.abs(z) > 3.0)),
                     "p_max": float(-math.expm1(z.size * math.log1p(-tail)))}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1-20")
    ap.add_argument("--states", default="51,async,lever9")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    seeds = seeds_of(a.seeds)
    specs = [s for s in a.states.split(";") if s]
    zs = {s: {} for s in specs}
    t0 = time.perf_counter()
    for seed in seeds:
        gen = record("noisy", seed)
        truth, rec = to_inscal_truth(gen), to_record(gen)
        for spec in specs:
            res = systematic51(rec, states=spec)
            for name, z in normalised(res, truth).items():
                zs[spec].setdefault(name, []).append(z)
            lev = np.abs(zs[spec]["accel_lever_arm"][-1])
            print(f"seed {seed:3d} {spec:32s} -> {res.diagnostics.get('state_options')}: lever arms max z "
                  f"{np.max(lev):.2f}, all groups max z {max(np.max(np.abs(v[-1]), initial=0.0) for v in zs[spec].values()):.2f}  "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
    out = {spec: summary(zs[spec], seeds) for spec in specs}
    for spec, groups in out.items():
        print(f"== {spec}: {len(seeds)} seeds")
        for name, g in groups.items():
            print(f"   {name:24s} n {g['n']:4d}  RMS z {g['rms']:.3f}  max {g['max']:.2f} (seed {g['max_seed']}, "
                  f"P(max >= it) {g['p_max']:.3g})  |z|>2 {100 * g['beyond_2']:.1f} %  |z|>3 {100 * g['beyond_3']:.2f} %")
    if a.json:
        Path(a.json).write_text(json.dumps({"seeds": seeds, "summary": out, "z": zs}, indent=1))


if __name__ == "__main__":
    main()
