"""Allan deviation of IMU records (a face of the noise engine, inscal.analysis.noise) and the noise
coefficients read off it.

For a white rate noise of density N (ARW for gyros, VRW for accelerometers) the
overlapping Allan deviation is ``sigma(tau) = N / sqrt(tau)``; bias instability B is read
at the flat bottom as ``sigma_min / sqrt(2 ln 2 / pi) = sigma_min / 0.664`` (IEEE Std 952).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.analysis.noise.estimators import StreamingScaleVariance
from inscal.analysis.noise.motion import MotionStats
from inscal.io.streaming import iter_window

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
    """Overlapping Allan deviation of each column of ``increments``, by the noise engine.

    The engine is :class:`StreamingAllan` (the estimator of ``allantools.oadev``, which stays a test
    oracle).  Increments are converted to rates (``/ dt``).  The white-noise coefficient is the
    least-squares fit of ``sigma = N / sqrt(tau)`` over ``tau <= white_tau_max`` (a quick look; the
    identified ARW with its interval is :func:`inscal.analysis.noise.identify.allan_view`'s).

    Parameters
    ----------
    increments : numpy.ndarray
        (N, k) angle [rad] or velocity [m/s] increments.
    rate_hz : float
        The sample rate [Hz].
    taus : array_like, optional
        Averaging times [s] (whole multiples of the sample interval; default the octaves).
    white_tau_max : float
        The longest averaging time of the white-noise fit [s].

    Returns
    -------
    AllanResult
        ``taus``, ``adev`` and ``adev_err`` per column, ``white`` (the coefficient N), the bias
        instability and its averaging time.

    Raises
    ------
    ValueError
        Increments that are not (N, k), too few samples, or averaging times off the sample grid.

    Examples
    --------
    White angle noise of ARW ``N`` has ``sigma(tau) = N / sqrt(tau)``:

    >>> import numpy as np
    >>> from inscal.analysis.allan import allan
    >>> N, rate = 1e-5, 100.0  # rad/sqrt(s), Hz
    >>> dtheta = np.random.default_rng(0).normal(0.0, N * np.sqrt(1.0 / rate), (20000, 1))
    >>> res = allan(dtheta, rate)
    >>> round(float(res.white[0]) / N, 2)
    1.0
    """
    x = np.asarray(increments, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] < 16:
        raise ValueError(f"need at least 16 samples of shape (N, k), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("increments contain NaN or inf")
    acc = StreamingAllan(x.shape[0], rate_hz, x.shape[1], taus=taus)
    acc.update(x)
    return acc.result(white_tau_max)


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
    ``allantools.oadev``) from increments fed chunk by chunk, in bounded memory: a face over the one
    engine, :class:`inscal.analysis.noise.estimators.StreamingScaleVariance` (the Allan variance is
    twice the Haar wavelet variance it sums).

    ``n`` is the number of increments that will be fed (it fixes the tau grid, as in :func:`allan`).
    """

    def __init__(self, n: int, rate_hz: float, k: int = 3, piece: int = 1 << 18, taus=None):
        if n < 16:
            raise ValueError(f"need at least 16 samples, got {n}")
        taus = octave_taus(int(n), float(rate_hz)) if taus is None else np.asarray(taus, dtype=float)
        m = np.unique(np.round(taus * rate_hz))
        self.engine = StreamingScaleVariance(n, rate_hz, k, m, piece=piece, increments=True)
        self.n, self.rate_hz, self.k = self.engine.n, self.engine.rate_hz, self.engine.k

    def update(self, increments) -> None:
        """Feed the next chunk of increments ((N, channels), or (N,) for one); more than the announced
        count, a wrong shape or a NaN/inf is a ValueError.
        """
        self.engine.update(increments)

    def result(self, white_tau_max: float = 1.0) -> AllanResult:
        """The :class:`AllanResult` of the fed increments (all ``n`` of them): the octave taus with at
        least two terms, each deviation's 1-sigma ``adev / sqrt(terms)``, the white-noise coefficient read
        at taus up to ``white_tau_max`` [s]."""
        sv = self.engine.result()
        ok = sv.n_terms > 1  # allantools drops the taus with a single term
        adev = sv.adev[ok]
        err = adev / np.sqrt(sv.n_terms[ok])[:, None]
        return _result(sv.taus[ok], adev, err, white_tau_max)


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


def motion_warning(rec, sel) -> str | None:
    """One line when the window ``sel`` of ``rec`` is not static
    (:meth:`inscal.analysis.noise.motion.MotionStats.warning`), else None."""
    mot = MotionStats(int(sel.sum()), rec.rate_hz)
    mot.update(np.asarray(rec.dtheta[sel], dtype=float),
               None if getattr(rec, "gimbal", None) is None else np.asarray(rec.gimbal[sel], dtype=float))
    return mot.warning()


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
