"""``inscal compensate``: apply a calibration parameter file to a record.

The increments are compensated with the S16 form (``ImuErrors.compensate_increments``:
``M^-1 (N - bias)``, g-sensitivity, and the fixed-point iteration of the nonlinear
terms) chunk by chunk, so multi-day records are never held in memory twice.  The
output is a record of the same layout without truth; the parameter file's hash and
method are kept in its ``compensated_with`` attribute.

Thermal model: when the parameter file has a ``[thermal]`` table, each sample is first mapped to the
model's reference temperature at the record's /temperature (the model's sensor, interpolated to the
middle of each sample interval; :class:`inscal.nav.stream.ThermalCompensation`), then compensated as
above.  A record without /temperature is refused unless ``--temperature DEGC`` gives a constant one;
samples outside the calibrated range follow the model's ``out_of_range`` (warn: one warning line;
clamp: the model evaluated at the range ends, one warning line; error: refused).  The compensated
record keeps the /temperature readings, and ``compensated_with`` says which thermal model was applied.

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

from inscal.cli.common import (CliError, call, check_not_input, check_output, load_checked_params, print_json, record_errors, short,
    thermal_compensation, warn)
from inscal.cli.options import JsonOption


def run_compensate(data: Path, params: Path, out: Path, force: bool = False, warn=None,
                   temperature: float | None = None) -> dict:
    """Compensate ``data`` with ``params`` into ``out``.  Refuses an already compensated
    record unless ``force``; ``warn(line)`` is called at once for each provenance (and thermal
    range) warning (they are also in the result's ``warnings``).  ``temperature``: a constant
    temperature [degC] for the parameter file's thermal model (see :func:`inscal.cli.common.thermal_compensation`)."""
    from inscal import io
    from inscal.core.thermal import ThermalError
    from inscal.io.paramfile import ParamFileError

    check_output(out, force)
    check_not_input(out, data, params)
    imu, gimbal, meta = load_checked_params(params)
    with record_errors(data, ParamFileError):
        info = io.record_info(data)
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
    comp, survey, twarn = thermal_compensation(data, params, meta, info, imu, temperature)
    warnings += twarn
    for w in warnings if warn is not None else ():
        warn(w)
    dt = 1.0 / info.rate_hz

    def chunks():
        from inscal.nav.stream import compensated_chunks, thermal_chunks

        src = io.iter_chunks(data)
        if comp is not None:  # to the thermal model's T_ref first, then the base errors
            src = thermal_chunks(src, comp)
        yield from compensated_chunks(src, imu, dt)

    used = {"file": str(params), "hash": io.file_hash(params), "method": meta.get("method", ""), "source": str(data)}
    thermal = None
    if comp is not None:
        thermal = {**comp.summary(), **{k: survey[k] for k in ("samples", "samples_outside", "seen_c")}}
        used["thermal"] = thermal
    attrs = {"compensated_with": json.dumps(used)}
    try:
        # the compensated record has no truth: its residual errors are not the simulated ones
        n = io.write_stream(out, replace(info, truth=None), chunks(), overwrite=force, extra_attrs=attrs)
    except (io.DataFileError, FileExistsError, FileNotFoundError) as exc:
        raise CliError(str(exc)) from None
    except ThermalError as exc:  # a thermal refusal met while streaming: nothing was written
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
    return {"data": str(data), "params": str(params), "method": meta.get("method", ""), "out": str(out), "samples": n,
            "thermal": thermal, "warnings": warnings}


def register(app: typer.Typer) -> None:
    @app.command()
    def compensate(
        data: Path = typer.Argument(..., help="HDF5 record to compensate"),
        params: Path = typer.Option(..., "--params", "-p", metavar="PARAMS.toml", help="calibration parameter file (TOML, from inscal calibrate)"),
        out: Path = typer.Option(..., "--out", "-o", help="compensated HDF5 record"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing output; compensate an already "
                                   "compensated record anyway"),
        temperature: float = typer.Option(None, "--temperature", metavar="DEGC", help="constant temperature in degC for the parameter "
                                          "file's thermal model (a record without /temperature; in place of the "
                                          "record's readings otherwise)"),
        json_: JsonOption = False,
    ):
        """Compensate a record's increments with a calibration parameter file (and its thermal model, at the
        record's temperature)."""
        res = call(run_compensate, data, params, out, force, warn=warn,
                             temperature=temperature)
        if json_:
            print_json(res)
        else:
            th = res["thermal"]
            extra = f", thermal model at {th['temperature']}" if th is not None else ""
            typer.echo(f"compensated {res['samples']} samples with {res['params']} ({res['method']}{extra}) -> {res['out']}")
