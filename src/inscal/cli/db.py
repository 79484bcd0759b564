"""``inscal db``: the calibration database (init, upgrade, recover, add, list, show, export, history, certificate)."""

from __future__ import annotations

import contextlib
from pathlib import Path

import typer

from inscal.cli.common import (
    CliError,
    check_output,
    fail,
    normal_serial,
    print_json,
    short,
)
from inscal.cli.guards import check_not_database, database_notes
from inscal.cli.options import Group

db_app = typer.Typer(no_args_is_help=True, add_completion=False, cls=Group,
                     help="The calibration database: units, sessions and results over time (SQLite file or "
                          "PostgreSQL URL; --db, else $INSCAL_DB, else calib.sqlite here).")

DB_HELP = "calibration database: a file (SQLite) or postgresql://USER@HOST/NAME (default: $INSCAL_DB, else calib.sqlite)"
PLOT_FORMATS = ("png", "pdf", "svg")


@contextlib.contextmanager
def db_errors():
    """Every refusal of the database, a parameter file or an option as one ``inscal: error:`` line (exit 2)."""
    import sqlalchemy

    from inscal.io.paramfile import ParamFileError
    from inscal.lab import DatabaseError

    try:
        yield
    except (CliError, DatabaseError, ParamFileError, ValueError) as exc:
        raise fail(str(exc)) from None
    except FileExistsError as exc:  # an output that appeared while the command ran
        raise fail(str(exc)) from None
    except sqlalchemy.exc.SQLAlchemyError as exc:
        orig = getattr(exc, "orig", None) or exc
        raise fail(f"database: {' '.join(str(orig).split())[:400]}") from None


def open_db(db: str | None, create: bool = False, readonly: bool = False, wait: float | None = None,
            notes: bool = True):
    """The calibration database of ``--db``; ``readonly`` for the commands that only read it (the file is then
    never written, and a read-only folder, file system or file is no obstacle); ``wait``: ``--wait SECONDS``;
    ``notes``: say on standard error what the opening recovered, or that files await it (:func:`database_notes`)."""
    from inscal.lab import open_database

    d = open_database(db, create=create, readonly=readonly, wait_s=wait)
    if notes:
        try:
            database_notes(d)
        except BaseException:
            d.close()
            raise
    return d


def _fmt(v) -> str:
    import numpy as np

    a = np.ravel(np.asarray(v, dtype=float))
    return "[" + ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a) + "]"


def _num(v, fmt: str = ".3g") -> str:
    """``v`` in ``fmt``, or ``-`` (right-aligned in the format's width) when not a finite number."""
    import math
    import re

    if v is None or not math.isfinite(v):
        width = re.match(r"[+ -]?(\d*)", fmt).group(1)
        return "-".rjust(int(width) if width else 1)
    return format(v, fmt)


def run_add(serial: str, params: Path | None, db: str | None, model: str | None, notes: str | None,
            data: Path | None, station: str | None, operator: str | None, date: str | None,
            temperature_c: float | None, supersedes: int | None, wait: float | None = None) -> dict:
    """``inscal db add``: register a unit, or record an existing parameter file as one of its calibrations."""
    serial = normal_serial(serial)
    from inscal import lab
    from inscal.io.files import file_hash, input_problem

    if params is None:
        if any(x is not None for x in (data, station, operator, date, temperature_c, supersedes)):
            raise CliError("--data, --station, --operator, --date, --temperature-c and --supersedes describe a "
                           "calibration: give its parameter file (inscal db add SERIAL PARAMS.toml ...)")
        with open_db(db, create=True, wait=wait) as d:
            unit, created = lab.add_unit(d, serial, model, notes)
            return {"db": d.where, "unit": unit.to_json(), "created": created}
    from inscal.cli.common import load_checked_params

    if (msg := input_problem(params, "parameter file")) is not None:
        raise CliError(msg)
    _, _, meta = load_checked_params(params)
    try:
        text = params.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise CliError(f"{short(params)}: not UTF-8 text") from None
    when = lab.check_date(lab.parse_date(date), "--date") if date is not None else None
    if temperature_c is not None and not -100.0 < temperature_c < 200.0:
        raise CliError(f"--temperature-c {temperature_c}: not an IMU temperature in deg C")
    if data is not None:
        if (msg := input_problem(data, "data file")) is not None:
            raise CliError(msg)
        h = file_hash(data)
        if meta.get("data_hash") and meta["data_hash"] != h:
            raise CliError(f"{short(params)} was calibrated from another record ({meta.get('data_file') or 'data'} "
                           f"{str(meta['data_hash'])[:19]}...), not {short(data)} ({h[:19]}...)")
        from inscal.io import DataFileError

        try:
            session = lab.session_from_record(data, record_sha256=h, date=when, station=station, operator=operator,
                                              temperature_c=temperature_c)
        except (DataFileError, OSError, KeyError) as exc:
            raise CliError(f"{short(data)}: {exc}") from None
    else:
        if not meta.get("data_hash"):
            raise CliError(f"{short(params)} does not say which record it comes from (no data_hash): give --data RECORD")
        when = when or (lab.parse_date(meta["created"]) if meta.get("created") else None)
        if when is None:
            raise CliError(f"{short(params)} has no 'created' time: give --date")
        session = lab.SessionInfo(record_sha256=str(meta["data_hash"]), date=when, record_path=meta.get("data_file"),
                                  station=station, operator=operator, temperature_c=temperature_c,
                                  path_name=(meta.get("metadata") or {}).get("scenario"))
    pm = meta.get("metadata") or {}
    options = {"method": meta["method"], "recorded_from": "parameter file",
               **{k: pm[k] for k in ("states", "filter_rate_hz") if k in pm}}
    with open_db(db, wait=wait) as d:
        if lab.get_unit(d, serial) is None:
            raise CliError(f"unknown unit {serial!r}: register it first with `inscal db add {serial} --model MODEL`")
        dup = lab.find_param_file(d, serial, lab.text_hash(text))
        if dup is not None:
            raise CliError(f"{short(params)} is recorded already for {serial} as result {dup}")
        same = [c.id for c in lab.calibrations(d, serial, method=meta["method"])
                if c.session.record_sha256 == session.record_sha256]
        if same and supersedes is None:  # as calibrate --serial refuses the same record calibrated again
            raise CliError(f"{serial} has a {meta['method']} calibration of the same record already (result "
                           f"{same[-1]}): --supersedes {same[-1]} records {short(params)} in its place")
        rid = lab.record_calibration(d, serial, text, session, options=options, supersedes=supersedes,
                                     date_given=date is not None, new_file=True)
        cal = lab.get_calibration(d, rid)
        return {"db": d.where, "serial": serial, "result_id": rid, "method": cal.method, "current": cal.current,
                "date": cal.to_json(False)["date"]}


def run_history(serial: str, db: str | None, method: str | None, k: float, plot: Path | None, force: bool):
    """``inscal db history``: ``(JSON report, History)``; the plot written when asked."""
    from inscal import lab

    if plot is not None:
        if plot.suffix.lower().lstrip(".") not in PLOT_FORMATS:
            raise CliError(f"--plot {short(plot)}: use a .png, .pdf or .svg name")
        check_not_database(plot, db, "--plot")
        check_output(plot, force)
    with open_db(db, readonly=True) as d:
        h = lab.unit_history(d, serial, method, k)
    rep = h.to_json() | {"db": d.where, "plot": None}
    if plot is not None:
        from inscal.io.files import output_unit
        from inscal.report.history import history_plot

        with output_unit():
            history_plot(plot, h, overwrite=force)
        rep["plot"] = str(plot)
    return rep, h


def pick_calibration(d, serial: str, result: int | None):
    """Result ``result`` of unit ``serial`` (default: its current calibration); a :class:`CliError` when the unit
    is unknown, has no calibration or the result is another unit's."""
    from inscal import lab

    if lab.get_unit(d, serial) is None:
        raise CliError(f"unknown unit {serial!r} in {d.where}")
    cal = lab.get_calibration(d, result) if result is not None else lab.current_calibration(d, serial)
    if cal is None:
        raise CliError(f"unit {serial} has no calibration yet")
    if cal.serial != serial:
        raise CliError(f"result {result} is a calibration of {cal.serial}, not {serial}")
    return cal


#: the files of a certificate (``--out NAME.html`` names them all)
CERT_SUFFIXES = (".html", ".pdf", ".json")


def certificate_paths(out: Path, stem: str, pdf: bool) -> tuple[Path, bool, dict[str, Path]]:
    """``(folder, whether to make it, {suffix: path})`` of ``--out``: a ``.html``/``.pdf``/``.json`` name gives
    the stem of the three files; anything else is a folder (made when missing) that gets ``STEM.*``."""
    if out.suffix.lower() in CERT_SUFFIXES:  # its folder must exist, as for every output file
        folder, base, make = out.parent, out.with_suffix(""), False
    else:
        if out.exists() and not out.is_dir():
            raise CliError(f"--out {short(out)}: not a folder; give a folder or a .html, .pdf or .json name")
        folder, base, make = out, out / stem, not out.exists()
        if make and not folder.parent.is_dir():
            raise CliError(f"folder {short(folder.parent)} does not exist")
    paths = {sfx: base.with_name(base.name + sfx) for sfx in CERT_SUFFIXES if pdf or sfx != ".pdf"}
    return folder, make, paths


def run_certificate(serial: str, out: Path, db: str | None, result: int | None, pdf: bool, force: bool,
                    issued: str | None, laboratory: str | None, authorized_by: str | None) -> dict:
    """``inscal db certificate``: the HTML, PDF and JSON of a calibration's certificate, published together."""
    import datetime as dt
    import json

    from inscal import lab
    from inscal.io.files import atomic_path, make_output_dir, output_unit
    from inscal.io.jsonfile import to_jsonable
    from inscal.lab.model import utc_naive
    from inscal.report.certificate import (
        CHROMIUM_ENV,
        CertificateError,
        certificate_data,
        certificate_html,
        file_stem,
        find_chromium,
        pdf_pages,
        print_pdf,
    )

    when = lab.check_date(lab.parse_date(issued), "--issued") if issued is not None else dt.datetime.now(dt.UTC)
    check_not_database(out, db)
    chromium = find_chromium() if pdf else None
    if pdf and chromium is None:
        raise CliError("the PDF is printed by headless Chromium, which is not installed (apt-get install chromium, "
                       f"or set {CHROMIUM_ENV} to its path); pass --no-pdf for the HTML and JSON only")
    with open_db(db, readonly=True) as d:
        cal = pick_calibration(d, serial, result)
        unit = lab.get_unit(d, serial)
        budget = lab.get_budget(d, cal.id)
    if utc_naive(when) < cal.date:
        raise CliError(f"--issued {utc_naive(when):%Y-%m-%d %H:%M} UTC lies before the calibration it certifies "
                       f"(result {cal.id}, record of {cal.date:%Y-%m-%d %H:%M} UTC): a certificate is issued after it")
    folder, make, paths = certificate_paths(out, file_stem(cal), pdf)
    stale = None if pdf else certificate_paths(out, file_stem(cal), True)[2][".pdf"]
    if stale is not None and stale.exists():  # it would sit beside the new HTML and JSON without matching them
        raise CliError(f"{short(stale)} exists from an earlier certificate and --no-pdf would not replace it: remove "
                       "it or choose another --out")
    if not make:
        for p in paths.values():
            check_not_database(p, db)
            check_output(p, force)
    doc = certificate_data(cal, unit, issued=when, laboratory=laboratory, authorized_by=authorized_by, budget=budget)
    page = certificate_html(doc)
    data = None
    if pdf:
        try:
            data = print_pdf(page, chromium)
        except CertificateError as exc:
            raise CliError(str(exc)) from None
    with output_unit():  # the three files: all published, or none
        if make:
            make_output_dir(folder)
        with atomic_path(paths[".html"], force) as tmp:
            tmp.write_text(page, encoding="utf-8")
        if data is not None:
            with atomic_path(paths[".pdf"], force) as tmp:
                tmp.write_bytes(data)
        with atomic_path(paths[".json"], force) as tmp:
            tmp.write_text(json.dumps(to_jsonable(doc), indent=2, ensure_ascii=False, allow_nan=False) + "\n",
                           encoding="utf-8")
    return {"db": d.where, "serial": serial, "result_id": cal.id, "certificate": doc["id"], "method": cal.method,
            "date": doc["calibration"]["date"], "issued": doc["issued"], "html": str(paths[".html"]),
            "pdf": str(paths[".pdf"]) if pdf else None, "pages": pdf_pages(data) if data is not None else None,
            "json": str(paths[".json"]), "fit_consistent": doc["fit"]["consistent"]}


def history_lines(rep: dict, h) -> list[str]:
    if not h.ids:
        return [f"{h.serial}: no {h.method} calibration"]
    from inscal.lab.drift import months_between

    span = months_between(h.dates[0], h.dates[-1])
    out = [(f"{h.serial} ({h.method}): {len(h.ids)} calibrations, {h.dates[0]:%Y-%m-%d} .. {h.dates[-1]:%Y-%m-%d} "
            f"({span:.3g} months); flags at k = {h.k:g}"),
           (f"  {'component':28s} {'n':>2s} {'mean':>10s} {'+-':>8s} {'spread/sigma':>12s} {'rate/month':>11s} "
            f"{'+-':>8s} {'z':>6s} {'step z':>7s}  flags")]
    for c in h.components:
        out.append(f"  {c.label:28s} {c.n:2d} {_num(c.mean, '10.4g')} {_num(c.mean_sigma, '8.2g')} "
                   f"{_num(c.repeatability_ratio, '12.3g')} {_num(c.rate, '+11.3g')} {_num(c.rate_sigma, '8.2g')} "
                   f"{_num(c.rate_z, '6.2f')} {_num(c.step_z, '7.2f')}  {','.join(c.flags) or '-'}  [{c.unit}]")
    flagged = h.flagged
    out.append(f"  {len(flagged)} flagged of {h.tests} tests ({h.expected_false_alarms:.2g} expected by chance at "
               f"k = {h.k:g})" + (": " + ", ".join(f"{c.label} ({'+'.join(c.flags)})" for c in flagged) if flagged
                                   else ""))
    if rep["plot"]:
        out.append(f"  plot -> {rep['plot']}")
    return out


def show_lines(cal, covariance: bool) -> list[str]:
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
    out.append(f"  fit: chi2 {_num(cal.fit_chi2, '.4g')} on {_num(cal.fit_dof, '.4g')} dof, p = {_num(cal.fit_p)}")
    out.append(f"  inscal {cal.inscal_version}; parameter file {cal.param_file_sha256[:19]}...; recorded "
               f"{cal.recorded_at:%Y-%m-%d %H:%M} UTC" + (f"; supersedes {cal.supersedes}" if cal.supersedes else ""))
    for name, p in cal.parameters.items():
        line = f"  {name:24s} {_fmt(p.value)} +- {_fmt(p.sigma)} {p.unit}"
        if p.sigma_formal is not None:
            line += f" (formal +- {_fmt(p.sigma_formal)})"
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


def register(app: typer.Typer) -> None:
    app.add_typer(db_app, name="db")


@db_app.command("init")
def init_cmd(db: str = typer.Option(None, "--db", help=DB_HELP),
             json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """Create the calibration database (a new SQLite file, or the tables of an empty PostgreSQL database)."""
    with db_errors():
        from inscal import lab

        d, created = lab.init_database(db)
        with d:
            rev = lab.revision_of(d)
            rep = {"db": d.where, "created": created, "revision": rev, "schema": lab.revision_number(rev)}
    if json_:
        print_json(rep)
        return
    typer.echo(f"{rep['db']}: {'created' if created else 'exists already'}, schema v{rep['schema']} ({rev})")


@db_app.command("upgrade")
def upgrade_cmd(db: str = typer.Option(None, "--db", help=DB_HELP),
                json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """Upgrade a database made by an older inscal to this inscal's schema (Alembic; every row kept)."""
    with db_errors():
        from inscal import lab

        old, new = lab.upgrade_database(db)
        with lab.open_database(db) as d:
            rep = {"db": d.where, "from": old, "to": new, "schema_from": lab.revision_number(old),
                   "schema_to": lab.revision_number(new), "rows": lab.table_counts(d)}
    if json_:
        print_json(rep)
        return
    if old == new:
        typer.echo(f"{rep['db']}: already at schema v{rep['schema_to']} ({new})")
    else:
        typer.echo(f"{rep['db']}: upgraded from schema v{rep['schema_from']} ({old}) to v{rep['schema_to']} ({new}); "
                   + ", ".join(f"{n} {t}" for t, n in rep["rows"].items()))


@db_app.command("recover")
def recover_cmd(db: str = typer.Option(None, "--db", help=DB_HELP),
                wait: float = typer.Option(None, "--wait", help="seconds to wait for another writer of the database "
                                           "(default: refused after 2 s, naming it)"),
                json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """Complete the publication of the files of results a killed command recorded but did not publish (any
    later write to the database does it too; read-only commands only say so)."""
    with db_errors():
        from inscal import lab

        with open_db(db, wait=wait, notes=False) as d:
            again = lab.recover_publications(d, strict=True)  # what the opening left (a writer held the lock)
            rep = {"db": d.where, "recovered": d.recovery.done + again.done, "waiting": again.waiting}
    if json_:
        print_json(rep)
        return
    for line in rep["recovered"]:
        typer.echo(f"completed: {line}")
    for line in rep["waiting"]:
        typer.echo(f"waiting: {line}")
    if not rep["recovered"] and not rep["waiting"]:
        typer.echo(f"{rep['db']}: every result's files are in place; nothing to recover")


@db_app.command("add")
def add_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
            params: Path = typer.Argument(None, help="a parameter file (inscal calibrate --out) to record as a "
                                                     "calibration of the unit; without it, register the unit"),
            db: str = typer.Option(None, "--db", help=DB_HELP),
            model: str = typer.Option(None, "--model", help="the unit's model (when registering it)"),
            notes: str = typer.Option(None, "--notes", help="notes on the unit (when registering it)"),
            data: Path = typer.Option(None, "--data", help="the record the parameter file was calibrated from "
                                      "(its hash must match; gives the site and path)"),
            station: str = typer.Option(None, "--station", help="the turntable / station of the run"),
            operator: str = typer.Option(None, "--operator", help="who ran it"),
            date: str = typer.Option(None, "--date", help="when the record was taken, YYYY-MM-DD or ISO time (UTC; "
                                     "default: the record's creation time, without --data the parameter file's)"),
            temperature_c: float = typer.Option(None, "--temperature-c", help="the IMU's temperature during the run [deg C]"),
            supersedes: int = typer.Option(None, "--supersedes", help="id of an earlier result this one replaces"),
            wait: float = typer.Option(None, "--wait", help="seconds to wait for another writer of the database "
                                       "(default: refused after 2 s, naming it)"),
            json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """Register a unit (SERIAL --model ...), or record a parameter file as one of its calibrations."""
    with db_errors():
        rep = run_add(serial, params, db, model, notes, data, station, operator, date, temperature_c, supersedes, wait)
    if json_:
        print_json(rep)
        return
    if "unit" in rep:
        u = rep["unit"]
        typer.echo(f"unit {u['serial']} {'registered' if rep['created'] else 'is registered already'}"
                   + (f" (model {u['model']})" if u["model"] else "") + f" in {rep['db']}")
    else:
        typer.echo(f"{rep['serial']}: {params} recorded as result {rep['result_id']} ({rep['method']}, {rep['date']})"
                   + (", now the current calibration" if rep["current"] else ""))


@db_app.command("list")
def list_cmd(db: str = typer.Option(None, "--db", help=DB_HELP),
             flagged: bool = typer.Option(False, "--flagged", help="only the units whose history raises a flag"),
             k: float = typer.Option(3.0, "--k", "-k", help="flag a parameter that moved more than k sigma"),
             json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """The units (the fleet view): results, current calibration and flags of each."""
    with db_errors():
        import math

        from inscal import lab

        if not (math.isfinite(k) and k > 0):
            raise CliError(f"--k must be > 0, got {k}")
        with open_db(db, readonly=True) as d:
            entries = lab.fleet(d, k, flagged_only=flagged)
            rep = {"db": d.where, "k": k, "units": [e.to_json() for e in entries]}
    if json_:
        print_json(rep)
        return
    if not entries:
        typer.echo(f"{rep['db']}: " + ("no unit raises a flag" if flagged else "no units"))
        return
    typer.echo(f"{'serial':20s} {'model':16s} {'results':>7s}  {'current':32s} flags (k = {k:g})")
    for e, j in zip(entries, rep["units"]):
        cur = "-" if e.current is None else f"{e.current.id} {e.current.method} {e.current.date:%Y-%m-%d}"
        fl = ", ".join(f"{f['label']} ({'+'.join(f['flags'])})" for f in j["flagged"]) or "none"
        typer.echo(f"{e.unit.serial:20s} {(e.unit.model or '-'):16s} {e.results:7d}  {cur:32s} {fl} "
                   f"[{j['tests']} tests, {j['expected_false_alarms']:.2g} expected by chance]")


@db_app.command("show")
def show_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
             db: str = typer.Option(None, "--db", help=DB_HELP),
             result: int = typer.Option(None, "--result", help="this result id (default: the current calibration)"),
             covariance: bool = typer.Option(False, "--covariance", help="print the covariance matrix too"),
             json_: bool = typer.Option(False, "--json", help="print the calibration as JSON")):
    """One calibration of a unit with every parameter, 1 sigma, fit, covariance and provenance."""
    with db_errors():
        with open_db(db, readonly=True) as d:
            cal = pick_calibration(d, serial, result)
    if json_:
        print_json(cal.to_json() | {"db": d.where})
        return
    for line in show_lines(cal, covariance):
        typer.echo(line)


@db_app.command("budget")
def budget_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
               db: str = typer.Option(None, "--db", help=DB_HELP),
               result: int = typer.Option(None, "--result", help="this result id (default: the current calibration)"),
               json_: bool = typer.Option(False, "--json", help="print the budget and its station as JSON")):
    """The GUM uncertainty budget stored with a calibration (``inscal calibrate --station FILE.toml``)."""
    from inscal import lab
    from inscal.report.budget import budget_lines

    with db_errors():
        with open_db(db, readonly=True) as d:
            cal = pick_calibration(d, serial, result)
            got = lab.get_budget(d, cal.id)
    if got is None:
        raise fail(f"result {cal.id} of {serial} was recorded without a station description: no uncertainty budget "
                   "(inscal calibrate ... --station FILE.toml --serial ... records one)")
    if json_:
        print_json(got | {"db": d.where, "serial": serial})
        return
    typer.echo(f"{serial} result {cal.id} ({cal.method}, {cal.date:%Y-%m-%d})")
    for line in budget_lines(got["budget"]):
        typer.echo(line)


@db_app.command("export")
def export_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
               out: Path = typer.Option(..., "--out", "-o", help="parameter file to write (TOML)"),
               db: str = typer.Option(None, "--db", help=DB_HELP),
               result: int = typer.Option(None, "--result", help="this result id (default: the current calibration)"),
               force: bool = typer.Option(False, "--force", help="overwrite an existing file"),
               json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """Write a unit's current parameter file (byte for byte the one its calibration wrote)."""
    with db_errors():
        from inscal import lab
        from inscal.io.files import atomic_path, output_unit

        check_not_database(out, db)
        check_output(out, force)
        with open_db(db, readonly=True) as d:
            cal = pick_calibration(d, serial, result)
        if lab.text_hash(cal.param_text) != cal.param_file_sha256:
            raise CliError(f"result {cal.id}: the stored parameter file does not match its sha256 (damaged database?)")
        with output_unit(), atomic_path(out, force) as tmp:
            tmp.write_text(cal.param_text, encoding="utf-8")
    rep = {"db": d.where, "serial": serial, "result_id": cal.id, "method": cal.method,
           "date": cal.to_json(False)["date"], "out": str(out), "param_file_sha256": cal.param_file_sha256}
    if json_:
        print_json(rep)
        return
    typer.echo(f"{serial}: result {cal.id} ({cal.method}, record of {cal.date:%Y-%m-%d}) -> {out}")


@db_app.command("history")
def history_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
                db: str = typer.Option(None, "--db", help=DB_HELP),
                method: str = typer.Option(None, "--method", "-m", help="calibration method (default: the current "
                                           "calibration's)"),
                k: float = typer.Option(3.0, "--k", "-k", help="flag a parameter that moved more than k sigma"),
                plot: Path = typer.Option(None, "--plot", help="figure of every parameter over time (.png, .pdf, .svg)"),
                force: bool = typer.Option(False, "--force", help="overwrite an existing plot"),
                json_: bool = typer.Option(False, "--json", help="print the history as JSON")):
    """Every parameter of a unit over time: repeatability, drift rate per month +- 1 sigma, flags."""
    with db_errors():
        import math

        if not (math.isfinite(k) and k > 0):
            raise CliError(f"--k must be > 0, got {k}")
        rep, h = run_history(serial, db, method, k, plot, force)
    if json_:
        print_json(rep)
        return
    for line in history_lines(rep, h):
        typer.echo(line)


@db_app.command("certificate")
def certificate_cmd(serial: str = typer.Argument(..., help="the unit's serial number"),
                    out: Path = typer.Option(..., "--out", "-o", help="a folder (made when missing) for "
                                             "INSCAL-SERIAL-ID.html/.pdf/.json, or NAME.html (also NAME.pdf, "
                                             "NAME.json)"),
                    db: str = typer.Option(None, "--db", help=DB_HELP),
                    result: int = typer.Option(None, "--result", help="this result id (default: the current "
                                               "calibration)"),
                    pdf: bool = typer.Option(True, "--pdf/--no-pdf", help="also print the PDF with headless Chromium "
                                             "(chromium on PATH or $INSCAL_CHROMIUM; without it --pdf is refused)"),
                    issued: str = typer.Option(None, "--issued", help="date of issue, YYYY-MM-DD or ISO time (UTC; "
                                               "default: now)"),
                    laboratory: str = typer.Option(None, "--lab", help="the laboratory's name and address"),
                    authorized_by: str = typer.Option(None, "--authorized-by", help="who authorizes the certificate"),
                    force: bool = typer.Option(False, "--force", help="overwrite existing certificate files"),
                    json_: bool = typer.Option(False, "--json", help="print the result as JSON")):
    """A calibration certificate (ISO/IEC 17025 §7.8): HTML, PDF and the same content as JSON, written together."""
    with db_errors():
        rep = run_certificate(serial, out, db, result, pdf, force, issued, laboratory, authorized_by)
    if json_:
        print_json(rep)
        return
    files = ", ".join(f for f in (rep["html"], rep["pdf"] and f"{rep['pdf']} ({rep['pages']} pages)", rep["json"]) if f)
    typer.echo(f"{serial}: certificate {rep['certificate']} (result {rep['result_id']}, {rep['method']}, record of "
               f"{rep['date'][:10]}) -> {files}")
