"""Encoder checks: the gimbal encoder angles against the gyros, move by move, and the encoder latency.

A record's encoder angles ``gimbal`` (N, 2) = [outer, inner] [rad] are read at the end times of
the increment intervals.  Two comparisons, both insensitive to the IMU's small errors:

Attitude through each move.  The moves (the gimbal turning between dwells) are found from the
gyros and from the encoders (a sample moves when either turns faster than 0.05 deg/s over
0.2 s), widened by half a second at each end so that both ends lie in the dwells; moves
longer than ``max_move_s`` are compared in pieces.  Through each piece, the body-frame rotation
from its start that the encoders give, ``C_s^b(start)^T C_s^b(t)`` with ``C_s^b = R_x(outer)
R_z(inner)`` (:func:`inscal.core.turntable.C_s_b` with zero non-orthogonality), is compared
(every 0.05 s and at the end) with the gyro increments over the same samples composed as
quaternions (``Exp(dtheta_k / 2)``: exact for a turn about a fixed axis), less the rate at rest
before the move (as an Earth rate turning with the IMU when it is at most twice the Earth
rate, else as a bias fixed in it).  The residual (the angle of ``C_enc^T C_gyro``) must stay
within ``tol_deg + tol_rel * angle turned + rest rate * time + latency_allow_s * rate`` (the
relative part covers scale factor and misalignment errors up to 1e-2; the last part,
zero at rest, the effect of a latency up to ``latency_allow_s`` while turning).  When the
angles as given fail, the angles with the outer and/or inner sign flipped, the columns swapped
and radians / degrees mixed up (57.3x) are tried, and the simplest change under which every
move agrees is named (a 180-degree turn with a flipped sign ends where it should: only its
middle tells).

Latency.  Encoders that read ``theta(t - delta)`` lag the gyros by the rotation of the last
``delta`` seconds: in the IMU frame ``eps(t) ~ delta * w(t)``, where ``eps`` is the attitude
difference (gyros against encoders) since the start of the move and ``w = R_z(inner)^T e_x
d(outer)/dt + e_z d(inner)/dt`` the body rate from the encoders (central differences;
:func:`inscal.core.kinematics.rates_at`).  ``delta`` is the least-squares fit of that over the
moves, with a 3 x 3 scale/misalignment matrix on the encoders' accumulated rotation, a bias
and an offset of each move as nuisance terms (eliminated move by move).  Working on angles,
not rate derivatives, keeps encoder noise out of the regressor and makes the chord error of
encoders interpolated from a lower rate cancel between acceleration and deceleration.  The fit
is repeated on angles shifted by the estimate (:func:`apply_latency`) until the correction is
below a thousandth of a sample (large shifts converge too); the 1-sigma is a delete-one-move
jackknife.  A latency over ``latency_limit_samples`` sample intervals and 3 sigma is named.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from itertools import pairwise

import numpy as np

from inscal.core.attitude import quat_angle, quat_conj, quat_from_rotvec_array, quat_mul_array, quat_rotate_inv
from inscal.core.earth import OMEGA_IE
from inscal.core.units import DEG
from inscal.io.records import DataFileError

#: the change of the angles each hypothesis makes: (swap columns, outer sign, inner sign, scale, name)
_SCALES = ((1.0, ""), (180.0 / math.pi, "radians-as-degrees"), (math.pi / 180.0, "degrees-as-radians"))
_SIGNS = ((1.0, 1.0, ""), (-1.0, 1.0, "outer-sign"), (1.0, -1.0, "inner-sign"), (-1.0, -1.0, "both-signs"))
HYPOTHESES = tuple((swap, so, si, sc, "+".join(p for p in (un, "swapped" if swap else "", sn) if p) or "as-given")
                   for sc, un in _SCALES for swap in (False, True) for so, si, sn in _SIGNS)

#: what each part of a hypothesis means and how to fix it (in the words of ``inscal import``)
_WORDS = {
    "radians-as-degrees": ("the angles are radians read as degrees, turning 57.3 times less than the gyros",
                           'import with --gimbal-unit rad (a mapping: gimbal = "rad")'),
    "degrees-as-radians": ("the angles are degrees read as radians, turning 57.3 times more than the gyros",
                           'import with --gimbal-unit deg (a mapping: gimbal = "deg")'),
    "swapped": ("the outer and inner columns are swapped", "swap the outer and inner columns"),
    "outer-sign": ("the outer angle has the wrong sign", "negate the outer angle"),
    "inner-sign": ("the inner angle has the wrong sign", "negate the inner angle"),
    "both-signs": ("both angles have the wrong sign", "negate both angles"),
}

#: how unlikely each part is (the simplest explanation that fits is named)
_WEIGHT = {"as-given": 0, "both-signs": 2}


class EncoderError(DataFileError):
    """Encoder angles that do not agree with the gyros (one line naming the cause)."""


@dataclass(frozen=True)
class MoveCheck:
    """One move: samples ``i0 .. i1`` (the rotation over the increments ``i0 + 1 .. i1``)."""

    index: int  # 1-based
    i0: int
    i1: int
    t_start: float  # s
    t_end: float  # s
    turned_deg: float  # the angle the gyros turn through (path length)
    rotation_deg: float  # the net rotation of the gyros
    residual_deg: float  # the largest angle between the encoders' and the gyros' rotation through it (as given)
    tolerance_deg: float  # at its end


@dataclass(frozen=True)
class EncoderCheck:
    """The result of :func:`compare_encoders`.

    ``cause``: ``"ok"``, ``"no-moves"`` (nothing to compare: ok), ``"latency"``, ``"disagree"``,
    or the hypothesis that fits (parts joined with ``+``: ``radians-as-degrees``,
    ``degrees-as-radians``, ``swapped``, ``outer-sign``, ``inner-sign``, ``both-signs``).
    ``message``: one line naming the cause and its fix ("" when ok).  ``latency_s`` and its
    ``latency_sigma_s``: the estimate for the angles as given (NaN when nothing turns, or when
    the angles as given do not fit and no latency explains it).  ``hypotheses``: ``(name, largest
    residual [deg], moves within tolerance)`` of every hypothesis tried (only the angles as given
    when they fit)."""

    ok: bool
    cause: str
    message: str
    n_moves: int
    max_residual_deg: float
    latency_s: float
    latency_sigma_s: float
    rate_hz: float
    moves: tuple[MoveCheck, ...] = ()
    hypotheses: tuple[tuple[str, float, int], ...] = ()

    @property
    def latency_samples(self) -> float:
        """The estimated encoder latency in samples of the record (``latency_s`` times the rate)."""
        return self.latency_s * self.rate_hz

    def summary(self) -> dict:
        """A JSON-ready summary (no per-move details)."""
        return {"ok": self.ok, "cause": self.cause, "message": self.message, "moves": self.n_moves,
                "max_residual_deg": _num(self.max_residual_deg), "latency_s": _num(self.latency_s),
                "latency_sigma_s": _num(self.latency_sigma_s), "latency_samples": _num(self.latency_samples)}

    def to_dict(self) -> dict:
        """The check as JSON: :meth:`summary` plus every move's comparison and every hypothesis tested
        (a sign, swapped columns, a unit, an offset) with its largest residual [deg].
        """
        d = self.summary()
        d["move_list"] = [asdict(m) for m in self.moves]
        d["hypotheses"] = [{"name": n, "max_residual_deg": _num(r), "moves_within": k} for n, r, k in self.hypotheses]
        return d


def _num(x: float):
    return None if not math.isfinite(x) else float(x)


# ----------------------------------------------------------------------------- geometry
def gimbal_quaternion(gimbal: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) of ``C_s^b = R_x(outer) R_z(inner)`` for angles (..., 2)."""
    hx, hz = 0.5 * gimbal[..., 0], 0.5 * gimbal[..., 1]
    cx, sx, cz, sz = np.cos(hx), np.sin(hx), np.cos(hz), np.sin(hz)
    return np.stack([cx * cz, sx * cz, -sx * sz, cx * sz], axis=-1)


def _prefix(q: np.ndarray) -> np.ndarray:
    """Prefix products ``q[0] q[1] ... q[k]`` (n, 4) of quaternions (n, 4), vectorised: by doubling
    for short runs, else in blocks of about sqrt(n) (sequential across a block, all blocks at once,
    then each block turned by the product of the blocks before it)."""
    n = q.shape[0]
    if n <= 4096:
        q = q.copy()
        k = 1
        while k < n:
            q[k:] = quat_mul_array(q[:-k], q[k:])
            k *= 2
        return q
    m = int(math.sqrt(n))
    nb = -(-n // m)
    blk = np.zeros((nb * m, 4))
    blk[:, 0] = 1.0
    blk[:n] = q
    blk = blk.reshape(nb, m, 4)
    for j in range(1, m):
        blk[:, j] = quat_mul_array(blk[:, j - 1], blk[:, j])
    carry = np.concatenate([[[1.0, 0.0, 0.0, 0.0]], _prefix(blk[:-1, -1])])
    return quat_mul_array(carry[:, None, :], blk).reshape(-1, 4)[:n]


def body_rates(gimbal: np.ndarray, rate_hz: float) -> np.ndarray:
    """Body rates (N-1, 3) [rad/s] of the IMU from encoder angles (N, 2), the means over the
    sample intervals: ``R_z(inner)^T e_x d(outer)/dt + e_z d(inner)/dt``, with the inner angle
    at the middle of each interval (exact for one axis turning at a time)."""
    d = np.diff(gimbal, axis=0) * rate_hz
    thz = 0.5 * (gimbal[1:, 1] + gimbal[:-1, 1])
    return np.column_stack([np.cos(thz) * d[:, 0], -np.sin(thz) * d[:, 0], d[:, 1]])


def apply_latency(time: np.ndarray, gimbal: np.ndarray, delta: float) -> np.ndarray:
    """Encoder angles corrected for a latency ``delta`` [s]: ``out(t) = gimbal(t + delta)``, linear
    interpolation, the first / last sample held beyond the ends.  Encoders that read
    ``theta(t - delta)`` (lagging the IMU by ``delta``) give back ``theta(t)``; a negative
    ``delta`` shifts the other way (so ``apply_latency(t, g, -d)`` makes encoders that lag by d)."""
    g = np.asarray(gimbal, dtype=float)
    if delta == 0.0:
        return g.copy()
    t = np.asarray(time, dtype=float)
    return np.column_stack([np.interp(t + delta, t, g[:, j]) for j in range(g.shape[1])])


# ----------------------------------------------------------------------------- moves
def _window_rate(cum: np.ndarray, h: int, dt: float) -> np.ndarray:
    """Mean rate over samples ``k - h .. k + h`` from a cumulative sum (n + 1, m) (edges clipped)."""
    n = cum.shape[0] - 1
    k = np.arange(n)
    lo, hi = np.clip(k - h, 0, n), np.clip(k + h + 1, 0, n)
    return (cum[hi] - cum[lo]) / ((hi - lo)[:, None] * dt)


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _wide_runs(dtheta: np.ndarray, gimbal: np.ndarray, rate_hz: float,
               margin_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs ``a .. b`` (inclusive) of moving samples widened by ``margin_s``, and the gyro rate (N,)
    [rad/s] over 0.2 s."""
    n = dtheta.shape[0]
    dt = 1.0 / rate_hz
    h = max(1, round(0.1 * rate_hz))
    wg = np.linalg.norm(_window_rate(np.concatenate([np.zeros((1, 3)), np.cumsum(dtheta, axis=0)]), h, dt), axis=1)
    we = np.abs(_window_rate(np.concatenate([np.zeros((1, 2)), gimbal - gimbal[0]]), h, dt)).max(axis=1)
    # thresholds: 0.05 deg/s, or above the gyros' rest level (their 5th percentile: Earth rate and bias)
    # and above the encoders' noise (from their second differences, which a steady turn leaves at zero)
    noise = float(np.median(np.abs(np.diff(gimbal, 2, axis=0)))) / 0.6745 / math.sqrt(6.0) if n > 2 else 0.0
    floor = 0.05 * DEG
    moving = (wg > max(floor, 3.0 * float(np.percentile(wg, 5)))) | (we > max(floor, 10.0 * noise * rate_hz / h))
    m = max(1, round(margin_s * rate_hz))
    c = np.concatenate([[0], np.cumsum(moving)])
    k = np.arange(n)
    a, b = _runs(c[np.minimum(k + m + 1, n)] - c[np.maximum(k - m, 0)] > 0)
    return a, b - 1, wg


def moving_runs(dtheta, gimbal, rate_hz: float, margin_s: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The moves as sample runs ``(a, b)``: the rotation over the increments ``a + 1 .. b``.  A sample
    moves when, over 0.2 s, the gyros turn faster than 0.05 deg/s and 3 times their 5th percentile
    (the rest level: Earth rate and bias), or the encoders faster than 0.05 deg/s and 10 times
    their noise; runs are widened by ``margin_s`` at each end (so ``a`` and ``b`` are at rest
    unless the run reaches an end of the record: it is then cut to samples ``1 .. N - 2``)."""
    a, b, _ = _wide_runs(np.asarray(dtheta, dtype=float), np.asarray(gimbal, dtype=float), float(rate_hz), margin_s)
    n = np.shape(dtheta)[0]
    a, b = np.maximum(a, 1), np.minimum(b, n - 2)
    keep = b - a >= 2
    return a[keep], b[keep]


@dataclass(frozen=True)
class _Run:
    """The gyros through one run: ``att[j]`` the attitude at sample ``a + j`` relative to sample
    ``a`` (increments less the rate at rest), ``rest`` (n, 3) that rate [rad/s] for the increments
    ``a + 1 .. b``, ``turned[j]`` the angle turned through by sample ``a + j``."""

    a: int
    b: int
    att: np.ndarray
    rest: np.ndarray
    turned: np.ndarray


def _gyro_runs(dtheta: np.ndarray, rate_hz: float, a_all: np.ndarray, b_all: np.ndarray) -> list[_Run]:
    """The gyro attitude through each run, less the rate at rest before it (up to 10 s of rest):
    turned with the IMU as an Earth rate when it is at most twice the Earth rate, else fixed in
    the IMU as a bias."""
    dt = 1.0 / rate_hz
    n = dtheta.shape[0]
    out = []
    ident = np.array([[1.0, 0.0, 0.0, 0.0]])
    prev = np.concatenate([[0], b_all[:-1] + 1])
    for a, b, p in zip(a_all, b_all, prev):
        lo = max(int(p), int(a) - round(10.0 * rate_hz))  # rest samples lo + 1 .. a (none: a run from the start)
        r = dtheta[lo + 1:a + 1].sum(axis=0) * rate_hz / (a - lo) if a > lo + 1 else np.zeros(3)
        a, b = max(int(a), 1), min(int(b), n - 2)
        if b - a < 2:
            continue
        inc = dtheta[a + 1:b + 1]
        if np.linalg.norm(r) <= 2.0 * OMEGA_IE:
            rest = quat_rotate_inv(np.concatenate([ident, _prefix(quat_from_rotvec_array(inc))[:-1]]), r)  # at each increment's start
        else:
            rest = np.broadcast_to(r, inc.shape)
        att = np.concatenate([ident, _prefix(quat_from_rotvec_array(inc - rest * dt))])
        turned = np.concatenate([[0.0], np.cumsum(np.linalg.norm(inc, axis=1))])
        out.append(_Run(a, b, att, np.asarray(rest), turned))
    return out


# ----------------------------------------------------------------------------- latency
def _pieces(runs: list[_Run], step: int) -> list[tuple[_Run, int, int]]:
    """Each run cut into pieces of at most ``step`` samples: ``(run, s, e)``."""
    out = []
    for run in runs:
        cuts = list(range(run.a, run.b, step)) + [run.b]
        out += [(run, s, e) for s, e in pairwise(cuts)]
    return out


def _latency_fit(gimbal: np.ndarray, rate_hz: float, pieces: list[tuple[_Run, int, int]]) -> tuple[float, float]:
    """One least-squares fit of the attitude difference ``eps`` (gyros against encoders, IMU frame)
    through each piece: ``eps = delta w_enc + M_p phi_enc + b_p (t - t_s) + c_p``, the 3 x 3 matrix
    ``M_p`` on the encoders' accumulated rotation ``phi_enc``, the bias ``b_p`` and the offset
    ``c_p`` of each piece eliminated; returns ``(delta, sigma)`` [s], sigma a delete-one-piece
    jackknife (NaN: nothing turns)."""
    dt = 1.0 / rate_hz
    info, rhs = [], []
    for run, s, e in pieces:
        if e - s < 3:
            continue
        g = gimbal[s - 1:e + 2]
        qe = gimbal_quaternion(g[1:-1])
        qg = quat_mul_array(quat_conj(run.att[s - run.a]), run.att[s - run.a:e - run.a + 1])
        d = quat_mul_array(quat_conj(quat_mul_array(quat_conj(qe[:1]), qe)), qg)
        eps = 2.0 * d[:, 1:] * np.where(d[:, :1] < 0, -1.0, 1.0)
        rate = (g[2:] - g[:-2]) * (0.5 * rate_hz)
        thz = g[1:-1, 1]
        w = np.column_stack([np.cos(thz) * rate[:, 0], -np.sin(thz) * rate[:, 0], rate[:, 1]])
        phi = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (w[1:] + w[:-1]), axis=0) * dt])
        z = np.column_stack([phi, np.arange(e - s + 1) * dt, np.ones(e - s + 1)])
        zi = np.linalg.pinv(z.T @ z, rcond=1e-12)
        zw, ze = z.T @ w, z.T @ eps  # per axis: the delta column w[:, i], the nuisance z (Schur complement)
        info.append(float(np.sum(w * w) - np.einsum("ki,kl,li->", zw, zi, zw)))
        rhs.append(float(np.sum(w * eps) - np.einsum("ki,kl,li->", zw, zi, ze)))
    info, rhs = np.array(info), np.array(rhs)
    tot = float(info.sum()) if info.size else 0.0
    if not tot > 0:
        return math.nan, math.nan
    delta = float(rhs.sum()) / tot
    left = tot - info
    ok = left > 1e-3 * tot
    if ok.sum() < 3:
        return delta, math.nan
    jk = (rhs.sum() - rhs[ok]) / left[ok]
    k = jk.size
    return delta, float(np.sqrt((k - 1) / k * np.sum((jk - jk.mean()) ** 2)))


def _latency(gimbal, rate_hz, time, pieces: list[tuple[_Run, int, int]], max_iter: int = 10) -> tuple[float, float]:
    total, sigma = 0.0, math.nan
    g = gimbal
    for _ in range(max_iter):
        d, sigma = _latency_fit(g, rate_hz, pieces)
        if not math.isfinite(d):
            return math.nan, math.nan
        total += d
        if abs(d) < 1e-3 / rate_hz or abs(total) > 0.25 * (time[-1] - time[0]):
            break
        g = apply_latency(time, gimbal, total)
    return total, sigma


def estimate_latency(dtheta, gimbal, rate_hz: float, time=None, margin_s: float = 0.5,
                     max_move_s: float = 60.0) -> tuple[float, float]:
    """Encoder latency ``(delta, sigma)`` [s] relative to the IMU (encoders that read ``theta(t - delta)``;
    ``delta > 0``: they lag), see the module docstring; NaN when nothing turns."""
    dtheta, gimbal, rate_hz = np.asarray(dtheta, dtype=float), np.asarray(gimbal, dtype=float), float(rate_hz)
    time = (np.arange(dtheta.shape[0]) + 1.0) / rate_hz if time is None else np.asarray(time, dtype=float)
    a, b, _ = _wide_runs(dtheta, gimbal, rate_hz, margin_s)
    pieces = _pieces(_gyro_runs(dtheta, rate_hz, a, b), max(2, round(max_move_s * rate_hz)))
    return _latency(gimbal, rate_hz, time, pieces)


# ----------------------------------------------------------------------------- the check
@dataclass(frozen=True)
class _Points:
    """The compared samples of every piece: ``j0`` the piece's first sample, ``j`` the sample,
    ``qg`` the gyro rotation from ``j0`` to ``j``, ``tol`` [rad], ``piece`` its index."""

    j0: np.ndarray
    j: np.ndarray
    qg: np.ndarray
    tol: np.ndarray
    piece: np.ndarray


def _points(pieces: list[tuple[_Run, int, int]], wg: np.ndarray, rate_hz: float, dec: int, tol0: float,
            tol_rel: float, rest: float, allow: float) -> tuple[_Points, np.ndarray, np.ndarray, np.ndarray]:
    j0, jj, qg, piece, turned = [], [], [], [], []
    s_all, e_all, turn_all = [], [], []
    for run, s, e in pieces:
        j = np.unique(np.append(np.arange(s + dec, e, dec), e))
        q0 = quat_conj(run.att[s - run.a])
        qg.append(quat_mul_array(np.broadcast_to(q0, (j.size, 4)), run.att[j - run.a]))
        turned.append(run.turned[j - run.a] - run.turned[s - run.a])
        j0.append(np.full(j.size, s))
        jj.append(j)
        piece.append(np.full(j.size, len(s_all)))
        s_all.append(s)
        e_all.append(e)
        turn_all.append(turned[-1][-1])
    j0, jj, turned = np.concatenate(j0), np.concatenate(jj), np.concatenate(turned)
    tol = tol0 + tol_rel * turned + rest * (jj - j0) / rate_hz + allow * (wg[jj] + wg[j0])
    pts = _Points(j0, jj, np.concatenate(qg), tol, np.concatenate(piece))
    return pts, np.array(s_all), np.array(e_all), np.array(turn_all)


def compare_encoders(dtheta, gimbal, rate_hz: float, time=None, *, tol_deg: float = 0.1, tol_rel: float = 0.02,
                     latency_limit_samples: float = 1.0, latency_allow_s: float = 0.1, max_move_s: float = 60.0,
                     margin_s: float = 0.5, estimate: bool = True) -> EncoderCheck:
    """Compare the encoder angles ``gimbal`` (N, 2) [rad] with the gyro increments ``dtheta`` (N, 3)
    [rad] at ``rate_hz`` (see the module docstring); ``time`` (N,) [s] for the messages and the
    latency shifts (default: uniform from ``1 / rate_hz``).  Does not raise on bad data: the
    result's ``ok``, ``cause`` and ``message`` say what is wrong."""
    dtheta = np.asarray(dtheta, dtype=float)
    gimbal = np.asarray(gimbal, dtype=float)
    rate_hz = float(rate_hz)
    n = dtheta.shape[0]
    if gimbal.shape != (n, 2) or dtheta.shape != (n, 3):
        raise ValueError(f"dtheta must be (N, 3) and gimbal (N, 2), got {dtheta.shape} and {gimbal.shape}")
    time = (np.arange(n) + 1.0) / rate_hz if time is None else np.asarray(time, dtype=float)
    nan = math.nan
    a_all, b_all, wg = _wide_runs(dtheta, gimbal, rate_hz, margin_s)
    runs = _gyro_runs(dtheta, rate_hz, a_all, b_all)
    if not runs:
        return EncoderCheck(True, "no-moves", "", 0, nan, nan, nan, rate_hz)
    rest = max(OMEGA_IE, float(np.median([np.linalg.norm(r.rest.mean(axis=0)) for r in runs])))
    pieces = _pieces(runs, max(2, round(max_move_s * rate_hz)))
    pts, i0, i1, turned = _points(pieces, wg, rate_hz, max(1, round(0.05 * rate_hz)), tol_deg * DEG, tol_rel,
                                  rest, latency_allow_s)
    m = int(i0.size)
    ends = np.stack([gimbal[pts.j0], gimbal[pts.j]], axis=1)  # (points, 2 ends, 2 angles)

    def residuals(h):
        swap, so, si, sc = h[:4]
        g = (ends[..., ::-1] if swap else ends) * (np.array([so, si]) * sc)
        qs = gimbal_quaternion(g)
        r = quat_angle(quat_mul_array(quat_conj(quat_mul_array(quat_conj(qs[:, 0]), qs[:, 1])), pts.qg))
        worst = np.full(m, -np.inf)
        np.maximum.at(worst, pts.piece, r)
        bad = np.zeros(m, dtype=bool)
        np.logical_or.at(bad, pts.piece, r > pts.tol)
        return r, worst, bad

    r0, worst0, bad0 = residuals(HYPOTHESES[0])
    last = np.flatnonzero(np.append(pts.piece[1:] != pts.piece[:-1], True))  # each piece's last point
    moves = tuple(MoveCheck(k + 1, int(s), int(e), float(time[s]), float(time[e]), float(turned[k] / DEG),
                            float(quat_angle(pts.qg[last[k]]) / DEG), float(worst0[k] / DEG), float(pts.tol[last[k]] / DEG))
                  for k, (s, e) in enumerate(zip(i0, i1)))
    worst = float(worst0.max() / DEG)
    if not bad0.any():
        hyp = (("as-given", worst, m),)
        if not estimate:
            return EncoderCheck(True, "ok", "", m, worst, nan, nan, rate_hz, moves, hyp)
        delta, sigma = _latency(gimbal, rate_hz, time, pieces)
        if _significant(delta, sigma, rate_hz, latency_limit_samples):
            return EncoderCheck(False, "latency", _latency_message(delta, sigma, rate_hz), m, worst, delta, sigma,
                                rate_hz, moves, hyp)
        return EncoderCheck(True, "ok", "", m, worst, delta, sigma, rate_hz, moves, hyp)
    tried, fits = [], []
    for h in HYPOTHESES:
        _, w, bad = (r0, worst0, bad0) if h[4] == "as-given" else residuals(h)
        tried.append((h[4], float(w.max() / DEG), int(m - bad.sum())))
        if not bad.any():
            fits.append((sum(_WEIGHT.get(q, 1) for q in h[4].split("+")), float(w.max()), len(fits), h[4]))
    k = int(np.argmax(bad0))
    on = pts.piece == k
    p = int(np.flatnonzero(on)[np.argmax(r0[on] - pts.tol[on])])
    where = (f"move {k + 1} of {m}, a {turned[k] / DEG:.4g} deg turn at t = {time[i0[k]]:.2f} .. {time[i1[k]]:.2f} s, "
             f"is off by {r0[p] / DEG:.3g} deg at t = {time[pts.j[p]]:.2f} s")
    if fits:
        _, r, _, name = min(fits)
        said = " and ".join(_WORDS[q][0] for q in name.split("+"))
        fix = "; ".join(_WORDS[q][1] for q in name.split("+"))
        msg = (f"the encoder angles do not follow the gyros: {said} (as given, {where}; changed so, all {m} moves "
               f"agree to {r / DEG:.2g} deg): {fix} to correct")
        return EncoderCheck(False, name, msg, m, worst, nan, nan, rate_hz, moves, tuple(tried))
    if estimate:  # a latency too long for latency_allow_s
        delta, sigma = _latency(gimbal, rate_hz, time, pieces)
        if _significant(delta, sigma, rate_hz, latency_limit_samples):
            again = compare_encoders(dtheta, apply_latency(time, gimbal, delta), rate_hz, time, tol_deg=tol_deg,
                                     tol_rel=tol_rel, latency_allow_s=latency_allow_s, max_move_s=max_move_s,
                                     margin_s=margin_s, estimate=False)
            if again.ok:
                return EncoderCheck(False, "latency", _latency_message(delta, sigma, rate_hz), m, worst, delta, sigma,
                                    rate_hz, moves, tuple(tried))
    d_out, d_in = (np.asarray(gimbal[i1[k]], float) - np.asarray(gimbal[i0[k]], float)) / DEG
    msg = (f"the encoders and the gyros disagree by {r0[p] / DEG:.3g} deg on move {k + 1} of {m} at "
           f"t = {time[pts.j[p]]:.2f} s (the move: the gyros turn {turned[k] / DEG:.4g} deg, the outer angle changes by "
           f"{d_out:.4g} deg and the inner by {d_in:.4g} deg, t = {time[i0[k]]:.2f} .. {time[i1[k]]:.2f} s; tolerance "
           f"{pts.tol[p] / DEG:.2g} deg; {int(bad0.sum())} move(s) disagree); no unit, sign, column or latency error "
           "explains it: a jump or glitch of an encoder?")
    return EncoderCheck(False, "disagree", msg, m, worst, nan, nan, rate_hz, moves, tuple(tried))


def _significant(delta: float, sigma: float, rate_hz: float, limit_samples: float) -> bool:
    return (math.isfinite(delta) and abs(delta) * rate_hz > limit_samples
            and not (math.isfinite(sigma) and abs(delta) <= 3.0 * sigma))


def _latency_message(delta: float, sigma: float, rate_hz: float) -> str:
    word = "lag" if delta > 0 else "lead"
    sig = f" +- {sigma * 1e3:.2g} ms" if math.isfinite(sigma) else ""
    return (f"the encoders {word} the IMU by {abs(delta) * 1e3:.1f} ms{sig} ({abs(delta) * rate_hz:.3g} samples at "
            f"{rate_hz:g} Hz; --encoder-latency {round(delta, 4):g} to correct)")


#: a latency under a sample that the check measured (at least this many samples, and 3 sigma) is named
#: (:func:`small_latency`): a calibration misfits by it through the turns
SMALL_LATENCY_SAMPLES = 0.1


def small_latency(delta: float | None, sigma: float | None, rate_hz: float) -> str | None:
    """The words for a latency ``delta`` +- ``sigma`` [s] that the check let pass (under a sample) but
    measured (:data:`SMALL_LATENCY_SAMPLES` and 3 sigma), or None: who leads, by how much, in samples; half a
    sample is named as rates stamped at the end (encoders that lead) or the start (that lag) of their
    averaging interval (a ROS driver's, where REP 145 asks for the instant they represent, its centre)."""
    if delta is None or sigma is None or not _significant(delta, sigma, rate_hz, SMALL_LATENCY_SAMPLES):
        return None
    n = abs(delta) * rate_hz
    edge = "end" if delta < 0 else "start"  # the increments late (the encoders lead) or early
    half = (f", half a sample: rates stamped at the {edge} of their averaging interval, not at its centre, the "
            "instant they represent (REP 145)" if abs(n - 0.5) < 0.1 else "")
    pm = f" +- {sigma * 1e3:.2g} ms" if math.isfinite(sigma) else ""
    who = "lag" if delta > 0 else "lead"
    return f"the encoders {who} the IMU by {abs(delta) * 1e3:.3g} ms{pm} ({n:.3g} samples{half})"


def check_record_encoders(record, strict: bool = False) -> EncoderCheck | None:
    """:func:`compare_encoders` on a record (or any object with ``dtheta``, ``gimbal``, ``rate_hz``
    and ``time``); None when it has no encoder angles.  ``strict``: raise :class:`EncoderError`
    with the one-line message when the check fails."""
    if getattr(record, "gimbal", None) is None:
        return None
    res = compare_encoders(np.asarray(record.dtheta), np.asarray(record.gimbal), float(record.rate_hz),
                           np.asarray(record.time))
    if strict and not res.ok:
        raise EncoderError(res.message)
    return res
