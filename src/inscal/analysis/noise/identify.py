"""Identification of a record's noise, channel by channel: one streamed pass over a static window
(the Allan/Haar wavelet variance of the six channels on a log grid, the motion statistics, the
stuck/saturated/count checks), then the fit or the model choice on the octave scales, and the
result in IEEE 952-2020 / 1293-2018 field units.

Channels: ``gx gy gz`` (the gyro increments /dtheta, rad) and ``ax ay az`` (/dvel, m/s), turned into
rates by ``/ dt``.  A channel is refused when it is stuck (more than half of its successive
increments equal, or a stretch of equal increments far longer than chance allows: frozen or
saturated), saturated (more than 1 % of it at its extreme value), or holds raw counts (every
increment a whole number of at least 1: not SI).  The stretches of a window that move, tilt or step
(:mod:`inscal.analysis.noise.motion`) are cut out with a margin and the curve computed on the static
segments left (:func:`cut_motion`); a window that moves in more than :data:`MAX_CUT_SHARE` of it is
refused with the times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.analysis.noise.estimators import (ScaleVariance, StreamingScaleVariance, log_scales, octave_scales, pooled,
                                              segment_factors)
from inscal.analysis.noise.fit import Curve, fit_curve, n_params
from inscal.analysis.noise.intervals import chi2_bounds, wv_interval
from inscal.analysis.noise.motion import MotionStats
from inscal.analysis.noise.selection import AUTO_MIN_MODEL, AUTO_MODEL, Selection, readoffs, select
from inscal.core import noise_models as nm
from inscal.core import units
from inscal.io.streaming import iter_window

CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")
KINDS = {c: ("gyro" if c[0] == "g" else "accel") for c in CHANNELS}
#: a parameter whose 95 % interval spans more than this factor is flagged unresolved
UNRESOLVED_SPAN = 1e3
#: the margin cut out on each side of a moving stretch [s]: a turn's start and its settling
CUT_MARGIN_S = 5.0
#: the largest share of a window cut out as moving; a window that moves more is refused with the times
MAX_CUT_SHARE = 0.1
#: the shortest run of equal successive increments taken for a stuck stretch
STUCK_RUN_MIN = 20
#: the octave scales a model of p parameters needs: p + 2 (two degrees of freedom left for the J test)
EXTRA_SCALES = 2
#: the most points a curve computed elsewhere may have: one per octave of a record of 2^64 samples (the
#: fit's time grows faster than the square of the points: 100 points take tens of seconds, 300 minutes)
MAX_CURVE_POINTS = 64
#: the most bytes of a curve file (64 rows of four numbers and comments fit in a few kB)
MAX_CURVE_BYTES = 1_000_000
#: the variances (SI, after AVAR -> WV) a curve may hold: beyond, squares and weights leave float range
CURVE_RANGE = (1e-60, 1e60)
#: the sample intervals [s] a curve may state (m = tau / dt stays an exact integer, below 2^53)
DT_RANGE = (1e-9, 1e6)


class NoiseInputError(ValueError):
    """A record or curve that cannot be identified (one line: what and where)."""


def required_scales(model: str) -> int:
    """Octave scales a fit of ``model`` needs: its p parameters + 2 (``auto``: those of
    :data:`~inscal.analysis.noise.selection.AUTO_MIN_MODEL`; its richer candidates are tried where the
    record has the scales)."""
    codes = nm.parse_model(AUTO_MIN_MODEL if model == "auto" else model)
    return sum(n_params(c) for c in codes) + EXTRA_SCALES


def required_samples(model: str) -> int:
    """Samples a record needs for ``model``: J octave scales up to a tenth of the record,
    i.e. n >= 10 * 2^(J - 1) (:func:`inscal.analysis.noise.estimators.octave_scales`)."""
    return int(10 * 2 ** (required_scales(model) - 1))


class ChannelChecks:
    """Stuck, saturated and raw-count signs of each channel, gathered chunk by chunk."""

    def __init__(self, k: int):
        self.k = k
        self.n = 0
        self.equal = np.zeros(k, dtype=np.int64)  # successive equal increments
        self.hi = np.full(k, -np.inf)
        self.lo = np.full(k, np.inf)
        self.n_hi = np.zeros(k, dtype=np.int64)
        self.n_lo = np.zeros(k, dtype=np.int64)
        self.integer = np.ones(k, dtype=bool)
        self.last = None
        self.run = np.zeros(k, dtype=np.int64)  # the current run of equal successive increments
        self.longest = np.zeros(k, dtype=np.int64)
        self.longest_end = np.zeros(k, dtype=np.int64)  # the sample index that ends it

    def update(self, x) -> None:
        """Take the next chunk of increments, (N, k): count successive equal values, track each
        channel's extremes and how often they occur, and whether every value is a whole number."""
        xx = x if self.last is None else np.concatenate([self.last, x])
        eq = np.diff(xx, axis=0) == 0  # eq[i]: sample (self.n + i + first) equals the one before
        self.equal += np.sum(eq, axis=0)
        first = 0 if self.last is not None else 1
        for c in range(self.k):
            e = np.concatenate([[False], eq[:, c], [False]])
            d = np.flatnonzero(np.diff(e.astype(np.int8)))
            starts, ends = d[::2], d[1::2]  # runs of True: eq[starts:ends]
            if starts.size == 0:
                self.run[c] = 0
                continue
            lens = ends - starts
            if starts[0] == 0:
                lens[0] += self.run[c]  # the run goes on from the last chunk
            j = int(np.argmax(lens))
            if lens[j] > self.longest[c]:
                self.longest[c] = lens[j]
                self.longest_end[c] = self.n + first + ends[j] - 1
            self.run[c] = lens[-1] if ends[-1] == eq.shape[0] else 0
        self.last = x[-1:]
        self.n += x.shape[0]
        self.integer &= np.all((x == np.round(x)) & (np.abs(x) >= 1) | (x == 0), axis=0)
        for ext, cnt, fn, better in ((self.hi, self.n_hi, np.max, np.greater), (self.lo, self.n_lo, np.min, np.less)):
            v = fn(x, axis=0)
            c = np.sum(x == v, axis=0)
            new = better(v, ext)
            same = v == ext
            cnt[new] = c[new]
            cnt[same] += c[same]
            ext[new] = v[new]

    def stuck_stretch(self, c: int) -> tuple[int, int] | None:
        """Channel ``c``'s longest run of equal successive increments as ``(first, last)`` sample
        indices when it is far longer than chance allows, else None: with p the channel's share of
        equal successive increments, n p^L is the expected number of runs of length L, so a run with
        n p^L < 1e-3 (and at least :data:`STUCK_RUN_MIN`) is a frozen or saturated stretch."""
        L = int(self.longest[c])
        if L < STUCK_RUN_MIN or self.n < 2:
            return None
        p = self.equal[c] / (self.n - 1)
        if p > 0 and (self.n * p**L >= 1e-3):
            return None
        end = int(self.longest_end[c])
        return end - L, end

    def problems(self, names, t0: float = 0.0, dt: float = 1.0) -> list[str]:
        """One line per channel (named by ``names``) that looks like raw counts, stuck or saturated;
        empty when every channel looks sound."""
        out = []
        for c, name in enumerate(names):
            if self.integer[c] and self.hi[c] - self.lo[c] >= 1:
                out.append(f"{name} holds whole numbers (raw counts?): the record must be in SI (rad, m/s) - "
                           "convert the counts with the sensor's scale factor first")
            elif self.n > 1 and self.equal[c] > 0.5 * (self.n - 1):
                out.append(f"{name} is stuck ({100 * self.equal[c] / (self.n - 1):.0f} % of its successive "
                           "increments are equal)")
            elif self.hi[c] > self.lo[c] and max(self.n_hi[c], self.n_lo[c]) > max(0.01 * self.n, 10):
                side = "maximum" if self.n_hi[c] >= self.n_lo[c] else "minimum"
                frac = 100 * max(self.n_hi[c], self.n_lo[c]) / self.n
                out.append(f"{name} is saturated ({frac:.1f} % of its samples at its {side})")
            elif (st := self.stuck_stretch(c)) is not None:
                out.append(f"{name} is stuck or saturated from {t0 + st[0] * dt:.6g} s to {t0 + (st[1] + 1) * dt:.6g} s "
                           f"({st[1] - st[0] + 1} equal increments in a row; use --start/--stop to leave it out)")
        return out


@dataclass(frozen=True)
class Scan:
    """What one pass over a window gathers: the variances of the six channels on the log grid, the
    motion statistics and the channel checks."""

    sv: ScaleVariance
    motion: MotionStats
    checks: ChannelChecks
    t_first: float
    t_last: float


def scan_window(path, win, chunk_size: int = 1 << 18, per_octave: int = 4) -> Scan:
    """One streamed pass over the window ``win`` of the record at ``path`` (bounded memory)."""
    n = win.n
    acc = StreamingScaleVariance(n, win.rate_hz, 6, log_scales(n, per_octave), increments=True)
    mot, chk = MotionStats(n, win.rate_hz, 6), ChannelChecks(6)
    t_first = t_last = None
    for t, dth, dv, g in iter_window(path, ("time", "dtheta", "dvel", "gimbal"), win.i0, win.i1, chunk_size):
        t_first = float(t[0]) if t_first is None else t_first
        t_last = float(t[-1])
        x = np.concatenate([dth, dv], axis=1)
        acc.update(x)
        mot.update(x, g)
        chk.update(x)
    return Scan(acc.result(), mot, chk, t_first, t_last)


@dataclass(frozen=True)
class Cut:
    """The moving stretches cut out of a window (:func:`cut_motion`): ``spans_s`` as (start, end) [s]
    of the record's time, their total ``seconds`` and ``share`` of the window, the static segments
    kept (``segments``) and the samples the pooled curve uses."""

    spans_s: tuple
    seconds: float
    share: float
    segments: int
    samples_used: int

    def to_dict(self) -> dict:
        """The cut as JSON-ready fields."""
        return {"spans_s": [list(s) for s in self.spans_s], "seconds": self.seconds, "share": self.share,
                "static_segments": self.segments, "samples_used": self.samples_used,
                "margin_s": CUT_MARGIN_S, "max_share": MAX_CUT_SHARE}


def cut_motion(path, win, scan: Scan, t0: float, chunk_size: int = 1 << 18, per_octave: int = 4) -> tuple:
    """The window without its moving stretches: every stretch that moves, turns, steps or is stuck
    (:meth:`inscal.analysis.noise.motion.MotionStats.moving_spans`, widened by :data:`CUT_MARGIN_S`
    on each side) cut out, and the variances computed on each static segment left and pooled
    (:func:`inscal.analysis.noise.estimators.pooled`: each factor from the segments long enough for it,
    its degrees of freedom from the terms used).  Returns ``(ScaleVariance, Cut)``; a
    :class:`NoiseInputError` with the times where more than :data:`MAX_CUT_SHARE` of the window would be
    cut, where the gimbal turns, or where no segment is long enough.  ``t0``: the time of the window's
    sample -1 [s]."""
    dt = 1.0 / win.rate_hz
    spans = scan.motion.moving_spans(CUT_MARGIN_S)
    where = ", ".join(f"{t0 + a * dt:.6g}-{t0 + b * dt:.6g} s" for a, b in spans[:4]) + (
        f" and {len(spans) - 4} more" if len(spans) > 4 else "")
    cut = sum(b - a for a, b in spans)
    if cut > MAX_CUT_SHARE * win.n:
        raise NoiseInputError(f"it moves in {100 * cut / win.n:.3g} % of the window (more than the "
                              f"{100 * MAX_CUT_SHARE:g} % inscal cuts out), at {where}: noise is identified on a "
                              "static window; choose one with --start/--stop")
    if scan.motion.gmin is not None and float(np.max(scan.motion.gmax - scan.motion.gmin)) > 1e-3:
        raise NoiseInputError("the gimbal turns in the window: noise is identified on a static window; choose one "
                              "with --start/--stop")
    keep, prev = [], 0
    for a, b in spans + [(win.n, win.n)]:
        if a > prev:
            keep.append((prev, a))
        prev = b
    m_all = log_scales(win.n, per_octave)
    parts = []
    for a, b in keep:
        ms = segment_factors(m_all, b - a)
        if b - a < 16 or ms.size == 0:
            continue
        acc = StreamingScaleVariance(b - a, win.rate_hz, 6, ms, increments=True)
        for dth, dv in iter_window(path, ("dtheta", "dvel"), win.i0 + a, win.i0 + b, chunk_size):
            acc.update(np.concatenate([dth, dv], axis=1))
        parts.append(acc.result())
    if not parts:
        raise NoiseInputError(f"no static stretch of 16 samples is left once the motion at {where} is cut out")
    sv = pooled(parts, m_all, dt)
    return sv, Cut(tuple((float(t0 + a * dt), float(t0 + b * dt)) for a, b in spans), float(cut * dt),
                   float(cut / win.n), len(parts), int(sv.n))


def octave_curve(sv: ScaleVariance, c: int) -> Curve:
    """Channel ``c``'s curve at the octave factors only (the fit's scales)."""
    oct_m = octave_scales(sv.n)
    sel = np.isin(sv.m, oct_m)
    sub = ScaleVariance(sv.m[sel], sv.dt, sv.n, sv.wv[sel], sv.n_terms[sel])
    return Curve.from_scale_variance(sub, c)


def identify_curve(curve: Curve, model: str, rng: np.random.Generator, n_starts: int = 12) -> Selection:
    """``auto``: :func:`select` over the sub-sums of the largest model; else the fit of ``model``."""
    if model == "auto":
        return select(curve, AUTO_MODEL, rng)
    f = fit_curve(curve, model, n_starts=n_starts, rng=rng)
    row = (f.model, None, f.gof, f.gof_p, len(f.theta), "")
    return Selection(f, (row,), f"{f.model}: as asked (--model)", "none")


def param_key(name: str) -> str:
    """The parameter key of a label (``GM1.tc`` -> ``tc``), which indexes the unit tables."""
    return name.split(".")[1]


def channel_summary(name: str, sel: Selection, sv: ScaleVariance, c: int, kind: str | None = None) -> dict:
    """One channel's result in field units (JSON-ready): the model, why, every parameter with its
    95 % interval, the discrete forms, the fit's statistics, the IEEE read-offs, and the curves."""
    kind = kind or KINDS.get(name, "gyro")
    fu = nm.FIELD_UNITS[kind]
    f = sel.chosen
    params, unresolved = {}, []
    for pn, v, lo, hi in zip(f.names, f.values, f.lower, f.upper):
        u = fu[param_key(pn)]
        params[pn] = {"value": float(units.from_si(float(v), u)), "lower_95": float(units.from_si(float(lo), u)),
                      "upper_95": float(units.from_si(float(hi), u)), "unit": u}
        if not (lo > 0 and hi / lo <= UNRESOLVED_SPAN):
            params[pn]["unresolved"] = True
            unresolved.append(pn)
    dt = sv.dt
    rate_unit = "deg/h" if kind == "gyro" else "ug"
    lo, hi = wv_interval(sv)
    tau = sv.taus
    read = ieee_readoffs(sv, c, kind)
    contrib = np.stack([t.avar(sv.m, dt) for t in f.terms], axis=1)
    return {
        "channel": name, "kind": kind, "model": f.model, "why": sel.reason,
        "parameters": params,
        "unseen_terms": [t.code for t, neg in zip(f.terms, f.negligible) if neg],
        "dropped_unseen": list(sel.removed),
        "unresolved": {"parameters": unresolved,
                       "rule": f"95 % interval wider than a factor {UNRESOLVED_SPAN:g} (or reaching 0)"},
        "richer_near_fits": [{"model": m, "criterion_gap": g, "j_drop": d, "record_length_factor": x}
                             for m, g, d, x in sel.richer],
        "discrete_per_sample_si": [{"term": t.code, **nm.discrete(t, dt)} for t in f.terms],
        "objective": f.objective, "j_statistic": f.gof, "j_dof": f.gof_dof, "j_p_value": f.gof_p,
        "wvic": f.wvic, "starts": f.starts, "starts_at_best": f.hits,
        "fit_scales": {"m": f.curve.m.tolist(), "scale_index_j": np.log2(2 * f.curve.m).tolist(),
                       "tau_s": (f.curve.m * dt).tolist(), "wv_si": f.curve.wv.tolist(),
                       "weights": f.weights.tolist(), "wv_fit_si": f.wv_fit.tolist()},
        "selection_criterion": sel.criterion,
        "candidates": [{"model": r[0], "criterion": r[1], "j_statistic": r[2], "j_p_value": r[3], "parameters": r[4],
                        "set_aside": r[5]} for r in sel.candidates[:10]],
        "ieee_readoffs": read,
        "curve": {"tau_s": tau.tolist(), "m": sv.m.tolist(), "scale_index_j": sv.scale_index.tolist(),
                  "adev": units.from_si(sv.adev[:, c], rate_unit).tolist(),
                  "adev_lower_95": units.from_si(np.sqrt(2 * lo[:, c]), rate_unit).tolist(),
                  "adev_upper_95": units.from_si(np.sqrt(2 * hi[:, c]), rate_unit).tolist(),
                  "adev_fit": units.from_si(np.sqrt(contrib.sum(axis=1)), rate_unit).tolist(),
                  "adev_terms": {t.code + (str(i) if t.code == "GM" else ""): units.from_si(np.sqrt(contrib[:, i]), rate_unit).tolist()
                                 for i, t in enumerate(f.terms)},
                  "unit": rate_unit},
    }


def ieee_readoffs(sv: ScaleVariance, c: int, kind: str) -> dict:
    """Channel ``c``'s IEEE read-offs in field units, on the octave scales (one grid for ``noise`` and
    ``allan``), each with the tau it was read at and the equivalent degrees of freedom there."""
    fu = nm.FIELD_UNITS[kind]
    oct_ = np.isin(sv.m, octave_scales(sv.n))
    if oct_.sum() < 3:
        oct_[:] = True
    ro = readoffs(sv.taus[oct_], sv.adev[oct_, c], sv.edf[oct_])
    read = {}
    for code, d in ro.items():
        key = {"QN": "q", "WN": "n", "BI": "b", "RW": "k", "DR": "r"}[code]
        read[code] = {"value": float(units.from_si(d["value"], fu[key])), "unit": fu[key], "read_at_tau_s": d["tau_s"],
                      "edf": d["edf"] if math.isfinite(d["edf"]) else None}
        if "flat_bottom" in d:
            read[code]["flat_bottom"] = d["flat_bottom"]
    return read


def allan_view(scan: Scan, model: str, rng: np.random.Generator) -> dict:
    """What ``inscal allan`` shows, from the noise engine: the octave Allan deviation of the six
    channels (SI), and per channel the white-noise density N of the identified model (``model``,
    default ``auto``: the same value and 95 % interval ``inscal noise`` gives) with its source, and
    the IEEE read-offs (B with its tau and degrees of freedom)."""
    sv = scan.sv
    oct_ = np.isin(sv.m, octave_scales(sv.n)) & (sv.n_terms > 1)
    out = {"taus_s": sv.taus[oct_], "adev": sv.adev[oct_], "edf": sv.edf[oct_], "channels": []}
    for c, name in enumerate(CHANNELS):
        kind = KINDS[name]
        read = ieee_readoffs(sv, c, kind)
        curve = octave_curve(sv, c)
        f = None
        if np.all(curve.wv > 0) and np.all(np.isfinite(curve.wv)):
            try:
                f = identify_curve(curve, model, rng).chosen
            except (ValueError, np.linalg.LinAlgError):
                f = None  # a curve the engine cannot fit: the read-off, said so
        if f is None:
            v = float(units.to_si(read["WN"]["value"], read["WN"]["unit"]))
            out["channels"].append({"name": name, "kind": kind, "model": "none", "white": (v, math.nan, math.nan),
                                    "white_source": "IEEE read-off (no model fits this channel: constant or "
                                                    "noise-free?)", "readoffs": read})
            continue
        if "WN.n" in f.names:
            i = f.names.index("WN.n")
            n = (f.values[i], f.lower[i], f.upper[i])
            src = f"WN term of {f.model} ({'auto' if model == 'auto' else 'as asked'})"
        else:
            v = float(units.to_si(read["WN"]["value"], read["WN"]["unit"]))
            n = (v, math.nan, math.nan)
            src = f"IEEE read-off at tau = {read['WN']['read_at_tau_s']:.3g} s ({f.model} has no WN term)"
        out["channels"].append({"name": name, "kind": kind, "model": f.model, "white": n, "white_source": src,
                                "readoffs": read})
    return out


def noise_model(names, kinds, selections, rate_hz: float) -> nm.NoiseModel:
    """The :class:`~inscal.core.noise_models.NoiseModel` of the chosen fits: one channel per name,
    of kind ``kinds`` ('gyro' or 'accel'), identified at ``rate_hz`` [Hz]."""
    return nm.NoiseModel(tuple(nm.ChannelNoise(n, k, s.chosen.terms) for n, k, s in zip(names, kinds, selections)),
                         rate_hz)


def parse_curve_csv(text: str, where: str) -> tuple[str, Curve]:
    """A curve computed elsewhere: CSV rows ``tau_s, value, lower, upper`` under a header naming the
    quantity (``avar``, ``adev`` or ``wvar`` as the second column's name) and a sample interval as a
    comment ``# dt_s = 0.01``.  The octave scales m = tau / dt are kept; each point's equivalent
    degrees of freedom come from the ratio of its interval's bounds (the chi-square interval)."""
    dt = None
    rows = []
    header = None
    for ln, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            if "dt_s" in s:
                if dt is not None:
                    raise NoiseInputError(f"{where} line {ln}: a second '# dt_s' line; give the sample interval once")
                try:
                    dt = float(s.split("=", 1)[1])
                except (IndexError, ValueError):
                    raise NoiseInputError(f"{where} line {ln}: write the sample interval as '# dt_s = 0.01'") from None
            continue
        cells = [c.strip() for c in s.split(",")]
        if header is None:
            header = [c.lower() for c in cells]
            if len(header) != 4 or header[0] != "tau_s" or header[1] not in ("avar", "adev", "wvar"):
                raise NoiseInputError(f"{where}: the header must be 'tau_s,<avar|adev|wvar>,lower,upper' (SI units), "
                                      f"got {s[:80]!r}")
            continue
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            raise NoiseInputError(f"{where} line {ln}: not four numbers: {s[:80]!r}") from None
        if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
            raise NoiseInputError(f"{where} line {ln}: need four finite numbers (tau_s, value, lower, upper)")
        if not (vals[0] > 0 and 0 < vals[2] <= vals[1] <= vals[3]):
            raise NoiseInputError(f"{where} line {ln}: need tau > 0 and 0 < lower <= value <= upper")
        if not vals[2] < vals[3]:
            raise NoiseInputError(f"{where} line {ln}: the interval has zero width (lower = upper = {vals[3]:g}): "
                                  "its weight 1/(upper - lower)^2 would be infinite; give its 95 % interval")
        if len(rows) == MAX_CURVE_POINTS:
            raise NoiseInputError(f"{where}: more than {MAX_CURVE_POINTS} points (the limit: one per octave of a "
                                  f"2^{MAX_CURVE_POINTS}-sample record); give an octave curve, tau = dt, 2 dt, 4 dt ...")
        rows.append(vals)
    if header is None or len(rows) < 3:
        raise NoiseInputError(f"{where}: fewer than 3 points")
    if dt is None:
        raise NoiseInputError(f"{where}: no sample interval; add a line '# dt_s = <seconds>'")
    if not DT_RANGE[0] <= dt <= DT_RANGE[1]:
        raise NoiseInputError(f"{where}: the sample interval dt_s = {dt:g} s is not one of an IMU (give "
                              f"{DT_RANGE[0]:g} .. {DT_RANGE[1]:g} s, as '# dt_s = 0.01')")
    a = np.array(rows)
    quantity = header[1]
    with np.errstate(over="ignore", under="ignore"):
        if quantity == "adev":
            a[:, 1:] = a[:, 1:] ** 2
        if quantity in ("adev", "avar"):
            a[:, 1:] /= 2.0  # AVAR = 2 WV
    lo_v, hi_v = CURVE_RANGE
    if not np.all((a[:, 1:] >= lo_v) & (a[:, 1:] <= hi_v)):
        k = int(np.argmax(~np.all((a[:, 1:] >= lo_v) & (a[:, 1:] <= hi_v), axis=1)))
        raise NoiseInputError(f"{where}: point {k + 1} (tau = {a[k, 0]:g} s) is outside the {quantity} values "
                              f"inscal fits (wavelet variance {lo_v:g} .. {hi_v:g} in SI units): is it in SI?")
    m = a[:, 0] / dt
    if not np.all(m <= 2.0 ** 53):
        raise NoiseInputError(f"{where}: tau up to {a[-1, 0]:g} s is more than 2^53 samples of dt_s = {dt:g} s")
    if np.any(np.abs(m - np.round(m)) > 1e-6 * m) or np.any(np.diff(m) <= 0) or np.round(m[0]) < 1:
        raise NoiseInputError(f"{where}: tau must be increasing whole multiples of dt_s = {dt:g} s")
    edf = np.array([_edf_from_ratio(u / lo) for lo, u in zip(a[:, 2], a[:, 3])])
    return quantity, Curve(np.round(m), dt, a[:, 1], a[:, 2], a[:, 3], edf * 2 * np.round(m))


def _edf_from_ratio(ratio: float) -> float:
    """The degrees of freedom whose 95 % chi-square interval has upper/lower = ``ratio``."""
    lo_e, hi_e = 0.1, 1e9
    for _ in range(200):
        e = math.sqrt(lo_e * hi_e)
        lo, hi = chi2_bounds([e])
        if hi[0] / lo[0] > ratio:
            lo_e = e
        else:
            hi_e = e
    return e
