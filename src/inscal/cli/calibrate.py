"""``inscal calibrate``: estimate IMU and gimbal errors from a turntable record, or IMU errors from a
hand-held one (``multi-position``, ``ferraris``)."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from inscal.cli.common import (  # np: lazy (fast start)
    CliError,
    check_not_input,
    check_output,
    fail,
    normal_serial,
    np,
    print_json,
    read_record,
)
from inscal.cli.guards import check_outputs, database_notes
from inscal.cli.limits import check_mc_trials


def run_calibrate(data: Path, method: str, out: Path, force: bool = False, settle: float | None = None,
                  min_static: float | None = None, states: str | None = None, plots: Path | None = None,
                  filter_rate_hz: float = 1.0, arw: float | None = None, vrw: float | None = None,
                  gravity: str | None = None, encoder_sigma: float | None = None, encoder_latency: float = 0.0,
                  check_encoders: bool = True, db: str | None = None, serial: str | None = None,
                  station: str | None = None, operator: str | None = None, date: str | None = None,
                  temperature_c: float | None = None, supersedes: int | None = None, per_plateau: str | None = None,
                  thermal_order: list[str] | None = None, t_ref: float | None = None, plateau_tol: float = 0.5,
                  temperature_sensor: str = "", chamber_label: str = "chamber", wait: float | None = None,
                  accept_unconverged: bool = False, quadratic: bool = False, noise: Path | None = None,
                  thermal_model: Path | None = None, mc: int | None = None, mc_seed: int = 0,
                  mc_workers: int = 1, method_options: dict | None = None, tremor_dps: float | None = None) -> dict:
    """Calibrate ``data`` with ``method`` and write ``out``; returns the JSON report.
    Nothing is written unless the calibration succeeds.  ``states``/``plots``/``filter_rate_hz``/
    ``arw`` [deg/sqrt(h)]/``vrw`` [ug/sqrt(Hz)] apply to the systematic methods.  ``gravity``
    (wgs84 | psins | m/s^2) overrides the record's gravity model.  ``encoder_sigma`` [arcsec]: white
    noise of each encoder angle for the gimbal states (method ``unified``, or ``--states ...,gimbal``).
    A record with encoder angles has them compared with the gyros first (:mod:`inscal.io.encoders`): a
    unit, sign, column or time-offset error stops the calibration with one line unless
    ``check_encoders`` is False; ``encoder_latency`` [s] shifts the angles before (encoders that lag: > 0).
    ``serial``: record the result in the calibration database ``db`` (:mod:`inscal.lab`; None: ``INSCAL_DB``,
    else calib.sqlite) as a calibration of that unit, with the session's ``station``, ``operator``,
    ``date`` and ``temperature_c``, committed together with the parameter file (a failure of either
    leaves neither); ``supersedes``: the id of an earlier result this one replaces.
    Method ``thermal-plateaus``: ``per_plateau`` (default n25) runs on each temperature plateau, then the
    thermal model is fitted with ``thermal_order`` (``["gyro_bias=2", ...]``), ``t_ref`` [degC] (default 20),
    ``plateau_tol`` [degC], ``temperature_sensor`` and ``chamber_label`` (:mod:`inscal.calibrate.thermal`).
    ``accept_unconverged``: a systematic run that does not converge keeps its last iterate, with a note,
    instead of ending with one line (:class:`inscal.calibrate.systematic.driver.NotConverged`).
    ``settle``, ``min_static`` [s]: None, the method's own default (:class:`~inscal.runs.calibration.CalibrationSetup`);
    ``quadratic``: ``multi-position`` estimates the quadratic accelerometer terms too; ``method_options``: the
    no-turntable method's keyword options given (:data:`~inscal.runs.calibration.NO_TABLE_OPTIONS`, the function's
    units: ``face_tilt``, ``turn_closure`` in rad); ``tremor_dps``: the hand tremor a still pose may hold
    [deg/s rms] (multi-position; None: its default).  ``noise``: a noise.toml
    (``inscal noise --out``) whose white terms weight the systematic filter and whose Gauss-Markov terms become
    bias states (:mod:`inscal.calibrate.systematic.gm_states`).  ``station`` a description FILE.toml: the GUM
    budget (:func:`_budget`); its chamber temperature stability goes through ``thermal_model`` (a parameter file
    with a ``[thermal]`` table) or else the unit's newest thermal result in the database, at ``temperature_c``
    (allowed without ``serial`` then) or the record's mean temperature; ``mc`` trials at most of the budget's JCGM
    101 Monte Carlo (:mod:`inscal.cli.budget_mc`; seed ``mc_seed``, ``mc_workers`` Dask workers)."""
    from inscal.io.files import input_problem
    from inscal.runs.calibration import CalibrationSetup

    setup = CalibrationSetup(method, states, settle, min_static, filter_rate_hz, arw, vrw, gravity, encoder_sigma,
                             encoder_latency, check_encoders, per_plateau, parse_orders(thermal_order), t_ref,
                             plateau_tol, temperature_sensor, chamber_label, accept_unconverged, quadratic,
                             None if noise is None else str(noise),
                             method_options=tuple(sorted((method_options or {}).items())), tremor=tremor_dps)
    if (msg := setup.problem(plots is not None)) is not None:
        raise CliError(msg)
    if (msg := input_problem(data, "data file")) is not None:
        raise CliError(msg)
    check_outputs([("--out", out), ("--plots", plots)], [data, thermal_model], db, serial is not None)
    check_output(out, force)
    check_not_input(out, data)
    if plots is not None and (plots.exists() and not plots.is_dir() or not plots.parent.is_dir()):
        raise CliError(f"--plots {plots}: not a folder, nor one that can be created here")
    desc = station_description(station, method)
    thermal = budget_thermal_model(thermal_model, desc, temperature_c if serial is None else None)
    if mc is not None and desc is None:
        raise CliError("--mc is the Monte Carlo of the uncertainty budget: give --station FILE.toml")
    check_mc_trials(mc)
    if mc is not None:
        from inscal.uncertainty.sensitivity import WINDOW_METHODS

        if method not in WINDOW_METHODS:
            raise CliError(f"--mc: the Monte Carlo of the budget runs the window-mean methods "
                           f"({', '.join(WINDOW_METHODS)}), not {method}: the site and clock enter a filter linearly, "
                           "and a thousand filter runs would take hours")
    if mc_workers < 1:
        raise CliError(f"--mc-workers {mc_workers}: at least 1")
    budget_opts = None if desc is None else {"station": desc, "thermal": thermal, "temperature_c": temperature_c,
                                             "mc": mc, "mc_seed": mc_seed, "mc_workers": mc_workers}
    if desc is not None:
        station = desc.name  # the session's station: the description's name
    lab_db = _open_lab(db, serial, station if desc is None or serial is not None else None, operator, date,
                       temperature_c if desc is None or serial is not None else None, supersedes, data,
                       setup.options(), wait)
    if lab_db is None:
        return _calibrate(data, setup, out, force, plots, lab_db, budget_opts)
    try:
        return _calibrate(data, setup, out, force, plots, lab_db, budget_opts)
    finally:  # committed with the files when the command's output unit publishes them, else rolled back
        from inscal.io.files import after_unit

        after_unit(lambda: (lab_db["staged"].close() if "staged" in lab_db else None, lab_db["db"].close()))


def station_description(station: str | None, method: str):
    """The station description of ``--station FILE.toml`` (:mod:`inscal.uncertainty.station`), None for a station's
    name; refused with one line when it cannot be read or the method has no budget."""
    if station is None or not station.lower().endswith(".toml"):
        return None
    from inscal.uncertainty.sensitivity import BUDGET_METHODS
    from inscal.uncertainty.station import StationError, read_station

    if method not in BUDGET_METHODS:
        raise CliError(f"--station {station}: an uncertainty budget needs one of the methods "
                       f"{', '.join(BUDGET_METHODS)}, not {method}")
    try:
        return read_station(station)
    except StationError as exc:
        raise CliError(str(exc)) from None


def budget_thermal_model(path: Path | None, desc, temperature_c: float | None):
    """``(path, ThermalModel)`` of ``--thermal-model PARAMS.toml`` (None without it), read before the calibration
    runs: refused with one line when there is no budget, the file cannot be read or carries no thermal model.
    ``temperature_c``: a ``--temperature-c`` given without ``--serial`` (the budget's stated temperature), checked."""
    if desc is None:
        if path is not None:
            raise CliError(f"--thermal-model {path}: it serves the uncertainty budget: give --station FILE.toml")
        return None
    if temperature_c is not None and not (math.isfinite(temperature_c) and -100.0 < temperature_c < 200.0):
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    if path is None:
        return None
    from inscal.io.paramfile import ParamFileError, load_params

    try:
        meta = load_params(path)[2]
    except ParamFileError as exc:
        raise CliError(f"--thermal-model: {exc}") from None
    model = meta.get("thermal")
    if model is None or model.is_zero:
        raise CliError(f"--thermal-model {path}: the parameter file has no thermal model (no [thermal] table with "
                       "coefficients; --method thermal-plateaus or --states ...,thermal write one)")
    return path, model


def parse_orders(items: list[str] | None) -> tuple[tuple[str, int], ...]:
    """``--thermal-order NAME=K`` (repeatable; NAME a thermal term, K its polynomial order) as pairs."""
    out = []
    for item in items or []:
        name, sep, k = str(item).partition("=")
        try:
            order = int(k)
        except ValueError:
            order = None
        if not sep or not name.strip() or order is None:
            raise CliError(f"--thermal-order {item!r}: expected NAME=ORDER, e.g. gyro_bias=2 (NAME a thermal term, "
                           "ORDER 0 .. 3; 0: constant)")
        out.append((name.strip(), order))
    return tuple(out)


def _open_lab(db, serial, station, operator, date, temperature_c, supersedes, data: Path,
              options: dict, wait: float | None = None) -> dict | None:
    """The calibration database and what ``--serial`` records in it, checked before the calibration
    runs: the unit is registered, the record not yet calibrated with the same options (unless
    ``--supersedes``); None without ``--serial``."""
    if serial is None:
        extra = [n for n, v in (("--db", db), ("--station", station), ("--operator", operator), ("--date", date),
                                ("--temperature-c", temperature_c), ("--supersedes", supersedes), ("--wait", wait))
                 if v is not None]
        if extra:
            raise CliError(f"{', '.join(extra)}: the calibration is recorded in the database for a unit: give --serial")
        return None
    serial = normal_serial(serial)
    import sqlalchemy

    from inscal import lab
    from inscal.io.files import file_hash
    from inscal.io.paramfile import ParamFileError

    if temperature_c is not None and not (math.isfinite(temperature_c) and -100.0 < temperature_c < 200.0):
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    for name, text in (("--station", station), ("--operator", operator)):  # checked before the calibration runs
        if text is not None and len(text) > 200:
            raise CliError(f"{name} {text[:40]!r}...: {len(text)} characters, at most 200")
    try:
        when = lab.check_date(lab.parse_date(date), "--date") if date is not None else None
        d = lab.open_database(db, wait_s=wait)
    except (lab.DatabaseError, ValueError) as exc:
        raise CliError(str(exc)) from None
    database_notes(d)
    try:
        if lab.get_unit(d, serial) is None:
            raise CliError(f"unknown unit {serial!r} in {d.where}: register it first with `inscal db add {serial} "
                           "--model MODEL`")
        if supersedes is not None:
            old = lab.get_calibration(d, supersedes)
            if old.serial != serial:
                raise CliError(f"--supersedes {supersedes}: that result is a calibration of {old.serial}, not {serial}")
        h = file_hash(data)
        done = lab.find_calibration(d, h, options, serial)
        if done is not None and supersedes is None:
            raise CliError(f"{data} is recorded already for {serial} with these options (result {done}; `inscal db "
                           f"export {serial} --result {done} --out FILE` writes its parameter file); --supersedes {done} "
                           "records a new calibration in its place")
    except (lab.DatabaseError, ParamFileError, sqlalchemy.exc.SQLAlchemyError) as exc:
        d.close()
        raise CliError(str(getattr(exc, "orig", None) or exc).split("\n")[0]) from None
    except BaseException:
        d.close()
        raise
    return {"db": d, "serial": serial, "hash": h, "options": options, "date": when, "station": station,
            "operator": operator, "temperature_c": temperature_c, "supersedes": supersedes}


def _calibrate(data: Path, setup, out: Path, force: bool, plots, lab_db: dict | None, budget_opts=None) -> dict:
    """The calibration of :func:`run_calibrate` once its options are checked (the record's own part:
    :func:`inscal.runs.calibration.calibrate_record`, which a batch of calibrations runs too); ``budget_opts``:
    the station description and what :func:`_budget` takes with it (None: no budget)."""
    from inscal import io
    from inscal.cli.common import short
    from inscal.cli.limits import check_memory
    from inscal.io.files import output_unit
    from inscal.runs.calibration import RecordError, calibrate_record

    # the size first, before the record is read: the record in memory, then the filter's per-step stores
    try:
        info = io.record_info(data)
    except (io.DataFileError, OSError, KeyError, TypeError, ValueError):
        info = None  # read_record names what is wrong with the file
    if info is not None:
        for need, what, hint in setup.memory_needs(info, short(data, 60)):
            check_memory(need, what, hint)
    try:
        rec = read_record(data)
    except OSError as exc:
        raise CliError(str(exc)) from None
    if budget_opts is not None:  # a station of another site: refused before the calibration runs
        from inscal.uncertainty.station import StationError, site_check

        try:
            site_check(budget_opts["station"], rec.site.latitude, rec.site.height, None)
        except StationError as exc:
            raise CliError(f"--station: {exc}") from None
    try:
        cal = calibrate_record(rec, data, setup)
    except RecordError as exc:
        raise CliError(str(exc)) from None
    res, rec, meta, enc_report, systematic = cal.result, cal.record, cal.metadata, cal.encoders, setup.systematic
    budget = None if budget_opts is None else _budget(res, budget_opts["station"], lab_db, rec, setup,
                                                      budget_opts["temperature_c"], budget_opts["thermal"],
                                                      budget_opts)
    try:
        with output_unit() as unit:  # the parameter file, the plots and the database row: all together, or none
            if lab_db is not None:
                lab_db["unit"] = unit
            report = _write_outputs(data, out, force, plots, res, rec, meta, enc_report, systematic, lab_db)
            if budget is not None:
                report["budget"] = budget
        if lab_db is not None:
            report["db"] = _recorded(lab_db)
    except FileExistsError as exc:  # a file that appeared at an output while this ran is not replaced
        rid = (lab_db or {}).get("result_id")
        if rid is not None:  # the database had committed: its copy of the file is whole
            raise CliError(f"{exc}; the result is recorded in {lab_db['db'].where} as result {rid} (inscal db export "
                           f"{lab_db['serial']} --result {rid} --out FILE writes its parameter file)") from None
        raise CliError(str(exc)) from None
    return report


def _budget(res, station, lab_db: dict | None, rec, setup, temperature_c: float | None = None, thermal=None,
            mc: dict | None = None) -> dict:
    """The uncertainty budget of ``res`` at ``station`` (:func:`inscal.uncertainty.session.session_budget`: with the
    unit's repeatability and newest thermal model when ``lab_db`` is given, the chamber's temperature through
    ``thermal``, and the JCGM 101 Monte Carlo of ``mc``); kept in ``lab_db`` to be stored with the result."""
    from inscal.uncertainty.session import BudgetError, session_budget

    mc = mc or {}
    try:
        sb = session_budget(res, station, rec, setup, db=None if lab_db is None else lab_db["db"],
                            serial=None if lab_db is None else lab_db["serial"], temperature_c=temperature_c,
                            thermal=thermal, mc=mc.get("mc"), mc_seed=mc.get("mc_seed", 0),
                            mc_workers=mc.get("mc_workers", 1))
    except BudgetError as exc:
        raise CliError(f"--mc: {exc}" if exc.part == "monte_carlo" else f"--station: no uncertainty budget: {exc}") \
            from None
    if lab_db is not None:
        lab_db["budget"] = sb.stored()
    return sb.document


def _write_outputs(data: Path, out: Path, force: bool, plots: Path | None, res, rec, meta: dict, enc_report,
                   systematic: bool, lab_db: dict | None = None) -> dict:
    """Write the parameter file and the plots of :func:`run_calibrate` (inside its output unit), and record
    the result in the calibration database when asked (committed last, just before the unit publishes
    the files: a failure before leaves neither); returns the report."""
    from inscal import io
    from inscal.io.files import make_output_dir
    from inscal.io.paramfile import ParamFileError, save_params

    truth = rec.truth
    try:
        if lab_db is None:
            save_params(out, res, data_file=data.name, data_hash=io.file_hash(data), overwrite=force, metadata=meta)
        else:
            from inscal.io.files import atomic_path
            from inscal.lab import param_file_text

            text = param_file_text(res, data.name, lab_db["hash"], meta)  # what save_params writes, byte for byte
            with atomic_path(out, force) as tmp:
                tmp.write_text(text, encoding="utf-8")
    except (ParamFileError, FileExistsError, FileNotFoundError, OSError) as exc:
        raise CliError(str(exc)) from None
    report = {"method": res.method, "gravity": {**rec.site.gravity_model.to_json(), "g_site_m_s2": rec.site.gravity},
              "parameters": res.to_field(truth), "out": str(out), "notes": res.notes}
    if enc_report is not None:
        report["encoders"] = enc_report  # the encoders against the gyros: moves, residual, latency
    if res.thermal is not None:  # the thermal model in field units, its fit and the plateaus
        from inscal.core.thermal import thermal_to_field

        report["thermal"] = thermal_to_field(res.thermal, res.thermal_sigma) | {"fit": res.thermal_fit}
        if "thermal" in res.diagnostics:  # thermal states: the temperature history and the coefficient table
            report["thermal_states"] = res.diagnostics["thermal"]
    if res.fit is not None:
        report["fit"] = res.fit  # chi2, dof, p, per-window (per-block) residuals, cause and note
    if "still" in res.diagnostics:  # no turntable: every candidate pose, kept or rejected, with its reason
        report["still"] = res.diagnostics["still"]
    if systematic:
        d = res.diagnostics
        report.update({"frame": d["frame"], "states": d["states"], "state_options": d["state_options"],
                       "innovations": d["innovations"], "noise": d["noise"], "passes": d["passes"],
                       "converged": d["converged"], "convergence": d.get("convergence"),
                       "model_error": d.get("model_error")})
        report["unobservable"] = d.get("unobservable", [])  # components at (nearly) their prior sigma
        if "selection" in d:  # --states auto: every nested-model test
            report["selection"] = d["selection"]
        if "encoder" in d:  # unified / gimbal states: the encoder attitude innovations
            report["encoder"] = d["encoder"]
        if plots is not None:
            from inscal.report.figures import convergence_plots

            try:
                make_output_dir(plots)  # created once the calibration succeeded (removed again if a plot fails)
                report["plots"] = [str(p) for p in convergence_plots(plots, res, truth, overwrite=force)]
            except (FileExistsError, FileNotFoundError, OSError) as exc:
                raise CliError(f"--plots: {exc}") from None
    if lab_db is not None:
        _stage(lab_db, data, rec, res, text)
    return report


def _stage(lab_db: dict, data: Path, rec, res, text: str) -> None:
    """Write the calibration into the database in one transaction, left open: it is committed as the first
    step of the output unit's publication, with SIGINT/SIGTERM held, just before the parameter file and
    the plots are renamed into place (:func:`inscal.io.files.output_unit`), together with the journal of
    those files (:mod:`inscal.lab.journal`), so that an interrupt leaves both or neither and a SIGKILL
    after the commit leaves a publication that the next write completes; any failure before rolls it back."""
    import sqlalchemy

    from inscal import lab
    from inscal.io.paramfile import ParamFileError
    from inscal.lab.journal import add as journal_add

    d = lab_db["db"]
    try:
        session = lab.session_from_record(data, record_sha256=lab_db["hash"], date=lab_db["date"],
                                          station=lab_db["station"], operator=lab_db["operator"],
                                          temperature_c=lab_db["temperature_c"], site=rec.site)
        staged = lab.stage_calibration(d, lab_db["serial"], text, session, options=lab_db["options"],
                                       covariance=lab.covariance_of(res), supersedes=lab_db["supersedes"],
                                       date_given=lab_db["date"] is not None, budget=lab_db.get("budget"))
    except (lab.DatabaseError, ParamFileError, ValueError, sqlalchemy.exc.SQLAlchemyError) as exc:
        msg = str(getattr(exc, "orig", None) or exc).split("\n")[0]
        raise CliError(f"--db {d.where}: not recorded, and {data} not calibrated into a file either: {msg}") from None
    lab_db["staged"] = staged

    unit, entries = lab_db["unit"], []

    def commit():  # the result and the journal of its files in one transaction (inscal.lab.journal)
        try:
            entries.extend(journal_add(staged.conn, staged.value["result_id"], unit.pending))
            staged.commit()
        except Exception as exc:  # nothing is published: the unit removes the files
            msg = " ".join(str(getattr(exc, "orig", None) or exc).split())[:300]
            raise CliError(f"--db {d.where}: not recorded, and {data} not calibrated into a file either: {msg}") \
                from None
        lab_db["result_id"] = staged.value["result_id"]

    unit.before_publish.append(commit)
    unit.after_publish.append(lambda: lab.published(d, entries))  # every file in place: the journal cleared


def _recorded(lab_db: dict) -> dict:
    """The ``db`` entry of the report: the result as staged (committed when the command's outputs are published)."""
    from inscal.lab.model import iso

    v = lab_db["staged"].value
    return {"db": lab_db["db"].where, "serial": lab_db["serial"], "result_id": v["result_id"], "current": v["current"],
            "date": iso(v["date"])}


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
            sig = f" +- {_fmt(r['sigma'])}" if "sigma" in r else ""
            out.append(f"    {name:20s} order {r['order']} {_fmt(r['value'])}{sig} {r['unit']}")
        f = terms.get(name)
        if f is not None:
            verdict = "consistent" if f["consistent"] else "INCONSISTENT, sigma scaled: see the note"
            p = f.get("p_value")
            ptxt = "no dof" if not f["dof"] else f"p = {p:.3g}"
            out.append(f"      fit: chi2 {f['chi2']:.4g} on {f['dof']} dof, {ptxt}: {verdict}")
    return out


def _fmt(v) -> str:
    a = np.ravel(np.asarray(v, dtype=float))
    return "[" + ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a) + "]"


def _method_options(alpha, gravity_tol, face_tilt, min_turn_end, turn_tol, turn_closure) -> dict:
    """The no-turntable options given on the command line, in the method function's units."""
    from inscal.core import units

    given = {"alpha": alpha, "gravity_tol": gravity_tol, "min_turn_end": min_turn_end, "turn_tol_deg": turn_tol,
             "face_tilt": None if face_tilt is None else units.to_si(face_tilt, "deg"),
             "turn_closure": None if turn_closure is None else units.to_si(turn_closure, "deg")}
    return {k: float(v) for k, v in given.items() if v is not None}


def register(app: typer.Typer) -> None:
    @app.command()
    def calibrate(
        data: Path = typer.Argument(..., help="HDF5 record (inscal simulate, or a recorded run)"),
        method: str = typer.Option(..., "--method", "-m",
                                   help="six-position | twelve-position | n25 | joint | systematic51 | systematic30 | "
                                        "unified | thermal-plateaus (a turntable record) | multi-position | ferraris "
                                        "(no turntable: still poses at unknown orientations; six faces and three "
                                        "whole turns)"),
        out: Path = typer.Option(..., "--out", "-o", help="parameter file to write (TOML)"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing parameter file"),
        settle: float = typer.Option(None, "--settle-s", help="settling time dropped at both ends of each window [s] "
                                     "(default 1; multi-position, ferraris: 0.25)"),
        min_static: float = typer.Option(None, "--min-static-s", help="shortest static window used [s] (default 20; "
                                         "multi-position: 1; ferraris: 2)"),
        quadratic: bool = typer.Option(False, "--quadratic", help="multi-position: estimate the quadratic "
                                       "accelerometer terms too (12 parameters: at least 12 poses, and more for the fit to have "
                                       "accelerometer degrees of freedom)"),
        # the no-turntable methods' options (None: the method's own default)
        alpha: float = typer.Option(None, "--alpha", help="multi-position, ferraris: false-alarm probability of "
                                    "the still-pose tests (default 1e-3; ferraris 1e-4)"),
        gravity_tol: float = typer.Option(None, "--gravity-tol", help="multi-position, ferraris: the largest "
                                          "relative difference between the poses' specific force and the site's "
                                          "gravity (default 0.15; ferraris 0.1)"),
        face_tilt: float = typer.Option(None, "--face-tilt-deg", help="ferraris: rms angle in deg between a face and "
                                        "the horizontal when it rests on a table (flatness, squareness, the table's "
                                        "level; in the sigma) (default 0.3; 0: exact faces)"),
        min_turn_end: float = typer.Option(None, "--min-turn-end-s", help="ferraris: shortest still pose in s at "
                                           "the ends of a turn, after --settle-s at both ends (default 0.3)"),
        turn_tol: float = typer.Option(None, "--turn-tol-deg", help="ferraris: how far from 360 deg a whole turn "
                                       "may be, in deg (default 30)"),
        turn_closure: float = typer.Option(None, "--turn-closure-deg", help="ferraris: rms difference in deg between "
                                           "a whole turn's angle and 360 deg (a turn by hand against a stop; in the "
                                           "sigma) (default 0.2; 0: exact turns)"),
        tremor_dps: float = typer.Option(None, "--tremor-dps", help="multi-position: the hand tremor a still pose "
                                         "may hold [deg/s rms] (default 3; the accelerometers judge a pose, the gyros "
                                         "may tremble up to this)"),
        states: str = typer.Option(None, "--states", help="systematic: auto (the default: async, lever9, g-sensitivity "
                                   "off-diagonals and cross-coupling chosen by F-tests on the innovations) | 51 | 30, "
                                   "plus options lever9, async, psins, gimbal, gdiag, nocross, auto (e.g. 51,lever9 or "
                                   "auto,psins), and thermal: the thermal coefficients as states, the record's /temperature a known "
                                   "input, T_ref 20 degC (thermal: orders 2,2,3,2 and the dT/dt term; thermal=GSABR: orders "
                                   "of gyro bias, gyro scale factor, accel bias, accel scale factor 0-3 and the dT/dt term "
                                   "0-1, e.g. 51,thermal=11110); unified: extra options (e.g. lever9, auto)"),
        plots: Path = typer.Option(None, "--plots", help="systematic: folder for the convergence plots (PNG)"),
        filter_rate: float = typer.Option(1.0, "--filter-rate-hz", help="systematic: filter update rate [Hz]"),
        arw: float = typer.Option(None, "--arw", help="systematic: gyro white noise [deg/sqrt(h)] (default: from the data)"),
        vrw: float = typer.Option(None, "--vrw", help="systematic: accelerometer white noise [ug/sqrt(Hz)] (default: from the data)"),
        gravity: str = typer.Option(None, "--gravity", help="gravity model: wgs84 | psins | a measured value in m/s^2 "
                                    "(default: the record's)"),
        encoder_sigma: float = typer.Option(None, "--encoder-sigma", help="unified / gimbal states: white noise of "
                                            "each encoder angle [arcsec] (default 1)"),
        encoder_latency: float = typer.Option(0.0, "--encoder-latency", help="shift the encoder angles by this many "
                                              "seconds before calibrating (> 0: encoders that lag the IMU)"),
        skip_encoder_check: bool = typer.Option(False, "--skip-encoder-check", help="calibrate even when the encoder "
                                                "angles do not follow the gyros"),
        serial: str = typer.Option(None, "--serial", help="record the result in the calibration database as a "
                                   "calibration of this unit (registered with inscal db add)"),
        db: str = typer.Option(None, "--db", help="with --serial: the calibration database, a file (SQLite) or "
                               "postgresql://USER@HOST/NAME (default: $INSCAL_DB, else calib.sqlite)"),
        station: str = typer.Option(None, "--station", help="the turntable / station of the run: its name (with "
                                    "--serial), or a station description FILE.toml (n25, six-position, twelve-position, "
                                    "joint, systematic51, systematic30, multi-position, ferraris): the GUM "
                                    "uncertainty budget is computed, printed and, with --serial, stored with the result"),
        operator: str = typer.Option(None, "--operator", help="with --serial: who ran it"),
        date: str = typer.Option(None, "--date", help="with --serial: when the record was taken, YYYY-MM-DD or ISO "
                                 "time (UTC; default: the record's creation time)"),
        temperature_c: float = typer.Option(None, "--temperature-c", help="with --serial: the IMU's temperature "
                                            "during the run [deg C] (with --station FILE.toml also without --serial: "
                                            "where the budget's temperature slope is taken)"),
        supersedes: int = typer.Option(None, "--supersedes", help="with --serial: id of an earlier result this one "
                                       "replaces (e.g. the same record calibrated again)"),
        per_plateau: str = typer.Option(None, "--per-plateau", help="thermal-plateaus: the method run on each "
                                        "temperature plateau (default n25; any other method)"),
        thermal_order: list[str] = typer.Option(None, "--thermal-order", help="thermal-plateaus: NAME=ORDER, the "
                                                "polynomial order of a thermal term in T - T_ref (repeatable; default "
                                                "gyro_bias, gyro_scale_factor, accel_bias, accel_scale_factor = 2, "
                                                "misalignments 0 = constant, at most 1; an order not named is "
                                                "raised while its fit misfits the plateaus)"),
        t_ref: float = typer.Option(None, "--t-ref", help="thermal-plateaus: reference temperature of the model "
                                    "[deg C] (default 20; inside the plateaus' range)"),
        plateau_tol: float = typer.Option(0.5, "--plateau-tol", help="thermal-plateaus: a plateau's readings stay "
                                          "within this of their mean [deg C]"),
        temperature_sensor: str = typer.Option("", "--temperature-sensor", help="thermal-plateaus: the temperature "
                                               "sensor (default: the mean of the record's sensors)"),
        chamber_label: str = typer.Option("chamber", "--chamber-label", help="thermal-plateaus: label prefix of the "
                                          "path's chamber transitions (the plateaus are cut there; without them they "
                                          "are found in the temperature)"),
        wait: float = typer.Option(None, "--wait", help="with --serial: seconds to wait for another writer of the "
                                   "database (default: refused after 2 s, naming it)"),
        accept_unconverged: bool = typer.Option(False, "--accept-unconverged", help="systematic: keep the last "
                                                "iterate of a run that does not converge (a note in the text, the JSON "
                                                "and the parameter file) instead of ending with exit 2"),
        noise: Path = typer.Option(None, "--noise", help="systematic: an identified noise model (noise.toml of inscal "
                                   "noise): its white terms weight the filter, its Gauss-Markov terms become bias "
                                   "states"),
        mc: int = typer.Option(None, "--mc", help="with --station and a window-mean method: the budget's JCGM 101 "
                               "Monte Carlo, at most N trials (adaptive: it stops when every component's linear "
                               "interval is validated or not; e.g. 10000)"),
        mc_seed: int = typer.Option(0, "--mc-seed", help="seed of the Monte Carlo"),
        mc_workers: int = typer.Option(1, "--mc-workers", help="Dask workers of the Monte Carlo (1: this process)"),
        thermal_model: Path = typer.Option(None, "--thermal-model", help="with --station FILE.toml: a parameter "
                                           "file with a thermal model ([thermal], from thermal-plateaus or thermal "
                                           "states) whose slope dy/dT propagates the chamber's temperature stability "
                                           "(default: the unit's newest result in the database that has one)"),
        json_: bool = typer.Option(False, "--json", help="print the parameters as JSON"),
    ):
        """Calibrate IMU errors (and gimbal non-orthogonality / mounting attitude) from a record."""
        try:
            rep = run_calibrate(data, method, out, force, settle, min_static, states, plots, filter_rate, arw, vrw,
                                gravity, encoder_sigma, encoder_latency, not skip_encoder_check, db, serial, station,
                                operator, date, temperature_c, supersedes, per_plateau, thermal_order, t_ref,
                                plateau_tol, temperature_sensor, chamber_label, wait, accept_unconverged, quadratic,
                                noise, thermal_model, mc, mc_seed, mc_workers,
                                _method_options(alpha, gravity_tol, face_tilt, min_turn_end, turn_tol, turn_closure),
                                tremor_dps)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json({k: v for k, v in rep.items() if k not in ("out", "notes")} | {"notes": rep["notes"]})
            return
        typer.echo(f"{rep['method']}: parameters -> {rep['out']}")
        for name, e in rep["parameters"].items():
            line = f"  {name:24s} {_fmt(e['value'])} +- {_fmt(e['sigma'])} {e['unit']}"
            if "sigma_formal" in e:
                line += f" (formal +- {_fmt(e['sigma_formal'])})"
            if "error" in e:
                line += f"   (error {_fmt(e['error'])})"
            typer.echo(line)
        if "thermal" in rep:
            for line in thermal_lines(rep["thermal"]):
                typer.echo(line)
        if "encoders" in rep:
            e = rep["encoders"]
            lat = "" if e["latency_s"] is None else f", latency {e['latency_s'] * 1e3:.3g} ms"
            typer.echo(f"  encoders: agree with the gyros on {e['moves']} moves{lat}")
        if "fit" in rep:
            for line in fit_lines(rep["fit"]):
                typer.echo(line)
        for c in rep.get("still", []):
            if not c["kept"]:
                typer.echo(f"  pose {c['pose']} ({c['t0_s']:.1f}-{c['t1_s']:.1f} s): rejected, {c['reason']}")
        if "selection" in rep:
            sel = rep["selection"]
            typer.echo(f"  states: {sel['chosen']} (chosen from the data, {sel['fits']} fits; full model {sel['full']})")
            for t in sel["tests"]:
                verb = ("added" if t["accepted"] else "not needed") if t["step"] == "add" else \
                    ("dropped" if t["accepted"] else "kept")
                if t.get("status", "tested") != "tested":
                    typer.echo(f"    {t['term']:8s} {verb:10s} not compared: {t['status']}")
                    continue
                typer.echo(f"    {t['term']:8s} {verb:10s} statistic {t['statistic']:.4g} on {t['dk']} dof "
                           f"(dispersion {t['dispersion']:.3g}), p = {t['p_value']:.3g}")
        if "innovations" in rep:
            inn = rep["innovations"]
            typer.echo(f"  filter: NIS mean {inn['nis_mean']:.3f} (expected {inn.get('nis_expected', 6.0):.3f}); "
                       f"{len(rep['passes'])} passes"
                       + ("" if rep["converged"] else " (not converged)"))
        for p in rep.get("plots", []):
            typer.echo(f"  plot: {p}")
        for n in rep["notes"]:
            typer.echo(f"  note: {n}")
        if "budget" in rep:
            from inscal.report.budget import budget_lines

            for line in budget_lines(rep["budget"], full=False):
                typer.echo("  " + line)
        if "db" in rep:
            r = rep["db"]
            typer.echo(f"  recorded in {r['db']}: {r['serial']} result {r['result_id']}"
                       + (", now the current calibration" if r["current"] else ""))
