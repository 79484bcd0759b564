"""The steps of the warm-up (:mod:`inscal.cli.warmup`): the commands' own ``run_*`` functions on short records
of the built-in scenarios, and the kernels that no command reaches from Python, with their callers' argument
types."""

from __future__ import annotations

from pathlib import Path

#: the records of the warm-up: name -> (base scenario, path builder and its arguments, extra TOML tables)
RECORDS = {
    "s16": ("s16", ("s16_table1", {"rate_dps": 20.0, "dwell_s": 10.0, "accel_dps2": 20.0}), {}),
    "s16-gimbal": ("s16-gimbal", ("s16_table1", {"rate_dps": 20.0, "dwell_s": 10.0, "accel_dps2": 20.0}), {}),
    "n25": ("n25", ("n25_twelve", {"dwell_s": 25.0, "rate_dps": 20.0, "rate_test_dps": 20.0, "rate_test_turns": 1,
                                   "accel_dps2": 20.0}), {}),
    "n25-rotmod": ("n25", ("rotmod16", {"duration_s": 60.0, "dwell_s": 5.0}), {}),
    "n25-static": ("n25", ("static", {"duration_s": 200.0}), {}),
    "asynchrony": ("s16", ("static", {"duration_s": 2.0}),
                   {"errors": {"time_asynchrony": {"value": 0.1, "unit": "ms"}}}),
}

def scenario_files(folder: Path) -> dict[str, Path]:
    """Write the scenario TOML files of :data:`RECORDS` into ``folder``; returns name -> file."""
    import tomli_w

    from inscal import SCHEMA_VERSION
    from inscal.core import turntable

    files = {}
    for name, (base, (builder, kw), extra) in RECORDS.items():
        path = getattr(turntable, builder)(**kw)
        doc = {"schema_version": SCHEMA_VERSION, "base": base, "scenario": {"name": f"warmup-{name}"}, **extra,
               "path": path.to_dict()}
        files[name] = folder / f"{name}.toml"
        files[name].write_text(tomli_w.dumps(doc), encoding="utf-8")
    return files


def _records(tmp: Path) -> None:
    from inscal.cli.simulate import run_simulate

    for name, toml in scenario_files(tmp).items():
        run_simulate(str(toml), tmp / f"{name}.h5", seed=1, force=True, show_progress=False)


def _systematic(tmp: Path) -> None:
    from inscal.cli.calibrate import run_calibrate
    from inscal.cli.calibrate_setup import CalibrateOptions

    run_calibrate(CalibrateOptions(tmp / "s16.h5", "systematic51", tmp / "s16-51.toml", force=True))
    run_calibrate(CalibrateOptions(tmp / "s16.h5", "systematic30", tmp / "s16-30.toml", force=True))
    run_calibrate(CalibrateOptions(tmp / "s16-gimbal.h5", "unified", tmp / "unified.toml", force=True))


def _observability(tmp: Path) -> None:
    from inscal.cli.observability import run_observability

    run_observability(str(tmp / "s16.toml"))


def _n25_methods(tmp: Path) -> None:
    from inscal.cli.calibrate import run_calibrate
    from inscal.cli.calibrate_setup import CalibrateOptions

    for method in ("six-position", "twelve-position", "n25", "joint"):
        run_calibrate(CalibrateOptions(tmp / "n25.h5", method, tmp / f"params-{method}.toml", force=True))


def _bound(tmp: Path) -> None:
    from inscal.cli.design import DesignOptions, run_design
    from inscal.cli.observability import CrlbOptions, run_crlb

    run_crlb(CrlbOptions(str(tmp / "s16.toml")))
    run_design(DesignOptions(tmp / "designed.toml", 3.0, candidates=2, population=2, scheduler="none", force=True,
                             progress=False))


def _navigate(tmp: Path) -> None:
    from inscal.cli.navigate import NavigateOptions, run_navigate

    rm = tmp / "n25-rotmod.h5"
    run_navigate(NavigateOptions(rm))
    params = tmp / "params-n25.toml"
    run_navigate(NavigateOptions(rm, params=params if params.is_file() else None, vertical="damped", height_ref="0"))
    run_navigate(NavigateOptions(tmp / "n25-static.h5", init="align", align_coarse_s=60.0, align_fine_s=60.0))


def _library(tmp: Path) -> None:
    """What no command above reaches: the PSINS gravity formula (``--gravity psins``, a site table's
    ``gravity = "psins"``) and the normal gravity called from Python at a latitude alone, the
    covariance-form Kalman steps (tests and benchmark), the square-root and smoother steps called from Python
    (the filters call them from their compiled passes, which caches other entries) and the bias-instability
    recursion of the noise-only simulation (``montecarlo --set simulation=reuse``), the streamed Allan variance's kernels, with the argument types
    their callers use."""
    import numpy as np

    from inscal.analysis.noise.estimators import StreamingScaleVariance
    from inscal.core import kalman
    from inscal.core.earth import normal_gravity, parse_gravity
    from inscal.sim.kernel import gauss_markov_filter

    acc = StreamingScaleVariance(4096, 100.0, 2, [1, 2], piece=1024)  # the streamed Allan variance (inscal
    acc.update(np.zeros((4096, 2)))  # noise), in pieces that shift its history
    parse_gravity("psins").g(0.5, 10.0)
    normal_gravity(0.5)
    gauss_markov_filter(np.zeros((2, 3)), 0.5, np.zeros(3))
    n, N = 9, 12
    P = np.eye(N)
    kalman.predict(P, n, np.eye(n), np.zeros((n, N - n)), np.eye(n) * 1e-6, np.zeros(N - n))
    idx = np.arange(3, dtype=np.int64)
    K, Sinv, x = np.empty((N, 3)), np.empty((3, 3)), np.empty(N)
    kalman.update(P, idx, np.ones(3), np.zeros(3), K, Sinv, x)
    kalman.update_dense(P, np.eye(N)[:3].copy(), np.eye(3), np.zeros(3), K, Sinv, x)
    U = np.eye(N)
    kalman.sr_predict(U, n, np.eye(n), np.zeros((n, N - n)), np.eye(n) * 1e-6)
    kalman.sr_update(U, idx, np.ones(3), np.zeros(3), K, Sinv, x)
    lam, Lam = np.zeros(N), np.zeros((N, N))
    kalman.smoother_step(lam, Lam, idx, K, Sinv, np.zeros(3))
    kalman.adjoint_back(lam, Lam, n, np.eye(n), np.zeros((n, N - n)))
    kalman.smoothed_constant(np.eye(N), lam, Lam, n, np.zeros(N - n), np.eye(N - n))
    kalman.smoothed(np.eye(N), lam, Lam)  # the plain form (the benchmark's replay and the tests use it)
    Rb = np.zeros((N, N))  # the square-root information smoother's steps (tests and bench/smoother_positivity.py)
    kalman.info_rows(Rb, idx, np.ones(3))
    kalman.info_rows_dense(Rb, np.eye(N)[:3].copy(), np.eye(3))
    kalman.info_back(Rb, n, np.eye(n), np.zeros((n, N - n)), kalman.noise_factor(np.eye(n) * 1e-6))
    kalman.sr_smoothed(np.eye(N), Rb, n, np.eye(N - n))


STEP_FUNCTIONS = {"records": _records, "systematic": _systematic, "observability": _observability,
                  "n25-methods": _n25_methods, "bound": _bound, "navigate": _navigate, "library": _library}
