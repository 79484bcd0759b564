"""``inscal navigate``: strapdown navigation of an IMU record, with error analysis."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.common import (CliError, LazyModule, call, check_not_input, check_output, load_checked_params, np,
    print_json, short, thermal_compensation, warn)
from inscal.cli.options import (ForceOption, JsonOption, TemperatureOption, gravity_option, options_of, out_option,
                                plot_option)

units = LazyModule("inscal.core.units")  # np, units: imported on first use (fast start of the command line)

def _nmi(x_m: float) -> float:
    return float(units.from_si(x_m, "nmi"))


def _as(x):
    return None if x is None else units.from_si(np.asarray(x, dtype=float), "arcsec")


def report(res, data: Path, params: Path | None, n: int, rate: float, has_truth: bool, out: Path | None,
           gimbal_model=None) -> dict:
    """The ``--json`` document (field units: m, nmi, m/s, arcsec, h; the final vehicle attitude in
    degrees, with the heading, clockwise from North, beside the yaw, counter-clockwise from East)."""
    from inscal.report.figures import heading_deg

    s = res.summary
    rep = {
        "data": str(data),
        "params": None if params is None else str(params),
        "out": None if out is None else str(out),
        "samples": n,
        "rate_hz": rate,
        "mode": res.config.mode,
        "vertical_channel": res.config.vertical,
        "height_reference": None,
        "init": res.init,
        "truth": has_truth,
        "duration_h": units.from_si(s["duration_s"], "h"),
        "max_position_error_m": s["max_position_error_m"],
        "final_position_error_m": s["final_position_error_m"],
        "max_position_error_nmi": _nmi(s["max_position_error_m"]),
        "final_position_error_nmi": _nmi(s["final_position_error_m"]),
        "final_position_error_east_north_m": s["final_position_error_en_m"],
        "max_height_error_m": float(np.max(np.abs(res.errors.position[:, 2]))) if res.errors is not None else None,
        "final_height_error_m": float(res.errors.position[-1, 2]) if res.errors is not None else None,
        "max_velocity_error_mps": s["max_velocity_error_mps"],
        "max_velocity_error_enu_mps": s["max_velocity_error_enu_mps"],
    }
    if res.output.time.size:
        att = np.degrees(res.output.vehicle_attitude(gimbal_model)[-1])
        rep["final_attitude_deg"] = {"roll": float(att[0]), "pitch": float(att[1]), "yaw": float(att[2]),
                                     "heading": float(heading_deg(np.radians(att[2])))}
    if s["max_attitude_error_rad"] is not None:
        a = _as(s["max_attitude_error_rad"])
        rep["max_attitude_error_arcsec"] = {"roll": a[0], "pitch": a[1], "yaw": a[2]}
        rep["max_imu_attitude_error_arcsec"] = _as(s["max_imu_attitude_error_rad"])
    comps = {}
    for name, c in s["components"].items():
        conv = _as if name in ("roll", "pitch", "yaw") else (lambda v: v)
        unit = "arcsec" if name in ("roll", "pitch", "yaw") else ("m" if name.startswith("position") else "m/s")
        comps[name] = {"unit": unit, **{k: (None if c[k] is None else float(conv(c[k])))
                                        for k in ("schuler", "earth", "foucault")}}
    rep["oscillation_amplitudes"] = comps
    if res.alignment is not None:
        al = res.alignment
        rep["alignment"] = {
            "end_time_s": al.time_end,
            "gyro_bias_estimate_deg_h": units.from_si(al.gyro_bias, "deg/h"),
            "accel_bias_estimate_ug": units.from_si(al.accel_bias, "ug"),
            "attitude_sigma_arcsec": _as(al.sigma_phi),
        }
    return rep


PLOT_FORMATS = ("png", "pdf", "svg")


def parse_height_ref(value: str | None):
    """``--height-ref``: a constant height in metres, or a CSV file with columns time_s,height_m."""
    from inscal.nav.run import HeightReference

    if value is None:
        return None
    try:
        return HeightReference(float(value))
    except ValueError:
        pass
    path = Path(value)
    if not path.is_file():
        raise CliError(f"--height-ref {short(value)}: neither a number (metres) nor a CSV file (time_s,height_m)")
    try:
        return HeightReference.read_csv(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise CliError(f"--height-ref {short(path)}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None


@dataclass(frozen=True)
class NavigateOptions:
    """What ``inscal navigate`` is asked: navigate ``data`` (with the parameter file ``params`` applied on the
    fly) in ``mode`` (free | damped) with the ``vertical`` channel (hold | damped | free, on ``height_ref``: a
    constant [m] or a CSV), initialised by ``init`` (auto | truth | align, coarse and fine alignment times
    [s]), the solution at ``output_rate_hz`` written to ``out`` (``force``: over an existing file), its
    ``plot``; ``gravity`` (wgs84 | psins | m/s^2) overrides the record's gravity model; ``temperature`` [degC]:
    a constant temperature for the parameter file's thermal model
    (:func:`inscal.cli.common.thermal_compensation`)."""

    data: Path
    params: Path | None = None
    mode: str = "free"
    vertical: str = "hold"
    init: str = "auto"
    align_coarse_s: float = 60.0
    align_fine_s: float = 600.0
    output_rate_hz: float = 1.0
    out: Path | None = None
    force: bool = False
    gravity: str | None = None
    height_ref: str | None = None
    plot: Path | None = None
    temperature: float | None = None


def run_navigate(o: NavigateOptions, warn=None) -> dict:
    """Navigate as ``o`` says (:class:`NavigateOptions`); ``warn(line)`` is called at once for each
    provenance (and thermal range) warning (they are also in the result's ``warnings``)."""
    return navigate_file(o, warn)[0]


def navigate_file(o: NavigateOptions, warn=None):
    """:func:`run_navigate` returning ``(report, NavResult, gimbal model)`` (the demo draws the run)."""
    data, params, mode, vertical, init = o.data, o.params, o.mode, o.vertical, o.init
    align_coarse_s, align_fine_s, output_rate_hz, out, force = (o.align_coarse_s, o.align_fine_s, o.output_rate_hz,
                                                                o.out, o.force)
    gravity, height_ref, plot, temperature = o.gravity, o.height_ref, o.plot, o.temperature
    import warnings as pywarnings

    from inscal import io
    from inscal import nav as nv
    from inscal.nav.strapdown import NavConfig
    from inscal.sim import simulate as sim

    if out is not None:
        check_output(out, force)
        check_not_input(out, data, *([params] if params is not None else []))
    if plot is not None:
        fmt = plot.suffix.lower().lstrip(".")
        if fmt not in PLOT_FORMATS:
            raise CliError(f"--plot {short(plot)}: unknown plot format {short(plot.suffix or '(none)', 20)!r}; "
                           "use a .png, .pdf or .svg name")
        check_output(plot, force)
        check_not_input(plot, data, *([params] if params is not None else []), what="--plot")
        if out is not None and Path(plot).resolve() == Path(out).resolve():
            raise CliError("--plot and --out must be different files")
    href = parse_height_ref(height_ref)
    if href is not None and vertical == "free":
        raise CliError("--height-ref needs --vertical damped (or hold): a free vertical channel uses no reference")
    try:
        info = io.record_info(data)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CliError(str(exc)) from None
    if gravity is not None:
        import dataclasses

        from inscal.cli.common import parse_gravity_option

        info = dataclasses.replace(info, site=info.site.with_gravity(parse_gravity_option(gravity)))
    imu = gim = comp = None
    warnings = []
    if params is None and temperature is not None:
        raise CliError("--temperature is the temperature of a parameter file's thermal model: give --params")
    if params is not None:
        imu, gim, pmeta = load_checked_params(params)
        from inscal.io.paramfile import provenance_mismatch
        from inscal.io.records import compensated_with, record_attrs

        attrs = record_attrs(data)
        mismatch = provenance_mismatch(data, params, pmeta, attrs)
        if mismatch:
            warnings.append(mismatch)
        done = compensated_with(attrs)
        if done is not None:
            warnings.append(f"{data} is already compensated (with {done}): --params applies a correction again")
        comp, _, twarn = thermal_compensation(data, params, pmeta, info, imu, temperature)
        warnings += twarn
        for w in warnings if warn is not None else ():
            warn(w)
    try:
        config = NavConfig(mode=mode, vertical=vertical, output_rate_hz=output_rate_hz)
        align_cfg = nv.AlignConfig(coarse_time=align_coarse_s, fine_time=align_fine_s)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    scenario = None
    if info.truth is not None and info.path is not None:
        try:
            scenario = sim.scenario_from_record(info)
        except ValueError as exc:
            raise CliError(f"{short(data)}: its truth does not make a scenario ({exc})") from None
    if init == "auto":
        init = "truth" if scenario is not None else "align"
    if init not in ("truth", "align"):
        raise CliError(f"--init must be auto, truth or align, got {init!r}")
    if init == "truth" and scenario is None:
        raise CliError(f"{data} has no truth (not a simulated record): use --init align")
    needed, what = nv.samples_needed(info.rate_hz, config, init, align_cfg)
    if info.n_samples < needed:
        raise CliError(f"{data}: {nv.too_short(info.n_samples, info.rate_hz, needed, what)}")
    try:
        with pywarnings.catch_warnings():  # the thermal range was surveyed (and warned about) above
            pywarnings.simplefilter("ignore", RuntimeWarning)
            res = nv.navigate(io.iter_chunks(data), info.rate_hz, info.site, init=init, scenario=scenario,
                              params=imu, gimbal_model=gim, config=config, align_config=align_cfg, height_ref=href,
                              thermal=comp)
    except ValueError as exc:
        raise CliError(f"{data}: {exc}") from None
    if out is not None:
        meta = {"data": str(data), "params": None if params is None else str(params),
                "gimbal_nonorthogonality_rad": 0.0 if gim is None else gim.nonorthogonality}
        try:
            nv.write_nav(out, res, meta, overwrite=force)
        except (FileExistsError, FileNotFoundError, OSError) as exc:
            raise CliError(str(exc)) from None
    if href is not None:
        span = href.span()
        t_nav = (float(res.output.time[0]), float(res.output.time[-1]))
        if span is not None and (span[0] > t_nav[0] + 1.0 or span[1] < t_nav[1] - 1.0):
            w = (f"--height-ref {short(height_ref)} covers {span[0]:g} s to {span[1]:g} s, the navigation "
                 f"{t_nav[0]:g} s to {t_nav[1]:g} s: its end values are held outside")
            warnings.append(w)
            if warn is not None:
                warn(w)
    if plot is not None:
        from inscal.report.figures import navigation_plot

        title = (f"{Path(data).name}{' with ' + Path(params).name if params is not None else ''}: "
                 f"{res.config.mode}, vertical {res.config.vertical}, init {res.init}")
        try:
            navigation_plot(plot, res, title, gim, overwrite=force)
        except (FileExistsError, FileNotFoundError, OSError) as exc:
            raise CliError(f"--plot {short(plot)}: {getattr(exc, 'strerror', None) or exc}") from None
    rep = report(res, data, params, info.n_samples, info.rate_hz, scenario is not None, out, gim)
    if href is not None:
        rep["height_reference"] = ({"height_m": float(href.height[0])} if href.constant else
                                   {"file": str(height_ref), "span_s": list(href.span()), "points": int(href.time.size)})
    rep["plot"] = None if plot is None else str(plot)
    rep["gravity"] = {**info.site.gravity_model.to_json(), "g_site_m_s2": info.site.gravity}
    rep["thermal"] = res.thermal
    rep["warnings"] = warnings
    return rep, res, gim


def register(app: typer.Typer) -> None:
    @app.command()
    def navigate(
        data: Path = typer.Argument(..., help="IMU record (HDF5, from `inscal simulate` or recorded)"),
        params: Annotated[Path | None, typer.Option("--params", metavar="PARAMS.toml", help=(
            "calibration parameter file (TOML) applied on the fly"))] = None,
        mode: str = typer.Option("free", "--mode", metavar="free|damped", help="free (pure inertial) or damped (horizontal damping, zero reference velocity)"),
        vertical: str = typer.Option("hold", "--vertical", metavar="hold|damped|free", help="vertical channel: hold (v_U = 0, h = site), damped "
                                     "(3rd-order loop on the reference height) or free (pure inertial: diverges, e-folding ~9.5 min)"),
        height_ref: str = typer.Option(None, "--height-ref", metavar="M|CSV", help="external height for --vertical damped/hold: a constant "
                                       "in metres, or a CSV file with columns time_s,height_m (interpolated)"),
        plot: plot_option("plot of the run (.png, .pdf, .svg): position error E/N/U [m] and horizontal [nmi], "
                          "attitude error (or attitude and heading)") = None,
        init: str = typer.Option("auto", "--init", metavar="auto|truth|align", help="auto (truth if the record has it, else align), truth or align"),
        align_coarse_s: float = typer.Option(60.0, "--align-coarse-s", help="coarse alignment time [s]"),
        align_fine_s: float = typer.Option(600.0, "--align-fine-s", help="Kalman fine alignment time [s]"),
        output_rate_hz: float = typer.Option(1.0, "--output-rate-hz", help="rate of the navigation output [Hz]"),
        out: out_option("write the navigation solution (HDF5)", required=False) = None,
        force: ForceOption = False,
        gravity: gravity_option("the record's") = None,
        temperature: TemperatureOption = None,
        json_: JsonOption = False,
    ):
        """Navigate (strapdown, pure inertial or damped) and report the errors on a static base.  A parameter
        file with a thermal model is applied at the record's temperature."""
        rep = call(run_navigate, options_of(NavigateOptions, locals()), warn=warn)
        if json_:
            print_json(rep)
            return
        from inscal.report.text import navigation_lines

        for line in navigation_lines(rep):
            typer.echo(line)
