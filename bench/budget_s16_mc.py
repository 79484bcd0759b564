"""A reduced JCGM 101 Monte Carlo of the S16 (systematic filter) budget: the station's errors put into the
simulator's truth, the record calibrated with what the station states.

Usage::

    .venv/bin/python bench/budget_s16_mc.py [--runs 200] [--rate-hz 20] [--out /tmp/budget-s16-mc]

Every run draws, from the station file's distributions: the site's gravity and latitude (the simulator's
site; the filter is given the stated ones), the time base (the record simulated at ``rate / (1 + eps)``
and labelled ``rate``), an angle error of every stop of the table on the axis that moved to it (table
angle plus encoder rounding: the path's turns moved so that each stop lands off by its own error), and
the record's noise (its own seeded generator); then ``systematic30`` (states 30) calibrates it.  The
linear budget (:func:`inscal.uncertainty.sensitivity.calibration_budget`) of one such record gives u_c and U.
Per component: the Monte Carlo standard deviation of the errors against u_c, and the coverage of
``estimate +- U``.  One filter run costs ~2.7 s at 20 Hz, so 1000 runs (~45 min of one core) are out of
reach on a shared two-core machine; ``--runs`` says how many were done (the ratio's own 1-sigma
precision is ``1 / sqrt(2 runs)``, the coverage's ``sqrt(0.95 * 0.05 / runs)``).  Wobble is not drawn:
the simulator has no tilt of the table top (the filter reads no table attitude; see bench/budget_s16.py).
"""

from __future__ import annotations

import argparse
import functools
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal.analysis.montecarlo import Experiment, Summary, run_study
from inscal.analysis.montecarlo import summarize as mc_summarize
from inscal.calibrate import calibrate
from inscal.core import units
from inscal.core.earth import Site
from inscal.core.error_model import PARAMETERS, ImuErrors
from inscal.core.turntable import AXES
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.station import read_station
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

STATION = Path(__file__).resolve().parents[1] / "tests" / "data" / "station.toml"
NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias")


@functools.lru_cache(maxsize=2)
def nominal(rate_hz: float):
    """The s16 scenario as the station states it (site gravity = the station's value; the IMU's errors
    those the 30-state filter estimates, so that its estimate has no model error) and the station."""
    st = read_station(STATION)
    sc = scenarios.build("s16", rate_hz=rate_hz)
    imu = ImuErrors(**{PARAMETERS[n].attribute: getattr(sc.imu, PARAMETERS[n].attribute) for n in NAMES})  # the 30 states' terms
    return replace(sc, imu=imu, site=sc.site.with_gravity(st["gravity"].value)), st


def moved_path(path, errors: np.ndarray):
    """``path`` whose k-th turn lands ``errors[k]`` [rad] off (on its own axis): turn k is lengthened by
    ``e_k - e_prev`` where ``e_prev`` is the error left on that axis by its previous turn."""
    last = {a: 0.0 for a in AXES}
    moves = []
    for m, e in zip(path.moves, errors):
        if m.axis == "none":
            moves.append(m)
            continue
        moves.append(replace(m, angle=m.angle + e - last[m.axis]))
        last[m.axis] = e
    return replace(path, moves=tuple(moves), closed=False)


def one_run(exp: Experiment, point: int, rng: np.random.Generator) -> dict:
    """One run: the flat estimate minus the truth (NaN where the filter holds a component fixed)."""
    p = exp.params
    sc, st = nominal(p["rate_hz"])
    site = sc.site
    dg, dlat, eps = (float(st[k].draw(rng)) for k in ("gravity", "latitude", "time_base"))
    n = len(sc.path.moves)
    e = st["table_angle"].draw(rng, n) + st["encoder_resolution"].draw(rng, n)
    true_site = Site(site.latitude + dlat, site.longitude, site.height).with_gravity(site.gravity + dg)
    truth = replace(sc, site=true_site, path=moved_path(sc.path, e), rate_hz=p["rate_hz"] / (1.0 + eps))
    rec = simulate(truth, rng).to_record()
    rec = replace(rec, site=site, rate_hz=p["rate_hz"], time=np.asarray(rec.time) * (1.0 + eps))
    r = calibrate(rec, "systematic30", states="30", arw=np.array(p["arw"]), vrw=np.array(p["vrw"]))
    err = np.concatenate([np.ravel(r.error((sc.imu, sc.gimbal), n_)) for n_ in NAMES])
    sig = np.concatenate([np.ravel(r.sigma[n_]) for n_ in NAMES])
    return {"error": np.where(np.isfinite(sig), err, np.nan).tolist()}


def summarize(exp: Experiment, results: list[list[dict]]) -> Summary:
    """Per component: u_c, MC sigma, their ratio, the coverage of +-U."""
    err = np.array([r["error"] for r in results[0]], float)
    rows = []
    for k, lab in enumerate(exp.params["labels"]):
        i, uc, U, f = exp.params["index"][k], exp.params["u_c_si"][k], exp.params["U_si"][k], exp.params["field"][k]
        e = err[:, i]
        sd = float(np.std(e, ddof=1))
        cov = float(np.mean(np.abs(e) <= U))
        rows.append({"component": lab, "u_c": uc / f, "mc_sigma": sd / f, "ratio": sd / uc, "mc_mean": float(e.mean()) / f,
                     "coverage": cov, "ok": bool(abs(sd / uc - 1) <= 0.10 and 0.93 <= cov <= 0.97)})
    return Summary("S16 budget: linear GUM vs Monte Carlo", [("component", "component")], rows, [f"{len(err)} runs"])


def main() -> None:
    """Run the study and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--rate-hz", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--out", default="/tmp/budget-s16-mc")
    args = ap.parse_args()
    sc, st = nominal(args.rate_hz)
    rec = simulate(sc, np.random.default_rng(99)).to_record()
    t0 = time.perf_counter()
    r = calibrate(rec, "systematic30", states="30")
    t_run = time.perf_counter() - t0
    arw = units.to_si(r.diagnostics["noise"]["arw_deg_sqrt_h"], "deg/sqrt(h)")
    vrw = units.to_si(r.diagnostics["noise"]["vrw_ug_sqrt_hz"], "ug/sqrt(Hz)")
    t0 = time.perf_counter()
    b = S.calibration_budget(r, st, record=rec, states="30", arw=arw, vrw=vrw)
    t_budget = time.perf_counter() - t0
    flat = []
    for n_ in NAMES:
        flat += [(n_, j) for j in range(np.size(r.sigma[n_]))]
    index = [flat.index((c.parameter, c.index)) for c in b.components]
    field = [float(units.to_si(1.0, c.unit)) for c in b.components]
    params = {"rate_hz": args.rate_hz, "arw": np.asarray(arw).tolist(), "vrw": np.asarray(vrw).tolist(),
              "labels": [c.label for c in b.components], "index": index, "field": field,
              "u_c_si": [c.u_c * f for c, f in zip(b.components, field)],
              "U_si": [c.U * f for c, f in zip(b.components, field)]}
    exp = Experiment("budget-mc-s16", params, ({"path": "s16"},), one_run, summarize)
    t0 = time.perf_counter()
    res = run_study(exp, args.out, args.runs, args.seed, scheduler="synchronous", force=True)
    t_mc = time.perf_counter() - t0
    s = mc_summarize(exp, res)
    print(f"one filter run {t_run:.1f} s, linear budget {t_budget:.1f} s, {args.runs} MC runs {t_mc:.0f} s")
    print(f"{'component':24s} {'u_c':>9s} {'MC sd':>9s} {'ratio':>6s} {'MC mean':>9s} {'cover':>6s}")
    for row in s.rows:
        print(f"{row['component']:24s} {row['u_c']:9.4g} {row['mc_sigma']:9.4g} {row['ratio']:6.3f} "
              f"{row['mc_mean']:9.3g} {row['coverage']:6.3f} {'ok' if row['ok'] else 'FAIL'}")
    print(f"{sum(r['ok'] for r in s.rows)}/{len(s.rows)} components pass; notes {s.notes}; failed {s.data['runs_failed']}")


if __name__ == "__main__":
    main()
