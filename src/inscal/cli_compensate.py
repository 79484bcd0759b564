"""``inscal compensate``: apply a calibration parameter file to a record.

The increments are compensated with the S16 form (``ImuErrors.compensate_increments``:
``M^-1 (N - bias)``, g-sensitivity, and the fixed-point iteration of the nonlinear
terms) chunk by chunk, so multi-day records are never held in memory twice.  The
output is a record of the same layout without truth; the parameter file's hash and
method are kept in its attributes.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import typer

from .cliutil import CliError, check_output, fail, print_json


def run_compensate(data: Path, params: Path, out: Path, force: bool = False) -> dict:
    from . import io
    from .paramfile import ParamFileError, load_params

    check_output(out, force)
    if out.resolve() == data.resolve():
        raise CliError("--out must differ from the input record")
    try:
        imu, gimbal, meta = load_params(params)
        info = io.record_info(data)
    except (ParamFileError, io.DataFileError) as exc:
        raise CliError(str(exc)) from None
    dt = 1.0 / info.rate_hz

    def chunks():
        from .navigation import compensated_chunks

        yield from compensated_chunks(io.iter_chunks(data), imu, dt)

    attrs = {"compensated_with": json.dumps({"file": str(params), "hash": io.file_hash(params),
                                             "method": meta.get("method", ""), "source": str(data)})}
    try:
        # the compensated record has no truth: its residual errors are not the simulated ones
        n = io.write_stream(out, replace(info, truth=None), chunks(), overwrite=force, extra_attrs=attrs)
    except (io.DataFileError, FileExistsError, FileNotFoundError) as exc:
        raise CliError(str(exc)) from None
    return {"data": str(data), "params": str(params), "method": meta.get("method", ""), "out": str(out), "samples": n}


def register(app: typer.Typer) -> None:
    @app.command()
    def compensate(
        data: Path = typer.Argument(..., help="HDF5 record to compensate"),
        params: Path = typer.Option(..., "--params", "-p", help="calibration parameter file (TOML, from inscal calibrate)"),
        out: Path = typer.Option(..., "--out", "-o", help="compensated HDF5 record"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing output"),
        json_: bool = typer.Option(False, "--json", help="print a JSON summary"),
    ):
        """Compensate a record's increments with a calibration parameter file."""
        try:
            res = run_compensate(data, params, out, force)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
        else:
            typer.echo(f"compensated {res['samples']} samples with {res['params']} ({res['method']}) -> {res['out']}")
