"""Robust statistics in compiled loops: an exact median that costs the same whatever the data.

A classical quickselect (NumPy's ``np.median``, numba's) partitions around a pivot with a data-dependent
branch per element; on noise that branch goes either way at random, and the mispredictions, not the
comparisons, set the cost (about 9 ns per element for a window of 10,000 samples, 2 ns when a benchmark
repeats the same array and the branch predictor has learnt it).  :func:`exact_median` counts the values into
a histogram over their range instead, which finds the bins of the middle ranks without such branches, and
narrows a bin that holds both: 35 us for 10,000 fresh values, 1.2 ms for 386,000.

The median is one value of the data (the mean of the two middle ones for an even count, ``(a + b) / 2`` as
NumPy computes it), so the result is value for value what :func:`numpy.median` gives, NaN and infinities
included (``tests/core/test_robust.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: bins of the histogram that narrows an order statistic
SELECT_BINS = 2048


@njit(cache=True)
def _order_pair(x, k, out):
    """The ``k``-th and, when ``k + 1 < len(x)``, the ``(k + 1)``-th smallest values of ``x`` (0-based, finite
    values) into ``out[0]``, ``out[1]``, exactly: a histogram of the values over their range finds the bins of
    the two ranks (a value's bin never decreases with the value); a bin holding both is narrowed the same way
    (the outliers of the range gone), two bins give the largest value of the first and the smallest of the
    second; a few values are sorted."""
    nb = SELECT_BINS
    cnt = np.zeros(nb, np.int64)
    cnt4 = np.zeros((4, nb), np.int64)
    buf = x
    while True:
        n = buf.shape[0]
        k1 = min(k + 1, n - 1)
        if n <= 64:
            srt = np.sort(buf)
            out[0] = srt[k]
            out[1] = srt[k1]
            return
        lo = buf[0]
        hi = buf[0]
        for v in buf:
            lo = min(lo, v)
            hi = max(hi, v)
        if not hi > lo:
            out[0] = lo
            out[1] = lo
            return
        sc = nb / (hi - lo)
        cnt4[:, :] = 0
        for i in range(n):  # four interleaved counts: values in one bin do not wait on each other's increment
            cnt4[i & 3, min(int((buf[i] - lo) * sc), nb - 1)] += 1
        for b in range(nb):
            cnt[b] = cnt4[0, b] + cnt4[1, b] + cnt4[2, b] + cnt4[3, b]
        below = 0
        b0 = 0
        while below + cnt[b0] <= k:
            below += cnt[b0]
            b0 += 1
        if below + cnt[b0] > k1:  # both ranks in bin b0: narrow it
            sel = np.empty(cnt[b0] + 1)
            m = 0
            for v in buf:  # without a branch: every value written, the kept ones advance
                sel[m] = v
                m += min(int((v - lo) * sc), nb - 1) == b0
            buf = sel[:m]
            k -= below
            continue
        b1 = b0 + 1  # the rank k + 1 opens the next non-empty bin
        while cnt[b1] == 0:
            b1 += 1
        top = -np.inf
        bottom = np.inf
        for v in buf:
            b = min(int((v - lo) * sc), nb - 1)
            if b == b0 and v > top:
                top = v
            elif b == b1 and v < bottom:
                bottom = v
        out[0] = top
        out[1] = bottom
        return


@njit(cache=True)
def exact_median(x, pair):
    """``np.median`` of ``x`` (1-D, not empty): the middle value, or the mean of the two middle values
    (``(a + b) / 2``, as NumPy's mean of them); NaN when a value is; ``pair`` (2,) work."""
    n = x.shape[0]
    finite = True
    for v in x:
        if np.isnan(v):
            return np.nan
        finite = finite and abs(v) < np.inf
    if finite:
        _order_pair(x, (n - 1) // 2, pair)
    else:  # infinite values: no histogram over their range
        srt = np.sort(x)
        pair[0] = srt[(n - 1) // 2]
        pair[1] = srt[min(n // 2, n - 1)]
    if n % 2 == 1:
        return pair[0]
    return (pair[0] + pair[1]) / 2.0
