"""Statistical consistency of the S16 systematic calibration over seeded Monte Carlo runs: the first 10 seeds
of ``bench/systematic_stats.py`` (its 50 give the figures: mean NEES in its band, every parameter's RMS(error /
sigma) within 20 % of 1).

The runs are those of ``inscal montecarlo s16-table2`` (the same run and summary functions),
51 states only, on the S16 section 4.1 record (1.07 h at 100 Hz, S16 noise), with at most 2
filter passes instead of the CLI's 5.  Over 50 seeds, 2 passes give the figures of the converged
filter (3 passes, the default stop) to 3 digits: mean NEES 41.77, RMS(error/sigma) 0.830 ... 1.198,
per-group mean |errors| equal.  A 50 Hz record is not equivalent (mean NEES 45.8, outside the
band; lever-arm error +23 %; 4 parameters outside 0.8 ... 1.2), so the rate stays at 100 Hz.

* 10 seeds: the mean NEES of the 42 parameter states (e from ``CompParams.error_state`` against the
  truth in the filter's frame, P from ``res.covariance``) lies in its 95 % chi-square band (420
  degrees of freedom: a sigma 10 % off in every state leaves it), and no parameter's RMS(error /
  sigma) lies outside its 99.99 % band over 10 runs, sqrt(chi2_10 / 10) in [0.25, 1.99] (0.4 % of
  false alarms over the 42; a sigma wrong by a factor two in one state leaves it; the 20 % check of
  each state needs the bench's 50 runs).  These seeds hold the largest: accel_scale_factor.x at 1.80
  (three errors near 3 sigma in 10 runs; over 50 seeds 1.16, over 200 seeds 1.05: chance).
* The same 10 seeds: S16 Table 2 - the median over runs of the mean |error| of the
  nonlinearity, cross-coupling and lever-arm groups is below the paper's figures; for the
  g-sensitivity, whose diagonal is seen only through gyrocompassing, the figure must equal
  the expectation from the reported sigma (sqrt(2/pi) x mean sigma, the Cramer-Rao bound of
  this record) within 25 %, whether or not it reaches S16's 0.0002 deg/h/g (it does not:
  the bound is 0.00049, the figure 0.00055).
"""

from __future__ import annotations

import dataclasses
import math

import pytest
from scipy.stats import chi2

from inscal.analysis import montecarlo as mc
from inscal.analysis import studies
from inscal.sim.scenarios import S16_TABLE2
from inscal.analysis.studies.common import nees_band

RUNS = 10
TABLE2_RUNS = 10
PARAMS = {"methods": ["systematic51"], "rate_hz": 100.0, "max_passes": 2}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("s16-table2")
    exp = studies.get_experiment("s16-table2", PARAMS)
    res = mc.run_study(exp, out, runs=RUNS, seed=0, scheduler="synchronous")
    assert res.complete() and not any("error" in r for r in res.records.values())
    return exp, res


@pytest.fixture(scope="module")
def summary(study):
    return mc.summarize(*study)


@pytest.fixture(scope="module")
def table2(study):
    exp, res = study
    s = mc.summarize(exp, dataclasses.replace(res, runs=TABLE2_RUNS))
    assert s.data["runs_done"] == [TABLE2_RUNS]
    return {r["group"]: r for r in s.rows}


@pytest.mark.slow
def test_study_shape(summary):
    n = summary.data["nees"]["systematic51"]
    assert n["dof"] == 42 and n["runs"] == RUNS
    assert n["band95"] == pytest.approx(list(nees_band(RUNS, 42)))
    assert len(summary.data["z"]["systematic51"]["components"]) == 42  # the estimated components (frame-fixed ones out)


@pytest.mark.slow
def test_mean_nees_in_its_chi_square_band(summary):
    n = summary.data["nees"]["systematic51"]
    lo, hi = n["band95"]
    assert lo <= n["mean"] <= hi, f"mean NEES {n['mean']:.4g} outside [{lo:.4g}, {hi:.4g}] (dof {n['dof']}, {RUNS} runs)"


@pytest.mark.slow
def test_error_over_sigma_rms_within_its_band(summary):
    comps = summary.data["z"]["systematic51"]["components"]
    lo, hi = (math.sqrt(chi2.ppf(q, RUNS) / RUNS) for q in (0.00005, 0.99995))  # [0.25, 1.99]
    out = {c["parameter"]: round(c["rms_z"], 3) for c in comps if not lo <= c["rms_z"] <= hi}
    assert not out, f"RMS(error/sigma) outside [{lo:.3f}, {hi:.3f}]: {out}"


@pytest.mark.slow
def test_s16_table2_groups_below_the_paper(table2):
    for g in ("accel_nonlinearity", "accel_cross_coupling", "accel_lever_arm"):
        r = table2[g]
        assert r["systematic51_mae"] < S16_TABLE2[g], (g, r["systematic51_mae"])
        assert r["systematic51_mae"] < r["before"] / 100  # 2 cm, 300 ug/g^2 before calibration


@pytest.mark.slow
def test_g_sensitivity_at_its_cramer_rao_expectation(table2):
    r = table2["gyro_g_sensitivity"]
    assert r["systematic51_mae"] == pytest.approx(r["systematic51_crb"], rel=0.25), (
        f"median mean |error| {r['systematic51_mae']:.3g} deg/h/g vs sqrt(2/pi) sigma {r['systematic51_crb']:.3g}; "
        f"S16 Table 2: {S16_TABLE2['gyro_g_sensitivity']:g}")


def test_unified_nees_counts_the_gimbal_states():
    """A unified (``51,gimbal``) result's NEES includes dth and the mount attitude: 49 parameter
    states (45 IMU + 4 gimbal), consistent against the true gimbal, and far off against an ideal
    gimbal (the s16-gimbal truth: dth 20", mount 0.1/0.1/20 deg).  One seeded 20 Hz record."""
    import numpy as np

    from inscal.calibrate import calibrate
    from inscal.analysis.truth import systematic_statistics
    from inscal.io.records import Record, Truth
    from inscal.sim.scenarios import build
    from inscal.sim.simulate import simulate

    sc = dataclasses.replace(build("s16-gimbal"), rate_hz=20.0)
    d = simulate(sc, np.random.default_rng(5))
    rec = Record(d.time, d.dtheta, d.dvel, d.gimbal, sc.rate_hz, sc.site, path=sc.path,
                 truth=Truth(sc.imu, sc.gimbal, sc.noise), scenario=sc.name)
    res = calibrate(rec, "unified", max_passes=2)
    s = systematic_statistics(res, sc.imu, sc.gimbal)
    assert s["dof"] == 49
    assert s["nees"] < chi2.ppf(0.999, 49), s["nees"]
    assert "gimbal_nonorthogonality" in s["errors"] and "mount_attitude.gamma0" in s["errors"]
    wrong = systematic_statistics(res, sc.imu)  # ideal gimbal as the truth: the gimbal states are off by far
    assert wrong["nees"] > 1e3 * s["nees"]
    assert abs(wrong["z"][-4]) > 100 > abs(s["z"][-4])
