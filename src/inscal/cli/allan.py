"""``inscal allan``: Allan deviation of the gyro and accelerometer channels of a record, a view of the
noise engine (``inscal noise``): the same pass, curve, white-noise density and read-offs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import typer

from inscal.cli.common import (CliError, LazyModule, call, check_not_input, check_output, print_json, record_errors, short, warn,
    write_figure)
from inscal.cli.limits import check_memory
from inscal.cli.options import ForceOption, JsonOption, SeedOption

np = LazyModule("numpy")
units = LazyModule("inscal.core.units")

#: plot formats (from the --plot suffix)
PLOT_FORMATS = ("png", "pdf", "svg")
#: memory per sample of the window: the phase history of the six channels in the noise engine's one pass
#: (inscal.analysis.noise.estimators, as ``inscal noise``) and the motion statistics
BYTES_PER_SAMPLE = 16


def run_allan(data: Path, start_s: float = 0.0, stop_s: float | None = None, plot: Path | None = None,
              force: bool = False, warn=None, model: str = "auto", seed: int = 0) -> dict:
    """Allan deviation of a window of ``data``, a view of the noise engine: one streamed pass
    (:func:`inscal.analysis.noise.identify.scan_window`), the octave curve, and per axis the white-noise
    density N (ARW, VRW) of the model ``inscal noise`` identifies (``model``, default ``auto``; the same
    value and 95 % interval) and the IEEE bias-instability read-off with its tau and degrees of freedom.
    ``warn(line)`` is called for a window that is not static (the warning is also in the result's
    ``warnings``)."""
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
    if model.strip().lower() != "auto":
        from inscal.core.noise_models import model_string, parse_model

        try:
            model = model_string(parse_model(model))
        except ValueError as exc:
            raise CliError(f"--model: {exc}") from None
    else:
        model = "auto"
    with record_errors(data):
        win = io.record_window(data, start_s, stop_s)
        if win.n < 1000:
            span = f"between {start_s:g} s and {stop_s:g} s" if stop_s is not None else f"from {start_s:g} s to its end"
            raise CliError(f"{short(data)}: only {win.n} samples {span}; the Allan deviation needs >= 1000 samples "
                           "of a static window")
        check_memory(win.n * BYTES_PER_SAMPLE, f"the window of {short(data)} ({win.n} samples, {win.n / win.rate_hz:.4g} s "
                     f"at {win.rate_hz:g} Hz)", "take a shorter window with --start/--stop")
        from inscal.analysis.noise import identify as idf

        scan = idf.scan_window(data, win)
    t0 = scan.t_first - 1 / win.rate_hz
    warnings, cut = [], None
    w = scan.motion.warning(t0, idf.CHANNELS)
    if w:  # as inscal noise: the moving stretches cut out where they are few, else the warning
        with record_errors(data):
            try:
                sv, cut = idf.cut_motion(data, win, scan, t0)
            except idf.NoiseInputError:
                sv = None
        if sv is not None:
            scan = dataclasses.replace(scan, sv=sv)
            w = (f"cut out: {cut.seconds:.4g} s ({100 * cut.share:.3g} % of the window) that moves, at "
                 + ", ".join(f"{a:.6g}-{b:.6g} s" for a, b in cut.spans_s) + f" ({idf.CUT_MARGIN_S:g} s margin each "
                 f"side); the curve is computed on the {cut.segments} static segments left")
    for line in ([w] if w else []) + scan.checks.problems(idf.CHANNELS, t0, 1 / win.rate_hz):
        warnings.append(line)
        if warn is not None:
            warn(line)
    try:
        view = idf.allan_view(scan, model, np.random.default_rng(seed))
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise CliError(f"{short(data)}: the noise of this window cannot be identified ({short(exc)}); "
                       "try --model WN") from None
    ch = view["channels"]
    res = {
        "data": str(data),
        "window_s": [float(t0), float(scan.t_last)],
        "taus_s": view["taus_s"],
        "edf": view["edf"],
        "gyro_adev_deg_h": units.from_si(view["adev"][:, :3], "deg/h").T,
        "accel_adev_ug": units.from_si(view["adev"][:, 3:], "ug").T,
        "model_asked": model,
    }
    for sensor, key, unit, sl in (("gyro", "arw_deg_rth", "deg/sqrt(h)", slice(0, 3)),
                                  ("accel", "vrw_ug_rthz", "ug/sqrt(Hz)", slice(3, 6))):
        white = np.array([c["white"] for c in ch[sl]])
        res[key] = units.from_si(white[:, 0], unit)
        res[key.replace("_", "_lower_95_", 1)] = units.from_si(white[:, 1], unit)
        with np.errstate(over="ignore"):  # an unseen term's upper bound beyond float range: inf, unbounded
            res[key.replace("_", "_upper_95_", 1)] = units.from_si(white[:, 2], unit)
        res[f"{sensor}_white_source"] = [c["white_source"] for c in ch[sl]]
        res[f"{sensor}_model"] = [c["model"] for c in ch[sl]]
        bi = [c["readoffs"]["BI"] for c in ch[sl]]
        bkey = "gyro_bias_instability_deg_h" if sensor == "gyro" else "accel_bias_instability_ug"
        res[bkey] = [b["value"] for b in bi]
        res[f"{sensor}_bias_instability_tau_s"] = [b["read_at_tau_s"] for b in bi]
        res[f"{sensor}_bias_instability_edf"] = [b["edf"] for b in bi]
        # a minimum at the longest tau read is no flat bottom: the record is too short to see the bias
        # instability, and the figure is only an upper bound
        res[f"{sensor}_bias_instability_upper_bound"] = [not b["flat_bottom"] for b in bi]
    res["warnings"] = warnings
    if cut is not None:
        res["cut"] = cut.to_dict()
    if plot is not None:
        from inscal.report.figures import allan_plot

        write_figure(allan_plot, plot, res["taus_s"], res["gyro_adev_deg_h"], res["accel_adev_ug"], overwrite=force)
        res["plot"] = str(plot)
    return res


def register(app: typer.Typer) -> None:
    @app.command("allan")
    def allan_cmd(
        data: Path = typer.Argument(..., help="HDF5 record (use a static window)"),
        start_s: float = typer.Option(0.0, "--start", metavar="SECONDS", help="window start [s]"),
        stop_s: float = typer.Option(None, "--stop", metavar="SECONDS", help="window end [s] (default: end of record)"),
        plot: Path = typer.Option(None, "--plot", help="write an Allan deviation plot (.png, .pdf or .svg)"),
        force: ForceOption = False,
        model: str = typer.Option("auto", "--model", metavar="MODEL", help="the noise model whose white-noise term gives ARW/VRW "
                                  "(as inscal noise: 'auto' or a sum such as 'WN+RW+2GM')"),
        seed: SeedOption = 0,
        json_: JsonOption = False,
    ):
        """Allan deviation of a record: ARW and VRW with their 95 % intervals (the noise engine's, as
        inscal noise) and the bias-instability read-off per axis."""
        res = call(run_allan, data, start_s, stop_s, plot, force,
                        warn=warn, model=model, seed=seed)
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
            edf = res[f"{sensor}_bias_instability_edf"][k]
            return (("< " if ub else "") + f"{res[f'{sensor}_bias_instability_{unit}'][k]:.4g} "
                    f"({res[f'{sensor}_bias_instability_tau_s'][k]:.3g} s, {edf:.3g})")

        def white(key, k):
            v, lo, hi = (res[key.replace("_", x, 1)][k] for x in ("_", "_lower_95_", "_upper_95_"))
            return f"{v:.4g}" + (f" [{lo:.3g}, {hi:.3g}]" if np.isfinite(lo) else " (read-off)")

        for k, ax in enumerate("xyz"):
            tab.add_row(ax, escape(white("arw_deg_rth", k)), bi("gyro", "deg_h", k),
                        escape(white("vrw_ug_rthz", k)), bi("accel", "ug", k))
        Console().print(tab)
        typer.echo("ARW/VRW [95 % interval]: the white-noise term of the noise model inscal noise identifies "
                   f"(--model {res['model_asked']}): gyro {', '.join(res['gyro_model'])}; accel "
                   f"{', '.join(res['accel_model'])}; BI: the IEEE read-off sigma_min / 0.664 (at tau, with its "
                   "degrees of freedom)")
        if any(res["gyro_bias_instability_upper_bound"] + res["accel_bias_instability_upper_bound"]):
            typer.echo("'<': the deviation still falls at the longest tau (no flat bottom in this window): "
                       "the bias instability is below the figure, not measured")
