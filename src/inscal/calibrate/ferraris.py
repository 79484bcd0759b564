"""The Ferraris method: six faces and three whole turns, without a rate table (Ferraris, Grimaldi &
Parvis, Sensors and Materials 7(5), 1995, 311-330), on faces as real faces are: tilted by a stated amount.

The IMU (in a cube, or a box with square faces) rests on each of its six faces (``+x, -x, +y, -y, +z, -z``
up, in any order), and turns through one whole turn (360 deg) about the vertical on a face whose axis j is
vertical, for each of j = x, y, z, starting and ending still on that face.  The still poses are found by
:mod:`.static_detect` (down to ``min_turn_end`` s, the short poses at the ends of a turn); a face is the
longest pose of at least ``min_static`` s whose largest specific-force component is that axis with that
sign; a *whole turn* is the motion between two still poses on the same face (any still pauses between them
on that face included) whose integrated rotation is within ``turn_tol_deg`` of 360 deg about the vertical.

Faces (the cube frame c: its axes the faces' normals).  Face ``+-i`` holds the unit vector ``u = +-e_i + d``
vertical (``d`` the face's tilt, orthogonal to ``e_i``: the face's flatness, the table's level and how it
was put down), and the accelerometers read ``a(+-i) = g M u + b``.  With ``D`` the columns
``(a(+i) - a(-i)) / g`` and ``U`` the columns ``u(+i) - u(-i)`` (Ferraris 1995 eq. 7-8)::

    M = D U^-1

and the bias from the axis each face holds vertical (imucal's form of eq. 6, ``b_i = (a_i(+i) + a_i(-i)) / 2``,
here in the calibrated frame: row i of ``M^-1 (a(+i) + a(-i) - 2 b) = g (u(+i) + u(-i))``)::

    (M^-1 b)_i = (M^-1 (a(+i) + a(-i)))_i / 2 - g (u_i(+i) + u_i(-i)) / 2

The estimate takes ``d = 0``; it is exact for exact faces and its error is second order in the tilt
for the biases and scale factors (``b = sum faces / 6`` is first order: the horizontal axes read ``g d``),
first order for the misalignments, which six faces cannot tell from a tilt.  The accelerometer frame p
(``M = L Q``, L lower triangular: :mod:`.multiposition`) carries the results.

Gyros (Ferraris 1995 eq. 9-11).  ``b_g`` is the mean of the six faces after the vertical Earth rate
``W sin L`` along each face's measured vertical is removed.  A whole turn about the vertical on a face
integrates ``int w dt = 2 pi s M_g v + b_g T + W sin L T v + h`` with ``v`` the vertical that face holds in
the frame c (measured: ``M^-1 (a - b)`` of the turn's end poses, normalised), ``s = +-1`` the sense and
``h`` the horizontal Earth rate integrated as the body turns; with ``W`` the columns
``s (int w - b_g T - W sin L T v - h) / (2 pi)`` (the angle ``2 pi`` of a turn that closes) and ``V`` the
columns ``v``::

    M_g = W V^-1,      reported as  M_g Q^T  (in the frame p)

so the turn's own tilt cancels: the gyro misalignments are known to within the accelerometer frame's.

1 sigma.  The noise of the face means, of the turns' end poses and of the turn integrals (the gyro's
white noise over T); the horizontal Earth rate at the faces' unknown headings (``(W cos L)^2 / 2`` per
horizontal axis of each face, averaged over the six) and in each turn (``|int exp(i theta) dt|^2 (W cos
L)^2 / 2`` per horizontal axis, ``theta`` the measured angle turned); the closure of each turn (its angle
``2 pi`` within ``turn_closure`` rms: a turn by hand against a stop); and the face tilt ``d``, two
components of variance ``face_tilt^2 / 2`` per face, propagated to first order (central differences) and
to second order (the Hessian: its mean and variance, ``tr(H S) / 2`` and ``tr((H S)^2) / 2``, enter the
covariance as the mean square error: the estimate stays that of exact faces).
"""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.multiposition import ACC_FREE, check_gravity, frame_of, lower_frame
from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.static_detect import detect_still
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.earth import OMEGA_IE
from inscal.core.error_model import GimbalErrors, ImuErrors, split_scale_misalignment

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")
#: the default face tilt: the rms angle between a face's normal and the vertical of a hand-placed box on a
#: table (its flatness and squareness, the table's level, what lies under it) [rad]
FACE_TILT = math.radians(0.3)
#: the default closure of a whole turn made by hand against a stop (a box's edge): the rms difference
#: between the angle turned and 360 deg [rad]
TURN_CLOSURE = math.radians(0.2)
#: the input vector of :func:`_estimate`: (name, size) in order
_LAYOUT = (("a", 18), ("w", 18), ("turn", 9), ("T", 3), ("at", 9), ("hb", 3), ("ht", 9), ("tilt", 12), ("ang", 3))
_ENDS = np.cumsum([size for _, size in _LAYOUT])
_SL = {name: slice(int(end) - size, int(end)) for (name, size), end in zip(_LAYOUT, _ENDS)}
N_INPUTS = int(_ENDS[-1])


def _face(f: np.ndarray) -> str:
    i = int(np.argmax(np.abs(f)))
    return ("+" if f[i] > 0 else "-") + "xyz"[i]


def _ups(tilt: np.ndarray) -> np.ndarray:
    """The unit verticals (6, 3) of the faces in FACES order, in the frame c, tilted by ``tilt`` (6, 2): the
    components along the two horizontal axes ``i + 1``, ``i + 2`` (mod 3) of face ``+-i``."""
    u = np.zeros((6, 3))
    for k in range(6):
        i = k // 2
        u[k, i] = 1.0 if k % 2 == 0 else -1.0
        u[k, (i + 1) % 3] += tilt[k, 0]
        u[k, (i + 2) % 3] += tilt[k, 1]
    return u / np.linalg.norm(u, axis=1)[:, None]


def _estimate(inp: np.ndarray, g: float, wv: float, sense: np.ndarray) -> np.ndarray:
    """Parameters (K_a 3, E_a 6, b_a 3, K_g 3, E_g 6, b_g 3) from the input vector (:data:`_LAYOUT`): the six
    faces' mean accel and gyro in FACES order, the three turns' integrals and durations, the mean accel of
    each turn's end poses, the horizontal Earth rate left in the gyro bias and in each turn, the faces' tilts,
    the angle of each whole turn (2 pi when it closes); ``sense``: +-1 per turn (module docstring)."""
    a = inp[_SL["a"]].reshape(6, 3)
    w = inp[_SL["w"]].reshape(6, 3)
    turn = inp[_SL["turn"]].reshape(3, 3)
    T = inp[_SL["T"]]
    at = inp[_SL["at"]].reshape(3, 3)
    u = _ups(inp[_SL["tilt"]].reshape(6, 2))
    D = np.column_stack([(a[2 * i] - a[2 * i + 1]) / g for i in range(3)])
    U = np.column_stack([u[2 * i] - u[2 * i + 1] for i in range(3)])
    M = D @ np.linalg.inv(U)  # Ferraris 1995 eq. 7-8 on tilted faces
    N = np.linalg.inv(M)
    # the bias from the axis each face holds vertical (imucal's form of eq. 6, in the calibrated frame)
    rhs = np.array([0.5 * N[i] @ (a[2 * i] + a[2 * i + 1]) - 0.5 * g * (u[2 * i, i] + u[2 * i + 1, i])
                    for i in range(3)])
    ba = M @ rhs
    uf = (a - ba) @ N.T
    uf /= np.linalg.norm(uf, axis=1)[:, None]
    bg = np.mean(w - wv * uf, axis=0) - inp[_SL["hb"]]  # eq. 9, the vertical Earth rate removed
    v = (at - ba) @ N.T
    v /= np.linalg.norm(v, axis=1)[:, None]  # the vertical each turn is about, frame c
    ht = inp[_SL["ht"]].reshape(3, 3)
    ang = inp[_SL["ang"]]
    W = np.column_stack([sense[j] * (turn[j] - bg * T[j] - wv * T[j] * v[j] - ht[j]) / ang[j]
                         for j in range(3)])  # eq. 10-11
    Mg = W @ np.linalg.inv(v.T)
    L, Q = lower_frame(M)
    ka, ea = split_scale_misalignment(L)
    kg, eg = split_scale_misalignment(Mg @ Q.T)
    return np.concatenate([ka, ea, ba, kg, eg, bg])


def _tilt_moments(fn, x: np.ndarray, var_c: float) -> np.ndarray:
    """The second-order part of the face tilt's effect on the parameters: ``E[y y^T]`` of ``y = d^T H d / 2``
    over the tilts ``d`` (12, independent, variance ``var_c``), H the Hessian of ``fn`` at ``x``."""
    sl = _SL["tilt"]
    idx = np.arange(sl.start, sl.stop)
    m = idx.size
    h = 1e-3
    f0 = fn(x)

    def shifted(p, q, dp, dq):
        e = x.copy()
        e[idx[p]] += dp
        e[idx[q]] += dq
        return fn(e)

    H = np.zeros((f0.size, m, m))
    for p in range(m):
        H[:, p, p] = (shifted(p, p, h, 0.0) - 2.0 * f0 + shifted(p, p, -h, 0.0)) / h**2
        for q in range(p + 1, m):
            H[:, p, q] = H[:, q, p] = (shifted(p, q, h, h) - shifted(p, q, h, -h) - shifted(p, q, -h, h)
                                       + shifted(p, q, -h, -h)) / (4.0 * h * h)
    mean = 0.5 * var_c * np.trace(H, axis1=1, axis2=2)
    cov = 0.5 * var_c**2 * np.einsum("kpq,lqp->kl", H, H)
    return cov + np.outer(mean, mean)


def _turns(poses, dth: np.ndarray, time: np.ndarray, turn_tol_deg: float):
    """The first whole turn about each axis: {axis: (integral, T, i0, i1, first pose, last pose)}, and the
    notes on the turns found but not used."""
    turns: dict[int, tuple] = {}
    notes = []
    for k, c0 in enumerate(poses):
        face = _face(c0.accel)
        a = c0.i1
        for c1 in poses[k + 1:]:
            if _face(c1.accel) != face:
                break
            b = c1.i0
            d = dth[a:b].sum(axis=0)
            ang = math.degrees(float(np.linalg.norm(d)))
            if abs(ang - 360.0) <= turn_tol_deg:
                j = int(np.argmax(np.abs(d)))
                if face[1] != "xyz"[j]:
                    notes.append(f"a whole turn about {'xyz'[j]} on face {face} (poses {c0.number}-{c1.number}) is "
                                 "not about the vertical: not used")
                elif j in turns:
                    notes.append(f"a second whole turn about {'xyz'[j]} (poses {c0.number}-{c1.number}): not used")
                else:
                    turns[j] = (d, float(time[b - 1] - time[a - 1]), a, b, c0, c1)
                break
    return turns, notes


def ferraris(record_like, settle: float = 0.25, min_static: float = 2.0, alpha: float = 1e-4,
             turn_tol_deg: float = 30.0, min_turn_end: float = 0.3, gravity_tol: float = 0.1,
             face_tilt: float = FACE_TILT, turn_closure: float = TURN_CLOSURE) -> CalibrationResult:
    """Calibrate without a turntable from six faces and three whole turns (Ferraris 1995; module docstring).

    The faces' tilt (``face_tilt``) and the turns' closure (``turn_closure``) are stated inputs of
    the sigma.

    Parameters
    ----------
    record_like : Record
        A Ferraris session (``time``, ``dtheta``, ``dvel``, ``rate_hz``, ``site``).
    settle : float
        Seconds dropped at each end of a pose [s].
    min_static : float
        The shortest face pose [s].
    alpha : float
        The false-alarm rate of the still detector's tests.
    turn_tol_deg : float
        How far from 360 deg a turn may be [deg].
    min_turn_end : float
        The shortest still pose at the end of a turn, after ``settle`` at both ends [s].
    gravity_tol : float
        The largest relative difference between the faces' median specific force and the site's
        gravity (more is a wrong unit or site).
    face_tilt : float
        The rms angle between a face's normal and the vertical [rad] (0: exact faces).
    turn_closure : float
        The rms difference between a whole turn's angle and 360 deg [rad] (0: exact).

    Returns
    -------
    CalibrationResult
        The IMU errors that the faces and the turns determine (SI), with their 1 sigma.

    Raises
    ------
    CalibrationError
        Faces or turns not found, or a gravity magnitude that does not match the site.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.sim.records import scenario_record
    >>> from inscal.calibrate import ferraris
    >>> rec = scenario_record("ferraris-mems", np.random.default_rng(0))  # with its truth
    >>> res = ferraris(rec)
    >>> z = (res.imu.gyro_bias - rec.truth.imu.gyro_bias) / res.sigma["gyro_bias"]
    >>> bool(np.all(np.abs(z) < 3))
    True
    """
    _check_options(settle, min_static, min_turn_end, turn_tol_deg, gravity_tol, face_tilt, turn_closure)
    min_turn_end = min(min_turn_end, min_static)
    time = np.asarray(record_like.time, float)
    dth = np.asarray(record_like.dtheta, float)
    dv = np.asarray(record_like.dvel, float)
    site = record_like.site
    g = float(site.gravity)
    si = detect_still(time, dth, dv, min_still=min_turn_end, settle=settle, alpha=alpha)
    poses = si.require(6, "the Ferraris method (six faces)")
    check_gravity(float(np.median([np.linalg.norm(c.accel) for c in poses])), g, gravity_tol)
    faces = _six_faces(poses, si, min_static)
    turns, tnotes = _turns(poses, dth, time, turn_tol_deg)
    if len(turns) < 3:
        raise CalibrationError(f"found whole turns about {''.join('xyz'[j] for j in sorted(turns)) or 'no axis'}: "
                               "Ferraris needs one 360 deg turn about the vertical on a face with each of x, y, z "
                               f"vertical, from a still pose of at least {min_turn_end:g} s (--min-turn-end-s, after "
                               f"--settle-s {settle:g} at both ends) and back to one")
    wv = OMEGA_IE * math.sin(site.latitude)
    wh = OMEGA_IE * math.cos(site.latitude)
    x, vx, sgn = _inputs(faces, turns, si, dth, wh, face_tilt, turn_closure)

    def fn(z):
        return _estimate(z, g, wv, sgn)

    p, cov = _propagate(fn, x, vx, face_tilt)
    return _result(p, cov, si, faces, turns, tnotes, face_tilt, turn_closure, wh)


def _check_options(settle, min_static, min_turn_end, turn_tol_deg, gravity_tol, face_tilt, turn_closure) -> None:
    """:func:`ferraris`'s options in their ranges, else a :class:`CalibrationError` naming the first that is not."""
    for name, v, ok in (("settle", settle, settle >= 0), ("min_static", min_static, min_static > 0),
                        ("min_turn_end", min_turn_end, min_turn_end > 0),
                        ("turn_tol_deg", turn_tol_deg, 0 < turn_tol_deg < 180),
                        ("gravity_tol", gravity_tol, 0 < gravity_tol < 1),
                        ("face_tilt", face_tilt, 0 <= face_tilt <= math.radians(10.0)),
                        ("turn_closure", turn_closure, 0 <= turn_closure <= math.radians(10.0))):
        if not (math.isfinite(v) and ok):
            raise CalibrationError(f"ferraris: {name} = {v} out of range (settle >= 0, min_static > 0, "
                                   "min_turn_end > 0, 0 < turn_tol_deg < 180, 0 < gravity_tol < 1, "
                                   "0 <= face_tilt, turn_closure <= 10 deg)")


def _six_faces(poses, si, min_static: float) -> dict:
    """The longest still pose of at least ``min_static`` s on each face: {face: pose}, every face of
    :data:`FACES` (else a :class:`CalibrationError` naming the faces missing and why)."""
    faces: dict[str, object] = {}
    for c in poses:
        f = _face(c.accel)
        if c.duration >= min_static and (f not in faces or c.duration > faces[f].duration):
            faces[f] = c
    missing = [f for f in FACES if f not in faces]
    if missing:
        short = [c for c in poses if _face(c.accel) in missing]
        rej = [c for c in si.rejected if _face(c.accel) in missing and c.duration > 0]
        why = ""
        if short:
            c = max(short, key=lambda c: c.duration)
            why = (f"; on {_face(c.accel)} the longest still pose lasts {c.duration:.3g} s, below --min-static-s "
                   f"{min_static:g}")
        elif rej:
            why = f"; {rej[0].describe()}"
        raise CalibrationError(f"the face poses (still >= {min_static:g} s) rest on {len(faces)} of the six faces: no "
                               f"pose with {', '.join(missing)} up (Ferraris needs all six){why}")
    return faces


def _inputs(faces: dict, turns: dict, si, dth: np.ndarray, wh: float, face_tilt: float, turn_closure: float):
    """The input vector of :func:`_estimate` (:data:`_LAYOUT`), its variances (the Type A noise of the means
    and integrals, the Type B horizontal Earth rate, face tilt and turn closure) and the sense of each turn."""
    x = np.zeros(N_INPUTS)
    vx = np.zeros(N_INPUTS)
    x[_SL["a"]] = np.concatenate([faces[f].accel for f in FACES])
    vx[_SL["a"]] = np.concatenate([faces[f].accel_sigma ** 2 for f in FACES])
    x[_SL["w"]] = np.concatenate([faces[f].gyro for f in FACES])
    vx[_SL["w"]] = np.concatenate([faces[f].gyro_sigma ** 2 for f in FACES])
    dens = si.gyro_density
    at, vat, reach = [], [], []
    for j in range(3):
        d, T, a, b, c0, c1 = turns[j]
        w0, w1 = c0.duration, c1.duration  # the end poses' mean, weighted by duration (same attitude)
        at.append((w0 * c0.accel + w1 * c1.accel) / (w0 + w1))
        vat.append((w0**2 * c0.accel_sigma**2 + w1**2 * c1.accel_sigma**2) / (w0 + w1) ** 2)
        # the horizontal Earth rate as the body turns: |int exp(i theta) dt| (theta the angle turned so far)
        ax = d / np.linalg.norm(d)
        theta = np.cumsum(dth[a:b] @ ax)
        reach.append(abs(complex(np.sum(si.dt[a:b] * np.exp(1j * theta)))))
    x[_SL["turn"]] = np.concatenate([turns[j][0] for j in range(3)])
    vx[_SL["turn"]] = np.concatenate([dens**2 * turns[j][1] for j in range(3)])
    x[_SL["T"]] = [turns[j][1] for j in range(3)]
    x[_SL["at"]] = np.concatenate(at)
    vx[_SL["at"]] = np.concatenate(vat)
    # Type B: the horizontal Earth rate at the faces' unknown headings, (W cos L)^2 / 2 per horizontal axis
    # of a face (4 of the 6 faces per axis), averaged over the six; in a turn along its two horizontal axes
    vx[_SL["hb"]] = 4.0 * 0.5 * wh**2 / 36.0
    vht = np.zeros((3, 3))
    for j in range(3):
        vht[j] = 0.5 * (wh * reach[j]) ** 2
        vht[j, j] = 0.0
    vx[_SL["ht"]] = vht.ravel()
    vx[_SL["tilt"]] = 0.5 * face_tilt**2  # two components per face
    x[_SL["ang"]] = 2.0 * math.pi
    vx[_SL["ang"]] = turn_closure**2
    # the sense of each turn: + when it turns counterclockwise about the vertical it is about
    sgn = np.array([math.copysign(1.0, turns[j][0][j] * at[j][j]) for j in range(3)])
    return x, vx, sgn


def _propagate(fn, x: np.ndarray, vx: np.ndarray, face_tilt: float):
    """The parameters ``fn(x)`` and their covariance: the inputs' variances ``vx`` to first order (central
    differences), the face tilt's to second order too (:func:`_tilt_moments`)."""
    p = fn(x)
    J = np.zeros((p.size, x.size))
    for k in range(x.size):
        h = 1e-6 * max(abs(x[k]), 1e-3) if vx[k] > 0 else 0.0
        if h == 0.0:
            continue
        e = np.zeros_like(x)
        e[k] = h
        J[:, k] = (fn(x + e) - fn(x - e)) / (2 * h)
    cov = (J * vx[None, :]) @ J.T
    if face_tilt > 0:
        cov = cov + _tilt_moments(fn, x, 0.5 * face_tilt**2)
    return p, cov


def _result(p: np.ndarray, cov: np.ndarray, si, faces: dict, turns: dict, tnotes: list, face_tilt: float,
            turn_closure: float, wh: float) -> CalibrationResult:
    """:func:`ferraris`'s result from the parameters ``p`` and their covariance: the accelerometer
    misalignments the frame holds fixed set to 0 (sigma NaN), the notes and the diagnostics."""
    sd = np.sqrt(np.diag(cov))
    ea = p[3:9].copy()
    held = np.ones(6, bool)
    held[list(ACC_FREE)] = False
    ea[held] = 0.0
    sea = sd[3:9].copy()
    sea[held] = np.nan
    values = {"accel_scale_factor": p[0:3], "accel_misalignment": ea, "accel_bias": p[9:12],
              "gyro_scale_factor": p[12:15], "gyro_misalignment": p[15:21], "gyro_bias": p[21:24]}
    sigma = {"accel_scale_factor": sd[0:3], "accel_misalignment": sea, "accel_bias": sd[9:12],
             "gyro_scale_factor": sd[12:15], "gyro_misalignment": sd[15:21], "gyro_bias": sd[21:24]}
    tilt_deg = math.degrees(face_tilt)
    notes = list(si.notes) + tnotes + [
        f"faces tilted by {tilt_deg:.3g} deg rms (stated, --face-tilt-deg) are in the sigma: the misalignments are "
        "known to within the faces' tilt, the biases and scale factors to second order in it; the turns are assumed "
        f"about the vertical and to close within {math.degrees(turn_closure):.3g} deg rms (stated, --turn-closure-deg; "
        "in the sigma of the gyro scale factors); the horizontal Earth rate "
        f"({units.from_si(wh, 'deg/h'):.3g} deg/h) at the faces' unknown headings is not removed: the sigma holds it"]
    labels = [f"{n}.{c}" for n, cs in (("accel_scale_factor", "xyz"), ("accel_misalignment", ("xy", "xz", "yx", "yz",
              "zx", "zy")), ("accel_bias", "xyz"), ("gyro_scale_factor", "xyz"), ("gyro_misalignment", ("xy", "xz",
              "yx", "yz", "zx", "zy")), ("gyro_bias", "xyz")) for c in cs]
    keep = [i for i in range(p.size) if not (3 <= i < 9 and held[i - 3])]
    diagnostics = {"still": si.report(), "faces": {f: faces[f].number for f in FACES},
                   "turns": {"xyz"[j]: {"degrees": math.degrees(float(np.linalg.norm(turns[j][0]))),
                                        "seconds": turns[j][1], "poses": [turns[j][4].number, turns[j][5].number]}
                             for j in range(3)},
                   "face_tilt_deg": tilt_deg, "turn_closure_deg": math.degrees(turn_closure),
                   "covariance": {"labels": [labels[i] for i in keep], "P": cov[np.ix_(keep, keep)]},
                   "frame": "accelerometer frame (x: accel x, y in the accel xy plane)"}
    return CalibrationResult("ferraris", ImuErrors(**values), GimbalErrors(), sigma, tuple(values), None,
                             diagnostics, notes, truth_transform=frame_of)
