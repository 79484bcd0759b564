"""Plausibility checks of imported data: finite values, a regular time base in the declared unit,
physically possible values, constant or saturated channels, increment magnitudes against Earth rate
and gravity, encoder angles against the gyros.

Physical limits (:func:`check_values`, :func:`~inscal.io.formats.base.check_angles`; constants in
:mod:`inscal.io.mapping`; not skippable: a value beyond them is not IMU data, and the arithmetic
downstream would only overflow): an angular rate of ``MAX_RATE`` (100 rev/s = 36,000 deg/s, an
order above the widest-range MEMS gyros and 36 times a fast turntable's 1,000 deg/s), a specific
force of ``MAX_ACCEL`` (1,000 g, 20 times a tactical accelerometer's 50 g range), a gimbal angle
of ``MAX_ANGLE`` (1.6 million turns, 19 days at 1 rev/s) or a jump between two encoder readings of
more than a wrap (2 pi) plus ``MAX_RATE`` times the interval, and a timestamp of ``MAX_TIME``
(1e12 s, 31,700 years: a Unix time in seconds is 1.7e9).

Time unit (:func:`time_base`, :func:`check_magnitudes`): an IMU samples at ``MIN_RATE_HZ`` (2/3
Hz) to ``MAX_RATE_HZ`` (50 kHz); a median interval outside that range, which a factor of 1e3, 1e6 or 1e9
brings inside, is a time column in milliseconds, microseconds or nanoseconds read as seconds (or
seconds declared as milliseconds), and so is an accelerometer magnitude of 1e-3 (1e-6) times
gravity from increments over a time column: the increments are divided by an interval 1e3 (1e6)
times too long.  The message names the unit and how to set it (:attr:`Raw.time_fix`).

Temperature readings (:func:`check_temperature`): every sensor has at least one reading, every reading
lies in the plausible span :data:`~inscal.io.records.TEMPERATURE_SPAN` once converted from its
declared unit (kelvin declared as degC reads 293 degC: the message names the unit that would make the
column plausible, K, degC or degF, and how to declare it).
"""

from __future__ import annotations

import json
import math

import numpy as np

from inscal.core import earth, units
from inscal.core.earth import Site
from inscal.core.units import DEG
from inscal.io.encoders import EncoderCheck, compare_encoders
from inscal.io.formats.base import Raw, RawTemperature, check_angles
from inscal.io.mapping import (
    CHECKS,
    JITTER_TOL,
    MAX_ACCEL,
    MAX_RATE,
    MAX_RATE_HZ,
    MAX_TIME,
    MIN_RATE_HZ,
    REGRID_TOL,
    TIME_FACTORS,
    ImportFileError,
)
from inscal.io.records import TEMPERATURE_SPAN, DataFileError, Temperature

#: the checks ``skip`` may name: the mapping's, and ``encoders`` (:func:`check_encoders`)
SKIPPABLE = CHECKS + ("encoders",)


# ----------------------------------------------------------------------------- checks
def check_finite(raw: Raw, where: str) -> None:
    """Refuse (:class:`~inscal.io.mapping.ImportFileError`) a NaN or Inf in the time, the six sensor channels or the gimbal
    angles, naming the channel, how many and the first line or row.
    """
    chans = [(raw.time_label, raw.time)] if raw.time is not None else []
    chans += [(raw.labels[k], raw.raw_channels[:, k]) for k in range(6)]
    if raw.gimbal is not None:
        chans += [("outer angle", raw.gimbal[:, 0]), ("inner angle", raw.gimbal[:, 1])]
    for name, x in chans:
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.argmax(bad))
            raise ImportFileError(f"{where}: {name} has {int(bad.sum())} NaN/Inf value(s), first at {raw.at(k)}{raw.hint}")


def check_integers(raw: Raw, where: str) -> None:
    """Refuse a sensor channel that holds only whole numbers while its unit is not ``counts``: integer
    counts read as physical units (the message names the mapping's ``counts`` and its scale).
    """
    for k in range(6):
        if raw.counts[k // 3]:
            continue
        # every double from 2^52 up is a whole number: such values (1e300) say nothing of counts, and are
        # check_values' business
        x = raw.raw_channels[:, k]
        x = x[np.abs(x) < 2.0**52]
        if x.size and np.ptp(x) > 0 and np.all(x == np.round(x)):
            which = "gyro" if k < 3 else "accel"
            raise ImportFileError(f"{where}: {raw.labels[k]} holds only whole numbers (e.g. {x[np.argmax(x != 0)]:g}): "
                                  f"integer data (raw counts? import them as csv/txt with {which} = \"counts\" and "
                                  f"{which}_scale in the mapping)")


def _time_candidates(declared: float) -> list[float]:
    """Factors ``rho`` (the interval as read over the true one) of the units a time column could really be
    in (seconds, or :data:`~inscal.io.mapping.TIME_FACTORS` below them) other than the ``declared`` one's
    SI factor, the smallest correction first."""
    true = [1.0] + [1.0 / f for f, _ in TIME_FACTORS]
    return sorted((declared / f for f in true if not math.isclose(f, declared)),
                  key=lambda r: abs(math.log(r)))


def _time_name(factor: float) -> str:
    """The name of the time unit of SI ``factor`` (seconds, milliseconds, ..., minutes, hours)."""
    names = {1.0: "seconds", 60.0: "minutes", 3600.0: "hours", **{1.0 / f: name for f, name in TIME_FACTORS}}
    return names[min(names, key=lambda f: abs(math.log(f / factor)))]


def time_unit_message(raw: Raw, where: str, rho: float, evidence: str) -> str:
    """The one line for a time column whose values are read ``rho`` times too long (declared seconds,
    really milliseconds: ``rho`` = 1000), with ``evidence`` and how to declare the real unit
    (:attr:`Raw.time_fix` with the unit, or, for a unit inscal has none of, how to convert)."""
    declared = float(units.to_si(1.0, raw.time_unit, "time"))
    true = declared / rho
    unit = next((u for u, f in units.FACTOR.items() if units.KIND[u] == "time" and math.isclose(f, true)), None)
    if unit is not None and raw.time_fix:
        fix = raw.time_fix.format(unit=unit, factor=f"{rho:g}")
    else:
        known = ", ".join(u for u, k in units.KIND.items() if k == "time")
        fix = (f"convert it to seconds before importing (divide by {rho:g}; the time units inscal reads: {known})"
               if rho > 1 else f"convert it to seconds before importing (the time units inscal reads: {known})")
    col = raw.time_label.replace("time", "the time column", 1)
    return (f"{where}: {col} looks like {_time_name(true)}, not {_time_name(declared)} ({evidence}); {fix}"
            f"{raw.hint}")


def _per_second(hz: float) -> str:
    return f"{hz / 1e3:.6g} kHz" if hz >= 1e3 else f"{hz:.6g} Hz"


def _check_time_values(raw: Raw, where: str) -> None:
    """Timestamps beyond :data:`MAX_TIME` while most of the column is within it, and single values out
    of line with both neighbours (a corrupt row): named with their row, before the steps are judged."""
    t = raw.time
    with np.errstate(all="ignore"):
        big = np.abs(t) > MAX_TIME
    if big.any() and float(np.median(np.abs(t))) <= MAX_TIME:
        k = int(np.argmax(big))
        raise ImportFileError(f"{where}: {raw.time_label} is {t[k]:.6g} s at {raw.at(k)}: beyond any clock (limit "
                              f"{MAX_TIME:.0e} s, 31,700 years; the column's median is {float(np.median(t)):.6g} s)"
                              f"{raw.hint}")
    if t.size < 3:
        return
    with np.errstate(all="ignore"):
        st = np.diff(t)
        # t[k] far above both neighbours (ten steps) while they are in order: not two rows swapped but one value
        # that does not belong
        far = 10.0 * float(np.median(np.abs(st)))
        spike = (st[:-1] > far) & (st[1:] < -far) & (t[2:] > t[:-2])
    if spike.any():
        k = int(np.argmax(spike)) + 1
        raise ImportFileError(f"{where}: {raw.time_label} is {t[k]:.9g} s at {raw.at(k)}, out of line with its "
                              f"neighbours ({t[k - 1]:.9g} and {t[k + 1]:.9g} s): a corrupt timestamp{raw.hint}")


def _check_time_unit(raw: Raw, st: np.ndarray, rate_hz: float | None, where: str) -> None:
    """A median sample interval that a factor of 1e3, 1e6 or 1e9 explains: against ``rate_hz`` when it
    is given, else against the rates an IMU samples at (module docstring)."""
    med = float(np.median(st))
    declared = float(units.to_si(1.0, raw.time_unit, "time"))
    shown = f"median sample interval {med / declared:.6g} {raw.time_unit}"
    if rate_hz is not None:
        for rho in _time_candidates(declared):
            if abs(med * rate_hz / rho - 1.0) < 0.01:
                raise ImportFileError(time_unit_message(
                    raw, where, rho, f"{shown}, {med * rate_hz:.6g} times the {1.0 / rate_hz:.6g} s of --rate-hz "
                    f"{rate_hz:g}"))
        return
    lo, hi = 1.0 / MAX_RATE_HZ, 1.0 / MIN_RATE_HZ
    if lo <= med <= hi:
        return
    for rho in _time_candidates(declared):
        if lo <= med / rho <= hi:
            raise ImportFileError(time_unit_message(
                raw, where, rho, f"{shown}: {_per_second(1.0 / med)} as read, {_per_second(rho / med)} as "
                f"{_time_name(declared / rho)}; if the samples really are {med:.6g} s apart, give --rate-hz "
                f"{1.0 / med:.6g}"))
    raise ImportFileError(f"{where}: {raw.time_label}: {shown} ({med:.6g} s) is no IMU's (expected {lo:g} .. {hi:g} "
                          f"s, {MIN_RATE_HZ:.3g} Hz .. {MAX_RATE_HZ / 1e3:g} kHz): the wrong column, or a unit inscal "
                          f"does not read?{raw.hint}")


def time_base(raw: Raw, n: int, rate_hz: float | None, where: str) -> tuple[np.ndarray, float, dict]:
    """Check the timestamps and return ``(time [s], rate [Hz], info)``."""
    info: dict = {"regridded": False}
    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ImportFileError(f"--rate-hz must be positive, got {rate_hz:g}")
    if raw.time is None:
        if rate_hz is None:
            raise ImportFileError(f"{where}: no time column; give --rate-hz (samples are then taken as uniform)")
        info["time_column"] = False
        return (np.arange(n) + 1.0) / rate_hz, float(rate_hz), info
    t = raw.time
    name = raw.time_label
    _check_time_values(raw, where)
    st = np.diff(t)
    back = np.flatnonzero(st < 0)
    if back.size:
        k = int(back[0])
        raise ImportFileError(f"{where}: {name} goes backwards at {raw.at(k + 1)} (t = {t[k + 1]:.9g} s after "
                              f"{t[k]:.9g} s; {back.size} backward step(s)){raw.hint}")
    rep = np.flatnonzero(st == 0)
    if rep.size:
        k = int(rep[0])
        raise ImportFileError(f"{where}: {name} repeats at {raw.at(k + 1)} (t = {t[k]:.9g} s twice; "
                              f"{rep.size} repeated timestamp(s)){raw.hint}")
    _check_time_unit(raw, st, rate_hz, where)
    if np.all(np.abs(t) > MAX_TIME):
        raise ImportFileError(f"{where}: {name} reads {t[0]:.6g} .. {t[-1]:.6g} s: beyond any clock (limit "
                              f"{MAX_TIME:.0e} s, 31,700 years){raw.hint}")
    med = float(np.median(st))
    gaps = np.flatnonzero(st > 1.5 * med)
    if gaps.size:
        k = int(gaps[np.argmax(st[gaps])])
        raise ImportFileError(
            f"{where}: {name} has {gaps.size} gap(s) over 1.5 sample intervals; the largest is {st[k]:.6g} s "
            f"(about {int(round(st[k] / med)) - 1} missing sample(s)) at {raw.at(k + 1)} (t = {t[k]:.9g} -> "
            f"{t[k + 1]:.9g} s){raw.hint}")
    dt_est = float((t[-1] - t[0]) / (n - 1))
    info["largest_step_s"] = float(st.max())
    jitter = float(np.max(np.abs(st - dt_est)) / dt_est)
    info["jitter"] = jitter
    if rate_hz is None:
        if jitter > JITTER_TOL:
            k = int(np.argmax(np.abs(st - dt_est)))
            raise ImportFileError(
                f"{where}: {name} is not uniform: steps vary by up to {jitter:.3g} of the {dt_est:.6g} s interval "
                f"(limit {JITTER_TOL:g}; worst at {raw.at(k + 1)}, t = {t[k + 1]:.9g} s); if the timestamps are "
                f"only quantised, give --rate-hz to rebuild a uniform time base{raw.hint}")
        r = 1.0 / dt_est
        for d in range(0, 7):  # a rate written with few digits (e.g. 100, 200.5) is taken as exact
            rr = round(r, d)
            if abs(rr - r) <= 1e-9 * r:
                r = rr
                break
        return t, float(r), info
    nominal = 1.0 / rate_hz
    if abs(med / nominal - 1.0) > 1e-3 or abs(dt_est / nominal - 1.0) > 1e-4:
        raise ImportFileError(
            f"{where}: --rate-hz {rate_hz:g} is inconsistent with the timestamps: {1.0 / dt_est:.9g} Hz from the first "
            f"to the last sample (median step {med:.6g} s){raw.hint}")
    if jitter <= JITTER_TOL:
        return t, float(rate_hz), info
    if jitter > REGRID_TOL:
        k = int(np.argmax(np.abs(st - dt_est)))
        raise ImportFileError(f"{where}: {name} is irregular: steps vary by up to {jitter:.3g} of the sample interval "
                              f"(limit {REGRID_TOL:g} with --rate-hz; worst at {raw.at(k + 1)}){raw.hint}")
    k = np.arange(n)
    t0 = float(np.mean(t - k * nominal))
    info["regridded"] = True
    return t0 + k * nominal, float(rate_hz), info


def check_values(raw: Raw, rate_hz: float, where: str, gyro_unit: str = "rad", accel_unit: str = "m/s") -> None:
    """Every value within the physical limits (module docstring): the rate of each gyro and the specific
    force of each accelerometer (an increment over the sample interval ``1 / rate_hz``, or the rate
    itself), and the gimbal angles.  The first value beyond a limit is named with its file, column,
    row, value as read and the limit."""
    inc = raw.kind == "increments"
    dt = 1.0 / rate_hz
    for k in range(6):
        si = (raw.gyro if k < 3 else raw.accel)[:, raw.axes[k % 3]]
        with np.errstate(all="ignore"):
            per_s = np.abs(si) * (rate_hz if inc else 1.0)
        lim = MAX_RATE if k < 3 else MAX_ACCEL
        bad = np.flatnonzero(per_s > lim)
        if not bad.size:
            continue
        i = int(bad[0])
        unit = gyro_unit if k < 3 else accel_unit
        how = f"an increment in {unit} over {dt:.6g} s" if inc else f"a rate in {unit}"
        more = f"; {bad.size} such values" if bad.size > 1 else ""
        if bad.size > 0.5 * per_s.size:
            more = f"; {bad.size} of the {per_s.size} values: a unit or scale error, not a corrupt value"
        if k < 3:
            what = (f"an angular rate of {per_s[i]:.3g} rad/s ({per_s[i] / DEG:.3g} deg/s, {how}), beyond any gyro "
                    f"(limit {MAX_RATE:.0f} rad/s = 100 rev/s)")
        else:
            what = (f"a specific force of {per_s[i]:.3g} m/s^2 ({per_s[i] / units.G0:.3g} g, {how}), beyond any "
                    f"accelerometer (limit {MAX_ACCEL / units.G0:.0f} g)")
        raise ImportFileError(f"{where}: {raw.labels[k]} is {raw.raw_channels[i, k]:.6g} at {raw.at(i)}: {what}{more}")
    if raw.gimbal is not None:
        check_angles(raw.gimbal, dt, where, raw.at)


def check_constant(raw: Raw, where: str) -> None:
    """Refuse a sensor channel that is constant over the whole file: a dead or disconnected channel
    (``--skip-check constant`` imports anyway).
    """
    for k in range(6):
        x = raw.raw_channels[:, k]
        if np.ptp(x) == 0:
            raise ImportFileError(f"{where}: {raw.labels[k]} is constant ({x[0]:g}) over all {x.size} samples: "
                                  "a dead or disconnected channel (--skip-check constant to import anyway)")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


#: the longest run of one channel pinned at its extreme that is marked rather than refused [s]: a fast hand
#: turn holds a consumer gyro at its range for a fraction of a second; a channel stuck longer is not a turn
MAX_PINNED_S = 2.0
#: the largest share of a channel's samples that may be pinned at its extreme and marked
MAX_PINNED_SHARE = 0.05


def check_saturation(raw: Raw, where: str, min_run: int = 5, rel: float = 1e-7, noisy: float = 0.9,
                     rate_hz: float | None = None) -> list[dict]:
    """The runs of a noisy channel pinned at its maximum or minimum for ``min_run`` samples while another
    channel moves: a sensor at its range (a gyro in a fast hand turn).  Returned as marks, one per run
    (``channel``, ``level`` in the file's values, ``word`` maximum | minimum, ``first`` row index and
    ``samples``), which the record keeps (:func:`saturated_samples`) so the calibrations leave those samples
    out; refused (:class:`~inscal.io.mapping.ImportFileError`) when a channel is pinned longer than
    :data:`MAX_PINNED_S` (at ``rate_hz``) or on more than :data:`MAX_PINNED_SHARE` of its samples: a stuck
    channel, not a turn.

    Only channels that change on at least ``noisy`` of their other samples are judged: in
    noise-free or coarsely quantised data repeated values are normal (a constant-rate turn
    reads the same on every sample)."""
    x6 = raw.raw_channels
    span = np.ptp(x6, axis=0)
    marks = []
    for k in range(6):
        x = x6[:, k]
        if span[k] == 0:  # constant: the constant check's business
            continue
        pinned = 0
        for lim, word in ((x.max(), "maximum"), (x.min(), "minimum")):
            at = x == lim
            if at.sum() < min_run:
                continue
            for a, b in _runs(at):
                if b - a < min_run:
                    continue
                same = np.delete(np.diff(x) == 0, np.arange(a, b - 1))
                if same.size == 0 or np.mean(same) > 1 - noisy:
                    continue
                others = np.delete(x6[a:b], k, axis=1)
                if not np.any(np.ptp(others, axis=0) > rel * np.delete(span, k)):
                    continue
                pinned += b - a
                marks.append({"channel": raw.labels[k].split(" ")[0], "level": float(lim), "word": word,
                              "first": int(a), "samples": int(b - a)})
        mine = [m_ for m_ in marks if m_["channel"] == raw.labels[k].split(" ")[0]]
        if not mine:
            continue
        top = max(mine, key=lambda m_: m_["samples"])
        why = None
        if rate_hz is not None and top["samples"] / rate_hz > MAX_PINNED_S:
            why = f"{top['samples'] / rate_hz:.3g} s, longer than the {MAX_PINNED_S:g} s of a fast turn"
        elif pinned > MAX_PINNED_SHARE * x.size:
            why = f"{pinned} of its {x.size} samples pinned in all, more than {MAX_PINNED_SHARE:.0%}"
        if why is not None:
            raise ImportFileError(
                f"{where}: {raw.labels[k]} looks saturated: pinned at its {top['word']} {top['level']:g} for "
                f"{top['samples']} samples from {raw.at(top['first'])} while the other channels change ({why}: a stuck "
                "channel or a sensor beyond its range; --skip-check saturation to import anyway)")
    return marks


def saturated_spans(marks: list[dict], time: np.ndarray, dt: float) -> list[dict]:
    """The marks of :func:`check_saturation` on the record's time: ``channel``, ``t0`` (start of the first
    pinned sample's interval), ``t1`` (end of the last) [s], ``samples``, ``level``."""
    return [{"channel": m["channel"], "t0": float(time[m["first"]] - dt),
             "t1": float(time[m["first"] + m["samples"] - 1]), "samples": m["samples"], "level": m["level"]}
            for m in marks]


def saturated_samples(time: np.ndarray, source: str | dict | None) -> np.ndarray | None:
    """Bool per sample of a record: its interval overlaps a span its import marked saturated (the record's
    ``source`` attribute, key ``saturated``); None when nothing was marked."""
    if not source:
        return None
    try:
        src = json.loads(source) if isinstance(source, str) else dict(source)
    except (ValueError, TypeError):
        return None
    spans = src.get("saturated") if isinstance(src, dict) else None
    if not spans:
        return None
    t = np.asarray(time, float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    out = np.zeros(t.size, bool)
    for sp in spans:
        out |= (t > float(sp["t0"]) + 1e-9 * dt) & (t - dt < float(sp["t1"]) - 1e-9 * dt)
    return out if out.any() else None


def _blocks(x: np.ndarray, m: int) -> np.ndarray:
    nb = x.shape[0] // m
    return x[: nb * m].reshape(nb, m, -1).sum(axis=1)


#: the largest gyro reading at rest a unit declared by the user (a mapping's ``[units] gyro``, the rad/s of
#: a ROS ``sensor_msgs/Imu``) is trusted with [rad/s]: 10 deg/s, above the turn-on bias of any consumer MEMS
#: gyro (a few deg/s); a declared unit that reads more at rest (arcsec declared as rad: 15 rad/s) cannot be
#: right and is refused
MAX_DECLARED_BIAS = 10.0 * DEG


def check_magnitudes(dth: np.ndarray, dv: np.ndarray, rate_hz: float, site: Site, where: str, kind: str,
                      gyro_unit: str, accel_unit: str, raw: Raw | None = None,
                      declared: str | None = None) -> list[str]:
    """Gravity and Earth rate judged from magnitudes (unit mix-ups give factors far from 1).  With the
    ``raw`` source of increments over a time column, gravity 1e3 (1e6, 1e9) times too small or large
    is named as the time column's unit (:func:`time_unit_message`).

    The gyros: the 5th percentile of their 1-s mean rates, against the Earth rate.  Read 57 times the
    Earth rate, it looks like degrees read as radians, but a MEMS gyro's bias (0.1 .. a few deg/s) reads
    the same; read 1/57 of it, radians read as degrees.  With a ``declared`` gyro unit (its name: the
    user's mapping's, or that of a format whose messages fix it) such a reading is trusted: the finding is returned as a
    warning line with the figure, not raised, up to :data:`MAX_DECLARED_BIAS`; without one (a format's
    default unit, assumed) it is refused.  Returns the warnings."""
    dt = 1.0 / rate_hz
    m = max(1, min(dth.shape[0], int(round(rate_hz))))
    T = m * dt
    f = np.linalg.norm(_blocks(dv, m), axis=1) / T
    w = np.linalg.norm(_blocks(dth, m), axis=1) / T
    g = site.gravity
    ratio = float(np.median(f)) / g
    if raw is not None and raw.time is not None and kind == "increments" and not 0.8 < ratio < 1.2:
        declared_t = float(units.to_si(1.0, raw.time_unit, "time"))
        for rho in _time_candidates(declared_t):
            if 0.8 < ratio * rho < 1.2:  # increments divided by an interval rho times too long
                raise ImportFileError(time_unit_message(
                    raw, where, rho, f"the accelerometers read {ratio * g:.4g} m/s^2 over its {dt:.6g} s interval, "
                    f"{ratio:.3g} of gravity: the interval is " +
                    (f"{rho:g} times too long" if rho > 1 else f"{1 / rho:g} times too short")))
    if not 0.8 < ratio < 1.2:
        guesses = [("g, not m/s^2 (accel unit)", 1.0 / units.G0), ("m/s^2, not g (accel unit)", units.G0),
                   ("rates, not increments", rate_hz), ("increments, not rates", 1.0 / rate_hz),
                   ("mg, not m/s^2", 1e3 / units.G0)]
        why = [s for s, fac in guesses if 0.8 < ratio / fac < 1.2]
        hint = f": the values look like {' or '.join(why)}" if why else ": wrong unit or scale?"
        raise ImportFileError(
            f"{where}: accelerometers read {ratio * g:.6g} m/s^2 (median magnitude, as {kind} in {accel_unit}), "
            f"not gravity {g:.4g} m/s^2{hint} (--skip-check magnitudes to import anyway)")
    p5 = float(np.percentile(w, 5))
    om = earth.OMEGA_IE
    rad = 180.0 / math.pi
    if om * rad / 3 < p5 < om * rad * 3:
        look = "degrees, not radians"
    elif om / rad / 3 < p5 < om / rad * 3:
        look = "radians, not degrees"
    elif om * 206264.8 / 3 < p5 < om * 206264.8 * 3:
        look = "arcsec, not radians"
    else:
        return []
    figure = (f"gyros read at least {p5:.4g} rad/s ({p5 / DEG:.4g} deg/s = {p5 / DEG * 3600:.4g} deg/h, 5th "
              f"percentile of 1-s means, as {kind} in {gyro_unit}) where the Earth rate is {om / DEG * 3600:.4g} deg/h")
    if declared is not None and p5 <= MAX_DECLARED_BIAS:
        why = ("a MEMS gyro's bias reads so; were the values degrees read as radians, every rate would be 57.3 "
               "times too large" if look == "degrees, not radians" else
               "a gyro whose bias cancels the Earth rate reads so; were the values radians read as degrees, every "
               "rate would be 57.3 times too small")
        return [f"{where}: {figure}: kept in the declared unit {declared} ({why}: check the unit if the sensor is "
                "not one that reads so)"]
    raise ImportFileError(
        f"{where}: {figure}: the values look like {look} "
        + ("or a gyro bias far above the Earth rate (a MEMS gyro's; a csv/txt mapping that declares the unit, "
           "[units] gyro, imports it with a warning) " if look == "degrees, not radians" else "")
        + ("beyond any gyro's bias at rest, whatever unit is declared " if declared is not None else "")
        + "(--skip-check magnitudes to import anyway)")


def check_motion(dtheta: np.ndarray, theta: np.ndarray, dt: float, what: str, time: np.ndarray,
                 block_s: float = 0.5, max_fraction: float = 0.005) -> None:
    """The gyros must turn where the gimbal angles ``theta`` (N, 2) turn, and rest where they rest.

    Half-second blocks are compared where the gimbal is clearly static (< 0.02 deg/s) or clearly
    turning at a steady rate (> 1 deg/s) in the block and both neighbours; more than
    ``max_fraction`` of such blocks disagreeing (gyro > 0.5 deg/s at rest, or a turn rate off
    by 20 %) means the angles are not aligned with the increments.
    """
    n = dtheta.shape[0]
    m = max(1, int(round(block_s / dt)))
    nb = n // m
    if nb < 4:
        return
    T = m * dt
    ends = theta[np.arange(nb) * m + m - 1]  # angle at the end of each block
    wg = np.full(nb, np.nan)
    wg[1:] = np.linalg.norm(np.diff(ends, axis=0), axis=1) / T
    wm = np.linalg.norm(_blocks(dtheta, m), axis=1) / T
    static = wg < 0.02 * DEG
    moving = wg > 1.0 * DEG
    cs = static[1:-1] & static[:-2] & static[2:]
    steady = (np.abs(wg[:-2] - wg[1:-1]) < 0.1 * wg[1:-1]) & (np.abs(wg[2:] - wg[1:-1]) < 0.1 * wg[1:-1])
    cm = moving[1:-1] & moving[:-2] & moving[2:] & steady
    # and where the gyros turn steadily (angles in the wrong unit turn 57 times too slowly or too fast,
    # which the two tests above, keyed on the angles, do not see)
    gmov = wm > 1.0 * DEG
    gsteady = (np.abs(wm[:-2] - wm[1:-1]) < 0.1 * wm[1:-1]) & (np.abs(wm[2:] - wm[1:-1]) < 0.1 * wm[1:-1])
    cg = gmov[1:-1] & gmov[:-2] & gmov[2:] & gsteady & np.isfinite(wg[1:-1]) & ~cm
    bad_s = cs & (wm[1:-1] > 0.5 * DEG)
    bad_m = cm & (np.abs(wm[1:-1] - wg[1:-1]) > 0.2 * wg[1:-1])
    bad_g = cg & (np.abs(wg[1:-1] - wm[1:-1]) > 0.2 * wm[1:-1])
    bad = bad_s | bad_m | bad_g
    clean = int(cs.sum() + cm.sum() + cg.sum())
    if clean and bad.sum() > max(2, max_fraction * clean):
        b = int(np.argmax(bad)) + 1
        t = time[b * m + m - 1]
        state = "at rest" if static[b] else f"turning at {wg[b] / DEG:.3g} deg/s"
        turning = (cm | cg) & (wm[1:-1] > 0) & (wg[1:-1] > 0)
        ratio = float(np.median(wg[1:-1][turning] / wm[1:-1][turning])) if turning.any() else float("nan")
        hint = ""
        if abs(ratio * (180.0 / math.pi) - 1.0) < 0.05:
            hint = (" (the angles turn 57.3 times slower than the gyros: radians read as degrees? see --gimbal-unit rad, "
                    "or gimbal = \"rad\" in a mapping)")
        elif abs(ratio / (180.0 / math.pi) - 1.0) < 0.05:
            hint = (" (the angles turn 57.3 times faster than the gyros: degrees read as radians? see --gimbal-unit deg, "
                    "or gimbal = \"deg\" in a mapping)")
        elif math.isfinite(ratio) and abs(ratio - 1.0) > 0.2:
            hint = f" (the angles turn {ratio:.3g} times as fast as the gyros: a scale or unit error?)"
        raise ImportFileError(
            f"the increments do not follow the {what}: {int(bad.sum())} of {clean} half-second blocks disagree "
            f"(first ending at t = {t:.3f} s: {what} {state}, gyros {wm[b] / DEG:.3g} deg/s){hint} "
            "(--skip-check motion to import anyway)")


def check_encoders(dtheta: np.ndarray, gimbal: np.ndarray, rate_hz: float, time: np.ndarray) -> EncoderCheck:
    """The encoder angles against the gyros, move by move, and the encoder latency
    (:func:`inscal.io.encoders.compare_encoders`); a problem is one :class:`ImportFileError` line
    naming the cause and its fix."""
    res = compare_encoders(dtheta, gimbal, rate_hz, time)
    if not res.ok:
        raise ImportFileError(f"{res.message} (--skip-check encoders to import anyway)")
    return res


#: temperatures [degC] a hint may suppose: a lab, a thermal chamber or a vehicle (a unit that puts a
#: column here is named as the likely one)
_HINT_SPAN = (-60.0, 130.0)


def _unit_hint(read: np.ndarray, declared: str, fix: str, name: str) -> str:
    """Which other temperature unit makes readings ``read`` (as written in the file) plausible, and how to say so."""
    for u in ("K", "degC", "degF"):
        if u == declared:
            continue
        c = units.to_celsius(read, u)
        if _HINT_SPAN[0] <= float(np.min(c)) and float(np.max(c)) <= _HINT_SPAN[1]:
            how = f": {fix.format(unit=u, name=name)}" if fix else ""
            return f"; as {u} they would read {float(np.min(c)):.6g} .. {float(np.max(c)):.6g} degC{how}"
    return ""


def check_temperature(src: RawTemperature, time: np.ndarray | None = None) -> Temperature:
    """Checked temperature readings as a :class:`~inscal.io.records.Temperature`: at ``src.time``, or at
    ``time`` (the record's sample times, one per row of ``src``).  Every sensor needs a reading and
    plausible values (module docstring).  Rows where no sensor has a reading are dropped; where some
    sensors have a reading and others not, the others are interpolated linearly between their own
    readings (held beyond the first and the last): the readings keep their own times, common to the
    sensors.  One :class:`ImportFileError` line on a problem."""
    where = src.where
    t = np.asarray(src.time if src.time is not None else time, dtype=float)
    v = np.asarray(src.values, dtype=float)
    has = np.isfinite(v)
    lo, hi = TEMPERATURE_SPAN
    for s, label in enumerate(src.labels):
        rows = np.flatnonzero(has[:, s])
        if not rows.size:
            raise ImportFileError(f"{where}: {label} has no reading: all its {v.shape[0]} cells are empty")
        x = v[rows, s]
        bad = (x < lo) | (x > hi)
        if bad.any():
            i = int(rows[int(np.argmax(bad))])
            unit = src.units[s]
            sc, off = units.TEMPERATURE_UNITS[unit]
            read = (x - off) / sc
            as_read = f"{float(read[int(np.argmax(bad))]):.6g} {unit}"
            raise ImportFileError(
                f"{where}: {label} reads {as_read}{'' if unit == 'degC' else f' = {v[i, s]:.6g} degC'} at "
                f"{src.at(i)} (its readings {float(x.min()):.6g} .. {float(x.max()):.6g} degC), outside the plausible "
                f"{lo:g} .. {hi:g} degC{_unit_hint(read, unit, src.fix, src.names[s])}")
    keep = has.any(axis=1)
    tt, vals = t[keep], v[keep].copy()
    for s in range(v.shape[1]):
        miss = ~has[keep, s]
        if miss.any():
            vals[miss, s] = np.interp(tt[miss], t[has[:, s]], v[has[:, s], s])
    try:
        return Temperature(tt, vals, src.names)
    except DataFileError as exc:
        raise ImportFileError(f"{where}: {exc}") from None
