"""Streams of IMU increments for the navigator: records in chunks, and their compensation by a
parameter set on the fly."""

from __future__ import annotations

from typing import Iterable, Iterator

import numpy as np

from inscal.core.error_model import ImuErrors


# =============================================================================== streams
class SampleStream:
    """Consumes an iterable of ``(time, dtheta, dvel, gimbal)`` chunks; ``take(n)`` returns the
    next n samples (concatenated), ``chunks()`` the rest, chunk by chunk."""

    def __init__(self, chunks: Iterable):
        self._it = iter(chunks)
        self._pending = None

    def _next(self):
        if self._pending is not None:
            p, self._pending = self._pending, None
            return p
        c = next(self._it)
        if hasattr(c, "dtheta"):  # simulate.Chunk
            c = (c.time, c.dtheta, c.dvel, c.gimbal)
        return c

    def peek(self):
        """The next chunk without consuming it (None at the end)."""
        if self._pending is None:
            try:
                self._pending = self._next()
            except StopIteration:
                return None
        return self._pending

    def take(self, n: int):
        parts, have = [], 0
        while have < n:
            try:
                t, dth, dv, g = self._next()
            except StopIteration:
                break
            need = n - have
            if t.shape[0] > need:
                self._pending = (t[need:], dth[need:], dv[need:], None if g is None else g[need:])
                t, dth, dv, g = t[:need], dth[:need], dv[:need], None if g is None else g[:need]
            parts.append((t, dth, dv, g))
            have += t.shape[0]
        if not parts:
            return None
        g = None if any(p[3] is None for p in parts) else np.concatenate([p[3] for p in parts])
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]), g)

    def chunks(self) -> Iterator:
        while True:
            try:
                yield self._next()
            except StopIteration:
                return


def chunks_of(data, chunk_size: int = 1 << 19) -> Iterator:
    """Chunk tuples from an in-memory record (SimData or io.Record: .time .dtheta .dvel .gimbal)."""
    n = data.time.shape[0]
    for k in range(0, n, chunk_size):
        sl = slice(k, k + chunk_size)
        yield data.time[sl], data.dtheta[sl], data.dvel[sl], None if data.gimbal is None else data.gimbal[sl]


def compensated_chunks(chunks, params: ImuErrors, dt: float):
    """``(t, dtheta, dvel, gimbal)`` chunks compensated with ``params`` (one chunk of look-ahead)."""
    prev = None
    it = iter(chunks)
    cur = next(it, None)
    while cur is not None:
        nxt = next(it, None)
        t, dth, dv, g = cur
        after = (nxt[1][0], nxt[2][0]) if nxt is not None and len(nxt[1]) else None
        cdth, cdv = params.compensate_increments(dt, dth, dv, prev=prev, next=after)
        if len(dth):
            prev = (dth[-1], dv[-1])
        yield t, cdth, cdv, g
        cur = nxt
