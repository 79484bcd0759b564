"""Allan deviation of IMU records (allantools) and the noise coefficients read off it.

For a white rate noise of density N (ARW for gyros, VRW for accelerometers) the
overlapping Allan deviation is ``sigma(tau) = N / sqrt(tau)``; bias instability B is read
at the flat bottom as ``sigma_min / sqrt(2 ln 2 / pi) = sigma_min / 0.664`` (IEEE Std 952).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.io.records import iter_window

BI_FACTOR = math.sqrt(2 * math.log(2) / math.pi)  # 0.664


@dataclass(frozen=True)
class AllanResult:
    """An Allan deviation: ``adev`` (n_tau, channels) at ``taus`` [s] in the rate unit of the input (SI) with
    its 1-sigma ``adev_err``, the white-noise coefficient ``white`` [unit sqrt(s)] (ARW or VRW), the bias
    instability [unit] and the tau of the curve's minimum [s].
    """
    taus: np.ndarray  # [s]
    adev: np.ndarray  # (n_tau, n_channels) in the rate unit of the input (SI)
    adev_err: np.ndarray
    white: np.ndarray  # (n_channels,) N coefficient [unit * sqrt(s)]
    bias_instability: np.ndarray  # (n_channels,) [unit]
    tau_bi: np.ndarray  # tau at the minimum [s]


def octave_taus(n: int, rate_hz: float, max_fraction: float = 0.1) -> np.ndarray:
    """Octave-spaced averaging times [s]: 1, 2, 4, ... samples up to ``max_fraction`` of the ``n`` samples."""
    m = 2 ** np.arange(0, int(math.log2(max(2, n * max_fraction))) + 1)
    return m / rate_hz


def allan(increments: np.ndarray, rate_hz: float, taus=None, white_tau_max: float = 1.0) -> AllanResult:
    """Overlapping Allan deviation of each column of ``increments`` (N, k) sampled at ``rate_hz``.

    Increments are converted to rates (``/ dt``).  The white-noise coefficient is the
    least-squares fit of ``sigma = N / sqrt(tau)`` over ``tau <= white_tau_max``.
    """
    import allantools  # here: it imports scipy (slow); the streamed path does not need it

    x = np.asarray(increments, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 16:
        raise ValueError(f"need at least 16 samples of shape (N, k), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("increments contain NaN or inf")
    rate = x * rate_hz
    taus = octave_taus(x.shape[0], rate_hz) if taus is None else np.asarray(taus, dtype=float)
    cols, errs, t_out = [], [], None
    for c in range(rate.shape[1]):
        t, ad, ade, _ = allantools.oadev(rate[:, c], rate=rate_hz, data_type="freq", taus=taus)
        t_out = t if t_out is None else t_out
        cols.append(ad)
        errs.append(ade)
    adev = np.stack(cols, axis=1)
    err = np.stack(errs, axis=1)
    return _result(t_out, adev, err, white_tau_max)


def _result(t_out, adev, err, white_tau_max) -> AllanResult:
    """The noise coefficients read off the deviations (shared by :func:`allan` and :class:`StreamingAllan`)."""
    sel = t_out <= white_tau_max
    if not sel.any():
        sel = np.zeros_like(t_out, dtype=bool)
        sel[0] = True
    with np.errstate(divide="ignore"):  # a noise-free channel: adev 0, white 0
        white = np.exp(np.mean(np.log(adev[sel]) + 0.5 * np.log(t_out[sel])[:, None], axis=0))
    imin = np.argmin(adev, axis=0)
    return AllanResult(t_out, adev, err, white, adev[imin, np.arange(adev.shape[1])] / BI_FACTOR, t_out[imin])


class StreamingAllan:
    """The overlapping Allan deviation of :func:`allan` (octave taus, same estimator as
    ``allantools.oadev``) from increments fed chunk by chunk, in bounded memory.

    The phase ``x_j = sum_{i<j} (inc_i - c)`` (rad or m/s; ``c`` is the mean increment of the first
    chunk, which only helps rounding) is kept for the last ``2 m_max`` samples (``m_max <= n / 10``),
    and the squared second differences ``(x_{i+2m} - 2 x_{i+m} + x_i)^2`` of every octave ``m`` are
    summed as soon as their three phases are known: the exact sums, not an approximation.
    Memory: about ``2.5 m_max`` rows of ``k`` floats (0.25 n), instead of the whole record.

    ``n`` is the number of increments that will be fed (it fixes the tau grid, as in :func:`allan`).
    """

    def __init__(self, n: int, rate_hz: float, k: int = 3, piece: int = 1 << 18):
        if n < 16:
            raise ValueError(f"need at least 16 samples, got {n}")
        self.n, self.rate_hz, self.k = int(n), float(rate_hz), int(k)
        taus = octave_taus(self.n, self.rate_hz)
        m = np.unique(np.round(taus * self.rate_hz))
        m = m[(m > 0) & (m < self.n + 1)].astype(np.int64)  # allantools: m < len(phase)
        self.m = m
        self.taus = m / self.rate_hz
        m_max = int(m.max())
        self.piece = int(max(1024, min(piece, self.n)))
        self.slack = max(self.piece, m_max // 2)  # rows appended between two shifts of the history
        self.cap = 2 * m_max + 1 + self.slack
        self.buf = np.empty((min(self.cap, self.n + 1), self.k))
        self.buf[0] = 0.0
        self.b0 = 0  # global phase index of buf[0]
        self.fill = 1  # rows of buf in use: phases b0 .. b0 + fill - 1
        self.next_i = np.zeros(m.size, dtype=np.int64)  # next term index of each m
        self.sums = np.zeros((m.size, self.k))
        self.fed = 0
        self.c = None

    def update(self, increments) -> None:
        """Feed the next chunk of increments ((N, channels), or (N,) for one); more than the announced
        count, a wrong shape or a NaN/inf is a ValueError.
        """
        x = np.asarray(increments, dtype=float)
        if x.ndim == 1:
            x = x[:, None]
        if x.ndim != 2 or x.shape[1] != self.k:
            raise ValueError(f"increments of shape (N, {self.k}) expected, got {x.shape}")
        if self.fed + x.shape[0] > self.n:
            raise ValueError(f"more than the announced {self.n} increments")
        if not np.all(np.isfinite(x)):
            raise ValueError("increments contain NaN or inf")
        if self.c is None and x.shape[0]:
            self.c = x.mean(axis=0)
        for a in range(0, x.shape[0], self.piece):
            self._feed(x[a:a + self.piece])

    def _feed(self, x) -> None:
        L = x.shape[0]
        if self.fill + L > self.buf.shape[0]:  # drop the phases no term needs any more
            keep0 = int(min(self.next_i.min(), self.b0 + self.fill - 1)) - self.b0
            rows = self.fill - keep0
            if keep0 > 0:
                step = min(keep0, 1 << 16)  # blocks that do not overlap: no temporary copy of the history
                for a in range(0, rows, step):
                    self.buf[a: min(rows, a + step)] = self.buf[keep0 + a: keep0 + min(rows, a + step)]
            self.b0 += keep0
            self.fill -= keep0
            if self.fill + L > self.buf.shape[0]:  # first shift of a buffer sized for a short record
                self.buf = np.concatenate([self.buf[: self.fill], np.empty((L, self.k))])
        ph = self.buf[self.fill - 1: self.fill + L]
        ph[1:] = x - self.c
        np.cumsum(ph, axis=0, out=ph)  # the running phase, carried from the last row
        self.fill += L
        self.fed += L
        J = self.b0 + self.fill - 1  # the last phase index known
        for j, m in enumerate(self.m):
            i0, i1 = int(self.next_i[j]), J - 2 * int(m)  # terms i0 .. i1
            if i1 < i0:
                continue
            l0, cnt = i0 - self.b0, i1 - i0 + 1
            b = self.buf
            d = b[l0 + 2 * m: l0 + 2 * m + cnt] - 2.0 * b[l0 + m: l0 + m + cnt] + b[l0: l0 + cnt]
            self.sums[j] += np.einsum("ij,ij->j", d, d)
            self.next_i[j] = i1 + 1

    def result(self, white_tau_max: float = 1.0) -> AllanResult:
        """The Allan deviation of everything fed (exactly the announced count): the octave taus with more
        than one term, as allantools keeps them; ``white_tau_max`` as :func:`allan`.
        """
        if self.fed != self.n:
            raise ValueError(f"fed {self.fed} of the announced {self.n} increments")
        nterm = (self.n + 1 - 2 * self.m).astype(float)
        ok = nterm > 1  # allantools drops the taus with a single term
        nterm = np.maximum(nterm, 1.0)
        adev = np.sqrt(self.sums / (2.0 * nterm[:, None])) / (self.m[:, None] / self.rate_hz)
        err = adev / np.sqrt(nterm)[:, None]
        return _result(self.taus[ok], adev[ok], err[ok], white_tau_max)


def first_dwell(gimbal, n: int, chunk: int = 1 << 18, tol: float = 1e-9) -> int:
    """Length of the static start of a record: the index of the first step where a gimbal angle
    changes by ``tol`` rad or more (``n - 1`` when it never does; ``n - 1`` without gimbal), read
    chunk by chunk from an array or a dataset."""
    if gimbal is None:
        return n - 1
    prev = None
    for a in range(0, n, chunk):
        g = np.asarray(gimbal[a:min(n, a + chunk)], dtype=float)
        gg = g if prev is None else np.concatenate([prev, g])
        moving = ~np.all(np.abs(np.diff(gg, axis=0)) < tol, axis=1)
        if moving.any():
            return int(np.argmax(moving)) + (a - 1 if prev is not None else 0)
        prev = g[-1:]
    return n - 1


def allan_of(increments, stop: int, rate_hz: float, chunk: int = 1 << 18, **kw) -> AllanResult:
    """:func:`allan` of ``increments[:stop]`` (an array or a dataset), streamed in chunks
    (:class:`StreamingAllan`): the same result in bounded memory."""
    acc = StreamingAllan(stop, rate_hz, k=int(np.shape(increments)[1]) if len(np.shape(increments)) > 1 else 1)
    for a in range(0, stop, chunk):
        acc.update(np.asarray(increments[a:min(stop, a + chunk)], dtype=float))
    return acc.result(**kw)


#: Earth rotation rate [rad/s] (WGS84; inscal.core.earth.OMEGA_IE, not imported: it loads numba)
OMEGA_IE = 7.292115e-5


def motion_warning(rec, sel) -> str | None:
    """One line when the window ``sel`` of ``rec`` is not static: the gyro rate (block means of
    about 1 s) departs from its median by more than 10x the Earth rate (and 6x its noise) in more
    than 1 % of the window, or the gimbal angles change by more than 1 mrad."""
    mot = MotionStats(int(sel.sum()), rec.rate_hz)
    mot.update(np.asarray(rec.dtheta[sel], dtype=float),
               None if getattr(rec, "gimbal", None) is None else np.asarray(rec.gimbal[sel], dtype=float))
    return mot.warning()


class MotionStats:
    """What :func:`motion_warning` needs, gathered chunk by chunk: the gyro increments summed over
    blocks of about 1 s (at least 20 blocks) and the span of the gimbal angles."""

    def __init__(self, n: int, rate_hz: float):
        self.rate_hz = rate_hz
        self.m = max(1, min(n // 20, int(round(rate_hz))))  # ~1 s blocks (at least 20 of them)
        self.k = n // self.m
        self.sums = np.empty((self.k, 3))
        self.nb = 0
        self.rest = np.zeros((0, 3))
        self.gmin = self.gmax = None

    def update(self, dtheta, gimbal=None) -> None:
        """Feed the next chunk of angle increments (and gimbal angles, when the record has them)."""
        if self.nb < self.k:
            x = np.concatenate([self.rest, dtheta]) if self.rest.shape[0] else dtheta
            nfull = min(x.shape[0] // self.m, self.k - self.nb)
            take = nfull * self.m
            self.sums[self.nb: self.nb + nfull] = x[:take].reshape(nfull, self.m, 3).sum(axis=1)
            self.nb += nfull
            self.rest = x[take:] if self.nb < self.k else np.zeros((0, 3))
        if gimbal is not None and gimbal.shape[0]:
            lo, hi = gimbal.min(axis=0), gimbal.max(axis=0)
            self.gmin = lo if self.gmin is None else np.minimum(self.gmin, lo)
            self.gmax = hi if self.gmax is None else np.maximum(self.gmax, hi)

    def warning(self) -> str | None:
        """One line when the window is not static (the gyro rate departs from its median by more than the
        threshold in over 1 % of it, or the gimbal angles move), else None.
        """
        k, m = self.k, self.m
        rates = self.sums[: self.nb] * self.rate_hz / m
        dev = rates - np.median(rates, axis=0)  # a gyro bias is not motion
        d = np.diff(rates, axis=0)  # noise from successive differences: robust to the turns themselves
        sig = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2) if k > 2 else np.zeros(3)
        thr = max(10 * OMEGA_IE, 6 * float(np.sqrt(np.sum(sig**2))))
        frac = float(np.mean(np.linalg.norm(dev, axis=1) > thr)) if k else 0.0
        moving = frac > 0.01
        why = f"the gyro rate departs from its median by more than {thr:.2g} rad/s in {100 * frac:.0f} % of it"
        if not moving and self.gmin is not None:
            span = float(np.max(self.gmax - self.gmin))
            if span > 1e-3:
                moving, why = True, f"the gimbal turns by {np.degrees(span):.3g} deg in it"
        if not moving:
            return None
        return (f"the window is not static ({why}): the Allan deviation mixes rotation into the noise; "
                "use --start/--stop on a static part of the record")


def stream_allan(data: Path, win, chunk_size: int = 1 << 18):
    """Gyro and accelerometer Allan deviations of the window ``win`` (:func:`inscal.io.record_window`)
    and its motion statistics, streamed in chunks: two passes (gyro with /time and /gimbal, then
    accelerometers), so memory holds about a quarter of one sensor's window, never the record.
    Returns ``(gyro AllanResult, accel AllanResult, MotionStats, (t_first, t_last))``."""
    n = win.n
    acc, mot = StreamingAllan(n, win.rate_hz), MotionStats(n, win.rate_hz)
    t_first = t_last = None
    for t, dth, g in iter_window(data, ("time", "dtheta", "gimbal"), win.i0, win.i1, chunk_size):
        t_first = float(t[0]) if t_first is None else t_first
        t_last = float(t[-1])
        acc.update(dth)
        mot.update(dth, g)
    gyro = acc.result()
    acc = None  # one phase history at a time
    acc = StreamingAllan(n, win.rate_hz)
    for (dv,) in iter_window(data, ("dvel",), win.i0, win.i1, chunk_size):
        acc.update(dv)
    return gyro, acc.result(), mot, (t_first, t_last)
