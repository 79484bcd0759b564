"""The budget a path promises before it runs (``inscal observability --crlb --station``) against the budget of a
calibration of that path (``calibrate --station``), and a path designed for the combined uncertainty against one
designed for the bound alone (``design --station``).

1. S16's path at the test station (tests/data/station.toml), ``systematic51`` on a noisy simulated record: per
   component the combined standard uncertainty and the site and clock contributions, before (the bound and its
   consider analysis) and after (the filter's own sigma and finite differences through it).
2. Two 30-minute designs, same seed and candidates: for the bound alone, and for the combined uncertainty at a
   station whose latitude is known to ``--lat-arcsec`` only (a map rather than a survey); each path's worst ratio of
   the combined uncertainty to S16's 1-h path's, at that station.

Run: ``.venv/bin/python bench/budget_before_run.py [--rate-hz 20] [--candidates 128]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal.calibrate import calibrate
from inscal.uncertainty.before_run import at_station, bound_budget, consider_u
from inscal.core import units
from inscal.core.turntable import s16_table1
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.station import read_station, station_from_dict
from inscal.plan import bound as B
from inscal.plan.design import design, make_objective
from inscal.plan.rows import BiasNoise
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

STATION = Path(__file__).resolve().parents[1] / "tests" / "data" / "station.toml"


def main() -> None:
    """Run both comparisons and print them."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate-hz", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--candidates", type=int, default=128)
    ap.add_argument("--lat-arcsec", type=float, default=30.0)
    args = ap.parse_args()
    st = read_station(STATION)
    sc = at_station(replace(scenarios.build("s16"), rate_hz=args.rate_hz), st)
    t0 = time.perf_counter()
    b = B.crlb(sc, "51", keep_history=False, consider=consider_u(st))
    before = bound_budget(b, st)
    t_before = time.perf_counter() - t0
    rec = simulate(sc, np.random.default_rng(args.seed)).to_record()
    t0 = time.perf_counter()
    r = calibrate(rec, "systematic51")
    after = S.calibration_budget(r, st, record=rec)
    t_after = time.perf_counter() - t0
    print(f"S16 path at {st.name!r}: before the run {t_before:.2f} s, after (calibration and its 8 difference runs, "
          f"{args.rate_hz:g} Hz) {t_after:.1f} s")
    print(f"  {'component':24s} {'u_c before':>11s} {'u_c after':>11s} {'ratio':>6s}   gravity / latitude / time base "
          "contribution, before | after")
    ratios = []
    for c0 in before.components:
        try:
            c1 = after.component(c0.label)
        except KeyError:
            continue
        ratios.append(c1.u_c / c0.u_c)
        lines0 = {x.input: x.contribution for x in c0.contributions}
        lines1 = {x.input: x.contribution for x in c1.contributions}
        print(f"  {c0.label:24s} {c0.u_c:11.4g} {c1.u_c:11.4g} {c1.u_c / c0.u_c:6.3f}   "
              + " ".join(f"{lines0[k]:.3g}" for k in ("gravity", "latitude", "time_base")) + " | "
              + " ".join(f"{lines1[k]:.3g}" for k in ("gravity", "latitude", "time_base")) + f" {c0.unit}")
    print(f"  u_c after / before: median {np.median(ratios):.3f}, range {min(ratios):.3f} .. {max(ratios):.3f}")

    doc = st.to_dict()
    doc["inputs"]["latitude"]["uncertainty"] = args.lat_arcsec
    doc["inputs"]["latitude"]["uncertainty_unit"] = "arcsec"
    poor = station_from_dict(doc)
    base = at_station(scenarios.build("s16"), poor)
    u = consider_u(poor)

    def setup(consider):
        return B.make_setup("51", base.site, base.gimbal, base.noise.arw, base.noise.vrw,
                            BiasNoise.from_imu_noise(base.noise), consider=consider)

    judge = make_objective(setup(u))
    print(f"\n30-min designs ({args.candidates} candidates, seed 0), judged by the worst combined uncertainty / S16's "
          f"1-h path's at a station with latitude u = {args.lat_arcsec:g} arcsec ({units.from_si(u['latitude'], 'arcsec'):.3g}):")
    for label, cons in (("for the bound alone", None), ("for the combined uncertainty", u)):
        t0 = time.perf_counter()
        res = design(30.0, candidates=args.candidates, setup=setup(cons), seed=0)
        bb = B.evaluate(setup(u), res.path, keep_history=False)
        worst = int(np.argmax(bb.combined_sigma / judge.targets))
        print(f"  {label:30s} combined objective {judge.value(bb.combined_sigma):.3f} (bound alone "
              f"{judge.value(bb.sigma):.3f}); worst {bb.labels[worst]}; {time.perf_counter() - t0:.1f} s")
    ref = B.evaluate(setup(u), s16_table1(), keep_history=False)
    print(f"  S16's own 1-h path: combined {judge.value(ref.combined_sigma):.3f}")


if __name__ == "__main__":
    main()
