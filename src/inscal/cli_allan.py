"""``inscal allan``: Allan deviation of the gyro and accelerometer channels of a record."""

from __future__ import annotations

from pathlib import Path

import typer

from .cliutil import CliError, LazyModule, check_not_input, check_output, fail, print_json, short

np = LazyModule("numpy")
units = LazyModule("inscal.units")
#: Earth rotation rate [rad/s] (WGS84; inscal.earth.OMEGA_IE, not imported: it loads numba)
OMEGA_IE = 7.292115e-5

#: plot formats (from the --plot suffix)
PLOT_FORMATS = ("png", "pdf", "svg")


def motion_warning(rec, sel) -> str | None:
    """One line when the window ``sel`` of ``rec`` is not static: the gyro rate (block means of
    about 1 s) departs from its median by more than 10x the Earth rate (and 6x its noise) in more
    than 1 % of the window, or the gimbal angles change by more than 1 mrad."""
    mot = MotionStats(int(sel.sum()), rec.rate_hz)
    mot.update(np.asarray(rec.dtheta[sel], dtype=float),
               None if getattr(rec, "gimbal", None) is None else np.asarray(rec.gimbal[sel], dtype=float))
    return mot.warning()


class MotionStats:
    """What :func:`motion_warning` needs, gathered chunk by chunk: the gyro increments summed over
    blocks of about 1 s (at least 20 blocks) and the span of the gimbal angles."""

    def __init__(self, n: int, rate_hz: float):
        self.rate_hz = rate_hz
        self.m = max(1, min(n // 20, int(round(rate_hz))))  # ~1 s blocks (at least 20 of them)
        self.k = n // self.m
        self.sums = np.empty((self.k, 3))
        self.nb = 0
        self.rest = np.zeros((0, 3))
        self.gmin = self.gmax = None

    def update(self, dtheta, gimbal=None) -> None:
        if self.nb < self.k:
            x = np.concatenate([self.rest, dtheta]) if self.rest.shape[0] else dtheta
            nfull = min(x.shape[0] // self.m, self.k - self.nb)
            take = nfull * self.m
            self.sums[self.nb: self.nb + nfull] = x[:take].reshape(nfull, self.m, 3).sum(axis=1)
            self.nb += nfull
            self.rest = x[take:] if self.nb < self.k else np.zeros((0, 3))
        if gimbal is not None and gimbal.shape[0]:
            lo, hi = gimbal.min(axis=0), gimbal.max(axis=0)
            self.gmin = lo if self.gmin is None else np.minimum(self.gmin, lo)
            self.gmax = hi if self.gmax is None else np.maximum(self.gmax, hi)

    def warning(self) -> str | None:
        k, m = self.k, self.m
        rates = self.sums[: self.nb] * self.rate_hz / m
        dev = rates - np.median(rates, axis=0)  # a gyro bias is not motion
        d = np.diff(rates, axis=0)  # noise from successive differences: robust to the turns themselves
        sig = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2) if k > 2 else np.zeros(3)
        thr = max(10 * OMEGA_IE, 6 * float(np.sqrt(np.sum(sig**2))))
        frac = float(np.mean(np.linalg.norm(dev, axis=1) > thr)) if k else 0.0
        moving = frac > 0.01
        why = f"the gyro rate departs from its median by more than {thr:.2g} rad/s in {100 * frac:.0f} % of it"
        if not moving and self.gmin is not None:
            span = float(np.max(self.gmax - self.gmin))
            if span > 1e-3:
                moving, why = True, f"the gimbal turns by {np.degrees(span):.3g} deg in it"
        if not moving:
            return None
        return (f"the window is not static ({why}): the Allan deviation mixes rotation into the noise; "
                "use --start/--stop on a static part of the record")


def stream_allan(data: Path, win, chunk_size: int = 1 << 18):
    """Gyro and accelerometer Allan deviations of the window ``win`` (:func:`inscal.io.record_window`)
    and its motion statistics, streamed in chunks: two passes (gyro with /time and /gimbal, then
    accelerometers), so memory holds about a quarter of one sensor's window, never the record.
    Returns ``(gyro AllanResult, accel AllanResult, MotionStats, (t_first, t_last))``."""
    from . import io
    from .analysis.allan import StreamingAllan

    n = win.n
    acc, mot = StreamingAllan(n, win.rate_hz), MotionStats(n, win.rate_hz)
    t_first = t_last = None
    for t, dth, g in io.iter_window(data, ("time", "dtheta", "gimbal"), win.i0, win.i1, chunk_size):
        t_first = float(t[0]) if t_first is None else t_first
        t_last = float(t[-1])
        acc.update(dth)
        mot.update(dth, g)
    gyro = acc.result()
    acc = None  # one phase history at a time
    acc = StreamingAllan(n, win.rate_hz)
    for (dv,) in io.iter_window(data, ("dvel",), win.i0, win.i1, chunk_size):
        acc.update(dv)
    return gyro, acc.result(), mot, (t_first, t_last)


def run_allan(data: Path, start_s: float = 0.0, stop_s: float | None = None, plot: Path | None = None,
              force: bool = False, warn=None) -> dict:
    """Allan deviation of a window of ``data``; ``warn(line)`` is called for a window that is not
    static (the warning is also in the result's ``warnings``).  The record is streamed in chunks
    (bounded memory, multi-day records included)."""
    from . import io

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
            raise CliError(f"only {win.n} samples between {start_s} s and {stop_s} s; need >= 1000 of a static window")
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
        from .report import allan_plot

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
        from rich.table import Table

        from rich.markup import escape

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
