"""What the ``inscal db`` commands do, apart from their options and printing: the database opened with its
refusals as one line, a unit registered or a parameter file recorded, a unit's history, a certificate."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.common import (
    CliError,
    check_output,
    fail,
    normal_serial,
    short,
)
from inscal.cli.guards import check_not_database, database_notes
from inscal.cli.options import (
    DateOption,
    DbOption,
    ForceOption,
    OperatorOption,
    ResultOption,
    SerialArgument,
    SupersedesOption,
    TemperatureCOption,
    WaitOption,
    option,
    out_option,
)

PLOT_FORMATS = ("png", "pdf", "svg")


@dataclass(frozen=True)
class AddOptions:
    """The options of ``inscal db add``: the unit ``serial``, and for a calibration its parameter file
    ``params`` with the session it was calibrated in."""

    serial: SerialArgument
    params: Annotated[Path | None, typer.Argument(help=(
        "a parameter file (inscal calibrate --out) to record as a calibration of the unit; without it, register "
        "the unit"))] = None
    db: DbOption = None
    model: option("--model", "the unit's model (when registering it)", str, "MODEL") = None
    notes: option("--notes", "notes on the unit (when registering it)", str, "TEXT") = None
    data: option("--data", "the record the parameter file was calibrated from (its hash must match; gives the site "
                 "and path)", Path, "RECORD") = None
    station: option("--station", "the turntable / station of the run", str, "STATION") = None
    operator: OperatorOption = None
    date: DateOption = None
    temperature_c: TemperatureCOption = None
    supersedes: SupersedesOption = None
    wait: WaitOption = None


@dataclass(frozen=True)
class CertificateOptions:
    """The options of ``inscal db certificate``: result ``result`` (None: the current one) of unit ``serial``
    certified into ``out``."""

    serial: SerialArgument
    out: out_option("a folder (made when missing) for INSCAL-SERIAL-ID.html/.pdf/.json, or NAME.html (also "
                    "NAME.pdf, NAME.json)")
    db: DbOption = None
    result: ResultOption = None
    pdf: Annotated[bool, typer.Option("--pdf/--no-pdf", help=(
        "also print the PDF with headless Chromium (chromium on PATH or $INSCAL_CHROMIUM; without it --pdf is "
        "refused)"))] = True
    issued: option("--issued", "date of issue, YYYY-MM-DD or ISO time (UTC; default: now)", str, "DATE") = None
    laboratory: option("--lab", "the laboratory's name and address", str, "TEXT") = None
    authorized_by: option("--authorized-by", "who authorizes the certificate", str, "NAME") = None
    force: ForceOption = False


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




def run_add(o: AddOptions) -> dict:
    """``inscal db add``: register a unit, or record an existing parameter file as one of its calibrations."""
    serial = normal_serial(o.serial)
    from inscal import lab
    from inscal.io.files import file_hash, input_problem

    if o.params is None:
        if any(x is not None for x in (o.data, o.station, o.operator, o.date, o.temperature_c, o.supersedes)):
            raise CliError("--data, --station, --operator, --date, --temperature-c and --supersedes describe a "
                           "calibration: give its parameter file (inscal db add SERIAL PARAMS.toml ...)")
        with open_db(o.db, create=True, wait=o.wait) as d:
            unit, created = lab.add_unit(d, serial, o.model, o.notes)
            return {"db": d.where, "unit": unit.to_json(), "created": created}
    from inscal.cli.common import load_checked_params

    if (msg := input_problem(o.params, "parameter file")) is not None:
        raise CliError(msg)
    _, _, meta = load_checked_params(o.params)
    try:
        text = o.params.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise CliError(f"{short(o.params)}: not UTF-8 text") from None
    when = lab.check_date(lab.parse_date(o.date), "--date") if o.date is not None else None
    if o.temperature_c is not None and not -100.0 < o.temperature_c < 200.0:
        raise CliError(f"--temperature-c {o.temperature_c}: not an IMU temperature in deg C")
    if o.data is not None:
        if (msg := input_problem(o.data, "data file")) is not None:
            raise CliError(msg)
        h = file_hash(o.data)
        if meta.get("data_hash") and meta["data_hash"] != h:
            raise CliError(f"{short(o.params)} was calibrated from another record ({meta.get('data_file') or 'data'} "
                           f"{str(meta['data_hash'])[:19]}...), not {short(o.data)} ({h[:19]}...)")
        from inscal.io import DataFileError

        try:
            session = lab.session_from_record(o.data, record_sha256=h, date=when, station=o.station, operator=o.operator,
                                              temperature_c=o.temperature_c)
        except (DataFileError, OSError, KeyError) as exc:
            raise CliError(f"{short(o.data)}: {exc}") from None
    else:
        if not meta.get("data_hash"):
            raise CliError(f"{short(o.params)} does not say which record it comes from (no data_hash): give --data RECORD")
        when = when or (lab.parse_date(meta["created"]) if meta.get("created") else None)
        if when is None:
            raise CliError(f"{short(o.params)} has no 'created' time: give --date")
        session = lab.SessionInfo(record_sha256=str(meta["data_hash"]), date=when, record_path=meta.get("data_file"),
                                  station=o.station, operator=o.operator, temperature_c=o.temperature_c,
                                  path_name=(meta.get("metadata") or {}).get("scenario"))
    pm = meta.get("metadata") or {}
    options = {"method": meta["method"], "recorded_from": "parameter file",
               **{k: pm[k] for k in ("states", "filter_rate_hz") if k in pm}}
    with open_db(o.db, wait=o.wait) as d:
        if lab.get_unit(d, serial) is None:
            raise CliError(f"unknown unit {serial!r}: register it first with `inscal db add {serial} --model MODEL`")
        dup = lab.find_param_file(d, serial, lab.text_hash(text))
        if dup is not None:
            raise CliError(f"{short(o.params)} is recorded already for {serial} as result {dup}")
        same = [c.id for c in lab.calibrations(d, serial, method=meta["method"])
                if c.session.record_sha256 == session.record_sha256]
        if same and o.supersedes is None:  # as calibrate --serial refuses the same record calibrated again
            raise CliError(f"{serial} has a {meta['method']} calibration of the same record already (result "
                           f"{same[-1]}): --supersedes {same[-1]} records {short(o.params)} in its place")
        rid = lab.record_calibration(d, serial, text, session, options=options, supersedes=o.supersedes,
                                     date_given=o.date is not None, new_file=True)
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


def run_certificate(o: CertificateOptions) -> dict:
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

    when = lab.check_date(lab.parse_date(o.issued), "--issued") if o.issued is not None else dt.datetime.now(dt.UTC)
    check_not_database(o.out, o.db)
    chromium = find_chromium() if o.pdf else None
    if o.pdf and chromium is None:
        raise CliError("the PDF is printed by headless Chromium, which is not installed (apt-get install chromium, "
                       f"or set {CHROMIUM_ENV} to its path); pass --no-pdf for the HTML and JSON only")
    with open_db(o.db, readonly=True) as d:
        cal = pick_calibration(d, o.serial, o.result)
        unit = lab.get_unit(d, o.serial)
        budget = lab.get_budget(d, cal.id)
    if utc_naive(when) < cal.date:
        raise CliError(f"--issued {utc_naive(when):%Y-%m-%d %H:%M} UTC lies before the calibration it certifies "
                       f"(result {cal.id}, record of {cal.date:%Y-%m-%d %H:%M} UTC): a certificate is issued after it")
    folder, make, paths = certificate_paths(o.out, file_stem(cal), o.pdf)
    stale = None if o.pdf else certificate_paths(o.out, file_stem(cal), True)[2][".pdf"]
    if stale is not None and stale.exists():  # it would sit beside the new HTML and JSON without matching them
        raise CliError(f"{short(stale)} exists from an earlier certificate and --no-pdf would not replace it: remove "
                       "it or choose another --out")
    if not make:
        for p in paths.values():
            check_not_database(p, o.db)
            check_output(p, o.force)
    doc = certificate_data(cal, unit, issued=when, laboratory=o.laboratory, authorized_by=o.authorized_by, budget=budget)
    page = certificate_html(doc)
    data = None
    if o.pdf:
        try:
            data = print_pdf(page, chromium)
        except CertificateError as exc:
            raise CliError(str(exc)) from None
    with output_unit():  # the three files: all published, or none
        if make:
            make_output_dir(folder)
        with atomic_path(paths[".html"], o.force) as tmp:
            tmp.write_text(page, encoding="utf-8")
        if data is not None:
            with atomic_path(paths[".pdf"], o.force) as tmp:
                tmp.write_bytes(data)
        with atomic_path(paths[".json"], o.force) as tmp:
            tmp.write_text(json.dumps(to_jsonable(doc), indent=2, ensure_ascii=False, allow_nan=False) + "\n",
                           encoding="utf-8")
    return {"db": d.where, "serial": o.serial, "result_id": cal.id, "certificate": doc["id"], "method": cal.method,
            "date": doc["calibration"]["date"], "issued": doc["issued"], "html": str(paths[".html"]),
            "pdf": str(paths[".pdf"]) if o.pdf else None, "pages": pdf_pages(data) if data is not None else None,
            "json": str(paths[".json"]), "fit_consistent": doc["fit"]["consistent"]}
