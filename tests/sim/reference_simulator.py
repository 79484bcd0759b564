"""The simulator as it was before the compiled single pass (inscal 61c15d3: ``sim/simulate.py``,
``core/kinematics.py`` and ``ImuErrors.measure_increments``), copied here unchanged as the reference
of tests/sim/test_simulate_speed_equivalence.py: the gimbal kinematics and the integrals in numba, the
gimbal angles, the error model (NumPy, BLAS matrix products) and the noise (NumPy/SciPy) after it.

Only the plumbing is adapted: ``measure_increments`` is a function of the ``ImuErrors`` (its matrices
rebuilt here from the fields, N25 eq. 1-4, S16 eq. 12) and ``simulate_chunks`` yields tuples
``(time, dtheta, dvel, gimbal, true_dtheta, true_dvel)``.  It must not import the simulator it checks.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.signal import lfilter

from inscal.core.attitude import dcm_from_euler

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


def outer_axis(dtheta):
    return np.array([math.cos(dtheta), 0.0, math.sin(dtheta)])


def off_diagonal(angles):
    e = np.zeros((3, 3))
    for k, (i, j) in enumerate(((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))):
        e[i, j] = angles[k]
    return e


def m_g(imu):
    return (np.eye(3) + np.diag(imu.gyro_scale_factor)) @ (np.eye(3) + off_diagonal(imu.gyro_misalignment))


def m_a(imu):
    return (np.eye(3) + np.diag(imu.accel_scale_factor)) @ (np.eye(3) + off_diagonal(imu.accel_misalignment))


def k_cross(imu):
    kx = imu.accel_cross_coupling
    return np.array([[kx[0], kx[1], 0.0], [kx[2], 0.0, kx[3]], [0.0, kx[4], kx[5]]])


def has_nonlinear(imu):
    return bool(np.any(imu.accel_nonlinearity) or np.any(imu.accel_cross_coupling) or np.any(imu.accel_lever_arm))


@njit(cache=True)
def _gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc):
    """Gimbal angles and rates ``(theta_x, theta_z, w_x, w_z)`` at time t on segment s (angles
    quadratic in time within a segment)."""
    tau = t - seg_t0[s]
    thx = seg_th0[s, 0] + seg_w0[s, 0] * tau + 0.5 * seg_acc[s, 0] * tau * tau
    thz = seg_th0[s, 1] + seg_w0[s, 1] * tau + 0.5 * seg_acc[s, 1] * tau * tau
    return thx, thz, seg_w0[s, 0] + seg_acc[s, 0] * tau, seg_w0[s, 1] + seg_acc[s, 1] * tau


@njit(cache=True)
def _rates_at(t, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_out, f_out):
    """Evaluate w_is^s and f^s at time t on segment s (writes into w_out, f_out; no allocation).

    ``C_s^n = C_b^n Rot(u, theta_x) R_z(theta_z)`` (N25 eq. 7-8); ``w_is^s`` per N25 eq. 9 with the
    outer rate about the tilted axis u, ``f^s = C_n^s [0, 0, g]`` (eq. 10, static base).
    """
    thx, thz, wx, wz = _gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc)
    # Rodrigues rotation about the unit outer axis u (exact N25 eq. 5)
    c, sn = math.cos(thx), math.sin(thx)
    t1 = 1.0 - c
    ux, uy, uz = u[0], u[1], u[2]
    x00 = c + ux * ux * t1
    x01 = ux * uy * t1 - uz * sn
    x10 = uy * ux * t1 + uz * sn
    x11 = c + uy * uy * t1
    x20 = uz * ux * t1 - uy * sn
    x21 = uz * uy * t1 + ux * sn
    x02 = ux * uz * t1 + uy * sn
    x12 = uy * uz * t1 - ux * sn
    x22 = c + uz * uz * t1
    cz, sz = math.cos(thz), math.sin(thz)
    # columns of C_s^n = Cbn Cx Rz : x_s = Cbn (cz Cx[:,0] + sz Cx[:,1]), y_s = Cbn (-sz Cx[:,0] + cz Cx[:,1]), z_s = Cbn Cx[:,2]
    ax0 = cz * x00 + sz * x01
    ax1 = cz * x10 + sz * x11
    ax2 = cz * x20 + sz * x21
    ay0 = -sz * x00 + cz * x01
    ay1 = -sz * x10 + cz * x11
    ay2 = -sz * x20 + cz * x21
    w0_ = 0.0
    w1_ = 0.0
    w2_ = 0.0
    f0_ = 0.0
    f1_ = 0.0
    f2_ = 0.0
    for k in range(3):
        xs = Cbn[k, 0] * ax0 + Cbn[k, 1] * ax1 + Cbn[k, 2] * ax2
        ys = Cbn[k, 0] * ay0 + Cbn[k, 1] * ay1 + Cbn[k, 2] * ay2
        zs = Cbn[k, 0] * x02 + Cbn[k, 1] * x12 + Cbn[k, 2] * x22
        w0_ += xs * wie_n[k]
        w1_ += ys * wie_n[k]
        w2_ += zs * wie_n[k]
        if k == 2:
            f0_ = xs * g
            f1_ = ys * g
            f2_ = zs * g
    # outer rate about u, expressed in s: Rz^T u wx (u is fixed in the inner-gimbal frame); inner rate wz e_z
    w_out[0] = w0_ + (cz * ux + sz * uy) * wx
    w_out[1] = w1_ + (-sz * ux + cz * uy) * wx
    w_out[2] = w2_ + uz * wx + wz
    f_out[0] = f0_
    f_out[1] = f1_
    f_out[2] = f2_


@njit(cache=True)
def _segment_at(t, seg_t1):
    """Smallest s with ``seg_t1[s] > t`` (clamped to the last segment)."""
    lo = 0
    hi = seg_t1.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if seg_t1[mid] > t:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True)
def _simulate_kernel(k0, n, dt, seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, glx, glw,
                     want_nl, dth, dv, f2, fx, ww, dw):
    S = seg_t0.shape[0]
    w = np.empty(3)
    f = np.empty(3)
    w_prev = np.empty(3)
    w_end = np.empty(3)
    a0 = k0 * dt
    s = 0
    while s < S - 1 and seg_t1[s] <= a0:
        s += 1
    static_seg = -1
    ws = np.zeros(3)
    fs = np.zeros(3)
    if want_nl:
        _rates_at(a0, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_prev, f)
    for j in range(n):
        a = (k0 + j) * dt
        b = (k0 + j + 1) * dt
        for c in range(3):
            dth[j, c] = 0.0
            dv[j, c] = 0.0
            if want_nl:
                f2[j, c] = 0.0
                fx[j, c] = 0.0
                ww[j, c] = 0.0
                ww[j, c + 3] = 0.0
        sa = a
        end_static = False
        while True:
            sb = seg_t1[s] if (seg_t1[s] < b and s < S - 1) else b
            h = sb - sa
            is_static = seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0
            if h > 0.0:
                if is_static:
                    if static_seg != s:
                        _rates_at(seg_t0[s], s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, ws, fs)
                        static_seg = s
                    nq = 1
                else:
                    nq = glx.shape[0]
                for q in range(nq):
                    if is_static:
                        wq = h
                        for c in range(3):
                            w[c] = ws[c]
                            f[c] = fs[c]
                    else:
                        tq = 0.5 * (sa + sb) + 0.5 * h * glx[q]
                        wq = 0.5 * h * glw[q]
                        _rates_at(tq, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                    for c in range(3):
                        dth[j, c] += wq * w[c]
                        dv[j, c] += wq * f[c]
                    if want_nl:
                        f2[j, 0] += wq * f[0] * f[0]
                        f2[j, 1] += wq * f[1] * f[1]
                        f2[j, 2] += wq * f[2] * f[2]
                        fx[j, 0] += wq * f[0] * f[1]
                        fx[j, 1] += wq * f[0] * f[2]
                        fx[j, 2] += wq * f[1] * f[2]
                        ww[j, 0] += wq * w[0] * w[0]
                        ww[j, 1] += wq * w[1] * w[1]
                        ww[j, 2] += wq * w[2] * w[2]
                        ww[j, 3] += wq * w[0] * w[1]
                        ww[j, 4] += wq * w[0] * w[2]
                        ww[j, 5] += wq * w[1] * w[2]
            if sb >= b:
                end_static = is_static and static_seg == s
                break
            s += 1
            sa = sb
        if want_nl:
            # delta w = w(b) - w(a) (the integral of w-dot); w is continuous across segments
            if end_static:
                for c in range(3):
                    w_end[c] = ws[c]
            else:
                _rates_at(b, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_end, f)
            for c in range(3):
                dw[j, c] = w_end[c] - w_prev[c]
                w_prev[c] = w_end[c]
        # the next sample starts in segment s (or the one after, if s ends exactly at b)
        if s < S - 1 and seg_t1[s] <= b:
            s += 1


@njit(cache=True)
def _accumulate(wq, w, f, want_nl, j, sgn, iv, if2, ifx, iww):
    c = sgn * wq
    for i in range(3):
        iv[j, i] += c * f[i]
    if want_nl:
        if2[j, 0] += c * f[0] * f[0]
        if2[j, 1] += c * f[1] * f[1]
        if2[j, 2] += c * f[2] * f[2]
        ifx[j, 0] += c * f[0] * f[1]
        ifx[j, 1] += c * f[0] * f[2]
        ifx[j, 2] += c * f[1] * f[2]
        iww[j, 0] += c * w[0] * w[0]
        iww[j, 1] += c * w[1] * w[1]
        iww[j, 2] += c * w[2] * w[2]
        iww[j, 3] += c * w[0] * w[1]
        iww[j, 4] += c * w[0] * w[2]
        iww[j, 5] += c * w[1] * w[2]


@njit(cache=True)
def _asynchrony_kernel(k0, n1, dt, tau, seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, glx, glw,
                       want_nl, iv, if2, ifx, iww, wdel):
    """Boundary integrals for a time asynchrony ``tau``: for the sample boundaries
    ``t_j = (k0 + j) dt``, j = 0 .. n1-1, ``I_j = int_{t_j - tau}^{t_j} (f, f^(2), f^(x), w w^T)``
    (signed: negative for ``tau < 0``) and ``wdel_j = w(t_j - tau)``.  Before t = 0 and after
    the end of the path the base is static at the first / last gimbal angles.  Each piece
    between segment breakpoints is integrated with Gauss-Legendre (pieces longer than dt
    are split into <= dt parts), static segments exactly."""
    S = seg_t0.shape[0]
    T = seg_t1[S - 1]
    w = np.empty(3)
    f = np.empty(3)
    w_beg = np.empty(3)
    f_beg = np.empty(3)
    w_fin = np.empty(3)
    f_fin = np.empty(3)
    _rates_at(0.0, 0, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_beg, f_beg)
    _rates_at(T, S - 1, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w_fin, f_fin)
    nq = glx.shape[0]
    for j in range(n1):
        tb = (k0 + j) * dt
        ta = tb - tau
        for c in range(3):
            iv[j, c] = 0.0
            if want_nl:
                if2[j, c] = 0.0
                ifx[j, c] = 0.0
                iww[j, c] = 0.0
                iww[j, c + 3] = 0.0
        if tau > 0.0:
            lo, hi, sgn = ta, tb, 1.0
        else:
            lo, hi, sgn = tb, ta, -1.0
        x = lo
        if x < 0.0:  # static base before the path starts
            xe = hi if hi < 0.0 else 0.0
            _accumulate(xe - x, w_beg, f_beg, want_nl, j, sgn, iv, if2, ifx, iww)
            x = xe
        if x < hi and x < T:
            s = _segment_at(x, seg_t1)
            while x < hi and s < S:
                xe = seg_t1[s] if seg_t1[s] < hi else hi
                h = xe - x
                if h > 0.0:
                    if seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0:
                        _rates_at(seg_t0[s], s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                        _accumulate(h, w, f, want_nl, j, sgn, iv, if2, ifx, iww)
                    else:
                        m = int(math.ceil(h / dt)) if h > dt else 1
                        hp = h / m
                        for p in range(m):
                            pa = x + p * hp
                            pb = xe if p == m - 1 else pa + hp
                            hh = pb - pa
                            for q in range(nq):
                                tq = 0.5 * (pa + pb) + 0.5 * hh * glx[q]
                                _rates_at(tq, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                                _accumulate(0.5 * hh * glw[q], w, f, want_nl, j, sgn, iv, if2, ifx, iww)
                x = xe
                s += 1
        if x < hi:  # static base after the path ends
            _accumulate(hi - x, w_fin, f_fin, want_nl, j, sgn, iv, if2, ifx, iww)
        if want_nl:
            if ta <= 0.0:
                for c in range(3):
                    wdel[j, c] = w_beg[c]
            elif ta >= T:
                for c in range(3):
                    wdel[j, c] = w_fin[c]
            else:
                s = _segment_at(ta, seg_t1)
                _rates_at(ta, s, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g, w, f)
                for c in range(3):
                    wdel[j, c] = w[c]


def size_effect(lever_arm, w, wdot=None):
    """Size-effect specific force a_size (..., 3) for rates ``w`` (..., 3) (S16 eq. 9-11).

    ``a_size_i = e_i . (w x (w x p_i) + wdot x p_i)``, ``p_i = lever_arm[i]``.
    """
    w = np.asarray(w, dtype=float)
    p = np.asarray(lever_arm, dtype=float)
    w2 = np.sum(w * w, axis=-1, keepdims=True)
    # (w x (w x p_i))_i = w_i (w . p_i) - p_ii |w|^2
    wp = w @ p.T  # (..., i) = w . p_i
    out = w * wp - np.diag(p) * w2
    if wdot is not None:
        wd = np.asarray(wdot, dtype=float)
        # (wdot x p_i)_i = wdot_j p_ik - wdot_k p_ij for (i, j, k) cyclic
        out = out + np.stack(
            [
                wd[..., 1] * p[0, 2] - wd[..., 2] * p[0, 1],
                wd[..., 2] * p[1, 0] - wd[..., 0] * p[1, 2],
                wd[..., 0] * p[2, 1] - wd[..., 1] * p[2, 0],
            ],
            axis=-1,
        )
    return out


class ReferenceNoise:
    """Stateful, chunk-size-independent noise generator."""

    def __init__(self, noise, rng, dt):
        self.noise = noise
        self.dt = dt
        self.g_arw, self.g_vrw, self.g_gbi, self.g_abi, self.g_enc = rng.spawn(5)
        self.zi_g = None
        self.zi_a = None
        self.q_g = (np.zeros(3), np.zeros(3))
        self.q_a = (np.zeros(3), np.zeros(3))

    def _gm(self, gen, sigma, tau, n, zi_name):
        if not np.any(sigma):
            return 0.0
        phi = math.exp(-self.dt / tau)
        zi = getattr(self, zi_name)
        if zi is None:  # stationary start (drawn first, so results do not depend on chunking)
            zi = (gen.standard_normal(3) * sigma * phi)[None, :]
        drive = gen.standard_normal((n, 3)) * sigma * math.sqrt(1 - phi * phi)
        out, zf = lfilter([1.0], [1.0, -phi], drive, axis=0, zi=zi)
        setattr(self, zi_name, zf)
        return out

    @staticmethod
    def _quantize(x, q, state):
        """Quantize increments of an accumulating output: emit whole quanta of the running
        total, the remainder carries to the next sample.  ``state = (total, emitted_counts)``;
        the running total is summed in the same order whatever the chunking."""
        if q <= 0:
            return x, state
        total, emitted = state
        acc = np.cumsum(np.vstack([total[None, :], x]), axis=0)[1:]
        counts = np.floor(acc / q)
        out = np.diff(np.vstack([emitted[None, :], counts]), axis=0) * q
        return out, (acc[-1], counts[-1])

    def apply(self, dth, dv, gimbal):
        n, nz, dt = dth.shape[0], self.noise, self.dt
        if np.any(nz.arw):
            dth = dth + self.g_arw.standard_normal((n, 3)) * nz.arw * math.sqrt(dt)
        if np.any(nz.vrw):
            dv = dv + self.g_vrw.standard_normal((n, 3)) * nz.vrw * math.sqrt(dt)
        dth = dth + self._gm(self.g_gbi, nz.gyro_bias_instability, nz.gyro_bias_tau, n, "zi_g") * dt
        dv = dv + self._gm(self.g_abi, nz.accel_bias_instability, nz.accel_bias_tau, n, "zi_a") * dt
        dth, self.q_g = self._quantize(dth, nz.gyro_quantization, self.q_g)
        dv, self.q_a = self._quantize(dv, nz.accel_quantization, self.q_a)
        if nz.encoder_noise > 0:
            gimbal = gimbal + self.g_enc.standard_normal(gimbal.shape) * nz.encoder_noise
        return dth, dv, gimbal


def measure_increments(imu, dt, dth, dv, f2=None, fx=None, wwT=None, dw=None, dv_gyro=None):
    """Measured increments from the exact integrals of one sample interval each.

    ``dth = int w``, ``dv = int f``; for the nonlinear terms ``f2 = int f^(2)``,
    ``fx = int f^(x)``, ``wwT = int [wx^2, wy^2, wz^2, wx wy, wx wz, wy wz]``,
    ``dw = w(t_k) - w(t_{k-1})`` (the integral of w-dot).  Everything is linear in
    these integrals, so the result is exact whatever the motion inside the interval.

    With a time asynchrony ``tau``, ``dv, f2, fx, wwT, dw`` are the integrals over the
    accelerometer window ``[t_{k-1} - tau, t_k - tau]`` and ``dv_gyro`` is ``int f``
    over the gyro window ``[t_{k-1}, t_k]`` (for the g-sensitivity; default ``dv``).
    """
    dth = np.asarray(dth, dtype=float)
    dv = np.asarray(dv, dtype=float)
    dvg = dv if dv_gyro is None else np.asarray(dv_gyro, dtype=float)
    dt = np.asarray(dt, dtype=float)[..., None] if np.ndim(dt) else dt
    ng = (dth + dvg @ imu.gyro_g_sensitivity.T) @ m_g(imu).T + imu.gyro_bias * dt
    fa = dv
    if has_nonlinear(imu):
        fa = fa + f2 * imu.accel_nonlinearity + fx @ k_cross(imu).T
        if np.any(imu.accel_lever_arm):
            p = imu.accel_lever_arm
            # int (w_i (w . p_i) - p_ii |w|^2) dt expressed with the integrated products
            wx2, wy2, wz2, wxy, wxz, wyz = (wwT[..., k] for k in range(6))
            cen = np.stack(
                [
                    wx2 * p[0, 0] + wxy * p[0, 1] + wxz * p[0, 2] - p[0, 0] * (wx2 + wy2 + wz2),
                    wxy * p[1, 0] + wy2 * p[1, 1] + wyz * p[1, 2] - p[1, 1] * (wx2 + wy2 + wz2),
                    wxz * p[2, 0] + wyz * p[2, 1] + wz2 * p[2, 2] - p[2, 2] * (wx2 + wy2 + wz2),
                ],
                axis=-1,
            )
            fa = fa + cen + size_effect(p, np.zeros(3), dw)
    na = fa @ m_a(imu).T + imu.accel_bias * dt
    return ng, na


def _angles(seg, t):
    """``Segments.angles(t)[0]`` as it was (searchsorted on the segment ends, quadratic in time)."""
    k = np.clip(np.searchsorted(seg.t1, t, side="left"), 0, len(seg.t0) - 1)
    tau = (t - seg.t0[k])[:, None]
    return seg.th0[k] + seg.w0[k] * tau + 0.5 * seg.acc[k] * tau**2


def simulate_chunks(scenario, rng, chunk_size=1 << 19, keep_truth=False):
    """Yield the simulation in chunks.  ``rng`` may be None only when the noise is zero."""
    seg = scenario.path.segments()
    dt = 1.0 / scenario.rate_hz
    N = scenario.n_samples
    u = outer_axis(scenario.gimbal.nonorthogonality)
    Cbn = np.ascontiguousarray(dcm_from_euler(scenario.gimbal.mount_attitude))
    wie_n = scenario.site.earth_rate_n
    g = scenario.site.gravity
    imu = scenario.imu
    want_nl = has_nonlinear(imu)
    noise = None if scenario.noise.is_zero else ReferenceNoise(scenario.noise, rng, dt)
    for k0 in range(0, N, chunk_size):
        n = min(chunk_size, N - k0)
        dth = np.empty((n, 3))
        dv = np.empty((n, 3))
        m = n if want_nl else 1
        f2, fx, dw = np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        ww = np.empty((m, 6))
        _simulate_kernel(k0, n, dt, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie_n, g, _GL_X, _GL_W,
                         want_nl, dth, dv, f2, fx, ww, dw)
        t = (k0 + 1 + np.arange(n)) * dt
        th = _angles(seg, t)
        if imu.has_asynchrony:
            # accelerometer window [t_{k-1} - tau, t_k - tau] = gyro window - I_k + I_{k-1}
            iv, if2, ifx, wdel = np.empty((n + 1, 3)), np.empty((m + 1, 3)), np.empty((m + 1, 3)), np.empty((m + 1, 3))
            iww = np.empty((m + 1, 6))
            _asynchrony_kernel(k0, n + 1, dt, imu.time_asynchrony, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn,
                               wie_n, g, _GL_X, _GL_W, want_nl, iv, if2, ifx, iww, wdel)
            dva = dv - iv[1:] + iv[:-1]
            if want_nl:
                f2, fx, ww = f2 - if2[1:] + if2[:-1], fx - ifx[1:] + ifx[:-1], ww - iww[1:] + iww[:-1]
                dw = wdel[1:] - wdel[:-1]
            mdth, mdv = measure_increments(imu, dt, dth, dva, f2, fx, ww, dw, dv_gyro=dv)
        else:
            mdth, mdv = measure_increments(imu, dt, dth, dv, f2, fx, ww, dw)
        gimbal = th
        if noise is not None:
            mdth, mdv, gimbal = noise.apply(mdth, mdv, gimbal)
        yield t, mdth, mdv, gimbal, (dth if keep_truth else None), (dv if keep_truth else None)


def simulate(scenario, rng=None, keep_truth=False, chunk_size=1 << 19):
    """The whole simulation: ``(time, dtheta, dvel, gimbal, true_dtheta, true_dvel)``, concatenated."""
    parts = list(simulate_chunks(scenario, rng, chunk_size, keep_truth))
    return tuple(None if parts[0][i] is None else np.concatenate([q[i] for q in parts]) for i in range(6))
