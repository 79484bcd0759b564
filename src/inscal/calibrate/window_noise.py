"""The sigma of window means widened for the bias drift of an identified noise model (``--noise noise.toml`` with
the window methods: ``n25``, ``six-position``, ``twelve-position``, ``joint``).

A window's mean carries, besides its white noise (estimated from the window itself, :mod:`.windows`), the slow
part of the bias: Gauss-Markov (GM), bias-instability (BI, flicker), rate-random-walk (RW) and ramp (DR) terms.
The constant bias is a parameter, so what enters the fit is how far a window's mean bias lies from its
neighbours'.  For two adjacent windows of ``m`` samples, ``E[(ybar_b - ybar_a)^2] / 2`` is by definition the
Allan variance at ``m`` (IEEE 952 eq. C.8); each window's variance is widened by the Allan variance of the
model's slow terms at ``m = max(window length, spacing to the nearest other window's centre)`` (in samples),
with each term's exact discrete-time Allan variance (:mod:`inscal.core.noise_models`)::

    sigma_widened^2 = sigma_white^2 + sum_{terms not WN, QN} AVAR_term(m, dt)

A window far from every other one (a long spacing) gets the bias wander over that spacing; the white (WN) and
quantization (QN) terms are left to the window's own estimate.  This treats the windows' drifts as independent,
an approximation: neighbouring windows' drifts are correlated (they share the wander between them).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from inscal.calibrate.windows import CalibrationError
from inscal.core.noise_models import NoiseModel, Quantization, WhiteNoise

#: the channel names of a six-axis noise model: gyros, then accelerometers
CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")


def slow_terms(model: NoiseModel) -> list[tuple]:
    """The slow (not white, not quantization) terms of each of the six channels, in :data:`CHANNELS` order."""
    out = []
    for name in CHANNELS:
        try:
            ch = model.channel(name)
        except KeyError as exc:
            raise CalibrationError(f"noise model: {exc.args[0]}; the window methods need channels "
                                   f"{', '.join(CHANNELS)}") from None
        out.append(tuple(t for t in ch.terms if not isinstance(t, (WhiteNoise, Quantization))))
    return out


def drift_variance(terms, m: float, dt: float) -> float:
    """The summed exact Allan variance of ``terms`` at ``m`` samples of ``dt`` seconds (SI rate units squared)."""
    return float(sum(float(t.avar(np.array([float(m)]), dt)[0]) for t in terms))


def widened(windows, model: NoiseModel, rate_hz: float) -> tuple[list, list[dict]]:
    """The windows (any frozen dataclasses with ``i0``, ``i1``, ``gyro_sigma``, ``accel_sigma``) with their sigma
    widened (module docstring), and per window the added std [SI] and the ``m`` it used."""
    dt = 1.0 / float(rate_hz)
    slow = slow_terms(model)
    centres = np.array([0.5 * (w.i0 + w.i1) for w in windows], float)
    out, info = [], []
    for k, w in enumerate(windows):
        n = max(int(w.i1 - w.i0), 1)
        others = np.abs(np.delete(centres, k) - centres[k])
        m = max(float(n), float(np.min(others)) if others.size else float(n))
        add = np.sqrt([drift_variance(slow[c], m, dt) for c in range(6)])
        gs = np.sqrt(np.asarray(w.gyro_sigma, float) ** 2 + add[:3] ** 2)
        fs = np.sqrt(np.asarray(w.accel_sigma, float) ** 2 + add[3:] ** 2)
        out.append(dataclasses.replace(w, gyro_sigma=gs, accel_sigma=fs))
        info.append({"m": m, "gyro_add": add[:3], "accel_add": add[3:]})
    return out, info
