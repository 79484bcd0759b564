"""Study ``s16-table2``: S16 Table 2, the 51- and 30-state filters over many noise draws, with NEES."""

from __future__ import annotations

import functools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from inscal.analysis.montecarlo import Experiment, StudyError, Summary
from inscal.analysis.studies.common import (
    check_methods,
    check_passes,
    nees_band,
    rms_z_band,
    verdict,
    warmup_systematic,
)
from inscal.analysis.truth import is_record_method, systematic_statistics
from inscal.calibrate import calibrate
from inscal.calibrate.systematic.params import truth_in_frame
from inscal.calibrate.systematic.states import StateSet
from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.io.records import Record, Truth
from inscal.sim.scenarios import S16_TABLE2, build
from inscal.sim.simulate import simulate

#: expected mean |x| of a zero-mean normal x per unit sigma
_HALF_NORMAL_MEAN = math.sqrt(2.0 / math.pi)


@functools.lru_cache(maxsize=8)
def _s16_scenario(rate_hz: float):

    sc = build("s16")
    return sc if rate_hz == sc.rate_hz else replace(sc, rate_hz=rate_hz)


def s16_record(rate_hz: float, rng: np.random.Generator):
    """An :class:`inscal.io.Record` of the built-in ``s16`` scenario at ``rate_hz`` with noise from ``rng``."""

    sc = _s16_scenario(float(rate_hz))
    d = simulate(sc, rng)
    return Record(d.time, d.dtheta, d.dvel, d.gimbal, sc.rate_hz, sc.site, path=sc.path,
                  truth=Truth(sc.imu, sc.gimbal, sc.noise), scenario=sc.name)


def _table2_run(exp: Experiment, p: int, rng: np.random.Generator) -> dict:

    rec = s16_record(exp.params["rate_hz"], rng)
    sc = _s16_scenario(float(exp.params["rate_hz"]))
    return {m: systematic_statistics(calibrate(rec, m, max_passes=exp.params["max_passes"], accept_unconverged=True), sc.imu, sc.gimbal)
            for m in exp.params["methods"]}


def _group_of(key: str) -> str:
    return key.split(".")[0]


def _ordered_groups(keys) -> list[str]:
    order = {n: i for i, n in enumerate(PARAMETERS)}
    return sorted(dict.fromkeys(_group_of(k) for k in keys), key=lambda g: order.get(g, 99))


def _true_magnitude(exp: Experiment) -> dict[str, float]:
    """Mean |true value| per group in the filter's (gyro-defined) frame, field units: the error
    a method leaves when it does not estimate the group."""

    imu = truth_in_frame(_s16_scenario(float(exp.params["rate_hz"])).imu, StateSet.parse("51")).to_imu()
    out = {}
    for name, p in PARAMETERS.items():
        attr, unit = p.attribute, p.unit
        if p.group != "imu" or not hasattr(imu, attr):
            continue
        v = np.abs(np.ravel(units.from_si(np.asarray(getattr(imu, attr), float), unit)))
        if name == "accel_lever_arm":
            v = np.abs(np.diag(units.from_si(np.asarray(imu.accel_lever_arm, float), unit)))  # S16 form: diagonal
        if name == "gyro_misalignment":
            v = v[[2, 4, 5]]  # the gyro-defined frame fixes xy, xz, yz
        out[name] = float(np.mean(v)) if v.size else 0.0
    return out


def _table2_summarize(exp: Experiment, results: list[list[dict]]) -> Summary:

    methods = exp.params["methods"]
    res = results[0]
    R = len(res)
    lo_z, hi_z = exp.params["z_rms_band"]
    before = _true_magnitude(exp)
    groups = _ordered_groups(k for r in res for m in methods for k in r.get(m, {}).get("errors", {}))
    per_run: dict[str, dict[str, dict[str, np.ndarray]]] = {m: {} for m in methods}
    for m in methods:
        for g in groups:
            mae, crb = [], []
            for r in res:
                e = {k: v for k, v in r[m]["errors"].items() if _group_of(k) == g} if m in r else {}
                if not e:
                    continue
                sg = [r[m]["sigmas"][k] for k in e if k in r[m]["sigmas"]]
                mae.append(float(np.mean(np.abs(list(e.values())))))
                crb.append(_HALF_NORMAL_MEAN * float(np.mean(sg)) if sg else math.nan)
            per_run[m][g] = {"mae": np.array(mae), "crb": np.array(crb)}
    rows = []
    for g in groups:
        row = {"group": g, "unit": PARAMETERS[g].unit, "before": before.get(g), "s16_target": S16_TABLE2.get(g)}
        for m in methods:
            x = per_run[m][g]
            row[f"{m}_mae"] = float(np.median(x["mae"])) if x["mae"].size else None  # None: not estimated
            row[f"{m}_crb"] = float(np.median(x["crb"])) if x["crb"].size else None
            row[f"{m}_mae_max"] = float(np.max(x["mae"])) if x["mae"].size else None
        rows.append(row)
    checks, notes = [], []
    # S16 Table 2 targets
    m51 = next((m for m in methods if m == "systematic51"), None)
    for g, target in S16_TABLE2.items():
        row = next((r for r in rows if r["group"] == g), None)
        for m in methods:
            if row is None or row.get(f"{m}_mae") is None:
                if row is not None and m != m51:
                    notes.append(f"{g}: not estimated by {m} (left at {row['before']:.4g} {row['unit']} mean |error|)")
                continue
            v, c = row[f"{m}_mae"], row[f"{m}_crb"]
            reach = "reachable" if c <= target else "NOT reachable from this record"
            checks.append({"claim": f"{m}: median mean |error| of {g} <= S16 Table 2 {target:g} {row['unit']}",
                           "holds": bool(v <= target), "value": v, "target": target, "crb": c,
                           "detail": f"{v:.3g} vs {target:g} {row['unit']}; expected from sigma (CRB) {c:.3g}: "
                                     f"target {reach}; value/CRB {v / c:.3g}"})
    # NEES and per-parameter error/sigma
    nees, zstats = {}, {}
    for m in methods:
        runs_m = [r[m] for r in res if m in r]
        if not runs_m:
            continue
        dof = runs_m[0]["dof"]
        x = np.array([q["nees"] for q in runs_m])
        lo, hi = nees_band(len(x), dof)
        nees[m] = {"mean": float(np.mean(x)), "band95": [lo, hi], "dof": dof, "runs": len(x), "inside": bool(lo <= np.mean(x) <= hi),
                   "nis_mean": float(np.mean([q["nis_mean"] for q in runs_m])),
                   "converged": sum(q["converged"] for q in runs_m), "passes_mean": float(np.mean([q["passes"] for q in runs_m]))}
        keys = list(dict.fromkeys(k for q in runs_m for k in q["errors"]))
        comp = []
        for k in keys:
            e = np.array([q["errors"][k] for q in runs_m if k in q["errors"] and k in q["sigmas"]])
            sg = np.array([q["sigmas"][k] for q in runs_m if k in q["errors"] and k in q["sigmas"]])
            zz = e / sg
            comp.append({"parameter": k, "unit": PARAMETERS[_group_of(k)].unit, "n": int(e.size),
                         "bias": float(np.mean(e)), "std": float(np.std(e, ddof=1)) if e.size > 1 else None,
                         "rms_error": float(np.sqrt(np.mean(e * e))), "mean_sigma": float(np.mean(sg)),
                         "mean_z": float(np.mean(zz)), "rms_z": float(np.sqrt(np.mean(zz * zz)))})
        labels = StateSet.parse(runs_m[0]["states"]).labels()[9:]
        Z = np.array([q["z"] for q in runs_m])
        state_rms = np.sqrt(np.mean(Z * Z, axis=0))
        zstats[m] = {"components": comp, "state_labels": labels if len(labels) == dof else [f"x{i}" for i in range(dof)],
                     "state_rms_z": state_rms.tolist()}
    for m, n in nees.items():
        model_ok = m == "systematic51"
        notes.append(f"{m}: mean NEES {n['mean']:.4g} (dof {n['dof']}), 95 % band of the mean of {n['runs']} runs "
                     f"[{n['band95'][0]:.4g}, {n['band95'][1]:.4g}]: {'inside' if n['inside'] else 'OUTSIDE'}"
                     + ("" if model_ok else " (the 30-state model omits errors present in the s16 truth: not expected "
                                           "to be chi-square)")
                     + f"; NIS mean {n['nis_mean']:.4g} (6 expected); converged {n['converged']}/{n['runs']}, "
                     f"{n['passes_mean']:.2g} passes")
        if model_ok:
            checks.append({"claim": f"{m}: mean NEES inside its 95 % chi-square band", "holds": n["inside"],
                           "detail": f"{n['mean']:.4g} in [{n['band95'][0]:.4g}, {n['band95'][1]:.4g}]"})
            comp = zstats[m]["components"]
            out = [c for c in comp if not lo_z <= c["rms_z"] <= hi_z]
            zlo, zhi = rms_z_band(R) if R > 1 else (math.nan, math.nan)
            chance = [c for c in comp if not zlo <= c["rms_z"] <= zhi] if R > 1 else []
            worst = sorted(comp, key=lambda c: -abs(math.log(c["rms_z"])))[:3]
            checks.append({"claim": f"{m}: RMS(error/sigma) within [{lo_z:g}, {hi_z:g}] for every parameter",
                           "holds": not out, "outside": [c["parameter"] for c in out],
                           "outside_sampling_band": [c["parameter"] for c in chance],
                           "detail": f"{len(out)} of {len(comp)} outside"
                                     + (": " + ", ".join(f"{c['parameter']} {c['rms_z']:.3f}" for c in out) if out else "")
                                     + "; worst " + ", ".join(f"{c['parameter']} {c['rms_z']:.3f}" for c in worst)
                                     + f"; the 95 % sampling band of one RMS over {R} runs is [{zlo:.3f}, {zhi:.3f}]: "
                                     f"{len(chance)} outside it, about {0.05 * len(comp):.1f} expected by chance"})
    notes = [f"{c['claim']}: {verdict(c['holds'])} ({c['detail']})" for c in checks] + notes
    notes.append(f"median over {R} runs of the mean |error| per group (estimate - truth in the filter's gyro-defined "
                 "frame; 'CRB' = sqrt(2/pi) x the mean reported sigma, the expected mean |error| of a consistent "
                 "filter); errors of groups a method does not estimate are absent")
    cols = [("group", "group"), ("unit", "unit"), ("before", "before |x|")]
    for m in methods:
        cols += [(f"{m}_mae", f"{m} mean|err|"), (f"{m}_crb", f"{m} CRB")]
    cols.append(("s16_target", "S16 Table 2"))
    return Summary(f"s16-table2: S16 §4.1 systematic calibration, {R} runs (rate {exp.params['rate_hz']:g} Hz, "
                   f"max {exp.params['max_passes']} passes)", cols, rows, notes,
                   {"checks": checks, "methods": methods, "nees": nees, "z": zstats, "targets": S16_TABLE2,
                    "mae_per_run": {m: {g: v["mae"].tolist() for g, v in per_run[m].items()} for m in methods}})


def _table2_plot(exp: Experiment, s: Summary, path: Path) -> None:
    import matplotlib.pyplot as plt

    methods = s.data["methods"]
    rows = s.rows
    ncol = 5
    nrow = max(1, math.ceil(len(rows) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 3.2 * nrow), squeeze=False)
    w = 0.8 / max(1, len(methods))
    for ax, r in zip(axes.flat, rows):
        for i, m in enumerate(methods):
            v = r.get(f"{m}_mae")
            x = (i - (len(methods) - 1) / 2) * w
            if v is None:
                ax.text(x, 0.5, "not\nestimated", transform=ax.get_xaxis_transform(), ha="center", fontsize=7, color=f"C{i}")
                continue
            ax.bar(x, v, w, color=f"C{i}", label=m)
            if r.get(f"{m}_crb") is not None:
                ax.plot([x - w / 2, x + w / 2], [r[f"{m}_crb"]] * 2, "k:", lw=1.2, label="CRB (sqrt(2/pi) σ)" if i == 0 else None)
        if r.get("s16_target") is not None:
            ax.axhline(r["s16_target"], color="r", ls="--", lw=1.2, label="S16 Table 2")
        if r.get("before"):
            ax.axhline(r["before"], color="gray", ls="-.", lw=1, label="before (|truth|)")
        ax.set_yscale("log")
        ax.set_xlim(-0.5, 0.5)
        ax.set_xticks([])
        ax.set_title(f"{r['group']} [{r['unit']}]", fontsize=9)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    for ax in list(axes.flat)[len(rows):]:
        ax.axis("off")
    handles, labels = {}, {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(list(handles.values()), list(handles.keys()), loc="upper right", fontsize=8)
    fig.suptitle(s.title + ": median mean |error| per group", fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.88, 0.95))
    fig.savefig(path, dpi=110)




def s16_table2(methods=("systematic51", "systematic30"), rate_hz: float = 100.0, max_passes: int = 5,
               z_rms_band=(0.8, 1.2)) -> Experiment:
    ms = check_methods(methods)
    if not all(is_record_method(m) for m in ms):
        raise StudyError(f"s16-table2 compares the systematic methods only, got {ms}")
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not (math.isfinite(rate_hz) and rate_hz > 0):
        raise StudyError(f"rate_hz must be a positive number, got {rate_hz!r}")
    zb = list(z_rms_band) if isinstance(z_rms_band, (list, tuple)) else None
    if not zb or len(zb) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in zb) or not 0 < zb[0] < 1 < zb[1]:
        raise StudyError(f"z_rms_band must be [lo, hi] with 0 < lo < 1 < hi, got {z_rms_band!r}")
    params = {"methods": ms, "rate_hz": float(rate_hz), "max_passes": check_passes(max_passes),
              "z_rms_band": [float(v) for v in zb]}
    return Experiment("s16-table2", params, ({"scenario": "s16"},), _table2_run, _table2_summarize, _table2_plot,
                      warmup_systematic, version=1,
                      description="S16 Table 2: systematic calibration accuracy (51 vs 30 states), NEES and error/sigma")
