"""``inscal db``: the calibration database (init, upgrade, recover, add, list, show, export, history, certificate).
What the commands do apart from their options and printing is in :mod:`inscal.cli.db_run`."""

from __future__ import annotations


import typer

from inscal.cli.common import CliError, check_output, fail, print_json
from inscal.cli.db_run import (
    AddOptions,
    CertificateOptions,
    db_errors,
    open_db,
    pick_calibration,
    run_add,
    run_certificate,
    run_history,
)
from inscal.cli.guards import check_not_database
from inscal.cli.options import (
    DbOption,
    ForceOption,
    Group,
    JsonOption,
    KOption,
    ResultOption,
    SerialArgument,
    WaitOption,
    options_of,
    out_option,
    plot_option,
    with_options,
)

db_app = typer.Typer(no_args_is_help=True, add_completion=False, cls=Group,
                     help="The calibration database: units, sessions and results over time (SQLite file or "
                          "PostgreSQL URL; --db, else $INSCAL_DB, else calib.sqlite here).")


def register(app: typer.Typer) -> None:
    app.add_typer(db_app, name="db")


@db_app.command("init")
def init_cmd(db: DbOption = None,
             json_: JsonOption = False):
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
def upgrade_cmd(db: DbOption = None,
                json_: JsonOption = False):
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
def recover_cmd(db: DbOption = None,
                wait: WaitOption = None,
                json_: JsonOption = False):
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


def _command(name: str, options_class, run):
    """``inscal db NAME``: its options the fields of ``options_class`` (:func:`inscal.cli.options.with_options`), its
    work ``run(options)`` (:mod:`inscal.cli.db_run`; a refusal is one line), ``--json`` the report; the decorated
    function (its docstring the command's help) prints the report's text lines, given the options."""
    def decorate(text):
        def command(json_: JsonOption = False, **options):
            with db_errors():
                rep = run(options_of(options_class, options))
            if json_:
                print_json(rep)
                return
            text(rep, options)

        command.__name__, command.__doc__ = text.__name__, text.__doc__
        return db_app.command(name)(with_options(options_class, before="json_")(command))
    return decorate


@_command("add", AddOptions, run_add)
def add_cmd(rep: dict, options: dict) -> None:
    """Register a unit (SERIAL --model ...), or record a parameter file as one of its calibrations."""
    if "unit" in rep:
        u = rep["unit"]
        typer.echo(f"unit {u['serial']} {'registered' if rep['created'] else 'is registered already'}"
                   + (f" (model {u['model']})" if u["model"] else "") + f" in {rep['db']}")
    else:
        typer.echo(f"{rep['serial']}: {options['params']} recorded as result {rep['result_id']} ({rep['method']}, "
                   f"{rep['date']})" + (", now the current calibration" if rep["current"] else ""))


@db_app.command("list")
def list_cmd(db: DbOption = None,
             flagged: bool = typer.Option(False, "--flagged", help="only the units whose history raises a flag"),
             k: KOption = 3.0,
             json_: JsonOption = False):
    """The units (the fleet view): results, current calibration and flags of each."""
    with db_errors():
        from inscal import lab

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
def show_cmd(serial: SerialArgument,
             db: DbOption = None,
             result: ResultOption = None,
             covariance: bool = typer.Option(False, "--covariance", help="print the covariance matrix too"),
             json_: JsonOption = False):
    """One calibration of a unit with every parameter, 1 sigma, fit, covariance and provenance."""
    with db_errors():
        with open_db(db, readonly=True) as d:
            cal = pick_calibration(d, serial, result)
    if json_:
        print_json(cal.to_json() | {"db": d.where})
        return
    from inscal.report.text import show_lines

    for line in show_lines(cal, covariance):
        typer.echo(line)


@db_app.command("budget")
def budget_cmd(serial: SerialArgument,
               db: DbOption = None,
               result: ResultOption = None,
               json_: JsonOption = False):
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
def export_cmd(serial: SerialArgument,
               out: out_option("parameter file to write (TOML)"),
               db: DbOption = None,
               result: ResultOption = None,
               force: ForceOption = False,
               json_: JsonOption = False):
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
def history_cmd(serial: SerialArgument,
                db: DbOption = None,
                method: str = typer.Option(None, "--method", "-m", metavar="METHOD", help="calibration method (default: the current "
                                           "calibration's)"),
                k: KOption = 3.0,
                plot: plot_option("figure of every parameter over time (.png, .pdf, .svg)") = None,
                force: ForceOption = False,
                json_: JsonOption = False):
    """Every parameter of a unit over time: repeatability, drift rate per month +- 1 sigma, flags."""
    with db_errors():
        rep, h = run_history(serial, db, method, k, plot, force)
    if json_:
        print_json(rep)
        return
    from inscal.report.text import history_lines

    for line in history_lines(rep, h):
        typer.echo(line)


@_command("certificate", CertificateOptions, run_certificate)
def certificate_cmd(rep: dict, options: dict) -> None:
    """A calibration certificate (ISO/IEC 17025 §7.8): HTML, PDF and the same content as JSON, written together."""
    files = ", ".join(f for f in (rep["html"], rep["pdf"] and f"{rep['pdf']} ({rep['pages']} pages)", rep["json"]) if f)
    typer.echo(f"{options['serial']}: certificate {rep['certificate']} (result {rep['result_id']}, {rep['method']}, record of "
               f"{rep['date'][:10]}) -> {files}")
