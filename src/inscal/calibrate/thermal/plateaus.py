"""Temperature plateaus of a record and the record-like part of the record on each (see
:mod:`inscal.calibrate.thermal`): the chamber's transitions in the path, or intervals where the
temperature holds; the path cut exactly at rest."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.calibrate.windows import CalibrationError
from inscal.core.samples import SampleSpan
from inscal.core.thermal import select_sensor, temperature_rate
from inscal.core.turntable import Move, RotationPath

#: label prefix of the chamber's transition moves (the simulator's ``sim.scenarios.CHAMBER_LABEL``)
CHAMBER_LABEL = "chamber"
#: a plateau's readings stay within this of their mean [degC]
PLATEAU_TOL_C = 0.5
#: the shortest plateau found in the temperature alone [s]
MIN_PLATEAU_S = 600.0


@dataclass(frozen=True)
class Plateau:
    """One temperature plateau of a record: the cut ``[t0, t1]`` [s, record clock], the samples
    ``i0 .. i1 - 1`` it holds, the mean temperature of the sensor over it and their spread [degC]."""

    index: int
    t0: float
    t1: float
    i0: int
    i1: int
    temperature_c: float
    spread_c: float
    min_c: float
    max_c: float
    label: str = ""

    @property
    def duration(self) -> float:
        return self.t1 - self.t0

    def to_json(self) -> dict:
        return {"index": self.index, "start_s": self.t0, "end_s": self.t1, "duration_s": self.duration,
                "samples": self.i1 - self.i0, "temperature_c": self.temperature_c, "spread_c": self.spread_c,
                "min_c": self.min_c, "max_c": self.max_c, "label": self.label}


@dataclass
class PlateauRecord(SampleSpan):
    """A plateau as a record of its own (what the calibration methods take): time rebased to 0 at the
    cut, the increments, the encoder angles (or None), the cut path (or None), rate and site."""

    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    gimbal: np.ndarray | None
    rate_hz: float
    site: object
    path: RotationPath | None
    plateau: Plateau
    scenario: str = ""
    temperature: None = None  # constant on a plateau: the per-plateau methods calibrate at one temperature


def _move_spans(path: RotationPath) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per move: its start, the end of its motion (= start for a pure dwell) and its end [s]."""
    seg = path.segments()
    n = len(path.moves)
    start, motion_end, end = np.empty(n), np.empty(n), np.empty(n)
    t = float(path.initial_dwell) if path.initial_dwell > 0 else 0.0
    moving = (np.abs(seg.w0).sum(axis=1) + np.abs(seg.acc).sum(axis=1)) > 0
    for k in range(n):
        mine = np.flatnonzero(seg.move_index == k)
        if mine.size == 0:  # a zero-length move
            start[k] = motion_end[k] = end[k] = t
            continue
        start[k] = float(seg.t0[mine[0]])
        end[k] = float(seg.t1[mine[-1]])
        mov = mine[moving[mine]]
        motion_end[k] = float(seg.t1[mov[-1]]) if mov.size else start[k]
        t = end[k]
    return start, motion_end, end


def cut_path(path: RotationPath, a: float, b: float, name: str | None = None) -> tuple[RotationPath, float, float]:
    """The part of ``path`` between times ``a`` and ``b`` as a path of its own, and the cut ``(a, b)``
    actually taken: a cut inside a rotation moves to the static instant after it (``a``) or before it
    (``b``), so the part starts and ends at rest and its angles follow the original exactly (the part's
    time 0 is the original's ``a``)."""
    start, motion_end, end = _move_spans(path)
    n = len(path.moves)
    a, b = float(a), float(b)
    # the move whose span holds a (-1: the initial dwell)
    k = -1 if a < (start[0] if n else math.inf) else int(np.searchsorted(end, a, side="right"))
    if k >= n:
        raise CalibrationError(f"cut at {a:.3f} s is after the end of path {path.name!r} ({end[-1]:.3f} s)")
    if k >= 0 and a < motion_end[k]:
        a = float(motion_end[k])  # inside a rotation: from its end
    first_end = float(path.initial_dwell) if k < 0 else float(end[k])
    j = int(np.searchsorted(end, b, side="left")) if n else -1
    j = min(j, n - 1)
    if j >= 0 and b < start[j]:
        j -= 1
    if j >= 0 and b < motion_end[j]:  # inside a rotation: up to its start
        b = float(start[j])
        j -= 1
    if b <= a:
        raise CalibrationError(f"nothing of path {path.name!r} lies at rest between {a:.3f} and {b:.3f} s")
    th = path.segments().angles(np.array([a]))[0][0]
    moves = list(path.moves[k + 1:j + 1]) if j > k else []
    if moves:
        last = moves[-1]
        moves[-1] = Move(last.axis, last.angle, last.rate, max(0.0, min(last.dwell, b - motion_end[j])), last.label)
        dwell0 = first_end - a
    else:  # the whole part is one dwell
        moves = [Move("none", dwell=b - a, label=path.moves[k].label if k >= 0 else "")]
        dwell0 = 0.0
    trial = RotationPath(name or f"{path.name}[{a:g}-{b:g} s]", tuple(moves), accel=path.accel,
                         initial=(float(th[0]), float(th[1])), initial_dwell=dwell0, closed=False)
    end_th = trial.final_angles()
    closed = all(abs(math.remainder(end_th[i] - trial.initial[i], 2 * math.pi)) < 1e-9 for i in range(2))
    return (RotationPath(trial.name, trial.moves, accel=trial.accel, initial=trial.initial,
                         initial_dwell=trial.initial_dwell, closed=closed), a, b)


def _temperature(record_like, sensor: str) -> tuple[np.ndarray, np.ndarray]:
    temp = getattr(record_like, "temperature", None)
    if temp is None:
        raise CalibrationError("the record has no temperature: plateaus need the sensor readings (/temperature)")
    try:
        T = select_sensor(temp.values, temp.sensors, sensor)
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    return np.asarray(temp.time, dtype=float), np.asarray(T, dtype=float)


def _stats(tt: np.ndarray, T: np.ndarray, a: float, b: float) -> tuple[float, float, float, float]:
    """Mean, standard deviation, min and max of the readings in ``[a, b]`` (interpolated at the middle
    when the sensor has no reading inside)."""
    m = (tt >= a) & (tt <= b)
    if not np.any(m):
        v = float(np.interp(0.5 * (a + b), tt, T))
        return v, 0.0, v, v
    x = T[m]
    return float(np.mean(x)), float(np.std(x)), float(np.min(x)), float(np.max(x))


def _sample_range(time: np.ndarray, rate_hz: float, a: float, b: float) -> tuple[int, int]:
    """Samples whose interval ``(t - 1/rate, t]`` lies inside ``[a, b]``."""
    dt = 1.0 / rate_hz
    eps = 1e-6 * dt
    i0 = int(np.searchsorted(time - dt, a - eps, side="left"))
    i1 = int(np.searchsorted(time, b + eps, side="right"))
    return i0, max(i0, i1)


def chamber_cuts(path: RotationPath, chamber_label: str) -> list[tuple[float, float, str]] | None:
    """The copies of the base path between the chamber's transitions, ``[(a, b, label)]`` (see the
    module docstring), or None when the path has no transition labelled ``chamber_label``."""
    lab = chamber_label.strip().lower()
    idx = [k for k, m in enumerate(path.moves) if m.axis == "none" and lab and m.label.strip().lower().startswith(lab)]
    if not idx:
        return None
    start, _, end = _move_spans(path)
    cuts, a, label = [], 0.0, "start"
    for k in idx:
        if start[k] > a:
            cuts.append((a, float(start[k]), label))
        a = max(float(start[k]), float(end[k]) - float(path.initial_dwell))
        label = path.moves[k].label
    total = float(end[-1])
    if total > a:
        cuts.append((a, total, label))
    return cuts


def moving_mean(tt: np.ndarray, T: np.ndarray, window_s: float) -> np.ndarray:
    """The mean of the readings within ``window_s / 2`` of each reading (any time grid)."""
    cs = np.concatenate([[0.0], np.cumsum(T)])
    lo = np.searchsorted(tt, tt - 0.5 * window_s, side="left")
    hi = np.searchsorted(tt, tt + 0.5 * window_s, side="right")
    return (cs[hi] - cs[lo]) / (hi - lo)


def stable_intervals(tt: np.ndarray, T: np.ndarray, tol_c: float, min_s: float) -> list[tuple[int, int]]:
    """Index ranges ``[i, j)`` of the readings where the temperature holds: the least-squares slope over
    ``min_s / 2`` below ``tol_c / min_s`` and the readings, averaged over ``min_s / 2`` (a sensor's white
    noise is no drift), within ``tol_c`` of the mean of the range (max - min <= 2 tol), at least ``min_s``
    long; found greedily from the start."""
    w = 0.5 * min_s
    rate = temperature_rate(tt, T, w)
    S = moving_mean(tt, T, w)
    calm = np.abs(rate) <= tol_c / max(min_s, 1e-9)
    out = []
    n = T.shape[0]
    i = 0
    while i < n:
        if not calm[i]:
            i += 1
            continue
        j, lo, hi = i, S[i], S[i]
        while j < n and calm[j] and max(hi, S[j]) - min(lo, S[j]) <= 2.0 * tol_c:
            lo, hi = min(lo, S[j]), max(hi, S[j])
            j += 1
        if tt[j - 1] - tt[i] >= min_s:
            out.append((i, j))
            i = j
        else:
            i += 1
    return out


def find_plateaus(record_like, sensor: str = "", chamber_label: str | None = CHAMBER_LABEL,
                  plateau_tol: float = PLATEAU_TOL_C, min_plateau_s: float = MIN_PLATEAU_S) -> list[Plateau]:
    """The temperature plateaus of a record (see the module docstring); raises :class:`CalibrationError`
    in one line when there is no temperature or a chamber-labelled copy is not on a plateau."""
    if not (math.isfinite(plateau_tol) and plateau_tol > 0):
        raise CalibrationError(f"plateau tolerance must be > 0 degC, got {plateau_tol}")
    if not (math.isfinite(min_plateau_s) and min_plateau_s > 0):
        raise CalibrationError(f"shortest plateau must be > 0 s, got {min_plateau_s}")
    tt, T = _temperature(record_like, sensor)
    time = np.asarray(record_like.time, dtype=float)
    rate_hz = float(record_like.rate_hz)
    if time.shape[0] == 0:
        raise CalibrationError("the record has no samples")
    t_first, t_last = float(time[0] - 1.0 / rate_hz), float(time[-1])
    path = getattr(record_like, "path", None)
    cuts = chamber_cuts(path, chamber_label) if (path is not None and chamber_label) else None
    plateaus = []
    if cuts is not None:
        for a, b, label in cuts:
            if b > t_last + 1.0 / rate_hz:  # the record stops before the path: cut at its last sample
                b = t_last
            if b - a <= 0:
                continue
            mean, sd, lo, hi = _stats(tt, T, a, b)
            inside = (tt >= a) & (tt <= b)  # drift within the copy, not the sensor's white noise
            smooth = moving_mean(tt[inside], T[inside], 0.5 * min_plateau_s) if np.any(inside) else np.array([mean])
            slo, shi = float(np.min(smooth)), float(np.max(smooth))
            if max(shi - mean, mean - slo) > plateau_tol:
                raise CalibrationError(
                    f"copy {len(plateaus) + 1} of the path ({a:.0f}-{b:.0f} s, after {label!r}) is not on a plateau: "
                    f"the temperature spans {slo:.3g} .. {shi:.3g} degC (averaged over {0.5 * min_plateau_s:g} s; "
                    f"tolerance +-{plateau_tol:g} degC about its mean); "
                    "soak the chamber longer or widen the tolerance")
            i0, i1 = _sample_range(time, rate_hz, a, b)
            plateaus.append(Plateau(len(plateaus), a, b, i0, i1, mean, sd, lo, hi, label))
        return plateaus
    for i, j in stable_intervals(tt, T, plateau_tol, min_plateau_s):
        a, b = max(float(tt[i]), t_first), min(float(tt[j - 1]), t_last)
        if b - a < min_plateau_s:
            continue
        if path is not None:
            try:
                _, a, b = cut_path(path, a, b)
            except CalibrationError:
                continue  # the turntable never rests inside it
        mean, sd, lo, hi = _stats(tt, T, a, b)
        i0, i1 = _sample_range(time, rate_hz, a, b)
        plateaus.append(Plateau(len(plateaus), a, b, i0, i1, mean, sd, lo, hi, f"{mean:.3g} degC"))
    return plateaus


def plateau_records(record_like, plateaus: list[Plateau]) -> list[PlateauRecord]:
    """One record-like object per plateau (time rebased to 0 at the cut; the path cut exactly)."""
    time = np.asarray(record_like.time, dtype=float)
    dth, dv = record_like.dtheta, record_like.dvel
    gim = getattr(record_like, "gimbal", None)
    path = getattr(record_like, "path", None)
    out = []
    for p in plateaus:
        sl = slice(p.i0, p.i1)
        g = None if gim is None else np.asarray(gim[sl], dtype=float)
        sub_path = None
        if path is not None:
            sub_path, _, _ = cut_path(path, p.t0, p.t1, name=f"{path.name}@{p.temperature_c:.4g}degC")
            # whole turns taken off the angles, as the time is rebased: the copy starts where the base path does
            turns = 2.0 * math.pi * np.round(np.asarray(sub_path.initial) / (2.0 * math.pi))
            if np.any(turns):
                sub_path = RotationPath(sub_path.name, sub_path.moves, accel=sub_path.accel,
                                        initial=tuple(float(x) for x in np.asarray(sub_path.initial) - turns),
                                        initial_dwell=sub_path.initial_dwell, closed=sub_path.closed)
                g = None if g is None else g - turns
        out.append(PlateauRecord(time[sl] - p.t0, np.asarray(dth[sl], dtype=float), np.asarray(dv[sl], dtype=float),
                                 g, float(record_like.rate_hz), record_like.site, sub_path, p,
                                 str(getattr(record_like, "scenario", "") or "")))
    return out
