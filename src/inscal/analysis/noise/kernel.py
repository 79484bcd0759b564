"""The compiled inner loop of the streamed Allan / Haar wavelet variance
(:class:`inscal.analysis.noise.estimators.StreamingScaleVariance` with ``kernel=sum_squared_terms``): the
same sums as the NumPy path, fused into one pass per averaging factor without temporaries.  Kept out of
:mod:`.estimators` so that ``inscal allan`` does not load numba at start."""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def sum_squared_terms(buf, l0s, cnts, ms, sums):  # pragma: no cover - compiled
    """``sums[j, c] += sum_{i<cnts[j]} (x[l+2m] - 2 x[l+m] + x[l])^2``, ``l = l0s[j] + i``, ``m = ms[j]``,
    ``x = buf[:, c]``: the squared second differences of the phase (IEEE 952 eq. C.8 terms)."""
    k = buf.shape[1]
    for j in range(ms.size):
        m = ms[j]
        l0 = l0s[j]
        for i in range(cnts[j]):
            s = l0 + i
            for c in range(k):
                d = buf[s + 2 * m, c] - 2.0 * buf[s + m, c] + buf[s, c]
                sums[j, c] += d * d
