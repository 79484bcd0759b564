"""Study ``n25-fig5``: N25 Fig. 5, the calibration error against the gimbal non-orthogonality."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from inscal.analysis.montecarlo import Experiment, StudyError, Summary, std_ci
from inscal.analysis.studies.common import (
    check_common,
    scenario_key,
    simulate_record,
    warmup,
)
from inscal.analysis.truth import estimated_parameter_names
from inscal.calibrate import calibrate
from inscal.core import units

FIG5_DTHETA = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 40.0)


# ------------------------------------------------------------------------------ n25-fig5
def _fig5_run(exp: Experiment, p: int, rng: np.random.Generator) -> dict:

    dtheta = exp.points[p]["dtheta_arcsec"]
    rec = simulate_record(scenario_key(exp.params, dtheta), rng, exp.params["simulation"])
    res = calibrate(rec, exp.params["method"], uncertainty=exp.params["uncertainty"])
    if "gimbal_nonorthogonality" not in estimated_parameter_names(res):
        raise StudyError(f"method {exp.params['method']!r} does not estimate the gimbal non-orthogonality")
    out = {"dtheta_est_arcsec": float(units.from_si(res.gimbal.nonorthogonality, "arcsec"))}
    sig = getattr(res, "sigma", None)
    if isinstance(sig, dict) and "gimbal_nonorthogonality" in sig:
        out["sigma_arcsec"] = float(units.from_si(np.asarray(sig["gimbal_nonorthogonality"], float), "arcsec"))
    return out


def _fig5_summarize(exp: Experiment, results: list[list[dict]]) -> Summary:
    rows = []
    for pt, res in zip(exp.points, results):
        true = pt["dtheta_arcsec"]
        x = np.array([r["dtheta_est_arcsec"] for r in res if r.get("dtheta_est_arcsec") is not None], float)
        n = x.size
        std = float(np.std(x, ddof=1)) if n > 1 else math.nan
        lo, hi = std_ci(std, n)
        sig = [r["sigma_arcsec"] for r in res if r.get("sigma_arcsec") is not None]
        rows.append({
            "dtheta_arcsec": true, "n": n,
            "mean_arcsec": float(np.mean(x)) if n else math.nan,
            "bias_arcsec": float(np.mean(x) - true) if n else math.nan,
            "std_arcsec": std,
            "rsd_pct": 100 * std / abs(true) if true else math.nan,
            "rsd_ci95_lo_pct": 100 * lo / abs(true) if true else math.nan,
            "rsd_ci95_hi_pct": 100 * hi / abs(true) if true else math.nan,
            "sigma_formal_arcsec": float(np.mean(sig)) if sig else None,
        })
    thr, at = exp.params["rsd_threshold_pct"], exp.params["rsd_threshold_from_arcsec"]
    sel = [r for r in rows if r["dtheta_arcsec"] >= at and r["n"] > 1]
    ok = bool(sel) and all(r["rsd_pct"] < thr for r in sel)
    if sel:
        notes = [f"RSD < {thr:g} % for every dtheta >= {at:g} arcsec: {'yes' if ok else 'NO'}"
                 f" (largest {max(r['rsd_pct'] for r in sel):.2f} %)"]
    else:  # no spread from one run: no verdict either way
        notes = [f"RSD < {thr:g} % for every dtheta >= {at:g} arcsec: not known (an RSD needs at least 2 runs per "
                 "value)"]
        ok = None
    cols = [("dtheta_arcsec", "dθ true [″]"), ("n", "runs"), ("mean_arcsec", "mean [″]"), ("bias_arcsec", "bias [″]"),
            ("std_arcsec", "std [″]"), ("rsd_pct", "RSD [%]"), ("rsd_ci95_lo_pct", "RSD 95% lo"), ("rsd_ci95_hi_pct", "RSD 95% hi")]
    if any(r["sigma_formal_arcsec"] is not None for r in rows):
        cols.append(("sigma_formal_arcsec", "formal σ [″]"))
    return Summary(f"n25-fig5: relative std of the estimated gimbal non-orthogonality (method {exp.params['method']})",
                   cols, rows, notes, {"rsd_below_threshold": ok})


def _fig5_plot(exp: Experiment, s: Summary, path: Path) -> None:
    import matplotlib.pyplot as plt

    rows = [r for r in s.rows if r["n"] > 1]
    x = np.array([r["dtheta_arcsec"] for r in rows])
    rsd = np.array([r["rsd_pct"] for r in rows])
    lo = np.array([r["rsd_ci95_lo_pct"] for r in rows])
    hi = np.array([r["rsd_ci95_hi_pct"] for r in rows])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    if not rows:  # one run per value: no spread to draw (log axes of nothing cannot be drawn either)
        for ax in (a1, a2):
            ax.text(0.5, 0.5, "an RSD needs at least 2 runs per dθ value", ha="center", va="center",
                    transform=ax.transAxes)
            ax.set_axis_off()
        a1.set_title("N25 Fig. 5 (1 run per value)")
        fig.savefig(path, dpi=120)
        plt.close(fig)
        return
    a1.errorbar(x, rsd, yerr=[rsd - lo, hi - rsd], fmt="o-", capsize=3, label="Monte Carlo (95 % CI)")
    a1.axhline(exp.params["rsd_threshold_pct"], color="r", ls="--", lw=1, label=f"{exp.params['rsd_threshold_pct']:g} %")
    a1.axvline(exp.params["rsd_threshold_from_arcsec"], color="gray", ls=":", lw=1)
    a1.set_xscale("log")
    a1.set_yscale("log")
    a1.set_xlabel("true dθ [arcsec]")
    a1.set_ylabel("RSD of estimated dθ [%]")
    a1.set_title(f"N25 Fig. 5 ({rows[0]['n'] if rows else 0} runs per value)")
    a1.grid(True, which="both", alpha=0.3)
    a1.legend()
    std = np.array([r["std_arcsec"] for r in rows])
    bias = np.array([r["bias_arcsec"] for r in rows])
    a2.plot(x, std, "o-", label="std")
    sem = std / np.sqrt(np.array([r["n"] for r in rows]))
    a2.errorbar(x, bias, yerr=2 * sem, fmt="s--", capsize=3, label="bias (±2 s.e.)")
    a2.axhline(0, color="k", lw=0.5)
    a2.set_xscale("log")
    a2.set_xlabel("true dθ [arcsec]")
    a2.set_ylabel("estimation error [arcsec]")
    a2.grid(True, which="both", alpha=0.3)
    a2.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def n25_fig5(dtheta_arcsec=FIG5_DTHETA, method: str = "n25", arw_deg_rt_h: float = 0.02, vrw_ug_rt_hz: float = 20.0,
             dwell_s: float = 100.0, rate_hz: float = 100.0, simulation: str = "full", uncertainty: bool = False,
             rsd_threshold_pct: float = 10.0, rsd_threshold_from_arcsec: float = 7.0) -> Experiment:
    vals = dtheta_arcsec if isinstance(dtheta_arcsec, (list, tuple)) else [dtheta_arcsec]
    try:
        vals = [float(v) for v in vals]
    except (TypeError, ValueError):
        raise StudyError(f"dtheta_arcsec must be a number or a list of numbers, got {dtheta_arcsec!r}") from None
    if not vals or any(not math.isfinite(v) or v == 0 for v in vals):
        raise StudyError("dtheta_arcsec values must be finite and non-zero")
    if len(set(vals)) != len(vals):
        raise StudyError("dtheta_arcsec values must be distinct")
    if not isinstance(method, str):
        raise StudyError("method must be a string")
    if not isinstance(uncertainty, bool):
        raise StudyError(f"uncertainty must be true or false, got {uncertainty!r}")
    params = {"dtheta_arcsec": vals, "method": method, "uncertainty": uncertainty,
              **check_common({"arw_deg_rt_h": arw_deg_rt_h, "vrw_ug_rt_hz": vrw_ug_rt_hz, "dwell_s": dwell_s,
                               "rate_hz": rate_hz, "simulation": simulation}),
              "rsd_threshold_pct": float(rsd_threshold_pct), "rsd_threshold_from_arcsec": float(rsd_threshold_from_arcsec)}
    return Experiment("n25-fig5", params, tuple({"dtheta_arcsec": v} for v in vals), _fig5_run, _fig5_summarize,
                      _fig5_plot, warmup, version=1, description="N25 Fig. 5: RSD of the estimated dθ vs dθ")
