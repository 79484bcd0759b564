"""Attitude conventions and helpers.

Conventions (used throughout inscal):

* A direction cosine matrix ``C_a^b`` maps vectors from frame a to frame b:
  ``v^b = C_a^b v^a``.  Its columns are the axes of frame a expressed in b.
* Elementary rotations are *active*: ``rot_x(t) = exp(t [e_x x])`` is the DCM
  ``C_a^b`` of a frame a obtained by a right-handed rotation ``t`` of b about x.
  (S16 Table 1 checks this: +90 deg about East takes the IMU y-axis from North to Up.)
* Euler angles follow N25 eq. 8: ``C_b^n = R_z(yaw) R_y(pitch) R_x(roll)`` (z-y-x
  order), returned/accepted as ``[roll, pitch, yaw]`` = ``[alpha, beta, gamma]``.
* Quaternions are scalar-first ``[w, x, y, z]`` in the numba kernels (scipy uses
  scalar-last; conversion helpers below).

The vectorised helpers sit on ``scipy.spatial.transform.Rotation``; the small
``@njit`` kernels are for the hot loops (simulation, strapdown).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation


@njit(cache=True)
def skew(v):
    """Cross-product matrix [v x]."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@njit(cache=True, inline="always")
def skew_entry(v, i, j):
    """The entry (i, j) of [v x], ``(v x e_j)_i``, without building the matrix (for the kernels' loops)."""
    if j == 0:
        return 0.0 if i == 0 else (v[2] if i == 1 else -v[1])
    if j == 1:
        return -v[2] if i == 0 else (0.0 if i == 1 else v[0])
    return v[1] if i == 0 else (-v[0] if i == 1 else 0.0)


@njit(cache=True)
def axis_angle_dcm(axis, angle):
    """Exact DCM of a right-handed rotation ``angle`` about unit ``axis`` (Rodrigues).

    Used for the tilted outer gimbal axis (N25 eq. 5, exact instead of first order).
    """
    n = math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
    r = axis_angle_xyz(math.cos(angle), math.sin(angle), axis[0] / n, axis[1] / n, axis[2] / n)
    return np.array([[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]])


@njit(cache=True, inline="always")
def axis_angle_xyz(c, s, x, y, z):
    """The Rodrigues matrix (row-major 9-tuple) of the right-handed rotation about the unit axis (x, y, z) whose
    angle has cosine ``c`` and sine ``s``, on scalars: :func:`axis_angle_dcm` for the allocation-free kernels
    (which reuse the trigonometry of an axis at rest)."""
    t = 1.0 - c
    return (c + x * x * t, x * y * t - z * s, x * z * t + y * s,
            y * x * t + z * s, c + y * y * t, y * z * t - x * s,
            z * x * t - y * s, z * y * t + x * s, c + z * z * t)


@njit(cache=True)
def rot_x(t):
    """The elementary rotation matrix about x by ``t`` [rad], active and right-handed."""
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@njit(cache=True)
def rot_y(t):
    """The elementary rotation matrix about y by ``t`` [rad], active and right-handed."""
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@njit(cache=True)
def rot_z(t):
    """The elementary rotation matrix about z by ``t`` [rad], active and right-handed."""
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def dcm_from_euler(att) -> np.ndarray:
    """``C_b^n = R_z(yaw) R_y(pitch) R_x(roll)`` (N25 eq. 8) from ``[roll, pitch, yaw]`` [rad].

    Accepts shape (3,) or (N, 3); returns (3, 3) or (N, 3, 3).
    """
    att = np.asarray(att, dtype=float)
    # intrinsic Z-Y-X sequence == R_z R_y R_x (scipy: upper case = intrinsic)
    r = Rotation.from_euler("ZYX", att[..., ::-1])
    return r.as_matrix()


def euler_from_dcm(c) -> np.ndarray:
    """Inverse of :func:`dcm_from_euler` (N25 eq. 36): ``[roll, pitch, yaw]`` [rad]."""
    c = np.asarray(c, dtype=float)
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = -np.arcsin(np.clip(c[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def small_angle_error(c_est, c_true) -> np.ndarray:
    """Rotation vector phi of ``C_est C_true^T = exp([phi x])`` (error in the reference frame
    of the columns' target, e.g. the n-frame for ``C_b^n``).  Exact, not first order."""
    e = np.einsum("...ij,...kj->...ik", np.asarray(c_est), np.asarray(c_true))
    return Rotation.from_matrix(e).as_rotvec()


def quat_from_dcm(c) -> np.ndarray:
    """Scalar-first quaternion from DCM(s)."""
    q = Rotation.from_matrix(np.asarray(c, dtype=float)).as_quat()  # scalar-last
    return np.roll(q, 1, axis=-1)


def dcm_from_quat(q) -> np.ndarray:
    """The rotation matrix of the unit quaternion ``q = [w, x, y, z]`` (scalar first), shape (4,) or (N, 4)."""
    q = np.asarray(q, dtype=float)
    return Rotation.from_quat(np.roll(q, -1, axis=-1)).as_matrix()


def axis_angle_dcm_array(axis: np.ndarray, angle) -> np.ndarray:
    """Rodrigues rotations (n, 3, 3) about one unit ``axis`` through each of ``angle`` [rad] (n,):
    ``I + sin(a) K + (1 - cos(a)) K^2``, ``K = [axis x]``; the array face of :func:`axis_angle_dcm`."""
    K = skew(axis)
    a = np.asarray(angle, float)[:, None, None]
    return np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * (K @ K)


def dcm_from_rotvec(v: np.ndarray) -> np.ndarray:
    """The rotation matrix ``exp([v x])`` of one rotation vector ``v`` (3,) [rad] (Rodrigues; identity at 0)."""
    a = float(np.linalg.norm(v))
    if a == 0.0:
        return np.eye(3)
    K = skew(v / a)
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * (K @ K)


def quat_mul_array(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton products of quaternion arrays (..., 4), scalar first, broadcasting: the NumPy face of
    :func:`quat_mul` (the same products in the same order)."""
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3
    out[..., 1] = p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2
    out[..., 2] = p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1
    out[..., 3] = p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0
    return out


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugates (inverses of unit quaternions) of quaternions (..., 4), scalar first."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_from_rotvec_array(rotvec: np.ndarray) -> np.ndarray:
    """Exact quaternions (..., 4) of rotation vectors (..., 3): the NumPy face of :func:`quat_from_rotvec`,
    with ``sin(a/2)/a`` from ``np.sinc`` (1/2 at 0; equal to the kernels' series to round-off)."""
    a = np.linalg.norm(rotvec, axis=-1)
    s = 0.5 * np.sinc(a / (2.0 * math.pi))  # sin(a/2)/a, 1/2 at 0
    return np.concatenate([np.cos(0.5 * a)[..., None], s[..., None] * rotvec], axis=-1)


def quat_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle [rad] of quaternions (..., 4), in [0, pi]."""
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def quat_rotate_inv(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``C(q)^T v`` for quaternions (n, 4) and vectors (n, 3) or (3,): the inverse of :func:`quat_rotate_xyz`."""
    w, u = q[..., :1], -q[..., 1:]
    v = np.broadcast_to(v, u.shape)
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


# ---------------------------------------------------------------- numba kernels
@njit(cache=True)
def quat_mul(p, q):
    """Hamilton product p*q, scalar-first."""
    return np.array(
        [
            p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3],
            p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2],
            p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1],
            p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0],
        ]
    )


@njit(cache=True, inline="always")
def quat_from_rotvec_xyz(x, y, z):
    """Exact quaternion ``(w, x, y, z)`` of the rotation vector (x, y, z), as scalars (for the
    allocation-free kernels).  Series near zero: cos(a/2) and sin(a/2)/a to O(a^6), exact to
    round-off for a < 1e-4."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        a = math.sqrt(a2)
        c = math.cos(0.5 * a)
        s = math.sin(0.5 * a) / a
    return c, s * x, s * y, s * z


@njit(cache=True)
def quat_from_rotvec(v):
    """Exact quaternion of rotation vector ``v`` (series near zero)."""
    c, x, y, z = quat_from_rotvec_xyz(v[0], v[1], v[2])
    return np.array([c, x, y, z])


@njit(cache=True)
def quat_to_dcm(q):
    """The rotation matrix of the unit quaternion ``q = [w, x, y, z]`` (scalar first): the kernel form of
    :func:`dcm_from_quat` for one quaternion."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return np.array(
        [
            [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
        ]
    )


@njit(cache=True, inline="always")
def quat_to_dcm_xyz(q0, q1, q2, q3):
    """The rotation matrix (row-major 9-tuple) of the scalar-first quaternion, normalised first, on
    scalars: :func:`quat_to_dcm` for the allocation-free kernels (the matrix of :func:`dcm_from_quat`)."""
    n = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    w, x, y, z = q0 * n, q1 * n, q2 * n, q3 * n
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w),
            2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w),
            2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y))


@njit(cache=True, inline="always")
def quat_mul_xyz(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product, scalar-first, on scalars (no allocation): :func:`quat_mul` for the
    allocation-free kernels."""
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


@njit(cache=True, inline="always")
def quat_rotate_xyz(q0, q1, q2, q3, x, y, z):
    """Rotate (x, y, z) by the unit quaternion, on scalars: ``C(q) v``."""
    # t = 2 q_v x v ; v' = v + q0 t + q_v x t
    tx = 2.0 * (q2 * z - q3 * y)
    ty = 2.0 * (q3 * x - q1 * z)
    tz = 2.0 * (q1 * y - q2 * x)
    return (
        x + q0 * tx + (q2 * tz - q3 * ty),
        y + q0 * ty + (q3 * tx - q1 * tz),
        z + q0 * tz + (q1 * ty - q2 * tx),
    )


@njit(cache=True, inline="always")
def quat_from_rotvec_poly_xyz(x, y, z):
    """Exact quaternion ``(w, x, y, z)`` of the rotation vector (x, y, z) without trigonometry for
    the angles of a sample: with ``u = a^2 / 4``, ``cos(a/2) = sum (-u)^k / (2k)!`` and
    ``sin(a/2)/a = sum (-u)^k / (2 (2k+1)!)`` to ``u^4``; the first term left out,
    ``u^5 / 10! < 6.5e-18``, is below the round-off of 1 for ``a^2 < 0.03`` (a < 10 deg per sample).
    Larger angles take the trigonometric form (the value of :func:`quat_from_rotvec_xyz`).
    The strapdown kernel's form; the filters keep :func:`quat_from_rotvec_xyz` and its rounding."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:  # Earth and transport rotation per sample: the terms past u fall below 1e-19
        c = 1.0 - a2 * 0.125
        s = 0.5 - a2 * (1.0 / 48.0)
    elif a2 < 0.03:
        u = 0.25 * a2
        c = 1.0 + u * (-0.5 + u * (1.0 / 24.0 + u * (-1.0 / 720.0 + u * (1.0 / 40320.0))))
        s = 0.5 + u * (-1.0 / 12.0 + u * (1.0 / 240.0 + u * (-1.0 / 10080.0 + u * (1.0 / 725760.0))))
    else:
        a = math.sqrt(a2)
        c = math.cos(0.5 * a)
        s = math.sin(0.5 * a) / a
    return c, s * x, s * y, s * z
