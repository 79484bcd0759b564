"""The systematic filter's robust scheme: a velocity model-error term estimated from the record's own
innovations, with weights that settle before the parameters do.

Why not bounded influence.  A step whose innovation misfits leaves a velocity error in the navigator that an
inflated ``R`` does not remove: the next step sees the same error, and on a record whose moves misfit
everywhere (another toolbox's lever-arm timing, an unmodelled asynchrony) 70-93 % of the steps passed a cap on
the NIS, which steps were down-weighted changed with every pass, and the pass-to-pass map did not contract
(2-cycles, estimates 400-6,000 ppm off).  A misfit in the moves is a model (or noise) problem, not a
handful of outliers.

The model-error term.  The velocity misfit of a step is treated as what it physically is: an unmodelled
specific force over the step, i.e. extra accelerometer white noise during it.  Step ``k`` runs with the
accelerometer PSD ``q_a lambda_k`` (``lambda_k >= 1``; the kernel's ``q_factor``), so ``Q_d`` grows in the
velocity rows *and* in the position rows and their correlation (``int Phi Q_c Phi^T``): the filter takes the
misfit up in its velocity state at that step instead of dragging the constants, and the next step starts
clean.  The factors are

* per motion state (``static`` / ``moving`` steps, the mean body rate of the step against
  :data:`MOVING_RATE`), ``lambda_g = lambda_g,prev * s_g`` with ``s_g`` the median NIS of the group's
  regular steps over its expectation's median (the noise the record shows, a method-of-moments step towards
  ``E[NIS] = expected``: the NIS of a step whose ``S`` is dominated by its own ``Q_d`` scales as
  ``1 / lambda``); a group stays at 1 until its scale is significant (:data:`GROUP_THRESHOLD`, and four
  standard errors of a median of its size), and never goes below 1: the noise estimated from the record
  (or given) is the least the filter assumes;
* per step for isolated outliers (the NIS above ``cap`` times the group's level, its median NIS over the
  chi2(6) median when below 1: a noise-free record's floors make every NIS small, and a step that misfits by
  a fraction of a floor sigma is as much an outlier as one at 6 sigma on noisy data): a factor on its ``R``
  that brings the step's NIS to that threshold.  The misfit of a step is weighted by its own size, step by
  step, and the other steps of its turn keep their information.

The group factors' yardstick is the noise assumed (estimated from the record, or its floors), not the level
the dwells show.  On a noise-free float32 record the dwells' increments are constant, so their rounding is a constant per attitude
that the bias and attitude states absorb, and the dwells' NIS falls far below the floors'; the turns' rounding
and the integration scheme's error (1e-8 to 1e-6 m/s a step at 100 Hz, against 2e-6 m/s of the VRW floor over
1 s) are white-like and stay.  Holding the moves to the dwells' level called that a misfit (a factor of 138 on
every moving step of the independent oracle's record), and the turns, which observe the lever arms, the asynchrony and the cross-coupling, lost 10-800x of
their information for a residual a fraction of the assumed sigma: a residual below the noise assumed does not
contradict the information the sigma claim.  A step whose own misfit stands out of its group's level is
still an outlier (above).

The outer iteration.  The factors are estimated after a pass from its innovations and used by the next pass,
for at most :data:`WEIGHT_PASSES` passes or until they settle (no factor changes by more than
:data:`SETTLE_RATIO`); then they are frozen, and the remaining passes are a Gauss-Newton iteration of one
fixed weighted least-squares problem (the iterated smoother), which converges on a record the model can
follow.  A pass that ran with other factors than the one before it is never called converged.  Nested fits
(``--states auto``) share the full model's frozen factors, so their chi-square values compare.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.calibrate.systematic.record_stats import step_rates

#: mean body rate of a step [rad/s] above which it is a moving step (0.1 deg/s, the misfit signature's
#: turning rate; Earth rate is 0.004 deg/s)
MOVING_RATE = 0.1 * math.pi / 180.0
#: the least significant scale of a group's NIS (median over its expectation's median) that turns its
#: model-error term on
GROUP_THRESHOLD = 1.5
#: passes that may change the factors; after them (or once they settle) they are frozen
WEIGHT_PASSES = 3
#: factors have settled when none changes by more than this ratio
SETTLE_RATIO = 1.25
#: the median of chi2 with 6 degrees of freedom over its mean
CHI2_6_MEDIAN_RATIO = 5.348121 / 6.0
#: standard error of the median of chi2(6)/6 from one value (1.2533 sd, sd = sqrt(12)/6)
MEDIAN_SE_1 = 1.2533 * math.sqrt(12.0) / 6.0
GROUPS = ("static", "moving")
#: the largest factor (a step with it carries no velocity information: its NIS is then not brought to the cap)
MAX_FACTOR = 1e12


@dataclass(frozen=True)
class ModelError:
    """Per-step factors on the accelerometer noise (``q_factor``, ``lambda_k >= 1``) and what they came from."""

    q_factor: np.ndarray  # (M,) factor on the accelerometer noise (the motion state's)
    r_factor: np.ndarray  # (M,) factor on R (isolated outliers; 1 elsewhere)
    group_factor: dict  # group name -> lambda_g
    outliers: int  # steps with their own factor above their group's
    settled: bool  # no factor changed by more than SETTLE_RATIO against the previous ones

    @property
    def weighted_away(self) -> bool:
        """Whether the term is on: a motion state's factor above 1, or outlier steps (the record misfits the model
        beyond its noise somewhere)."""
        return any(f > 1.0 for f in self.group_factor.values()) or self.outliers > 0

    def as_dict(self) -> dict:
        """The JSON form (the factors per group, the outlier count)."""
        return {"group_factor": {k: float(v) for k, v in self.group_factor.items()}, "outliers": int(self.outliers),
                "settled": bool(self.settled)}


def moving_steps(dtheta: np.ndarray, dt: float, n_per: int, M: int) -> np.ndarray:
    """``(M,)`` bool: the filter steps whose mean body rate exceeds :data:`MOVING_RATE`."""
    mean_rate, _, _ = step_rates(np.ascontiguousarray(dtheta, dtype=float), dt, dt ** 2, n_per, M)
    return mean_rate > MOVING_RATE


def initial(M: int) -> ModelError:
    """No model-error term: every factor 1."""
    return ModelError(np.ones(M), np.ones(M), {g: 1.0 for g in GROUPS}, 0, True)


def step_noise(qam: float, T: float) -> np.ndarray:
    """The velocity/position block (6 x 6, ENU velocity then ENU position) of one step's ``Q_d`` for a unit
    factor on the accelerometer white noise of PSD ``qam``: ``qam [[T, T^2/2], [T^2/2, T^3/3]] (x) I_3``."""
    b = np.array([[T, T * T / 2.0], [T * T / 2.0, T ** 3 / 3.0]]) * qam
    return np.kron(b, np.eye(3))


def nis_at(S1: np.ndarray, Qv: np.ndarray, z: np.ndarray, lam) -> np.ndarray:
    """NIS ``z^T (S1 + (lam - 1) Qv)^-1 z`` per step (``S1`` (m, 6, 6) the innovation covariance with a unit
    factor, ``z`` (m, 6), ``lam`` scalar or (m,); ``Qv`` (6, 6) the direction the factor scales: the step's
    accelerometer noise, or ``diag(R)`` for a factor on R)."""
    lam = np.broadcast_to(np.asarray(lam, float), (S1.shape[0],))
    S = S1 + (lam - 1.0)[:, None, None] * Qv[None]
    return np.einsum("ki,ki->k", z, np.linalg.solve(S, z[..., None])[..., 0])


def _solve_log(fun, target: float, lo: float = 0.0, hi: float = math.log(MAX_FACTOR), iters: int = 50) -> float:
    """``lam = exp(x)``, ``x`` in ``[lo, hi]`` (natural log) with ``fun(lam) = target`` for ``fun`` decreasing
    (bisection; the bounds when the target lies outside)."""
    if fun(math.exp(lo)) <= target:
        return math.exp(lo)
    if fun(math.exp(hi)) >= target:
        return math.exp(hi)
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if fun(math.exp(mid)) > target:
            lo = mid
        else:
            hi = mid
    return math.exp(0.5 * (lo + hi))


def update_factors(prev: ModelError, S: np.ndarray, z: np.ndarray, expected: np.ndarray, moving: np.ndarray,
                   qam: float, T: float, r: np.ndarray, r_used: np.ndarray, q_used: np.ndarray,
                   cap: float) -> ModelError:
    """The factors after a pass: its per-step innovation covariances ``S`` (M, 6, 6) and innovations ``z`` (M, 6)
    (raw units), the NIS expectations (``6 - tr(S^-1 R)``), the moving-step mask, the mean accelerometer PSD
    ``qam``, the step ``T`` [s], the measurement variances ``r`` (6,), the factors on R and on the accelerometer
    noise each step ran with (``r_used``, ``q_used``: the bounded passes' jumps included) and the outlier cap (module docstring).  The unit-factor covariance of each step is its ``S``
    less its model-error and outlier parts; the group factor solves ``median(NIS / expected) = median(chi2_6) / 6``
    over the group, an outlier's factor on R brings its NIS to ``cap`` times the group's level."""
    M = z.shape[0]
    Qv = step_noise(qam, T)
    Rm = np.diag(np.asarray(r, float))
    S1 = S - (q_used[:M] - 1.0)[:, None, None] * Qv[None] - (r_used[:M] - 1.0)[:, None, None] * Rm[None]
    gf = {}
    q = np.ones(M)
    level = np.ones(M)  # each step's group scale at its new factor, at most 1: the outliers' NIS is relative to it
    for name, mask in (("static", ~moving[:M]), ("moving", moving[:M])):
        lam_prev = float(prev.group_factor.get(name, 1.0))
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            gf[name] = lam_prev
            continue
        e = expected[idx]
        med = lambda v: float(np.median(nis_at(S1[idx], Qv, z[idx], v) / e)) / CHI2_6_MEDIAN_RATIO  # noqa: E731
        s = med(1.0)  # the group's scale against the noise assumed (module docstring)
        threshold = max(GROUP_THRESHOLD, 1.0 + 4.0 * MEDIAN_SE_1 / math.sqrt(idx.size))
        lam = 1.0
        if s > threshold or lam_prev > 1.0:
            lam = max(_solve_log(med, 1.0), 1.0)
        gf[name] = lam
        q[idx] = lam
        level[idx] = min(max(med(lam), 1e-12), 1.0)
    # isolated outliers: NIS beyond the cap at their group's level; a factor on their R brings them to it
    rf = np.ones(M)
    if math.isfinite(cap):
        Sq = S1 + (q - 1.0)[:, None, None] * Qv[None]
        target = cap * level
        out = np.flatnonzero(nis_at(Sq, Rm, z, 1.0) > target)
        if out.size:
            lo, hi = np.zeros(out.size), np.full(out.size, math.log(MAX_FACTOR))
            for _ in range(50):  # bisection on log(alpha) for every outlier at once (NIS decreases with alpha)
                mid = 0.5 * (lo + hi)
                above = nis_at(Sq[out], Rm, z[out], np.exp(mid)) > target[out]
                lo = np.where(above, mid, lo)
                hi = np.where(above, hi, mid)
            rf[out] = np.exp(hi)
    ratio = np.concatenate([np.maximum(q / prev.q_factor[:M], prev.q_factor[:M] / q),
                            np.maximum(rf / prev.r_factor[:M], prev.r_factor[:M] / rf)])
    settled = bool(np.all(ratio <= SETTLE_RATIO))
    return ModelError(q, rf, gf, int(np.sum(rf > 1.0)), settled)


def note(me: ModelError, moving: int) -> str:
    """The note of a run whose model-error term was on ("" when every factor is 1)."""
    parts = [f"{g} steps x{f:.3g}" for g, f in me.group_factor.items() if f > 1.0]
    if not parts and not me.outliers:
        return ""
    what = ", ".join(parts) if parts else "none per motion state"
    return (f"velocity model-error term estimated from the innovations (factor on the accelerometer noise: {what}; "
            f"{me.outliers} isolated outlier steps of their own; {moving} moving steps): the record misfits the "
            "model beyond the assumed noise, and its steps are weighted by the misfit they show")



#: the largest shift of a parameter when the candidate terms are added, in units of the sum of the two sigma
#: (term_shift), that the model without them explains: the sum bounds the sigma of the difference whatever the
#: correlation of the two estimates, so the test errs towards keeping a result
TERM_SHIFT_LIMIT = 4.0


def term_shift(x: np.ndarray, P: np.ndarray, labels: list, x_big: np.ndarray, P_big: np.ndarray,
               labels_big: list) -> np.ndarray:
    """Per parameter state of the smaller model, the shift of its estimate when terms are added, over the sum of
    the two sigma ``|x - x_big| / (sigma + sigma_big)`` (when the added terms are zero both estimates are unbiased
    and ``sd(x - x_big) <= sigma + sigma_big``; Hausman's 1978 ``P_big - P`` does not apply, as the two runs carry
    model-error factors of their own).  A term the smaller model leaves out and the record holds (an asynchrony, a
    lever arm) drags its estimate and shows as a shift beyond :data:`TERM_SHIFT_LIMIT` even where a model-error
    term has made its fit look consistent.  States not in the larger model are given 0."""
    where = {name: i for i, name in enumerate(labels_big)}
    z = np.zeros(len(labels))
    for i, name in enumerate(labels):
        j = where.get(name)
        if j is None:
            continue
        s = math.sqrt(max(float(P[i, i]), 0.0)) + math.sqrt(max(float(P_big[j, j]), 0.0))
        if s > 0:
            z[i] = abs(float(x[i]) - float(x_big[j])) / s
    return z
