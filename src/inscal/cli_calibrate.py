"""``inscal calibrate``: estimate IMU and gimbal errors from a turntable record."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from .cliutil import CliError, check_output, fail, print_json


def run_calibrate(data: Path, method: str, out: Path, force: bool = False, settle: float = 1.0,
                  min_static: float = 20.0) -> dict:
    """Calibrate ``data`` with ``method`` and write ``out``; returns the JSON report.
    Nothing is written unless the calibration succeeds."""
    from . import io
    from .calibrate import METHODS, CalibrationError, calibrate
    from .paramfile import ParamFileError, save_params

    if method not in METHODS:
        raise CliError(f"unknown method {method!r}; choose one of: {', '.join(METHODS)}")
    if not data.is_file():
        raise CliError(f"{data}: no such data file")
    check_output(out, force)
    try:
        rec = io.read_record(data)
    except (ValueError, OSError) as exc:  # DataFileError is a ValueError
        raise CliError(str(exc)) from None
    try:
        res = calibrate(rec, method, settle=settle, min_static=min_static)
    except CalibrationError as exc:
        raise CliError(f"{data}: {exc}") from None
    truth = rec.truth
    try:
        save_params(out, res, data_file=data.name, data_hash=io.file_hash(data), overwrite=force,
                    metadata={"scenario": rec.scenario or None, "windows": len(res.windows.windows) if res.windows else None})
    except (ParamFileError, FileExistsError, FileNotFoundError, OSError) as exc:
        raise CliError(str(exc)) from None
    report = {"method": res.method, "parameters": res.to_field(truth), "out": str(out), "notes": res.notes}
    return report


def _fmt(v) -> str:
    a = np.atleast_1d(np.asarray(v, dtype=float))
    return "[" + ", ".join("nan" if not np.isfinite(x) else f"{x:.4g}" for x in a) + "]"


def register(app: typer.Typer) -> None:
    @app.command()
    def calibrate(
        data: Path = typer.Argument(..., help="HDF5 record (inscal simulate, or a recorded run)"),
        method: str = typer.Option(..., "--method", "-m", help="six-position | twelve-position | n25 | joint"),
        out: Path = typer.Option(..., "--out", "-o", help="parameter file to write (TOML)"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing parameter file"),
        settle: float = typer.Option(1.0, "--settle-s", help="settling time dropped at both ends of each window [s]"),
        min_static: float = typer.Option(20.0, "--min-static-s", help="shortest static window used [s]"),
        json_: bool = typer.Option(False, "--json", help="print the parameters as JSON"),
    ):
        """Calibrate IMU errors (and gimbal non-orthogonality / mounting attitude) from a record."""
        try:
            rep = run_calibrate(data, method, out, force, settle, min_static)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json({"method": rep["method"], "parameters": rep["parameters"]})
            return
        typer.echo(f"{rep['method']}: parameters -> {rep['out']}")
        for name, e in rep["parameters"].items():
            line = f"  {name:24s} {_fmt(e['value'])} +- {_fmt(e['sigma'])} {e['unit']}"
            if "error" in e:
                line += f"   (error {_fmt(e['error'])})"
            typer.echo(line)
        for n in rep["notes"]:
            typer.echo(f"  note: {n}")
