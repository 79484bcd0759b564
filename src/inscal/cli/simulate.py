"""``inscal simulate``: make an IMU record (HDF5) from a built-in or TOML scenario."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from inscal.cli.common import CliError, LazyModule, call, check_output, parse_gravity_option, print_json, short
from inscal.cli.options import ForceOption, JsonOption, SeedOption

np = LazyModule("numpy")


def summary(sc, out: Path, seed: int | None, n: int) -> dict:
    return {
        "scenario": sc.name,
        "out": str(out),
        "samples": n,
        "duration_s": n / sc.rate_hz,
        "rate_hz": sc.rate_hz,
        "path": sc.path.name,
        "moves": len(sc.path.moves),
        "seed": seed,
        "site": {"latitude_deg": math.degrees(sc.site.latitude), "longitude_deg": math.degrees(sc.site.longitude),
                 "height_m": sc.site.height},
        "gravity": {**sc.site.gravity_model.to_json(), "g_site_m_s2": sc.site.gravity},
        "noise": not sc.noise.is_zero,
        **({"temperature": _temperature_summary(sc)} if sc.temperature is not None else {}),
    }


def _temperature_summary(sc) -> dict:
    """The scenario's temperature profile and sensor, and whether the IMU errors follow it."""
    t = np.linspace(0.0, float(sc.path.duration), 2001)
    T, rate = sc.temperature.at(t)
    s = sc.temperature_sensor
    return {"min_c": float(T.min()), "max_c": float(T.max()), "max_rate_c_per_min": float(np.max(np.abs(rate)) * 60.0),
            "sensors": list(s.names), "sensor_rate_hz": s.rate_hz, "thermal_model": sc.has_thermal}


def _with_gravity(sc, text: str):
    from dataclasses import replace

    return replace(sc, site=sc.site.with_gravity(parse_gravity_option(text)))


#: bytes a record stores per sample: time (8), dtheta (3 x 8), dvel (3 x 8), gimbal (2 x 8), float64
BYTES_PER_SAMPLE = 8 * (1 + 3 + 3 + 2)
#: more samples than this is not a sensible simulation (10^10: 3.2 years at 100 Hz, 720 GB)
MAX_SAMPLES = 10**10
#: room kept free beside the record (HDF5 metadata, truth, the file system)
HEADROOM_BYTES = 64 << 20


def _human(nbytes: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if nbytes < 1000 or unit == "PB":
            return f"{nbytes:.3g} {unit}"
        nbytes /= 1000
    return f"{nbytes:.3g} PB"  # pragma: no cover


def check_size(sc, out: Path) -> int:
    """Refuse (one line) a record with an absurd number of samples or one larger than the free
    space of the output folder, before anything is written.  Returns the estimated bytes."""
    import shutil

    dur = sc.path.duration
    n_exact = dur * sc.rate_hz
    if not math.isfinite(n_exact) or n_exact > MAX_SAMPLES:
        raise CliError(f"{short(sc.name, 60)}: {n_exact:.3g} samples ({dur / 3600:.3g} h at {sc.rate_hz:g} Hz) is not a "
                       f"sensible record (at most {MAX_SAMPLES:.0e} samples); check the duration, the rate and the path's angles")
    n = sc.n_samples
    need = n * BYTES_PER_SAMPLE
    folder = out.parent if str(out.parent) else Path(".")
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return need  # the write itself reports an unusable folder
    if need + HEADROOM_BYTES > free:
        raise CliError(f"{short(out)} would take about {_human(need)} ({n} samples x {BYTES_PER_SAMPLE} bytes) but "
                       f"{short(folder)} has {_human(free)} free; shorten --duration-h or lower --rate-hz")
    return need


def run_simulate(scenario: str, out: Path, seed: int = 0, duration_h: float | None = None,
                 rate_hz: float | None = None, force: bool = False, show_progress: bool = True,
                 no_noise: bool = False, gravity: str | None = None) -> dict:
    from inscal.core.progress import ProgressBar
    from inscal.sim import scenarios
    from inscal.sim import simulate as sim

    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise CliError(f"--rate-hz must be positive, got {rate_hz:g}")
    try:
        sc = scenarios.build(scenario, duration_s=None if duration_h is None else duration_h * 3600.0, rate_hz=rate_hz)
    except ValueError as exc:  # ScenarioError, PathError, unit errors
        raise CliError(str(exc)) from None
    if gravity is not None:
        sc = _with_gravity(sc, gravity)
    if no_noise:
        from dataclasses import replace

        from inscal.core.error_model import ImuNoise

        sc = replace(sc, noise=ImuNoise())
    check_output(out, force)
    check_size(sc, out)
    rng = np.random.default_rng(seed)
    with ProgressBar(f"simulating {sc.name}", sc.n_samples, show_progress, lines=False, transient=True) as bar:
        try:
            n = sim.write_simulation(out, sc, rng, overwrite=force, progress=bar.update)
        except (FileExistsError, FileNotFoundError, ValueError, OSError) as exc:  # OSError: e.g. a read-only folder
            raise CliError(str(exc)) from None
    res = summary(sc, out, seed, n)
    if duration_h is not None:
        res["requested_duration_s"] = duration_h * 3600.0
        path_s = float(sc.path.duration)
        if abs(path_s - duration_h * 3600.0) > 0.5 / sc.rate_hz:
            res["duration_note"] = (f"--duration-h {duration_h:g} gives {path_s / 3600:.4g} h: the path is made of whole "
                                    f"cycles of {sc.path.name} ({len(sc.path.moves)} moves), rounded up")
    return res


def register(app: typer.Typer) -> None:
    @app.command()
    def simulate(
        scenario: str = typer.Argument(..., help="built-in scenario (s16, s16-table3, s16-gimbal, psins19, n25, n25-rotmod, "
                                       "n25-static, static, static-24h, rotmod16, rotmod16-6h, thermal-plateaus, "
                                       "thermal-plateaus-s16, thermal-ramp, thermal-cycle, thermal-warmup; without a "
                                       "turntable: handheld-mems, handheld-tactical, handheld-navigation) or a .toml file"),
        out: Path = typer.Option(..., "--out", "-o", help="output HDF5 record"),
        seed: SeedOption = 0,
        duration_h: float = typer.Option(None, "--duration-h", metavar="HOURS", help="duration in hours (static, rotation-modulation and thermal-warmup scenarios)"),
        rate_hz: float = typer.Option(None, "--rate-hz", help="sampling rate [Hz] (default: the scenario's)"),
        force: ForceOption = False,
        no_noise: bool = typer.Option(False, "--no-noise", help="drop the scenario's stochastic errors (deterministic errors stay)"),
        gravity: str = typer.Option(None, "--gravity", metavar="MODEL", help="gravity model: wgs84 | psins | a measured value in m/s^2 "
                                    "(default: the scenario's, wgs84 unless its site table says otherwise)"),
        json_: JsonOption = False,
    ):
        """Simulate an IMU on a dual-axis turntable (or hand-held) and write an HDF5 record."""
        res = call(run_simulate, scenario, out, seed, duration_h, rate_hz, force, show_progress=not json_, no_noise=no_noise,
                           gravity=gravity)
        if json_:
            print_json(res)
        else:
            typer.echo(f"{short(res['scenario'])}: {res['samples']} samples, {res['duration_s']:.1f} s at {res['rate_hz']:g} Hz, "
                       f"path {res['path']} ({res['moves']} moves) -> {res['out']}")
            if "duration_note" in res:
                typer.echo(f"  note: {res['duration_note']}")
            if "temperature" in res:
                t = res["temperature"]
                typer.echo(f"  temperature {t['min_c']:.1f} .. {t['max_c']:.1f} degC (at most {t['max_rate_c_per_min']:.2f} "
                           f"degC/min), {len(t['sensors'])} sensor(s) at {t['sensor_rate_hz']:g} Hz in /temperature"
                           + ("; the IMU errors follow it (thermal model in /truth/thermal)" if t["thermal_model"] else ""))
