"""Still intervals of a record without encoders (hand-held or fixture poses), with the reason for
every decision.

The record is ``time`` (end of each sample interval, s; any time base: jittered, with gaps),
``dtheta`` and ``dvel`` (the increments of each interval).  The rates of sample k are
``x_k = increment_k / dt_k`` with ``dt_k = t_k - t_{k-1}`` (the first sample: the median step).

Noise (from the record itself).  For white noise of density ``N`` the rate ``x_k`` has the variance
``N^2 / dt_k``, so on any still stretch ``(x_k - x_{k-1}) / sqrt(1/dt_k + 1/dt_{k-1})`` has the
standard deviation ``N``, whatever the jitter; ``N`` per axis is the robust (MAD) scale of that
quantity over the record (moves are a minority of the samples and smooth at the sample rate, so the
median ignores them), then pooled over the quiet blocks.  The sigma of a window mean uses the density
of batch means of 8 samples over the quiet blocks (the same for white noise; right also for increments
that a trapezoidal rule made from samples, whose neighbours correlate).  A noise-free record gets the
round-off floor ``1e-12`` of the signal.

Detection, every threshold a quantile at the false-alarm probability ``alpha``:

1. blocks of ``block_s`` seconds (by time, not by sample count); a block is *quiet* when the
   weighted scatter ``sum_k dt_k (x_k - xbar)^2 / N^2`` of the gyros and of the accelerometers each
   stay under the chi-square quantile (at ``alpha`` over the number of blocks) of their ``3 (m - 1)``
   degrees of freedom, and no step in it is
   a gap (``dt_k`` above ``1.5`` median steps plus the chi-square bound of the step jitter);
2. runs of quiet blocks are the *candidates*; ``settle`` seconds are dropped at both ends;
3. a candidate is kept unless it is too short (``min_still``), it tilts (the slope of the specific
   force over the window, a chi-square test on 3 dof, reported as a tilt rate), it turns (its mean
   gyro rate differs from the median of the candidates by more than the chi-square bound of its own
   noise plus the scatter between poses, which holds the Earth rate and g-sensitivity), or it is
   saturated (samples at the clip level ``accel_range`` / ``gyro_range`` when given, a gyro that holds
   its record-wide extreme for 3 samples or more (a clipped output), or an accelerometer
   that reads one value to round-off while the record's noise says it should scatter).

:meth:`StillIntervals.require` raises one line naming the first rejection when fewer poses than a
model needs remain (e.g. ``found 7 still poses, the model needs 9: pose 3 turned, gyro 0.8 deg/s
above the 0.05 deg/s threshold``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from inscal.calibrate.windows import CalibrationError
from inscal.core import units

#: the round-off floor of the noise density of a noise-free record, relative to the signal
NOISE_FLOOR = 1e-12
#: samples per batch of the batch-means density (longer than any correlation a conversion leaves)
BATCH = 8


@dataclass(frozen=True)
class Candidate:
    """One run of quiet samples ``[i0, i1)`` (after settling) and the decision on it."""

    number: int  # 1-based, in time order
    i0: int
    i1: int
    t0: float  # start of the first interval [s]
    t1: float  # end of the last interval [s]
    kept: bool
    reason: str  # why it was kept or rejected, in field units
    gyro: np.ndarray  # time-weighted mean rate [rad/s]
    accel: np.ndarray  # time-weighted mean specific force [m/s^2]
    gyro_sigma: np.ndarray  # 1 sigma of ``gyro`` from the noise density [rad/s]
    accel_sigma: np.ndarray  # 1 sigma of ``accel`` [m/s^2]

    @property
    def duration(self) -> float:
        """The candidate's length ``t1 - t0`` [s]."""
        return self.t1 - self.t0

    def describe(self) -> str:
        """One line for the user: the pose number, its time span [s], kept or rejected, and why."""
        return f"pose {self.number} ({self.t0:.2f}-{self.t1:.2f} s): {'kept' if self.kept else 'rejected'}, {self.reason}"


@dataclass(frozen=True)
class StillIntervals:
    """The candidates of one record, the noise densities and thresholds used."""

    candidates: tuple[Candidate, ...]
    gyro_density: np.ndarray  # N per axis [rad/s/sqrt(s)]
    accel_density: np.ndarray  # [m/s^2/sqrt(s)]
    dt: np.ndarray  # the step of every sample [s]
    gap: np.ndarray  # bool per sample: its step is a gap
    gyro_clipped: np.ndarray  # bool per sample: a gyro at its clip level
    notes: tuple[str, ...] = ()

    @property
    def kept(self) -> list[Candidate]:
        """The candidates kept as still poses, in time order."""
        return [c for c in self.candidates if c.kept]

    @property
    def rejected(self) -> list[Candidate]:
        """The candidates rejected, in time order (each with its reason)."""
        return [c for c in self.candidates if not c.kept]

    def report(self) -> list[dict]:
        """Every candidate, kept or rejected, with its reason (field units)."""
        return [{"pose": c.number, "t0_s": c.t0, "t1_s": c.t1, "kept": c.kept, "reason": c.reason}
                for c in self.candidates]

    def require(self, needed: int, what: str = "the model") -> list[Candidate]:
        """The kept poses, or :class:`CalibrationError` in one line when fewer than ``needed``."""
        kept = self.kept
        if len(kept) >= needed:
            return kept
        why = "; ".join(f"pose {c.number} {c.reason}" for c in self.rejected[:2])
        if not self.candidates:
            why = "no quiet interval in the record (it moves throughout)"
        elif not why:
            why = f"the record holds only {len(kept)} still intervals, all usable: record more poses"
        return _raise(f"found {len(kept)} still poses, {what} needs {needed}: {why}")


def _raise(msg: str):
    raise CalibrationError(msg)


def _steps(time: np.ndarray) -> np.ndarray:
    d = np.diff(time)
    if d.size == 0 or not np.all(np.isfinite(time)) or np.any(d <= 0):
        bad = int(np.argmax(~(d > 0))) + 1 if d.size else 0
        raise CalibrationError(f"time must increase strictly (sample {bad}: {time[bad - 1] if bad else 0:.6g} s, "
                               f"then {time[bad] if d.size else 0:.6g} s)")
    return np.concatenate([[np.median(d)], d])


def _density(x: np.ndarray, dt: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Robust white-noise density per axis from successive differences (see the module docstring)."""
    z = np.diff(x, axis=0) / np.sqrt(1.0 / dt[1:] + 1.0 / dt[:-1])[:, None]
    z = z[ok[1:] & ok[:-1]]
    n = 1.4826 * np.median(np.abs(z), axis=0)
    floor = NOISE_FLOOR * max(float(np.sqrt(np.mean(x * x))), 1e-300) * math.sqrt(float(np.median(dt)))
    return np.maximum(n, floor)


def _flat_tops(x: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Samples where a sensor sits at its record-wide extreme for at least 3 samples in a row (a clipped
    output reads one value; a real signal does not repeat its extreme to round-off)."""
    out = np.zeros(x.shape[0], bool)
    for ax in range(x.shape[1]):
        a = np.abs(x[:, ax])
        top = a.max()
        if top == 0.0:
            continue
        at = a >= top * (1.0 - 1e-12)
        edges = np.diff(np.concatenate([[0], at.astype(np.int8), [0]]))
        for i0, i1 in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            if i1 - i0 >= 3:
                out[i0:i1] = True
    return out


def _block_scatter(x, dt, starts):
    """Per block and axis: the weighted scatter ``sum_k dt_k (x_k - xbar)^2`` about the weighted mean."""
    w = np.add.reduceat(dt, starts)
    mean = np.add.reduceat(x * dt[:, None], starts, axis=0) / w[:, None]
    idx = np.repeat(np.arange(starts.size), np.diff(np.append(starts, dt.size)))
    dev = x - mean[idx]
    return np.add.reduceat(dt[:, None] * dev * dev, starts, axis=0)


def _batch_density(x, dt, starts, m, sel, length: int = BATCH):
    """Noise density per axis from the scatter of batch means (``length`` samples) about their block's mean,
    pooled over the blocks ``sel`` (batch means, Law & Carson 1979); None without two batches anywhere."""
    num, dof = np.zeros(x.shape[1]), 0
    for b in np.flatnonzero(sel & (m >= 2 * length)):
        i0, nb = starts[b], m[b] // length
        xs, ds = x[i0:i0 + nb * length].reshape(nb, length, -1), dt[i0:i0 + nb * length].reshape(nb, length)
        T = ds.sum(axis=1)
        means = np.einsum("bk,bki->bi", ds, xs) / T[:, None]
        mean = (T @ means) / T.sum()
        num += T @ ((means - mean) ** 2)
        dof += nb - 1
    return None if dof < 5 else np.sqrt(num / dof)


def _pooled(scatter, m, sel, floor):
    """The noise density per axis pooled over the blocks ``sel`` (scatter / dof); ``floor`` below."""
    dof = np.maximum(m[sel] - 1, 0).sum()
    if dof <= 0:
        return None
    return np.maximum(np.sqrt(scatter[sel].sum(axis=0) / dof), floor)


def detect_still(time, dtheta, dvel, *, min_still: float = 2.0, settle: float = 0.25, block_s: float | None = None,
                 alpha: float = 1e-3, gyro_range: float | None = None, accel_range: float | None = None,
                 gravity: float | None = None) -> StillIntervals:
    """The still intervals of a record (see the module docstring).  SI: ``min_still``, ``settle``,
    ``block_s`` (default ``min_still / 4``) in s, ``gyro_range`` [rad/s], ``accel_range`` [m/s^2] (the
    sensors' clip levels, when known); ``gravity`` [m/s^2] only words the tilt rate (default: the
    median specific force of the candidates)."""
    time = np.asarray(time, float)
    dth = np.asarray(dtheta, float)
    dv = np.asarray(dvel, float)
    n = time.shape[0]
    if time.ndim != 1 or dth.shape != (n, 3) or dv.shape != (n, 3):
        raise CalibrationError(f"time, dtheta, dvel must be (n,), (n, 3), (n, 3); got {time.shape}, {dth.shape}, "
                               f"{dv.shape}")
    if n < 10:
        raise CalibrationError(f"record too short ({n} samples) to hold a still pose")
    if not (np.all(np.isfinite(dth)) and np.all(np.isfinite(dv))):
        raise CalibrationError("the increments hold NaN or infinite values")
    if not (alpha > 0 and alpha < 0.5 and min_still > 0 and settle >= 0):
        raise CalibrationError(f"alpha in (0, 0.5), min_still > 0, settle >= 0; got {alpha}, {min_still}, {settle}")
    dt = _steps(time)
    w = dth / dt[:, None]
    f = dv / dt[:, None]
    # gaps: a step far above the jitter of the steps (a lost sample makes at least 1.5 median steps)
    med = float(np.median(dt))
    jit = 1.4826 * float(np.median(np.abs(dt - med)))
    gap_tol = max(1.5 * med, med + math.sqrt(stats.chi2.ppf(1.0 - alpha / n, 1)) * jit)
    gap = dt > gap_tol
    gap[0] = False
    ok = ~gap
    notes = []
    if gap.any():
        k = np.flatnonzero(gap)
        notes.append(f"{k.size} time gap(s) over {gap_tol * 1e3:.3g} ms (longest {dt[k].max() * 1e3:.4g} ms at "
                     f"t = {time[k[np.argmax(dt[k])]]:.3f} s): the samples after them are not used in still poses")
    clip_g = _flat_tops(w, dt) if gyro_range is None else np.any(np.abs(w) >= gyro_range, axis=1)
    clip_a = np.zeros(n, bool) if accel_range is None else np.any(np.abs(f) >= accel_range, axis=1)
    # 1. quiet blocks
    bs = block_s if block_s is not None else min_still / 4.0
    t_start = time - dt
    blk = np.floor((t_start - t_start[0]) / bs).astype(np.int64)
    starts = np.flatnonzero(np.concatenate([[True], blk[1:] != blk[:-1]]))
    m = np.diff(np.append(starts, n))
    scat_g, scat_a = _block_scatter(w, dt, starts), _block_scatter(f, dt, starts)
    dof = 3 * np.maximum(m - 1, 1)
    crit = stats.chi2.ppf(1.0 - alpha / starts.size, dof)  # alpha for the whole record (Bonferroni)
    unknown = gap.copy()
    unknown[0] = True  # the first sample's interval starts at an unknown time: not used in a still pose
    has_gap = np.add.reduceat(unknown.astype(np.int64), starts) > 0
    usable = ~has_gap & (m > 1)
    # the noise densities: successive differences (moves inflate them a little), then pooled over the
    # quiet blocks twice (the blocks that pass with the densities found so far)
    ng, na = _density(w, dt, ok), _density(f, dt, ok)
    floor_g, floor_a = (NOISE_FLOOR * max(float(np.sqrt(np.mean(x * x))), 1e-300) * math.sqrt(med) for x in (w, f))
    for _ in range(3):
        quiet_blk = (np.sum(scat_g / ng**2, axis=1) <= crit) & (np.sum(scat_a / na**2, axis=1) <= crit) & usable
        new_g, new_a = _pooled(scat_g, m, quiet_blk, floor_g), _pooled(scat_a, m, quiet_blk, floor_a)
        if new_g is None:
            break
        ng, na = new_g, new_a
    quiet_blk = (np.sum(scat_g / ng**2, axis=1) <= crit) & (np.sum(scat_a / na**2, axis=1) <= crit) & usable
    quiet = np.repeat(quiet_blk, m)
    # the density that sets the sigma of a window mean: from batch means (immune to the short correlation
    # of increments made from samples by a trapezoidal rule); the sample-level ng, na judge the blocks
    mg_, ma_ = _batch_density(w, dt, starts, m, quiet_blk), _batch_density(f, dt, starts, m, quiet_blk)
    mg_ = ng if mg_ is None else np.maximum(mg_, floor_g)
    ma_ = na if ma_ is None else np.maximum(ma_, floor_a)
    # 2. candidates: runs of quiet blocks, settled
    edges = np.diff(np.concatenate([[0], quiet.astype(np.int8), [0]]))
    runs = list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))
    raw = []
    for a, b in runs:
        ta, tb = t_start[a] + settle, time[b - 1] - settle
        i0 = int(np.searchsorted(t_start, ta - 1e-12 * max(1.0, abs(ta)), "left")) if settle else int(a)
        i1 = int(np.searchsorted(time, tb + 1e-12 * max(1.0, abs(tb)), "right")) if settle else int(b)
        i0, i1 = max(i0, int(a)), min(i1, int(b))
        if i1 - i0 >= 2:
            raw.append((i0, i1))
    means = []
    for i0, i1 in raw:
        d = dt[i0:i1]
        T = float(d.sum())
        means.append((T, w[i0:i1].T @ d / T, f[i0:i1].T @ d / T))
    long_ = [k for k, (T, _, _) in enumerate(means) if T >= min_still]
    zg = math.sqrt(stats.chi2.ppf(1.0 - alpha, 3))
    if long_:
        gm = np.array([means[k][1] for k in long_])
        base = np.median(gm, axis=0)
        between = 1.4826 * float(np.median(np.linalg.norm(gm - base, axis=1))) / math.sqrt(3.0) if len(long_) > 2 else 0.0
        gnorm = float(np.median([np.linalg.norm(means[k][2]) for k in long_]))
    else:
        base, between, gnorm = np.zeros(3), 0.0, 0.0
    g_word = gravity if gravity is not None else gnorm
    cands = []
    for num, ((i0, i1), (T, gmean, fmean)) in enumerate(zip(raw, means), start=1):
        d = dt[i0:i1]
        reason = None
        if T < min_still:
            reason = f"too short, {T:.3g} s below the {min_still:.3g} s minimum"
        elif clip_a[i0:i1].any():
            reason = f"accelerometer saturated ({int(clip_a[i0:i1].sum())} samples at the {accel_range:.4g} m/s^2 clip level)"
        elif clip_g[i0:i1].any():
            reason = f"gyro saturated ({int(clip_g[i0:i1].sum())} samples at the clip level)"
        else:  # a clipped sensor reads one value while its noise says it should scatter
            flat = (np.ptp(f[i0:i1], axis=0) <= 1e-12 * np.abs(fmean)) & (na > 1e3 * floor_a)
            if flat.any():
                ax = int(np.argmax(flat))
                reason = (f"accelerometer {'xyz'[ax]} saturated (flat at {fmean[ax]:.5g} m/s^2 while its noise is "
                          f"{na[ax] / math.sqrt(med):.3g} m/s^2 per sample)")
        if reason is None:  # tilt: slope of the specific force, weighted least squares per axis
            tc = (time[i0:i1] - 0.5 * d) - float((time[i0:i1] - 0.5 * d) @ d / T)
            sxx = float(np.sum(d * tc * tc))
            slope = (f[i0:i1].T @ (d * tc)) / sxx
            # a trend is a long-window statistic: its noise is the batch-means density (a short correlation of the
            # increments, as jittered stamps leave, does not inflate it)
            chi = float(np.sum(slope**2 * sxx / ma_**2))
            if chi > zg**2:
                # the threshold on the trend's size along its own direction u: chi = |slope|^2 sxx sum(u^2 / na^2)
                # passes zg^2 exactly where |slope| passes it, so the value printed is above the one printed beside
                u = slope / float(np.linalg.norm(slope))
                tilt = float(np.linalg.norm(slope)) / max(g_word, 1e-300)
                thr = zg / math.sqrt(sxx * float(np.sum(u**2 / ma_**2))) / max(g_word, 1e-300)
                reason = (f"tilted, {units.from_si(tilt, 'deg/s'):.3g} deg/s (accelerometer trend) above the "
                          f"{units.from_si(thr, 'deg/s'):.3g} deg/s threshold")
        if reason is None:  # turning: mean rate against the other poses
            dev = float(np.linalg.norm(gmean - base))
            thr = zg * math.sqrt(float(np.max(ng)) ** 2 / T + between**2)
            if dev > thr:
                reason = (f"turned, gyro {units.from_si(dev, 'deg/s'):.3g} deg/s above the "
                          f"{units.from_si(thr, 'deg/s'):.3g} deg/s threshold")
        kept = reason is None
        if kept:
            reason = f"still for {T:.3g} s"
        cands.append(Candidate(num, i0, i1, float(t_start[i0]), float(time[i1 - 1]), kept, reason, gmean, fmean,
                               mg_ / math.sqrt(T), ma_ / math.sqrt(T)))
    return StillIntervals(tuple(cands), mg_, ma_, dt, gap, clip_g, tuple(notes))
