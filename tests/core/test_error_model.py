"""Canonical error model: exact forward/compensation round trip, S16 <-> N25 conversion, units."""

import math

import numpy as np
import pytest

from inscal.core import units
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise, errors_from_field, errors_to_field, from_s16, noise_from_field, off_diagonal, size_effect, split_scale_misalignment, to_s16


def full_errors(rng) -> ImuErrors:
    ug, g2 = units.to_si(1, "ug"), units.to_si(1, "ug/g^2")
    return ImuErrors(
        gyro_scale_factor=rng.normal(0, 300e-6, 3), gyro_misalignment=rng.normal(0, units.to_si(180, "arcsec"), 6),
        gyro_bias=rng.normal(0, units.to_si(0.05, "deg/h"), 3),
        gyro_g_sensitivity=rng.normal(0, units.to_si(0.001, "deg/h/g"), (3, 3)),
        accel_scale_factor=rng.normal(0, 300e-6, 3), accel_misalignment=rng.normal(0, units.to_si(180, "arcsec"), 6),
        accel_bias=rng.normal(0, 200 * ug, 3), accel_nonlinearity=rng.normal(0, 300 * g2, 3),
        accel_cross_coupling=rng.normal(0, 300 * g2, 6), accel_lever_arm=rng.normal(0, 0.02, (3, 3)),
    )


def test_forward_compensation_round_trip_exact():
    rng = np.random.default_rng(11)
    e = full_errors(rng)
    w = rng.normal(0, 0.2, (200, 3))
    f = rng.normal(0, 9.8, (200, 3))
    wd = rng.normal(0, 0.2, (200, 3))
    ng, na = e.measure(w, f, wd)
    w2, f2 = e.compensate(ng, na, wd)
    assert np.max(np.abs(w2 - w) / np.linalg.norm(w, axis=1, keepdims=True)) < 1e-12
    assert np.max(np.abs(f2 - f) / np.linalg.norm(f, axis=1, keepdims=True)) < 1e-12


def test_forward_model_terms_match_their_definitions():
    """Each S16 term in isolation, against its printed definition (S16 eq. 1, 4-6, 9-12)."""
    f = np.array([1.0, 2.0, 9.0])
    w = np.array([0.1, -0.2, 0.3])
    e = ImuErrors(accel_nonlinearity=[1e-4, 2e-4, 3e-4])
    assert e.measure(w, f)[1] == pytest.approx(f + np.array([1e-4, 2e-4, 3e-4]) * f**2, abs=1e-15)
    kx = np.arange(1, 7) * 1e-5  # [xy, xz, yx, yz, zx, zy]
    e = ImuErrors(accel_cross_coupling=kx)
    fx, fy, fz = f
    expect = f + np.array([kx[0] * fx * fy + kx[1] * fx * fz, kx[2] * fx * fy + kx[3] * fy * fz, kx[4] * fx * fz + kx[5] * fy * fz])
    assert e.measure(w, f)[1] == pytest.approx(expect, abs=1e-15)
    r = np.array([0.02, 0.03, 0.04])
    e = ImuErrors(accel_lever_arm=r)  # S16: lever arm along each accelerometer's own axis
    wx, wy, wz = w
    expect = f - np.array([(wy**2 + wz**2) * r[0], (wx**2 + wz**2) * r[1], (wx**2 + wy**2) * r[2]])  # S16 eq. 9-11
    assert e.measure(w, f)[1] == pytest.approx(expect, abs=1e-16)
    G = np.arange(9.0).reshape(3, 3) * 1e-7
    e = ImuErrors(gyro_g_sensitivity=G)
    assert e.measure(w, f)[0] == pytest.approx(w + G @ f, abs=1e-17)  # S16 eq. 1


def test_size_effect_general_lever_arm_is_rigid_body_kinematics():
    rng = np.random.default_rng(2)
    p = rng.normal(0, 0.05, (3, 3))
    w, wd = rng.normal(size=3), rng.normal(size=3)
    a = size_effect(p, w, wd)
    for i in range(3):
        full = np.cross(w, np.cross(w, p[i])) + np.cross(wd, p[i])
        assert a[i] == pytest.approx(full[i], abs=1e-15)


def test_increment_model_equals_rate_model_for_constant_inputs():
    rng = np.random.default_rng(7)
    e = full_errors(rng)
    w, f, dt = rng.normal(0, 0.1, 3), rng.normal(0, 9.8, 3), 0.01
    ng, na = e.measure(w, f)
    sq = f * f
    cr = np.array([f[0] * f[1], f[0] * f[2], f[1] * f[2]])
    ww = np.array([w[0] ** 2, w[1] ** 2, w[2] ** 2, w[0] * w[1], w[0] * w[2], w[1] * w[2]])
    dng, dna = e.measure_increments(dt, w * dt, f * dt, sq * dt, cr * dt, ww * dt, np.zeros(3))
    assert dng == pytest.approx(ng * dt, rel=1e-14)
    assert dna == pytest.approx(na * dt, rel=1e-14)


def test_s16_conversion_round_trip_and_meaning():
    rng = np.random.default_rng(8)
    e = full_errors(rng)
    s16, C_s_m = to_s16(e)
    # T_g is lower unit-triangular by construction; C_s_m is a proper rotation
    assert np.allclose(C_s_m @ C_s_m.T, np.eye(3), atol=1e-15) and np.linalg.det(C_s_m) == pytest.approx(1.0)
    assert s16.T_g[0, 1] == 0.0 and s16.T_g[0, 2] == 0.0 and s16.T_g[1, 2] == 0.0
    back = from_s16(s16, C_s_m)
    for name in ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "gyro_g_sensitivity",
                 "accel_scale_factor", "accel_misalignment", "accel_bias"):
        assert getattr(back, name) == pytest.approx(getattr(e, name), rel=1e-9, abs=1e-18)
    # meaning: the S16 compensation form gives the true rate in the m-frame (linear part)
    lin = ImuErrors(**{k: getattr(e, k) for k in ("gyro_scale_factor", "gyro_misalignment", "gyro_bias",
                                                  "accel_scale_factor", "accel_misalignment", "accel_bias")})
    s16l, C = to_s16(lin)
    w, f = rng.normal(size=3), rng.normal(size=3) * 9.8
    ng, na = lin.measure(w, f)
    assert s16l.T_g @ np.diag(s16l.K_g) @ ng - s16l.b_g == pytest.approx(C @ w, abs=1e-15)  # S16 eq. 3
    assert s16l.T_a @ np.diag(s16l.K_a) @ na - s16l.b_a == pytest.approx(C @ f, abs=1e-13)  # S16 eq. 6
    # the gyro x input axis is the m-frame x axis: x row of M_g C_m^s has no y, z entries
    Mm = lin.M_g @ C.T
    assert abs(Mm[0, 1]) < 1e-15 and abs(Mm[0, 2]) < 1e-15


def test_split_scale_misalignment_exact():
    k, ang = np.array([1e-4, -2e-4, 3e-4]), np.array([1e-3, -2e-3, 3e-3, 4e-4, -5e-4, 6e-4])
    M = (np.eye(3) + np.diag(k)) @ (np.eye(3) + off_diagonal(ang))
    k2, a2 = split_scale_misalignment(M)
    assert k2 == pytest.approx(k, abs=1e-15) and a2 == pytest.approx(ang, abs=1e-15)


def test_field_units_round_trip_and_refusals():
    d = {"gyro_bias": [0.01, 0.02, -0.03], "accel_bias": {"value": [1, 2, 3], "unit": "mg"},
         "gimbal_nonorthogonality": 20, "mount_attitude": {"value": [0.1, 0.1, 20], "unit": "deg"},
         "accel_lever_arm": {"value": [[2, 0, 0], [0, 2, 0], [0, 0, 2]], "unit": "cm"}}
    imu, gim = errors_from_field(d)
    assert imu.gyro_bias[2] == pytest.approx(-0.03 * math.pi / 180 / 3600)
    assert imu.accel_bias[0] == pytest.approx(1e-3 * 9.80665)
    assert gim.nonorthogonality == pytest.approx(20 * math.pi / 180 / 3600)
    back = errors_to_field(imu, gim)
    assert back["accel_bias"]["unit"] == "ug" and back["accel_bias"]["value"] == pytest.approx([1000, 2000, 3000])
    imu2, gim2 = errors_from_field(back)
    assert imu2.accel_lever_arm == pytest.approx(imu.accel_lever_arm, rel=1e-15)
    with pytest.raises(ValueError, match="unknown parameter"):
        errors_from_field({"gyro_bais": [0, 0, 0]})
    with pytest.raises(ValueError, match="angle unit"):
        errors_from_field({"gyro_bias": {"value": [0, 0, 0], "unit": "arcsec"}})
    with pytest.raises(ValueError, match="shape"):
        errors_from_field({"gyro_bias": [1, 2]})
    with pytest.raises(ValueError, match="NaN"):
        ImuErrors(gyro_bias=[0, float("nan"), 0])
    with pytest.raises(ValueError):
        noise_from_field({"arw": -1})


def test_units_table():
    assert units.to_si(1, "deg/h") == pytest.approx(4.84813681109536e-6)
    assert units.to_si(1, "arcsec") == pytest.approx(4.84813681109536e-6)
    assert units.to_si(1, "ug") == pytest.approx(9.80665e-6)
    assert units.to_si(1, "ug/g^2") == pytest.approx(1e-6 / 9.80665)
    assert units.to_si(1, "deg/h/g") == pytest.approx(4.84813681109536e-6 / 9.80665)
    assert units.to_si(1, "deg/sqrt(h)") == pytest.approx(math.pi / 180 / 60)
    assert units.to_si(1, "ug/sqrt(Hz)") == pytest.approx(9.80665e-6)
    assert units.to_si(2, "cm") == pytest.approx(0.02)
    assert units.to_si(1, "°/h") == units.to_si(1, "deg/h")
    assert units.from_si(units.to_si(123.0, "ppm"), "ppm") == pytest.approx(123.0)
    with pytest.raises(units.UnitError):
        units.to_si(1, "furlong")
    with pytest.raises(units.UnitError):
        units.to_si(1, "cm", kind="angle")


def test_frozen_and_readonly():
    e = ImuErrors()
    with pytest.raises(Exception):
        e.gyro_bias = np.ones(3)
    with pytest.raises(ValueError):
        e.gyro_bias[0] = 1.0
    assert ImuNoise().is_zero and not ImuNoise(arw=1e-6).is_zero
    assert GimbalErrors().nonorthogonality == 0.0
