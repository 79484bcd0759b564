"""Thermal-chamber calibration from plateaus (``thermal-plateaus``): the plateaus cut from the record,
the weighted polynomial fit against independent solutions, noise-free recovery of every thermal
coefficient, error / sigma with noise over a few seeds (the 20-seed study: bench/thermal_plateaus_seeds.py),
and the one-line refusals.  The records run at 20 Hz (the built-in scenario's 100 Hz changes nothing
the claims depend on, and costs five times the time)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.calibrate.result import param_value
from inscal.calibrate.thermal import (
    check_orders,
    combine,
    cut_path,
    find_plateaus,
    fit_raising_order,
    fit_term,
    plateau_records,
    stable_intervals,
    thermal_truth,
)
from inscal.calibrate.windows import CalibrationError, window_means
from inscal.core.error_model import ImuNoise
from inscal.core.thermal import THERMAL_TERMS
from inscal.io.records import Temperature
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

RATE_HZ = 20.0
LEVELS = scenarios.THERMAL_PLATEAUS_C
#: the built-in thermal model has a cubic accelerometer bias: fit it with its own order
ORDERS = {"accel_bias": 3}
#: the relative tolerance of the noise-free tests of the window methods (tests/calibrate/test_calibrate.py)
REL = 1e-6


def scenario(noise: bool = False, **kw):
    sc = dataclasses.replace(scenarios.build("thermal-plateaus"), rate_hz=RATE_HZ, **kw)
    return sc if noise else dataclasses.replace(sc, noise=ImuNoise())


@pytest.fixture(scope="module")
def clean():
    sc = scenario()
    return sc, simulate(sc).to_record()


def rel_errors(res, model) -> dict[str, float]:
    """Largest relative error of every coefficient of the truth ``model`` that ``res`` fitted."""
    out = {}
    for name in THERMAL_TERMS:
        tru = getattr(model, name)
        if tru.shape[0] == 0:
            continue
        est = getattr(res.thermal, name)
        assert est.shape == tru.shape, (name, est.shape, tru.shape)
        out[name] = float(np.max(np.abs(est - tru) / np.abs(tru)))
    return out


# ----------------------------------------------------------------------------- plateaus
def test_plateaus_cut_exactly(clean):
    """Each plateau is one copy of the base path, cut exactly: the same moves, time from 0 and the same
    increments as a simulation of the base path at the plateau's constant temperature."""
    sc, rec = clean
    plats = find_plateaus(rec)
    assert [p.temperature_c for p in plats] == list(LEVELS)
    assert all(p.spread_c == 0.0 for p in plats)
    base = dataclasses.replace(scenarios.build("n25"), noise=ImuNoise(), rate_hz=RATE_HZ)
    subs = plateau_records(rec, plats)
    for sub in subs[::2]:
        assert sub.path.moves == base.path.moves and sub.path.initial_dwell == base.path.initial_dwell
        assert sub.path.closed and np.allclose(sub.path.initial, base.path.initial, atol=1e-12)
        d = simulate(dataclasses.replace(base, imu=sc.thermal.errors_at(sc.imu, sub.plateau.temperature_c)))
        assert sub.time.shape == d.time.shape and np.max(np.abs(sub.time - d.time)) < 1e-9
        assert np.max(np.abs(sub.gimbal - d.gimbal)) < 1e-10
        assert np.max(np.abs(sub.dtheta - d.dtheta)) < 1e-9 * np.max(np.abs(d.dtheta))
        assert np.max(np.abs(sub.dvel - d.dvel)) < 1e-9 * np.max(np.abs(d.dvel))
    # the per-plateau method takes them like any record (the 12 positions and 6 rate tests of N25)
    ws = window_means(subs[1])
    assert len(ws.rate) == 6 and len([w for w in ws.static if w.duration > 90]) == 14


def test_plateaus_from_temperature_alone(clean):
    """Without the chamber's labels the plateaus are found in the temperature; the path is cut at rest."""
    _, rec = clean
    plats = find_plateaus(rec, chamber_label=None)
    assert [p.temperature_c for p in plats] == list(LEVELS)
    seg = rec.path.segments()
    for p in plats:
        _, w, acc = seg.angles(np.array([p.t0, p.t1]))
        assert np.all(w == 0) and np.all(acc == 0)  # both ends at rest
        sub_path, a, b = cut_path(rec.path, p.t0, p.t1)
        assert (a, b) == (p.t0, p.t1)
        t = np.linspace(a, b, 997)
        assert np.allclose(sub_path.segments().angles(t - a)[0], seg.angles(t)[0], atol=1e-9)
    # a cut inside a rotation moves to its end (start) and the part still follows the path
    moving = np.flatnonzero(np.abs(seg.w0).sum(axis=1) > 0)
    k = moving[3]
    mid = 0.5 * (seg.t0[k] + seg.t1[k])
    part, a, b = cut_path(rec.path, mid, 20000.0)
    assert a > mid and b <= 20000.0
    t = np.linspace(a, b, 1001)
    assert np.allclose(part.segments().angles(t - a)[0], seg.angles(t)[0], atol=1e-9)


def test_stable_intervals_with_sensor_noise():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 20000.0, 1.0)
    # 20 degC, a ramp to 45, back to 20 and a slow drift of 0.3 degC over 4000 s (within the tolerance)
    T = np.interp(t, [0, 3000, 4500, 8000, 9500, 14000, 18000, 20000], [20, 20, 45, 45, 20, 20, 20.3, 20.3])
    T = T + 0.05 * rng.standard_normal(t.size)
    got = [(t[i], t[j - 1], float(np.mean(T[i:j]))) for i, j in stable_intervals(t, T, 0.5, 600.0)]
    assert len(got) == 3, got
    for (a, b, m), (a0, b0, m0) in zip(got, [(0, 3000, 20), (4500, 8000, 45), (9500, 20000, 20.13)]):
        assert abs(a - a0) <= 160 and abs(b - b0) <= 160 and abs(m - m0) < 0.05, (a, b, m)
    # a tolerance below the drift splits the last plateau
    assert len(stable_intervals(t, T, 0.1, 600.0)) > 3


# ----------------------------------------------------------------------------- the weighted fit
def test_fit_term_is_the_generalised_least_squares_solution():
    """The fit against a dense GLS over all plateaus (block-diagonal covariance inverted directly), and,
    with diagonal covariances, against numpy's weighted polyfit per component."""
    rng = np.random.default_rng(5)
    dT = np.array([-60.0, -35.0, -10.0, 15.0, 40.0])
    m, K = 3, 2
    truth = rng.standard_normal((K + 1, m)) * [[1.0], [1e-2], [1e-4]]
    covs = []
    for _ in dT:
        A = rng.standard_normal((m, m)) * 1e-3
        covs.append(A @ A.T + np.diag(rng.uniform(1e-7, 1e-6, m)))
    X = [np.kron(d ** np.arange(K + 1), np.eye(m)) for d in dT]
    y = np.array([X[p] @ truth.ravel() + rng.multivariate_normal(np.zeros(m), covs[p]) for p in range(dT.size)])
    f = fit_term("accel_bias", dT, y, covs, K)
    Winv = [np.linalg.inv(C) for C in covs]
    N = sum(X[p].T @ Winv[p] @ X[p] for p in range(dT.size))
    b = np.linalg.solve(N, sum(X[p].T @ Winv[p] @ y[p] for p in range(dT.size)))
    assert np.allclose(f.coef.ravel(), b, rtol=1e-9, atol=1e-15)
    chi2 = sum((y[p] - X[p] @ b) @ Winv[p] @ (y[p] - X[p] @ b) for p in range(dT.size))
    assert f.chi2 == pytest.approx(chi2, rel=1e-9) and f.dof == 6
    if f.consistent:
        assert np.allclose(f.cov, np.linalg.inv(N), rtol=1e-8)
    # gains: coef = sum_p A_p y_p
    assert np.allclose(sum(f.gains[p] @ y[p] for p in range(dT.size)), f.coef.ravel(), rtol=1e-9, atol=1e-15)
    # diagonal covariances: per-component weighted polyfit
    sig = np.array([np.sqrt(np.diag(C)) for C in covs])
    fd = fit_term("accel_bias", dT, y, [np.diag(s ** 2) for s in sig], K)
    for c in range(m):
        ref = np.polyfit(dT, y[:, c], K, w=1.0 / sig[:, c])[::-1]
        assert np.allclose(fd.coef[:, c], ref, rtol=1e-8, atol=1e-15)


def test_inconsistent_fit_treats_the_misfit_as_systematic():
    """An inconsistent fit: sigma = sum_p |gain_p| s_c sigma_p (at least s_c x formal), the gains of the
    weighted least squares computed independently here; a consistent one keeps the formal sigma."""
    dT = np.linspace(-60.0, 40.0, 5)
    rng = np.random.default_rng(2)
    sig = np.array([1e-6, 2e-6, 1e-6])
    y = rng.standard_normal((5, 3)) * sig
    y[:, 2] += 1e-5 * dT ** 2  # a quadratic seen with order 1: component z misfits
    covs = [np.diag(sig ** 2)] * 5
    f = fit_term("gyro_bias", dT, y, covs, 1)
    assert not f.consistent and f.p_value < 1e-3 and "treated as systematic" in f.note and "\n" not in f.note
    X = np.vander(dT, 2, increasing=True)
    for c in range(3):
        H = np.linalg.solve(X.T @ X / sig[c] ** 2, X.T / sig[c] ** 2)  # coef = H y
        formal = np.sqrt(np.diag(H @ H.T)) * sig[c]
        s_c = max(1.0, math.sqrt(f.chi2_components[c] / 3))
        want = np.maximum(np.abs(H).sum(axis=1) * s_c * sig[c], s_c * formal)
        assert np.allclose(f.sigma[:, c], want, rtol=1e-9), c
    assert f.chi2_components[2] > 100 * 3 and np.all(f.sigma[:, 2] > 10 * f.sigma[:, 0])
    # the quadratic's effect on the value at 0 and the slope is covered by the systematic sigma
    truth = np.polyfit(dT, 1e-5 * dT ** 2, 1)[::-1]  # what the order-1 fit converges to, noise-free
    assert np.all(np.abs(f.coef[:, 2] - truth) < f.sigma[:, 2])
    # with the right order the fit is consistent and the sigma formal
    f2 = fit_term("gyro_bias", dT, y, covs, 2)
    assert f2.consistent and np.all(f2.scale == 1.0) and not f2.note


# ----------------------------------------------------------------------------- noise-free recovery
def test_noise_free_recovery_n25(clean):
    """With the default orders (quadratic): the cubic accelerometer bias of the truth leaves noise-free plateau
    estimates off the quadratic by 17 ug rms, so its order is raised to 3 and every coefficient comes back to 1e-6
    (order 2 gave the linear term 18 % off at 3.5 sigma, the fit called consistent); a named order is kept and its
    fit flagged inconsistent, its sigma scaled."""
    sc, rec = clean
    res = calibrate(rec, "thermal-plateaus", per_plateau="n25")
    rel = rel_errors(res, sc.thermal)
    assert set(rel) == {"gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor"}
    assert max(rel.values()) < REL, rel
    assert res.thermal.order("accel_bias") == 3 and res.thermal.order("gyro_bias") == 2
    assert any(n.startswith("accel_bias: order 2 misfits the plateaus") and "raised to order 3" in n for n in res.notes)
    # the per-plateau estimates themselves are exact: the scatter was the quadratic's misfit
    for p in res.diagnostics["plateaus"]:
        tru = sc.thermal.errors_at(sc.imu, p["temperature_c"]).accel_bias
        assert np.max(np.abs(np.array(p["values"]["accel_bias"]) - tru)) < REL * np.max(np.abs(tru))
    # the order named: kept, the fit flagged inconsistent and its systematic sigma covers the error it leaves
    plats = find_plateaus(rec)
    two = combine(res.diagnostics["plateau_results"], plats, check_orders({"accel_bias": 2}), 20.0, "", "n25",
                  frozenset({"accel_bias"}))
    assert two.thermal.order("accel_bias") == 2 and not two.thermal_fit["terms"]["accel_bias"]["consistent"]
    assert any(n.startswith("accel_bias: the order-2 fit over 5 plateaus is inconsistent") for n in two.notes)
    err = two.thermal.accel_bias - sc.thermal.accel_bias[:2]
    assert np.max(np.abs(err[0]) / np.abs(sc.thermal.accel_bias[0])) > 0.1  # the linear term 12-18 % off
    assert np.all(np.array(two.thermal_fit["terms"]["accel_bias"]["scale"]) > 10)  # sigma scaled, not formal
    th = res.thermal
    assert (th.t_ref, th.t_min, th.t_max) == (20.0, LEVELS[0], LEVELS[-1])
    assert not np.any(th.gyro_bias_rate) and np.all(np.isnan(res.thermal_sigma["gyro_bias_rate"]))
    assert any("gyro_bias_rate" in n and "not estimated" in n for n in res.notes)
    assert any("no covariance" in n for n in res.notes)  # n25 reports sigma only
    assert len(res.diagnostics["plateaus"]) == 5 and res.thermal_fit["per_plateau"] == "n25"
    # the misalignments are constant (order 0, their weighted mean): no thermal term for them
    assert th.order("gyro_misalignment") == 0 and "gyro_misalignment" in res.thermal_fit["constant"]


def test_noise_free_recovery_joint_and_values_at_t_ref(clean):
    sc, rec = clean
    res = calibrate(rec, "thermal-plateaus", per_plateau="joint", orders=ORDERS, t_ref=10.0)
    # the truth at the new reference: errors_at(10 degC), coefficients re-expanded about 10 degC
    ref = sc.thermal.errors_at(sc.imu, 10.0)
    for name in res.estimated:
        est, tru = np.atleast_1d(res.value(name)), np.atleast_1d(param_value(ref, sc.gimbal, name))
        assert np.all(np.abs(est - tru) <= REL * np.abs(tru)), name
    truth = thermal_truth(res, sc.imu, sc.gimbal, sc.thermal)
    for name, c in truth.items():
        assert np.all(np.abs(getattr(res.thermal, name) - c) <= REL * np.abs(c)), name
    # about 10 degC the linear accelerometer bias term is c1 + 2 c2 (-10) + 3 c3 (-10)^2
    c = sc.thermal.accel_bias
    assert np.allclose(truth["accel_bias"][0], c[0] + 2 * c[1] * -10.0 + 3 * c[2] * 100.0, rtol=1e-12)


def test_misalignment_terms_and_a_cubic_bias():
    """A truth with linear misalignment terms and third-order accelerometer biases, all recovered."""
    ARCSEC = math.pi / 180.0 / 3600.0
    model = scenarios.thermal_model().replace(
        gyro_misalignment=np.array([[0.05, -0.03, 0.04, 0.02, -0.06, 0.01]]) * ARCSEC,
        accel_misalignment=np.array([[-0.04, 0.05, 0.03, -0.02, 0.06, -0.05]]) * ARCSEC)
    sc = scenario(thermal=model)
    rec = simulate(sc).to_record()
    orders = {"accel_bias": 3, "gyro_misalignment": 1, "accel_misalignment": 1}
    res = calibrate(rec, "thermal-plateaus", per_plateau="joint", orders=orders)
    rel = rel_errors(res, model)
    assert set(rel) == {"gyro_bias", "gyro_scale_factor", "accel_bias", "accel_scale_factor", "gyro_misalignment",
                        "accel_misalignment"}
    assert max(rel.values()) < REL, rel
    # with the default orders (constant misalignments, quadratic biases) every misfitting order is raised
    auto = calibrate(rec, "thermal-plateaus", per_plateau="joint")
    assert max(rel_errors(auto, model).values()) < REL
    assert {n.split(":")[0] for n in auto.notes if "raised to order" in n} == {"accel_bias", "gyro_misalignment",
                                                                              "accel_misalignment"}
    # kept constant by name, the misalignments misfit the plateaus and their sigma are scaled, with a note
    const = combine(auto.diagnostics["plateau_results"], find_plateaus(rec), check_orders({"accel_bias": 3}), 20.0,
                    "", "joint", frozenset({"accel_bias", "gyro_misalignment", "accel_misalignment"}))
    assert not const.thermal_fit["constant"]["accel_misalignment"]["consistent"]
    assert any(n.startswith("accel_misalignment: the weighted mean") for n in const.notes)


# ----------------------------------------------------------------------------- with noise
@pytest.mark.parametrize("seeds", [(11, 12, 13)])
def test_error_over_sigma_with_noise(seeds):
    """error / sigma of every thermal coefficient over a few seeds (the 20-seed spread: the bench)."""
    sc = scenario(noise=True)
    z, p = [], []
    for seed in seeds:
        rec = simulate(sc, np.random.default_rng(seed)).to_record()
        res = calibrate(rec, "thermal-plateaus", orders=ORDERS)
        for name, c in thermal_truth(res, sc.imu, sc.gimbal, sc.thermal).items():
            zz = (getattr(res.thermal, name) - c) / res.thermal_sigma[name]
            assert np.all(np.isfinite(zz)), name
            z.append(zz.ravel())
            p.append(res.thermal_fit["terms"][name]["p_value"])
    z = np.concatenate(z)
    assert z.size == 3 * 3 * (2 + 2 + 3 + 2)
    assert np.max(np.abs(z)) < 4.5, np.max(np.abs(z))
    rms = math.sqrt(np.mean(z ** 2))
    assert 0.75 < rms < 1.3, rms  # 81 standard normal numbers: 0.85 .. 1.15 at 95 %
    assert min(p) > 1e-3  # no fit inconsistent on data the model describes


# ----------------------------------------------------------------------------- refusals (one line each)
def one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg and msg
    return msg


def test_refusals(clean):
    _, rec = clean
    no_temp = SimpleNamespace(**{**vars(rec), "temperature": None})
    with pytest.raises(CalibrationError) as e:
        calibrate(no_temp, "thermal-plateaus")
    assert "no temperature" in one_line(e)
    # three plateaus: a cubic needs four
    t3 = find_plateaus(rec)[2].t1
    n = int(np.searchsorted(rec.time, t3, side="right"))
    tt = rec.temperature.time <= t3 + 1
    short = SimpleNamespace(**{**vars(rec), "time": rec.time[:n], "dtheta": rec.dtheta[:n], "dvel": rec.dvel[:n],
                               "gimbal": rec.gimbal[:n], "temperature": Temperature(
                                   rec.temperature.time[tt], rec.temperature.values[tt], rec.temperature.sensors)})
    with pytest.raises(CalibrationError) as e:
        calibrate(short, "thermal-plateaus", orders={"accel_bias": 3})
    assert "3 temperature plateau(s) found (at -40, -15, 10 degC)" in one_line(e) and "needs at least 4" in str(e.value)
    for kw, text in (({"orders": {"accel_bias": 4}}, "expected 0 .. 3"),
                     ({"orders": {"gyro_misalignment": 2}}, "expected 0 .. 1"),
                     ({"orders": {"gyro_bias_rate": 1}}, "cannot be seen on plateaus"),
                     ({"orders": {"bias": 1}}, "unknown term 'bias'"),
                     ({"t_ref": 80.0}, "outside the plateaus' range -40 .. 60 degC"),
                     ({"per_plateau": "thermal-plateaus"}, "cannot be thermal-plateaus"),
                     ({"per_plateau": "n26"}, "unknown method 'n26'"),
                     ({"bogus": 1}, "unknown option(s) for n25: ['bogus']"),
                     ({"plateau_tol": 0.0}, "plateau tolerance must be > 0"),
                     ({"sensor": "case"}, "no temperature sensor 'case'")):
        with pytest.raises(CalibrationError) as e:
            calibrate(rec, "thermal-plateaus", **kw)
        assert text in one_line(e), (kw, str(e.value))
    # a copy of the path while the chamber still moves
    vals = rec.temperature.values.copy()
    vals[(rec.temperature.time > 12000) & (rec.temperature.time < 12500), 0] += 2.0
    drifting = SimpleNamespace(**{**vars(rec), "temperature": Temperature(rec.temperature.time, vals, ("imu",))})
    with pytest.raises(CalibrationError) as e:
        calibrate(drifting, "thermal-plateaus")
    assert "copy 3 of the path" in one_line(e) and "is not on a plateau" in str(e.value)
    with pytest.raises(CalibrationError) as e:
        calibrate(window_means(plateau_records(rec, find_plateaus(rec)[:1])[0]), "thermal-plateaus")
    assert "needs the record" in one_line(e)
    assert check_orders(None)["gyro_bias"] == 2 and check_orders({"accel_bias": 3})["accel_bias"] == 3


def test_noise_free_plateaus_give_the_coefficients_back():
    """A noise-free record: every plateau estimate has a zero sigma.  The fit cannot weight them; it fits them
    alike (they are exact up to round-off), returns the polynomial, and says so, instead of stopping with "a
    plateau estimate has a zero or non-finite sigma"."""
    dT = np.array([-30.0, -10.0, 0.0, 15.0, 30.0])
    coef = np.array([[1e-4, -2e-4, 3e-4], [2e-6, 1e-6, -1e-6], [3e-8, -1e-8, 2e-8]])  # order 2, three axes
    y = np.array([coef[0] + coef[1] * t + coef[2] * t * t for t in dT])
    f = fit_term("accel_bias", dT, y, [np.zeros((3, 3)) for _ in dT], 2)
    assert np.allclose(f.coef, coef, rtol=1e-9, atol=1e-18)
    assert np.all(f.sigma < 1e-12 * np.abs(coef) + 1e-20) and "noise-free" in f.note and math.isnan(f.p_value)
    # with a misfit (a plateau off by 1e-6, 1e-2 of the values: far above their round-off) the fit is
    # inconsistent and its systematic sigma (sum over plateaus of |gain| x residual rms) covers the error
    y2 = y.copy()
    y2[2] += 1e-6
    f2 = fit_term("accel_bias", dT, y2, [np.zeros((3, 3)) for _ in dT], 2)
    assert not f2.consistent and "noise-free plateau estimates (zero sigma) off the polynomial" in f2.note
    assert np.all(f2.sigma[0] > 1e-7) and np.all(np.abs(f2.coef - coef) < f2.sigma + 1e-12)
    # the residual rms per component is the one independent least squares leaves (each column alike)
    X = np.vander(dT, 3, increasing=True)
    r = y2 - X @ np.linalg.lstsq(X, y2, rcond=None)[0]
    assert np.allclose(f2.chi2_components, np.sum(r ** 2, axis=0), rtol=1e-9)
    # a misfit at the round-off (1e-7 of the values) is none: the fit stays consistent
    y3 = y.copy()
    y3[2] += 0.5e-7 * np.abs(y).max(axis=0)
    f3 = fit_term("accel_bias", dT, y3, [np.zeros((3, 3)) for _ in dT], 2)
    assert f3.consistent and "noise-free" in f3.note
    # raising the order: a quadratic seen from order 1 is raised to 2 and fits exactly
    f4, note = fit_raising_order("accel_bias", dT, y, [np.zeros((3, 3)) for _ in dT], 1, 3)
    assert f4.order == 2 and f4.consistent and "raised to order 2" in note
    assert np.allclose(f4.coef, coef, rtol=1e-9, atol=1e-18)
