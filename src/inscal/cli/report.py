"""``inscal report``: an HTML report of a record, with parameter files compared (and, for a record with
/temperature or a parameter file with a thermal model, the temperature and the thermal curves)."""

from __future__ import annotations

from pathlib import Path

import typer

from inscal.cli.common import (CliError, call, check_not_input, check_output, load_checked_params, print_json, short,
    warn)
from inscal.cli.options import ForceOption, JsonOption


#: samples of the first dwell below which :func:`inscal.report.record.record_report` leaves out the noise section
NOISE_MIN_SAMPLES = 2000


def run_report(data: Path, params: list[Path], out: Path, force: bool = False, warn=None,
               noise: list[Path] | None = None) -> dict:
    """Write the report; ``warn(line)`` is called at once for each provenance warning (a parameter file
    calibrated from another record, scenario or IMU serial: its errors against this record's truth
    mean nothing), also in the result's ``warnings``.  ``noise``: noise.toml files whose models the report
    shows (each read and checked before any work)."""
    from inscal.io.files import input_problem
    from inscal.io.paramfile import provenance_mismatch
    from inscal.report.record import record_report
    from inscal.report.thermal import PlateauError, params_plateaus

    check_output(out, force)
    check_not_input(out, data, *params, *(noise or []))
    if data.suffix == ".toml":  # a noise model (noise.toml of inscal noise): its own report
        if noise:
            raise CliError("--noise shows a noise model beside a record; a noise model's own report takes none")
        return _noise_model_report(data, params, out, force)
    from inscal import io
    from inscal.io.noisefile import NoiseFileError, model_from_document
    from inscal.io.tomlfile import read_toml

    models = []
    for p in noise or []:
        try:
            doc = read_toml(p, NoiseFileError, "noise model file")
            models.append((str(p), model_from_document(doc, short(p)), doc))
        except NoiseFileError as exc:
            raise CliError(str(exc)) from None

    sets = [(str(p), *load_checked_params(p)) for p in params]
    for p, _, _, meta in sets:
        try:
            params_plateaus(meta)
        except PlateauError as exc:
            raise CliError(f"{p}: thermal per-plateau points: {exc}") from None
    if (msg := input_problem(data, "file")) is not None:
        raise CliError(msg)
    warnings = [w for p, _, _, meta in sets if (w := provenance_mismatch(data, Path(p), meta)) is not None]
    for w in warnings:
        if warn is not None:
            warn(w)
    try:
        # the samples stay on disk: the report streams them (bounded memory for multi-day records)
        with io.open_record(data) as rec:
            res = record_report(out, rec, sets, overwrite=force, noise_models=models)
            if "arw_deg_rth" not in res:  # the noise section was left out: say why, in one line
                from inscal.analysis.allan import first_dwell

                first = first_dwell(rec.gimbal, rec.n_samples)
                w = (f"{short(data)}: no noise (Allan deviation) section: the first dwell has {first} samples "
                     f"({first / rec.rate_hz:.6g} s at {rec.rate_hz:g} Hz), it needs {NOISE_MIN_SAMPLES}")
                warnings.append(w)
                if warn is not None:
                    warn(w)
    except io.DataFileError as exc:
        raise CliError(str(exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{short(data)}: not a valid inscal record ({type(exc).__name__}: {short(exc)})") from None
    except OSError as exc:
        raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
    res["out"] = str(out)
    res["warnings"] = warnings
    return res


def _noise_model_report(data: Path, params: list[Path], out: Path, force: bool) -> dict:
    """The report of a noise.toml (:mod:`inscal.report.noise_model`); CliError (one line) for a file that is not
    one, or parameter files beside it."""
    from inscal.io.noisefile import NoiseFileError, model_from_document
    from inscal.io.tomlfile import read_toml
    from inscal.report.noise_model import noise_model_report

    if params:
        raise CliError("--params tabulates calibrations against a record; a noise model's report takes none")
    try:
        doc = read_toml(data, NoiseFileError, "noise model file")
        model = model_from_document(doc, str(data))
    except (NoiseFileError, OSError) as exc:
        raise CliError(str(exc)) from None
    try:
        res = noise_model_report(out, model, doc, str(data), overwrite=force)
    except OSError as exc:
        raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
    res["out"] = str(out)
    res["warnings"] = []
    return res


def register(app: typer.Typer) -> None:
    @app.command()
    def report(
        data: Path = typer.Argument(..., help="HDF5 record, or a noise model (noise.toml of inscal noise)"),
        params: list[Path] = typer.Option([], "--params", "-p", metavar="PARAMS.toml", help="parameter file(s) to tabulate (repeatable); "
                                          "a file with a thermal model also gets each thermal parameter's curve "
                                          "over its calibrated range with its 1-sigma band"),
        noise: list[Path] = typer.Option([], "--noise", metavar="NOISE.toml", help="noise model(s) from 'inscal noise --out' (noise.toml, "
                                         "repeatable): each process per channel in IEEE 952/1293 units with its 95 % "
                                         "interval and per-sample form, and the model's Allan deviation over the "
                                         "record's first dwell"),
        out: Path = typer.Option(..., "--out", "-o", help="HTML report to write"),
        force: ForceOption = False,
        json_: JsonOption = False,
    ):
        """Write an HTML report: gimbal motion, sensor outputs, temperature and dT/dt, Allan deviation,
        identified noise models, parameters vs truth, thermal parameters over temperature with their 1-sigma
        bands."""
        res = call(run_report, data, params, out, force, warn=warn,
                         noise=noise)
        if json_:
            print_json(res)
        else:
            typer.echo(f"report written to {res['out']}")
