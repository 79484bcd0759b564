"""Allan deviation of IMU records (allantools) and the noise coefficients read off it.

For a white rate noise of density N (ARW for gyros, VRW for accelerometers) the
overlapping Allan deviation is ``sigma(tau) = N / sqrt(tau)``; bias instability B is read
at the flat bottom as ``sigma_min / sqrt(2 ln 2 / pi) = sigma_min / 0.664`` (IEEE Std 952).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import allantools
import numpy as np

BI_FACTOR = math.sqrt(2 * math.log(2) / math.pi)  # 0.664


@dataclass(frozen=True)
class AllanResult:
    taus: np.ndarray  # [s]
    adev: np.ndarray  # (n_tau, n_channels) in the rate unit of the input (SI)
    adev_err: np.ndarray
    white: np.ndarray  # (n_channels,) N coefficient [unit * sqrt(s)]
    bias_instability: np.ndarray  # (n_channels,) [unit]
    tau_bi: np.ndarray  # tau at the minimum [s]


def octave_taus(n: int, rate_hz: float, max_fraction: float = 0.1) -> np.ndarray:
    m = 2 ** np.arange(0, int(math.log2(max(2, n * max_fraction))) + 1)
    return m / rate_hz


def allan(increments: np.ndarray, rate_hz: float, taus=None, white_tau_max: float = 1.0) -> AllanResult:
    """Overlapping Allan deviation of each column of ``increments`` (N, k) sampled at ``rate_hz``.

    Increments are converted to rates (``/ dt``).  The white-noise coefficient is the
    least-squares fit of ``sigma = N / sqrt(tau)`` over ``tau <= white_tau_max``.
    """
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
    sel = t_out <= white_tau_max
    if not sel.any():
        sel = np.zeros_like(t_out, dtype=bool)
        sel[0] = True
    white = np.exp(np.mean(np.log(adev[sel]) + 0.5 * np.log(t_out[sel])[:, None], axis=0))
    imin = np.argmin(adev, axis=0)
    return AllanResult(t_out, adev, err, white, adev[imin, np.arange(adev.shape[1])] / BI_FACTOR, t_out[imin])
