"""The outputs of ``inscal calibrate``: the calibration database that ``--serial`` records in, opened and checked
before the calibration runs (:func:`open_lab`), then the parameter file, the convergence plots and the database
row, written inside the command's output unit so that they are published together, or none of them."""

from __future__ import annotations

import math
from pathlib import Path

from inscal.cli.common import CliError, normal_serial
from inscal.cli.guards import database_notes


def open_lab(db, serial, station, operator, date, temperature_c, supersedes, data: Path,
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


def write_outputs(data: Path, out: Path, force: bool, plots: Path | None, res, rec, meta: dict, enc_report,
                   systematic: bool, lab_db: dict | None = None) -> dict:
    """Write the parameter file and the plots of :func:`inscal.cli.calibrate.run_calibrate` (inside its output unit), and record
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
        stage(lab_db, data, rec, res, text)
    return report


def stage(lab_db: dict, data: Path, rec, res, text: str) -> None:
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


def recorded(lab_db: dict) -> dict:
    """The ``db`` entry of the report: the result as staged (committed when the command's outputs are published)."""
    from inscal.lab.model import iso

    v = lab_db["staged"].value
    return {"db": lab_db["db"].where, "serial": lab_db["serial"], "result_id": v["result_id"], "current": v["current"],
            "date": iso(v["date"])}
