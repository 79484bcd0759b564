"""Is a window static?  Motion, bias steps and stuck stretches, found at the resolution that matters
(a turn of a few seconds in hours of record), gathered chunk by chunk in the noise engine's pass.

Every channel's increments are summed over blocks of about 1 s.  Two checks run on them:

* the gyro rate (block means) departs from its median by more than ``max(10 Omega_ie, 6 sigma)``
  in more than 1 % of the window (sigma the block noise from successive differences, robust to the
  turns themselves): a window that turns for long;
* an event: for widths of w = 1, 2, 4, .. 64 blocks, the difference of two adjacent w-block sums
  ``D_i`` (an Allan-variance term at tau = w blocks) against the channel's own scatter of them,
  ``z_i = D_i^2 / (median(D^2) / 0.4549)`` (0.4549 the median of chi^2_1: under stationary Gaussian
  noise z_i ~ chi^2_1 whatever the noise's spectrum, since the median adapts per channel and width).
  A ``z`` beyond :data:`Z_EVENT` (7 sigma: a false alarm below 1e-11 per test, under 1e-4 over a
  day's 10^6 tests) and the largest within w of it marks the block after the boundary of its two
  halves (an edge, to a block) unless a narrower width found an edge within 2w; a turn, a tilt, a bias step or a shock shows so, however
  short against the record (a 9-s turn in 10^4 s: z ~ 10^8).

Channels stuck in a stretch (the same increment repeated far longer than the channel's share of
equal successive increments makes plausible: a saturated or frozen output) are found by
:class:`inscal.analysis.noise.identify.ChannelChecks`.  A window with an event is refused with the
times (``inscal noise``) or warned of (``inscal allan``), never fitted silently.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d

#: Earth rotation rate [rad/s] (WGS84; inscal.core.earth.OMEGA_IE, not imported: it loads numba)
OMEGA_IE = 7.292115e-5
#: an event: an Allan term beyond this many (robust) standard deviations of its width's scatter
Z_EVENT = 7.0
#: the widest pair of block sums compared, in blocks (about a minute)
MAX_WIDTH = 64
#: marked blocks closer than this are one event (the two edges of a turn)
MERGE = 2 * MAX_WIDTH
#: the median of chi^2 with one degree of freedom
CHI2_1_MEDIAN = 0.454936423119572


class MotionStats:
    """What :meth:`warning` and :meth:`events` need, gathered chunk by chunk: every channel's increments
    summed over blocks of about 1 s (at least 20 blocks) and the span of the gimbal angles.  The first
    three channels are the gyros' (rad)."""

    def __init__(self, n: int, rate_hz: float, k: int = 3):
        self.rate_hz = rate_hz
        self.n_total = int(n)
        self.m = max(1, min(n // 20, int(round(rate_hz))))  # ~1 s blocks (at least 20 of them)
        self.k = n // self.m
        self.nch = int(k)
        self.sums = np.empty((self.k, self.nch))
        self.nb = 0
        self.rest = np.zeros((0, self.nch))
        self.gmin = self.gmax = None

    def update(self, x, gimbal=None) -> None:
        """Feed the next chunk of increments, (N, k) with the gyros' first (and gimbal angles, when the
        record has them)."""
        x = np.asarray(x, dtype=float)
        if self.nb < self.k:
            xx = np.concatenate([self.rest, x]) if self.rest.shape[0] else x
            nfull = min(xx.shape[0] // self.m, self.k - self.nb)
            take = nfull * self.m
            self.sums[self.nb: self.nb + nfull] = xx[:take].reshape(nfull, self.m, self.nch).sum(axis=1)
            self.nb += nfull
            self.rest = xx[take:] if self.nb < self.k else np.zeros((0, self.nch))
        if gimbal is not None and gimbal.shape[0]:
            lo, hi = gimbal.min(axis=0), gimbal.max(axis=0)
            self.gmin = lo if self.gmin is None else np.minimum(self.gmin, lo)
            self.gmax = hi if self.gmax is None else np.maximum(self.gmax, hi)

    def _moving(self):
        """(per-block moving mask of the gyro rate against its median, threshold [rad/s])."""
        k, m = self.k, self.m
        rates = self.sums[: self.nb, :3] * self.rate_hz / m
        dev = rates - np.median(rates, axis=0)  # a gyro bias is not motion
        d = np.diff(rates, axis=0)  # noise from successive differences: robust to the turns themselves
        sig = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2) if k > 2 else np.zeros(3)
        thr = max(10 * OMEGA_IE, 6 * float(np.sqrt(np.sum(sig**2))))
        return np.linalg.norm(dev, axis=1) > thr, thr

    def event_mask(self) -> tuple[np.ndarray, np.ndarray]:
        """``(mask, zmax)``: the blocks inside an event (module docstring) and per channel the largest
        z in sigma units (sqrt of the largest z over every width)."""
        s = self.sums[: self.nb]
        nb = s.shape[0]
        mask = np.zeros(nb, dtype=bool)
        zmax = np.zeros(self.nch)
        c = np.concatenate([np.zeros((1, self.nch)), np.cumsum(s, axis=0)])
        w = 1
        while 2 * w <= nb // 4 and w <= MAX_WIDTH:
            d = c[2 * w:] - 2 * c[w:-w] + c[: -2 * w]  # sum of the later w blocks less the earlier w
            scale = np.median(d * d, axis=0) / CHI2_1_MEDIAN
            # a channel without scatter beyond the rounding of its sums (stuck, noise-free) has no events
            ok = np.sqrt(scale) > 1e-9 * w * np.median(np.abs(s), axis=0)
            z = np.zeros_like(d)
            z[:, ok] = d[:, ok] ** 2 / scale[ok]
            zmax = np.maximum(zmax, np.sqrt(z.max(axis=0)) if z.size else 0.0)
            zz = z.max(axis=1) if z.size else np.zeros(0)
            # an edge e makes |D_i| a triangle over i peaking at i + w = e: the local maxima are the edges
            hit = (zz > Z_EVENT**2) & (zz >= maximum_filter1d(zz, 2 * w + 1, mode="nearest"))
            if hit.any():  # each marks the block after the boundary of its halves (the edge, to a block),
                e = np.minimum(np.flatnonzero(hit) + w, nb - 1)  # unless a narrower width found one within 2w
                cum = np.concatenate([[0], np.cumsum(mask)])
                near = cum[np.minimum(e + 2 * w + 1, nb)] - cum[np.maximum(e - 2 * w, 0)]
                mask[e[near == 0]] = True
            w *= 2
        return mask, zmax

    def events(self, t0: float = 0.0, names=None, limit: int = 4) -> list[str]:
        """The stretches inside an event, ``'a-b s'`` from ``t0`` [s] (seconds of the window + t0),
        merged, at most ``limit`` of them and a count of the rest; the channel of the largest z is named."""
        mask, zmax = self.event_mask()
        if not mask.any():
            return []
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
        spans = []
        for a, b in zip(edges[::2], edges[1::2]):  # edges closer than MERGE blocks: one event
            if spans and a - spans[-1][1] < MERGE:
                spans[-1] = (spans[-1][0], b)
            else:
                spans.append((a, b))
        blk = self.m / self.rate_hz
        out = [f"{t0 + a * blk:.6g}-{t0 + b * blk:.6g} s" for a, b in spans[:limit]]
        if len(spans) > limit:
            out.append(f"and {len(spans) - limit} more")
        if names is not None:
            c = int(np.argmax(zmax))
            out[0] += f" ({names[c]} {zmax[c]:.3g} sigma)"
        return out

    def moving_spans(self, margin_s: float = 0.0) -> list[tuple[int, int]]:
        """The stretches that move or lie in an event as ``(first, end)`` sample indices of the window
        (``end`` one past the last), each widened by ``margin_s`` [s] on both sides and merged where
        they overlap (a turn's edges and the blocks between them, where its rate passes the
        threshold, are one stretch); empty when the window is static."""
        mask = self._moving()[0] | self.event_mask()[0]
        if not mask.any():
            return []
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
        pad = int(np.ceil(margin_s * self.rate_hz / self.m))
        spans = []
        for a, b in zip(edges[::2], edges[1::2]):
            a, b = max(a - pad, 0), min(b + pad, self.nb)
            if spans and a <= spans[-1][1]:
                spans[-1] = (spans[-1][0], b)
            else:
                spans.append((a, b))
        return [(a * self.m, b * self.m if b < self.nb else self.n_total) for a, b in spans]

    def moving_span(self) -> tuple[float, float] | None:
        """Seconds from the window's start of the first and the end of the last block that moves or
        lies in an event (None when none does)."""
        mask = self._moving()[0] | self.event_mask()[0]
        if not mask.any():
            return None
        idx = np.flatnonzero(mask)
        return float(idx[0] * self.m / self.rate_hz), float((idx[-1] + 1) * self.m / self.rate_hz)

    def warning(self, t0: float = 0.0, names=None) -> str | None:
        """One line when the window is not static (:meth:`reason`), else None."""
        why = self.reason(t0, names)
        if why is None:
            return None
        return (f"the window is not static ({why}): the Allan deviation mixes rotation into the noise; "
                "use --start/--stop on a static part of the record")

    def reason(self, t0: float = 0.0, names=None) -> str | None:
        """Why the window is not static, or None: the gyro rate departs from its median by more than the
        threshold in over 1 % of it, an event (module docstring: its times from ``t0`` [s], the channel
        of ``names`` that shows it most), or the gimbal angles move."""
        mask, thr = self._moving()
        frac = float(np.mean(mask)) if self.k else 0.0
        why = None
        if frac > 0.01:
            ev = self.events(t0, names)
            why = (f"the gyro rate departs from its median by more than {thr:.2g} rad/s in {100 * frac:.0f} % of it"
                   + (f"; edges at {', '.join(ev)}" if ev else ""))
        if why is None:
            ev = self.events(t0, names)
            if ev:
                why = (f"a turn, step or shock beyond {Z_EVENT:g} sigma of the record's own scatter at "
                       + ", ".join(ev))
        if why is None and self.gmin is not None:
            span = float(np.max(self.gmax - self.gmin))
            if span > 1e-3:
                why = f"the gimbal turns by {np.degrees(span):.3g} deg in it"
        return why
