"""``inscal import`` and ``inscal export``: convert other tools' IMU files to a record and back.

``import`` converts once (PSINS ``.bin``/``.mat``, csv or whitespace text through a mapping
TOML), with the checks of :mod:`inscal.io.importers`; every other command reads the record.
``export`` writes a record as csv (17 significant digits), PSINS ``.bin`` (float64) or
``.mat``, so that export -> import gives back the same doubles; a record's temperature goes into
the csv's columns, and with ``--temperature-out`` to a file that ``import --temperature`` reads.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.common import CliError, call, check_not_input, check_output, fail, print_json, short
from inscal.cli.options import ForceOption, JsonOption, gravity_option, option, options_of, with_options
from inscal.io.formats import REGISTRY, export_formats, import_help, source_help


@dataclass(frozen=True)
class ImportOptions:
    """What ``inscal import`` is asked: convert ``src`` (in format ``fmt``, :data:`inscal.io.formats.REGISTRY`)
    into the record ``out`` (``force``: over an existing file), with the csv/txt column ``mapping``, the rotation
    ``path`` (starting at ``path_start`` [s] of the source's time) or the encoder angles ``gimbal`` (in
    ``gimbal_unit``: deg | rad), the site (``lat``, ``lon`` [deg], ``height`` [m]), the sample rate ``rate_hz``,
    psins' ``dtype``, .mat's ``variable``, ``rates`` (rows of rates, not increments), the plausibility checks
    to ``skip``, the ``gravity`` model, the ``encoder_latency`` [s] corrected, the ``temperature`` readings
    (csv), a bag's ``topic``, ``stamps`` and ``temperature_topic``, and KF-GINS's ``config`` (YAML)."""

    src: Annotated[Path, typer.Argument(help=f"source file ({source_help()})")]
    fmt: Annotated[str, typer.Option("--format", "-f", help=import_help())]
    out: Annotated[Path, typer.Option("--out", "-o", help="HDF5 record to write")]
    mapping: option("--mapping", "csv/txt: columns, units, axes (TOML); may hold a site table", Path,
                    "MAPPING.toml") = None
    path: option("--path", "rotation path TOML (a path table as in scenario files) when there are no encoder "
                 "angles", Path, "PATH.toml") = None
    path_start: option("--path-start-s", "source time (s) at which the path starts (default: the start of the first "
                       "sample)") = None
    gimbal: option("--gimbal", "encoder angles file: columns time (s), outer, inner", Path, "CSV") = None
    gimbal_unit: option("--gimbal-unit", "unit of the --gimbal angles: deg | rad (default: the unit the file's header "
                        "gives, as 'outer [rad]', else deg)", str, "deg|rad") = None
    lat: option("--lat", "site latitude (deg)", metavar="DEG") = None
    lon: option("--lon", "site longitude (deg)", metavar="DEG") = None
    height: option("--height", "site ellipsoidal height (m)", metavar="M") = None
    rate_hz: option("--rate-hz", "sample rate (Hz) (default: from the timestamps, which must then be uniform; given: "
                    "slightly jittery timestamps are regridded)", metavar="HZ") = None
    dtype: Annotated[str, typer.Option("--dtype", metavar="float64|float32", help=(
        "psins .bin: float64 | float32"))] = "float64"
    variable: option("--variable", ".mat: the N x 7 variable (default: the first one)", str, "NAME") = None
    rates: Annotated[bool, typer.Option("--rates", help=(
        "psins/mat rows are rates w, f, t (rad/s, m/s^2), not increments"))] = False
    skip: Annotated[list[str] | None, typer.Option("--skip-check", metavar="CHECK", help=(
        "skip a plausibility check: constant | saturation | magnitudes | motion | encoders (repeatable)"))] = ()
    encoder_latency: Annotated[float, typer.Option("--encoder-latency", metavar="SECONDS", help=(
        "encoder latency (s) to correct: the angles are shifted to theta(t + SECONDS) (the encoder check names it "
        "when it is over a sample)"))] = 0.0
    gravity: gravity_option("wgs84; the model is stored in the record") = None
    temperature: option("--temperature", "temperature readings at their own times: a header row 'time [s],NAME "
                        "[degC],...' (a sensor per column; K, degF, ms accepted), then rows on the source's clock",
                        Path, "CSV") = None
    topic: option("--topic", "rosbag: the sensor_msgs/Imu topic (default: the bag's only one; the topics are listed "
                  "otherwise)", str, "TOPIC") = None
    stamps: Annotated[str, typer.Option("--stamps", metavar="header|receive", help=(
        "rosbag: the samples' time: header (the messages' header.stamp) | receive (when the bag recorded "
        "them)"))] = "header"
    temperature_topic: option("--temperature-topic", "rosbag: a sensor_msgs/Temperature topic (degC) for the record's "
                              "temperature", str, "TOPIC") = None
    config: option("--config", "kf-gins: its YAML configuration (imunoise block and imudatarate, kept with the "
                   "record)", Path, "CONFIG.yaml") = None
    force: ForceOption = False


def run_import(o: ImportOptions) -> dict:
    """Import as ``o`` says (:class:`ImportOptions`), with the checks of :mod:`inscal.io.importers`; returns
    the JSON report.  The options are checked before anything is read; a bad source is one line."""
    from inscal.io.checks import SKIPPABLE
    from inscal.io.files import input_problem
    from inscal.io.importers import import_file
    from inscal.io.mapping import ImportFileError
    from inscal.io.records import DataFileError

    spec = REGISTRY.get(o.fmt)
    if spec is None:
        raise CliError(f"unknown --format {o.fmt!r}; choose one of: {', '.join(REGISTRY)}")
    bad = sorted(set(o.skip or ()) - set(SKIPPABLE))
    if bad:
        raise CliError(f"--skip-check {', '.join(bad)}: unknown; known checks: {', '.join(SKIPPABLE)}")
    if not (math.isfinite(o.encoder_latency) and abs(o.encoder_latency) <= 1.0):
        raise CliError(f"--encoder-latency must be a finite shift of at most 1 s, got {o.encoder_latency}")
    if o.gimbal_unit is not None and o.gimbal_unit not in ("deg", "rad"):
        raise CliError(f"--gimbal-unit must be deg or rad, got {o.gimbal_unit!r}")
    if spec.folder is not None and o.src.is_dir():  # a source that is a folder (a ROS 2 bag)
        what, marker = spec.folder
        if not (o.src / marker).is_file():
            raise CliError(f"{o.src}: a {what} folder holds {marker}, and this one has none")
    elif (msg := input_problem(o.src, "file")) is not None:
        raise CliError(msg)
    check_output(o.out, o.force)
    check_not_input(o.out, o.src, role="source file")
    check_not_input(o.out, o.mapping, o.path, o.gimbal, o.temperature, o.config)
    try:
        gmodel = None
        if o.gravity is not None:
            from inscal.cli.common import parse_gravity_option

            gmodel = parse_gravity_option(o.gravity)  # applied to the site wherever it comes from
        return import_file(o.src, o.out, spec, None, o.mapping, o.path, o.path_start, o.gimbal, o.gimbal_unit,
                           o.rate_hz, o.dtype, o.variable, o.rates, tuple(o.skip or ()), overwrite=o.force,
                           encoder_latency=o.encoder_latency, gravity=gmodel, temperature_file=o.temperature,
                           topic=o.topic, stamps=o.stamps, config_file=o.config, temperature_topic=o.temperature_topic,
                           site_parts=(o.lat, o.lon, o.height))
    except (ImportFileError, DataFileError, FileExistsError, FileNotFoundError) as exc:
        msg = str(exc)
        if o.config is not None and o.rate_hz is None:  # the rate came from the configuration, not from an option
            msg = re.sub(r"--rate-hz ([0-9][0-9.eE+-]*)", lambda m: f"the rate {m.group(1)} Hz (imudatarate of --config "
                         f"{short(o.config)}; --rate-hz overrides it)", msg, count=1)
        raise CliError(msg) from None
    except OSError as exc:
        raise CliError(f"cannot write {o.out}: {exc.strerror or exc}") from None


def _is_record(p: Path) -> bool:
    """True for an HDF5 file (a record), False for anything else (a parameter file)."""
    try:
        with open(p, "rb") as fh:
            return fh.read(8) == b"\x89HDF\r\n\x1a\n"
    except OSError:
        return True


def run_export_calibration(params: Path, fmt: str, out: Path, force: bool = False) -> dict:
    """Export the parameter file ``params`` into another tool's convention ``fmt`` at ``out``
    (:func:`inscal.io.exports.calibration.export_calibration`; ``c`` writes ``NAME.c`` and ``NAME.h``);
    the outputs are checked first and a bad file is one line (:class:`~inscal.cli.common.CliError`).
    """
    from inscal.io.exports.calibration import export_calibration
    from inscal.io.paramfile import ParamFileError

    check_output(out, force)
    check_not_input(out, params, role="parameter file")
    if fmt == "c":
        if out.suffix != ".c":
            raise CliError(f"{out}: --format c writes NAME.c and NAME.h: give --out NAME.c")
        check_output(out.with_suffix(".h"), force)
        check_not_input(out.with_suffix(".h"), params, role="parameter file")
    if fmt == "imu-tk":
        from inscal.io.exports.calibration import imutk_gyro_path

        try:
            gout = imutk_gyro_path(out)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        check_output(gout, force)
        check_not_input(gout, params, role="parameter file")
    try:
        return export_calibration(params, out, fmt, overwrite=force)
    except (ParamFileError, FileExistsError, FileNotFoundError, ValueError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write {out}: {exc.strerror or exc}") from None


def run_export(data: Path, fmt: str, out: Path, gimbal_out: Path | None = None, path_out: Path | None = None,
               force: bool = False, temperature_out: Path | None = None) -> dict:
    from inscal.io.exports.calibration import CALIBRATION_FORMATS, NOISE_FORMATS
    from inscal.io.files import input_problem
    from inscal.io.importers import export_record
    from inscal.io.mapping import ImportFileError
    from inscal.io.records import DataFileError

    record_formats = export_formats()
    known = list(record_formats) + [f for f in list(CALIBRATION_FORMATS) + list(NOISE_FORMATS) if f not in record_formats]
    if fmt not in known:
        raise CliError(f"unknown --format {fmt!r}; choose one of: {', '.join(known)}")
    if (msg := input_problem(data, "data file")) is not None:
        raise CliError(msg)
    if not _is_record(data):  # a parameter file
        if fmt not in CALIBRATION_FORMATS and fmt not in NOISE_FORMATS:
            raise CliError(f"{data} is not a record (HDF5); a parameter file exports as "
                           f"{' | '.join(CALIBRATION_FORMATS)}, a noise model (noise.toml) as {' | '.join(NOISE_FORMATS)}")
        if gimbal_out or path_out or temperature_out:
            raise CliError("--gimbal-out, --path-out and --temperature-out apply to a record")
        return run_export_calibration(data, fmt, out, force)
    if fmt not in record_formats:
        raise CliError(f"{data} is a record; --format {fmt} exports a parameter file (a record exports as "
                       f"{' | '.join(record_formats)})")
    named = {"the outputs": out, "--gimbal-out": gimbal_out, "--path-out": path_out, "--temperature-out": temperature_out}
    outs = [(what, p) for what, p in named.items() if p is not None]
    for _, p in outs:
        check_output(p, force)
    resolved = [p.resolve() for _, p in outs]
    if len(set(resolved)) != len(resolved):
        raise CliError("--out, --gimbal-out, --path-out and --temperature-out must be different files")
    for what, p in outs:
        check_not_input(p, data, what=what, role="input record")
    try:
        return export_record(data, out, fmt, overwrite=force, gimbal_out=gimbal_out, path_out=path_out,
                             temperature_out=temperature_out)
    except (ImportFileError, DataFileError, FileExistsError, FileNotFoundError, OSError) as exc:
        raise CliError(str(exc)) from None


def register(app: typer.Typer) -> None:
    @app.command("import")
    @with_options(ImportOptions, before="json_")
    def import_(json_: JsonOption = False, **options):
        """Import IMU data (PSINS .bin/.mat, csv, text, KF-GINS text, ROS bags) into an HDF5 record, with checks."""
        res = call(run_import, options_of(ImportOptions, options, skip=tuple(options["skip"] or ())))
        for w in res["warnings"]:
            typer.echo(f"inscal: warning: {w}", err=True)
        if json_:
            print_json(res)
            return
        from inscal.report.text import import_line

        typer.echo(import_line(res))

    @app.command("export")
    def export(
        data: Path = typer.Argument(..., help="HDF5 record, or a calibration parameter file (TOML)"),
        fmt: str = typer.Option(..., "--format", "-f", help=f"a record: {' | '.join(export_formats())}; a parameter "
                                "file: kalibr | imucal | imu-tk (--out NAME_acc.calib, and NAME_gyro.calib) | "
                                "kf-gins | c; a noise model (inscal noise --out noise.toml): kalibr (imu.yaml) | "
                                "kf-gins (imunoise) | matlab (gyroparams/accelparams)"),
        out: Path = typer.Option(..., "--out", "-o", help="file to write"),
        gimbal_out: Path = typer.Option(None, "--gimbal-out", help="psins/mat: also write the gimbal angles "
                                        "(time in s, outer and inner in rad, said in its header) for import --gimbal"),
        path_out: Path = typer.Option(None, "--path-out", help="also write the record's rotation path (TOML) for "
                                      "import --path"),
        temperature_out: Path = typer.Option(None, "--temperature-out", help="also write the record's temperature "
                                             "readings at their own times (csv: time [s], one degC column per sensor) "
                                             "for import --temperature"),
        force: ForceOption = False,
        json_: JsonOption = False,
    ):
        """Export a record as csv (17 digits; its temperature too), PSINS .bin (float64 rows dθ, dv, t), .mat or
        KF-GINS text; or a calibration in Kalibr's, imucal's, imu_tk's or KF-GINS's convention, or as C99 source."""
        res = call(run_export, data, fmt, out, gimbal_out, path_out, force, temperature_out)
        if json_:
            print_json(res)
        elif "params" in res:
            typer.echo(f"exported {res['params']} ({res['format']}) -> {', '.join(res['files'])}")
            if res["dropped"] and res.get("method") == "noise model":
                typer.echo(f"inscal: warning: {res['format']} leaves out {'; '.join(res['dropped'])} (named in the "
                           "file's comments): a filter tuned from it lacks these terms", err=True)
            elif res["dropped"]:
                typer.echo(f"inscal: warning: {res['format']} cannot hold {', '.join(res['dropped'])} (non-zero in "
                           f"{res['params']}): compensating with the export differs from inscal compensate", err=True)
        else:
            typer.echo(f"exported {res['samples']} samples ({res['format']}) -> {res['out']}"
                       + (f"; gimbal angles -> {gimbal_out}" if gimbal_out else "")
                       + (f"; path -> {path_out}" if path_out else "")
                       + (f"; temperature -> {temperature_out}" if temperature_out else "")
                       + ("; temperature interpolated onto the sample times" if res["temperature"] == "interpolated"
                          else "")
                       + ("; temperature not exported (--temperature-out writes it)"
                          if res["temperature"] == "not exported" and not temperature_out else ""))
