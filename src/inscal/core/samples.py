"""A record's samples: the time (n,) and two per-axis arrays (n, 3) taken in as float arrays, their
shapes checked once for every reader (a logger's samples, a record handed to the still-pose detector); the
number of samples and the length of a record type (:class:`SampleSpan`)."""

from __future__ import annotations

import numpy as np


def triad_series(time, first, second, error: type[Exception], message: str):
    """``time``, ``first`` and ``second`` as float arrays shaped (n,), (n, 3), (n, 3); other shapes raise
    ``error(message.format(*shapes))`` (the caller's error and words, the three shapes filled in)."""
    t, a, b = (np.asarray(x, float) for x in (time, first, second))
    n = t.shape[0]
    if t.ndim != 1 or a.shape != (n, 3) or b.shape != (n, 3):
        raise error(message.format(t.shape, a.shape, b.shape))
    return t, a, b


class SampleSpan:
    """The size of a record's samples, for the record types (a mixin: the class has ``time`` (n,) [s] and
    ``rate_hz``)."""

    @property
    def n_samples(self) -> int:
        """The number of samples N."""
        return int(self.time.shape[0])

    @property
    def duration(self) -> float:
        """The record's length N / rate [s]."""
        return float(self.n_samples / self.rate_hz)
