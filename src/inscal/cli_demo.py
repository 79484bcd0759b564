"""``inscal demo``: the main job on built-in defaults.

1. simulate the S16 (Table 1 path, extended error model) and N25 (twelve positions,
   gimbal non-orthogonality) scenarios into DIR;
2. Allan deviation of the N25 record's first static window;
3. calibrate the N25 record with the proposed method and the joint fit, and compare
   with the truth;
4. navigate a rotation-modulated run with and without the calibration.
"""

from __future__ import annotations

import time
from pathlib import Path

import typer

from .cliutil import CliError, fail, print_json


def run_demo(out: Path, force: bool, seed: int, quick: bool, show_progress: bool, log) -> dict:
    from .cli_simulate import run_simulate

    out.mkdir(parents=True, exist_ok=True)
    res: dict = {"out": str(out), "seed": seed, "steps": {}}
    t0 = time.perf_counter()
    for name in ("s16", "n25"):
        r = run_simulate(name, out / f"{name}.h5", seed=seed, force=force, show_progress=show_progress)
        res["steps"][f"simulate_{name}"] = r
        log(f"simulated {name}: {r['samples']} samples, {r['duration_s'] / 3600:.2f} h -> {r['out']}")
    from .cli_allan import run_allan

    a = run_allan(out / "n25.h5", 0.0, 100.0)
    res["steps"]["allan_n25"] = {k: a[k] for k in ("arw_deg_rth", "vrw_ug_rthz")}
    log("Allan (N25 first dwell): ARW " + ", ".join(f"{v:.4f}" for v in a["arw_deg_rth"]) + " deg/rt(h) (true 0.02); VRW "
        + ", ".join(f"{v:.1f}" for v in a["vrw_ug_rthz"]) + " ug/rt(Hz) (true 20)")
    for stage in _STAGES:
        stage(out, force, seed, quick, show_progress, log, res)
    res["elapsed_s"] = time.perf_counter() - t0
    return res


#: later stages (calibration, navigation) append themselves here
_STAGES: list = []


def register(app: typer.Typer) -> None:
    @app.command()
    def demo(
        out: Path = typer.Option(Path("demo-output"), "--out", "-o", help="folder for the demo's files"),
        force: bool = typer.Option(False, "--force", help="overwrite files from an earlier demo"),
        seed: int = typer.Option(1, help="seed of the noise generators"),
        quick: bool = typer.Option(False, "--quick", help="shorter navigation run"),
        json_: bool = typer.Option(False, "--json", help="print the results as JSON"),
    ):
        """Run the main job on built-in defaults: simulate, calibrate, navigate, compare."""
        log = (lambda msg: None) if json_ else typer.echo
        try:
            res = run_demo(out, force, seed, quick, not json_, log)
        except CliError as exc:
            raise fail(str(exc)) from None
        if json_:
            print_json(res)
        else:
            typer.echo(f"demo finished in {res['elapsed_s']:.1f} s; files in {res['out']}/")
