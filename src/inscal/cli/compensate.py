"""``inscal compensate``: apply a calibration parameter file to a record.

The increments are compensated with the S16 form (``ImuErrors.compensate_increments``:
``M^-1 (N - bias)``, g-sensitivity, and the fixed-point iteration of the nonlinear
terms) chunk by chunk, so multi-day records are never held in memory twice.  The
output is a record of the same layout without truth; the parameter file's hash and
method are kept in its ``compensated_with`` attribute.

Provenance: one warning line (stderr) when the parameter file's ``data_hash``,
``metadata.scenario`` or ``metadata.imu_serial`` differ from the record's (each compared
only when both sides have it); a record that was already compensated (its
``compensated_with`` attribute is set) is refused unless ``--force``.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import typer

from inscal.cli.common import (
    CliError,
    check_not_input,
    check_output,
    fail,
    load_checked_params,
    print_json,
    short,
)


def run_compensate(data: Path, params: Path, out: Path, force: bool = False, warn=None) -> dict:
    """Compensate ``data`` with ``params`` into ``out``.  Refuses an already compensated
    record unless ``force``; ``warn(line)`` is called at once for each provenance warning
    (they are also in the result's ``warnings``)."""
    from inscal import io
    from inscal.io.paramfile import ParamFileError

    check_output(out, force)
    check_not_input(out, data, params)
    imu, gimbal, meta = load_checked_params(params)
    try:
        info = io.record_info(data)
    except (ParamFileError, io.DataFileError) as exc:
        raise CliError(str(exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{short(data)}: not a valid inscal record ({type(exc).__name__}: {short(exc)})") from None
    if info.n_samples < 2:
        raise CliError(f"{short(data)}: {info.n_samples} sample(s); nothing to compensate")
    from inscal.io.paramfile import provenance_mismatch
    from inscal.io.records import compensated_with, record_attrs

    attrs = record_attrs(data)
    warnings = []
    done = compensated_with(attrs)
    if done is not None:
        if not force:
            raise CliError(f"{data} is already compensated (with {done}); compensating it again would apply the "
                           "correction twice; use --force to do it anyway")
        warnings.append(f"{data} is already compensated (with {done}): compensating it a second time (--force)")
    mismatch = provenance_mismatch(data, params, meta, attrs)
    if mismatch:
        warnings.append(mismatch)
    for w in warnings:
        if warn is not None:
            warn(w)
    dt = 1.0 / info.rate_hz

    def chunks():
        from inscal.nav.stream import compensated_chunks

        yield from compensated_chunks(io.iter_chunks(data), imu, dt)

    attrs = {"compensated_with": json.dumps({"file": str(params), "hash": io.file_hash(params),
                                             "method": meta.get("method", ""), "source": str(data)})}
    try:
        # the compensated record has no truth: its residual errors are not the simulated ones
        n = io.write_stream(out, replace(info, truth=None), chunks(), overwrite=force, extra_attrs=attrs)
    except (io.DataFileError, FileExistsError, FileNotFoundError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
    return {"data": str(data), "params": str(params), "method": meta.get("method", ""), "out": str(out), "samples": n,
            "warnings": warnings}


def register(app: typer.Typer) -> None:
    @app.command()
    def compensate(
        data: Path = typer.Argument(..., help="HDF5 record to compensate"),
        params: Path = typer.Option(..., "--params", "-p", help="calibration parameter file (TOML, from inscal calibrate)"),
        out: Path = typer.Option(..., "--out", "-o", help="compensated HDF5 record"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing output; compensate an already "
                                   "compensated record anyway"),
        json_: bool = typer.Option(False, "--json", help="print a JSON summary"),
    ):
        """Compensate a record's increments with a calibration parameter file."""
        try:
            res = run_compensate(data, params, out, force, warn=lambda w: typer.echo(f"inscal: warning: {w}", err=True))
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
        else:
            typer.echo(f"compensated {res['samples']} samples with {res['params']} ({res['method']}) -> {res['out']}")
