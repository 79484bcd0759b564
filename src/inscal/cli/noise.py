"""``inscal noise``: identify the noise of a static record (or of an Allan/wavelet variance curve)."""

from __future__ import annotations

from pathlib import Path

import typer

from inscal.cli.common import (CliError, LazyModule, call, check_not_input, check_output, print_json, record_errors, short,
                               write_figure)
from inscal.cli.limits import check_memory
from inscal.cli.options import ForceOption, JsonOption, SeedOption

np = LazyModule("numpy")

PLOT_FORMATS = ("png", "pdf", "svg")
#: memory per sample of the window: the phase history of six channels (about 0.2 n rows, inscal.analysis.noise.estimators)
BYTES_PER_SAMPLE = 16


def _check_model(model: str) -> str:
    from inscal.core.noise_models import model_string, parse_model

    if model.strip().lower() == "auto":
        return "auto"
    try:
        return model_string(parse_model(model))
    except ValueError as exc:
        raise CliError(f"--model: {exc}") from None


def _check_channels(channels: str | None) -> list[str]:
    from inscal.analysis.noise.identify import CHANNELS

    if channels is None:
        return list(CHANNELS)
    names = [c.strip().lower() for c in channels.split(",") if c.strip()]
    bad = [c for c in names if c not in CHANNELS]
    if bad or not names or len(set(names)) != len(names):
        raise CliError(f"--channels {short(channels, 40)!r}: give distinct names among {', '.join(CHANNELS)}")
    return names


def run_noise(data: Path | None, model: str = "auto", channels: str | None = None, start_s: float = 0.0,
              stop_s: float | None = None, plot: Path | None = None, out: Path | None = None,
              from_curve: Path | None = None, kind: str = "gyro", seed: int = 0, force: bool = False) -> dict:
    """The identification as a JSON-ready dict (field units); nothing is written on a refusal."""
    from inscal import io
    from inscal.analysis.noise import identify as idf

    model = _check_model(model)
    names = _check_channels(channels)
    if (data is None) == (from_curve is None):
        raise CliError("give a RECORD or --from-curve CSV (one of them)")
    for name, v in (("--start", start_s), ("--stop", stop_s)):
        if v is not None and not np.isfinite(v):
            raise CliError(f"{name} must be a finite time in s, got {v}")
    src = data if data is not None else from_curve
    if plot is not None:
        if plot.suffix.lower().lstrip(".") not in PLOT_FORMATS:
            raise CliError(f"--plot {short(plot)}: use a .png, .pdf or .svg name")
        check_output(plot, force)
        check_not_input(plot, src, what="--plot")
    if out is not None:
        if out.suffix.lower() != ".toml":
            raise CliError(f"--out {short(out)}: the noise model is a .toml file")
        check_output(out, force)
        check_not_input(out, src, what="--out")
    rng = np.random.default_rng(seed)
    need = idf.required_samples(model)
    if from_curve is not None:
        if kind not in ("gyro", "accel"):
            raise CliError(f"--kind must be gyro or accel, got {kind!r}")
        if not from_curve.is_file():
            raise CliError(f"{short(from_curve)}: no such file")
        if from_curve.stat().st_size > idf.MAX_CURVE_BYTES:
            raise CliError(f"{short(from_curve)}: {from_curve.stat().st_size} bytes, more than a curve's "
                           f"{idf.MAX_CURVE_BYTES} (at most {idf.MAX_CURVE_POINTS} points)")
        try:
            quantity, curve = idf.parse_curve_csv(from_curve.read_text(encoding="utf-8"), short(from_curve))
        except (idf.NoiseInputError, UnicodeDecodeError) as exc:
            raise CliError(str(exc) if isinstance(exc, idf.NoiseInputError) else f"{short(from_curve)}: not a text file") from None
        j_need = idf.required_scales(model)
        if curve.m.size < j_need:
            raise CliError(f"{short(from_curve)}: {curve.m.size} octave points; model {model} needs at least {j_need}")
        name = names[0] if channels is not None else ("gx" if kind == "gyro" else "ax")
        sel = idf.identify_curve(curve, model, rng)
        sv = idf.ScaleVariance(curve.m, curve.dt, int(curve.n_terms[0] + 2 * curve.m[0] - 1), curve.wv[:, None],
                               curve.n_terms)
        summaries = [idf.channel_summary(name, sel, sv, 0, kind)]
        sels, chan_names, kinds, rate_hz = [sel], [name], [kind], 1.0 / curve.dt
        res = {"curve_file": str(from_curve), "quantity": quantity}
    else:
        with record_errors(data):
            win = io.record_window(data, start_s, stop_s)
            if win.n < need:
                raise CliError(f"{short(data)}: the window has {win.n} samples ({win.n / win.rate_hz:.4g} s); model "
                               f"{model} needs at least {need} ({need / win.rate_hz:.4g} s at {win.rate_hz:g} Hz): "
                               "a longer static record, or a smaller --model")
            check_memory(win.n * BYTES_PER_SAMPLE, f"the window of {short(data)} ({win.n} samples)",
                         "take a shorter window with --start/--stop")
            scan = idf.scan_window(data, win)
        t0 = scan.t_first - 1 / win.rate_hz
        idx = [idf.CHANNELS.index(c) for c in names]
        probs = scan.checks.problems(idf.CHANNELS, t0, 1 / win.rate_hz)
        probs = [p for p in probs if p.split(" ", 1)[0] in names]
        if probs:
            raise CliError(f"{short(data)}: {probs[0]}")
        sv, cut = scan.sv, None
        why = scan.motion.reason(t0, idf.CHANNELS)
        if why is not None:  # the moving stretches cut out, the curve on the static rest
            with record_errors(data):
                try:
                    sv, cut = idf.cut_motion(data, win, scan, t0)
                except idf.NoiseInputError as exc:
                    raise CliError(f"{short(data)}: {exc} ({why})") from None
            if sv.m.size < idf.required_scales(model) or sv.n < need:
                raise CliError(f"{short(data)}: once the motion at {', '.join(f'{a:.6g}-{b:.6g} s' for a, b in cut.spans_s)}"
                               f" is cut out, the static segments give {sv.m.size} scales; model {model} needs "
                               f"{idf.required_scales(model)}: a longer static record, or a smaller --model")
        sels = [idf.identify_curve(idf.octave_curve(sv, c), model, rng) for c in idx]
        summaries = [idf.channel_summary(nm_, s, sv, c) for nm_, s, c in zip(names, sels, idx)]
        chan_names, kinds, rate_hz = names, [idf.KINDS[c] for c in names], win.rate_hz
        res = {"data": str(data), "window_s": [scan.t_first - 1 / win.rate_hz, scan.t_last]}
        if cut is not None:
            res["cut"] = {**cut.to_dict(), "why": why}
    res.update({"model_asked": model, "seed": seed, "channels": summaries,
                "conventions": "SI inside; values in IEEE Std 952-2020 (gyro) / 1293-2018 (accelerometer) units; "
                               "AVAR(m) = 2 x Haar wavelet variance at width 2m; 95 % intervals (eta3 chi-square "
                               "for the curve, GMWM sandwich for the parameters); weights 1/(upper - lower)^2"})
    if out is not None:
        from inscal.io.noisefile import write_noise

        nmodel = idf.noise_model(chan_names, kinds, sels, rate_hz)
        intervals = {}
        for nme, s in zip(chan_names, sels):
            f, i, per = s.chosen, 0, {}
            for ti, t in enumerate(f.terms):
                per[ti] = {p: (f.lower[i + k], f.upper[i + k]) for k, p in enumerate(t.params)}
                i += len(t.params)
            intervals[nme] = per
        try:
            write_noise(out, nmodel, intervals, {"source": str(src), "seed": seed}, overwrite=force)
        except OSError as exc:
            raise CliError(f"cannot write {short(out)}: {exc.strerror or exc}") from None
        res["out"] = str(out)
    if plot is not None:
        from inscal.report.noise import noise_plot

        write_figure(noise_plot, plot, summaries, overwrite=force)
        res["plot"] = str(plot)
    return res


def register(app: typer.Typer) -> None:
    """Add the ``inscal noise`` command (noise identification) to ``app``."""
    @app.command("noise")
    def noise_cmd(
        data: Path = typer.Argument(None, help="HDF5 record (a static window of it)"),
        model: str = typer.Option("auto", "--model", metavar="MODEL", help="'auto' (choose among the sub-sums of QN+WN+BI+RW+DR+2GM "
                                  "by the J statistic plus a Hannan-Quinn penalty) or a sum such as 'WN+RW+2GM' "
                                  "(QN WN BI RW DR GM)"),
        channels: str = typer.Option(None, "--channels", metavar="CHANNELS", help="comma-separated among gx,gy,gz,ax,ay,az (default all)"),
        start_s: float = typer.Option(0.0, "--start", metavar="SECONDS", help="window start [s]"),
        stop_s: float = typer.Option(None, "--stop", metavar="SECONDS", help="window end [s] (default: end of record)"),
        plot: Path = typer.Option(None, "--plot", help="write the Allan deviation, fit and terms (.png/.pdf/.svg)"),
        out: Path = typer.Option(None, "--out", help="write the identified model (noise.toml)"),
        from_curve: Path = typer.Option(None, "--from-curve", metavar="CSV", help="fit a curve computed elsewhere: CSV "
                                        "'tau_s,<avar|adev|wvar>,lower,upper' in SI with a '# dt_s = ...' line"),
        kind: str = typer.Option("gyro", "--kind", metavar="gyro|accel", help="with --from-curve: gyro or accel"),
        seed: SeedOption = 0,
        force: ForceOption = False,
        json_: JsonOption = False,
    ):
        """Identify the noise: Allan/wavelet variance with intervals, GMWM fit, model choice, IEEE read-offs."""
        res = call(run_noise, data, model, channels, start_s, stop_s, plot, out, from_curve, kind, seed, force)
        if json_:
            print_json(res)
            return
        from rich.console import Console
        from rich.markup import escape
        from rich.table import Table

        con = Console()
        if "cut" in res:
            c = res["cut"]
            typer.echo(f"cut out: {c['seconds']:.4g} s ({100 * c['share']:.3g} % of the window) that moves, at "
                       + ", ".join(f"{a:.6g}-{b:.6g} s" for a, b in c["spans_s"])
                       + f" ({c['margin_s']:g} s margin each side); the curve is computed on the {c['static_segments']}"
                       f" static segments left")
        for ch in res["channels"]:
            tab = Table(title=escape(f"{ch['channel']} ({ch['kind']}): {ch['model']}"))
            for col in ("parameter", "value", "95 % interval", "unit"):
                tab.add_column(escape(col))
            for pn, p in ch["parameters"].items():
                tab.add_row(pn, f"{p['value']:.4g}", f"[{p['lower_95']:.3g}, {p['upper_95']:.3g}]", escape(p["unit"]))
            for code, r in ch["ieee_readoffs"].items():
                dof = f", {r['edf']:.3g} dof" if r.get("edf") is not None else ""
                tab.add_row(f"IEEE read-off {code}", f"{r['value']:.4g}", f"at tau = {r['read_at_tau_s']:.3g} s{dof}",
                            escape(r["unit"]))
            con.print(tab)
            typer.echo(f"  why: {ch['why']}; objective {ch['objective']:.4g}, J = {ch['j_statistic']:.3g} "
                       f"on {ch['j_dof']} dof")
            if ch["unresolved"]["parameters"]:
                typer.echo(f"  unresolved ({ch['unresolved']['rule']}): {', '.join(ch['unresolved']['parameters'])}")
