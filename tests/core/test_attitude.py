"""Attitude conventions and numba kernels against SciPy."""

import math

import numpy as np
import pytest
import scipy
from scipy.spatial.transform import Rotation

from inscal.core import attitude as at


def test_elementary_rotations_are_active():
    # +90 deg about x takes y to z (S16 Table 1 convention: outer +90 about East: N -> U)
    assert at.rot_x(math.pi / 2) @ [0, 1, 0] == pytest.approx([0, 0, 1], abs=1e-15)
    assert at.rot_y(math.pi / 2) @ [0, 0, 1] == pytest.approx([1, 0, 0], abs=1e-15)
    assert at.rot_z(math.pi / 2) @ [1, 0, 0] == pytest.approx([0, 1, 0], abs=1e-15)


def test_euler_zyx_order_and_round_trip():
    rng = np.random.default_rng(3)
    att = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], (50, 3))
    C = at.dcm_from_euler(att)
    for k in range(5):
        r, p, y = att[k]
        assert C[k] == pytest.approx(at.rot_z(y) @ at.rot_y(p) @ at.rot_x(r), abs=1e-15)  # N25 eq. 8
    assert at.euler_from_dcm(C) == pytest.approx(att, abs=1e-12)  # N25 eq. 36


def test_scipy_single_axis_from_euler_matches_our_rotation():
    """SciPy >= 1.17 changed from_euler for single-axis sequences; pin the behaviour we rely on."""
    assert tuple(int(x) for x in scipy.__version__.split(".")[:2]) >= (1, 17)
    for ax, fn in (("x", at.rot_x), ("y", at.rot_y), ("z", at.rot_z)):
        m = Rotation.from_euler(ax, 0.3).as_matrix()
        assert np.asarray(m).reshape(3, 3) == pytest.approx(fn(0.3), abs=1e-15)


def test_axis_angle_matches_scipy_rotvec():
    rng = np.random.default_rng(4)
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        ang = rng.uniform(-7, 7)
        assert at.axis_angle_dcm(axis, ang) == pytest.approx(Rotation.from_rotvec(axis * ang).as_matrix(), abs=1e-14)


def test_quaternion_kernels():
    rng = np.random.default_rng(5)
    for scale in (1e-9, 1e-5, 1e-3, 1.0):
        v = rng.normal(size=3) * scale
        q = at.quat_from_rotvec(v)
        assert at.quat_to_dcm(q) == pytest.approx(Rotation.from_rotvec(v).as_matrix(), abs=4e-16 + 1e-15 * scale)
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    p, q = at.quat_from_rotvec(rng.normal(size=3)), at.quat_from_rotvec(rng.normal(size=3))
    assert at.quat_to_dcm(at.quat_mul(p, q)) == pytest.approx(at.quat_to_dcm(p) @ at.quat_to_dcm(q), abs=1e-14)
    C = at.quat_to_dcm(p)
    assert at.dcm_from_quat(at.quat_from_dcm(C)) == pytest.approx(C, abs=1e-15)


def test_skew_and_small_angle_error():
    v, w = np.array([1.0, -2.0, 3.0]), np.array([0.5, 0.25, -1.0])
    assert at.skew(v) @ w == pytest.approx(np.cross(v, w), abs=1e-15)
    C = at.dcm_from_euler([0.1, 0.2, 0.3])
    phi = np.array([1e-5, -2e-5, 3e-5])
    Ce = Rotation.from_rotvec(phi).as_matrix() @ C
    assert at.small_angle_error(Ce, C) == pytest.approx(phi, abs=1e-16)


def test_numpy_and_scalar_faces_agree_with_the_array_kernels_and_scipy():
    rng = np.random.default_rng(11)
    # angles from the Earth rate per sample to a half turn: every branch of the series
    scale = np.repeat([1e-7, 1e-3, 0.05, 1.0, 3.0], 8)[:, None]
    v = rng.normal(size=(40, 3)) * scale
    w = rng.normal(size=(40, 3))
    qa = at.quat_from_rotvec_array(v)
    qs = np.roll(Rotation.from_rotvec(v).as_quat(), 1, axis=-1)  # independent: SciPy, scalar last
    assert qa == pytest.approx(qs, rel=1e-14, abs=1e-16)
    qb = at.quat_from_rotvec_array(w)
    prod = at.quat_mul_array(qa, qb)
    for k in range(40):
        assert np.array_equal(prod[k], at.quat_mul(qa[k], qb[k]))  # the same products in the same order
        assert np.array_equal(at.quat_mul_xyz(*qa[k], *qb[k]), prod[k])
        assert at.quat_from_rotvec(v[k]) == pytest.approx(qa[k], rel=1e-14, abs=1e-16)
        assert at.quat_from_rotvec_poly_xyz(*v[k]) == pytest.approx(qa[k], rel=2e-16 * 8, abs=1e-17)
        x = np.array(at.quat_rotate_xyz(*qa[k], *w[k]))
        assert x == pytest.approx(at.quat_to_dcm(qa[k]) @ w[k], rel=1e-13, abs=1e-15)
        assert at.quat_rotate_inv(qa[k], x) == pytest.approx(w[k], rel=1e-13, abs=1e-15)
    # composition as SciPy's (R(p) R(q) = R(p q)); angle and conjugate
    ref = np.roll((Rotation.from_rotvec(v) * Rotation.from_rotvec(w)).as_quat(), 1, axis=-1)
    assert prod == pytest.approx(ref * np.sign(np.sum(prod * ref, axis=-1))[:, None], abs=1e-14)  # q and -q alike
    ang = np.linalg.norm(v, axis=-1)
    assert at.quat_angle(qa)[ang < math.pi] == pytest.approx(ang[ang < math.pi], rel=1e-12, abs=1e-18)
    assert at.quat_mul_array(qa, at.quat_conj(qa)) == pytest.approx(np.tile([1.0, 0, 0, 0], (40, 1)), abs=1e-15)


def test_rodrigues_faces_agree_with_scipy():
    """The array face (one axis, many angles), the rotation-vector matrix and the scalar 9-tuple against SciPy's
    rotation vectors."""
    rng = np.random.default_rng(5)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    ang = rng.uniform(-7, 7, 12)
    ref = Rotation.from_rotvec(ang[:, None] * axis).as_matrix()
    assert at.axis_angle_dcm_array(axis, ang) == pytest.approx(ref, abs=1e-14)
    for k in range(12):
        v = ang[k] * axis
        assert at.dcm_from_rotvec(v) == pytest.approx(ref[k], abs=1e-14)
        r = at.axis_angle_xyz(math.cos(ang[k]), math.sin(ang[k]), *axis)
        assert np.reshape(r, (3, 3)) == pytest.approx(ref[k], abs=1e-14)
        q = np.roll(Rotation.from_rotvec(v).as_quat(), 1) * 3.0  # not unit: normalised first
        assert np.reshape(at.quat_to_dcm_xyz(*q), (3, 3)) == pytest.approx(ref[k], abs=1e-14)
    assert np.array_equal(at.dcm_from_rotvec(np.zeros(3)), np.eye(3))
