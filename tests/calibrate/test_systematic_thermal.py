"""Thermal states of the systematic filter (option ``thermal``): the thermal columns of Phi_np against finite
differences of the nonlinear propagation, the exactness of the filter's inverse thermal model against the
simulator's forward one, noise-free recovery of every thermal coefficient and of the base errors from a short
record, what a temperature history cannot separate, the result's thermal tables, and the one-line refusals.

The record: the psins19 IMU and path run twice (33 min at 50 Hz) while the temperature holds -20 degC for 5 min,
ramps to +60 degC at 4 degC/min and holds; the built-in thermal model (orders 2, 2, 3, 2 and the dT/dt term).
The temperature is read at 10 Hz and its rate taken over a 1-s window: the simulator's dT/dt steps at each
corner of the profile, and the default 60-s least-squares slope of 1-Hz readings smooths the step over +-30 s,
a model error of D x 4 degC/min there that a noise-free test sees (the dT/dt term 2-4 % off, the quadratic gyro
bias 10 %); with noise that error is far below the noise (the built-in thermal-ramp runs 1 degC/min)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.calibrate.systematic.dynamics import base_bias, linear, thermal_linear
from inscal.calibrate.systematic.kernel import one_step
from inscal.calibrate.systematic.params import (
    REF_SLICES,
    REF_WIDTH,
    ref_error_states,
    thermal_from_rows,
    thermal_rows,
    truth_in_frame,
)
from inscal.calibrate.systematic.states import (
    DEFAULT_SIGMA0,
    K_TH,
    StateSet,
    prior_sigma,
    thermal_orders_from,
)
from inscal.calibrate.systematic.thermal_states import data_information, thermal_offset
from inscal.calibrate.windows import CalibrationError
from inscal.core import earth, units
from inscal.core.attitude import dcm_from_quat, quat_from_dcm
from inscal.core.error_model import ImuNoise
from inscal.core.kinematics import true_attitude
from inscal.core.thermal import THERMAL_TERMS, ThermalModel
from inscal.core.turntable import RotationPath
from inscal.sim import scenarios
from inscal.sim.simulate import simulate
from inscal.sim.thermal import Piece, TemperatureProfile, TemperatureSensor

RATE_HZ = 50.0
T_REF = 20.0
#: the profile: hold, ramp at RAMP degC/min to T_HI, hold
T_LO, T_HI, HOLD_S, RAMP = -20.0, 60.0, 300.0, 4.0
SPAN = max(T_REF - T_LO, T_HI - T_REF)
WINDOW_S = 1.0
#: the noise-free tolerances of the base errors (tests/calibrate/test_systematic.py), per field unit
TOL = {"ppm": 0.05, "arcsec": 0.03, "deg/h": 0.001, "ug": 0.05, "ug/g^2": 0.05, "cm": 0.005, "ms": 0.01,
       "deg/h/g": 0.001}
#: relative tolerance of every thermal coefficient: within the base test's relative tolerances (TOL of the s16
#: truth: 1.7e-4 of the 300-ppm scale factors .. 2e-2 of the 0.05-deg/h gyro bias); measured at most 3.1e-4
REL = 1e-3


def profile(kind: str = "hold-ramp") -> TemperatureProfile:
    if kind == "constant":  # at T_ref throughout
        return TemperatureProfile(T_REF, (Piece("hold", duration_s=10.0),))
    if kind == "ramp":  # one rate throughout (the record ends before the ramp does)
        return TemperatureProfile(T_LO, (Piece("ramp", target_c=100.0, rate_c_per_min=2.5),))
    return TemperatureProfile(T_LO, (Piece("hold", duration_s=HOLD_S),
                                     Piece("ramp", target_c=T_HI, rate_c_per_min=RAMP)))


def scenario(kind: str = "hold-ramp", thermal: ThermalModel | None = None, sensor_hz: float = 10.0):
    base = scenarios.build("psins19")
    one = base.path
    path = RotationPath("psins19-x2", one.moves * 2, accel=one.accel, initial=one.initial,
                        initial_dwell=one.initial_dwell, closed=one.closed)
    return dataclasses.replace(base, path=path, noise=ImuNoise(), rate_hz=RATE_HZ,
                               thermal=thermal or scenarios.thermal_model(), temperature=profile(kind),
                               temperature_sensor=TemperatureSensor(rate_hz=sensor_hz))


def linear_model() -> ThermalModel:
    """The built-in model cut to order 1 (and its dT/dt term)."""
    m = scenarios.thermal_model()
    return m.replace(**{n: getattr(m, n)[:1] for n in ("gyro_bias", "gyro_scale_factor", "accel_bias",
                                                        "accel_scale_factor")})


@pytest.fixture(scope="module")
def clean():
    sc = scenario()
    d = simulate(sc)
    return sc, d, d.to_record()


@pytest.fixture(scope="module")
def result(clean):
    _, _, rec = clean
    return calibrate(rec, "systematic51", states="51,thermal=22321", temperature_rate_window_s=WINDOW_S)


# ----------------------------------------------------------------------------- Jacobian
def _nav_error(out, C_true, site):
    E = dcm_from_quat(out[:4]) @ C_true.T
    phi = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    rm, rn = earth.radii(site[0])
    dp = np.array([(out[8] - site[1]) * (rn + site[2]) * math.cos(site[0]), (out[7] - site[0]) * (rm + site[2]),
                   out[9] - site[2]])
    return np.concatenate([phi, out[4:7], dp])


@pytest.mark.parametrize("t0, axis", [(425.0, 0), (534.0, 1), (497.0, 2), (1000.0, None)])
def test_thermal_columns_match_finite_differences(clean, t0, axis):
    """Every thermal column of Phi_np (bias and scale-factor orders 1-3 of both triads, the dT/dt term) over one
    1-s step against central differences of ``one_step`` with the same temperature input: turning about x, y,
    z and at rest, at dT = -32, -24, -27, +7 degC and dT/dt = 4 degC/min.

    Tolerance: 1e-3 of the largest column of the group (term and order).  The columns are the base columns times
    a known scalar of the sample; the exact derivative differs by the factors ``A e_i`` and ``1 / (1 + s_i)``
    (states module docstring) and, for a scale factor, by the value ``(u - b)_i`` taken in the compensated frame
    rather than on the sensor axis: ``|A - I| <= 1.7e-4`` for this IMU and ``|s| <= 1e-4``, so parts in 1e4 of
    the group (measured at most 2.0e-4); a wrong power of dT (a factor |dT| >= 6.7 here), axis, sign or triad is O(1).
    The base filter's own Jacobian leaves out the size effect's dependence on the compensated rate (2e-3 of a
    gyro column at psins19's 10 deg/s: tests/calibrate/test_systematic.py allows it), so the derivatives are
    taken at the truth with the lever arms set to zero, where that term vanishes."""
    sc, d, _ = clean
    st = StateSet.parse("51,thermal=33331")
    truth = truth_in_frame(sc.imu, st, thermal=sc.thermal)
    k0, n, dt = round(t0 * RATE_HZ), int(RATE_HZ), 1.0 / RATE_HZ
    dth, dv = d.dtheta[k0:k0 + n], d.dvel[k0:k0 + n]
    turn = np.degrees(dth.sum(axis=0))
    if axis is None:
        assert np.max(np.abs(turn)) < 0.01
    else:
        assert abs(turn[axis]) > 9.0 and np.sum(np.abs(turn)) - abs(turn[axis]) < 0.05, turn
    T, rate = sc.temperature.at(d.time[k0:k0 + n] - 0.5 * dt)
    temp = (T - T_REF, rate)
    assert abs(temp[0][0]) > 5.0 and rate[0] == pytest.approx(RAMP / 60.0)
    site = np.array([sc.site.latitude, sc.site.longitude, sc.site.height])
    C0, C1 = true_attitude(sc, np.array([t0, t0 + 1.0]))
    nav0 = np.concatenate([quat_from_dcm(C0), np.zeros(3), site])
    # the truth propagates without error: the kernel's thermal compensation inverts the simulator's forward model
    x_true = _nav_error(one_step(dth, dv, dt, nav0, site, truth, st, temperature=temp)[0], C1, site)
    assert np.max(np.abs(x_true)) < 1e-6
    # without the thermal input the same step is off by the thermal errors (the input is used)
    x_none = _nav_error(one_step(dth, dv, dt, nav0, site, truth, StateSet.parse("51"))[0], C1, site)
    assert np.max(np.abs(x_none)) > 1e3 * max(np.max(np.abs(x_true)), 1e-9)
    lin = truth.copy()
    lin.lever[:] = 0.0
    _, _, phinp = one_step(dth, dv, dt, nav0, site, lin, st, temperature=temp)

    def propagate(p):
        return _nav_error(one_step(dth, dv, dt, nav0, site, p, st, temperature=temp)[0], C1, site)

    rows = [0, 1, 2, 3, 4, 5, 8]  # horizontal positions in radians are too coarse for differences
    kinds = st.columns()[0]
    sig = prior_sigma(st, {}, SPAN)
    labels = st.labels()[9:]
    groups = [g.name for g in st.groups for _ in g.labels]
    th_cols = [c for c in range(len(groups)) if kinds[c] == K_TH]
    assert len(th_cols) == 39  # 4 terms x 3 orders x 3 axes + the dT/dt term
    scale = {g: np.max(np.abs(phinp[rows][:, [c for c in th_cols if groups[c] == g]]))
             for g in {groups[c] for c in th_cols}}
    worst = 0.0
    for c in th_cols:
        h = 1e-2 * sig[c]
        e = np.zeros(len(groups))
        e[c] = h
        fd = (propagate(lin.corrected(st, -e)) - propagate(lin.corrected(st, e))) / (2 * h)
        err = np.max(np.abs(fd[rows] - phinp[rows, c]))
        worst = max(worst, err / scale[groups[c]])
        assert err <= 1e-3 * scale[groups[c]] + 1e-14 / h, (labels[c], fd, phinp[:, c])
    assert worst > 1e-6  # the approximations are there (a difference quotient that saw nothing would be 0)


# ----------------------------------------------------------------------------- exactness of the model
def _mixed_model(rng) -> ThermalModel:
    """Orders 3, 1, 0, 2 and the dT/dt term; magnitudes of a navigation-grade unit (SI)."""
    dph, ppm = units.to_si(1.0, "deg/h"), 1e-6
    return ThermalModel(t_ref=15.0, t_min=-30.0, t_max=55.0, sensor="case",
                        gyro_bias=rng.normal(size=(3, 3)) * dph * np.array([[3e-3], [3e-5], [3e-7]]),
                        gyro_scale_factor=rng.normal(size=(1, 3)) * ppm,
                        accel_scale_factor=rng.normal(size=(2, 3)) * ppm * np.array([[2.0], [0.02]]),
                        gyro_bias_rate=rng.normal(size=3) * units.to_si(0.02, "deg/h/(degC/min)"))


def test_thermal_rows_round_trip_and_bookkeeping():
    rng = np.random.default_rng(19)
    imu = scenarios.build("psins19").imu
    model = _mixed_model(rng)
    orders = thermal_orders_from({n: model.order(n) for n in ("gyro_bias", "gyro_scale_factor", "accel_bias",
                                                               "accel_scale_factor")} | {"gyro_bias_rate": 1})
    assert orders == (3, 1, 0, 2, 1)
    th = thermal_rows(model, imu)
    # the layout: orders of each term in rows 3 t + k - 1, the scale factors over 1 + K_0, the dT/dt term in row 12
    assert np.array_equal(th[0:3], model.gyro_bias)
    assert np.allclose(th[3], model.gyro_scale_factor[0] / (1.0 + imu.gyro_scale_factor), rtol=1e-15, atol=0)
    assert not np.any(th[4:9]) and not np.any(th[11])
    assert np.allclose(th[9:11], model.accel_scale_factor / (1.0 + imu.accel_scale_factor), rtol=1e-15, atol=0)
    assert np.array_equal(th[12], model.gyro_bias_rate)
    back = thermal_from_rows(th, orders, imu, model.t_ref, model.t_min, model.t_max, model.sensor)
    assert (back.t_ref, back.t_min, back.t_max, back.sensor) == (15.0, -30.0, 55.0, "case")
    for name in THERMAL_TERMS:
        assert getattr(back, name).shape == getattr(model, name).shape, name
        np.testing.assert_allclose(getattr(back, name), getattr(model, name), rtol=1e-15, atol=0, err_msg=name)
    np.testing.assert_array_equal(back.gyro_bias_rate, model.gyro_bias_rate)
    # without the dT/dt term its row is not read
    assert back.has_rate
    assert not thermal_from_rows(th, orders[:4] + (0,), imu, 15.0, -30.0, 55.0).has_rate
    # the feedback and the error state of the thermal groups (CompParams.corrected / error_state / the
    # reference-history rows): a correction x removed is an error state -x
    st = StateSet.parse("51,thermal=31021")
    p = truth_in_frame(imu, st, thermal=model)
    x = rng.normal(size=st.n_params) * prior_sigma(st, {}, 40.0)
    q = p.corrected(st, x)
    o = thermal_offset(st)
    np.testing.assert_allclose(q.error_state(st, p)[o:], -x[o:], rtol=1e-12, atol=0)
    row = np.zeros(REF_WIDTH)
    for f, (a, b, _) in REF_SLICES.items():
        row[a:b] = np.ravel(getattr(q, f))
    np.testing.assert_allclose(ref_error_states(row[None, :], st, p)[0], q.error_state(st, p), rtol=1e-12, atol=1e-300)
    assert not np.any(q.th[[4, 5, 6, 7, 8, 11]] - p.th[[4, 5, 6, 7, 8, 11]])  # orders not estimated stay


@pytest.mark.parametrize("frame", ["gyro", "accel"])
def test_thermal_linear_inverts_the_forward_model(frame):
    """``dynamics.thermal_linear`` with the true rows applied to the increments that ``ThermalModel.to_temperature``
    gives at each temperature and rate gives back what ``linear`` gives on the increments at T_ref, to round-off:
    the filter's inverse model against the simulator's forward one (independent code), in the filter's frame."""
    rng = np.random.default_rng(7)
    imu = scenarios.build("psins19").imu
    model = scenarios.thermal_model()
    n, dt = 400, 0.01
    dth0 = rng.normal(size=(n, 3)) * 0.2 * dt
    dv0 = (rng.normal(size=(n, 3)) * 3.0 + np.array([0.0, 0.0, 9.8])) * dt
    T = rng.uniform(-40.0, 60.0, n)
    rate = rng.normal(size=n) * 0.1
    dthT, dvT = model.to_temperature(imu, dt, dth0, dv0, T, rate)
    assert np.max(np.abs(dthT - dth0)) > 1e-5 * np.max(np.abs(dth0))  # the thermal errors are there
    st = StateSet.parse("51,psins,thermal" if frame == "accel" else "51,thermal")
    p = truth_in_frame(imu, st, thermal=model)
    th = thermal_rows(model, imu)
    assert np.array_equal(p.th, th)
    eg, ea = np.zeros(3), np.zeros(3)
    base_bias(p.Ag, p.bg, eg)
    base_bias(p.Aa, p.ba, ea)
    np.testing.assert_allclose(eg, imu.gyro_bias, rtol=1e-12)  # the base bias on the sensor axes
    np.testing.assert_allclose(ea, imu.accel_bias, rtol=1e-12)
    got, ref = np.empty(3), np.empty(3)
    worst = 0.0
    for A, eps, r0, xT, x0 in ((p.Ag, eg, 0, dthT, dth0), (p.Aa, ea, 6, dvT, dv0)):
        for j in range(n):
            thermal_linear(A, xT[j], 1.0 / dt, eps, th, r0, T[j] - model.t_ref, rate[j], got)
            linear(A, x0[j], 1.0 / dt, ref)
            worst = max(worst, np.max(np.abs(got - ref)) / np.max(np.abs(ref)))
    assert worst < 1e-12, worst
    # the scale-factor rows over 1 + K_0 matter: the canonical coefficients in their place are off by K_0 s
    raw = th.copy()
    raw[3:5] = model.gyro_scale_factor
    j = int(np.argmax(np.abs(T - model.t_ref)))
    thermal_linear(p.Ag, dthT[j], 1.0 / dt, eg, raw, 0, T[j] - model.t_ref, rate[j], got)
    linear(p.Ag, dth0[j], 1.0 / dt, ref)
    assert np.max(np.abs(got - ref)) > 1e-10 * np.max(np.abs(ref))


# ----------------------------------------------------------------------------- noise-free recovery
def test_noise_free_recovery(clean, result):
    """Every thermal coefficient within REL of the truth, and its error over the record's span (the coefficient's
    share of the term at the edge of the range, |err| SPAN^k; the dT/dt term's at the largest rate) within the
    base errors' noise-free tolerance TOL of its unit; the base errors within TOL."""
    sc, _, _ = clean
    res = result
    assert res.diagnostics["converged"] and res.diagnostics["states"] == 9 + 42 + 30
    th = res.thermal
    for name in ("gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor"):
        tru, est = getattr(sc.thermal, name), getattr(th, name)
        assert est.shape == tru.shape, name
        unit = THERMAL_TERMS[name][2]
        for k in range(tru.shape[0]):
            rel = np.abs(est[k] - tru[k]) / np.abs(tru[k])
            effect = units.from_si(np.abs(est[k] - tru[k]), unit) * SPAN ** (k + 1)
            assert np.all(rel < REL), (name, k + 1, rel)
            assert np.all(effect < TOL[unit]), (name, k + 1, effect)
    rel = np.abs(th.gyro_bias_rate - sc.thermal.gyro_bias_rate) / np.abs(sc.thermal.gyro_bias_rate)
    assert np.all(rel < REL), rel
    assert np.all(units.from_si(np.abs(th.gyro_bias_rate - sc.thermal.gyro_bias_rate), "deg/h/(degC/min)") * RAMP
                  < TOL["deg/h"])
    bad = []
    for name, e in res.to_field((sc.imu, sc.gimbal)).items():
        err = float(np.nanmax(np.abs(np.asarray(e["error"], float))))
        if err > TOL[e["unit"]]:
            bad.append(f"{name}: {err:.3g} {e['unit']}")
    assert not bad, bad
    # every coefficient observed: no note names one
    assert not any("thermal coefficients not observed" in n for n in res.notes), res.notes


def test_result_tables(result):
    """thermal_fit, diagnostics["thermal"] and the coefficient table: the canonical coefficients of the model
    (scale factors included) with their sigma, in field units."""
    res = result
    th = res.thermal
    assert (th.t_ref, th.t_min, th.t_max, th.sensor) == (T_REF, T_LO, T_HI, "")
    assert set(res.thermal_sigma) == {"gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor",
                                      "gyro_bias_rate"}
    for name, s in res.thermal_sigma.items():
        assert s.shape == np.shape(getattr(th, name)) and np.all(np.isfinite(s)) and np.all(s > 0), name
    fit = res.thermal_fit
    assert fit["method"].startswith("thermal states of the systematic filter") and "plateaus" not in fit
    assert fit["chi2"] == res.diagnostics["innovations"]["chi2"] and fit["dof"] == res.diagnostics["innovations"]["dof"]
    assert {"expected_chi2", "p_value", "consistent", "scale"} <= set(fit)
    d = res.diagnostics["thermal"]
    assert (d["t_ref"], d["t_min"], d["t_max"], d["span"], d["sensor"], d["rate_window_s"]) == \
        (T_REF, T_LO, T_HI, SPAN, "", WINDOW_S)
    assert d["rate_max_c_per_min"] == pytest.approx(RAMP, rel=1e-4)
    assert d["orders"] == {"gyro_bias": 2, "gyro_scale_factor": 2, "accel_bias": 3, "accel_scale_factor": 2,
                           "gyro_bias_rate": 1}
    table = d["coefficients"]
    assert list(table) == ["gyro_bias_dT1", "gyro_bias_dT2", "gyro_scale_factor_dT1", "gyro_scale_factor_dT2",
                           "accel_bias_dT1", "accel_bias_dT2", "accel_bias_dT3", "accel_scale_factor_dT1",
                           "accel_scale_factor_dT2", "gyro_bias_rate"]
    for g, row in table.items():
        term, k = ("gyro_bias_rate", 0) if g == "gyro_bias_rate" else (g[:-4], int(g[-1]))
        base = "deg/h/(degC/min)" if k == 0 else THERMAL_TERMS[term][2]
        assert row["unit"] == (base if k == 0 else units.per_degree_unit(base, k))
        value = th.gyro_bias_rate if k == 0 else getattr(th, term)[k - 1]
        sig = res.thermal_sigma[term] if k == 0 else res.thermal_sigma[term][k - 1]
        np.testing.assert_allclose(row["value"], units.from_si(value, base), rtol=1e-12, err_msg=g)
        np.testing.assert_allclose(row["sigma"], units.from_si(sig, base), rtol=1e-12, err_msg=g)
        assert np.all(np.array(row["ratio"]) < 0.01) and np.all(np.array(row["prior_sigma"]) > row["sigma"]), g
        if "data_sigma_ratio" in row:  # given when the driver hands thermal_result every parameter's covariance
            assert np.all(np.array(row["data_sigma_ratio"]) < 0.01), g
    # the covariance holds the thermal states last, labelled by group and axis
    labels = res.covariance["labels"]
    o = thermal_offset(res.states)
    assert labels[o] == "gyro_bias_dT1[x]" and labels[-1] == "gyro_bias_rate[z]" and len(labels) == o + 30


# ----------------------------------------------------------------------------- what a history cannot separate
def _data_ratio(res):
    st = res.states
    prior = prior_sigma(st, dict(DEFAULT_SIGMA0), res.diagnostics["thermal"]["span"])
    return 1.0 / np.sqrt(np.maximum(data_information(res.covariance["P"], prior, thermal_offset(st)), 1e-300))


def test_what_a_temperature_history_leaves_unseparated(result):
    """At a constant temperature every coefficient stays at its prior and the notes name them all; a ramp at one
    rate leaves the dT/dt term in one combination with the base gyro bias: its marginal sigma is small (the base
    bias's prior bounds the combination) but the data alone do not separate it (data_information), while the
    hold-ramp record separates every coefficient.  Thermal states from ``thermal_orders`` without ``states``."""
    lin = linear_model()
    orders = {"gyro_bias": 1, "gyro_scale_factor": 1, "accel_bias": 1, "accel_scale_factor": 1}  # rate: default 1
    runs = {}
    for kind in ("constant", "ramp"):
        rec = simulate(scenario(kind, lin, sensor_hz=1.0)).to_record()
        runs[kind] = calibrate(rec, "systematic51", thermal_orders=orders, max_passes=3)
        d = runs[kind].diagnostics
        assert d["states"] == 9 + 42 + 15 and d["state_options"] == "51,thermal=11111"
        assert d["thermal"]["orders"] == orders | {"gyro_bias_rate": 1}
    const = runs["constant"]
    note = [n for n in const.notes if n.startswith("thermal coefficients not observed")]
    assert len(note) == 1 and all(f"{g} xyz" in note[0] for g in
                                  ("gyro_bias_dT1", "gyro_scale_factor_dT1", "accel_bias_dT1",
                                   "accel_scale_factor_dT1", "gyro_bias_rate")), const.notes
    assert all(np.allclose(r["ratio"], 1.0, atol=1e-6) for r in const.diagnostics["thermal"]["coefficients"].values())
    assert const.thermal.is_zero  # left at the prior mean
    ramp = runs["ramp"]
    assert np.all(_data_ratio(ramp)[-3:] > 10.0)  # the dT/dt term: the data alone leave it free
    assert np.all(_data_ratio(ramp)[:-3] < 1e-2)  # the polynomial terms: separated
    assert np.all(np.array(ramp.diagnostics["thermal"]["coefficients"]["gyro_bias_rate"]["ratio"]) < 0.5)
    assert {u["parameter"] for u in ramp.diagnostics["unobservable"]} == {"gyro_bias"}
    assert any("gyro_bias_rate xyz" in n for n in ramp.notes if n.startswith("thermal coefficients not observed"))
    assert any("never falls (or never rises)" in n for n in ramp.notes)  # a one-way history, said so
    assert np.all(_data_ratio(result) < 1e-2)  # the hold-ramp record separates every coefficient
    assert np.all(_data_ratio(const) > 10.0)


# ----------------------------------------------------------------------------- refusals
def _refusal(rec, **kw) -> str:
    with pytest.raises(CalibrationError) as exc:
        calibrate(rec, "systematic51", **kw)
    msg = str(exc.value)
    assert "\n" not in msg and msg
    return msg


def test_refusals(clean):
    _, _, rec = clean
    plain = dataclasses.replace(rec, temperature=None)
    assert "need the record's temperature" in _refusal(plain, states="51,thermal")
    assert "t_ref 80 degC lies above the record's temperatures (-20 .. 60 degC, by 20 degC)" in _refusal(rec, states="51,thermal",
                                                                                          t_ref=80.0)
    assert "t_ref must be a temperature" in _refusal(rec, states="51,thermal", t_ref=math.nan)
    assert "thermal=9: expected five digits" in _refusal(rec, states="51,thermal=9")
    assert "thermal=22324: the polynomial orders go up to 3 and the dT/dt term is 0 or 1" in \
        _refusal(rec, states="51,thermal=22324")
    assert "unknown term(s) ['gyro_misalignment']" in _refusal(rec, thermal_orders={"gyro_misalignment": 1})
    assert "thermal order of accel_bias: 4, expected a whole number 0 .. 3" in \
        _refusal(rec, thermal_orders={"accel_bias": 4})
    assert "thermal order of gyro_bias_rate: 2" in _refusal(rec, thermal_orders={"gyro_bias_rate": 2})
    assert "no temperature sensor 'case'" in _refusal(rec, states="51,thermal", temperature_sensor="case")
    assert "temperature-rate window must be > 0 s" in _refusal(rec, states="51,thermal", temperature_rate_window_s=0.0)
    late = dataclasses.replace(rec, temperature=dataclasses.replace(rec.temperature, time=rec.temperature.time + 100.0))
    assert "temperature covers" in _refusal(late, states="51,thermal")
    # thermal=00000 is no thermal state at all; without thermal states a record without temperature calibrates
    assert StateSet.parse("51,thermal=00000").thermal == ()
