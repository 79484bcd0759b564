"""The bound's noise from an identified noise model (``inscal observability --crlb --noise noise.toml``): the white
terms (WN) as the gyro and accelerometer white noise, the Gauss-Markov (GM) and rate-random-walk (RW) terms as the
bias process noise of :class:`inscal.plan.rows.BiasNoise` (per axis; one correlation time per sensor, as the
bound's model has).  The systematic filter reads the same model (:mod:`inscal.calibrate.systematic.gm_states`)."""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.systematic.gm_states import ACCEL_NAMES, GYRO_NAMES, white_noise
from inscal.core.noise_models import GaussMarkov, NoiseModel, RandomWalk
from inscal.plan.rows import BiasNoise, BoundError


def bound_noise(model: NoiseModel) -> tuple[np.ndarray, np.ndarray, BiasNoise | None, list[str]]:
    """``(arw, vrw, bias_noise, left_out)`` of ``model`` (SI): the white noise per axis, the bias process noise
    (None when the model has no GM or RW term) and the terms the bound does not carry (``["gx: BI", ...]``).
    Several GM terms of a sensor need one correlation time (BoundError, one line, otherwise); the GM sigma of an
    axis is the root sum of squares of its GM terms'."""
    arw, vrw = white_noise(model)
    kw: dict = {}
    left: list[str] = []
    for sensor, names in (("gyro", GYRO_NAMES), ("accel", ACCEL_NAMES)):
        gm, rw, taus = np.zeros(3), np.zeros(3), set()
        for i, name in enumerate(names):
            ch = model.channel(name)
            for t in ch.terms:
                if isinstance(t, GaussMarkov) and t.sigma > 0:
                    gm[i] = math.hypot(gm[i], t.sigma)
                    taus.add(round(t.tc, 6))
                elif isinstance(t, RandomWalk):
                    rw[i] = math.hypot(rw[i], t.k)
                elif t.code not in ("WN", "QN"):
                    left.append(f"{name}: {t.code}")
        if len(taus) > 1:
            raise BoundError(f"noise model: the {sensor} Gauss-Markov terms have correlation times "
                             f"{', '.join(f'{x:g}' for x in sorted(taus))} s; the bound takes one per sensor")
        kw[f"{sensor}_gm"], kw[f"{sensor}_rw"] = gm, rw
        if taus:
            kw[f"{sensor}_tau"] = float(taus.pop())
    if not any(np.any(v) for k, v in kw.items() if not k.endswith("tau")):
        return arw, vrw, None, left
    return arw, vrw, BiasNoise(**kw), left
