"""Numerical footing of the systematic filter on other people's data: the resolution of quantized
increments, and numerical failures reported in one line."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.calibrate.systematic import driver
from inscal.calibrate.systematic.driver import data_resolution, float32_rounding
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def test_data_resolution_finds_the_quantum_of_counts_and_nothing_else():
    rng = np.random.default_rng(3)
    q = np.array([4.8e-7, 1.2e-3])
    counts = rng.integers(-40, 40, size=(5000, 2)) + np.array([100, 5000])
    assert data_resolution(counts * q) == pytest.approx(q, rel=1e-9)
    assert np.all(data_resolution(rng.normal(size=(5000, 2))) == 0.0)  # float64 noise: no quantum
    assert np.all(data_resolution(np.ones((100, 2))) == 0.0)  # a constant channel has no step to find
    # float32 increments within one binade lie on its grid: 2^-27 between 0.0625 and 0.125
    f32 = (rng.normal(size=(5000, 1)) * 1e-3 + 0.098).astype(np.float32).astype(float)
    assert data_resolution(f32)[0] == 2.0**-27


def test_a_numerical_failure_of_the_pass_is_one_calibration_error(noise_free_data, as_record, monkeypatch):
    sc, d = noise_free_data("s16")

    def failing(*a, **k):
        raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")

    monkeypatch.setattr(driver, "run_pass", failing)
    with pytest.raises(CalibrationError, match="numerical failure in pass 1 .*covariance lost its positive definiteness"):
        calibrate(as_record(d, sc), "systematic51")


def test_a_chi2_far_below_its_dof_is_a_misfit_and_keeps_the_sigma(noise_free_data, as_record):
    """A noise model far above the data's (here --vrw 1e5 ug/sqrt(Hz) on a noise-free record) leaves
    innovations far below their expectation: reported as inconsistent, with that cause, and the
    sigma not scaled (down) by the fit."""
    from inscal.core import units

    sc, d = noise_free_data("s16")
    res = calibrate(as_record(d, sc), "systematic51", vrw=units.to_si(1e5, "ug/sqrt(Hz)"), max_passes=2)
    fit = res.diagnostics["fit"]
    assert not fit["consistent"] and fit["p_value_low"] < 1e-3 and fit["scale"] == 1.0
    assert "the assumed noise is larger than the data's" in fit["cause"] and "conservative" in fit["note"]


def test_float32_records_show_their_rounding_noise():
    """A record stored in single precision: each increment carries the rounding of its float32 grid
    (2^-24 of its magnitude, ulp^2/12 in variance); float64 data and an all-zero column show none."""
    rng = np.random.default_rng(0)
    x = np.column_stack([0.098 + 1e-4 * rng.normal(size=5000), 1e-6 * rng.normal(size=5000), np.zeros(5000)])
    f = x.astype(np.float32).astype(float)
    q = float32_rounding(f)
    assert q[0] == pytest.approx(np.spacing(np.float32(0.098)) / np.sqrt(12.0), rel=0.01)
    assert 0 < q[1] < 1e-13 and q[2] == 0.0
    assert np.all(float32_rounding(x) == 0.0)
    # the empirical rounding error of the same values has that spread
    assert np.std(f[:, 0] - x[:, 0]) == pytest.approx(q[0], rel=0.1)


def test_a_large_valid_noise_calibrates_conservatively():
    """--arw 1 deg/sqrt(h) on a 0.002 deg/sqrt(h) record: the discrete noise of the third-order series in T
    went indefinite (a T^3 position-attitude term without the T^5 position variance that balances it) and
    the square-root prediction's Cholesky failed.  By quadrature Q_d is PSD; the fit runs, says the assumed
    noise is larger than the data's, and leaves the sigma conservative."""
    sc = scenarios.build("psins19")
    d = simulate(sc, np.random.default_rng(1))
    rec = SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=None, rate_hz=sc.rate_hz, site=sc.site)
    res = calibrate(rec, "systematic51", arw=units.to_si(1.0, "deg/sqrt(h)"))
    fit = res.diagnostics["fit"]
    assert not fit["consistent"] and fit["p_value_low"] < 1e-3 and fit["scale"] == 1.0
    err = res.to_field((sc.imu, None))["accel_scale_factor"]
    assert np.all(np.abs(np.asarray(err["error"])) < 3 * np.asarray(err["sigma"]))
