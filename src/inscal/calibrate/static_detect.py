"""Still intervals of a record without encoders (hand-held or fixture poses), with the reason for
every decision.

The record is ``time`` (end of each sample interval, s; any time base: jittered, with gaps),
``dtheta`` and ``dvel`` (the increments of each interval).  The rates of sample k are
``x_k = increment_k / dt_k`` with ``dt_k = t_k - t_{k-1}`` (the first sample: the median step).

A still pose is what the models need (Tedaldi et al., ICRA 2014; imu_tk judges a pose by the accelerometers
alone): for the accelerometer model a stretch whose specific force is constant within its noise, whatever the
gyros' zero-mean hand tremor; the gyro model integrates the rotation between the poses through the tremor.

Noise (from the record itself), at two scales.  At the sample rate, the per-sample scatter of the blocks
below (``sum_k dt_k (x_k - xbar)^2 / (m - 1)`` is the density ``N^2`` for white noise, whatever the jitter):
the median block first (most of a session is poses), then the median over the quiet blocks.  At the scale of a
pose -- where an on-chip low-pass filter's correlation, the tremor and a slow drift live, unseen by neighbouring
samples -- the scatter of batch means of ``batch_s`` (0.25 s, at least 8 samples) about their straight line:
from the still start when the record has one (the first stretch, from the record's start, of at least
``START_S`` = 10 s: a note gives its figures), else pooled over the settled candidates.  A noise-free record gets
the round-off floor ``1e-12`` of the signal.

Detection, every threshold a quantile at the false-alarm probability ``alpha``:

1. blocks of ``block_s`` seconds (by time; default ``min_still / 4``) without a time gap (a step above 1.5
   median steps plus the chi-square bound of the step jitter).  A block is *still to the accelerometers*
   when their scatter stays under the chi-square quantile (``alpha`` over the blocks) of ``3 (m - 1)`` dof
   times ``N_a^2`` plus the wobble ``(g tremor / (2 pi 4 Hz))^2 T_b`` that a tremor of the stated rate
   ``tremor`` (rms, default 3 deg/s; physiological tremor is 4-12 Hz) gives the specific force; its *gyros
   are within the tremor* when ``sum_k dt_k |w_k - w_0|^2`` about the record's still rate ``w_0`` stays under
   the quantile of ``3 m`` dof times ``N_g^2`` plus ``tremor^2 T_b``;
2. runs of blocks still to the accelerometers are split into the runs whose gyros are within the tremor
   (*candidates*) and the others (rejected, with their gyro scatter against the stated tremor, or named as a
   turn about gravity when their mean rate carries it); ``settle`` seconds are dropped at both ends, and the end
   batches whose mean rate or specific force differs from the rest's by more than 4 of their scatters (the slow
   start or end of a move) are trimmed;
3. a candidate is kept unless it is too short (``min_still``), saturated (samples at the clip level
   ``accel_range`` / ``gyro_range`` when given, samples ``clipped`` at import, a gyro that holds its
   record-wide maximum or minimum for 3 samples or more in a move, or an accelerometer that reads one value to
   round-off while the record's noise says it should scatter), it tilts (the slope of the specific force over
   the window against the pose-scale noise: an F test on 3 and ``nb - 2`` dof, reported as a tilt rate), or
   it turns (its mean gyro rate differs from the median of the candidates by more than the chi-square bound of
   its own noise plus the scatter between poses, which holds the Earth rate, g-sensitivity and drift).

Every candidate's reason carries its figures and thresholds (a kept one: its tilt rate, its rate against the
other poses, its gyro scatter).  The sigma of a pose's mean: the pose-scale density (its own batch means, the
still start's as a floor) over ``sqrt(T)``; for the gyros also the tremor's share ``2 var(tau) / T^2`` (a mean
rate over T holds ``(tau(t1) - tau(t0)) / T`` of a tremor angle tau, whose variance is that of the gyros
integrated through the pose less the white noise's ``N_g^2 T / 12``), and the tremor's attitude at the pose's
ends relative to its mean attitude (``wobble``) joins the rotations between the poses' mean attitudes.

:meth:`StillIntervals.require` raises one line naming the first rejection when fewer poses than a
model needs remain: the (up to) three rejected candidates closest to usable, with their figures, and the
options that would make them usable (``--min-static-s``, ``--settle-s``, ``--tremor-dps``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.samples import triad_series

#: the round-off floor of the noise density of a noise-free record, relative to the signal
NOISE_FLOOR = 1e-12
#: samples per batch of the batch-means density (longer than any correlation a conversion leaves), at least
BATCH = 8
#: the length of a batch at the scale of a pose [s] (longer than an on-chip filter's memory and a tremor's period)
BATCH_S = 0.25
#: the stated hand tremor a pose may hold by default [rad/s rms] (hand-held poses: 0.1-2 deg/s)
TREMOR = math.radians(3.0)
#: the lowest tremor frequency [Hz] (physiological tremor 4-12 Hz, Elble & Koller 1990): a tremor of rate
#: rms r wobbles the specific force by at most g r / (2 pi TREMOR_HZ)
TREMOR_HZ = 4.0
#: the end batches of a stretch that differ from the rest by more than this many of their scatters are trimmed
TRIM_Z = 4.0
#: the shortest still start [s] whose batch means give the noise at a pose's scale
START_S = 10.0


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
    gyro_sigma: np.ndarray  # 1 sigma of ``gyro`` from the noise at the pose's scale (tremor included) [rad/s]
    accel_sigma: np.ndarray  # 1 sigma of ``accel`` [m/s^2]
    wobble: np.ndarray = field(default_factory=lambda: np.zeros(3))  # the attitude at both ends relative to the
    # pose's mean attitude (small rotation vector from the gyros through the pose's tremor) [rad]
    score: float = 0.0  # a rejection's figure over its threshold (how far from usable; 0 when kept)
    fix: str = ""  # what would make a rejected candidate usable (an option), when an option would

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
    gyro_clipped: np.ndarray  # bool per sample: a gyro at its clip level (or marked saturated at import)
    notes: tuple[str, ...] = ()
    tremor: float = TREMOR  # the stated tremor level [rad/s rms]
    min_still: float = 2.0  # [s]
    settle: float = 0.25  # [s]

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
        """The kept poses, or :class:`CalibrationError` in one line when fewer than ``needed``: the best
        rejected poses (closest to usable) with their figures and what would make them usable."""
        kept = self.kept
        if len(kept) >= needed:
            return kept
        best = sorted(self.rejected, key=lambda c: (c.score, -c.duration))[:3]
        why = "; ".join(f"pose {c.number} ({c.t0:.1f}-{c.t1:.1f} s) {c.reason}" for c in best)
        by_option: dict[str, str] = {}  # one fix per option, the one that uses them all: the farthest pose's
        for c in sorted((c for c in best if c.fix), key=lambda c: c.score):  # (the largest tremor, the shortest)
            by_option[c.fix.split(" ")[0]] = c.fix
        fixes = list(by_option.values())
        if fixes:
            why += f"; to use them: {'; '.join(fixes)}"
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
    """Samples where a noisy sensor sits at its record-wide maximum or minimum for at least 3 samples in a row
    (a clipped output reads one value; a real signal does not repeat its extreme to round-off), far (10 sample
    scatters) from the axis's median: in a move.  An axis that repeats values on more than half of its samples
    is not judged (noise-free data repeat values normally)."""
    out = np.zeros(x.shape[0], bool)
    for ax in range(x.shape[1]):
        a = x[:, ax]
        d = np.diff(a)
        if np.ptp(a) == 0.0 or np.mean(d == 0.0) > 0.5:
            continue
        mid, scat = float(np.median(a)), 1.4826 * float(np.median(np.abs(d))) / math.sqrt(2.0)
        for top in (a.max(), a.min()):
            if abs(top - mid) <= 10.0 * scat:
                continue
            at = np.abs(a - top) <= 1e-9 * abs(top)  # a jittered time base divides one count by steps that differ
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


def _pooled(scatter, m, sel, floor):
    """The noise density per axis over the blocks ``sel``: the median of their scatter / dof (robust to the
    slow end of a move that a tremor allowance lets into a quiet block); ``floor`` below."""
    sel = sel & (m > 1)
    if not sel.any():
        return None
    return np.maximum(np.sqrt(np.median(scatter[sel] / (m[sel] - 1)[:, None], axis=0)), floor)


def _pose_density(x, dt, i0, i1, batch_s):
    """The noise density per axis at the scale of a pose: the scatter of the window's batch means (``batch_s``
    long, at least :data:`BATCH` samples) about their straight line (so a slow drift is not noise), and the
    number of batches (0: too few for an estimate)."""
    d = dt[i0:i1]
    L = max(BATCH, int(round(batch_s / float(np.median(d)))))
    nb = (i1 - i0) // L
    if nb < 4:
        return np.zeros(x.shape[1]), 0
    xs, ds = x[i0:i0 + nb * L].reshape(nb, L, -1), d[:nb * L].reshape(nb, L)
    T = ds.sum(axis=1)
    means = np.einsum("bk,bki->bi", ds, xs) / T[:, None]
    tc = np.cumsum(T) - 0.5 * T
    tc = tc - tc.mean()
    A = np.column_stack([np.ones(nb), tc])
    res = means - A @ np.linalg.lstsq(A, means, rcond=None)[0]
    return np.sqrt(np.sum(T[:, None] * res**2, axis=0) / (nb - 2)), nb


def _trim(w, f, dt, i0, i1, batch_s, ng, na, z: float = TRIM_Z) -> tuple[int, int]:
    """``[i0, i1)`` without its end batches (``batch_s`` long) whose mean rate or specific force differs from the
    rest's by more than ``z`` of the rest's batch scatter (floored by the densities ``ng``, ``na``): the slow
    start or end of a move that the blocks let through.  At least 4 batches are kept."""
    L = max(BATCH, int(round(batch_s / float(np.median(dt[i0:i1])))))
    floor = np.concatenate([ng, na]) / math.sqrt(L * float(np.median(dt[i0:i1])))
    x = np.column_stack([w, f])
    while (i1 - i0) // L > 4:
        nb = (i1 - i0) // L
        core = x[i0 + L:i0 + (nb - 1) * L].reshape(nb - 2, L, 6).mean(axis=1)
        c, sd = core.mean(axis=0), np.maximum(core.std(axis=0, ddof=1), floor)
        lim = z * sd * math.sqrt(1.0 + 1.0 / (nb - 2))
        head, tail = x[i0:i0 + L].mean(axis=0), x[i1 - L:i1].mean(axis=0)
        dh, dtl = float(np.max(np.abs(head - c) / lim)), float(np.max(np.abs(tail - c) / lim))
        if max(dh, dtl) <= 1.0:
            break
        if dh >= dtl:
            i0 += L
        else:
            i1 -= L
    return i0, i1


def _tremor_word(tremor: float) -> str:
    return f"{units.from_si(tremor, 'deg/s'):.3g} deg/s"


def _checked(time, dtheta, dvel, alpha, min_still, settle, tremor, batch_s, clipped):
    """The record as float arrays, or one clear :class:`CalibrationError` on a bad input."""
    time, dth, dv = triad_series(time, dtheta, dvel, CalibrationError,
                                 "time, dtheta, dvel must be (n,), (n, 3), (n, 3); got {}, {}, {}")
    n = time.shape[0]
    if n < 10:
        raise CalibrationError(f"record too short ({n} samples) to hold a still pose")
    if not (np.all(np.isfinite(dth)) and np.all(np.isfinite(dv))):
        raise CalibrationError("the increments hold NaN or infinite values")
    if not (alpha > 0 and alpha < 0.5 and min_still > 0 and settle >= 0 and tremor >= 0 and batch_s > 0):
        raise CalibrationError(f"alpha in (0, 0.5), min_still > 0, settle >= 0, tremor >= 0, batch_s > 0; got {alpha}, "
                               f"{min_still}, {settle}, {tremor}, {batch_s}")
    if clipped is not None and np.shape(clipped) != (n,):
        raise CalibrationError(f"clipped must be one flag per sample ({n}), got shape {np.shape(clipped)}")
    return time, dth, dv


def _stretches(qa, qg, m, t_start, time, settle, min_still):
    """Runs of blocks still to the accelerometers; within them, the blocks whose gyros stay within the stated tremor
    are the candidates, the others a stretch rejected for its gyros: ``(i0, i1, gyro_ok)`` with the settling cut."""
    pieces = []  # (a, b, gyro_ok)
    qa_s = np.repeat(qa, m)
    qg_s = np.repeat(qg, m)
    for a, b in _runs_of(qa_s):
        for c, d in _runs_of(qg_s[a:b]):
            pieces.append((a + c, a + d, True))
        for c, d in _runs_of(~qg_s[a:b]):
            pieces.append((a + c, a + d, False))
    pieces.sort()
    raw = []
    for a, b, ok in pieces:
        ta, tb = t_start[a] + settle, time[b - 1] - settle
        i0 = int(np.searchsorted(t_start, ta - 1e-12 * max(1.0, abs(ta)), "left")) if settle else int(a)
        i1 = int(np.searchsorted(time, tb + 1e-12 * max(1.0, abs(tb)), "right")) if settle else int(b)
        i0, i1 = max(i0, int(a)), min(i1, int(b))
        if i1 - i0 >= 2 and (ok or time[b - 1] - t_start[a] >= min_still):
            raw.append((i0, i1, ok))
    return raw


def _pose_noise(raw, w, f, dt, t_start, time, start_window, min_still, batch_s, ng, na, floors, notes):
    """The noise densities at a pose's scale: from the still start (the first stretch, from the record's start
    within ``start_window``, long enough), else pooled over the candidates long enough (settled: no move's tail in
    them), else the block densities ``ng``, ``na``; a note names the still start."""
    floor_g, floor_a = floors
    start = next(((i0, i1) for i0, i1, ok in raw[:1] if ok and t_start[i0] - t_start[0] <= start_window
                  and time[i1 - 1] - t_start[i0] >= START_S), None)
    if start is not None:
        pg, nbg = _pose_density(w, dt, *start, batch_s)
        pa, _ = _pose_density(f, dt, *start, batch_s)
        mg_, ma_ = np.maximum(pg, floor_g), np.maximum(pa, floor_a)
        notes.append(f"noise from the still start ({t_start[start[0]]:.1f}-{time[start[1] - 1]:.1f} s, {nbg} batches of "
                     f"{batch_s:g} s): gyro {units.from_si(float(np.max(mg_)), 'deg/h') / 60.0:.3g} deg/sqrt(h), "
                     f"accelerometer {float(np.max(ma_)) / 9.80665e-6:.3g} ug/sqrt(Hz)")
        return mg_, ma_
    mg_, ma_ = ng, na
    dens_g, dens_a, dof = np.zeros(3), np.zeros(3), 0
    for i0, i1, ok in raw:
        if ok and time[i1 - 1] - t_start[i0] >= min_still:
            pg, nbg = _pose_density(w, dt, i0, i1, batch_s)
            pa, _ = _pose_density(f, dt, i0, i1, batch_s)
            if nbg:
                dens_g, dens_a, dof = dens_g + (nbg - 2) * pg**2, dens_a + (nbg - 2) * pa**2, dof + nbg - 2
    if dof >= 5:
        mg_, ma_ = np.maximum(np.sqrt(dens_g / dof), floor_g), np.maximum(np.sqrt(dens_a / dof), floor_a)
    return mg_, ma_


def _pose_means(raw, w, f, dth, dt, batch_s, mg_, ma_):
    """Per stretch ``(T, mean rate, mean specific force, gyro density with the tremor, accelerometer density,
    batches, mean tremor attitude)``."""
    means = []
    for i0, i1, _ in raw:
        d = dt[i0:i1]
        T = float(d.sum())
        pg, nbg = _pose_density(w, dt, i0, i1, batch_s)
        pa, _ = _pose_density(f, dt, i0, i1, batch_s)
        gm = w[i0:i1].T @ d / T
        # the tremor: the attitude about the pose's mean attitude, the gyros integrated through the pose; a mean
        # rate over T holds (tau(t1) - tau(t0)) / T of a tremor angle tau (variance 2 var(tau) / T^2)
        cum = np.cumsum(dth[i0:i1] - np.outer(d, gm), axis=0)
        wob = -(cum.T @ d) / T
        var_tau = np.maximum(((cum + wob) ** 2).T @ d / T - mg_**2 * T / 12.0, 0.0)  # less the noise's bridge
        sg = np.sqrt(mg_**2 / T + 2.0 * var_tau / T**2) * math.sqrt(T)
        means.append((T, gm, f[i0:i1].T @ d / T, sg, np.maximum(pa, ma_), nbg, wob))
    return means


@dataclass(frozen=True)
class _Judge:
    """What a stretch is judged against (:func:`_verdict`): the record's rates, the still baselines, the noise and
    clip flags, the options."""

    time: np.ndarray
    t_start: np.ndarray
    dt: np.ndarray
    w: np.ndarray
    f: np.ndarray
    base: np.ndarray  # the quiet blocks' mean rate
    gbase: np.ndarray  # the long poses' median rate
    between: float  # their scatter
    g_word: float
    ma_: np.ndarray
    na_diff: np.ndarray
    floor_a: float
    med: float
    clip_a: np.ndarray
    clip_g: np.ndarray
    accel_range: float | None
    tremor: float
    min_still: float
    settle: float
    alpha: float


def _verdict(J: _Judge, i0, i1, ok, T, gmean, fmean, pg, pa, nb):
    """Why a stretch is not a still pose (saturated, too short, turned, tilted, tremor above the stated level), or
    that it is: ``(kept, reason, score, fix)``."""
    time, dt, w, f = J.time, J.dt, J.w, J.f
    tremor, min_still, settle = J.tremor, J.min_still, J.settle
    zg = math.sqrt(stats.chi2.ppf(1.0 - J.alpha, 3))
    d = dt[i0:i1]
    reason, score, fix = None, 0.0, ""
    rms = math.sqrt(float(np.sum(dt[i0:i1, None] * (w[i0:i1] - gmean) ** 2)) / T)
    if not ok:
        steady = float(np.linalg.norm(gmean - J.base))
        if steady > 0.5 * rms:
            reason = (f"turned, gyro {units.from_si(steady, 'deg/s'):.3g} deg/s from the still rate while the "
                      "accelerometers were steady (a turn about gravity)")
            score = 10.0
        else:
            reason = (f"gyro tremor {_tremor_word(rms)} rms above the stated tremor level {_tremor_word(tremor)} "
                      "(--tremor-dps)")
            score, fix = rms / max(tremor, 1e-300), f"--tremor-dps {units.from_si(1.2 * rms, 'deg/s'):.2g}"
    elif T < min_still:
        reason = f"too short, {T:.3g} s below the {min_still:.3g} s minimum"
        score, fix = min_still / T, f"--min-static-s {max(0.1, math.floor(T * 10) / 10):.2g}"
        if settle > 0:
            fix += f" (or --settle-s {0.5 * settle:.2g}: {2 * settle:.2g} s of it are dropped as settling)"
    elif J.clip_a[i0:i1].any():
        reason = f"accelerometer saturated ({int(J.clip_a[i0:i1].sum())} samples at the {J.accel_range:.4g} m/s^2 clip level)"
        score = 100.0
    elif J.clip_g[i0:i1].any():
        reason = f"gyro saturated ({int(J.clip_g[i0:i1].sum())} samples at the clip level)"
        score = 100.0
    else:  # a clipped sensor reads one value while its noise says it should scatter
        flat = (np.ptp(f[i0:i1], axis=0) <= 1e-12 * np.abs(fmean)) & (J.na_diff > 1e3 * J.floor_a)
        if flat.any():
            ax = int(np.argmax(flat))
            reason = (f"accelerometer {'xyz'[ax]} saturated (flat at {fmean[ax]:.5g} m/s^2 while its noise is "
                      f"{J.na_diff[ax] / math.sqrt(J.med):.3g} m/s^2 per sample)")
            score = 100.0
    tilt_txt = turn_txt = ""
    if reason is None:  # tilt: slope of the specific force (weighted least squares per axis) against the
        # noise at the scale of the pose (its batch means, the still start's floor): an F test on 3 and nb-2 dof
        tc = (time[i0:i1] - 0.5 * d) - float((time[i0:i1] - 0.5 * d) @ d / T)
        sxx = float(np.sum(d * tc * tc))
        slope = (f[i0:i1].T @ (d * tc)) / sxx
        chi = float(np.sum(slope**2 * sxx / pa**2))
        q = 3.0 * stats.f.ppf(1.0 - J.alpha, 3, max(nb - 2, 1)) if nb and np.any(pa > J.ma_) else zg**2
        tilt = float(np.linalg.norm(slope)) / max(J.g_word, 1e-300)
        # the threshold on the trend's size along its own direction u: chi = |slope|^2 sxx sum(u^2 / pa^2)
        # passes q exactly where |slope| passes it, so the word printed follows the two values printed
        u = slope / max(float(np.linalg.norm(slope)), 1e-300)
        thr = math.sqrt(q / (sxx * float(np.sum(u**2 / pa**2)))) / max(J.g_word, 1e-300)
        tilt_txt = (f"tilt {units.from_si(tilt, 'deg/s'):.3g} deg/s (accelerometer trend) "
                    f"{'above' if chi > q else 'within'} the {units.from_si(thr, 'deg/s'):.3g} deg/s threshold")
        if chi > q:
            reason, score = "tilted, " + tilt_txt, chi / q
    if reason is None:  # turning: mean rate against the other poses (their scatter holds the Earth rate,
        # g-sensitivity and the drift of the bias), with the pose's own noise (tremor included)
        dev = float(np.linalg.norm(gmean - J.gbase))
        thr = zg * math.sqrt(float(np.max(pg)) ** 2 / T + J.between**2)
        turn_txt = (f"gyro {units.from_si(dev, 'deg/s'):.3g} deg/s from the other poses "
                    f"{'above' if dev > thr else 'within'} the {units.from_si(thr, 'deg/s'):.3g} deg/s threshold")
        if dev > thr:
            reason, score = "turned, " + turn_txt, dev / thr
    kept = reason is None
    if kept:
        reason = f"still for {T:.3g} s ({tilt_txt}; {turn_txt}; gyro scatter {_tremor_word(rms)} rms)"
    return kept, reason, score, fix


def detect_still(time, dtheta, dvel, *, min_still: float = 2.0, settle: float = 0.25, block_s: float | None = None,
                 alpha: float = 1e-3, gyro_range: float | None = None, accel_range: float | None = None,
                 gravity: float | None = None, tremor: float = TREMOR, clipped: np.ndarray | None = None,
                 batch_s: float = BATCH_S) -> StillIntervals:
    """The still intervals of a record (see the module docstring).  SI: ``min_still``, ``settle``,
    ``block_s`` (default ``min_still / 4``), ``batch_s`` in s, ``gyro_range`` [rad/s], ``accel_range`` [m/s^2]
    (the sensors' clip levels, when known); ``tremor`` [rad/s rms]: the hand tremor a pose may hold (the stated
    level); ``clipped``: bool per sample, a sensor marked saturated at import; ``gravity`` [m/s^2] only words the
    tilt rate (default: the median specific force of the candidates)."""
    time, dth, dv = _checked(time, dtheta, dvel, alpha, min_still, settle, tremor, batch_s, clipped)
    n = time.shape[0]
    dt = _steps(time)
    w = dth / dt[:, None]
    f = dv / dt[:, None]
    # gaps: a step far above the jitter of the steps (a lost sample makes at least 1.5 median steps)
    med = float(np.median(dt))
    jit = 1.4826 * float(np.median(np.abs(dt - med)))
    gap_tol = max(1.5 * med, med + math.sqrt(stats.chi2.ppf(1.0 - alpha / n, 1)) * jit)
    gap = dt > gap_tol
    gap[0] = False
    notes = []
    if gap.any():
        k = np.flatnonzero(gap)
        notes.append(f"{k.size} time gap(s) over {gap_tol * 1e3:.3g} ms (longest {dt[k].max() * 1e3:.4g} ms at "
                     f"t = {time[k[np.argmax(dt[k])]]:.3f} s): the samples after them are not used in still poses")
    clip_g = _flat_tops(w, dt) if gyro_range is None else np.any(np.abs(w) >= gyro_range, axis=1)
    clip_a = np.zeros(n, bool) if accel_range is None else np.any(np.abs(f) >= accel_range, axis=1)
    marked = np.zeros(n, bool) if clipped is None else np.asarray(clipped, bool)
    clip_g = clip_g | marked
    # 1. blocks
    bs = block_s if block_s is not None else min_still / 4.0
    t_start = time - dt
    blk = np.floor((t_start - t_start[0]) / bs).astype(np.int64)
    starts = np.flatnonzero(np.concatenate([[True], blk[1:] != blk[:-1]]))
    m = np.diff(np.append(starts, n))
    Tb = np.add.reduceat(dt, starts)
    scat_g, scat_a = _block_scatter(w, dt, starts), _block_scatter(f, dt, starts)
    unknown = gap.copy()
    unknown[0] = True  # the first sample's interval starts at an unknown time: not used in a still pose
    usable = (np.add.reduceat(unknown.astype(np.int64), starts) == 0) & (m > 1)
    # sample-scale densities: the median block first (most of a session is poses), then pooled over the quiet
    # blocks (a low-pass filter correlates neighbours: successive differences would read it too low)
    dens = [np.sqrt(np.median(s_[usable] / np.maximum(m[usable] - 1, 1)[:, None], axis=0)) if usable.any()
            else _density(x, dt, ~gap) for s_, x in ((scat_g, w), (scat_a, f))]
    floor_g, floor_a = (NOISE_FLOOR * max(float(np.sqrt(np.mean(x * x))), 1e-300) * math.sqrt(med) for x in (w, f))
    ng, na = np.maximum(dens[0], floor_g), np.maximum(dens[1], floor_a)
    na_diff = _density(f, dt, ~gap)  # the noise a clipped accelerometer would lack (successive differences)
    base = np.median((np.add.reduceat(w * dt[:, None], starts, axis=0) / Tb[:, None])[usable], axis=0) if usable.any() \
        else np.zeros(3)
    dev_g = np.add.reduceat(dt[:, None] * (w - base) ** 2, starts, axis=0).sum(axis=1)  # about the baseline rate
    crit_a = stats.chi2.ppf(1.0 - alpha / starts.size, 3 * np.maximum(m - 1, 1))  # alpha for the whole record
    crit_g = stats.chi2.ppf(1.0 - alpha / starts.size, 3 * m)
    g_est = float(np.median(np.linalg.norm(np.add.reduceat(f * dt[:, None], starts, axis=0) / Tb[:, None], axis=1)))
    tilt_allow = (g_est * tremor / (2 * math.pi * TREMOR_HZ)) ** 2  # the specific force's wobble from that tremor

    def quiet_tests(ng_, na_):
        qa = (scat_a.sum(axis=1) <= float(np.max(na_)) ** 2 * crit_a + Tb * tilt_allow) & usable
        qg = dev_g <= float(np.max(ng_)) ** 2 * crit_g + Tb * tremor**2
        return qa, qg

    for _ in range(3):
        qa, qg = quiet_tests(ng, na)
        q = qa & qg
        new_g, new_a = _pooled(scat_g, m, q, floor_g), _pooled(scat_a, m, q, floor_a)
        if new_g is None:
            break
        base = np.add.reduceat(w * dt[:, None], starts, axis=0)[q].sum(axis=0) / Tb[q].sum()
        dev_g = np.add.reduceat(dt[:, None] * (w - base) ** 2, starts, axis=0).sum(axis=1)
        ng, na = new_g, new_a
    qa, qg = quiet_tests(ng, na)
    # 2. stretches: runs of blocks still to the accelerometers, split by the gyros' tremor; the ends of a stretch
    # where a move starts or stops slowly (within the tremor allowed) are trimmed
    raw = _stretches(qa, qg, m, t_start, time, settle, min_still)
    raw = [(*_trim(w, f, dt, i0, i1, batch_s, ng, na), ok) if ok else (i0, i1, ok) for i0, i1, ok in raw]
    raw = [r for r in raw if r[1] - r[0] >= 2]
    # 3. the noise at a pose's scale, each stretch's means, and the verdicts
    mg_, ma_ = _pose_noise(raw, w, f, dt, t_start, time, 2 * bs + settle, min_still, batch_s, ng, na,
                           (floor_g, floor_a), notes)
    means = _pose_means(raw, w, f, dth, dt, batch_s, mg_, ma_)
    long_ = [k for k, (T, *_r) in enumerate(means) if T >= min_still and raw[k][2]]
    if long_:
        gm = np.array([means[k][1] for k in long_])
        gbase = np.median(gm, axis=0)
        between = 1.4826 * float(np.median(np.linalg.norm(gm - gbase, axis=1))) / math.sqrt(3.0) if len(long_) > 2 else 0.0
        gnorm = float(np.median([np.linalg.norm(means[k][2]) for k in long_]))
    else:
        gbase, between, gnorm = np.zeros(3), 0.0, 0.0
    judge = _Judge(time, t_start, dt, w, f, base, gbase, between, gravity if gravity is not None else gnorm, ma_,
                   na_diff, floor_a, med, clip_a, clip_g, accel_range, tremor, min_still, settle, alpha)
    cands = []
    for num, ((i0, i1, ok), (T, gmean, fmean, pg, pa, nb, wob)) in enumerate(zip(raw, means), start=1):
        kept, reason, score, fix = _verdict(judge, i0, i1, ok, T, gmean, fmean, pg, pa, nb)
        cands.append(Candidate(num, i0, i1, float(t_start[i0]), float(time[i1 - 1]), kept, reason, gmean, fmean,
                               pg / math.sqrt(T), pa / math.sqrt(T), wob, score, fix))
    return StillIntervals(tuple(cands), mg_, ma_, dt, gap, clip_g, tuple(notes), tremor, min_still, settle)


def _runs_of(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))
