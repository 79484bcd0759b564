"""``inscal demo``: the main job on built-in defaults.

1. simulate the S16 (Table 1 path, extended error model) and N25 (twelve positions,
   gimbal non-orthogonality) scenarios into DIR;
2. Allan deviation of the N25 record's first static window;
3. calibrate the N25 record with the proposed method and the joint fit, and compare
   with the truth;
4. calibrate the S16 record with the systematic 51- and 30-state filters (S16 section 4) and
   compare the S16 Table 2 groups with the paper's figures;
5. navigate a rotation-modulated run with and without the calibration;
6. write the report: ``report.html`` (self-contained, every figure embedded), the figures as PNG
   files and ``summary.json`` (the result dict, as ``--json`` prints it).
"""

from __future__ import annotations

import time
from pathlib import Path

import typer

from inscal.cli.common import CliError, fail, print_json, short
from inscal.cli.options import ForceOption, JsonOption, SeedOption

#: the report's files (besides the records and parameter files of the steps)
REPORT_FILES = ("report.html", "summary.json", "allan.png", "s16-table2.png", "nav-comparison.png")
#: the navigation runs: label -> parameter file (None: uncalibrated)
NAV_RUNS = ("uncalibrated", "six-position", "n25", "joint")


def run_demo(out: Path, force: bool, seed: int, quick: bool, show_progress: bool, log) -> dict:
    from inscal.cli.common import check_output
    from inscal.cli.simulate import run_simulate

    out.mkdir(parents=True, exist_ok=True)
    for name in REPORT_FILES + tuple(f"nav-{label}.png" for label in NAV_RUNS):
        check_output(out / name, force)  # before the work, not after it
    res: dict = {"out": str(out), "seed": seed, "quick": quick, "steps": {}}
    ctx: dict = {"nav_runs": {}}  # what the report draws but summary.json does not hold (result objects)
    t0 = time.perf_counter()
    for name in ("s16", "n25"):
        r = run_simulate(name, out / f"{name}.h5", seed=seed, force=force, show_progress=show_progress)
        res["steps"][f"simulate_{name}"] = r
        log(f"simulated {name}: {r['samples']} samples, {r['duration_s'] / 3600:.2f} h -> {r['out']}")
    from inscal import io
    from inscal.cli.allan import run_allan
    from inscal.core import units

    a = run_allan(out / "n25.h5", 0.0, 100.0)
    noise = io.record_info(out / "n25.h5").truth.noise
    a["true_arw_deg_rth"] = units.from_si(noise.arw, "deg/sqrt(h)")
    a["true_vrw_ug_rthz"] = units.from_si(noise.vrw, "ug/sqrt(Hz)")
    ctx["allan"] = a
    res["steps"]["allan_n25"] = {k: a[k] for k in ("arw_deg_rth", "vrw_ug_rthz", "true_arw_deg_rth", "true_vrw_ug_rthz",
                                                   "window_s")}
    log("Allan (N25 first dwell): ARW " + ", ".join(f"{v:.4f}" for v in a["arw_deg_rth"])
        + f" deg/rt(h) (true {a['true_arw_deg_rth'][0]:g}); VRW " + ", ".join(f"{v:.1f}" for v in a["vrw_ug_rthz"])
        + f" ug/rt(Hz) (true {a['true_vrw_ug_rthz'][0]:g})")
    _calibrate_stage(out, force, seed, quick, show_progress, log, res)
    _systematic_stage(out, force, seed, quick, show_progress, log, res)
    _navigate_stage(out, force, seed, quick, show_progress, log, res, ctx["nav_runs"])
    _report_stage(out, force, log, res, ctx, t0)
    return res


def _report_stage(out, force, log, res, ctx, t0):
    """Figures, ``report.html`` and ``summary.json``."""
    import json

    from inscal.io.files import atomic_path
    from inscal.io.jsonfile import to_jsonable
    from inscal.report.demo import demo_report

    t1 = time.perf_counter()
    res["elapsed_s"] = t1 - t0
    try:
        files = demo_report(out, res, ctx.get("nav_runs"), ctx.get("allan"), overwrite=force)
    except (FileExistsError, FileNotFoundError) as exc:
        raise CliError(str(exc)) from None
    res["report"] = {"html": str(files.pop("report.html")), "figures": {k: str(v) for k, v in files.items()},
                     "summary": str(out / "summary.json"), "elapsed_s": round(time.perf_counter() - t1, 3)}
    res["elapsed_s"] = time.perf_counter() - t0
    with atomic_path(out / "summary.json", force) as tmp:
        tmp.write_text(json.dumps(to_jsonable(res), indent=2) + "\n", encoding="utf-8")
    log(f"report: {res['report']['html']} ({len(res['report']['figures'])} figures, "
        f"{res['report']['elapsed_s']:.1f} s), summary: {res['report']['summary']}")


def _calibrate_stage(out, force, seed, quick, show_progress, log, res):
    """Calibrate the N25 record with the traditional six-position scheme, the N25 method and the joint fit."""
    from inscal.cli.calibrate import run_calibrate
    from inscal.cli.calibrate_setup import CalibrateOptions

    res["steps"]["calibrate"] = {}
    for method in ("six-position", "n25", "joint"):
        r = run_calibrate(CalibrateOptions(out / "n25.h5", method, out / f"params-{method}.toml", force=force))
        p = r["parameters"]
        res["steps"]["calibrate"][method] = p  # every estimate: value, sigma, error (against the truth), unit
        dth = p.get("gimbal_nonorthogonality")
        dth_txt = (f"dtheta {dth['value'][0]:.2f}\" (error {dth['error'][0]:+.2f}\")" if dth and dth.get("error") is not None
                   else "dtheta not estimated")
        ab = p["accel_bias"]["error"]
        am = max(abs(x) for x in p["accel_misalignment"]["error"])
        log(f"calibrated n25 with {method:>12}: {dth_txt}; accel bias error [" + ", ".join(f"{x:+.1f}" for x in ab)
            + f"] ug; max accel installation error {am:.1f}\"")


#: filter passes in the demo: the second pass moves the 51-state estimate by ~25 sigma, the
#: third by ~0.1 sigma, so 2 passes give the converged figures (``inscal calibrate`` stops
#: after 3) to 3 digits over 50 s16 seeds, one pass (1 s) sooner
DEMO_SYSTEMATIC_PASSES = 2


def _systematic_stage(out, force, seed, quick, show_progress, log, res):
    """Calibrate the S16 record with the 51- and 30-state systematic filters and compare the
    S16 Table 2 groups (mean |error| over the estimated components, truth mapped into the
    filter's gyro-defined frame) with the paper's figures.  A group a filter does not estimate
    keeps its whole error: its mean |true value| is reported, marked not estimated."""
    import numpy as np

    from inscal import io
    from inscal.analysis.truth import result_errors
    from inscal.calibrate import calibrate
    from inscal.calibrate.systematic.params import truth_in_frame
    from inscal.calibrate.systematic.states import StateSet
    from inscal.calibrate.windows import CalibrationError
    from inscal.cli.common import check_output
    from inscal.core import units
    from inscal.core.error_model import PARAMETERS
    from inscal.io.paramfile import ParamFileError, save_params
    from inscal.sim.scenarios import S16_TABLE2

    data = out / "s16.h5"
    rec = io.read_record(data)
    truth = rec.truth
    digest = io.file_hash(data)
    true_m = truth_in_frame(truth.imu, StateSet.parse("51")).to_imu()  # the filter's frame
    res["steps"]["systematic_s16"] = {}
    for method in ("systematic51", "systematic30"):
        dest = out / f"params-{method}.toml"
        check_output(dest, force)
        t0 = time.perf_counter()
        try:
            r = calibrate(rec, method, max_passes=DEMO_SYSTEMATIC_PASSES)
        except CalibrationError as exc:
            raise CliError(f"{data}: {exc}") from None
        elapsed = time.perf_counter() - t0
        try:
            d = r.diagnostics
            save_params(dest, r, data_file=data.name, data_hash=digest, overwrite=force,
                        metadata={"scenario": rec.scenario or None, "frame": d["frame"], "states": d["state_options"],
                                  "state_count": d["states"], "filter_rate_hz": d["filter_rate_hz"],
                                  "nis_mean": d["innovations"]["nis_mean"], "chi2": d["innovations"]["chi2"],
                                  "dof": d["innovations"]["dof"], "p_value": d["innovations"]["p_value"],
                                  "max_passes": DEMO_SYSTEMATIC_PASSES})
        except (ParamFileError, FileExistsError, FileNotFoundError, OSError) as exc:
            raise CliError(str(exc)) from None
        err, sig = result_errors(r, truth.imu, truth.gimbal)
        comps = _components(r, err, sig)
        groups = {}
        for g in PARAMETERS:
            e = [abs(v) for k, v in err.items() if k.split(".")[0] == g]
            if e:
                groups[g] = {"mean_abs_error": float(np.mean(e)), "estimated": True}
            elif g in S16_TABLE2:  # not estimated: the whole error stays (S16 form: diagonal lever arm)
                v = np.asarray(getattr(true_m, PARAMETERS[g].attribute), float)
                v = np.diag(v) if g == "accel_lever_arm" else v
                groups[g] = {"mean_abs_error": float(np.mean(np.abs(units.from_si(v, PARAMETERS[g].unit)))),
                             "estimated": False}
            if g in groups:
                groups[g].update(unit=PARAMETERS[g].unit, s16=S16_TABLE2.get(g))
        inn = r.diagnostics["innovations"]
        res["steps"]["systematic_s16"][method] = {
            "groups": groups, "out": str(dest), "nis_mean": inn["nis_mean"], "passes": len(r.diagnostics["passes"]),
            "elapsed_s": round(elapsed, 3), "parameters": comps}

        def fmt(g, v, short=True):
            return (f"{(g.split('_', 1)[1] if short else g).replace('_', ' ')} {v['mean_abs_error']:.2g}"
                    + ("" if v["estimated"] else " (not estimated)") + (f" [S16 {v['s16']:g}]" if v["s16"] else "")
                    + f" {v['unit']}")
        log(f"calibrated s16 with {method}: S16 Table 2 mean |error| "
            + "; ".join(fmt(g, groups[g]) for g in S16_TABLE2) + f"; NIS {inn['nis_mean']:.3g} (6 expected), "
            f"{len(r.diagnostics['passes'])} passes, {elapsed:.1f} s")
        log(f"    {'':>12} linear terms: " + "; ".join(fmt(g, groups[g], False) for g in (
            "gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor", "accel_misalignment")))


def _components(r, err: dict, sig: dict) -> dict:
    """Per-parameter lists (field units) of a result's estimates with their errors and sigmas
    (``{"group.comp": x}`` of :func:`inscal.analysis.truth.result_errors`; NaN where a
    component is not an estimate), as in ``inscal calibrate --json``."""
    import math

    import numpy as np

    from inscal.core.error_model import (
        PARAMETERS,
        errors_to_field,
        parameter_components,
    )

    est = errors_to_field(r.imu, r.gimbal)
    out = {}
    for name in PARAMETERS:
        keys = [f"{name}.{c}" if c else name for c in parameter_components(name)]
        if name not in est or not any(k in err for k in keys):
            continue
        out[name] = {"value": [float(x) for x in np.ravel(est[name]["value"])],
                     "sigma": [sig.get(k, math.nan) for k in keys], "error": [err.get(k, math.nan) for k in keys],
                     "unit": PARAMETERS[name].unit}
    return out


def _navigate_stage(out, force, seed, quick, show_progress, log, res, nav_runs):
    """Navigate a rotation-modulated run of the N25 IMU with each calibration (N25 section 6).

    The navigation record is noise-free: with the N25 noise (ARW 0.02 deg/sqrt(h)) the attitude
    random walk alone reaches ~90" per hour and hides the differences between calibrations."""
    from inscal.cli.navigate import NavigateOptions, navigate_file
    from inscal.cli.simulate import run_simulate

    hours = 1.0 if quick else 6.0
    rec = out / "n25-rotmod.h5"
    run_simulate("n25-rotmod", rec, seed=seed, duration_h=hours, force=force, show_progress=show_progress, no_noise=True)
    res["steps"]["navigate"] = {}
    res["navigation_hours"] = hours
    for label in NAV_RUNS:
        params = None if label == "uncalibrated" else out / f"params-{label}.toml"
        r, nav_res, gim = navigate_file(NavigateOptions(rec, params=params))
        nav_runs[label] = (nav_res, gim)
        keep = {k: r[k] for k in ("duration_h", "max_position_error_m", "final_position_error_m", "max_position_error_nmi",
                                  "max_attitude_error_arcsec", "max_velocity_error_mps", "final_attitude_deg") if k in r}
        res["steps"]["navigate"][label] = keep
        att = list(keep.get("max_attitude_error_arcsec", {"roll": float("nan"), "pitch": float("nan"), "yaw": float("nan")}).values())
        log(f"navigated {hours:g} h rotation modulation with {label:>12}: max position error "
            f"{keep.get('max_position_error_m', float('nan')):8.1f} m, max attitude error (roll, pitch, yaw) "
            + ", ".join(f"{a:.1f}" for a in att) + " arcsec")



def register(app: typer.Typer) -> None:
    @app.command()
    def demo(
        out: Path = typer.Option(Path("demo-output"), "--out", "-o", help="folder for the demo's files"),
        force: ForceOption = False,
        seed: SeedOption = 1,
        quick: bool = typer.Option(False, "--quick", help="shorter navigation run"),
        json_: JsonOption = False,
    ):
        """Run the main job on built-in defaults: simulate, calibrate, navigate, compare."""
        log = (lambda msg: None) if json_ else typer.echo
        try:
            res = run_demo(out, force, seed, quick, not json_, log)
        except CliError as exc:
            raise fail(str(exc)) from None
        except OSError as exc:  # a read-only or full disk
            raise fail(f"cannot write in {short(out)}: {exc.strerror or exc}") from None
        if json_:
            print_json(res)
        else:
            typer.echo(f"demo finished in {res['elapsed_s']:.1f} s; files in {res['out']}/; open {res['report']['html']}")
