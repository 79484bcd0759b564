"""``inscal allan``: Allan deviation of the gyro and accelerometer channels of a record."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from . import units
from .cliutil import CliError, check_output, fail, print_json


def run_allan(data: Path, start_s: float = 0.0, stop_s: float | None = None, plot: Path | None = None,
              force: bool = False) -> dict:
    from . import io
    from .analysis.allan import allan

    try:
        rec = io.read_record(data)
    except io.DataFileError as exc:
        raise CliError(str(exc)) from None
    t = rec.time
    sel = (t > start_s) & (t <= (stop_s if stop_s is not None else np.inf))
    if sel.sum() < 1000:
        raise CliError(f"only {int(sel.sum())} samples between {start_s} s and {stop_s} s; need >= 1000 of a static window")
    g = allan(rec.dtheta[sel], rec.rate_hz)
    a = allan(rec.dvel[sel], rec.rate_hz)
    res = {
        "data": str(data),
        "window_s": [float(t[sel][0] - 1 / rec.rate_hz), float(t[sel][-1])],
        "taus_s": g.taus,
        "gyro_adev_deg_h": units.from_si(g.adev, "deg/h").T,
        "accel_adev_ug": units.from_si(a.adev, "ug").T,
        "arw_deg_rth": units.from_si(g.white, "deg/sqrt(h)"),
        "vrw_ug_rthz": units.from_si(a.white, "ug/sqrt(Hz)"),
        "gyro_bias_instability_deg_h": units.from_si(g.bias_instability, "deg/h"),
        "accel_bias_instability_ug": units.from_si(a.bias_instability, "ug"),
    }
    if plot is not None:
        check_output(plot, force)
        from .report import allan_plot

        allan_plot(plot, g.taus, res["gyro_adev_deg_h"], res["accel_adev_ug"], overwrite=force)
        res["plot"] = str(plot)
    return res


def register(app: typer.Typer) -> None:
    @app.command("allan")
    def allan_cmd(
        data: Path = typer.Argument(..., help="HDF5 record (use a static window)"),
        start_s: float = typer.Option(0.0, "--start", help="window start [s]"),
        stop_s: float = typer.Option(None, "--stop", help="window end [s] (default: end of record)"),
        plot: Path = typer.Option(None, "--plot", help="write an Allan deviation plot (PNG)"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing plot"),
        json_: bool = typer.Option(False, "--json", help="print results as JSON"),
    ):
        """Allan deviation of a record: ARW, VRW and bias instability per axis."""
        try:
            res = run_allan(data, start_s, stop_s, plot, force)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
            return
        from rich.console import Console
        from rich.table import Table

        tab = Table(title=f"Allan deviation of {data}")
        for col in ("axis", "ARW [deg/rt(h)]", "gyro BI [deg/h]", "VRW [ug/rt(Hz)]", "accel BI [ug]"):
            tab.add_column(col)
        for k, ax in enumerate("xyz"):
            tab.add_row(ax, f"{res['arw_deg_rth'][k]:.4g}", f"{res['gyro_bias_instability_deg_h'][k]:.4g}",
                        f"{res['vrw_ug_rthz'][k]:.4g}", f"{res['accel_bias_instability_ug'][k]:.4g}")
        Console().print(tab)
