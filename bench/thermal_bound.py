"""Can a continuous chamber ramp reach the plateau method's accuracy?  The Cramér-Rao bound of every thermal
coefficient (the systematic filter's posterior, :mod:`inscal.plan.bound` with ``--states 51,thermal``) on
temperature histories of the ``s16`` IMU and noise, against the accuracy the plateau method (a) reaches:

* ``thermal-ramp`` (built-in, 2.1 h): the S16 Table 1 path twice; -40 degC for 10 min, 1 degC/min to +60 degC, hold;
* ``ramp2-1x`` (1.07 h): the S16 path once; -40 degC for 7 min, 2 degC/min to +60 degC, hold;
* ``cycle2-2x`` (2.1 h): the S16 path twice; -40 degC for 5 min, 2 degC/min to +60 degC, 10 min, 2 degC/min back;
* ``thermal-cycle`` when the scenario exists (built-in);
* ``plateaus (a)`` (9.0 h of chamber): the 51-state bound of the S16 path at each of the five plateaus (-40 .. +60
  degC), then the generalised least-squares polynomial of each term (:func:`inscal.plan.thermal.plateau_sigma`;
  no dT/dt term: a plateau holds dT/dt = 0);
* ``plateaus 1-run``: ``thermal-plateaus-s16`` (9.0 h) as one record with the thermal states (the bound of the
  plateau experiment used whole, the chamber's ramps included).

Per coefficient group: the prior, the largest truth of the built-in model (illustrative), and the largest 1 sigma
over the three axes of each history.  ``--gm`` adds a Gauss-Markov bias instability to every bound (the plateau
method's per-plateau bound then has it too; its constant part is what a plateau's fit sees, to first order).

    .venv/bin/python bench/thermal_bound.py              # about 10 s after compilation
    .venv/bin/python bench/thermal_bound.py --gm 0.001,1,3600   # gyro deg/h, accel ug, tau s
    .venv/bin/python bench/thermal_bound.py --exact-rate # the profile's exact dT/dt instead of the 60-s slope
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from inscal.calibrate.systematic.states import THERMAL_ORDERS, field_value
from inscal.core import units
from inscal.core.thermal import RATE_WINDOW_S
from inscal.core.turntable import RotationPath, s16_table1
from inscal.plan.bound import crlb
from inscal.plan.rows import BiasNoise
from inscal.plan.thermal import plateau_base_sigma, plateau_sigma
from inscal.sim import scenarios
from inscal.sim.thermal import Piece, TemperatureProfile


def s16_path(times: int) -> RotationPath:
    one = s16_table1()
    return RotationPath(f"s16-table1-x{times}", one.moves * times, accel=one.accel, initial=one.initial,
                        initial_dwell=one.initial_dwell, closed=one.closed)


def variants() -> dict:
    base = scenarios.build("s16")
    model = scenarios.thermal_model()
    out = {"thermal-ramp": (scenarios.build("thermal-ramp"), 2.1)}
    p1 = s16_path(1)
    out["ramp2-1x"] = (replace(base, name="ramp2-1x", path=p1, thermal=model, temperature=TemperatureProfile(
        -40.0, (Piece("hold", duration_s=420.0), Piece("ramp", target_c=60.0, rate_c_per_min=2.0)))), p1.duration / 3600)
    p2 = s16_path(2)
    out["cycle2-2x"] = (replace(base, name="cycle2-2x", path=p2, thermal=model, temperature=TemperatureProfile(
        -40.0, (Piece("hold", duration_s=300.0), Piece("ramp", target_c=60.0, rate_c_per_min=2.0),
                Piece("hold", duration_s=600.0), Piece("ramp", target_c=-40.0, rate_c_per_min=2.0)))), p2.duration / 3600)
    if "thermal-cycle" in scenarios.BUILTIN:
        sc = scenarios.build("thermal-cycle")
        out["thermal-cycle"] = (sc, sc.path.duration / 3600)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gm", default="", help="Gauss-Markov bias instability: gyro deg/h, accel ug, tau s")
    ap.add_argument("--exact-rate", action="store_true", help="the profile's exact dT/dt (default: the 60-s slope)")
    a = ap.parse_args(argv)
    bias = BiasNoise()
    if a.gm:
        g, ac, tau = (float(x) for x in a.gm.split(","))
        bias = BiasNoise(gyro_gm=units.to_si(g, "deg/h"), gyro_tau=tau, accel_gm=units.to_si(ac, "ug"), accel_tau=tau)
    window = None if a.exact_rate else RATE_WINDOW_S
    cols, hours = {}, {}
    for name, (sc, h) in variants().items():
        cols[name], hours[name] = crlb(sc, "51,thermal", bias_noise=bias, rate_window_s=window), h
    plate = crlb("s16", "51", bias_noise=bias)
    pl = plateau_sigma(plateau_base_sigma(plate), scenarios.THERMAL_PLATEAUS_C, 20.0, THERMAL_ORDERS)
    one = crlb("thermal-plateaus-s16", "51,thermal", bias_noise=bias, rate_window_s=window)
    hours["plateaus (a)"] = hours["plateaus 1-run"] = one.duration_s / 3600
    ref = cols["thermal-ramp"]
    truth = scenarios.thermal_model()
    names = list(cols) + ["plateaus (a)", "plateaus 1-run"]
    print(f"s16 IMU (ARW 5e-5 deg/sqrt(h), VRW 1 ug/sqrt(Hz)); dT/dt {'exact' if a.exact_rate else 'the 60-s slope'}"
          + (f"; Gauss-Markov bias {a.gm}" if a.gm else "") + "; largest 1 sigma over x, y, z")
    print(f"{'coefficient':24s} {'unit':18s} {'prior':>9s} {'|truth|':>9s} " + " ".join(f"{n:>14s}" for n in names))
    print(f"{'chamber time [h]':24s} {'':18s} {'':>9s} {'':>9s} " + " ".join(f"{hours[n]:14.2f}" for n in names))
    groups = dict.fromkeys(ref.setup.groups[i] for i in range(ref.setup.n_params) if "_dT" in ref.setup.groups[i]
                           or ref.setup.groups[i] == "gyro_bias_rate")
    for g in groups:
        idx = [i for i, gg in enumerate(ref.setup.groups) if gg == g]
        unit = ref.setup.units_[idx[0]]
        prior = field_value(ref.prior[idx[0]], unit)
        term, k = (g, 1) if g == "gyro_bias_rate" else (g.rsplit("_dT", 1)[0], int(g.rsplit("_dT", 1)[1]))
        tv = np.asarray(getattr(truth, term), float)
        tv = tv[k - 1] if tv.ndim == 2 else tv
        row = []
        for n in names:
            if n == "plateaus (a)":
                row.append(field_value(float(np.max(pl[g])), unit) if g in pl else float("nan"))
                continue
            b = one if n == "plateaus 1-run" else cols[n]
            by = b.by_label()
            row.append(field_value(max(by[f"{g}[{ax}]"] for ax in "xyz"), unit))
        print(f"{g:24s} {unit:18s} {prior:9.3g} {field_value(float(np.max(np.abs(tv))), unit):9.3g} "
              + " ".join(f"{v:14.3g}" for v in row))
    print("plateaus (a): the base terms at each plateau from the 51-state bound of the S16 path "
          f"({plate.steps} s), then the polynomial fit; no dT/dt term")


if __name__ == "__main__":
    main()
