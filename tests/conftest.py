"""Fixtures shared by the test packages (``tests/<layer>/`` mirror ``inscal.<layer>``; ``tests/paper/``
holds the slow reproductions of the papers' figures):

- ``noise_free``: a built-in scenario with its noise removed (the IMU and gimbal errors kept);
- ``noise_free_data``: its simulation, cached for the whole session per scenario name;
- ``as_record``: a record-like object of a simulation (what the estimators take);
- ``nav_error`` and ``step_columns``: the finite-difference harness of the systematic filter's
  F blocks, which propagates one filter step of the nonlinear navigation with perturbed
  parameters and compares the difference quotients with the filter's ``Phi`` columns.
"""

from __future__ import annotations

import os

# one BLAS thread per test process (``make test`` sets it too): the xdist workers already fill the cores, and
# idle OpenBLAS threads spin; set before anything imports NumPy, and inherited by the commands the tests start
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from inscal.calibrate.systematic.kernel import one_step
from inscal.core import earth
from inscal.core.attitude import dcm_from_quat, quat_from_dcm
from inscal.core.error_model import ImuNoise
from inscal.core.kinematics import true_attitude
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

#: the test files that take longest (seconds of one worker, ``--durations=0`` of the whole suite on 2 cores,
#: OpenBLAS on one thread), longest first: they start first, so that the workers of ``make test``
#: (``--dist loadfile --no-loadscope-reorder``) end together; every other file keeps its place after them.
#: The command-line files that fork their commands share the worker's fork servers (tests/cli/conftest.py's
#: ``fork_servers``): the first of them on a worker starts them (~2 s of CPU each), the others do not.
#: ``cli/test_demo_html.py`` is not here: it checks the demo run of ``cli/test_readme_block_0.py`` (tests/cli/demo_share.py),
#: a few s when it comes after that file (its place among the other files), 9 s more when it runs the demo itself
LONGEST = (
    "paper/test_systematic_stats.py",  # 8 s (10 seeds; the 50 in bench/systematic_stats.py)
    "oracles/test_robust_sweep.py",  # 36 s
    "cli/test_signals_under_load.py",  # 23 s
    "cli/test_concurrent_writers.py",  # 20 s
    "cli/test_site_pages.py",  # 26 s (the landing tour, the own-record page, the table-free sessions, the noise guide)
    "cli/test_db_cli.py",  # 17 s (the guide's block forked, no script start)
    "io/test_encoders.py",  # 18 s (the n25 imports made once for the module)
    "cli/test_db_transactions.py",  # 17 s (fault injection through a fork server)
    "analysis/test_montecarlo.py",  # 17 s (the runner's two LocalCluster tests share one cluster)
    "cli/test_readme_block_0.py",  # 18 s
    "calibrate/test_noise_matrix.py",  # 18 s
    "calibrate/test_selection.py",  # 16 s
    "cli/test_readme_block_2.py",  # 14 s (no script start: part 0 runs the entry point)
    "lab/test_batch.py",  # 14 s (the run after the kill in the process)
    "oracles/test_methods_into_lab.py",  # 12 s (every table-free and window method through every lab path)
    "cli/test_hardening_round4.py",  # 10 s
    "oracles/test_handheld_consumer.py",  # 9 s (consumer-MEMS sessions: tremor, saturation)
    "cli/test_memory_caps.py",  # 9 s (the two interrupts forked: no interpreter start each)
    "cli/test_calibrate_caps.py",  # 7 s (the interrupt forked)
    "oracles/test_handheld_multiposition.py",  # 8 s
    "io/test_import_bags.py",  # 5 s (3 storages written and read, a calibration through a bag)
    "oracles/test_oracle_calibration.py",  # ~5 s (both noise-free seeds: the CLI's run only, no library fit beside it)
    "lab/test_db_integrity.py",  # 7 s
    "uncertainty/test_budget_mc.py",  # 12 s (two JCGM 101 Monte Carlos of a six-position budget)
    "cli/test_budget_mc_cli.py",  # 6 s
)
TESTS = Path(__file__).resolve().parent


def pytest_collection_modifyitems(config, items):
    """The files of :data:`LONGEST` first, in its order (a stable sort: the tests of a file and the other
    files keep their order)."""
    rank = {name: i for i, name in enumerate(LONGEST)}

    def key(item):
        try:
            rel = Path(item.fspath).resolve().relative_to(TESTS).as_posix()
        except ValueError:
            return len(rank)
        return rank.get(rel, len(rank))

    items.sort(key=key)


def _noise_free(name: str, **kw):
    return dataclasses.replace(scenarios.build(name), noise=ImuNoise(), **kw)


@pytest.fixture(scope="session")
def noise_free():
    """``noise_free(name, **replace)``: the built-in scenario ``name`` without noise."""
    return _noise_free


@pytest.fixture(scope="session")
def noise_free_data():
    """``noise_free_data(name)``: ``(scenario, SimData)`` of the noise-free built-in scenario,
    simulated once per session."""
    cache = {}

    def get(name: str):
        if name not in cache:
            sc = _noise_free(name)
            cache[name] = (sc, simulate(sc))
        return cache[name]

    return get


@pytest.fixture(scope="session")
def as_record():
    """``as_record(data, sc, gimbal=True)``: the record-like object of a simulation."""

    def make(d, sc, gimbal: bool = True):
        return SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal if gimbal else None,
                               rate_hz=sc.rate_hz, site=sc.site, path=sc.path)

    return make


def _nav_error(out, C_true, site):
    """The 9 navigation errors (attitude, velocity, position in metres) of a navigation state
    ``out = [q(4), v(3), lat, lon, h]`` against the true attitude at a static site."""
    E = dcm_from_quat(out[:4]) @ C_true.T
    phi = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    rm, rn = earth.radii(site[0])
    dp = np.array([(out[8] - site[1]) * (rn + site[2]) * math.cos(site[0]), (out[7] - site[0]) * (rm + site[2]),
                   out[9] - site[2]])
    return np.concatenate([phi, out[4:7], dp])


@pytest.fixture(scope="session")
def nav_error():
    return _nav_error


@pytest.fixture(scope="session")
def step_columns():
    """``step_columns(sc, d, st, truth, t0)`` -> ``(x0, phinn, phinp, propagate, nav0, C0, C1, site, step)``:
    one 1-s filter step of the noise-free simulation ``d`` from ``t0``, propagated with the true
    parameters (``x0``: its navigation errors), the filter's ``Phi_nn`` and ``Phi_np``, and
    ``propagate(params, nav0=nav0)``: the navigation errors after the same step with other
    parameters or another initial state (central differences of it are the F blocks)."""

    def make(sc, d, st, truth, t0: float):
        k0, n = int(round(t0 * sc.rate_hz)), int(sc.rate_hz)
        dth, dv, dt = d.dtheta[k0:k0 + n], d.dvel[k0:k0 + n], 1.0 / sc.rate_hz
        site = np.array([sc.site.latitude, sc.site.longitude, sc.site.height])
        C0, C1 = true_attitude(sc, np.array([t0, t0 + 1.0]))
        nav0 = np.concatenate([quat_from_dcm(C0), np.zeros(3), site])
        x0, phinn, phinp = one_step(dth, dv, dt, nav0, site, truth, st)

        def propagate(params, start=nav0):
            return _nav_error(one_step(dth, dv, dt, start, site, params, st)[0], C1, site)

        return _nav_error(x0, C1, site), phinn, phinp, propagate, nav0, C0

    return make
