"""Built-in Monte Carlo experiments (N25 section 5).

``n25-fig5``
    N25 Figure 5: the relative standard deviation (std / true value) of the estimated
    gimbal non-orthogonality for dtheta in 1 ... 40 arcsec.  Scenario: the built-in ``n25``
    scenario (N25 site, mount attitude [0.1, 0.1, 20] deg, ARW 0.02 deg/sqrt(h),
    VRW 20 ug/sqrt(Hz), FOG-grade IMU errors :data:`inscal.scenarios.N25_ERRORS`, twelve
    positions of 100 s plus rate tests, 100 Hz) with its non-orthogonality set to each
    value.  Calibration method ``n25`` unless ``method`` says otherwise.
``n25-schemes``
    Bias and standard deviation of the error of every calibrated parameter, per scheme:
    scheme 1 = method ``n25`` (N25), scheme 2 = ``six-position`` (traditional, ignores
    non-orthogonality and leveling), ``joint`` (joint nonlinear least squares).  Every
    run simulates one record and calibrates it with every method (paired comparison:
    the schemes see the same noise, so their differences are measured more precisely).

Both draw all randomness from the generator a run is given: only the sensor noise is
random; the true errors are the scenario's.

Parameters (``inscal montecarlo EXPERIMENT --set KEY=VALUE``; ``--list`` shows defaults):
``arw_deg_rt_h``, ``vrw_ug_rt_hz`` (N25: 0.02, 20), ``dwell_s`` (100), ``rate_hz`` (100),
``simulation`` (below); ``n25-fig5``: ``dtheta_arcsec`` (list), ``method`` (``n25``),
``uncertainty`` (false: the formal 1-sigma of the calibration is not needed for the
empirical RSD and costs as much as the rest of a run; true adds a "formal σ" column);
``n25-schemes``: ``methods`` (list), ``dtheta_arcsec`` (20).

Simulation (parameter ``simulation``): ``"full"`` simulates every run with
:func:`inscal.simulate.simulate`.  ``"reuse"`` computes the noise-free part of the
record (the deterministic kinematics and sensor errors, which do not depend on the
seed) once per worker and configuration point, and adds the noise exactly as
``simulate`` does, from the same generator: the record is bit-for-bit the one ``simulate``
returns (tests/test_montecarlo.py checks ``array_equal``), only faster.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import units
from ..errors import PARAMETERS, GimbalErrors, ImuErrors, MISALIGN_NAMES, CROSS_NAMES
from .montecarlo import Experiment, Summary, StudyError, register_experiment, std_ci

FIG5_DTHETA = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 40.0)
SCHEME_LABELS = {"n25": "scheme 1 (n25)", "six-position": "scheme 2 (six-position)", "joint": "joint LSQ",
                 "twelve-position": "twelve-position"}
_SIMULATION_MODES = ("full", "reuse")
_COMMON_DEFAULTS = {"arw_deg_rt_h": 0.02, "vrw_ug_rt_hz": 20.0, "dwell_s": 100.0, "rate_hz": 100.0, "simulation": "full"}


# ----------------------------------------------------------------------------- scenario
def _check_common(p: dict) -> dict:
    out = {}
    for k in ("arw_deg_rt_h", "vrw_ug_rt_hz", "dwell_s", "rate_hz"):
        v = p[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise StudyError(f"{k} must be a non-negative number, got {v!r}")
        out[k] = float(v)
    if out["dwell_s"] <= 0 or out["rate_hz"] <= 0:
        raise StudyError("dwell_s and rate_hz must be positive")
    if p["simulation"] not in _SIMULATION_MODES:
        raise StudyError(f"simulation must be one of {_SIMULATION_MODES}, got {p['simulation']!r}")
    out["simulation"] = p["simulation"]
    return out


@functools.lru_cache(maxsize=64)
def _scenario_cached(key: str):
    from ..scenarios import build
    from ..turntable import n25_twelve

    p = json.loads(key)
    sc = build("n25")
    gim = sc.gimbal
    if p.get("dtheta_arcsec") is not None:
        gim = GimbalErrors(units.to_si(p["dtheta_arcsec"], "arcsec"), gim.mount_attitude)
    noise = replace(sc.noise, arw=units.to_si(p["arw_deg_rt_h"], "deg/sqrt(h)"), vrw=units.to_si(p["vrw_ug_rt_hz"], "ug/sqrt(Hz)"))
    path = sc.path if p["dwell_s"] == 100.0 else n25_twelve(dwell_s=p["dwell_s"])
    return replace(sc, gimbal=gim, noise=noise, path=path, rate_hz=p["rate_hz"])


def n25_scenario(params: dict, dtheta_arcsec: float | None = None):
    """The built-in ``n25`` scenario with the study's noise, dwell, rate and (if given)
    non-orthogonality."""
    return _scenario_cached(_scenario_key(params, dtheta_arcsec))


@functools.lru_cache(maxsize=12)
def _clean_record(key: str):
    """The noise-free measured record of a scenario (cached per worker process)."""
    from ..simulate import simulate

    sc = _scenario_cached(key)
    return simulate(replace(sc, noise=type(sc.noise)()), None)


def simulate_record(scenario_key: str, rng: np.random.Generator, mode: str):
    """An :class:`inscal.io.Record` of the scenario behind ``scenario_key`` with noise from ``rng``."""
    from ..io import Record, Truth
    from ..simulate import _NoiseState, simulate

    sc = _scenario_cached(scenario_key)
    if mode == "full":
        d = simulate(sc, rng)
        t, dth, dv, gim = d.time, d.dtheta, d.dvel, d.gimbal
    else:
        clean = _clean_record(scenario_key)
        t = clean.time
        state = _NoiseState(sc.noise, rng, 1.0 / sc.rate_hz)
        chunk = 1 << 19  # simulate()'s chunking: the noise state advances chunk by chunk
        parts = [state.apply(clean.dtheta[k:k + chunk], clean.dvel[k:k + chunk], clean.gimbal[k:k + chunk])
                 for k in range(0, t.shape[0], chunk)]
        dth, dv, gim = (np.concatenate([q[i] for q in parts]) for i in range(3))
    return Record(t, dth, dv, gim, sc.rate_hz, sc.site, path=sc.path, truth=Truth(sc.imu, sc.gimbal, sc.noise), scenario=sc.name)


def _scenario_key(params: dict, dtheta_arcsec: float | None) -> str:
    key = {k: params[k] for k in ("arw_deg_rt_h", "vrw_ug_rt_hz", "dwell_s", "rate_hz")}
    key["dtheta_arcsec"] = dtheta_arcsec
    return json.dumps(key, sort_keys=True)


def _warmup(exp: Experiment) -> None:
    """Compile (and cache on disk) the numba kernels with a short simulation."""
    from ..simulate import Scenario, simulate
    from ..turntable import Move, Path as TPath

    sc = n25_scenario(exp.params, 1.0)
    short = TPath("warmup", (Move("outer", 0.1, 0.5, 0.1),), accel=1.0, initial_dwell=0.1, closed=False)
    simulate(Scenario("warmup", short, sc.site, sc.imu, sc.gimbal, sc.noise, sc.rate_hz), np.random.default_rng(0))


# --------------------------------------------------------------------------- parameters
def parameter_components(name: str) -> list[str]:
    """Component labels of a registry parameter (``accel_bias`` -> x, y, z ...)."""
    shape = PARAMETERS[name][4]
    if shape == ():
        return [""]
    if name.endswith("misalignment"):
        return list(MISALIGN_NAMES)
    if name == "accel_cross_coupling":
        return list(CROSS_NAMES)
    if name == "mount_attitude":
        return ["alpha0", "beta0", "gamma0"]
    if shape == (3,):
        return ["x", "y", "z"]
    return [f"{a}{b}" for a in "xyz" for b in "xyz"]


def parameter_errors(imu: ImuErrors, gimbal: GimbalErrors | None, true_imu: ImuErrors, true_gimbal: GimbalErrors,
                     names) -> dict[str, float]:
    """``{"accel_bias.z": estimate - truth, ...}`` in field units for the registry
    parameters ``names``."""
    out = {}
    for name in names:
        obj, attr, kind, unit, shape = PARAMETERS[name]
        est_src, true_src = (imu, true_imu) if obj == "imu" else (gimbal, true_gimbal)
        if est_src is None:
            continue
        err = units.from_si(np.asarray(getattr(est_src, attr), float) - np.asarray(getattr(true_src, attr), float), unit)
        for comp, v in zip(parameter_components(name), np.ravel(err)):
            out[f"{name}.{comp}" if comp else name] = float(v)
    return out


def _estimated_names(result) -> list[str]:
    est = getattr(result, "estimated", None)
    names = [n for n in (est or PARAMETERS) if n in PARAMETERS]
    return names


# ------------------------------------------------------------------------------ n25-fig5
def _fig5_run(exp: Experiment, p: int, rng: np.random.Generator) -> dict:
    from ..calibrate import calibrate

    dtheta = exp.points[p]["dtheta_arcsec"]
    rec = simulate_record(_scenario_key(exp.params, dtheta), rng, exp.params["simulation"])
    res = calibrate(rec, exp.params["method"], uncertainty=exp.params["uncertainty"])
    if "gimbal_nonorthogonality" not in _estimated_names(res):
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
    notes = [f"RSD < {thr:g} % for every dtheta >= {at:g} arcsec: {'yes' if ok else 'NO'}"
             + (f" (largest {max(r['rsd_pct'] for r in sel):.2f} %)" if sel else "")]
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
              **_check_common({"arw_deg_rt_h": arw_deg_rt_h, "vrw_ug_rt_hz": vrw_ug_rt_hz, "dwell_s": dwell_s,
                               "rate_hz": rate_hz, "simulation": simulation}),
              "rsd_threshold_pct": float(rsd_threshold_pct), "rsd_threshold_from_arcsec": float(rsd_threshold_from_arcsec)}
    return Experiment("n25-fig5", params, tuple({"dtheta_arcsec": v} for v in vals), _fig5_run, _fig5_summarize,
                      _fig5_plot, _warmup, version=1, description="N25 Fig. 5: RSD of the estimated dθ vs dθ")


# ---------------------------------------------------------------------------- n25-schemes
def _schemes_run(exp: Experiment, p: int, rng: np.random.Generator) -> dict:
    from ..calibrate import calibrate, window_means

    key = _scenario_key(exp.params, exp.params["dtheta_arcsec"])
    sc = _scenario_cached(key)
    ws = window_means(simulate_record(key, rng, exp.params["simulation"]))  # segmented once, for every method
    out = {}
    for m in exp.params["methods"]:
        res = calibrate(ws, m, uncertainty=False)
        out[m] = parameter_errors(res.imu, res.gimbal, sc.imu, sc.gimbal, _estimated_names(res))
    return out


def _schemes_summarize(exp: Experiment, results: list[list[dict]]) -> Summary:
    methods = exp.params["methods"]
    res = results[0]
    keys: list[str] = []
    for r in res:
        for m in methods:
            keys += [k for k in r.get(m, {}) if k not in keys]
    order = {n: i for i, n in enumerate(PARAMETERS)}
    keys.sort(key=lambda k: (order.get(k.split(".")[0], 99), parameter_components(k.split(".")[0]).index(k.split(".")[1]) if "." in k else 0))
    rows = []
    for k in keys:
        name = k.split(".")[0]
        row = {"parameter": k, "unit": PARAMETERS[name][3]}
        for m in methods:
            x = np.array([r[m][k] for r in res if m in r and r[m].get(k) is not None], float)
            row[f"{m}_bias"] = float(np.mean(x)) if x.size else None
            row[f"{m}_std"] = float(np.std(x, ddof=1)) if x.size > 1 else None
            row[f"{m}_rms"] = float(np.sqrt(np.mean(x * x))) if x.size else None
        rows.append(row)
    cols = [("parameter", "parameter"), ("unit", "unit")]
    for m in methods:
        cols += [(f"{m}_bias", f"{m} bias"), (f"{m}_std", f"{m} std")]
    checks = _scheme_checks(rows, methods)
    notes = [f"{c['claim']}: {'yes' if c['holds'] else 'NO'} ({c['detail']})" for c in checks]
    notes.append("schemes: " + ", ".join(f"{m} = {SCHEME_LABELS.get(m, m)}" for m in methods)
                 + "; scheme 3 (system-level Kalman calibration) is not part of this study")
    return Summary(f"n25-schemes: calibration error (estimate - truth), {len(res)} runs, dθ = {exp.params['dtheta_arcsec']:g}″",
                   cols, rows, notes, {"checks": checks, "methods": methods})


def _group_rms(rows, m, pred) -> float | None:
    v = [r[f"{m}_rms"] for r in rows if pred(r["parameter"]) and r.get(f"{m}_rms") is not None]
    return float(np.sqrt(np.mean(np.square(v)))) if v else None


#: joint counts as "at least as accurate" as n25 when its group RMS error is at most this
#: factor times n25's (the Monte Carlo uncertainty of an RMS from 200 paired runs is a few %)
JOINT_TOLERANCE = 1.05

_CLAIM_GROUPS = {
    "z-accelerometer bias": lambda k: k == "accel_bias.z",
    "accelerometer scale factors": lambda k: k.startswith("accel_scale_factor."),
    "accelerometer installation angles": lambda k: k.startswith("accel_misalignment."),
    "gyro installation angles": lambda k: k.startswith("gyro_misalignment."),
}


def _scheme_checks(rows, methods) -> list[dict]:
    """The N25 claims (group RMS error, scheme 1 < scheme 2) and joint <= n25 for every
    parameter group (RMS over the group's components; groups have one unit each)."""
    checks = []
    if "n25" in methods and "six-position" in methods:
        for g, pred in _CLAIM_GROUPS.items():
            ra, rb = _group_rms(rows, "n25", pred), _group_rms(rows, "six-position", pred)
            if ra is not None and rb is not None:
                checks.append({"claim": f"n25 < six-position for {g}", "holds": bool(ra < rb),
                               "detail": f"RMS {ra:.4g} vs {rb:.4g}", "n25": ra, "six-position": rb})
    if "joint" in methods and "n25" in methods:
        worse, ratios = [], {}
        for g in dict.fromkeys(r["parameter"].split(".")[0] for r in rows):
            pred = lambda k, g=g: k.split(".")[0] == g  # noqa: E731
            ra, rb = _group_rms(rows, "joint", pred), _group_rms(rows, "n25", pred)
            if ra is None or rb is None or rb == 0:
                continue
            ratios[g] = ra / rb
            if ra > rb * JOINT_TOLERANCE:
                worse.append(f"{g} x{ra / rb:.3f}")
        checks.append({"claim": f"joint <= n25 (within {100 * (JOINT_TOLERANCE - 1):.0f} %) for every parameter group",
                       "holds": not worse and bool(ratios),
                       "detail": ("worse: " + ", ".join(worse)) if worse else
                                 "RMS ratio joint/n25 per group: " + ", ".join(f"{g} {v:.3f}" for g, v in ratios.items()),
                       "ratios": ratios})
    return checks


def _schemes_plot(exp: Experiment, s: Summary, path: Path) -> None:
    import matplotlib.pyplot as plt

    methods = s.data["methods"]
    groups: dict[str, list[dict]] = {}
    for r in s.rows:
        groups.setdefault(r["parameter"].split(".")[0], []).append(r)
    n = len(groups)
    ncol = 3
    nrow = max(1, math.ceil(n / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(5 * ncol, 3.2 * nrow), squeeze=False)
    w = 0.8 / max(1, len(methods))
    for ax, (g, rows) in zip(axes.flat, groups.items()):
        x = np.arange(len(rows))
        for i, m in enumerate(methods):
            y = [r.get(f"{m}_rms") or np.nan for r in rows]  # not estimated: no bar
            ax.bar(x + (i - (len(methods) - 1) / 2) * w, y, w, label=SCHEME_LABELS.get(m, m), color=f"C{i}")
        ax.set_xticks(x, [r["parameter"].split(".", 1)[1] if "." in r["parameter"] else g for r in rows])
        ax.set_title(f"{g} [{rows[0]['unit']}]")
        ax.set_ylabel("RMS error")
        ax.set_yscale("log")
        vals = [r.get(f"{m}_rms") for r in rows for m in methods if r.get(f"{m}_rms")]
        if vals:  # a common floor well below the smallest bar, so bar heights compare
            ax.set_ylim(bottom=min(vals) / 4)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", fontsize=9)
    fig.suptitle(s.title)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    fig.savefig(path, dpi=110)


def n25_schemes(methods=("n25", "six-position", "joint"), dtheta_arcsec: float = 20.0, arw_deg_rt_h: float = 0.02,
                vrw_ug_rt_hz: float = 20.0, dwell_s: float = 100.0, rate_hz: float = 100.0,
                simulation: str = "full") -> Experiment:
    ms = [methods] if isinstance(methods, str) else list(methods)
    if not ms or not all(isinstance(m, str) for m in ms) or len(set(ms)) != len(ms):
        raise StudyError(f"methods must be a list of distinct method names, got {methods!r}")
    if isinstance(dtheta_arcsec, bool) or not isinstance(dtheta_arcsec, (int, float)) or not math.isfinite(dtheta_arcsec):
        raise StudyError(f"dtheta_arcsec must be a number, got {dtheta_arcsec!r}")
    params = {"methods": ms, "dtheta_arcsec": float(dtheta_arcsec),
              **_check_common({"arw_deg_rt_h": arw_deg_rt_h, "vrw_ug_rt_hz": vrw_ug_rt_hz, "dwell_s": dwell_s,
                               "rate_hz": rate_hz, "simulation": simulation})}
    return Experiment("n25-schemes", params, ({"scenario": "n25", "dtheta_arcsec": float(dtheta_arcsec)},), _schemes_run,
                      _schemes_summarize, _schemes_plot, _warmup, version=1,
                      description="N25 §5: error bias/std of every parameter for each calibration scheme")


register_experiment("n25-fig5", n25_fig5, "N25 Fig. 5: relative std of the estimated gimbal non-orthogonality vs dθ")
register_experiment("n25-schemes", n25_schemes, "N25 §5: bias and std of every calibrated parameter per scheme")
