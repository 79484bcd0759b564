"""Multi-position calibration without a turntable: still poses at unknown orientations and the
rotations between them (hand-held, a cube, a tilting fixture).

Frame.  Without a table the poses define no external frame, so the calibration frame p is the one
the accelerometers define (Tedaldi, Pretto & Menegatti, ICRA 2014, eq. 2-5): x along accelerometer x,
y in the plane of accelerometers x and y.  In it the accelerometer matrix is lower triangular, i.e. in
inscal's form ``M_a = (I + K_a)(I + E_a)`` the angles xy, xz, yz of ``E_a`` are zero by definition
(reported with sigma NaN, held); the gyro matrix ``M_g = (I + K_g)(I + E_g)`` is full (its six angles
are the misalignment of the gyros to the accelerometer frame).  :func:`frame_of` maps a true error
model of any frame into p (``result.truth_transform``).

Accelerometers (Tedaldi 2014 eq. 9; Skog & Haendel 2006): at every still pose k with mean output
``a_k``, ``f_k = M_a^-1 (a_k - b_a)`` (with ``quadratic``: the fixed point ``f + k2 f^2 = M_a^-1 (a_k - b_a)``)
must have the site's gravity magnitude; the residual ``(|f_k| - g) / sigma_k`` with ``sigma_k`` the
noise of ``a_k`` projected on ``f_k``; 9 (12) parameters by Levenberg-Marquardt.

Gyros (Tedaldi 2014 eq. 13-16, with the Earth rate): between consecutive poses the compensated
increments ``M_g^-1 (dtheta_j - b_g dt_j)`` are integrated to the rotation ``R_k = C_{b(t1)}^{b(t0)}``:
on each sample the rate is the quartic whose integrals over the sample and its two neighbours on
each side are their increments (any time base), the quaternion equation ``q' = q (x) w / 2`` is integrated by
fourth-order Magnus steps with exact exponentials (Iserles & Norsett 1999; the ``w1 x w2`` term is the
coning that Euler steps miss, Savage, Strapdown Analytics 2000, sec. 7.1), and the samples' quaternions are multiplied in a balanced tree.
The gravity direction predicted at pose k+1 is::

    u_{k+1} = R_k^T Rot(w_ie^{b_k}, dt_k) u_k,     w_ie^{b_{k+1}} = R_k^T w_ie^{b_k}

with ``R_k`` taken between the poses' mean attitudes (the attitude the accelerometers' mean gives): a hand
trembles, so the body at the end of pose k differs from its mean by the tremor's angle there, the mean over both
ends from the gyros through the pose (:attr:`.static_detect.Candidate.wobble`) plus or minus ``T_k / 2`` times the
tremor's mean rate (the pose's mean rate less the model's still rate ``M_g w_ie + b_g``)
(the Earth frame turns by ``w_ie dt_k`` during the move; ``w_ie^{b_0} = W sin L u_0 + p h1 + q h2`` with
``h1, h2`` horizontal at pose 0 and ``p, q`` estimated: the heading is unknown).  Still pose k also
gives ``g_k = M_g w_ie^{b_k} + b_g`` (3 equations).  Parameters ``K_g, E_g, b_g, p, q`` (14) by
Levenberg-Marquardt on the transition residuals (2 per move, the predicted minus measured direction
on the plane normal to it) and the still means.  The Earth rate is *visible* when the sigma of its
horizontal part ``(p, q)`` is below a third of ``W cos L``: then the bias is separated from it; if not,
``b_g`` carries the unresolved Earth rate in its sigma and a note says so.

Uncertainty: the covariance of each fit from its Jacobian (central differences) and the noise of the
window means (:mod:`.static_detect`), scaled by chi^2/dof when the fit rejects the model (p < 0.001);
the accelerometer model's covariance moves the gravity directions it gives the poses, all together: the gyro
residuals' covariance is ``I + D P_a D^T`` (``D = dr_g/dxa``) and the gyro fit is generalised least squares
with it (whitened by its Cholesky factor), so the gyro chi^2 and covariance hold it once.
Observability: the singular values of the normalised Jacobian; a direction below ``sv_tol`` makes
the named parameters undetermined (an error, not a small sigma) and names the extra pose that helps
most among the 26 faces, edges and corners of a cube.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import linalg, optimize, stats

from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.static_detect import TREMOR, StillIntervals, detect_still
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.attitude import dcm_from_rotvec, quat_from_rotvec_array, quat_mul_array, quat_to_dcm
from inscal.core.earth import OMEGA_IE
from inscal.core.error_model import (
    GimbalErrors,
    ImuErrors,
    off_diagonal,
    parameter_components,
    split_scale_misalignment,
)

#: p-value below which a fit rejects its model (its covariance is then scaled by chi^2/dof)
P_REJECT = 1e-3
AXES = "xyz"
#: the lower-triangular angles of E_a (yx, zx, zy) among the six (xy, xz, yx, yz, zx, zy)
ACC_FREE = (2, 4, 5)


# --------------------------------------------------------------------------------- frames, rotations
def lower_frame(Ma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Ma = L Q`` with L lower triangular (positive diagonal) and Q a rotation: the accelerometer frame."""
    q, r = np.linalg.qr(np.asarray(Ma, float).T)  # Ma^T = q r  ->  Ma = r^T q^T
    s = np.sign(np.diag(r))
    L, Q = r.T * s[None, :], (q * s[None, :]).T
    return L, Q


def frame_of(truth) -> tuple[ImuErrors, GimbalErrors]:
    """The true errors ``(ImuErrors, GimbalErrors)`` expressed in the accelerometer frame p of this method."""
    imu, gim = truth
    Ma = (np.eye(3) + np.diag(imu.accel_scale_factor)) @ (np.eye(3) + off_diagonal(imu.accel_misalignment))
    Mg = (np.eye(3) + np.diag(imu.gyro_scale_factor)) @ (np.eye(3) + off_diagonal(imu.gyro_misalignment))
    L, Q = lower_frame(Ma)
    ka, ea = split_scale_misalignment(L)
    kg, eg = split_scale_misalignment(Mg @ Q.T)
    ea = np.where(np.isin(np.arange(6), ACC_FREE), ea, 0.0)
    return (ImuErrors(gyro_scale_factor=kg, gyro_misalignment=eg, gyro_bias=imu.gyro_bias, accel_scale_factor=ka,
                      accel_misalignment=ea, accel_bias=imu.accel_bias, accel_nonlinearity=imu.accel_nonlinearity),
            gim)


def rate_poly_matrix(h: np.ndarray) -> np.ndarray:
    """Per sample j, the matrix mapping the increments of samples j-2 .. j+2 to the coefficients
    ``c_0 .. c_4`` of the rate ``h_j w(tau) = sum_m c_m tau^m`` on ``tau = s / h_j`` in [0, 1]: the quartic whose
    integrals over the five sample intervals are their increments (any time base).  ``h``: (n, 5), the
    lengths of the five intervals."""
    hj = h[:, 2:3]
    edges = np.column_stack([-(h[:, 0] + h[:, 1]), -h[:, 1], np.zeros(len(h)), h[:, 2], h[:, 2] + h[:, 3],
                             h[:, 2] + h[:, 3] + h[:, 4]]) / hj
    lo, hi = edges[:, :-1], edges[:, 1:]
    A = np.stack([(hi ** (m + 1) - lo ** (m + 1)) / (m + 1) for m in range(5)], axis=2)  # (n, interval, power)
    return np.linalg.inv(A)  # int h_j w dtau over an interval = its increment


def rotations(coef: np.ndarray, seg: np.ndarray, nseg: int, substeps: int = 2) -> np.ndarray:
    """``C_{b(end)}^{b(start)}`` of every segment (``seg[j]``: the segment of increment j, in order).

    Each sample's rotation: the rate is the quartic ``coef`` (n, 5 coefficients, 3 axes) of
    :func:`rate_poly_matrix` (its integrals over the five intervals j-2 .. j+2 are their compensated
    increments), and the quaternion equation ``q' = q (x) w / 2`` is integrated over the interval by
    ``substeps`` fourth-order Magnus steps at the Gauss nodes, ``phi = d (w1 + w2) / 2 + sqrt(3) d^2 (w1 x w2) / 12``
    and the exact quaternion of phi (Iserles & Norsett 1999); the samples' quaternions are then multiplied
    in a balanced tree (order kept)."""
    n = coef.shape[0]
    q = np.zeros((n, 4))
    q[:, 0] = 1.0
    d = 1.0 / substeps

    def w(t):
        return coef[:, 0] + t * (coef[:, 1] + t * (coef[:, 2] + t * (coef[:, 3] + t * coef[:, 4])))

    c1, c2 = 0.5 - math.sqrt(3.0) / 6.0, 0.5 + math.sqrt(3.0) / 6.0
    for k in range(substeps):  # 4th-order Magnus step on [k d, (k + 1) d] (Iserles & Norsett 1999), exact exponential
        w1, w2 = w((k + c1) * d), w((k + c2) * d)
        phi = 0.5 * d * (w1 + w2) + math.sqrt(3.0) / 12.0 * d * d * np.cross(w1, w2)
        q = quat_mul_array(q, quat_from_rotvec_array(phi))
    q /= np.linalg.norm(q, axis=1)[:, None]
    g = seg.copy()
    while True:  # products of disjoint neighbour pairs within a segment, order kept, until one per segment
        pair = np.concatenate([g[1:] == g[:-1], [False]])
        if not pair.any():
            break
        first = np.concatenate([[True], g[1:] != g[:-1]])
        pos = np.arange(g.size) - np.maximum.accumulate(np.where(first, np.arange(g.size), 0))
        j = np.flatnonzero((pos % 2 == 0) & pair)
        q[j] = quat_mul_array(q[j], q[j + 1])
        keep = np.ones(g.size, bool)
        keep[j + 1] = False
        q, g = q[keep], g[keep]
    out = np.tile(np.eye(3), (nseg, 1, 1))
    for qq, s_ in zip(q, g):
        out[s_] = quat_to_dcm(qq / np.linalg.norm(qq))
    return out


# ----------------------------------------------------------------------------------------- fitting
def _jacobian(fun, x, steps, central: bool = True):
    """Central (or forward) differences of the residual vector ``fun`` at ``x``."""
    cols = []
    r0 = None if central else fun(x)
    for j, h in enumerate(steps):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((fun(x + e) - fun(x - e)) / (2.0 * h) if central else (fun(x + e) - r0) / h)
    return np.column_stack(cols)


def _solve(fun, x0, steps, names):
    """Levenberg-Marquardt to round-off, then the covariance (chi^2-scaled if the fit rejects the model)."""
    sol = optimize.least_squares(fun, x0, jac=lambda x: _jacobian(fun, x, steps, False), method="lm", xtol=1e-15,
                                 ftol=1e-15, gtol=1e-15, max_nfev=200)
    x = sol.x
    r = fun(x)
    J = _jacobian(fun, x, steps)
    n, p = J.shape
    dof = n - p
    chi2 = float(r @ r)
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    cov = (Vt.T / np.where(s > 0, s, np.inf) ** 2) @ Vt
    pval = float(stats.chi2.sf(chi2, dof)) if dof > 0 else 1.0
    scale = math.sqrt(chi2 / dof) if dof > 0 and pval < P_REJECT else 1.0
    fit = {"chi2": chi2, "dof": dof, "p_value": pval, "consistent": pval >= P_REJECT, "scale": scale}
    return x, cov * scale**2, cov, J, fit


def _weak(J: np.ndarray, typical: np.ndarray, labels: list[str], sv_tol: float) -> list[str]:
    """The parameters in the directions the data leave undetermined (normalised singular values)."""
    Jn = J * typical[None, :]
    _, s, Vt = np.linalg.svd(Jn, full_matrices=False)
    bad = s < sv_tol * s[0]
    if not bad.any():
        return []
    v = np.abs(Vt[bad]).max(axis=0)
    return [labels[i] for i in np.argsort(-v) if v[i] > 0.1]


CUBE = [np.array(v, float) / np.linalg.norm(v) for v in
        [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]]


def _direction_name(v) -> str:
    return " ".join(f"{'+' if c > 0 else '-'}{a}" for a, c in zip(AXES, v) if abs(c) > 1e-9) + " up"


class _Accel:
    """The accelerometer magnitude fit (parameters K_a 3, E_a lower 3, b_a 3 [, k2 3])."""

    def __init__(self, a, sig, g, quadratic):
        self.a, self.sig, self.g, self.quad = a, sig, g, quadratic
        self.labels = ([f"accel_scale_factor.{c}" for c in AXES] + ["accel_misalignment.yx", "accel_misalignment.zx",
                       "accel_misalignment.zy"] + [f"accel_bias.{c}" for c in AXES]
                       + ([f"accel_nonlinearity.{c}" for c in AXES] if quadratic else []))
        self.typical = np.array([1.0] * 6 + [g] * 3 + ([1.0 / g] * 3 if quadratic else []))

    def unpack(self, x):
        E = np.zeros(6)
        E[list(ACC_FREE)] = x[3:6]
        M = (np.eye(3) + np.diag(x[:3])) @ (np.eye(3) + off_diagonal(E))
        k2 = x[9:12] if self.quad else np.zeros(3)
        return M, x[6:9], k2, E

    def forces(self, x, a=None):
        M, b, k2, _ = self.unpack(x)
        y = np.linalg.solve(M, ((self.a if a is None else a) - b).T).T
        f = y.copy()
        for _ in range(60 if self.quad else 0):  # fixed point f = y - k2 f^2 (S16 eq. 7-8 form)
            f = y - k2 * f * f
        return f, M

    def residuals(self, x):
        f, M = self.forces(x)
        n = np.linalg.norm(f, axis=1)
        u = f / n[:, None]
        Mi = np.linalg.inv(M)
        s = np.sqrt(np.sum((u @ Mi) ** 2 * self.sig**2, axis=1))  # noise of a_k along f_k
        return (n - self.g) / s


def multi_position(record_like, settle: float = 0.25, min_static: float = 1.0, quadratic: bool = False,
                   alpha: float = 1e-3, gyro_range: float | None = None, accel_range: float | None = None,
                   gravity_tol: float = 0.15, sv_tol: float = 1e-7, still: StillIntervals | None = None,
                   tremor: float = TREMOR, clipped: np.ndarray | None = None) -> CalibrationResult:
    """Calibrate without a turntable: still poses at unknown orientations and the moves between them.

    The accelerometer model from the gravity magnitude of each pose, the gyro model from the rotations
    between poses (Tedaldi 2014; module docstring).

    Parameters
    ----------
    record_like : Record
        A hand-held session (``time``, ``dtheta``, ``dvel``, ``rate_hz``, ``site``).
    settle, min_static : float
        Seconds dropped at each end of a pose, and the shortest pose [s]
        (:func:`~inscal.calibrate.static_detect.detect_still`).
    quadratic : bool
        Fit the accelerometers' quadratic terms too.
    alpha : float
        The false-alarm rate of the still detector's tests.
    gyro_range, accel_range : float, optional
        The clip levels [rad/s], [m/s^2], when known.
    gravity_tol : float
        The largest relative difference between the poses' median specific force and the site's
        gravity (a larger one is a wrong unit).
    sv_tol : float
        The relative singular value below which a direction is unobservable.
    still : StillIntervals, optional
        The still detector's result, computed once by the caller.
    tremor : float
        The hand tremor a pose may hold [rad/s rms].
    clipped : numpy.ndarray, optional
        Bool per sample: a sensor marked saturated at import (its moves are not used).

    Returns
    -------
    CalibrationResult
        The IMU errors (SI) and their 1 sigma.

    Raises
    ------
    CalibrationError
        Too few still poses (the message says which were too short and the option that would keep
        them), or a gravity magnitude that does not match the site.

    Examples
    --------
    A simulated hand-held session of a MEMS IMU (the fit takes about 2 s: not run in the tests):

    >>> import numpy as np
    >>> from inscal.sim.records import scenario_record
    >>> from inscal.calibrate import multi_position
    >>> rec = scenario_record("handheld-mems", np.random.default_rng(0))
    >>> res = multi_position(rec)  # doctest: +SKIP
    >>> np.round(np.degrees(res.imu.gyro_bias) * 3600.0)  # deg/h; the truth: 400, -700, 1000  # doctest: +SKIP
    array([ 402., -699.,  994.])
    """
    time = np.asarray(record_like.time, float)
    dth = np.asarray(record_like.dtheta, float)
    dv = np.asarray(record_like.dvel, float)
    site = record_like.site
    g = float(site.gravity)
    si = still if still is not None else detect_still(time, dth, dv, min_still=min_static, settle=settle,
                                                      alpha=alpha, gyro_range=gyro_range, accel_range=accel_range,
                                                      tremor=tremor, clipped=clipped)
    need = 12 if quadratic else 9
    poses = si.require(need, f"the {'quadratic ' if quadratic else ''}accelerometer model")
    notes = list(si.notes)
    a = np.array([c.accel for c in poses])
    sa = np.array([c.accel_sigma for c in poses])
    med = float(np.median(np.linalg.norm(a, axis=1)))
    check_gravity(med, g, gravity_tol)
    acc, xa, cova, cova_formal, Ja, fita = _accel_fit(a, sa, g, med, quadratic, sv_tol)
    gyr, xg, covg, covg_formal, fitg = _gyro_fit(time, dth, si, poses, acc, xa, cova, site, notes, sv_tol)
    # ---------------------------------------------------------------------- result
    values, sigma, formal, estimated = _values(acc, xa, xg, cova, covg, cova_formal, covg_formal, quadratic)
    for name, fit in (("accelerometer", fita), ("gyro", fitg)):
        if not fit["consistent"]:
            notes.append(f"the {name} fit rejects its model (chi2 {fit['chi2']:.4g} on {fit['dof']} dof, p = "
                         f"{fit['p_value']:.2g}): its sigma are scaled by {fit['scale']:.3g}")
    earth = gyr.earth_report(xg, covg)  # adds its note when the horizontal Earth rate is not resolved
    notes += gyr.notes
    obs = _observability(Ja, acc, a, xa, sv_tol)
    notes.append(f"pose set: accelerometer fit condition {obs['condition']:.3g}, weakest {', '.join(obs['weakest'])}; "
                 f"the extra pose that would help most: {obs['extra_pose']}")
    fit = _fit_report(acc, gyr, xa, xg, fita, fitg, poses)
    labels = acc.labels + gyr.labels
    pa = len(acc.labels)
    P = np.zeros((pa + 14, pa + 14))
    P[:pa, :pa], P[pa:, pa:] = cova, covg
    keep = [i for i, lab in enumerate(labels) if not lab.startswith("earth_rate")]
    diagnostics = {"fit": fit, "formal_sigma": formal, "still": si.report(),
                   "covariance": {"labels": [labels[i] for i in keep], "P": P[np.ix_(keep, keep)]},
                   "frame": "accelerometer frame (x: accel x, y in the accel xy plane; Tedaldi 2014)",
                   "earth_rate": earth,
                   "observability": obs}
    imu = ImuErrors(**{k: v for k, v in values.items()})
    return CalibrationResult("multi-position", imu, GimbalErrors(), sigma, tuple(estimated), None, diagnostics, notes,
                             truth_transform=frame_of)


def check_gravity(med: float, g: float, gravity_tol: float) -> None:
    """A :class:`CalibrationError` when the still poses' median specific force ``med`` [m/s^2] is more than
    ``gravity_tol`` (relative) from the site's gravity ``g``: wrong units, or the wrong site."""
    if abs(med / g - 1.0) > gravity_tol:
        raise CalibrationError(f"the still poses read {med:.5g} m/s^2 (median), far from the site's gravity "
                               f"{g:.5g} m/s^2 (more than {gravity_tol:.0%}): wrong units, or the wrong site or "
                               "--gravity")


def _accel_fit(a: np.ndarray, sa: np.ndarray, g: float, med: float, quadratic: bool, sv_tol: float):
    """The accelerometer model from the poses' mean specific forces ``a`` (1 sigma ``sa``): the problem, its
    solution, covariance (scaled and formal), Jacobian and fit report (a :class:`CalibrationError` when the
    poses leave a direction undetermined)."""
    acc = _Accel(a, sa, g, quadratic)
    xa0 = np.zeros(len(acc.labels))
    xa0[:3] = med / g - 1.0
    J0 = _jacobian(acc.residuals, xa0, 1e-6 * acc.typical)
    weak = _weak(J0, acc.typical, acc.labels, sv_tol)
    if weak:
        raise CalibrationError(_undetermined(weak, a, acc, xa0, sv_tol))
    xa, cova, cova_formal, Ja, fita = _solve(acc.residuals, xa0, 1e-7 * acc.typical, acc.labels)
    return acc, xa, cova, cova_formal, Ja, fita


def _gyro_fit(time, dth, si, poses, acc, xa, cova, site, notes: list, sv_tol: float):
    """The gyro model from the moves between the poses, with the gravity directions of the accelerometer
    model ``xa``: the problem, its solution, covariance (scaled and formal) and fit report (a
    :class:`CalibrationError` when the moves leave a direction undetermined)."""
    fa, Ma = acc.forces(xa)
    u = fa / np.linalg.norm(fa, axis=1)[:, None]
    gyr = _gyro_problem(time, dth, si, poses, u, site, notes)
    xg, covg, covg_formal, Jg, fitg = gyr.solve()
    weak_g = [lab for lab in _weak(Jg, gyr.typical, gyr.labels, sv_tol) if not lab.startswith("earth_rate")]
    dead = [f"gyro {AXES[j]}" for j in range(3) if np.ptp(dth[:, j]) == 0.0]
    if weak_g and dead:  # a channel that never changes: the motion is not the cause
        raise CalibrationError(f"{', '.join(dead)} reads the same increment throughout the record (a dead or stuck "
                               f"channel): it leaves {', '.join(weak_g[:6])} undetermined whatever the moves; check "
                               "the sensor and its column in the import")
    if weak_g:
        raise CalibrationError(f"the {sum(gyr.used)} moves between the poses leave {', '.join(weak_g[:6])} undetermined "
                               "(the rotations do not turn about all three axes): move about the axes named too")
    # the accelerometer model's uncertainty moves the measured gravity directions of all poses together: the gyro
    # residuals' covariance is I + D P_a D^T (D = dr/dxa by central differences in xa), and the gyro fit is redone
    # whitened by it (generalised least squares): its chi^2 and covariance then hold that uncertainty once
    steps = 1e-7 * acc.typical
    dr = np.column_stack([(gyr.residuals(xg, _unit(acc, xa, j, h)) - gyr.residuals(xg, _unit(acc, xa, j, -h))) / (2 * h)
                          for j, h in enumerate(steps)])
    Lc = np.linalg.cholesky(np.eye(dr.shape[0]) + dr @ cova @ dr.T)
    xg, covg, covg_formal, Jg, fitg = _solve(lambda x: linalg.solve_triangular(Lc, gyr.residuals(x), lower=True), xg,
                                             1e-7 * gyr.typical, gyr.labels)
    return gyr, xg, covg, covg_formal, fitg


def _values(acc, xa, xg, cova, covg, cova_formal, covg_formal, quadratic: bool):
    """The IMU errors of the two fits, their 1 sigma (scaled, and formal) and the parameters estimated."""
    Mav, ba, k2, Ea = acc.unpack(xa)
    values = {"accel_scale_factor": xa[:3], "accel_misalignment": Ea, "accel_bias": ba,
              "gyro_scale_factor": xg[:3], "gyro_misalignment": xg[3:9], "gyro_bias": xg[9:12]}
    sdev_a, sdev_g = np.sqrt(np.diag(cova)), np.sqrt(np.diag(covg))
    sigma = {"accel_scale_factor": sdev_a[:3], "accel_misalignment": np.full(6, np.nan),
             "accel_bias": sdev_a[6:9], "gyro_scale_factor": sdev_g[:3], "gyro_misalignment": sdev_g[3:9],
             "gyro_bias": sdev_g[9:12]}
    sigma["accel_misalignment"][list(ACC_FREE)] = sdev_a[3:6]
    formal = {k: v.copy() for k, v in sigma.items()}
    fa_, fg_ = np.sqrt(np.diag(cova_formal)), np.sqrt(np.diag(covg_formal))
    formal.update({"accel_scale_factor": fa_[:3], "accel_bias": fa_[6:9], "gyro_scale_factor": fg_[:3],
                   "gyro_misalignment": fg_[3:9], "gyro_bias": fg_[9:12]})
    formal["accel_misalignment"] = formal["accel_misalignment"].copy()
    formal["accel_misalignment"][list(ACC_FREE)] = fa_[3:6]
    estimated = ["gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
                 "accel_bias"]
    if quadratic:
        values["accel_nonlinearity"] = k2
        sigma["accel_nonlinearity"] = sdev_a[9:12]
        formal["accel_nonlinearity"] = fa_[9:12]
        estimated.append("accel_nonlinearity")
    return values, sigma, formal, estimated


def _fit_report(acc, gyr, xa, xg, fita: dict, fitg: dict, poses) -> dict:
    """The two fits together: chi^2, degrees of freedom, p-value, each channel's report and the residuals per
    pose and per move."""
    ra = acc.residuals(xa)
    rg_still, rg_turn = gyr.split(gyr.residuals(xg))
    rows = [{"window": c.number, "label": f"pose {c.number} ({c.t0:.1f}-{c.t1:.1f} s)",
             "accel": abs(float(ra[k])), "gyro": float(np.sqrt(np.mean(rg_still[k] ** 2)))} for k, c in enumerate(poses)]
    moves = [k for k in range(len(gyr.pairs)) if gyr.used[k]]
    rows += [{"window": len(poses) + m + 1, "label": f"move pose {poses[gyr.pairs[k][0]].number} -> "
              f"{poses[gyr.pairs[k][1]].number}", "accel": float("nan"), "gyro": float(np.sqrt(np.mean(rg_turn[m] ** 2)))}
             for m, k in enumerate(moves)]
    chi2, dof = fita["chi2"] + fitg["chi2"], fita["dof"] + fitg["dof"]
    p = float(stats.chi2.sf(chi2, dof)) if dof > 0 else 1.0
    return {"chi2": chi2, "dof": dof, "p_value": p, "consistent": fita["consistent"] and fitg["consistent"],
            "scale": max(fita["scale"], fitg["scale"]), "channels": {"accel": fita, "gyro": fitg}, "residuals": rows,
            "note": None if fita["consistent"] and fitg["consistent"] else "see the notes"}


def _unit(acc, xa, j, h):
    """The gravity directions of the poses with accelerometer parameter j moved by h."""
    x = xa.copy()
    x[j] += h
    f, _ = acc.forces(x)
    return f / np.linalg.norm(f, axis=1)[:, None]


def _undetermined(weak, a, acc, x0, sv_tol) -> str:
    """One line: the poses leave ``weak`` undetermined; the cube pose that helps most."""
    best = _best_extra_pose(a, acc, x0)
    n = a / np.linalg.norm(a, axis=1)[:, None]
    _, s, Vt = np.linalg.svd(n - n.mean(axis=0))
    if s[2] < 0.05 * s[0]:  # the gravity directions on one circle: one axis of rotation
        ax = Vt[2] * np.sign(Vt[2][np.argmax(np.abs(Vt[2]))])
        spread = f"all poses turn about one axis, [{ax[0]:.2f}, {ax[1]:.2f}, {ax[2]:.2f}] in the sensor frame"
    else:
        spread = "the poses do not span the directions of gravity"
    return (f"the {len(a)} still poses leave {', '.join(weak[:6])} undetermined ({spread}); "
            f"a pose with {best} would help most")


def _best_extra_pose(a, acc, x0) -> str:
    """The cube direction (of 26) whose pose, added, maximises the smallest normalised singular value."""
    g = acc.g
    best, val = None, -1.0
    for v in CUBE:
        trial = _Accel(np.vstack([a, g * v]), np.vstack([acc.sig, acc.sig.mean(axis=0)]), g, acc.quad)
        J = _jacobian(trial.residuals, x0, 1e-6 * acc.typical) * acc.typical[None, :]
        s = np.linalg.svd(J, compute_uv=False)
        if s[-1] / s[0] > val:
            best, val = v, s[-1] / s[0]
    return _direction_name(best)


def _observability(J, acc, a, x, sv_tol) -> dict:
    """The normalised singular spectrum of the accelerometer fit, its weakest parameters and the extra pose."""
    Jn = J * acc.typical[None, :]
    _, s, Vt = np.linalg.svd(Jn, full_matrices=False)
    v = np.abs(Vt[-1])
    return {"condition": float(s[0] / s[-1]), "weakest": [acc.labels[i] for i in np.argsort(-v)[:3]],
            "extra_pose": _best_extra_pose(a, acc, x)}


class _Gyro:
    """The gyro fit: K_g 3, E_g 6, b_g 3, horizontal Earth rate p, q at pose 0 (module docstring)."""

    labels = ([f"gyro_scale_factor.{c}" for c in AXES] + [f"gyro_misalignment.{c}" for c in
              parameter_components("gyro_misalignment")] + [f"gyro_bias.{c}" for c in AXES]
              + ["earth_rate.p", "earth_rate.q"])

    def __init__(self, five, seg, span, pairs, used, gmean, gsig, u, tsig, wv, h1, h2, omega_h, notes, wobble=None,
                 length=None):
        Ainv = rate_poly_matrix(five[:, :, 3])
        self.coef_raw = Ainv @ five[:, :, :3]
        self.coef_h = np.einsum("nij,nj->ni", Ainv, five[:, :, 3])
        self.seg, self.span, self.pairs, self.used = seg, span, pairs, used
        self.gmean, self.gsig, self.u, self.tsig = gmean, gsig, u, tsig
        self.wv, self.h1, self.h2, self.omega_h, self.notes = wv, h1, h2, omega_h, notes
        self.nseg = len(pairs)
        # per pose: the tremor's attitude at both ends about the mean (their mean, from the gyros through the
        # pose) and the pose's length; its ends differ by T times the tremor's mean rate, which the model gives
        self.wobble = np.zeros((len(gmean), 3)) if wobble is None else wobble
        self.length = np.zeros(len(gmean)) if length is None else length
        scale = max(omega_h, 1e-9)
        self.typical = np.array([1.0] * 9 + [scale] * 5)

    def unpack(self, x):
        M = (np.eye(3) + np.diag(x[:3])) @ (np.eye(3) + off_diagonal(x[3:9]))
        return M, x[9:12], x[12], x[13]

    def residuals(self, x, u=None):
        """The normalised residuals (still means, then moves); ``u``: other gravity directions of the poses."""
        uu = self.u if u is None else u
        M, b, p, q = self.unpack(x)
        Mi = np.linalg.inv(M)
        coef = (self.coef_raw - self.coef_h[:, :, None] * b[None, None, :]) @ Mi.T  # compensated, linear
        R = rotations(coef, self.seg, self.nseg)
        w = self.wv * uu[0] + p * self.h1 + q * self.h2  # w_ie in body at pose 0
        out_still, out_turn = [], []
        ws = [w]
        for k, (i, j) in enumerate(self.pairs):  # every move turns the Earth rate seen in the body
            # between the poses' mean attitudes: C_{b(end i)}^{b(mean i)} R_k C_{b(mean j)}^{b(start j)}, the
            # tremor's attitude at an end = the mean of both ends -+ T/2 times its mean rate (the mean measured
            # rate less the model's still rate; the Earth rate at pose j from R_k alone: the tremor's share of it
            # is far below the noise)
            mi = Mi @ (self.gmean[i] - (M @ ws[i] + b))
            mj = Mi @ (self.gmean[j] - (M @ (R[k].T @ ws[i]) + b))
            Rk = (dcm_from_rotvec(self.wobble[i] + 0.5 * self.length[i] * mi) @ R[k]
                  @ dcm_from_rotvec(self.wobble[j] - 0.5 * self.length[j] * mj).T)
            if self.used[k]:
                upred = Rk.T @ (dcm_from_rotvec(ws[i] * self.span[k]) @ uu[i])
                n = uu[j]
                e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
                e1 /= np.linalg.norm(e1)
                e2 = np.cross(n, e1)
                out_turn.append(np.array([e1 @ upred, e2 @ upred]) / self.tsig[k])
            ws.append(Rk.T @ ws[i])
        for k in range(len(self.gmean)):
            out_still.append((self.gmean[k] - (M @ ws[k] + b)) / self.gsig[k])
        return np.concatenate([np.ravel(out_still), np.ravel(out_turn)])

    def split(self, r):
        n = 3 * len(self.gmean)
        return r[:n].reshape(-1, 3), r[n:].reshape(-1, 2)

    def solve(self):
        x0 = np.zeros(14)
        x0[9:12] = np.median(self.gmean, axis=0)
        best = None
        for ang in np.linspace(0.0, 2 * math.pi, 8, endpoint=False):  # the heading: a coarse search first
            x = x0.copy()
            x[12:14] = self.omega_h * math.cos(ang), self.omega_h * math.sin(ang)
            c = float(np.sum(self.residuals(x) ** 2))
            if best is None or c < best[0]:
                best = (c, x)
        return _solve(self.residuals, best[1], 1e-7 * self.typical, self.labels)

    def earth_report(self, x, cov) -> dict:
        ph = float(math.hypot(x[12], x[13]))
        sig = float(math.sqrt(max(cov[12, 12], cov[13, 13])))
        visible = sig < self.omega_h / 3.0
        if not visible:
            self.notes.append(f"the horizontal Earth rate ({units.from_si(self.omega_h, 'deg/h'):.3g} deg/h) is not "
                              f"resolved by these gyros (sigma {units.from_si(sig, 'deg/h'):.3g} deg/h): the gyro bias "
                              "sigma includes it (unresolved at that level)")
        return {"horizontal_deg_h": units.from_si(ph, "deg/h"), "sigma_deg_h": units.from_si(sig, "deg/h"),
                "expected_deg_h": units.from_si(self.omega_h, "deg/h"), "visible": bool(visible)}


def _gyro_problem(time, dth, si: StillIntervals, poses, u, site, notes) -> _Gyro:
    """The moves between consecutive kept poses (a move with a gap or a clipped gyro is dropped, named)."""
    dt = si.dt
    rows, segs, span, pairs, tsig = [], [], [], [], []
    inc = np.column_stack([dth, dt])
    ng2 = float(np.max(si.gyro_density)) ** 2
    used = []
    for k in range(len(poses) - 1):
        c0, c1 = poses[k], poses[k + 1]
        a, b = c0.i1, c1.i0
        why = "has a time gap" if si.gap[a:b].any() else "saturates a gyro" if si.gyro_clipped[a:b].any() else None
        if why is not None:  # still integrated: it carries the Earth rate to the next pose
            notes.append(f"the move from pose {c0.number} to {c1.number} ({time[a]:.2f}-{time[b - 1]:.2f} s) {why}: "
                         "that rotation is not used")
        used.append(why is None)
        rows.append(np.stack([inc[a + d:b + d] for d in (-2, -1, 0, 1, 2)], axis=1))  # samples j-2 .. j+2
        segs.append(np.full(b - a, k))
        T = float(time[b - 1] - time[a - 1])
        span.append(T)
        pairs.append((k, k + 1))
        su = np.hypot(np.max(c0.accel_sigma), np.max(c1.accel_sigma)) / np.linalg.norm(c1.accel)
        tsig.append(math.sqrt(su**2 + ng2 * T))
    if sum(used) < 5:
        raise CalibrationError(f"{sum(used)} usable moves between the still poses: the gyro model needs at least 5")
    lat = site.latitude
    h1 = np.cross(u[0], [1.0, 0.0, 0.0] if abs(u[0][0]) < 0.9 else [0.0, 1.0, 0.0])
    h1 /= np.linalg.norm(h1)
    h2 = np.cross(u[0], h1)
    return _Gyro(np.concatenate(rows), np.concatenate(segs), np.array(span), pairs, used,
                 np.array([c.gyro for c in poses]), np.array([c.gyro_sigma for c in poses]), u, np.array(tsig),
                 OMEGA_IE * math.sin(lat), h1, h2, OMEGA_IE * math.cos(lat), [],
                 np.array([c.wobble for c in poses]), np.array([c.duration for c in poses]))
