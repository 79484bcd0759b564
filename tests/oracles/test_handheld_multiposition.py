"""Multi-position calibration (no turntable) against the independent hand-held generator
(tests/oracles/handheld_imu.py, NumPy only): noise-free logs give back every parameter to 1e-9 relative
for MEMS, tactical and navigation-grade magnitudes; noisy logs (tremor, jittered clock) within 3 sigma,
with a small error/sigma study (the 50-seed one: bench/bench_multiposition.py); a pose set that cannot
separate the accelerometer parameters is refused, naming them and the pose that would help."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade, rot

from inscal.calibrate import calibrate
from inscal.calibrate.multiposition import frame_of, lower_frame
from inscal.calibrate.result import errors_from_values
from inscal.calibrate.windows import CalibrationError
from inscal.core.earth import Site

LAT, G = 0.8, 9.80
NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias")


def record(lg):
    return SimpleNamespace(time=lg.time, dtheta=lg.dtheta, dvel=lg.dvel, site=Site(LAT, gravity_model=G))


def fit(kind, seed, noise, n_poses=10, rate_hz=50.0, **kw):
    rng = np.random.default_rng(seed)
    Mg, bg, Ma, ba, arw, vrw = grade(kind, rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=n_poses, rate_hz=rate_hz, lat=LAT, g=G, arw=arw * noise,
                  vrw=vrw * noise, **kw)
    res = calibrate(record(lg), "multi-position", min_static=2.0, settle=0.25)
    return res, canonical_truth(Mg, bg, Ma, ba)


@pytest.mark.parametrize("kind", ["mems", "tactical", "navigation"])
def test_noise_free_logs_give_back_every_parameter(kind):
    res, truth = fit(kind, 7, 0.0)
    for name in NAMES:
        v, e = truth[name], res.value(name)
        free = np.isfinite(res.sigma[name])  # the accelerometer frame's three held angles are 0 by definition
        # 1e-9 of the parameter's size (the largest of its components; gyro bias: or of the Earth rate)
        size = max(np.max(np.abs(v)), 7.292115e-5 if name == "gyro_bias" else 0.0)
        assert np.all(np.abs(e - v)[free] <= 1e-9 * size), (name, (e - v) / size)
    assert res.diagnostics["earth_rate"]["visible"]


def test_noisy_hand_held_logs_within_3_sigma_and_error_over_sigma_near_one():
    z = []
    for seed, kind in ((1, "mems"), (2, "tactical"), (3, "mems")):
        res, truth = fit(kind, seed, 1.0, n_poses=12, tremor_deg=0.5, tremor_hz=8.0, jitter=0.2)
        assert res.fit["consistent"], res.notes
        for name in NAMES:
            s = res.sigma[name]
            free = np.isfinite(s)
            r = (res.value(name) - truth[name])[free] / s[free]
            assert np.all(np.abs(r) < 3.5), (kind, seed, name, r)  # 3 sigma, and a little for 63 components
            z.extend(r)
    assert 0.6 < np.std(z) < 1.4, np.std(z)  # 63 draws; the 50-seed study is in bench/


def test_truth_transform_maps_any_frame_into_the_accelerometer_frame():
    rng = np.random.default_rng(0)
    Ma = np.eye(3) + rng.normal(0, 1e-2, (3, 3))
    L, Q = lower_frame(Ma)
    assert np.allclose(L @ Q, Ma, atol=1e-15) and np.allclose(np.triu(L, 1), 0.0) and np.all(np.diag(L) > 0)
    assert np.allclose(Q @ Q.T, np.eye(3), atol=1e-15) and np.linalg.det(Q) > 0
    Mg = np.eye(3) + rng.normal(0, 1e-2, (3, 3))
    truth = canonical_truth(Mg, np.ones(3), Ma, np.ones(3))  # Ma full: not the accelerometer frame
    imu, _ = frame_of(errors_from_values(truth))
    Mg_p = (np.eye(3) + np.diag(imu.gyro_scale_factor)) @ (np.eye(3) + np.array(
        [[0, imu.gyro_misalignment[0], imu.gyro_misalignment[1]], [imu.gyro_misalignment[2], 0,
         imu.gyro_misalignment[3]], [imu.gyro_misalignment[4], imu.gyro_misalignment[5], 0]]))
    assert np.allclose(Mg_p, Mg @ Q.T, atol=1e-14)


def test_poses_about_one_axis_are_refused_naming_the_parameters_and_a_pose():
    rng = np.random.default_rng(5)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    poses = [rot([1.0, 0.0, 0.0], 2 * math.pi * j / 10 + 0.1) for j in range(10)]  # about body x, horizontal
    lg = generate(rng, Mg, bg, Ma, ba, poses=poses, rate_hz=50.0, arw=arw, vrw=vrw)
    with pytest.raises(CalibrationError) as exc:
        calibrate(record(lg), "multi-position", min_static=2.0, settle=0.25)
    msg = str(exc.value)
    assert "leave accel_scale_factor.x undetermined" in msg and "one axis, [1.00, " in msg, msg  # f_x = 0: b_x stays
    assert "+x" in msg or "-x" in msg, msg  # the pose that helps has x along gravity


def test_a_gyro_saturating_in_a_fast_turn_costs_that_rotation_only():
    rng = np.random.default_rng(8)
    Mg, bg, Ma, ba, arw, vrw = grade("tactical", rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=50.0, lat=LAT, g=G, arw=arw, vrw=vrw)
    dt = np.diff(np.concatenate([[0.0], lg.time]))
    rate = lg.dtheta / dt[:, None]
    moves = [(lg.time > a[1]) & (lg.time <= b[0]) for a, b in zip(lg.still[:-1], lg.still[1:])]
    peaks = np.array([np.abs(rate[m]).max(axis=0) for m in moves])  # (move, axis)
    ax = int(np.argmax(np.sort(peaks, axis=0)[-1] / np.sort(peaks, axis=0)[-2]))
    k = int(np.argmax(peaks[:, ax]))  # the fastest turn about that axis saturates it, no other one does
    clip = 0.5 * (np.sort(peaks[:, ax])[-1] + np.sort(peaks[:, ax])[-2])
    rate[:, ax] = np.clip(rate[:, ax], -clip, clip)
    lg.dtheta = rate * dt[:, None]
    res = calibrate(record(lg), "multi-position", min_static=2.0, settle=0.25)
    assert [n for n in res.notes if "saturates a gyro" in n] == [n for n in res.notes if f"move from pose {k + 1} to "
                                                                 f"{k + 2} " in n], res.notes
    assert any("saturates a gyro" in n for n in res.notes), res.notes
    truth = canonical_truth(Mg, bg, Ma, ba)
    for name in NAMES:
        s = res.sigma[name]
        free = np.isfinite(s)
        assert np.all(np.abs(res.value(name) - truth[name])[free] < 3.5 * s[free]), name


def test_the_quadratic_accelerometer_terms_with_enough_poses():
    rng = np.random.default_rng(4)
    Mg, bg, Ma, ba, _, _ = grade("tactical", rng)
    k2 = np.array([2e-5, -3e-5, 1.5e-5])  # 1/(m/s^2): 200-300 ug/g^2
    lg = generate(rng, Mg, bg, Ma, ba, k2=k2, n_poses=14, rate_hz=50.0, lat=LAT, g=G)
    res = calibrate(record(lg), "multi-position", quadratic=True, min_static=2.0, settle=0.25)
    truth = canonical_truth(Mg, bg, Ma, ba) | {"accel_nonlinearity": k2}
    assert "accel_nonlinearity" in res.estimated
    for name, v in truth.items():
        free = np.isfinite(res.sigma[name])
        assert np.all(np.abs(res.value(name) - v)[free] <= 1e-9 * np.max(np.abs(v))), name
    with pytest.raises(CalibrationError, match="the quadratic accelerometer model needs 12"):
        calibrate(record(generate(rng, Mg, bg, Ma, ba, n_poses=10, rate_hz=50.0)), "multi-position", quadratic=True,
                  min_static=2.0, settle=0.25)
