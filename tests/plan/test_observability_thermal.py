"""The systematic filter's thermal states planned without data: ``observability(..., "51,thermal")`` (the
filter's own covariance and the observability matrix) and ``crlb(..., "51,thermal")`` (the fast bound), on the
17-min PSINS path with short chamber profiles (inscal.plan.thermal)."""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from inscal.calibrate.systematic.states import THERMAL_ORDERS, THERMAL_SIGMA0
from inscal.calibrate.systematic.thermal_states import sample_inputs
from inscal.core import units
from inscal.plan.bound import crlb
from inscal.plan.observability import RANK_TOL, ObservabilityError, observability
from inscal.plan.rows import BiasNoise, BoundError
from inscal.plan.thermal import known_temperature, plateau_sigma
from inscal.sim import scenarios
from inscal.sim.thermal import Piece, TemperatureProfile

RAMP = 4.0  # degC/min
#: 3 min at 0 degC, 4 degC/min to 40 degC (10 min), then 40 degC to the end of the 17-min path
HOLDS = TemperatureProfile(0.0, (Piece("hold", duration_s=180.0), Piece("ramp", target_c=40.0, rate_c_per_min=RAMP)))
#: one ramp at 4 degC/min over the whole path (-15 .. +54 degC): dT/dt never changes
RAMP_ONLY = TemperatureProfile(-15.0, (Piece("ramp", target_c=60.0, rate_c_per_min=RAMP),))
THERMAL_STATES = 30  # the default orders 2, 2, 3, 2 and the dT/dt term, three axes each


def scenario(profile, name="psins19-thermal"):
    return replace(scenarios.build("psins19"), name=name, temperature=profile)


@pytest.fixture(scope="module")
def holds():
    return observability(scenario(HOLDS), "51,thermal")


@pytest.fixture(scope="module")
def ramp_only():
    return observability(scenario(RAMP_ONLY), "51,thermal")


def test_thermal_states_and_their_priors(holds):
    """30 thermal states after the 42 of 51, in field units; each prior is the filter's: the term's sigma over the
    span max |T - t_ref| = 20 degC (t_ref 20 degC, the profile 0 .. 40 degC) to the coefficient's order."""
    assert holds.n_states == 81 and holds.n_params == 42 + THERMAL_STATES and sum(THERMAL_ORDERS) * 3 == THERMAL_STATES
    t = holds.thermal
    assert (t["t_ref"], t["t_min"], t["t_max"], t["span"]) == (20.0, 0.0, 40.0, 20.0)
    assert t["rate_max_c_per_min"] == pytest.approx(RAMP, rel=1e-6)
    for label, unit, prior in (("gyro_bias_dT1[x]", "deg/h/degC", 1.0 / 20), ("gyro_bias_dT2[y]", "deg/h/degC^2", 1.0 / 400),
                               ("gyro_scale_factor_dT2[z]", "ppm/degC^2", 1000.0 / 400),
                               ("accel_bias_dT3[x]", "ug/degC^3", 3000.0 / 8000),
                               ("accel_scale_factor_dT1[y]", "ppm/degC", 1000.0 / 20),
                               ("gyro_bias_rate[z]", "deg/h/(degC/min)", 1.0)):
        s = holds.by_label(label)
        assert s.unit == unit and s.prior == pytest.approx(prior, rel=1e-12), s
        assert math.isclose(s.posterior, s.ratio * s.prior, rel_tol=1e-12)
    assert units.to_si(1.0, "deg/h/(degC/min)") == pytest.approx(THERMAL_SIGMA0["gyro_bias_rate"])
    # holds at both ends: every coefficient separated, the dT/dt term from the gyro bias too (the PSINS noise,
    # 0.002 deg/sqrt(h): the worst, gyro_bias_dT2, at 0.03 of its prior)
    assert holds.rank == holds.n_params
    for s in holds.states:
        if "_dT" in s.group or s.group == "gyro_bias_rate":
            assert s.ratio < 0.1, s
    assert holds.null_weight("gyro_bias_rate[x]") == 0.0


def test_the_filter_reads_the_profile_as_a_record_of_it(holds):
    """The known input is the record's: the filter's own sample_inputs on the readings gives, at the middle of every
    sample, the temperature the bound takes (exact on this piecewise-linear profile, dT/dt its 60-s slope)."""
    sc = scenario(HOLDS)
    known = known_temperature(sc, "test")
    rate = 20.0
    n = int(sc.path.duration * rate)
    t = (np.arange(n) + 1.0) / rate
    tin = sample_inputs(SimpleNamespace(time=t, temperature=known.readings()), n, rate, 20.0)
    T, r = known.at(t - 0.5 / rate)
    assert np.max(np.abs(tin["dT"] + 20.0 - T)) < 1e-9 and np.max(np.abs(tin["rate"] - r)) < 1e-12
    T_exact, _ = HOLDS.at(t - 0.5 / rate)
    assert np.max(np.abs(T - T_exact)) < 1e-9
    on_ramp = (t > 240) & (t < 720)  # 60 s inside the ramp: the slope is the ramp's
    assert np.allclose(r[on_ramp], RAMP / 60.0, rtol=1e-9) and np.max(np.abs(r)) <= RAMP / 60.0 * (1 + 1e-9)


def test_a_ramp_at_one_rate_leaves_the_rate_term_with_the_gyro_bias(ramp_only, holds):
    """dT/dt constant over the record: the dT/dt term's column is RAMP times the base gyro bias's, so the data see
    b + D dT/dt only.  The observability matrix has one null direction per axis, (sigma_D * RAMP, -sigma_b) in the
    scaled states (sigma_b = 0.1 deg/h, sigma_D = 1 deg/h/(degC/min)); the posterior correlates the two near -1."""
    assert ramp_only.rank == ramp_only.n_params - 3
    w_b, w_d = RAMP * 1.0, 0.1  # deg/h: a unit scaled D moves the bias by RAMP deg/h, a unit scaled b by 0.1
    for a in "xyz":
        assert ramp_only.null_weight(f"gyro_bias[{a}]") == pytest.approx(w_b / math.hypot(w_b, w_d), rel=1e-6)
        assert ramp_only.null_weight(f"gyro_bias_rate[{a}]") == pytest.approx(w_d / math.hypot(w_b, w_d), rel=1e-4)
        p = ramp_only.thermal["partners"][f"gyro_bias_rate[{a}]"]
        assert p["with"] == f"gyro_bias[{a}]" and p["correlation"] < -0.97, p
        assert abs(holds.thermal["partners"][f"gyro_bias_rate[{a}]"]["correlation"]) < abs(p["correlation"])
        # the base bias falls back to its prior: only its sum with D RAMP is seen
        assert ramp_only.by_label(f"gyro_bias[{a}]").verdict == "unobservable"
    for d in ramp_only.weakest[:3]:  # the null space (any basis of it): gyro biases and dT/dt terms alone
        assert {lab.split("[")[0] for lab, w in d.components if abs(w) > 1e-6} <= {"gyro_bias", "gyro_bias_rate"}, \
            d.describe()
        assert d.singular_value <= RANK_TOL


def test_a_constant_temperature_observes_no_coefficient():
    """A profile that holds at t_ref: every thermal column is zero, every coefficient stays at its prior."""
    o = observability(scenario(TemperatureProfile(20.0)), "51,thermal")
    th = [s for s in o.states if "_dT" in s.group or s.group == "gyro_bias_rate"]
    assert len(th) == THERMAL_STATES and all(s.ratio == pytest.approx(1.0, abs=1e-9) for s in th)
    assert all(s.verdict == "unobservable" for s in th) and o.rank == o.n_params - THERMAL_STATES
    assert o.thermal["span"] == 1.0  # the filter's floor: a span of at least 1 degC spreads the prior


def test_bound_equals_the_filter_posterior():
    """The bound = the posterior of one pass of the filter on a noise-free 20 Hz simulation, every state incl. the 30
    thermal ones: measured 1.2e-4 on the thermal states, 2.7e-4 on the base ones on this path (1.3e-4 without thermal
    states: the filter's 20-Hz discretisation of the PSINS path's turns); 4e-5 on thermal-ramp, 4.6e-5 on the
    9-h thermal-plateaus-s16 (bench/thermal_bound.py).  Also with other orders (thermal=11101)."""
    sc = scenario(HOLDS)
    for spec, n_th in (("51,thermal", THERMAL_STATES), ("51,thermal=11101", 12)):
        o = observability(sc, spec)
        b = crlb(sc, spec, bias_noise=BiasNoise())
        assert b.labels == tuple(s.label for s in o.states) and len(b.labels) == 42 + n_th
        o_prior = np.array([s.prior for s in o.states])
        b_prior = np.array([r["prior"] for r in b.table()])
        assert np.allclose(b_prior, o_prior, rtol=1e-12)
        rel = b.sigma / np.sqrt(np.diag(o.covariance)) - 1
        assert np.max(np.abs(rel[42:])) < 5e-4 and np.max(np.abs(rel)) < 1e-3, np.max(np.abs(rel))
        assert b.to_dict()["temperature"]["span"] == o.thermal["span"] == 20.0


def test_exact_rate_and_bias_instability():
    """The profile's exact dT/dt (a step at each end of the ramp) observes the dT/dt term at least as well as the
    record's 60-s slope (measured 5-12 % better here); a Gauss-Markov gyro bias (0.05 deg/h, 10 min) costs the gyro
    bias's coefficients accuracy (x4 on the linear one), not the accelerometer's."""
    sc = scenario(HOLDS)
    rec = crlb(sc, "51,thermal", bias_noise=BiasNoise())
    exact = crlb(sc, "51,thermal", bias_noise=BiasNoise(), rate_window_s=None)
    by_r, by_e = rec.by_label(), exact.by_label()
    for a in "xyz":
        assert by_e[f"gyro_bias_rate[{a}]"] <= by_r[f"gyro_bias_rate[{a}]"] * (1 + 1e-6)
        assert by_e[f"gyro_bias_rate[{a}]"] == pytest.approx(by_r[f"gyro_bias_rate[{a}]"], rel=0.2)
    gm = crlb(sc, "51,thermal", bias_noise=BiasNoise(gyro_gm=units.to_si(0.05, "deg/h"), gyro_tau=600.0))
    by_g = gm.by_label()
    assert by_g["gyro_bias_dT1[x]"] > 3.0 * by_r["gyro_bias_dT1[x]"]
    assert by_g["accel_bias_dT1[x]"] == pytest.approx(by_r["accel_bias_dT1[x]"], rel=0.05)


def test_plateau_sigma_is_the_weighted_polynomial_fit():
    """plateau_sigma against numpy's weighted polyfit covariance (per-plateau sigmas that differ)."""
    levels = np.array([-40.0, -15.0, 10.0, 35.0, 60.0])
    rng = np.random.default_rng(3)
    s = rng.uniform(0.5, 2.0, (5, 3))
    out = plateau_sigma({"gyro_bias": s, "gyro_scale_factor": s, "accel_bias": s, "accel_scale_factor": s}, levels,
                        20.0, THERMAL_ORDERS)
    assert set(out) == {"gyro_bias_dT0", "gyro_bias_dT1", "gyro_bias_dT2", "gyro_scale_factor_dT0",
                        "gyro_scale_factor_dT1", "gyro_scale_factor_dT2", "accel_bias_dT0", "accel_bias_dT1",
                        "accel_bias_dT2", "accel_bias_dT3", "accel_scale_factor_dT0", "accel_scale_factor_dT1",
                        "accel_scale_factor_dT2"}
    for a in range(3):
        _, cov = np.polyfit(levels - 20.0, rng.standard_normal(5), 3, w=1.0 / s[:, a], cov="unscaled")
        ref = np.sqrt(np.diag(cov))[::-1]  # polyfit: highest order first
        assert [out[f"accel_bias_dT{k}"][a] for k in range(4)] == pytest.approx(ref, rel=1e-10)


def test_errors_are_one_line():
    """No temperature profile; t_ref outside the path's temperatures."""
    for call, err in ((lambda: observability("psins19", "51,thermal"), ObservabilityError),
                      (lambda: crlb("psins19", "51,thermal"), BoundError)):
        with pytest.raises(err, match="no") as exc:
            call()
        assert "\n" not in str(exc.value) and "temperature history" in str(exc.value)
    sc = scenario(HOLDS)
    with pytest.raises(ObservabilityError, match="t_ref 50 degC lies outside") as exc:
        observability(sc, "51,thermal", t_ref=50.0)
    assert "\n" not in str(exc.value)
    with pytest.raises(BoundError, match="outside"):
        crlb(sc, "51,thermal", t_ref=-5.0)
    # a scenario with a profile and no thermal states: the plain analysis, no temperature section
    o = observability(sc, "30")
    assert o.thermal is None and "temperature" not in o.to_dict()
