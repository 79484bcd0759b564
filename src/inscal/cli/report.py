"""``inscal report``: an HTML report of a record, with parameter files compared."""

from __future__ import annotations

from pathlib import Path

import typer

from inscal.cli.common import (
    CliError,
    check_not_input,
    check_output,
    fail,
    print_json,
    short,
)


def run_report(data: Path, params: list[Path], out: Path, force: bool = False) -> dict:
    from inscal.io.paramfile import ParamFileError, load_params
    from inscal.report.record import record_report

    check_output(out, force)
    check_not_input(out, data, *params)
    from inscal import io

    try:
        sets = [(str(p), *load_params(p)) for p in params]
    except ParamFileError as exc:
        raise CliError(str(exc)) from None
    try:
        # the samples stay on disk: the report streams them (bounded memory for multi-day records)
        with io.open_record(data) as rec:
            res = record_report(out, rec, sets, overwrite=force)
    except io.DataFileError as exc:
        raise CliError(str(exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{short(data)}: not a valid inscal record ({type(exc).__name__}: {short(exc)})") from None
    except OSError as exc:
        raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
    res["out"] = str(out)
    return res


def register(app: typer.Typer) -> None:
    @app.command()
    def report(
        data: Path = typer.Argument(..., help="HDF5 record"),
        params: list[Path] = typer.Option([], "--params", "-p", help="parameter file(s) to tabulate (repeatable)"),
        out: Path = typer.Option(..., "--out", "-o", help="HTML report to write"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing report"),
        json_: bool = typer.Option(False, "--json", help="print a JSON summary"),
    ):
        """Write an HTML report: gimbal motion, sensor outputs, Allan deviation, parameters vs truth."""
        try:
            res = run_report(data, params, out, force)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
        else:
            typer.echo(f"report written to {res['out']}")
