"""Built-in Monte Carlo experiments (N25 section 5, S16 section 4).

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
    non-orthogonality and leveling), scheme 3 = ``systematic30`` (N25: "system-level Kalman
    calibration plus discrete calibration of the gimbal rotation matrices"; the N25 IMU has
    linear errors only, so the 30-state S16 filter is the natural system-level method,
    ``systematic51`` may be named instead), ``joint`` (joint nonlinear least squares).  Every
    run simulates one record and calibrates it with every method (paired comparison:
    the schemes see the same noise, so their differences are measured more precisely).
    Scheme 3 reads the increments (no segmentation) and estimates the IMU in its own
    gyro-defined frame: its errors are taken against the truth mapped into that frame
    (``res.truth_transform``; N25 maps scheme 3's estimates into the turntable frame with
    the known rotations instead, the same to first order), the 3 gyro angles that define
    the frame are not estimates and are left out, and the gimbal parameters, which it does
    not estimate, are absent (never zero errors).  See :func:`result_errors`.
``s16-table2``
    S16 section 4.1 / Table 2: per run the built-in ``s16`` scenario is simulated with the
    run's generator and calibrated with ``systematic51`` and ``systematic30``; recorded per
    method are the error and 1 sigma of every estimated component (field units, truth in the
    filter's frame) and the NEES of the parameter error state (e from
    :meth:`~inscal.calibrate.systematic.CompParams.error_state`, P = ``res.covariance["P"]``,
    dof = len(e)).  Summary: per group the median over runs of the mean |error| against the
    S16 Table 2 figures (:data:`S16_TABLE2`) and against its expectation from the reported
    sigma (sqrt(2/pi) x mean sigma: a target below it is not reachable from this record),
    51 vs 30 for every group, the mean NEES against its 95 % chi-square band
    (:func:`nees_band`), and per parameter the RMS of error/sigma (should lie in
    ``z_rms_band``, default [0.8, 1.2]; :func:`rms_z_band` gives its sampling band).

All draw all randomness from the generator a run is given: only the sensor noise is
random; the true errors are the scenario's.

Parameters (``inscal montecarlo EXPERIMENT --set KEY=VALUE``; ``--list`` shows defaults):
``arw_deg_rt_h``, ``vrw_ug_rt_hz`` (N25: 0.02, 20), ``dwell_s`` (100), ``rate_hz`` (100),
``simulation`` (below); ``n25-fig5``: ``dtheta_arcsec`` (list), ``method`` (``n25``),
``uncertainty`` (false: the formal 1-sigma of the calibration is not needed for the
empirical RSD and costs as much as the rest of a run; true adds a "formal σ" column);
``n25-schemes``: ``methods`` (list), ``dtheta_arcsec`` (20), ``max_passes`` (5, the
systematic filter's passes); ``s16-table2``: ``methods`` (list of systematic methods),
``rate_hz`` (100), ``max_passes`` (5), ``z_rms_band`` ([0.8, 1.2]).

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
from types import SimpleNamespace

import numpy as np

from .. import units
from ..errors import PARAMETERS, GimbalErrors, ImuErrors, MISALIGN_NAMES, CROSS_NAMES
from .montecarlo import Experiment, Summary, StudyError, register_experiment, std_ci

FIG5_DTHETA = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 40.0)
SCHEME_LABELS = {"n25": "scheme 1 (n25)", "six-position": "scheme 2 (six-position)", "joint": "joint LSQ",
                 "twelve-position": "twelve-position", "systematic30": "scheme 3 (systematic30, system-level Kalman)",
                 "systematic51": "scheme 3 (systematic51, system-level Kalman)"}
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


def _is_record_method(method: str) -> bool:
    """Methods that read the increments (the systematic filter), not window means."""
    from ..calibrate import RECORD_METHODS

    return method in RECORD_METHODS


def result_errors(res, true_imu: ImuErrors, true_gimbal: GimbalErrors) -> tuple[dict[str, float], dict[str, float]]:
    """``({"accel_bias.z": estimate - truth, ...}, {same keys: 1 sigma})`` in field units for
    every component that ``res`` estimates.

    A method that defines its own IMU frame (``res.truth_transform`` set: the systematic
    filter, gyro-defined S16 m-frame) is compared with the truth mapped into that frame, and
    the components fixed by the frame definition or the model (NaN sigma: the three upper gyro
    angles of the gyro-defined frame, the off-diagonal lever arms of the S16 form) are left
    out: they are not estimates, so their (zero) error says nothing.  Parameters a method does
    not estimate (the gimbal, for the systematic filter) are absent, never zero errors.
    Sigmas are returned where the result has them (NaN placeholders are dropped)."""
    transform = getattr(res, "truth_transform", None)
    ti, tg = transform((true_imu, true_gimbal)) if transform is not None else (true_imu, true_gimbal)
    names = _estimated_names(res)
    err = parameter_errors(res.imu, res.gimbal, ti, tg, names)
    sig: dict[str, float] = {}
    sigma = getattr(res, "sigma", None) or {}
    for name in names:
        if name not in sigma:
            continue
        v = np.ravel(units.from_si(np.asarray(sigma[name], float), PARAMETERS[name][3]))
        comps = parameter_components(name)
        if v.size != len(comps):
            continue
        for comp, x in zip(comps, v):
            sig[f"{name}.{comp}" if comp else name] = float(x)
    if transform is not None:
        err = {k: v for k, v in err.items() if math.isfinite(sig.get(k, math.nan))}
    return err, {k: sig[k] for k in err if k in sig and math.isfinite(sig[k])}


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
    rec = simulate_record(key, rng, exp.params["simulation"])
    ws = None
    out: dict = {}
    diag = {}
    for m in exp.params["methods"]:
        if _is_record_method(m):  # scheme 3: the filter reads the increments
            res = calibrate(rec, m, max_passes=exp.params["max_passes"])
            d = res.diagnostics
            diag[m] = {"nis_mean": d["innovations"]["nis_mean"], "passes": len(d["passes"]), "converged": d["converged"]}
        else:
            if ws is None:
                ws = window_means(rec)  # segmented once, for every discrete method
            res = calibrate(ws, m, uncertainty=False)
        out[m] = result_errors(res, sc.imu, sc.gimbal)[0]
    if diag:
        out["diagnostics"] = diag
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
    notes = [f"{c['claim']}: {_verdict(c['holds'])} ({c['detail']})" for c in checks]
    notes.append("schemes: " + ", ".join(f"{m} = {SCHEME_LABELS.get(m, m)}" for m in methods))
    s3 = [m for m in methods if _is_record_method(m)]
    diag = {}
    for m in s3:
        d = [r["diagnostics"][m] for r in res if m in r.get("diagnostics", {})]
        if d:
            diag[m] = {"nis_mean": float(np.mean([x["nis_mean"] for x in d])),
                       "converged": sum(bool(x["converged"]) for x in d), "runs": len(d),
                       "passes_mean": float(np.mean([x["passes"] for x in d]))}
            notes.append(f"{m}: errors against the truth mapped into its gyro-defined frame (N25 maps scheme 3 into "
                         "the turntable frame with known rotations: the same to first order); the 3 gyro angles fixed "
                         "by that frame and the gimbal parameters are not estimated (absent); NIS mean "
                         f"{diag[m]['nis_mean']:.3g} (6 expected), converged in {diag[m]['converged']}/{len(d)} runs, "
                         f"{diag[m]['passes_mean']:.2g} passes on average")
    if not s3:
        notes.append("scheme 3 (system-level Kalman calibration, method systematic30/systematic51) not in this study")
    return Summary(f"n25-schemes: calibration error (estimate - truth), {len(res)} runs, dθ = {exp.params['dtheta_arcsec']:g}″",
                   cols, rows, notes, {"checks": checks, "methods": methods, "scheme3_diagnostics": diag})


def _verdict(holds) -> str:
    return "info" if holds is None else ("yes" if holds else "NO")


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
    s3 = next((m for m in methods if _is_record_method(m)), None)
    if s3 is not None and "n25" in methods:
        # N25 section 5: scheme 1 beats scheme 3 for the z-accelerometer bias and the installation angles
        for g, pred in _CLAIM_GROUPS.items():
            if g == "accelerometer scale factors":  # N25: scheme 3 "performs well" there (no ranking claimed)
                continue
            ra, rb = _group_rms(rows, "n25", pred), _group_rms(rows, s3, pred)
            if ra is not None and rb is not None:
                checks.append({"claim": f"n25 < {s3} for {g}", "holds": bool(ra < rb),
                               "detail": f"RMS {ra:.4g} vs {rb:.4g}" + (" (scheme 3: the 3 angles its frame leaves free)"
                                                                        if g.startswith("gyro") else ""),
                               "n25": ra, s3: rb})
        ratios = {}
        for g in dict.fromkeys(r["parameter"].split(".")[0] for r in rows):
            pred = lambda k, g=g: k.split(".")[0] == g  # noqa: E731
            ra, rb = _group_rms(rows, s3, pred), _group_rms(rows, "n25", pred)
            if ra is not None and rb:
                ratios[g] = ra / rb
        checks.append({"claim": f"scheme 3 ({s3}) vs scheme 1 (n25): RMS ratio per parameter group", "holds": None,
                       "detail": ", ".join(f"{g} {v:.3g}" for g, v in ratios.items()) or "no common group",
                       "ratios": ratios})
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


def _check_methods(methods) -> list[str]:
    from ..calibrate import METHODS

    ms = [methods] if isinstance(methods, str) else list(methods)
    if not ms or not all(isinstance(m, str) for m in ms) or len(set(ms)) != len(ms):
        raise StudyError(f"methods must be a list of distinct method names, got {methods!r}")
    bad = [m for m in ms if m not in METHODS]
    if bad:
        raise StudyError(f"unknown method(s) {bad}; choose from {', '.join(METHODS)}")
    return ms


def _check_passes(max_passes) -> int:
    if isinstance(max_passes, bool) or not isinstance(max_passes, int) or max_passes < 1:
        raise StudyError(f"max_passes must be a positive integer, got {max_passes!r}")
    return int(max_passes)


def n25_schemes(methods=("n25", "six-position", "joint", "systematic30"), dtheta_arcsec: float = 20.0,
                arw_deg_rt_h: float = 0.02, vrw_ug_rt_hz: float = 20.0, dwell_s: float = 100.0, rate_hz: float = 100.0,
                simulation: str = "full", max_passes: int = 5) -> Experiment:
    ms = _check_methods(methods)
    if isinstance(dtheta_arcsec, bool) or not isinstance(dtheta_arcsec, (int, float)) or not math.isfinite(dtheta_arcsec):
        raise StudyError(f"dtheta_arcsec must be a number, got {dtheta_arcsec!r}")
    params = {"methods": ms, "dtheta_arcsec": float(dtheta_arcsec), "max_passes": _check_passes(max_passes),
              **_check_common({"arw_deg_rt_h": arw_deg_rt_h, "vrw_ug_rt_hz": vrw_ug_rt_hz, "dwell_s": dwell_s,
                               "rate_hz": rate_hz, "simulation": simulation})}
    return Experiment("n25-schemes", params, ({"scenario": "n25", "dtheta_arcsec": float(dtheta_arcsec)},), _schemes_run,
                      _schemes_summarize, _schemes_plot, _warmup_systematic if any(_is_record_method(m) for m in ms)
                      else _warmup, version=2,
                      description="N25 §5: error bias/std of every parameter for each calibration scheme")


# ---------------------------------------------------------------------------- s16-table2
#: S16 Table 2 "after filter" figures (field units of :data:`inscal.errors.PARAMETERS`)
S16_TABLE2 = {"gyro_g_sensitivity": 0.0002, "accel_nonlinearity": 1.3, "accel_cross_coupling": 1.5,
              "accel_lever_arm": 0.01}
#: expected mean |x| of a zero-mean normal x per unit sigma
_HALF_NORMAL_MEAN = math.sqrt(2.0 / math.pi)


@functools.lru_cache(maxsize=8)
def _s16_scenario(rate_hz: float):
    from ..scenarios import build

    sc = build("s16")
    return sc if rate_hz == sc.rate_hz else replace(sc, rate_hz=rate_hz)


def s16_record(rate_hz: float, rng: np.random.Generator):
    """An :class:`inscal.io.Record` of the built-in ``s16`` scenario at ``rate_hz`` with noise from ``rng``."""
    from ..io import Record, Truth
    from ..simulate import simulate

    sc = _s16_scenario(float(rate_hz))
    d = simulate(sc, rng)
    return Record(d.time, d.dtheta, d.dvel, d.gimbal, sc.rate_hz, sc.site, path=sc.path,
                  truth=Truth(sc.imu, sc.gimbal, sc.noise), scenario=sc.name)


def systematic_statistics(res, true_imu: ImuErrors, true_gimbal: GimbalErrors | None = None) -> dict:
    """Per-run statistics of a systematic calibration against the truth: ``errors`` and
    ``sigmas`` per estimated component (field units, truth mapped into the filter's frame,
    components fixed by the frame or the model left out), and the NEES of the parameter error
    state (``e`` = :meth:`CompParams.error_state` of the estimate against
    :func:`truth_in_frame`, ``P`` = ``res.covariance["P"]``, ``dof`` = len(e)) with the
    per-state ``z = e / sqrt(diag P)``.  State sets with the gimbal states (``unified``): the
    estimate's ``res.gimbal`` against ``true_gimbal`` (default ideal) enter ``e``, so the NEES
    counts ``dth`` and the mount attitude too."""
    from ..calibrate.systematic import CompParams, truth_in_frame

    tg = GimbalErrors() if true_gimbal is None else true_gimbal
    err, sig = result_errors(res, true_imu, tg)
    st = res.states
    est = CompParams.from_imu(res.imu)
    if st.gimbal:
        est.gim = np.concatenate([[res.gimbal.nonorthogonality], np.asarray(res.gimbal.mount_attitude, float)])
    e = est.error_state(st, truth_in_frame(true_imu, st, tg if st.gimbal else None))
    P = np.asarray(res.covariance["P"], float)
    d = np.sqrt(np.diag(P))
    z = e / d
    nees = float(z @ np.linalg.solve(P / np.outer(d, d), z))  # correlation form: well conditioned
    inn = res.diagnostics["innovations"]
    return {"errors": err, "sigmas": sig, "nees": nees, "dof": int(e.size), "z": z.tolist(),
            "states": res.diagnostics["state_options"],
            "nis_mean": float(inn["nis_mean"]), "passes": len(res.diagnostics["passes"]),
            "converged": bool(res.diagnostics["converged"])}


def _table2_run(exp: Experiment, p: int, rng: np.random.Generator) -> dict:
    from ..calibrate import calibrate

    rec = s16_record(exp.params["rate_hz"], rng)
    sc = _s16_scenario(float(exp.params["rate_hz"]))
    return {m: systematic_statistics(calibrate(rec, m, max_passes=exp.params["max_passes"]), sc.imu, sc.gimbal)
            for m in exp.params["methods"]}


def _group_of(key: str) -> str:
    return key.split(".")[0]


def _ordered_groups(keys) -> list[str]:
    order = {n: i for i, n in enumerate(PARAMETERS)}
    return sorted(dict.fromkeys(_group_of(k) for k in keys), key=lambda g: order.get(g, 99))


def _true_magnitude(exp: Experiment) -> dict[str, float]:
    """Mean |true value| per group in the filter's (gyro-defined) frame, field units: the error
    a method leaves when it does not estimate the group."""
    from ..calibrate.systematic import StateSet, truth_in_frame

    imu = truth_in_frame(_s16_scenario(float(exp.params["rate_hz"])).imu, StateSet.parse("51")).to_imu()
    out = {}
    for name, (obj, attr, _, unit, _) in PARAMETERS.items():
        if obj != "imu" or not hasattr(imu, attr):
            continue
        v = np.abs(np.ravel(units.from_si(np.asarray(getattr(imu, attr), float), unit)))
        if name == "accel_lever_arm":
            v = np.abs(np.diag(units.from_si(np.asarray(imu.accel_lever_arm, float), unit)))  # S16 form: diagonal
        if name == "gyro_misalignment":
            v = v[[2, 4, 5]]  # the gyro-defined frame fixes xy, xz, yz
        out[name] = float(np.mean(v)) if v.size else 0.0
    return out


def rms_z_band(runs: int, level: float = 0.95) -> tuple[float, float]:
    """Sampling band of the RMS of ``runs`` independent standard normal draws."""
    from scipy.stats import chi2

    a = (1 - level) / 2
    return (math.sqrt(chi2.ppf(a, runs) / runs), math.sqrt(chi2.ppf(1 - a, runs) / runs))


def nees_band(runs: int, dof: int, level: float = 0.95) -> tuple[float, float]:
    """Band of the mean of ``runs`` chi-square(``dof``) draws: ``chi2.ppf([a, 1-a], runs*dof) / runs``."""
    from scipy.stats import chi2

    a = (1 - level) / 2
    return (float(chi2.ppf(a, runs * dof) / runs), float(chi2.ppf(1 - a, runs * dof) / runs))


def _table2_summarize(exp: Experiment, results: list[list[dict]]) -> Summary:
    from ..calibrate.systematic import StateSet

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
        row = {"group": g, "unit": PARAMETERS[g][3], "before": before.get(g), "s16_target": S16_TABLE2.get(g)}
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
            comp.append({"parameter": k, "unit": PARAMETERS[_group_of(k)][3], "n": int(e.size),
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
    notes = [f"{c['claim']}: {_verdict(c['holds'])} ({c['detail']})" for c in checks] + notes
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


def _warmup_systematic(exp: Experiment) -> None:
    """Compile (and cache on disk) the simulation and the systematic filter's kernels."""
    from ..calibrate import calibrate
    from ..scenarios import build
    from ..simulate import Scenario, simulate
    from ..turntable import Move, Path as TPath

    sc = build("s16")
    short = TPath("warmup", (Move("outer", math.pi / 2, 0.2, 10.0), Move("inner", math.pi / 2, 0.2, 10.0)),
                  initial_dwell=10.0, closed=False)
    wsc = Scenario("warmup", short, sc.site, sc.imu, sc.gimbal, sc.noise, 50.0)
    d = simulate(wsc, np.random.default_rng(0))
    rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=wsc.rate_hz, site=wsc.site)
    for m in ("systematic51", "systematic30"):
        calibrate(rec, m, max_passes=1)


def s16_table2(methods=("systematic51", "systematic30"), rate_hz: float = 100.0, max_passes: int = 5,
               z_rms_band=(0.8, 1.2)) -> Experiment:
    ms = _check_methods(methods)
    if not all(_is_record_method(m) for m in ms):
        raise StudyError(f"s16-table2 compares the systematic methods only, got {ms}")
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not (math.isfinite(rate_hz) and rate_hz > 0):
        raise StudyError(f"rate_hz must be a positive number, got {rate_hz!r}")
    zb = list(z_rms_band) if isinstance(z_rms_band, (list, tuple)) else None
    if not zb or len(zb) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in zb) or not 0 < zb[0] < 1 < zb[1]:
        raise StudyError(f"z_rms_band must be [lo, hi] with 0 < lo < 1 < hi, got {z_rms_band!r}")
    params = {"methods": ms, "rate_hz": float(rate_hz), "max_passes": _check_passes(max_passes),
              "z_rms_band": [float(v) for v in zb]}
    return Experiment("s16-table2", params, ({"scenario": "s16"},), _table2_run, _table2_summarize, _table2_plot,
                      _warmup_systematic, version=1,
                      description="S16 Table 2: systematic calibration accuracy (51 vs 30 states), NEES and error/sigma")


register_experiment("n25-fig5", n25_fig5, "N25 Fig. 5: relative std of the estimated gimbal non-orthogonality vs dθ")
register_experiment("n25-schemes", n25_schemes, "N25 §5: bias and std of every calibrated parameter per scheme")
register_experiment("s16-table2", s16_table2, "S16 Table 2: 51- vs 30-state systematic calibration, NEES, error/sigma")
