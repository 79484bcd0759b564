"""History, repeatability and drift (:mod:`inscal.lab.drift`): the statistics are the defined ones
(weighted least squares against numpy), their false alarms follow the Gaussian tail (not zero by
construction), an injected drift of 2 ppm/month over 6 monthly calibrations is flagged with its rate
within 2 sigma, and 100 stable units through the database raise the flags chance allows."""

from __future__ import annotations

import datetime as dt
import hashlib
import math

import numpy as np
import pytest
from scipy.stats import poisson

from inscal import lab
from inscal.lab.drift import MONTH_DAYS, component_drift, tail

SEED = 20250115
N_CAL = 6  # monthly calibrations
DATES = [dt.datetime(2025, m, 15, 9, 0) for m in range(1, N_CAL + 1)]
MONTHS = np.array([(d - DATES[0]).total_seconds() / 86400.0 / MONTH_DAYS for d in DATES])


def test_the_statistics_are_the_defined_ones():
    rng = np.random.default_rng(SEED)
    t = np.array([0.0, 1.0, 2.1, 2.9, 4.0, 5.2])
    s = rng.uniform(0.5, 2.0, t.size)
    y = 10.0 + 0.7 * t + s * rng.standard_normal(t.size)
    c = component_drift("accel_scale_factor", "accel_scale_factor[x]", "ppm", range(6), t, y, s, k=3.0)
    # the rate and its sigma: numpy's weighted fit (weights 1/sigma on the residuals), sigma from the stated sigma
    coef, cov = np.polyfit(t, y, 1, w=1.0 / s, cov="unscaled")
    assert c.rate == pytest.approx(coef[0], rel=1e-10) and c.rate_sigma == pytest.approx(math.sqrt(cov[0, 0]), rel=1e-10)
    w = 1.0 / s**2
    mean = np.sum(w * y) / np.sum(w)
    assert c.mean == pytest.approx(mean) and c.mean_sigma == pytest.approx(1.0 / math.sqrt(np.sum(w)))
    assert c.repeatability_ratio == pytest.approx(math.sqrt(np.sum(w * (y - mean) ** 2) / 5))
    assert c.spread == pytest.approx(np.std(y, ddof=1)) and c.within_sigma == pytest.approx(math.sqrt(np.mean(s**2)))
    assert c.step == pytest.approx(y[-1] - y[-2]) and c.step_sigma == pytest.approx(math.hypot(s[-1], s[-2]))
    assert c.change == pytest.approx(c.rate * 5.2) and c.tests == 2 and c.span_months == 5.2
    # a component held fixed in one calibration leaves that calibration out
    s2 = s.copy()
    s2[2] = np.nan
    assert component_drift("a", "a", "ppm", range(6), t, y, s2).ids == (0, 1, 3, 4, 5)
    # two calibrations: the step test only; one: none
    assert component_drift("a", "a", "ppm", [0, 1], t[:2], y[:2], s[:2]).tests == 1
    assert component_drift("a", "a", "ppm", [0], t[:1], y[:1], s[:1]).tests == 0
    # a step at the newest calibration is flagged as a step
    y3 = np.full(6, 5.0)
    y3[-1] += 3.2 * math.hypot(1.0, 1.0)  # 3.2 sigma: the line through it stays below 3 sigma
    assert component_drift("a", "a", "ppm", range(6), t, y3, np.ones(6)).flags == ("step",)


def test_false_alarms_follow_the_gaussian_tail():
    """20,000 stable components (6 monthly calibrations, known sigma between 0.5 and 2): the drift and step
    tests each flag a fraction erfc(3/sqrt 2) = 0.27 % of them, and their z are standard normal."""
    rng = np.random.default_rng(SEED + 1)
    m, k = 20_000, 3.0
    drift = step = 0
    zs = np.empty(m)
    for i in range(m):
        s = rng.uniform(0.5, 2.0, N_CAL)
        c = component_drift("a", "a", "ppm", range(N_CAL), MONTHS, 3.0 + s * rng.standard_normal(N_CAL), s, k)
        drift += "drift" in c.flags
        step += "step" in c.flags
        zs[i] = c.rate_z
    p = tail(k)
    lo, hi = poisson.ppf(1e-4, m * p), poisson.ppf(1 - 1e-4, m * p)
    print(f"stable components: {drift} drift and {step} step flags of {m} each, {m * p:.1f} expected "
          f"(accepted {lo:.0f}..{hi:.0f}); z mean {zs.mean():+.3f}, sd {zs.std():.3f}")
    assert lo <= drift <= hi and lo <= step <= hi
    assert abs(zs.mean()) < 0.03 and abs(zs.std() - 1.0) < 0.02


def record(db, serial: str, values: dict, sigma: dict, when: dt.datetime, k: int, synthetic_text) -> int:
    return lab.record_calibration(db, serial, synthetic_text(values, sigma), lab.SessionInfo(
        record_sha256="sha256:" + hashlib.sha256(f"{serial}/{k}".encode()).hexdigest(), date=when))


def test_an_injected_drift_is_flagged_with_its_rate(tmp_path, synthetic_text):
    """2 ppm/month in accel_scale_factor[x] over 6 monthly calibrations with 1 ppm sigma (the N25 record's
    accelerometer scale-factor sigma is 1.0 ppm): flagged, rate within 2 sigma of 2 ppm/month; then the same
    over 2,000 seeded repeats: the rate is within 2 sigma in 95.4 % of them and always flagged."""
    rng = np.random.default_rng(SEED + 2)
    truth = 2.0
    base = {"gyro_scale_factor": np.array([50.0, -30.0, 20.0]), "accel_scale_factor": np.array([80.0, -60.0, 100.0])}
    sig = {"gyro_scale_factor": np.array([2.8, 2.8, 2.8]), "accel_scale_factor": np.array([1.0, 1.0, 1.0])}
    with lab.open_database(tmp_path / "c.sqlite", create=True) as db:
        lab.add_unit(db, "FOG-DRIFT")
        for i, when in enumerate(DATES):
            vals = {n: v + sig[n] * rng.standard_normal(3) for n, v in base.items()}
            vals["accel_scale_factor"][0] += truth * MONTHS[i]
            record(db, "FOG-DRIFT", vals, sig, when, i, synthetic_text)
        h = lab.unit_history(db, "FOG-DRIFT", k=3.0)
        fl = lab.fleet(db, k=3.0, flagged_only=True)
    c = next(c for c in h.components if c.label == "accel_scale_factor[x]")
    print(f"injected {truth} ppm/month: {c.rate:.3f} +- {c.rate_sigma:.3f} ppm/month, "
          f"{(c.rate - truth) / c.rate_sigma:+.2f} sigma from the truth, z = {c.rate_z:.1f}, flags {c.flags}")
    assert "drift" in c.flags and abs(c.rate - truth) < 2 * c.rate_sigma
    assert c.n == N_CAL and c.unit == "ppm" and c.span_months == pytest.approx(MONTHS[-1])
    assert [e.unit.serial for e in fl] == ["FOG-DRIFT"]
    assert "accel_scale_factor[x]" in [f["label"] for f in fl[0].to_json()["flagged"]]
    # the coverage of the 2-sigma interval and the detection over repeats (the statistic alone)
    reps, inside, flagged = 2000, 0, 0
    for _ in range(reps):
        y = 80.0 + truth * MONTHS + rng.standard_normal(N_CAL)
        r = component_drift("a", "a", "ppm", range(N_CAL), MONTHS, y, np.ones(N_CAL))
        inside += abs(r.rate - truth) < 2 * r.rate_sigma
        flagged += "drift" in r.flags
    print(f"over {reps} repeats: rate within 2 sigma in {inside / reps:.3f} (0.954 expected), flagged in "
          f"{flagged / reps:.3f}")
    assert abs(inside / reps - 0.9545) < 4 * math.sqrt(0.9545 * 0.0455 / reps) and flagged == reps


def test_stable_units_raise_only_chance_flags(tmp_path, synthetic_text):
    """100 stable units x 6 monthly calibrations x 6 scale-factor components through the database: the flags
    at k = 3 are those of the Gaussian tail (each unit makes 12 tests; 100 x 12 x 0.27 % = 3.2 expected),
    within the Poisson 0.01 %..99.99 % range, and the fleet view lists exactly the units that have one."""
    rng = np.random.default_rng(SEED + 3)
    n_units, k = 100, 3.0
    base = {"gyro_scale_factor": np.array([50.0, -30.0, 20.0]), "accel_scale_factor": np.array([80.0, -60.0, 100.0])}
    with lab.open_database(tmp_path / "fleet.sqlite", create=True) as db:
        for u in range(n_units):
            serial = f"U{u:03d}"
            lab.add_unit(db, serial)
            for i, when in enumerate(DATES):
                sig = {n: rng.uniform(0.5, 3.0, 3) for n in base}
                vals = {n: v + sig[n] * rng.standard_normal(3) for n, v in base.items()}
                record(db, serial, vals, sig, when, i, synthetic_text)
        entries = lab.fleet(db, k)
        flagged_units = [e.unit.serial for e in lab.fleet(db, k, flagged_only=True)]
    tests = sum(e.history.tests for e in entries)
    flags = sum(len(c.flags) for e in entries for c in e.history.components)
    expected = sum(e.history.expected_false_alarms for e in entries)
    lo, hi = poisson.ppf(1e-4, expected), poisson.ppf(1 - 1e-4, expected)
    print(f"100 stable units: {flags} flags ({len(flagged_units)} units flagged) in {tests} tests at k = {k:g}, "
          f"{expected:.2f} expected by chance (accepted {lo:.0f}..{hi:.0f})")
    assert tests == n_units * 6 * 2 and expected == pytest.approx(tests * tail(k))
    assert lo <= flags <= hi
    assert flagged_units == [e.unit.serial for e in entries if e.history.flagged]
