"""The systematic filter on the independent oracle's record whose lever-arm timing misfits inscal's model.

The oracle (tests/oracles/reference_imu.py, no code shared with inscal.sim) writes a 19-position record in the PSINS
first-order asynchrony form ``f - tau w x f``: the lever-arm terms are not advanced with the rest of the specific
force, so every turn misfits inscal's delayed-accelerometer model by a few 1e-5 m/s.  Per record (noise-free
float32; noisy float32) and per state request, each group's largest |error|, largest sigma, largest error/sigma,
and the ratio of its sigma to the bound without the model-error term (the same states run with every model-error
factor at 1: the filter's posterior of a linear-Gaussian model is the Bayesian Cramer-Rao bound of the record at
the noise it assumes, :mod:`inscal.plan.bound`).  Usage: ``python bench/oracle_misfit.py [--states auto,...]
[--seed N] [--records free,noisy] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "oracles"))

import reference_imu as R  # noqa: E402
from adapter import to_inscal_truth, to_record  # noqa: E402

from inscal.calibrate.systematic import systematic51  # noqa: E402
from inscal.core import units  # noqa: E402
from inscal.core.error_model import GimbalErrors  # noqa: E402

SITE = R.Site(34.0 * R.DEG, 108.0 * R.DEG, 380.0, "psins")


def record(kind: str, seed: int):
    truth = R.psins_truth(np.random.default_rng(seed))
    if kind == "free":
        return R.generate(R.psins19(), SITE, truth, dtype="float32")
    return R.generate(R.psins19(), SITE, truth, arw=units.to_si(0.002, "deg/sqrt(h)"),
                      vrw=units.to_si(5.0, "ug/sqrt(Hz)"), rng=np.random.default_rng(seed + 100), dtype="float32")


def groups(res, truth) -> dict:
    out = {}
    for name, e in res.to_field((truth, GimbalErrors())).items():
        err = np.abs(np.asarray(e["error"], float))
        sig = np.asarray(e["sigma"], float)
        out[name] = {"unit": e["unit"], "err": float(np.nanmax(err)), "sigma": float(np.nanmax(sig)),
                     "z": float(np.nanmax(err / sig)), "sig_all": sig.tolist()}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--states", default="auto,51,async,lever9")
    ap.add_argument("--records", default="free,noisy")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--bound", action="store_true", help="also the run without the model-error term")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    specs = ["auto"] if a.states.startswith("auto") else []
    rest = a.states[5:] if a.states.startswith("auto") else a.states
    specs += [s for s in rest.split(";") if s]
    allres = {}
    for kind in a.records.split(","):
        gen = record(kind, a.seed)
        truth = to_inscal_truth(gen)
        rec = to_record(gen)
        for spec in specs:
            t0 = time.perf_counter()
            res = systematic51(rec, states=spec)
            dt = time.perf_counter() - t0
            d = res.diagnostics
            chosen = d.get("selection", {}).get("chosen", spec) if isinstance(d.get("selection"), dict) else spec
            g = groups(res, truth)
            row = {"states": chosen, "time_s": dt, "converged": d["converged"], "groups": g,
                   "model_error": d.get("model_error"), "fit": {k: d["fit"].get(k) for k in
                                                               ("consistent", "nis_ratio", "note") if k in d["fit"]}}
            if a.bound:
                b = systematic51(rec, states=chosen, robust=False, accept_unconverged=True)
                gb = groups(b, truth)
                scale = float(b.diagnostics["fit"].get("scale", 1.0))  # the bound is the formal posterior
                for k in g:
                    if k in gb:
                        g[k]["bound"] = gb[k]["sigma"] / scale
                        sb = np.asarray(gb[k]["sig_all"]) / scale
                        sa = np.asarray(g[k]["sig_all"])
                        g[k]["ratio"] = float(np.nanmax(sa / sb))
            row["lever_timing"] = d.get("lever_timing")
            allres[f"{kind}:{spec}"] = row
            print(f"== {kind} {spec} -> {chosen}  {dt:.0f} s  converged={d['converged']}  "
                  f"ME={ (d.get('model_error') or {}).get('group_factor')}  fit={row['fit']}")
            for k, v in g.items():
                extra = f"  bound {v['bound']:.3g} ratio {v['ratio']:.2f}" if "bound" in v else ""
                print(f"   {k:24s} err {v['err']:.3g} {v['unit']:7s} sigma {v['sigma']:.3g}  z {v['z']:.2f}{extra}")
            sys.stdout.flush()
    if a.json:
        Path(a.json).write_text(json.dumps(allres, indent=1, default=str))


if __name__ == "__main__":
    main()
