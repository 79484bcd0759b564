"""The registry of Monte Carlo studies (``register_experiment``, ``get_experiment``) and the built-in
experiments (N25 section 5, S16 section 4), one module each (``fig5``, ``schemes``, ``table2``;
shared helpers in ``common``).

``n25-fig5``
    N25 Figure 5: the relative standard deviation (std / true value) of the estimated
    gimbal non-orthogonality for dtheta in 1 ... 40 arcsec.  Scenario: the built-in ``n25``
    scenario (N25 site, mount attitude [0.1, 0.1, 20] deg, ARW 0.02 deg/sqrt(h),
    VRW 20 ug/sqrt(Hz), FOG-grade IMU errors :data:`inscal.sim.scenarios.N25_ERRORS`, twelve
    positions of 100 s plus rate tests, 100 Hz) with its non-orthogonality set to each
    value.  Calibration method ``n25`` unless ``method`` says otherwise.
``n25-schemes``
    Bias and standard deviation of the error of every calibrated parameter, per scheme:
    scheme 1 = method ``n25`` (N25), scheme 2 = ``six-position`` (traditional, ignores
    non-orthogonality and leveling), scheme 3 = ``systematic30`` (N25: "system-level Kalman
    calibration plus discrete calibration of the gimbal rotation matrices"; the N25 IMU has
    linear errors only, so the 30-state S16 filter is the natural system-level method,
    ``systematic51`` may be named instead), ``joint`` (joint nonlinear least squares).  Every
    run simulates one record and calibrates it with every method (paired comparison:
    the schemes see the same noise, so their differences are measured more precisely).
    Scheme 3 reads the increments (no segmentation) and estimates the IMU in its own
    gyro-defined frame: its errors are taken against the truth mapped into that frame
    (``res.truth_transform``; N25 maps scheme 3's estimates into the turntable frame with
    the known rotations instead, the same to first order), the 3 gyro angles that define
    the frame are not estimates and are left out, and the gimbal parameters, which it does
    not estimate, are absent (never zero errors).  See :func:`result_errors`.
``s16-table2``
    S16 section 4.1 / Table 2: per run the built-in ``s16`` scenario is simulated with the
    run's generator and calibrated with ``systematic51`` and ``systematic30``; recorded per
    method are the error and 1 sigma of every estimated component (field units, truth in the
    filter's frame) and the NEES of the parameter error state (e from
    :meth:`~inscal.calibrate.systematic.CompParams.error_state`, P = ``res.covariance["P"]``,
    dof = len(e)).  Summary: per group the median over runs of the mean absolute error against the
    S16 Table 2 figures (:data:`S16_TABLE2`) and against its expectation from the reported
    sigma (sqrt(2/pi) x mean sigma: a target below it is not reachable from this record),
    51 vs 30 for every group, the mean NEES against its 95 % chi-square band
    (:func:`nees_band`), and per parameter the RMS of error/sigma (should lie in
    ``z_rms_band``, default [0.8, 1.2]; :func:`rms_z_band` gives its sampling band).

All draw all randomness from the generator a run is given: only the sensor noise is
random; the true errors are the scenario's.

Parameters (``inscal montecarlo EXPERIMENT --set KEY=VALUE``; ``--list`` shows defaults):
``arw_deg_rt_h``, ``vrw_ug_rt_hz`` (N25: 0.02, 20), ``dwell_s`` (100), ``rate_hz`` (100),
``simulation`` (below); ``n25-fig5``: ``dtheta_arcsec`` (list), ``method`` (``n25``),
``uncertainty`` (false: the formal 1-sigma of the calibration is not needed for the
empirical RSD and costs as much as the rest of a run; true adds a "formal σ" column);
``n25-schemes``: ``methods`` (list), ``dtheta_arcsec`` (20), ``max_passes`` (5, the
systematic filter's passes); ``s16-table2``: ``methods`` (list of systematic methods),
``rate_hz`` (100), ``max_passes`` (5), ``z_rms_band`` ([0.8, 1.2]).

Simulation (parameter ``simulation``): ``"full"`` simulates every run with
:func:`inscal.sim.simulate.simulate`.  ``"reuse"`` computes the noise-free part of the
record (the deterministic kinematics and sensor errors, which do not depend on the
seed) once per worker and configuration point, and adds the noise exactly as
``simulate`` does, from the same generator: the record is bit-for-bit the one ``simulate``
returns (tests/analysis/test_montecarlo.py checks ``array_equal``), only faster.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

from inscal.analysis.montecarlo import (
    RUNS_FILE,
    Experiment,
    StudyError,
    StudyResult,
    read_results,
)

# ------------------------------------------------------------------------------ registry
_REGISTRY: dict[str, tuple[Callable[..., Experiment], str]] = {}


def register_experiment(name: str, factory: Callable[..., Experiment], description: str = "") -> None:
    """Make ``factory(**params) -> Experiment`` available as ``name``."""
    _REGISTRY[name] = (factory, description)


def available_experiments() -> dict[str, str]:
    return {k: d for k, (_, d) in sorted(_REGISTRY.items())}


def get_experiment(name: str, params: dict | None = None) -> Experiment:
    """The registered experiment ``name`` with ``params`` overriding its defaults."""
    if name not in _REGISTRY:
        raise StudyError(f"unknown experiment {name!r}; available: {', '.join(sorted(_REGISTRY))}")
    factory, _ = _REGISTRY[name]
    try:
        exp = factory(**(params or {}))
    except TypeError as exc:  # unknown keyword
        raise StudyError(f"{name}: {exc}") from None
    # the header records the registry name, so load_study() can rebuild the experiment
    return exp if exp.name == name else dataclasses.replace(exp, name=name)


def load_study(out, runs: int | None = None) -> tuple[Experiment, StudyResult]:
    """Rebuild a study from its folder (experiment from the registry with the recorded
    parameters; ``runs`` defaults to the largest complete repetition count)."""
    path = Path(out) / RUNS_FILE
    if not path.exists():
        raise StudyError(f"no study in {out} ({RUNS_FILE} missing)")
    header, records = read_results(path)
    exp = get_experiment(header["experiment"], header["params"])
    P = len(exp.points)
    if runs is None:
        runs = 0
        while all((runs * P + p) in records for p in range(P)):
            runs += 1
        runs = max(runs, 1)
    return exp, StudyResult(Path(out), header, records, runs, 0, 0.0)


# the built-in studies
from inscal.analysis.studies.fig5 import n25_fig5  # noqa: E402  (they use the registry above)
from inscal.analysis.studies.schemes import n25_schemes  # noqa: E402
from inscal.analysis.studies.table2 import s16_table2  # noqa: E402

register_experiment("n25-fig5", n25_fig5, "N25 Fig. 5: relative std of the estimated gimbal non-orthogonality vs dθ")
register_experiment("n25-schemes", n25_schemes, "N25 §5: bias and std of every calibrated parameter per scheme")
register_experiment("s16-table2", s16_table2, "S16 Table 2: 51- vs 30-state systematic calibration, NEES, error/sigma")
