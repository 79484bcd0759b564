"""Per-row attitude arithmetic of a navigation output, compiled, from the kernel's quaternions: the
Euler angles of the vehicle attitude ``C_b^n = C_s^n (C_s^b)^T`` (N25 eq. 34-36) and the rotation
vector of ``C_est C_true^T`` (the attitude error of :func:`inscal.core.attitude.small_angle_error`),
one pass over the rows each instead of SciPy's conversions and ``einsum``'s temporaries (the same
values to round-off)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.core.attitude import quat_to_dcm_xyz


@njit(cache=True)
def attitude_error(q, c_true):
    """Rotation vectors ``phi`` (N, 3) of ``C(q) C_true^T = exp([phi x])`` (exact, not first order): the
    quaternion of the product by the largest of its trace and diagonal (Shepperd), then
    ``phi = 2 atan2(|v|, w) v / |v|``, as SciPy's ``Rotation.from_matrix(...).as_rotvec()``."""
    n = q.shape[0]
    phi = np.empty((n, 3))
    e = np.empty((3, 3))
    for i in range(n):
        c = quat_to_dcm_xyz(q[i, 0], q[i, 1], q[i, 2], q[i, 3])
        for r in range(3):
            for k in range(3):
                e[r, k] = c[3 * r] * c_true[i, k, 0] + c[3 * r + 1] * c_true[i, k, 1] + c[3 * r + 2] * c_true[i, k, 2]
        tr = e[0, 0] + e[1, 1] + e[2, 2]
        m = 3
        big = tr
        for d in range(3):
            if e[d, d] > big:
                big = e[d, d]
                m = d
        if m == 3:
            w, x, y, z = 1.0 + tr, e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]
        elif m == 0:
            w, x, y, z = e[2, 1] - e[1, 2], 1.0 - tr + 2.0 * e[0, 0], e[1, 0] + e[0, 1], e[2, 0] + e[0, 2]
        elif m == 1:
            w, x, y, z = e[0, 2] - e[2, 0], e[0, 1] + e[1, 0], 1.0 - tr + 2.0 * e[1, 1], e[2, 1] + e[1, 2]
        else:
            w, x, y, z = e[1, 0] - e[0, 1], e[0, 2] + e[2, 0], e[1, 2] + e[2, 1], 1.0 - tr + 2.0 * e[2, 2]
        if w < 0.0:  # the rotation of angle <= pi
            w, x, y, z = -w, -x, -y, -z
        s = math.sqrt(x * x + y * y + z * z)
        f = 2.0 * math.atan2(s, w) / s if s > 0.0 else 0.0  # angle / |v| (the quaternion's scale cancels)
        phi[i, 0] = x * f
        phi[i, 1] = y * f
        phi[i, 2] = z * f
    return phi


@njit(cache=True)
def euler_of_products(q, b):
    """``[roll, pitch, yaw]`` (N, 3) of ``C(q[i]) b[i]^T`` (``b`` (N, 3, 3) or one (1, 3, 3) matrix for all
    rows): the vehicle attitude ``C_b^n = C_s^n (C_s^b)^T`` through the gimbal angles (N25 eq. 34-36),
    with the angles of :func:`inscal.core.attitude.euler_from_dcm` (``C_b^n = R_z(yaw) R_y(pitch) R_x(roll)``)."""
    n = q.shape[0]
    step = 0 if b.shape[0] == 1 else 1
    out = np.empty((n, 3))
    for i in range(n):
        c = quat_to_dcm_xyz(q[i, 0], q[i, 1], q[i, 2], q[i, 3])
        ib = i * step
        # rows 0 (column 0 only), 1 (column 0) and 2 of C b^T
        m00 = c[0] * b[ib, 0, 0] + c[1] * b[ib, 0, 1] + c[2] * b[ib, 0, 2]
        m10 = c[3] * b[ib, 0, 0] + c[4] * b[ib, 0, 1] + c[5] * b[ib, 0, 2]
        m20 = c[6] * b[ib, 0, 0] + c[7] * b[ib, 0, 1] + c[8] * b[ib, 0, 2]
        m21 = c[6] * b[ib, 1, 0] + c[7] * b[ib, 1, 1] + c[8] * b[ib, 1, 2]
        m22 = c[6] * b[ib, 2, 0] + c[7] * b[ib, 2, 1] + c[8] * b[ib, 2, 2]
        out[i, 0] = math.atan2(m21, m22)
        out[i, 1] = -math.asin(min(1.0, max(-1.0, m20)))
        out[i, 2] = math.atan2(m10, m00)
    return out
