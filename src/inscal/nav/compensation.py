"""On-the-fly compensation of the navigator's increments (S16 eq. 3, 6-12): the parameter block of
the kernel and the compensation of one sample, the model of
:meth:`inscal.core.error_model.ImuErrors.compensate` (rates = increments / dt; the fixed point of
S16 eq. 8 iterated three times, converged to ~1e-12 of the nonlinear correction)."""

from __future__ import annotations

import numpy as np
from numba import njit

from inscal.core.error_model import ImuErrors

# rows of the compensation parameter block ``cp`` (float64, (N_CP, 3))
P_MGI = 0  # rows 0..2: M_g^-1
P_MAI = 3  # rows 3..5: M_a^-1
P_G = 6  # rows 6..8: G
P_LEV = 9  # rows 9..11: lever arms p_i (row i)
P_EPS = 12  # gyro bias eps (measurement form) [rad/s]
P_NAB = 13  # accel bias nabla [m/s^2]
P_K2 = 14  # K2 diagonal [1/(m/s^2)]
P_KX1 = 15  # Kx rows 15..17
P_XEPS = 18  # extra gyro bias subtracted after compensation (alignment estimates) [rad/s]
P_XNAB = 19  # extra accel bias subtracted after compensation [m/s^2]
N_CP = 20


def compensation_block(params: ImuErrors | None) -> tuple[np.ndarray, int]:
    """Kernel parameter block and compensation level (0 none, 1 linear, 2 full) for ``params``."""
    cp = np.zeros((N_CP, 3))
    cp[P_MGI:P_MGI + 3] = np.eye(3)
    cp[P_MAI:P_MAI + 3] = np.eye(3)
    if params is None:
        return cp, 0
    cp[P_MGI:P_MGI + 3] = np.linalg.inv(params.M_g)
    cp[P_MAI:P_MAI + 3] = np.linalg.inv(params.M_a)
    cp[P_G:P_G + 3] = params.gyro_g_sensitivity
    cp[P_LEV:P_LEV + 3] = params.accel_lever_arm
    cp[P_EPS] = params.gyro_bias
    cp[P_NAB] = params.accel_bias
    cp[P_K2] = params.accel_nonlinearity
    cp[P_KX1:P_KX1 + 3] = params.K_cross
    level = 2 if params.has_nonlinear else 1
    return cp, level


@njit(cache=True, inline="always")
def compensate_sample(d0, d1, d2, e0, e1, e2, dt, cp, level, pw0, pw1, pw2, have_prev):
    """S16 compensation of one sample's increments ``dtheta = (d0, d1, d2)``, ``dv = (e0, e1, e2)``
    (the model of :meth:`inscal.core.error_model.ImuErrors.compensate`); returns the compensated
    ``dtheta`` and ``dv``.  ``pw``: the previous compensated rate (for the size effect's w-dot)."""
    a0 = d0 - cp[P_EPS, 0] * dt
    a1 = d1 - cp[P_EPS, 1] * dt
    a2 = d2 - cp[P_EPS, 2] * dt
    t0 = cp[P_MGI, 0] * a0 + cp[P_MGI, 1] * a1 + cp[P_MGI, 2] * a2  # S16 eq. 3 (linear part)
    t1 = cp[P_MGI + 1, 0] * a0 + cp[P_MGI + 1, 1] * a1 + cp[P_MGI + 1, 2] * a2
    t2 = cp[P_MGI + 2, 0] * a0 + cp[P_MGI + 2, 1] * a1 + cp[P_MGI + 2, 2] * a2
    b0 = e0 - cp[P_NAB, 0] * dt
    b1 = e1 - cp[P_NAB, 1] * dt
    b2 = e2 - cp[P_NAB, 2] * dt
    f0 = cp[P_MAI, 0] * b0 + cp[P_MAI, 1] * b1 + cp[P_MAI, 2] * b2  # S16 eq. 6 / 7 (f_0)
    f1 = cp[P_MAI + 1, 0] * b0 + cp[P_MAI + 1, 1] * b1 + cp[P_MAI + 1, 2] * b2
    f2 = cp[P_MAI + 2, 0] * b0 + cp[P_MAI + 2, 1] * b1 + cp[P_MAI + 2, 2] * b2
    g0, g1, g2 = f0, f1, f2
    w0 = t0 - (cp[P_G, 0] * g0 + cp[P_G, 1] * g1 + cp[P_G, 2] * g2)
    w1 = t1 - (cp[P_G + 1, 0] * g0 + cp[P_G + 1, 1] * g1 + cp[P_G + 1, 2] * g2)
    w2 = t2 - (cp[P_G + 2, 0] * g0 + cp[P_G + 2, 1] * g1 + cp[P_G + 2, 2] * g2)
    if level >= 2:
        idt = 1.0 / dt
        for _ in range(3):  # S16 eq. 8 as a fixed point (see core.error_model)
            # rates
            x0, x1, x2 = g0 * idt, g1 * idt, g2 * idt
            r0, r1, r2 = w0 * idt, w1 * idt, w2 * idt
            # K2 f^(2) + Kx f^(x) (S16 eq. 12)
            s0 = x0 * x0
            s1 = x1 * x1
            s2 = x2 * x2
            c0 = x0 * x1
            c1 = x0 * x2
            c2 = x1 * x2
            n0 = cp[P_K2, 0] * s0 + cp[P_KX1, 0] * c0 + cp[P_KX1, 1] * c1 + cp[P_KX1, 2] * c2
            n1 = cp[P_K2, 1] * s1 + cp[P_KX1 + 1, 0] * c0 + cp[P_KX1 + 1, 1] * c1 + cp[P_KX1 + 1, 2] * c2
            n2 = cp[P_K2, 2] * s2 + cp[P_KX1 + 2, 0] * c0 + cp[P_KX1 + 2, 1] * c1 + cp[P_KX1 + 2, 2] * c2
            # size effect a_i = e_i.(w x (w x p_i) + wdot x p_i) (S16 eq. 9-11)
            wp0 = r0 * cp[P_LEV, 0] + r1 * cp[P_LEV, 1] + r2 * cp[P_LEV, 2]
            wp1 = r0 * cp[P_LEV + 1, 0] + r1 * cp[P_LEV + 1, 1] + r2 * cp[P_LEV + 1, 2]
            wp2 = r0 * cp[P_LEV + 2, 0] + r1 * cp[P_LEV + 2, 1] + r2 * cp[P_LEV + 2, 2]
            ww = r0 * r0 + r1 * r1 + r2 * r2
            z0 = r0 * wp0 - cp[P_LEV, 0] * ww
            z1 = r1 * wp1 - cp[P_LEV + 1, 1] * ww
            z2 = r2 * wp2 - cp[P_LEV + 2, 2] * ww
            if have_prev:
                # w-dot integrated over the interval ~ difference of consecutive mean rates
                d0, d1, d2 = r0 - pw0, r1 - pw1, r2 - pw2
                z0 += (d1 * cp[P_LEV, 2] - d2 * cp[P_LEV, 1]) * idt
                z1 += (d2 * cp[P_LEV + 1, 0] - d0 * cp[P_LEV + 1, 2]) * idt
                z2 += (d0 * cp[P_LEV + 2, 1] - d1 * cp[P_LEV + 2, 0]) * idt
            g0 = f0 - (n0 + z0) * dt
            g1 = f1 - (n1 + z1) * dt
            g2 = f2 - (n2 + z2) * dt
            w0 = t0 - (cp[P_G, 0] * g0 + cp[P_G, 1] * g1 + cp[P_G, 2] * g2)
            w1 = t1 - (cp[P_G + 1, 0] * g0 + cp[P_G + 1, 1] * g1 + cp[P_G + 1, 2] * g2)
            w2 = t2 - (cp[P_G + 2, 0] * g0 + cp[P_G + 2, 1] * g1 + cp[P_G + 2, 2] * g2)
    return (w0 - cp[P_XEPS, 0] * dt, w1 - cp[P_XEPS, 1] * dt, w2 - cp[P_XEPS, 2] * dt,
            g0 - cp[P_XNAB, 0] * dt, g1 - cp[P_XNAB, 1] * dt, g2 - cp[P_XNAB, 2] * dt)
