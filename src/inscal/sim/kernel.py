"""The simulator's compiled pass: one loop over the samples of a chunk that does all the per-sample
arithmetic of :func:`inscal.sim.simulate.simulate_chunks`.

For each sample k (the gyro interval ``[t_{k-1}, t_k]``, ``t_k = (k + 1) dt``):

1. the exact integrals of the motion: each piece of the interval between segment breakpoints is
   integrated with 4-point Gauss-Legendre quadrature (a static segment exactly, with its rates
   evaluated once): ``int w``, ``int f`` and, only when the error model has the terms that need
   them, ``int f^(2)``, ``int f^(x)`` (nonlinearity, cross-coupling) and ``int w w^T``, ``delta w``
   (size effect).  The gimbal kinematics are :func:`inscal.core.kinematics.rates_at` (N25 eq. 5-10);
   within a segment only one gimbal turns, so the sine and cosine of the other one are taken once per
   segment (the same numbers: its angle is exactly its start angle);
2. with a time asynchrony, the accelerometer window ``gyro window - I_k + I_{k-1}`` from the
   boundary integrals of :func:`inscal.sim.simulate._asynchrony_kernel`;
3. the error model of :meth:`inscal.core.error_model.ImuErrors.measure_increments` (N25 eq. 1-2,
   S16 eq. 1, 4-12), every product summed in the same order as there, so both give the same bits;
   a term whose parameters are all zero is skipped, and a perfect IMU skips the model;
4. the noise of :class:`inscal.sim.simulate.NoiseState` from its normal draws (made in NumPy, in
   bulk, by the generator calls of ``NoiseState.apply``): white noise, first-order Gauss-Markov bias
   instability (the recursion of ``scipy.signal.lfilter([1], [1, -phi])``), quantization of the
   running totals, in the order and with the arithmetic of ``NoiseState.apply``;
5. the recorded gimbal angles at ``t_k`` (:meth:`inscal.core.turntable.Segments.angles`, the same
   expression) plus encoder noise.

A sample inside a static segment (after a sample that ended in it, so ``delta w = 0``) has integrals
and a measured output that depend only on its length ``t_k - t_{k-1}``, which takes a few values in
floating point (about 20 over an hour at 100 Hz): steps 1-3 are done once per length and segment and
their numbers reused (a small memo, in record runs without asynchrony), the same bits as doing them.

What the pass does is chosen by the bits of ``opts`` (``O_*`` below); arrays a run does not use are
passed with one row (or none) and are not touched.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.core.kinematics import gimbal_angles, rates_from_trig

# ----------------------------------------------------------------------------- options (bits of opts)
O_QUAD = 1  # int f^(2), int f^(x) and the accelerometer nonlinearity / cross-coupling (S16 eq. 4-6, 12)
O_LEVER = 2  # int w w^T, delta w and the size effect (S16 eq. 9-11)
O_GSENS = 4  # the gyro g-sensitivity (S16 eq. 1)
O_MEASURE = 8  # the error model (otherwise the measured increments are the true ones: a perfect IMU)
O_ASYNC = 16  # accelerometer window shifted by the time asynchrony (boundary integrals given)
O_RECORD = 32  # write time, measured increments and gimbal angles
O_TRUTH = 64  # write the true increments (gyro window)
O_RAW = 128  # write int f^(2), int f^(x), int w w^T, delta w of the gyro window (only those computed)
O_ARW = 256  # angle random walk
O_VRW = 512  # velocity random walk
O_GM_G = 1024  # gyro bias instability (first-order Gauss-Markov)
O_GM_A = 2048  # accelerometer bias instability
O_QUANT_G = 4096  # gyro quantization
O_QUANT_A = 8192  # accelerometer quantization
O_ENCODER = 16384  # encoder noise on the recorded gimbal angles

#: entries of the memo of static samples (the lengths b - a of the samples take a few values)
MEMO = 4


@njit(cache=True, inline="always")
def segment_trig(s, seg_th0, seg_w0, seg_acc):
    """``(turns_x, turns_z, cos, sin theta_x, cos, sin theta_z)`` of segment s: whether each gimbal
    turns, and the sine and cosine of the start angle of each (used for a gimbal at rest)."""
    tx = seg_w0[s, 0] != 0.0 or seg_acc[s, 0] != 0.0
    tz = seg_w0[s, 1] != 0.0 or seg_acc[s, 1] != 0.0
    return (tx, tz, math.cos(seg_th0[s, 0]), math.sin(seg_th0[s, 0]), math.cos(seg_th0[s, 1]),
            math.sin(seg_th0[s, 1]))


@njit(cache=True, inline="always")
def rates_on_segment(t, s, tx, tz, cx, sx, cz, sz, seg_t0, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g):
    """``(w_is^s, f^s)`` as a 6-tuple at time t on segment s, with the trigonometry of a gimbal at rest
    (``tx``/``tz`` False) from :func:`segment_trig`: the numbers of :func:`inscal.core.kinematics.rates_at`."""
    thx, thz, wx, wz = gimbal_angles(t, s, seg_t0, seg_th0, seg_w0, seg_acc)
    if tx:
        cx = math.cos(thx)
        sx = math.sin(thx)
    if tz:
        cz = math.cos(thz)
        sz = math.sin(thz)
    return rates_from_trig(cx, sx, cz, sz, wx, wz, u, Cbn, wie_n, g)


# ----------------------------------------------------------------------------- per-axis steps of the pass
# Small helpers that numba inlines: the pass keeps its numbers in scalars (registers), three axes at a time;
# each helper does the arithmetic the pass wrote out per axis, in the same order (the same bits).
@njit(cache=True, inline="always")
def add_scaled(a0, a1, a2, c, x0, x1, x2):
    """``a_i + c x_i`` for the three axes."""
    return a0 + c * x0, a1 + c * x1, a2 + c * x2


@njit(cache=True, inline="always")
def add_products(s0, s1, s2, s3, s4, s5, c, x0, x1, x2):
    """The six products of a 3-vector added with weight c: ``s + c (x_0^2, x_1^2, x_2^2, x_0 x_1, x_0 x_2,
    x_1 x_2)`` (``f^(2)`` and ``f^(x)``; the six of ``w w^T``)."""
    return (s0 + c * x0 * x0, s1 + c * x1 * x1, s2 + c * x2 * x2, s3 + c * x0 * x1, s4 + c * x0 * x2,
            s5 + c * x1 * x2)


@njit(cache=True, inline="always")
def shifted(a, j, c, x0, x1, x2):
    """The window shifted by the asynchrony: ``x_i - a[j + 1, c + i] + a[j, c + i]`` (gyro window - I_{j+1} + I_j)."""
    return (x0 - a[j + 1, c] + a[j, c], x1 - a[j + 1, c + 1] + a[j, c + 1], x2 - a[j + 1, c + 2] + a[j, c + 2])


@njit(cache=True, inline="always")
def mat_vec(m, x0, x1, x2):
    """``m x`` for a 3x3 ``m``, each row summed left to right."""
    return (m[0, 0] * x0 + m[0, 1] * x1 + m[0, 2] * x2, m[1, 0] * x0 + m[1, 1] * x1 + m[1, 2] * x2,
            m[2, 0] * x0 + m[2, 1] * x1 + m[2, 2] * x2)


@njit(cache=True, inline="always")
def put3(a, j, c, x0, x1, x2):
    """``a[j, c:c + 3] = x``."""
    a[j, c] = x0
    a[j, c + 1] = x1
    a[j, c + 2] = x2


@njit(cache=True, inline="always")
def white(x0, x1, x2, z, j, sigma, sqdt):
    """White noise added to the three axes: ``x_i + z[j, i] sigma_i sqrt(dt)``."""
    return x0 + z[j, 0] * sigma[0] * sqdt, x1 + z[j, 1] * sigma[1] * sqdt, x2 + z[j, 2] * sigma[2] * sqdt


@njit(cache=True, inline="always")
def gauss_markov_step(zi, z, j, c, sigma, drv, phi):
    """The bias of axis c in sample j: ``y = zi_c + sigma_c sqrt(1 - phi^2) z_jc``, and the state ``zi_c = phi y``."""
    y = zi[c] + z[j, c] * sigma[c] * drv
    zi[c] = y * phi
    return y


@njit(cache=True)
def simulate_pass(k0, n, dt, path, glx, glw, opts, model, boundary, noise, carry, out):
    """Samples ``k0 .. k0 + n - 1`` of a simulation (see the module docstring), all SI.

    The arguments come in tuples (numba unpacks them at no cost):

    * ``path`` = ``(seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g)``: the
      :class:`~inscal.core.turntable.Segments` arrays; ``u`` the outer axis, ``Cbn`` the mount attitude,
      ``wie_n``, ``g`` the site; ``glx``, ``glw`` the Gauss-Legendre nodes and weights.
    * ``model`` = ``(mg, bg, gs, ma, ba, k2, kc, p)``, the error model (``O_MEASURE``): ``mg``, ``ma`` = M_g,
      M_a; ``bg``, ``ba`` the biases; ``gs`` = G; ``k2`` the nonlinearity, ``kc`` the cross-coupling matrix,
      ``p`` the lever arms (rows).
    * ``boundary`` = ``(iv, if2, ifx, iww, wdel)``, asynchrony (``O_ASYNC``): boundary integrals and rates at
      ``t_j - tau`` for the boundaries ``j = 0 .. n`` of the chunk.
    * ``noise`` = ``(sqdt, z_arw, arw, z_vrw, vrw, z_gm_g, sig_g, drv_g, phi_g, zi_g, z_gm_a, sig_a, drv_a, phi_a,
      zi_a, q_g, tot_g, cnt_g, q_a, tot_a, cnt_a, z_enc, enc)``: standard normal draws ``z_*`` (n rows) with
      their coefficients (``sqdt`` = sqrt(dt)); Gauss-Markov ``drv = sqrt(1 - phi^2)`` and the filter states
      ``zi_*`` (updated); quanta ``q_*`` with the running totals ``tot_*`` and emitted counts ``cnt_*``
      (updated); ``enc`` the encoder sigma.
    * ``out`` = ``(time, mdth, mdv, gimbal, tdth, tdv, f2, fx, ww, dw)``, the outputs (below).

    ``carry`` (4,): ``w`` at ``k0 dt`` left by the pass that ended there (``carry[0] != 0``: taken, so
    a chunk done in several passes gives the numbers of one pass; 0: evaluated here), and set for the
    next pass.
    Outputs (n rows): ``time``, ``mdth``, ``mdv``, ``gimbal`` (``O_RECORD``); ``tdth``, ``tdv``
    (``O_TRUTH``); ``f2``, ``fx``, ``ww``, ``dw`` (``O_RAW``)."""
    seg_t0, seg_t1, seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g = path
    mg, bg, gs, ma, ba, k2, kc, p = model
    iv, if2, ifx, iww, wdel = boundary
    (sqdt, z_arw, arw, z_vrw, vrw, z_gm_g, sig_g, drv_g, phi_g, zi_g, z_gm_a, sig_a, drv_a, phi_a, zi_a,
     q_g, tot_g, cnt_g, q_a, tot_a, cnt_a, z_enc, enc) = noise
    time, mdth, mdv, gimbal, tdth, tdv, f2, fx, ww, dw = out
    S = seg_t0.shape[0]
    quad = (opts & O_QUAD) != 0
    lever = (opts & O_LEVER) != 0
    gsens = (opts & O_GSENS) != 0
    measure = (opts & O_MEASURE) != 0
    asyn = (opts & O_ASYNC) != 0
    record = (opts & O_RECORD) != 0
    truth = (opts & O_TRUTH) != 0
    raw = (opts & O_RAW) != 0
    o_arw = (opts & O_ARW) != 0
    o_vrw = (opts & O_VRW) != 0
    gm_g = (opts & O_GM_G) != 0
    gm_a = (opts & O_GM_A) != 0
    qz_g = (opts & O_QUANT_G) != 0
    qz_a = (opts & O_QUANT_A) != 0
    o_enc = (opts & O_ENCODER) != 0
    nq = glx.shape[0]

    a0 = k0 * dt
    s = 0
    while s < S - 1 and seg_t1[s] <= a0:
        s += 1
    sg = 0  # segment of the recorded angles at t_k: the smallest with seg_t1 >= t_k (Segments.angles)
    trig_seg = -1
    tx = tz = False
    cx = sx = cz = sz = 0.0
    static_seg = -1
    ws0 = ws1 = ws2 = fs0 = fs1 = fs2 = 0.0
    wp0 = wp1 = wp2 = 0.0  # w at the start of the sample (for delta w)
    if lever:
        if carry[0] != 0.0:
            wp0, wp1, wp2 = carry[1], carry[2], carry[3]
        else:
            tx, tz, cx, sx, cz, sz = segment_trig(s, seg_th0, seg_w0, seg_acc)
            trig_seg = s
            wp0, wp1, wp2, f0, f1, f2_ = rates_on_segment(a0, s, tx, tz, cx, sx, cz, sz, seg_t0, seg_th0, seg_w0,
                                                          seg_acc, u, Cbn, wie_n, g)
    use_memo = record and not raw and not asyn
    memo_s = np.full(MEMO, -1, dtype=np.int64)
    memo_h = np.zeros(MEMO)
    memo_v = np.zeros((MEMO, 12))
    memo_next = 0
    prev_static_end = -1  # the static segment in which the previous sample ended (-1: none, or not known)
    for j in range(n):
        a = (k0 + j) * dt
        b = (k0 + j + 1) * dt
        # --- 0. a sample inside a static segment (after one that ended in it, for delta w = 0): its integrals
        # and error model depend only on its length h, which takes a few values; the numbers of an earlier
        # sample of the same segment and length are taken again (bit for bit what steps 1-3 give)
        hit = -1
        qualify = False
        s_memo = s
        h_memo = b - a
        if (use_memo and (s == S - 1 or seg_t1[s] >= b) and (prev_static_end == s or not lever)
                and seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0):
            qualify = True
            for e in range(MEMO):
                if memo_s[e] == s and memo_h[e] == h_memo:
                    hit = e
                    break
        if hit >= 0:
            ng0, ng1, ng2 = memo_v[hit, 0], memo_v[hit, 1], memo_v[hit, 2]
            na0, na1, na2 = memo_v[hit, 3], memo_v[hit, 4], memo_v[hit, 5]
            prev_static_end = s
            if s < S - 1 and seg_t1[s] <= b:
                s += 1
            if truth:
                put3(tdth, j, 0, memo_v[hit, 6], memo_v[hit, 7], memo_v[hit, 8])
                put3(tdv, j, 0, memo_v[hit, 9], memo_v[hit, 10], memo_v[hit, 11])
        else:
            # --- 1. the integrals over [a, b], piece by piece between breakpoints
            th0 = th1 = th2 = 0.0
            v0 = v1 = v2 = 0.0
            q0 = q1 = q2 = 0.0
            x0 = x1 = x2 = 0.0
            r0 = r1 = r2 = r3 = r4 = r5 = 0.0
            sa = a
            end_static = False
            while True:
                sb = seg_t1[s] if (seg_t1[s] < b and s < S - 1) else b
                h = sb - sa
                is_static = seg_w0[s, 0] == 0.0 and seg_w0[s, 1] == 0.0 and seg_acc[s, 0] == 0.0 and seg_acc[s, 1] == 0.0
                if h > 0.0:
                    if trig_seg != s:
                        tx, tz, cx, sx, cz, sz = segment_trig(s, seg_th0, seg_w0, seg_acc)
                        trig_seg = s
                    if is_static and static_seg != s:
                        ws0, ws1, ws2, fs0, fs1, fs2 = rates_on_segment(seg_t0[s], s, tx, tz, cx, sx, cz, sz, seg_t0,
                                                                        seg_th0, seg_w0, seg_acc, u, Cbn, wie_n, g)
                        static_seg = s
                    for k in range(1 if is_static else nq):
                        if is_static:
                            wq = h
                            w0, w1, w2, f0, f1, f2_ = ws0, ws1, ws2, fs0, fs1, fs2
                        else:
                            tq = 0.5 * (sa + sb) + 0.5 * h * glx[k]
                            wq = 0.5 * h * glw[k]
                            w0, w1, w2, f0, f1, f2_ = rates_on_segment(tq, s, tx, tz, cx, sx, cz, sz, seg_t0, seg_th0,
                                                                       seg_w0, seg_acc, u, Cbn, wie_n, g)
                        th0, th1, th2 = add_scaled(th0, th1, th2, wq, w0, w1, w2)
                        v0, v1, v2 = add_scaled(v0, v1, v2, wq, f0, f1, f2_)
                        if quad:
                            q0, q1, q2, x0, x1, x2 = add_products(q0, q1, q2, x0, x1, x2, wq, f0, f1, f2_)
                        if lever:
                            r0, r1, r2, r3, r4, r5 = add_products(r0, r1, r2, r3, r4, r5, wq, w0, w1, w2)
                if sb >= b:
                    end_static = is_static and static_seg == s
                    break
                s += 1
                sa = sb
            d0 = d1 = d2 = 0.0
            if lever:
                # delta w = w(b) - w(a) (the integral of w-dot); w is continuous across segments
                if end_static:
                    we0, we1, we2 = ws0, ws1, ws2
                else:
                    if trig_seg != s:
                        tx, tz, cx, sx, cz, sz = segment_trig(s, seg_th0, seg_w0, seg_acc)
                        trig_seg = s
                    we0, we1, we2, f0, f1, f2_ = rates_on_segment(b, s, tx, tz, cx, sx, cz, sz, seg_t0, seg_th0, seg_w0,
                                                                  seg_acc, u, Cbn, wie_n, g)
                d0 = we0 - wp0
                d1 = we1 - wp1
                d2 = we2 - wp2
                wp0, wp1, wp2 = we0, we1, we2
            prev_static_end = s if end_static else -1
            # the next sample starts in segment s (or the one after, if s ends exactly at b)
            if s < S - 1 and seg_t1[s] <= b:
                s += 1
            if truth:
                put3(tdth, j, 0, th0, th1, th2)
                put3(tdv, j, 0, v0, v1, v2)
            if raw:
                if quad:
                    put3(f2, j, 0, q0, q1, q2)
                    put3(fx, j, 0, x0, x1, x2)
                if lever:
                    put3(ww, j, 0, r0, r1, r2)
                    put3(ww, j, 3, r3, r4, r5)
                    put3(dw, j, 0, d0, d1, d2)
            if not record:
                continue
            # --- 2. the accelerometer window [a - tau, b - tau] = gyro window - I_{j+1} + I_j
            va0, va1, va2 = v0, v1, v2
            if asyn:
                va0, va1, va2 = shifted(iv, j, 0, v0, v1, v2)
                if quad:
                    q0, q1, q2 = shifted(if2, j, 0, q0, q1, q2)
                    x0, x1, x2 = shifted(ifx, j, 0, x0, x1, x2)
                if lever:
                    r0, r1, r2 = shifted(iww, j, 0, r0, r1, r2)
                    r3, r4, r5 = shifted(iww, j, 3, r3, r4, r5)
                    d0 = wdel[j + 1, 0] - wdel[j, 0]
                    d1 = wdel[j + 1, 1] - wdel[j, 1]
                    d2 = wdel[j + 1, 2] - wdel[j, 2]
            # --- 3. the error model: N_g = M_g (w + G f) + eps, N_a = M_a (f + a_size + K2 f^(2) + Kx f^(x)) + nabla
            if measure:
                e0, e1, e2 = th0, th1, th2
                if gsens:  # the g-sensitivity acts on the gyro window's specific force
                    g0, g1, g2 = mat_vec(gs, v0, v1, v2)
                    e0, e1, e2 = th0 + g0, th1 + g1, th2 + g2
                m0, m1, m2 = mat_vec(mg, e0, e1, e2)
                ng0, ng1, ng2 = m0 + bg[0] * dt, m1 + bg[1] * dt, m2 + bg[2] * dt
                if quad:
                    c0, c1, c2 = mat_vec(kc, x0, x1, x2)
                    va0, va1, va2 = va0 + q0 * k2[0] + c0, va1 + q1 * k2[1] + c1, va2 + q2 * k2[2] + c2
                if lever:
                    rr = r0 + r1 + r2
                    va0 = va0 + (r0 * p[0, 0] + r3 * p[0, 1] + r4 * p[0, 2] - p[0, 0] * rr) + (d1 * p[0, 2] - d2 * p[0, 1])
                    va1 = va1 + (r3 * p[1, 0] + r1 * p[1, 1] + r5 * p[1, 2] - p[1, 1] * rr) + (d2 * p[1, 0] - d0 * p[1, 2])
                    va2 = va2 + (r4 * p[2, 0] + r5 * p[2, 1] + r2 * p[2, 2] - p[2, 2] * rr) + (d0 * p[2, 1] - d1 * p[2, 0])
                m0, m1, m2 = mat_vec(ma, va0, va1, va2)
                na0, na1, na2 = m0 + ba[0] * dt, m1 + ba[1] * dt, m2 + ba[2] * dt
            else:
                ng0, ng1, ng2 = th0, th1, th2
                na0, na1, na2 = va0, va1, va2
            if qualify:  # keep the numbers for the next samples of this length in this segment
                memo_s[memo_next] = s_memo
                memo_h[memo_next] = h_memo
                put3(memo_v, memo_next, 0, ng0, ng1, ng2)
                put3(memo_v, memo_next, 3, na0, na1, na2)
                put3(memo_v, memo_next, 6, th0, th1, th2)
                put3(memo_v, memo_next, 9, v0, v1, v2)
                memo_next = (memo_next + 1) % MEMO
        # --- 4. the noise, in the order of NoiseState.apply
        if o_arw:
            ng0, ng1, ng2 = white(ng0, ng1, ng2, z_arw, j, arw, sqdt)
        if o_vrw:
            na0, na1, na2 = white(na0, na1, na2, z_vrw, j, vrw, sqdt)
        if gm_g:  # y_k = phi y_(k-1) + sigma sqrt(1 - phi^2) z_k, axis by axis
            ng0 = ng0 + gauss_markov_step(zi_g, z_gm_g, j, 0, sig_g, drv_g, phi_g) * dt
            ng1 = ng1 + gauss_markov_step(zi_g, z_gm_g, j, 1, sig_g, drv_g, phi_g) * dt
            ng2 = ng2 + gauss_markov_step(zi_g, z_gm_g, j, 2, sig_g, drv_g, phi_g) * dt
        if gm_a:
            na0 = na0 + gauss_markov_step(zi_a, z_gm_a, j, 0, sig_a, drv_a, phi_a) * dt
            na1 = na1 + gauss_markov_step(zi_a, z_gm_a, j, 1, sig_a, drv_a, phi_a) * dt
            na2 = na2 + gauss_markov_step(zi_a, z_gm_a, j, 2, sig_a, drv_a, phi_a) * dt
        if qz_g:  # whole quanta of the running total; the remainder carries to the next sample
            ng0, ng1, ng2 = (quantum_step(ng0, q_g, tot_g, cnt_g, 0), quantum_step(ng1, q_g, tot_g, cnt_g, 1),
                             quantum_step(ng2, q_g, tot_g, cnt_g, 2))
        if qz_a:
            na0, na1, na2 = (quantum_step(na0, q_a, tot_a, cnt_a, 0), quantum_step(na1, q_a, tot_a, cnt_a, 1),
                             quantum_step(na2, q_a, tot_a, cnt_a, 2))
        # --- 5. the recorded gimbal angles at b (Segments.angles: theta = th0 + w0 tau + 0.5 acc tau^2)
        while sg < S - 1 and seg_t1[sg] < b:
            sg += 1
        tau = b - seg_t0[sg]
        gx = seg_th0[sg, 0] + seg_w0[sg, 0] * tau + 0.5 * seg_acc[sg, 0] * (tau * tau)
        gz = seg_th0[sg, 1] + seg_w0[sg, 1] * tau + 0.5 * seg_acc[sg, 1] * (tau * tau)
        if o_enc:
            gx = gx + z_enc[j, 0] * enc
            gz = gz + z_enc[j, 1] * enc
        time[j] = b
        put3(mdth, j, 0, ng0, ng1, ng2)
        put3(mdv, j, 0, na0, na1, na2)
        gimbal[j, 0] = gx
        gimbal[j, 1] = gz
    if lever:
        carry[0] = 1.0
        carry[1] = wp0
        carry[2] = wp1
        carry[3] = wp2


@njit(cache=True, inline="always")
def quantum_step(x, q, total, emitted, c):
    """Add x to the running total of axis c and return the whole quanta it completes (times q)."""
    total[c] = total[c] + x
    cnt = np.floor(total[c] / q)  # a float, as numpy's (math.floor would give an integer)
    out = (cnt - emitted[c]) * q
    emitted[c] = cnt
    return out


@njit(cache=True)
def gauss_markov_filter(x, phi, z):
    """The first-order Gauss-Markov recursion ``y_k = x_k + z``, ``z = phi y_k`` per column of x (n, k),
    from the state ``z`` (k,), updated in place: ``scipy.signal.lfilter([1], [1, -phi], x, axis=0, zi=z)``
    with the same bits (its direct form II transposed computes ``1 x_k + z`` and ``0 x_k - (-phi) y_k``),
    as the compiled pass does it."""
    n, k = x.shape
    y = np.empty((n, k))
    for i in range(n):
        for j in range(k):
            v = z[j] + x[i, j]
            z[j] = v * phi
            y[i, j] = v
    return y

