"""What the built-in studies share: parameter checks, cached scenarios and noise-free records (the
``reuse`` simulation mode), and the chi-square bands of their consistency checks."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from inscal.analysis.montecarlo import Experiment, StudyError
from inscal.calibrate import METHODS, calibrate
from inscal.core import units
from inscal.core.error_model import GimbalErrors
from inscal.core.stats import chi2_ppf
from inscal.core.turntable import Move, RotationPath, n25_twelve
from inscal.io.records import Record, Truth
from inscal.sim.scenarios import build
from inscal.sim.simulate import NoiseState, Scenario, simulate

_SIMULATION_MODES = ("full", "reuse")


# ----------------------------------------------------------------------------- scenario
def check_common(p: dict) -> dict:
    out = {}
    for k in ("arw_deg_rt_h", "vrw_ug_rt_hz", "dwell_s", "rate_hz"):
        v = p[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise StudyError(f"{k} must be a non-negative number, got {v!r}")
        out[k] = float(v)
    if out["dwell_s"] <= 0 or out["rate_hz"] <= 0:
        raise StudyError("dwell_s and rate_hz must be positive")
    if p["simulation"] not in _SIMULATION_MODES:
        raise StudyError(f"simulation must be one of {_SIMULATION_MODES}, got {p['simulation']!r}")
    out["simulation"] = p["simulation"]
    return out


@functools.lru_cache(maxsize=64)
def scenario_cached(key: str):

    p = json.loads(key)
    sc = build("n25")
    gim = sc.gimbal
    if p.get("dtheta_arcsec") is not None:
        gim = GimbalErrors(units.to_si(p["dtheta_arcsec"], "arcsec"), gim.mount_attitude)
    noise = replace(sc.noise, arw=units.to_si(p["arw_deg_rt_h"], "deg/sqrt(h)"), vrw=units.to_si(p["vrw_ug_rt_hz"], "ug/sqrt(Hz)"))
    path = sc.path if p["dwell_s"] == 100.0 else n25_twelve(dwell_s=p["dwell_s"])
    return replace(sc, gimbal=gim, noise=noise, path=path, rate_hz=p["rate_hz"])


def n25_scenario(params: dict, dtheta_arcsec: float | None = None):
    """The built-in ``n25`` scenario with the study's noise, dwell, rate and (if given)
    non-orthogonality."""
    return scenario_cached(scenario_key(params, dtheta_arcsec))


@functools.lru_cache(maxsize=12)
def _clean_record(key: str):
    """The noise-free measured record of a scenario (cached per worker process)."""

    sc = scenario_cached(key)
    return simulate(replace(sc, noise=type(sc.noise)()), None)


def simulate_record(scenario_key: str, rng: np.random.Generator, mode: str):
    """An :class:`inscal.io.Record` of the scenario behind ``scenario_key`` with noise from ``rng``."""

    sc = scenario_cached(scenario_key)
    if mode == "full":
        d = simulate(sc, rng)
        t, dth, dv, gim = d.time, d.dtheta, d.dvel, d.gimbal
    else:
        clean = _clean_record(scenario_key)
        t = clean.time
        state = NoiseState(sc.noise, rng, 1.0 / sc.rate_hz)
        chunk = 1 << 19  # simulate()'s chunking: the noise state advances chunk by chunk
        parts = [state.apply(clean.dtheta[k:k + chunk], clean.dvel[k:k + chunk], clean.gimbal[k:k + chunk])
                 for k in range(0, t.shape[0], chunk)]
        dth, dv, gim = (np.concatenate([q[i] for q in parts]) for i in range(3))
    return Record(t, dth, dv, gim, sc.rate_hz, sc.site, path=sc.path, truth=Truth(sc.imu, sc.gimbal, sc.noise), scenario=sc.name)


def scenario_key(params: dict, dtheta_arcsec: float | None) -> str:
    key = {k: params[k] for k in ("arw_deg_rt_h", "vrw_ug_rt_hz", "dwell_s", "rate_hz")}
    key["dtheta_arcsec"] = dtheta_arcsec
    return json.dumps(key, sort_keys=True)


def warmup(exp: Experiment) -> None:
    """Compile (and cache on disk) the numba kernels with a short simulation."""

    sc = n25_scenario(exp.params, 1.0)
    short = RotationPath("warmup", (Move("outer", 0.1, 0.5, 0.1),), accel=1.0, initial_dwell=0.1, closed=False)
    simulate(Scenario("warmup", short, sc.site, sc.imu, sc.gimbal, sc.noise, sc.rate_hz), np.random.default_rng(0))


def rms_z_band(runs: int, level: float = 0.95) -> tuple[float, float]:
    """Sampling band of the RMS of ``runs`` independent standard normal draws."""

    a = (1 - level) / 2
    return (math.sqrt(chi2_ppf(a, runs) / runs), math.sqrt(chi2_ppf(1 - a, runs) / runs))


def nees_band(runs: int, dof: int, level: float = 0.95) -> tuple[float, float]:
    """Band of the mean of ``runs`` chi-square(``dof``) draws: ``chi2.ppf([a, 1-a], runs*dof) / runs``."""

    a = (1 - level) / 2
    return (chi2_ppf(a, runs * dof) / runs, chi2_ppf(1 - a, runs * dof) / runs)




def verdict(holds) -> str:
    return "info" if holds is None else ("yes" if holds else "NO")


def check_methods(methods) -> list[str]:

    ms = [methods] if isinstance(methods, str) else list(methods)
    if not ms or not all(isinstance(m, str) for m in ms) or len(set(ms)) != len(ms):
        raise StudyError(f"methods must be a list of distinct method names, got {methods!r}")
    bad = [m for m in ms if m not in METHODS]
    if bad:
        raise StudyError(f"unknown method(s) {bad}; choose from {', '.join(METHODS)}")
    return ms


def check_passes(max_passes) -> int:
    if isinstance(max_passes, bool) or not isinstance(max_passes, int) or max_passes < 1:
        raise StudyError(f"max_passes must be a positive integer, got {max_passes!r}")
    return int(max_passes)


def warmup_systematic(exp: Experiment) -> None:
    """Compile (and cache on disk) the simulation and the systematic filter's kernels."""

    sc = build("s16")
    short = RotationPath("warmup", (Move("outer", math.pi / 2, 0.2, 10.0), Move("inner", math.pi / 2, 0.2, 10.0)),
                  initial_dwell=10.0, closed=False)
    wsc = Scenario("warmup", short, sc.site, sc.imu, sc.gimbal, sc.noise, 50.0)
    d = simulate(wsc, np.random.default_rng(0))
    rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=wsc.rate_hz, site=wsc.site)
    for m in ("systematic51", "systematic30"):
        calibrate(rec, m, max_passes=1)
