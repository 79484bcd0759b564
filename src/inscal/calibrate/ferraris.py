"""The Ferraris method: six faces and three whole turns, without a rate table (Ferraris, Grimaldi &
Parvis, Sensors and Materials 7(5), 1995, 311-330).

The IMU (in a cube, or a box with square faces) rests on each of its six faces (``+x, -x, +y, -y, +z, -z``
up, in any order), and turns through one whole turn (360 deg) about each of its three axes, starting and
ending still on a face.  The still poses are found by :mod:`.static_detect`; each is assigned to a face
by the sign of its largest specific-force component; a *whole turn* is a move between two still poses on
the same face whose integrated rotation is near 360 deg.

Accelerometers (Ferraris 1995 eq. 6-8), ``a(+i)`` the mean output with ``+i`` up (``f = +g e_i``)::

    b_a = sum_i (a(+i) + a(-i)) / 6,      M_a[:, i] = (a(+i) - a(-i)) / (2 g)

Gyros (Ferraris 1995 eq. 9-11): ``b_g`` the mean of the six faces after the vertical Earth rate
``W sin L`` along each face's measured gravity direction is removed (the horizontal Earth rate, at most
``W cos L``, is not: a note gives it), and for the whole turn about axis j::

    M_g[:, j] = (int (dtheta - b_g dt) - W sin L u T) / (2 pi s_j)     (s_j = +-1, the sense of the turn)

with ``u`` the vertical in the body and ``T`` the duration of the turn.  The results are expressed in
the accelerometer frame of :mod:`.multiposition` (``M_a = L Q``, L lower triangular; ``M_g Q^T``), so both
methods report the same parameters.  1 sigma: the noise of the window means and of the turn integrals
propagated through these equations (central differences); the horizontal Earth rate the method leaves in is a Type B input (sigma
``W cos L / 2`` in the face means, ``W cos L T / 2`` in a turn); the method's other assumptions (exact
faces, turns about the body axes) are not in the sigma and are named in the notes.
"""

from __future__ import annotations

import math

import numpy as np

from inscal.calibrate.multiposition import ACC_FREE, frame_of, lower_frame
from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.static_detect import detect_still
from inscal.calibrate.windows import CalibrationError
from inscal.core import units
from inscal.core.earth import OMEGA_IE
from inscal.core.error_model import GimbalErrors, ImuErrors, split_scale_misalignment

FACES = ("+x", "-x", "+y", "-y", "+z", "-z")


def _face(f: np.ndarray) -> str:
    i = int(np.argmax(np.abs(f)))
    return ("+" if f[i] > 0 else "-") + "xyz"[i]


def _estimate(inp: np.ndarray, g: float, wv: float, sense: np.ndarray, earth: np.ndarray) -> np.ndarray:
    """Parameters (K_a 3, E_a 6, b_a 3, K_g 3, E_g 6, b_g 3) from the input vector: the six faces' mean
    accel (18) and gyro (18) in FACES order, then the three turns' integrals (9) and durations (3);
    ``sense``: +-1 per turn, ``earth``: the Earth rate integrated over each turn (3, 3) [rad]."""
    a = inp[:18].reshape(6, 3)
    w = inp[18:36].reshape(6, 3)
    turn = inp[36:45].reshape(3, 3)
    T = inp[45:48]
    ba = a.sum(axis=0) / 6.0  # Ferraris 1995 eq. 6
    Ma = np.column_stack([(a[2 * i] - a[2 * i + 1]) / (2.0 * g) for i in range(3)])  # eq. 7-8
    u = np.linalg.solve(Ma, (a - ba).T).T
    u /= np.linalg.norm(u, axis=1)[:, None]
    hb, ht = inp[48:51], inp[51:60].reshape(3, 3)  # the horizontal Earth rate left in (zero; a Type B input)
    bg = np.mean(w - wv * u, axis=0) - hb  # eq. 9, the vertical Earth rate removed (to first order in M_g - I)
    cols = []
    for j in range(3):
        cols.append(sense[j] * (turn[j] - bg * T[j] - earth[j] - ht[j]) / (2.0 * math.pi))  # eq. 10-11
    Mg = np.column_stack(cols)
    L, Q = lower_frame(Ma)
    ka, ea = split_scale_misalignment(L)
    kg, eg = split_scale_misalignment(Mg @ Q.T)
    return np.concatenate([ka, ea, ba, kg, eg, bg])


def ferraris(record_like, settle: float = 0.25, min_static: float = 2.0, alpha: float = 1e-3,
             turn_tol_deg: float = 30.0) -> CalibrationResult:
    """Calibrate from six faces and three whole turns (module docstring).  ``settle``, ``min_static`` [s],
    ``alpha``: :func:`.static_detect.detect_still`; ``turn_tol_deg``: how far from 360 deg a move between
    two poses on the same face may be and still count as a whole turn."""
    time = np.asarray(record_like.time, float)
    dth = np.asarray(record_like.dtheta, float)
    dv = np.asarray(record_like.dvel, float)
    site = record_like.site
    g = float(site.gravity)
    si = detect_still(time, dth, dv, min_still=min_static, settle=settle, alpha=alpha)
    poses = si.require(6, "the Ferraris method (six faces)")
    faces: dict[str, list] = {}
    for c in poses:
        faces.setdefault(_face(c.accel), []).append(c)
    missing = [f for f in FACES if f not in faces]
    if missing:
        raise CalibrationError(f"the still poses rest on {len(faces)} of the six faces: no pose with "
                               f"{', '.join(missing)} up (Ferraris needs all six)")
    turns: dict[int, tuple] = {}
    for c0, c1 in zip(poses[:-1], poses[1:]):
        if _face(c0.accel) != _face(c1.accel):
            continue
        a, b = c0.i1, c1.i0
        d = dth[a:b].sum(axis=0)
        ang = float(np.linalg.norm(d))
        j = int(np.argmax(np.abs(d)))
        if abs(math.degrees(ang) - 360.0) <= turn_tol_deg and j not in turns:
            T = float(time[b - 1] - time[a - 1])
            turns[j] = (d, T, b - a, c0, c1)
    if len(turns) < 3:
        raise CalibrationError(f"found whole turns about {''.join('xyz'[j] for j in sorted(turns)) or 'no axis'}: "
                               "Ferraris needs one 360 deg turn about each of x, y, z, from and back to a still face")
    inp, var = [], []
    for f in FACES:
        c = faces[f][0]
        inp.append(c.accel)
        var.append(c.accel_sigma**2)
    for f in FACES:
        c = faces[f][0]
        inp.append(c.gyro)
        var.append(c.gyro_sigma**2)
    dens = si.gyro_density
    for j in range(3):
        d, T, n, _, _ = turns[j]
        inp.append(d)
        var.append(dens**2 * T)
    for j in range(3):
        inp.append([turns[j][1]])
        var.append([0.0])
    # Type B: the horizontal Earth rate the method leaves in the face means (at most W cos L, sigma half that)
    # and in each turn (its integral over a turn, at most W cos L T)
    wh_si = OMEGA_IE * math.cos(site.latitude)
    inp.append(np.zeros(3))
    var.append(np.full(3, (wh_si / 2.0) ** 2))
    for j in range(3):
        inp.append(np.zeros(3))
        var.append(np.full(3, (wh_si * turns[j][1] / 2.0) ** 2))
    x = np.concatenate([np.ravel(v) for v in inp])
    vx = np.concatenate([np.ravel(v) for v in var])
    wv = OMEGA_IE * math.sin(site.latitude)
    # the sense of each turn (the sign of its integral along its axis) and the vertical Earth rate it
    # integrates: the part along the turn axis stays, the rest turns with the body and averages out
    sgn = np.array([np.sign(turns[j][0][j]) for j in range(3)])
    earth = np.zeros((3, 3))
    for j in range(3):
        u0 = turns[j][3].accel / np.linalg.norm(turns[j][3].accel)
        earth[j, j] = wv * turns[j][1] * u0[j]
    p = _estimate(x, g, wv, sgn, earth)
    J = np.zeros((p.size, x.size))
    for k in range(x.size):
        h = 1e-6 * max(abs(x[k]), 1e-3)
        e = np.zeros_like(x)
        e[k] = h
        J[:, k] = (_estimate(x + e, g, wv, sgn, earth) - _estimate(x - e, g, wv, sgn, earth)) / (2 * h)
    cov = (J * vx[None, :]) @ J.T
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
    wh = units.from_si(OMEGA_IE * math.cos(site.latitude), "deg/h")
    notes = list(si.notes) + [
        f"Ferraris assumes exact cube faces and turns about the body axes (not in the sigma); the horizontal Earth "
        f"rate ({wh:.3g} deg/h) is not removed from the gyro bias nor from the turns: the sigma holds it (Type B)"]
    labels = [f"{n}.{c}" for n, cs in (("accel_scale_factor", "xyz"), ("accel_misalignment", ("xy", "xz", "yx", "yz",
              "zx", "zy")), ("accel_bias", "xyz"), ("gyro_scale_factor", "xyz"), ("gyro_misalignment", ("xy", "xz",
              "yx", "yz", "zx", "zy")), ("gyro_bias", "xyz")) for c in cs]
    keep = [i for i in range(p.size) if not (3 <= i < 9 and held[i - 3])]
    diagnostics = {"still": si.report(), "faces": {f: [c.number for c in faces[f]] for f in FACES},
                   "turns": {"xyz"[j]: {"degrees": math.degrees(float(np.linalg.norm(turns[j][0]))),
                                        "seconds": turns[j][1]} for j in range(3)},
                   "covariance": {"labels": [labels[i] for i in keep], "P": cov[np.ix_(keep, keep)]},
                   "frame": "accelerometer frame (x: accel x, y in the accel xy plane)"}
    return CalibrationResult("ferraris", ImuErrors(**values), GimbalErrors(), sigma, tuple(values), None,
                             diagnostics, notes, truth_transform=frame_of)
