"""The maximal-overlap Allan variance and Haar (MODWT) wavelet variance of every channel of a record,
streamed in one pass of chunks (bounded memory): one engine for both.

With the phase ``x_i = sum_{l<i} y_l`` (``x_0 = 0``; ``y`` the rate samples, or the increments
divided by ``dt``) and an averaging factor ``m`` (``tau = m dt``), each term

    D_i(m) = x_{i+2m} - 2 x_{i+m} + x_i,   i = 0 .. n - 2m   (M = n - 2m + 1 terms)

is ``m`` times the difference of two adjacent m-sample means, so::

    AVAR(m) = sum D^2 / (2 m^2 M)   (the overlapping estimator of IEEE 952 eq. C.8 and allantools.oadev)
    WV(m)   = sum D^2 / (4 m^2 M)   (the MODWT Haar wavelet variance at width L = 2m, scale index
                                    j = log2(2m) for octave m: Percival & Walden 2000 eq. 306b, the
                                    boundary coefficients left out)

i.e. AVAR(m) = 2 WV(2m-wide).  The phase is kept for the last ``2 m_max + chunk`` samples only, and
the squared terms of every ``m`` are summed as soon as their three phases are known: the exact
sums, not an approximation.  The rounding of the phase is kept small by removing the first chunk's
mean before summing (a constant rate does not change any D).  Two numba kernels do the work: the
running phase, and per factor one pass down each channel's phases (stored channel-major) summing
D^2 in blocks of :data:`BLOCK` terms (a two-level sum; the inner one spread over vector lanes), about
0.6 ns per term and factor: a 24-h 100-Hz six-channel record at its 20 octave factors in about a second.

Intervals (:mod:`inscal.analysis.noise.intervals`) use the equivalent degrees of freedom
``eta3 = max(M / L, 1)`` (Percival & Walden 2000 eq. 314c), as GMWM's ``wvar`` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

#: terms summed in one partial sum before it is added to the total (a two-level sum: rounding
#: about (BLOCK + M / BLOCK) eps instead of M eps on M terms)
BLOCK = 4096


def octave_scales(n: int, max_fraction: float = 0.1) -> np.ndarray:
    """Averaging factors 1, 2, 4, ... up to ``max(2, n max_fraction)`` (scale index j = log2(2m))."""
    return 2 ** np.arange(0, int(math.log2(max(2, n * max_fraction))) + 1)


def log_scales(n: int, per_octave: int = 8, max_fraction: float = 0.1) -> np.ndarray:
    """A denser grid for plots: ``per_octave`` factors per octave (rounded, unique), the octaves included."""
    top = math.log2(max(2, n * max_fraction))
    dense = np.unique(np.round(2 ** np.arange(0, top + 1e-9, 1.0 / per_octave)).astype(np.int64))
    return np.unique(np.concatenate([dense, octave_scales(n, max_fraction)]))


@dataclass(frozen=True)
class ScaleVariance:
    """The Allan and Haar wavelet variances of ``k`` channels at averaging factors ``m``.

    ``wv[j, c]`` is channel c's Haar wavelet variance at width ``2 m[j]`` and ``avar = 2 wv`` its Allan
    variance at ``tau = m dt``, in the squared rate unit of the input; ``n_terms`` the number M of
    terms (MODWT coefficients) behind each value."""

    m: np.ndarray  # (J,) averaging factors
    dt: float  # [s]
    n: int  # samples
    wv: np.ndarray  # (J, k)
    n_terms: np.ndarray  # (J,)

    @property
    def taus(self) -> np.ndarray:
        """The averaging times ``tau = m dt`` [s], shape (J,)."""
        return self.m * self.dt

    @property
    def avar(self) -> np.ndarray:
        """The Allan variance ``2 wv`` at ``taus``, (J, k), in the squared rate unit of the input."""
        return 2.0 * self.wv

    @property
    def adev(self) -> np.ndarray:
        """The Allan deviation ``sqrt(avar)`` at ``taus``, (J, k), in the rate unit of the input."""
        return np.sqrt(self.avar)

    @property
    def scale_index(self) -> np.ndarray:
        """log2 of the Haar width 2m: the wavelet scale index j for the octave factors (fractional otherwise)."""
        return np.log2(2.0 * self.m)

    @property
    def edf(self) -> np.ndarray:
        """eta3 = max(M / L, 1), L = 2m the Haar width (Percival & Walden 2000 eq. 314c)."""
        return np.maximum(self.n_terms / (2.0 * self.m), 1.0)

    def channel(self, c: int) -> "ScaleVariance":
        """The variances of channel ``c`` alone: a :class:`ScaleVariance` with ``k = 1``."""
        return ScaleVariance(self.m, self.dt, self.n, self.wv[:, c:c + 1], self.n_terms)


class StreamingScaleVariance:
    """:class:`ScaleVariance` of ``n`` samples of ``k`` channels fed chunk by chunk.

    ``update(x)`` takes rates (``increments=False``) or increments (``increments=True``: they are the
    rates times ``dt``, and the phase is their running sum; the result is then in rate units).
    Memory: about ``k (3 m_max + piece)`` floats."""

    def __init__(self, n: int, rate_hz: float, k: int = 3, m=None, piece: int = 1 << 16,
                 increments: bool = True):
        if n < 16:
            raise ValueError(f"need at least 16 samples, got {n}")
        self.n, self.rate_hz, self.k = int(n), float(rate_hz), int(k)
        m = octave_scales(self.n) if m is None else np.asarray(m)
        m = np.unique(np.asarray(m, dtype=np.int64))
        self.m = m[(m > 0) & (m < self.n + 1)]  # at least one term (allantools: m < len(phase))
        if self.m.size == 0:
            raise ValueError(f"no averaging factor fits {n} samples")
        self.scale = 1.0 / self.rate_hz if increments else 1.0  # D / (m scale): a difference of rate means
        m_max = int(self.m.max())
        self.piece = int(max(1024, min(piece, self.n)))
        self.slack = max(self.piece, m_max)  # rows appended between two shifts of the history
        # the phase history, channel-major (each channel's phases contiguous: the kernels run down them)
        self.buf = np.empty((self.k, min(2 * m_max + 1 + self.slack, self.n + 1)))
        self.buf[:, 0] = 0.0
        self.b0 = 0  # global phase index of buf[0]
        self.fill = 1  # rows of buf in use: phases b0 .. b0 + fill - 1
        self.next_i = np.zeros(self.m.size, dtype=np.int64)  # next term index of each m
        self.sums = np.zeros((self.m.size, self.k))
        self.fed = 0
        self.c = None

    def update(self, x) -> None:
        """Feed the next chunk ((N, k), or (N,) for one channel) of rates or increments; more than the
        announced ``n`` samples, a wrong shape or a NaN/inf is a ValueError."""
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        x = np.ascontiguousarray(x)  # the kernels' one compiled layout
        if x.ndim != 2 or x.shape[1] != self.k:
            raise ValueError(f"samples of shape (N, {self.k}) expected, got {x.shape}")
        if self.fed + x.shape[0] > self.n:
            raise ValueError(f"more than the announced {self.n} increments")
        if not np.all(np.isfinite(x)):
            raise ValueError("increments contain NaN or inf")
        if self.c is None and x.shape[0]:
            self.c = np.ascontiguousarray(x.mean(axis=0))
        for a in range(0, x.shape[0], self.piece):
            self._feed(x[a:a + self.piece])

    def _shift(self, L: int) -> None:
        """Drop the phases no term needs any more, so that ``L`` more fit, and re-base the rest."""
        keep0 = int(min(self.next_i.min(), self.b0 + self.fill - 1)) - self.b0
        rows = self.fill - keep0
        if rows >= 2:
            shift_rebase(self.buf, keep0, rows, self.c)
        elif keep0 > 0:
            self.buf[:, :rows] = self.buf[:, keep0:keep0 + rows]
        self.b0 += keep0
        self.fill -= keep0
        if self.fill + L > self.buf.shape[1]:  # first shift of a buffer sized for a short record
            self.buf = np.concatenate([self.buf[:, : self.fill], np.empty((self.k, L))], axis=1)

    def _feed(self, x) -> None:
        L = x.shape[0]
        if self.fill + L > self.buf.shape[1]:
            self._shift(L)
        append_phase(self.buf, self.fill, x, self.c)
        self.fill += L
        self.fed += L
        J = self.b0 + self.fill - 1  # the last phase index known
        accumulate(self.buf, self.b0, J, self.m, self.next_i, self.sums)

    def result(self) -> ScaleVariance:
        """The :class:`ScaleVariance` of the ``n`` samples fed (a ValueError before all of them are):
        the factors with at least one term, the wavelet variance in rate units squared."""
        if self.fed != self.n:
            raise ValueError(f"fed {self.fed} of the announced {self.n} increments")
        nterm = self.n + 1 - 2 * self.m
        wv = self.sums / (4.0 * np.maximum(nterm, 1)[:, None] * (self.m[:, None] * self.scale) ** 2)
        ok = nterm >= 1
        return ScaleVariance(self.m[ok].astype(float), 1.0 / self.rate_hz, self.n, wv[ok], nterm[ok].astype(float))


@njit(cache=True)
def append_phase(buf, start, x, c):
    """Continue each channel's phase: ``buf[ch, start + i] = buf[ch, start + i - 1] + x[i, ch] - c[ch]``
    (the running sum, carried from the last phase known; in order, as ``numpy.cumsum``; two channels'
    sums side by side, so that one's addition waits less on the other's)."""
    k = buf.shape[0]
    for ch0 in range(0, k, 2):
        ch1 = min(ch0 + 1, k - 1)  # an odd last channel: summed twice, the same values written
        a0, a1, c0, c1 = buf[ch0, start - 1], buf[ch1, start - 1], c[ch0], c[ch1]
        r0, r1 = buf[ch0], buf[ch1]
        for i in range(x.shape[0]):
            a0 += x[i, ch0] - c0
            a1 += x[i, ch1] - c1
            r0[start + i] = a0
            r1[start + i] = a1


@njit(cache=True)
def shift_rebase(buf, keep0, rows, c):
    """Move each channel's phases ``keep0 .. keep0 + rows - 1`` to the front, minus the line through
    the first and last of them, and add that line's slope to the rate ``c[ch]`` removed from the samples
    to come (a linear function of the index changes no second difference D; the phases stay small,
    and their rounding, eps abs(x), is what limits D)."""
    for ch in range(buf.shape[0]):
        x0 = buf[ch, keep0]
        b = (buf[ch, keep0 + rows - 1] - x0) / (rows - 1)
        for a in range(rows):
            buf[ch, a] = buf[ch, keep0 + a] - (x0 + b * a)
        c[ch] += b


@njit(cache=True)
def second_difference(x2, x1, x0):
    """``x2 - 2 x1 + x0`` in this order (compiled without reassociation: the rounding of a difference
    of large phases is that of the plain formula, as in allantools)."""
    return (x2 - 2.0 * x1) + x0


@njit(cache=True, fastmath={"reassoc"})
def accumulate(buf, b0, last, m, next_i, sums):
    """Add to ``sums[j, ch]`` the squares of every term ``D_i(m_j) = x_{i+2m} - 2 x_{i+m} + x_i`` of
    channel ch whose three phases are in ``buf[ch]`` (phase index ``b0`` at column 0, ``last`` the last
    one known) and not yet counted (from ``next_i[j]``, advanced past the last one): one pass down
    each channel per factor, in partial sums of :data:`BLOCK` terms (reassociated into vector lanes:
    the rounding of a sum of positive terms only shrinks)."""
    for ch in range(buf.shape[0]):  # channel outer: a factor's newest windows are the next one's (cache)
        x = buf[ch]
        for j in range(m.size):
            mm = m[j]
            i0, i1 = next_i[j] - b0, last - 2 * mm - b0
            total = 0.0
            for a in range(i0, i1 + 1, BLOCK):
                e = min(a + BLOCK, i1 + 1)
                x0, x1, x2 = x[a:e], x[a + mm:e + mm], x[a + 2 * mm:e + 2 * mm]  # slices: no index wrap-around
                part = 0.0
                for t in range(e - a):
                    d = second_difference(x2[t], x1[t], x0[t])
                    part += d * d
                total += part
            sums[j, ch] += total
    for j in range(m.size):
        next_i[j] = max(next_i[j], last - 2 * m[j] + 1)


def segment_factors(m, n_seg: int, max_fraction: float = 0.1) -> np.ndarray:
    """The factors of ``m`` a static segment of ``n_seg`` samples is long enough for: up to
    ``max(2, n_seg max_fraction)``, the rule of :func:`octave_scales` for a whole record."""
    m = np.asarray(m)
    return m[m <= max(2.0, n_seg * max_fraction)]


def pooled(parts, m, dt: float) -> ScaleVariance:
    """The variances of several static segments of one record pooled at the factors ``m``: at each
    factor the squared terms of every segment that has it (:func:`segment_factors`), over their total
    number M (the terms that span a cut are not formed: the curve's M, its degrees of freedom, counts
    only those used).  ``parts``: each segment's :class:`ScaleVariance`; factors no segment has are left out."""
    m = np.asarray(m, dtype=float)
    k = parts[0].wv.shape[1]
    tot, M = np.zeros((m.size, k)), np.zeros(m.size)
    for p in parts:
        j = np.searchsorted(m, p.m)
        ok = (j < m.size) & (m[np.minimum(j, m.size - 1)] == p.m)
        tot[j[ok]] += p.wv[ok] * p.n_terms[ok, None]
        M[j[ok]] += p.n_terms[ok]
    has = M > 0
    return ScaleVariance(m[has], float(dt), int(sum(p.n for p in parts)), tot[has] / M[has, None], M[has])


def scale_variance(x, rate_hz: float, m=None, increments: bool = False, chunk: int = 1 << 18) -> ScaleVariance:
    """:class:`ScaleVariance` of the rows of ``x`` (an array or an HDF5 dataset, (N, k) or (N,)), streamed."""
    n = int(np.shape(x)[0])
    k = int(np.shape(x)[1]) if len(np.shape(x)) > 1 else 1
    acc = StreamingScaleVariance(n, rate_hz, k, m, increments=increments)
    for a in range(0, n, chunk):
        acc.update(np.asarray(x[a:min(n, a + chunk)], dtype=float))
    return acc.result()
