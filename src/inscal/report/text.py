"""Plain-text lines of calibration results for the terminal: a calibration's parameters, fit and thermal model,
a stored result, and a unit's history (the ``inscal calibrate`` and ``inscal db`` text outputs)."""

from __future__ import annotations

import math
import re

import numpy as np

from inscal.lab.drift import months_between
from inscal.report.budget import budget_lines


def vector(v) -> str:
    """``[a, b, c]`` of a value or a vector, 4 significant digits, ``nan`` for a value that is not finite."""
    a = np.ravel(np.asarray(v, dtype=float))
    return "[" + ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a) + "]"


def number(v, fmt: str = ".3g") -> str:
    """``v`` in ``fmt``, or ``-`` (right-aligned in the format's width) when not a finite number."""
    if v is None or not math.isfinite(v):
        width = re.match(r"[+ -]?(\d*)", fmt).group(1)
        return "-".rjust(int(width) if width else 1)
    return format(v, fmt)


def fit_lines(fit: dict) -> list[str]:
    """The printed fit of a window-mean method: chi2, dof, p, verdict and the residuals of
    every window (RMS of the normalised residuals, gyro / accelerometer)."""
    exp = "" if fit.get("expected_chi2", fit["dof"]) == fit["dof"] else f", {fit['expected_chi2']:.4g} expected"
    ref = "expected" if exp else "dof"
    if fit["consistent"]:
        verdict = "consistent"
    elif fit.get("p_value_low", 1.0) < 1e-3:  # chi2 far below its dof: the noise model is too large
        verdict = f"INCONSISTENT (chi2 far below its {ref}), sigma conservative: see the note"
    else:
        verdict = f"INCONSISTENT (sqrt(chi2/{ref}) = {fit['scale']:.3g}), sigma adjusted: see the note"
    out = [f"  fit: chi2 {fit['chi2']:.4g} on {fit['dof']} dof{exp}, p = {fit['p_value']:.3g}: {verdict}"]
    res = fit["residuals"]
    if res and "nis_mean" in res[0]:  # systematic filter: time blocks of its innovations
        per = fit.get("expected_chi2", fit["dof"]) / max(fit["dof"] / 6.0, 1.0)
        out.append(f"  innovations per time block (mean NIS, expected {per:.3g}; velocity RMS m/s, position RMS m):")
        out += [f"    {r['window']:3d} {r['label']:24s} {r['nis_mean']:9.3g}  {r['velocity_rms_m_s']:9.3g}  "
                f"{r['position_rms_m']:9.3g}" for r in res]
        return out
    out.append("  residuals per window (normalised RMS, gyro / accel):")
    out += [f"    {r['window']:3d} {r['label']:44s} {r['gyro']:9.3g} / {r['accel']:9.3g}" for r in res]
    return out


def thermal_lines(th: dict) -> list[str]:
    """The printed thermal model: the plateaus, then per term and order the coefficients +- 1 sigma (field
    units) and the fit of the term over the plateaus."""
    fit = th.get("fit") or {}
    plats = fit.get("plateaus", [])
    out = [f"  thermal model: T_ref {th['t_ref']:g} degC, range {th['t_min']:.4g} .. {th['t_max']:.4g} degC"
           + (f", {len(plats)} plateaus at " + ", ".join(f"{p['temperature_c']:.4g}" for p in plats) + " degC"
              if plats else "")
           + (f" ({fit['per_plateau']} on each)" if "per_plateau" in fit else "")]
    terms = fit.get("terms", {})
    for name, rows in th["terms"].items():
        for r in rows:
            sig = f" +- {vector(r['sigma'])}" if "sigma" in r else ""
            out.append(f"    {name:20s} order {r['order']} {vector(r['value'])}{sig} {r['unit']}")
        f = terms.get(name)
        if f is not None:
            verdict = "consistent" if f["consistent"] else "INCONSISTENT, sigma scaled: see the note"
            p = f.get("p_value")
            ptxt = "no dof" if not f["dof"] else f"p = {p:.3g}"
            out.append(f"      fit: chi2 {f['chi2']:.4g} on {f['dof']} dof, {ptxt}: {verdict}")
    return out


def history_lines(rep: dict, h) -> list[str]:
    """The printed history of a unit (:func:`inscal.lab.unit_history`): one row per parameter with its mean,
    repeatability, drift rate and flags; ``rep`` the command's report (its ``plot``)."""
    if not h.ids:
        return [f"{h.serial}: no {h.method} calibration"]
    span = months_between(h.dates[0], h.dates[-1])
    out = [(f"{h.serial} ({h.method}): {len(h.ids)} calibrations, {h.dates[0]:%Y-%m-%d} .. {h.dates[-1]:%Y-%m-%d} "
            f"({span:.3g} months); flags at k = {h.k:g}"),
           (f"  {'component':28s} {'n':>2s} {'mean':>10s} {'+-':>8s} {'spread/sigma':>12s} {'rate/month':>11s} "
            f"{'+-':>8s} {'z':>6s} {'step z':>7s}  flags")]
    for c in h.components:
        out.append(f"  {c.label:28s} {c.n:2d} {number(c.mean, '10.4g')} {number(c.mean_sigma, '8.2g')} "
                   f"{number(c.repeatability_ratio, '12.3g')} {number(c.rate, '+11.3g')} {number(c.rate_sigma, '8.2g')} "
                   f"{number(c.rate_z, '6.2f')} {number(c.step_z, '7.2f')}  {','.join(c.flags) or '-'}  [{c.unit}]")
    flagged = h.flagged
    out.append(f"  {len(flagged)} flagged of {h.tests} tests ({h.expected_false_alarms:.2g} expected by chance at "
               f"k = {h.k:g})" + (": " + ", ".join(f"{c.label} ({'+'.join(c.flags)})" for c in flagged) if flagged
                                   else ""))
    if rep["plot"]:
        out.append(f"  plot -> {rep['plot']}")
    return out


def show_lines(cal, covariance: bool) -> list[str]:
    """The printed calibration ``cal`` (a stored result): its record, fit, provenance, every parameter +- 1 sigma,
    its covariance (the matrix when ``covariance``) and notes."""
    s = cal.session
    head = f"{cal.serial}" + (f" ({cal.unit_model})" if cal.unit_model else "")
    state = " (current)" if cal.current else ""
    if cal.superseded_by:
        state += f" (superseded by {', '.join(map(str, cal.superseded_by))})"
    out = [f"{head}: result {cal.id}, {cal.method}" + (f" [{cal.state_set}]" if cal.state_set else "")
           + f", record of {cal.date:%Y-%m-%d %H:%M} UTC{state}"]
    where = [f"{s.record_sha256[:19]}...", s.record_path or ""]
    for label, v in (("station", s.station), ("operator", s.operator), ("path", s.path_name)):
        if v:
            where.append(f"{label} {v}")
    if s.latitude_deg is not None:
        where.append(f"site {s.latitude_deg:.6g} deg N {s.longitude_deg:.6g} deg E {s.height_m:.4g} m")
    if s.g_site_m_s2 is not None:
        where.append(f"g {s.g_site_m_s2:.7g} m/s^2")
    if s.temperature_c is not None:
        where.append(f"{s.temperature_c:g} degC")
    out.append("  record: " + ", ".join(w for w in where if w))
    out.append(f"  fit: chi2 {number(cal.fit_chi2, '.4g')} on {number(cal.fit_dof, '.4g')} dof, p = {number(cal.fit_p)}")
    out.append(f"  inscal {cal.inscal_version}; parameter file {cal.param_file_sha256[:19]}...; recorded "
               f"{cal.recorded_at:%Y-%m-%d %H:%M} UTC" + (f"; supersedes {cal.supersedes}" if cal.supersedes else ""))
    for name, p in cal.parameters.items():
        line = f"  {name:24s} {vector(p.value)} +- {vector(p.sigma)} {p.unit}"
        if p.sigma_formal is not None:
            line += f" (formal +- {vector(p.sigma_formal)})"
        out.append(line)
    cov = cal.covariance or {}
    if cov:
        n = len(cov.get("labels", []))
        kind = "full" if cov.get("correlations") else "diagonal only (the method reports no correlations)"
        out.append(f"  covariance: {n}x{n} over the {cov.get('basis')} ({cov.get('units')} units), {kind}")
        if covariance and cov.get("matrix") is not None:
            for lab_, row in zip(cov["labels"], cov["matrix"]):
                out.append(f"    {lab_:28s} " + " ".join("nan" if x is None else f"{x:.3g}" for x in row))
    for note in cal.notes:
        out.append(f"  note: {note}")
    return out


def calibration_lines(rep: dict) -> list[str]:
    """The printed calibration of ``inscal calibrate`` (its JSON report ``rep``): every parameter +- 1 sigma, the
    thermal model, the encoders, the fit, the rejected poses, the chosen states, the filter's NIS, the plots,
    the notes, the uncertainty budget and the database row."""
    out = [f"{rep['method']}: parameters -> {rep['out']}"]
    for name, e in rep["parameters"].items():
        line = f"  {name:24s} {vector(e['value'])} +- {vector(e['sigma'])} {e['unit']}"
        if "sigma_formal" in e:
            line += f" (formal +- {vector(e['sigma_formal'])})"
        if "error" in e:
            line += f"   (error {vector(e['error'])})"
        out.append(line)
    if "thermal" in rep:
        out += thermal_lines(rep["thermal"])
    if "encoders" in rep:
        e = rep["encoders"]
        lat = "" if e["latency_s"] is None else f", latency {e['latency_s'] * 1e3:.3g} ms"
        out.append(f"  encoders: agree with the gyros on {e['moves']} moves{lat}")
    if "fit" in rep:
        out += fit_lines(rep["fit"])
    for c in rep.get("still", []):
        if not c["kept"]:
            out.append(f"  pose {c['pose']} ({c['t0_s']:.1f}-{c['t1_s']:.1f} s): rejected, {c['reason']}")
    if "selection" in rep:
        sel = rep["selection"]
        how = (f"the states named, {sel['base']}, checked for the lever-arm timing and the frame: {sel['fits']} more fits"
               if sel.get("named") else f"chosen from the data, {sel['fits']} fits")
        out.append(f"  states: {sel['chosen']} ({how}; full model {sel['full']})")
        for t in sel["tests"]:
            verb = ("added" if t["accepted"] else "not needed") if t["step"] == "add" else \
                ("dropped" if t["accepted"] else "kept")
            if t.get("status", "tested") != "tested":
                out.append(f"    {t['term']:8s} {verb:10s} not compared: {t['status']}")
                continue
            out.append(f"    {t['term']:8s} {verb:10s} statistic {t['statistic']:.4g} on {t['dk']} dof "
                       f"(dispersion {t['dispersion']:.3g}), p = {t['p_value']:.3g}")
    if "innovations" in rep:
        inn = rep["innovations"]
        out.append(f"  filter: NIS mean {inn['nis_mean']:.3f} (expected {inn.get('nis_expected', 6.0):.3f}); "
                   f"{len(rep['passes'])} passes"
                   + ("" if rep["converged"] else " (not converged)"))
    for p in rep.get("plots", []):
        out.append(f"  plot: {p}")
    for n in rep["notes"]:
        out.append(f"  note: {n}")
    if "budget" in rep:
        out += ["  " + line for line in budget_lines(rep["budget"], full=False)]
    if "db" in rep:
        r = rep["db"]
        out.append(f"  recorded in {r['db']}: {r['serial']} result {r['result_id']}"
                   + (", now the current calibration" if r["current"] else ""))
    return out


def navigation_lines(rep: dict) -> list[str]:
    """The printed navigation run of ``inscal navigate`` (its JSON report ``rep``): the errors of position, velocity,
    height and attitude, the final attitude, the oscillations' amplitudes and the files written."""
    out = []
    th = rep["thermal"]
    out.append(f"{rep['data']}: {rep['duration_h']:.2f} h navigated ({rep['mode']}, vertical {rep['vertical_channel']}, "
               f"init {rep['init']}{', params ' + rep['params'] if rep['params'] else ''}"
               f"{', thermal model at ' + th['temperature'] if th else ''})")
    out.append(f"  position error: max {rep['max_position_error_m']:.3f} m ({rep['max_position_error_nmi']:.4f} nmi), "
               f"final {rep['final_position_error_m']:.3f} m ({rep['final_position_error_nmi']:.4f} nmi)")
    out.append(f"  velocity error: max {rep['max_velocity_error_mps']:.4f} m/s (horizontal)")
    if rep["vertical_channel"] != "hold" or rep["height_reference"] is not None:
        out.append(f"  height error: max {rep['max_height_error_m']:.3f} m, final {rep['final_height_error_m']:.3f} m "
                   f"(vertical {rep['vertical_channel']})")
    if "final_attitude_deg" in rep:
        f = rep["final_attitude_deg"]
        out.append(f"  final attitude: roll {f['roll']:.4f}°, pitch {f['pitch']:.4f}°, yaw {f['yaw']:.4f}° "
                   f"(counter-clockwise from East) = heading {f['heading']:.4f}° (clockwise from North)")
    if "max_attitude_error_arcsec" in rep:
        a = rep["max_attitude_error_arcsec"]
        out.append(f"  attitude error: max roll {a['roll']:.2f}\", pitch {a['pitch']:.2f}\", yaw {a['yaw']:.2f}\"")
    for name in ("position_east", "position_north"):
        c = rep["oscillation_amplitudes"][name]
        parts = [f"{k} {c[k]:.3f} {c['unit']}" for k in ("schuler", "foucault", "earth") if c[k] is not None]
        if parts:
            out.append(f"  {name.replace('_', ' ')}: " + ", ".join(parts))
    if rep["out"]:
        out.append(f"  -> {rep['out']}")
    if rep["plot"]:
        out.append(f"  plot -> {rep['plot']}")
    return out


def import_line(res: dict) -> str:
    """The printed import of ``inscal import`` (its JSON report ``res``): the samples, their span and rate, the
    source and the record, with what the import found or did (gimbal angles, path, encoders, regridding, a bag's
    topic, integrated rates, saturation, temperature)."""
    extra = []
    if res["gimbal"]:
        extra.append(f"gimbal angles from {res['gimbal']}")
    if res["path"]:
        extra.append(f"path {res['path']}")
    if res["encoder_latency_s"]:
        extra.append(f"encoder latency {res['encoder_latency_s'] * 1e3:g} ms corrected")
    enc = res["encoders"]
    if enc is not None and enc["moves"]:
        lat = "" if enc["latency_s"] is None else f", latency {enc['latency_s'] * 1e3:.2f} ms" + (
            "" if enc["latency_sigma_s"] is None else f" +- {enc['latency_sigma_s'] * 1e3:.2f} ms")
        to = "" if enc["max_residual_deg"] is None else f" to {enc['max_residual_deg']:.2g} deg"
        extra.append(f"encoders agree with the gyros on {enc['moves']} moves{to}{lat}")
    if res["time_regridded"]:
        extra.append("time regridded")
    if (bag := res.get("bag")) is not None:
        extra.append(f"topic {bag['topic']} ({bag['storage']}, {bag['stamps']} stamps, {bag['messages']} messages)")
    if (ig := res.get("integration")) is not None:
        b = ig["error_bound"]
        extra.append(f"rates integrated onto a {ig['grid_rate_hz']:g} Hz grid, rule error <= "
                     f"{max(b['dtheta_rad']):.2g} rad, {max(b['dvel_m_s']):.2g} m/s"
                     + (f", {ig['gaps_bridged']} step(s) over 1.5 median steps bridged (longest "
                        f"{ig['largest_step_s']:.3g} s)" if ig.get("gaps_bridged") else "")
                     + (", white noise (one sample per increment)" if ig["noise"]["white"] else
                        f", noise variance {ig['noise']['variance_ratio'][0]:.2g}-"
                        f"{ig['noise']['variance_ratio'][1]:.2g} of white, neighbour correlation up to "
                        f"{ig['noise']['neighbour_correlation']:.2g} (jittered stamps)"))
    if sat := res.get("saturated"):
        extra.append(f"{len(sat)} run(s) of a sensor at its range marked saturated (first: {sat[0]['channel']} "
                     f"at {sat[0]['level']:g} for {sat[0]['samples']} samples from t = {sat[0]['t0']:.3f} s; the "
                     "calibrations leave them out)")
    if (temp := res["temperature"]) is not None:
        on = "on the sample times" if temp["grid"] == "record" else "at their own times"
        extra.append(f"temperature: {temp['readings']} readings of {', '.join(temp['sensors'])} {on}")
    return (f"imported {res['samples']} samples ({res['duration_s']:.1f} s at {res['rate_hz']:g} Hz, {res['kind']}) "
            f"from {res['source']} -> {res['out']}" + (f" ({'; '.join(extra)})" if extra else ""))
