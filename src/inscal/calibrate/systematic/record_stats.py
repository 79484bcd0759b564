"""Compiled scans of the increments for the systematic driver and its diagnostics: the robust spread of the
second differences (the noise estimate), the quantum of a quantized channel, the first turn of the record and
each filter step's rate features.

Each gives what the NumPy expression it replaces gives, bit for bit, in one or two passes over the record
instead of full-size temporaries and sorts: the order statistics are exact (a median is the same element of
the data whatever finds it: :func:`inscal.core.robust.exact_median`),
the sorted values of a channel come from a radix sort of order-preserving integer keys (three times faster
than a comparison sort on 10^5 .. 10^6 values), and every sum is formed in NumPy's order (sequential for
cumulative sums and three-element norms, pairwise for the mean of a row, :func:`pairwise_sum`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from inscal.core.robust import exact_median

#: radix sort: bits per digit (six passes over 64-bit keys)
RADIX_BITS = 11


@njit(cache=True)
def sorted_column(x, c, step):
    """``np.sort(x[::step, c])`` by an LSD radix sort of the IEEE-754 keys (negative values bit-inverted, the sign
    bit set on the others: the unsigned order of the keys is the order of the values; -0.0 sorts just before
    +0.0, which compare equal)."""
    n = (x.shape[0] + step - 1) // step
    sign = np.uint64(1) << np.uint64(63)
    a = np.empty(n, np.uint64)
    b = np.empty(n, np.uint64)
    col = np.empty(1)
    bits = col.view(np.uint64)
    for i in range(n):
        col[0] = x[i * step, c]
        u = bits[0]
        a[i] = ~u if (u & sign) else (u | sign)
    nd = 1 << RADIX_BITS
    mask = np.uint64(nd - 1)
    cnt = np.zeros(nd, np.int64)
    for p in range((64 + RADIX_BITS - 1) // RADIX_BITS):
        sh = np.uint64(RADIX_BITS * p)
        cnt[:] = 0
        for i in range(n):
            cnt[(a[i] >> sh) & mask] += 1
        if np.max(cnt) == n:  # one digit for all: this pass would not move anything
            continue
        s = 0
        for d in range(nd):
            m = cnt[d]
            cnt[d] = s
            s += m
        for i in range(n):
            d = (a[i] >> sh) & mask
            b[cnt[d]] = a[i]
            cnt[d] += 1
        a, b = b, a
    for i in range(n):
        u = a[i]
        a[i] = (u & ~sign) if (u & sign) else ~u
    return a.view(np.float64)


@njit(cache=True)
def column_quantum(x, c, step):
    """``driver.data_resolution`` of column ``c`` of ``x[::step]``: the smallest step ``q`` between its distinct values
    when every distinct value is within 1e-3 of a whole multiple of it and there are at least 16 of them, else 0
    (the distinct values of ``np.unique``: equal neighbours of the sorted values merged, the first kept)."""
    v = sorted_column(x, c, step)
    nd = 0
    q = np.inf
    prev = 0.0
    for i in range(v.shape[0]):
        if nd > 0 and v[i] == prev:
            continue
        if nd > 0:
            d = v[i] - prev
            if d > 0.0 and d < q:
                q = d
        v[nd] = v[i]
        prev = v[i]
        nd += 1
    if nd < 16 or not q < np.inf or not q > 0.0:
        return 0.0
    for i in range(nd):
        k = v[i] / q
        if not abs(k - np.round(k)) < 1e-3:
            return 0.0
    return q


@njit(cache=True)
def second_difference_mad(x, step):
    """Per column of ``x`` (n, k): the median absolute deviation of ``d2 = (x[2:] - 2 x[1:-1] + x[:-2])[::step]``
    from its median (``np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)``; NaN without second differences)."""
    n = x.shape[0]
    m = (n - 2 + step - 1) // step if n > 2 else 0
    out = np.full(x.shape[1], np.nan)
    if m == 0:
        return out
    d = np.empty(m)
    pair = np.empty(2)
    for c in range(x.shape[1]):
        for i in range(m):
            j = i * step
            d[i] = (x[j + 2, c] - 2.0 * x[j + 1, c]) + x[j, c]
        med = exact_median(d, pair)
        for i in range(m):
            d[i] = abs(d[i] - med)
        out[c] = exact_median(d, pair)
    return out


@njit(cache=True)
def first_turn(dth, h, dt, threshold):
    """The first ``i`` at which the body rate over ``h`` samples, ``|c[i + h] - c[i]| / (h dt)`` with ``c`` the
    cumulative sum of ``dth``, exceeds ``threshold`` (``np.flatnonzero(np.linalg.norm(c[h:] - c[:-h], axis=1) /
    (h * dt) > threshold)[0]``), ``len(dth)`` when it never does: the scan stops at the first turn."""
    n = dth.shape[0]
    if n <= h:
        return n
    c = np.empty((n, 3))
    c[0] = dth[0]
    for i in range(1, h + 1):
        for a in range(3):
            c[i, a] = c[i - 1, a] + dth[i, a]
    hdt = h * dt
    for i in range(n - h):
        if i > 0:
            for a in range(3):
                c[i + h, a] = c[i + h - 1, a] + dth[i + h, a]
        d0 = c[i + h, 0] - c[i, 0]
        d1 = c[i + h, 1] - c[i, 1]
        d2 = c[i + h, 2] - c[i, 2]
        if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / hdt > threshold:
            return i
    return n


@njit(cache=True)
def _pairwise_block(a, i0, n):
    """NumPy's pairwise sum of ``a[i0:i0 + n]`` for ``n <= 128``: sequential below 8 values, else eight running
    sums, combined in pairs, and the rest."""
    if n < 8:
        s = 0.0
        for i in range(n):
            s += a[i0 + i]
        return s
    r = np.empty(8)
    for j in range(8):
        r[j] = a[i0 + j]
    i = 8
    while i < n - (n % 8):
        for j in range(8):
            r[j] += a[i0 + i + j]
        i += 8
    s = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        s += a[i0 + i]
        i += 1
    return s


@njit(cache=True)
def pairwise_sum(a, i0, n):
    """NumPy's pairwise summation of ``a[i0:i0 + n]`` (the order of ``np.add.reduce`` over a contiguous row):
    blocks of at most 128 (:func:`_pairwise_block`), above that the sum of the two halves (the first a multiple
    of 8), evaluated with an explicit stack (a compiled recursive function does not load from numba's cache)."""
    if n <= 128:
        return _pairwise_block(a, i0, n)
    st_i = np.empty(192, np.int64)  # pending work: a range (i, m), or m = -1: add the last two values
    st_m = np.empty(192, np.int64)
    vals = np.empty(64)
    top = 1
    nv = 0
    st_i[0] = i0
    st_m[0] = n
    while top > 0:
        top -= 1
        i, m = st_i[top], st_m[top]
        if m < 0:
            nv -= 1
            vals[nv - 1] = vals[nv - 1] + vals[nv]
        elif m <= 128:
            vals[nv] = _pairwise_block(a, i, m)
            nv += 1
        else:
            m2 = m // 2
            m2 -= m2 % 8
            st_i[top], st_m[top] = 0, -1
            st_i[top + 1], st_m[top + 1] = i + m2, m - m2
            st_i[top + 2], st_m[top + 2] = i, m2
            top += 3
    return vals[0]


@njit(cache=True)
def step_rates(dtheta, dt, dt2, n_per, M):
    """Per filter step the mean body rate ``|w|`` (``np.linalg.norm(dtheta[:n].reshape(M, n_per, 3) / dt,
    axis=2).mean(axis=1)``), the largest and the last sample-to-sample rate change ``|dtheta_k+1 - dtheta_k| /
    dt2`` (``dt2 = dt ** 2``; zero for the record's last sample)."""
    rate = np.empty(n_per)
    mean_rate = np.empty(M)
    dw_max = np.empty(M)
    dw_end = np.empty(M)
    last = dtheta.shape[0] - 1
    for k in range(M):
        top = -np.inf
        v = 0.0
        for j in range(n_per):
            s = k * n_per + j
            w0, w1, w2 = dtheta[s, 0] / dt, dtheta[s, 1] / dt, dtheta[s, 2] / dt
            rate[j] = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
            if s < last:
                d0 = dtheta[s + 1, 0] - dtheta[s, 0]
                d1 = dtheta[s + 1, 1] - dtheta[s, 1]
                d2 = dtheta[s + 1, 2] - dtheta[s, 2]
                v = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / dt2
            else:
                v = 0.0
            if v > top or j == 0:
                top = v
        mean_rate[k] = pairwise_sum(rate, 0, n_per) / n_per
        dw_max[k] = top
        dw_end[k] = v
    return mean_rate, dw_max, dw_end
