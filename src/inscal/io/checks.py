"""Plausibility checks of imported data: finite values, a regular time base, constant or saturated
channels, increment magnitudes against Earth rate and gravity, encoder angles against the gyros."""

from __future__ import annotations

import math

import numpy as np

from inscal.core import earth, units
from inscal.core.earth import Site
from inscal.core.units import DEG
from inscal.io.encoders import EncoderCheck, compare_encoders
from inscal.io.formats import Raw
from inscal.io.mapping import CHECKS, JITTER_TOL, REGRID_TOL, ImportFileError

#: the checks ``skip`` may name: the mapping's, and ``encoders`` (:func:`check_encoders`)
SKIPPABLE = CHECKS + ("encoders",)


# ----------------------------------------------------------------------------- checks
def check_finite(raw: Raw, where: str) -> None:
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
    for k in range(6):
        if raw.counts[k // 3]:
            continue
        x = raw.raw_channels[:, k]
        if np.ptp(x) > 0 and np.all(x == np.round(x)):
            which = "gyro" if k < 3 else "accel"
            raise ImportFileError(f"{where}: {raw.labels[k]} holds only whole numbers (e.g. {x[np.argmax(x != 0)]:g}): "
                                  f"integer data (raw counts? import them as csv/txt with {which} = \"counts\" and "
                                  f"{which}_scale in the mapping)")


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


def check_constant(raw: Raw, where: str) -> None:
    for k in range(6):
        x = raw.raw_channels[:, k]
        if np.ptp(x) == 0:
            raise ImportFileError(f"{where}: {raw.labels[k]} is constant ({x[0]:g}) over all {x.size} samples: "
                                  "a dead or disconnected channel (--skip-check constant to import anyway)")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def check_saturation(raw: Raw, where: str, min_run: int = 5, rel: float = 1e-7, noisy: float = 0.9) -> None:
    """A noisy channel pinned at its maximum or minimum for ``min_run`` samples while another channel moves.

    Only channels that change on at least ``noisy`` of their other samples are judged: in
    noise-free or coarsely quantised data repeated values are normal (a constant-rate turn
    reads the same on every sample)."""
    x6 = raw.raw_channels
    span = np.ptp(x6, axis=0)
    for k in range(6):
        x = x6[:, k]
        if span[k] == 0:  # constant: the constant check's business
            continue
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
                if np.any(np.ptp(others, axis=0) > rel * np.delete(span, k)):
                    raise ImportFileError(
                        f"{where}: {raw.labels[k]} looks saturated: pinned at its {word} {lim:g} for {b - a} samples from "
                        f"{raw.at(a)} while the other channels change (--skip-check saturation to import anyway)")


def _blocks(x: np.ndarray, m: int) -> np.ndarray:
    nb = x.shape[0] // m
    return x[: nb * m].reshape(nb, m, -1).sum(axis=1)


def check_magnitudes(dth: np.ndarray, dv: np.ndarray, rate_hz: float, site: Site, where: str, kind: str,
                      gyro_unit: str, accel_unit: str) -> None:
    """Gravity and Earth rate judged from magnitudes (unit mix-ups give factors far from 1)."""
    dt = 1.0 / rate_hz
    m = max(1, min(dth.shape[0], int(round(rate_hz))))
    T = m * dt
    f = np.linalg.norm(_blocks(dv, m), axis=1) / T
    w = np.linalg.norm(_blocks(dth, m), axis=1) / T
    g = site.gravity
    ratio = float(np.median(f)) / g
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
    if om * 57.29577951 / 3 < p5 < om * 57.29577951 * 3:
        look = "degrees, not radians"
    elif om / 57.29577951 / 3 < p5 < om / 57.29577951 * 3:
        look = "radians, not degrees"
    elif om * 206264.8 / 3 < p5 < om * 206264.8 * 3:
        look = "arcsec, not radians"
    else:
        return
    raise ImportFileError(
        f"{where}: gyros read at least {p5:.4g} rad/s ({p5 / DEG * 3600:.4g} deg/h, 5th percentile of 1-s means, "
        f"as {kind} in {gyro_unit}) where the Earth rate is {om / DEG * 3600:.4g} deg/h: the values look like {look} "
        "(--skip-check magnitudes to import anyway)")


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
