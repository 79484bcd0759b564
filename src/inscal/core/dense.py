"""Entries of small dense matrix products for the numba kernels: plain loops (no BLAS call per step), each sum
taken in the order ``l = 0, 1, ...`` so that every kernel that uses it gets the bits of its own loop."""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def product_entry(s, X, i, Y, j, n):
    """``s + X[i, 0] Y[0, j] + ... + X[i, n-1] Y[n-1, j]``, summed left to right: the entry (i, j) of ``X Y``
    (``s = 0``) or of ``S + X Y`` (``s = S[i, j]``)."""
    for m in range(n):
        s += X[i, m] * Y[m, j]
    return s
