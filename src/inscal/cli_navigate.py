"""``inscal navigate``: strapdown navigation of an IMU record, with error analysis."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from . import units
from .cliutil import CliError, check_not_input, check_output, fail, print_json

def _nmi(x_m: float) -> float:
    return float(units.from_si(x_m, "nmi"))


def _as(x):
    return None if x is None else units.from_si(np.asarray(x, dtype=float), "arcsec")


def report(res, data: Path, params: Path | None, n: int, rate: float, has_truth: bool, out: Path | None) -> dict:
    """The ``--json`` document (field units: m, nmi, m/s, arcsec, h)."""
    s = res.summary
    rep = {
        "data": str(data),
        "params": None if params is None else str(params),
        "out": None if out is None else str(out),
        "samples": n,
        "rate_hz": rate,
        "mode": res.config.mode,
        "vertical_channel": res.config.vertical,
        "init": res.init,
        "truth": has_truth,
        "duration_h": units.from_si(s["duration_s"], "h"),
        "max_position_error_m": s["max_position_error_m"],
        "final_position_error_m": s["final_position_error_m"],
        "max_position_error_nmi": _nmi(s["max_position_error_m"]),
        "final_position_error_nmi": _nmi(s["final_position_error_m"]),
        "final_position_error_east_north_m": s["final_position_error_en_m"],
        "max_velocity_error_mps": s["max_velocity_error_mps"],
        "max_velocity_error_enu_mps": s["max_velocity_error_enu_mps"],
    }
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


def run_navigate(data: Path, params: Path | None = None, mode: str = "free", vertical: str = "hold",
                 init: str = "auto", align_coarse_s: float = 60.0, align_fine_s: float = 600.0,
                 output_rate_hz: float = 1.0, out: Path | None = None, force: bool = False, warn=None,
                 gravity: str | None = None) -> dict:
    """Navigate ``data`` (see the command); ``warn(line)`` is called at once for each
    provenance warning (they are also in the result's ``warnings``).  ``gravity`` (wgs84 | psins |
    m/s^2) overrides the record's gravity model."""
    from . import io, navigation as nv
    from .strapdown import NavConfig

    if out is not None:
        check_output(out, force)
        check_not_input(out, data, *([params] if params is not None else []))
    try:
        info = io.record_info(data)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise CliError(str(exc)) from None
    if gravity is not None:
        import dataclasses

        from .cli_simulate import parse_gravity_option

        info = dataclasses.replace(info, site=info.site.with_gravity(parse_gravity_option(gravity)))
    imu = gim = None
    warnings = []
    if params is not None:
        try:
            from .paramfile import load_params
        except ImportError:  # pragma: no cover - the parameter-file module ships with inscal
            raise CliError("this inscal cannot read parameter files") from None
        try:
            imu, gim, pmeta = load_params(params)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        from .cli_compensate import compensated_with, provenance_mismatch, record_attrs

        attrs = record_attrs(data)
        mismatch = provenance_mismatch(data, params, pmeta, attrs)
        if mismatch:
            warnings.append(mismatch)
        done = compensated_with(attrs)
        if done is not None:
            warnings.append(f"{data} is already compensated (with {done}): --params applies a correction again")
        for w in warnings:
            if warn is not None:
                warn(w)
    try:
        config = NavConfig(mode=mode, vertical=vertical, output_rate_hz=output_rate_hz)
        align_cfg = nv.AlignConfig(coarse_time=align_coarse_s, fine_time=align_fine_s)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    scenario = io.scenario_from_record(info) if (info.truth is not None and info.path is not None) else None
    if init == "auto":
        init = "truth" if scenario is not None else "align"
    if init not in ("truth", "align"):
        raise CliError(f"--init must be auto, truth or align, got {init!r}")
    if init == "truth" and scenario is None:
        raise CliError(f"{data} has no truth (not a simulated record): use --init align")
    if init == "align" and info.n_samples / info.rate_hz <= align_coarse_s + align_fine_s:
        raise CliError(f"{data} lasts {info.n_samples / info.rate_hz:g} s, not longer than the alignment "
                       f"({align_coarse_s:g} s coarse + {align_fine_s:g} s fine)")
    try:
        res = nv.navigate(io.iter_chunks(data), info.rate_hz, info.site, init=init, scenario=scenario,
                          params=imu, gimbal_model=gim, config=config, align_config=align_cfg)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if out is not None:
        meta = {"data": str(data), "params": None if params is None else str(params),
                "gimbal_nonorthogonality_rad": 0.0 if gim is None else gim.nonorthogonality}
        try:
            nv.write_nav(out, res, meta, overwrite=force)
        except (FileExistsError, FileNotFoundError, OSError) as exc:
            raise CliError(str(exc)) from None
    rep = report(res, data, params, info.n_samples, info.rate_hz, scenario is not None, out)
    rep["gravity"] = {**info.site.gravity_model.to_json(), "g_site_m_s2": info.site.gravity}
    rep["warnings"] = warnings
    return rep


def register(app: typer.Typer) -> None:
    @app.command()
    def navigate(
        data: Path = typer.Argument(..., help="IMU record (HDF5, from `inscal simulate` or recorded)"),
        params: Path = typer.Option(None, "--params", help="calibration parameter file (TOML) applied on the fly"),
        mode: str = typer.Option("free", "--mode", help="free (pure inertial) or damped (horizontal damping, zero reference velocity)"),
        vertical: str = typer.Option("hold", "--vertical", help="vertical channel: hold (v_U = 0, h = site) or damped (3rd-order loop)"),
        init: str = typer.Option("auto", "--init", help="auto (truth if the record has it, else align), truth or align"),
        align_coarse_s: float = typer.Option(60.0, "--align-coarse-s", help="coarse alignment time [s]"),
        align_fine_s: float = typer.Option(600.0, "--align-fine-s", help="Kalman fine alignment time [s]"),
        output_rate_hz: float = typer.Option(1.0, "--output-rate-hz", help="rate of the navigation output [Hz]"),
        out: Path = typer.Option(None, "--out", "-o", help="write the navigation solution (HDF5)"),
        force: bool = typer.Option(False, "--force", help="overwrite an existing output file"),
        gravity: str = typer.Option(None, "--gravity", help="gravity model: wgs84 | psins | a measured value in m/s^2 "
                                    "(default: the record's)"),
        json_: bool = typer.Option(False, "--json", help="print the results as JSON"),
    ):
        """Navigate (strapdown, pure inertial or damped) and report the errors on a static base."""
        try:
            rep = run_navigate(data, params, mode, vertical, init, align_coarse_s, align_fine_s, output_rate_hz, out,
                               force, warn=lambda w: typer.echo(f"inscal: warning: {w}", err=True), gravity=gravity)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(rep)
            return
        typer.echo(f"{rep['data']}: {rep['duration_h']:.2f} h navigated ({rep['mode']}, vertical {rep['vertical_channel']}, "
                   f"init {rep['init']}{', params ' + rep['params'] if rep['params'] else ''})")
        typer.echo(f"  position error: max {rep['max_position_error_m']:.3f} m ({rep['max_position_error_nmi']:.4f} nmi), "
                   f"final {rep['final_position_error_m']:.3f} m ({rep['final_position_error_nmi']:.4f} nmi)")
        typer.echo(f"  velocity error: max {rep['max_velocity_error_mps']:.4f} m/s (horizontal)")
        if "max_attitude_error_arcsec" in rep:
            a = rep["max_attitude_error_arcsec"]
            typer.echo(f"  attitude error: max roll {a['roll']:.2f}\", pitch {a['pitch']:.2f}\", yaw {a['yaw']:.2f}\"")
        for name in ("position_east", "position_north"):
            c = rep["oscillation_amplitudes"][name]
            parts = [f"{k} {c[k]:.3f} {c['unit']}" for k in ("schuler", "foucault", "earth") if c[k] is not None]
            if parts:
                typer.echo(f"  {name.replace('_', ' ')}: " + ", ".join(parts))
        if rep["out"]:
            typer.echo(f"  -> {rep['out']}")
