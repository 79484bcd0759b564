"""``inscal allan``: Allan deviation of the gyro and accelerometer channels of a record."""

from __future__ import annotations

from pathlib import Path

import typer

from inscal.cli.common import (
    CliError,
    LazyModule,
    check_not_input,
    check_output,
    fail,
    print_json,
    short,
)
from inscal.cli.limits import check_memory

np = LazyModule("numpy")
units = LazyModule("inscal.core.units")

#: plot formats (from the --plot suffix)
PLOT_FORMATS = ("png", "pdf", "svg")
#: memory per sample of the window: the phase history of the streamed Allan deviation (about a quarter of
#: the window's rows of 3 floats, inscal.analysis.allan.StreamingAllan) and the motion statistics
BYTES_PER_SAMPLE = 8


def run_allan(data: Path, start_s: float = 0.0, stop_s: float | None = None, plot: Path | None = None,
              force: bool = False, warn=None) -> dict:
    """Allan deviation of a window of ``data``; ``warn(line)`` is called for a window that is not
    static (the warning is also in the result's ``warnings``).  The record is streamed in chunks
    (bounded memory, multi-day records included)."""
    from inscal import io

    if plot is not None:
        fmt = plot.suffix.lower().lstrip(".")
        if fmt not in PLOT_FORMATS:
            raise CliError(f"--plot {short(plot)}: unknown plot format {short(plot.suffix or '(none)', 20)!r}; "
                           f"use a .png, .pdf or .svg name")
        check_output(plot, force)
        check_not_input(plot, data, what="--plot")
    for name, v in (("--start", start_s), ("--stop", stop_s)):
        if v is not None and not np.isfinite(v):
            raise CliError(f"{name} must be a finite time in s, got {v}")
    try:
        win = io.record_window(data, start_s, stop_s)
        if win.n < 1000:
            span = f"between {start_s:g} s and {stop_s:g} s" if stop_s is not None else f"from {start_s:g} s to its end"
            raise CliError(f"{short(data)}: only {win.n} samples {span}; the Allan deviation needs >= 1000 samples "
                           "of a static window")
        check_memory(win.n * BYTES_PER_SAMPLE, f"the window of {short(data)} ({win.n} samples, {win.n / win.rate_hz:.4g} s "
                     f"at {win.rate_hz:g} Hz)", "take a shorter window with --start/--stop")
        from inscal.analysis.allan import stream_allan

        g, a, mot, (t0, t1) = stream_allan(data, win)
    except io.DataFileError as exc:
        raise CliError(str(exc)) from None
    except (KeyError, TypeError, ValueError) as exc:
        raise CliError(f"{short(data)}: not a valid inscal record ({type(exc).__name__}: {short(exc)})") from None
    warnings = []
    w = mot.warning()
    if w:
        warnings.append(w)
        if warn is not None:
            warn(w)
    res = {
        "data": str(data),
        "window_s": [float(t0 - 1 / win.rate_hz), float(t1)],
        "taus_s": g.taus,
        "gyro_adev_deg_h": units.from_si(g.adev, "deg/h").T,
        "accel_adev_ug": units.from_si(a.adev, "ug").T,
        "arw_deg_rth": units.from_si(g.white, "deg/sqrt(h)"),
        "vrw_ug_rthz": units.from_si(a.white, "ug/sqrt(Hz)"),
        "gyro_bias_instability_deg_h": units.from_si(g.bias_instability, "deg/h"),
        "accel_bias_instability_ug": units.from_si(a.bias_instability, "ug"),
    }
    # a minimum at the longest tau is no flat bottom: the record is too short to see the bias
    # instability, and the figure is only an upper bound
    res["gyro_bias_instability_upper_bound"] = (np.asarray(g.tau_bi) >= g.taus[-1]).tolist()
    res["accel_bias_instability_upper_bound"] = (np.asarray(a.tau_bi) >= a.taus[-1]).tolist()
    res["warnings"] = warnings
    if plot is not None:
        from inscal.report.figures import allan_plot

        try:
            allan_plot(plot, g.taus, res["gyro_adev_deg_h"], res["accel_adev_ug"], overwrite=force)
        except OSError as exc:
            raise CliError(f"cannot write {short(plot)}: {exc.strerror or exc}") from None
        res["plot"] = str(plot)
    return res


def register(app: typer.Typer) -> None:
    @app.command("allan")
    def allan_cmd(
        data: Path = typer.Argument(..., help="HDF5 record (use a static window)"),
        start_s: float = typer.Option(0.0, "--start", help="window start [s]"),
        stop_s: float = typer.Option(None, "--stop", help="window end [s] (default: end of record)"),
        plot: Path = typer.Option(None, "--plot", help="write an Allan deviation plot (.png, .pdf or .svg)"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing plot"),
        json_: bool = typer.Option(False, "--json", help="print results as JSON"),
    ):
        """Allan deviation of a record: ARW, VRW and bias instability per axis."""
        try:
            res = run_allan(data, start_s, stop_s, plot, force,
                            warn=lambda w: typer.echo(f"inscal: warning: {w}", err=True))
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
            return
        from rich.console import Console
        from rich.markup import escape
        from rich.table import Table

        tab = Table(title=escape(f"Allan deviation of {data}"))
        for col in ("axis", "ARW [deg/rt(h)]", "gyro BI [deg/h]", "VRW [ug/rt(Hz)]", "accel BI [ug]"):
            tab.add_column(escape(col))  # brackets are Rich markup otherwise (the units vanished)
        def bi(sensor, unit, k):
            ub = res[f"{sensor}_bias_instability_upper_bound"][k]
            return ("< " if ub else "") + f"{res[f'{sensor}_bias_instability_{unit}'][k]:.4g}"

        for k, ax in enumerate("xyz"):
            tab.add_row(ax, f"{res['arw_deg_rth'][k]:.4g}", bi("gyro", "deg_h", k),
                        f"{res['vrw_ug_rthz'][k]:.4g}", bi("accel", "ug", k))
        Console().print(tab)
        if any(res["gyro_bias_instability_upper_bound"] + res["accel_bias_instability_upper_bound"]):
            typer.echo("'<': the deviation still falls at the longest tau (no flat bottom in this window): "
                       "the bias instability is below the figure, not measured")
