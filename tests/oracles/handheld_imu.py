"""An independent generator of hand-held (table-free) multi-position IMU logs, written from the
equations.  NumPy only: it shares no code with inscal (a test oracle).

Frames: navigation n = East-North-Up at latitude L, fixed to the Earth; body b = the frame in which
the accelerometer matrix is lower triangular (x along the accelerometer x axis, y in the plane of
accelerometers x and y), the convention of Tedaldi et al. (ICRA 2014) for a frame the poses define.

Motion (closed form).  The IMU rests in pose j (attitude ``C_b^n = C_j``) and moves to pose j+1 by a
rotation through ``Theta_j`` about a body axis ``e_j`` with the profile
``theta(s) = Theta (s - sin(2 pi s) / (2 pi))``, ``s = (t - t_m) / T`` (rate ``Theta/T (1 - cos 2 pi s)``,
zero rate and acceleration at both ends), and a hand tremor
``tau(s) = A sin^2(pi s) sin(2 pi f_tr t)`` about a second body axis ``e2_j``::

    C_b^n(t) = C_j Rot(e_j, theta) Rot(e2_j, tau),     Rot(e, a) = I + sin a [e]x + (1 - cos a) [e]x^2
    w_nb^b   = Rot(e2, tau)^T e theta_dot + e2 tau_dot
    w_ib^b   = w_nb^b + C_n^b w_ie^n,   w_ie^n = W [0, cos L, sin L]
    f^b      = C_n^b [0, 0, g]

(the tremor returns to zero at the end of the move, so ``C_{j+1} = C_j Rot(e_j, Theta_j)``).

Sensors::

    gyro:   w_meas = Mg w_ib^b + bg                 Mg full 3x3 (scale factors, misalignment)
    accel:  f_meas = Ma (f + k2 * f**2) + ba        Ma lower triangular, k2 elementwise

With ``samples``, the log holds instead the instantaneous readings at the edges (a logger's rates and
specific forces at its own timestamps; white noise of density ``arw/vrw`` over the median step).

Increments over ``[t_{k-1}, t_k]`` (any time base): Gauss-Legendre (8 points) on every piece between
the motion's breakpoints, so the quadrature is exact to round-off for the dwell and very accurate on
the smooth moves; white noise of density ``arw`` / ``vrw`` added as ``N sqrt(dt_k)`` per increment.
"""

import math
from dataclasses import dataclass, field

import numpy as np

EARTH_RATE = 7.292115e-5


def rot(e, a):
    e = np.asarray(e, float)
    k = np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])
    return np.eye(3) + math.sin(a) * k + (1.0 - math.cos(a)) * (k @ k)


def _rot_many(e, a):
    """Rot(e, a) for a scalar axis e and an array of angles a -> (n, 3, 3)."""
    k = np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])
    s, c = np.sin(a)[:, None, None], (1.0 - np.cos(a))[:, None, None]
    return np.eye(3)[None] + s * k[None] + c * (k @ k)[None]


@dataclass
class HandheldLog:
    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    poses: list  # C_b^n of every pose
    still: list  # (t0, t1) of every still pose
    truth: dict = field(default_factory=dict)


def random_poses(rng, n):
    """n attitudes spread over the sphere (the gravity directions of a Fibonacci lattice, random heading)."""
    out = []
    for i in range(n):
        z = 1.0 - 2.0 * (i + 0.5) / n
        phi = math.pi * (3.0 - math.sqrt(5.0)) * i
        up = np.array([math.sqrt(1 - z * z) * math.cos(phi), math.sqrt(1 - z * z) * math.sin(phi), z])  # n-up in b
        a = rng.normal(size=3)
        x = a - up * (a @ up)
        x /= np.linalg.norm(x)
        y = np.cross(up, x)
        out.append(np.array([x, y, up]))  # rows: the E, N, U axes in body components: C_b^n
    return out


def generate(rng, Mg, bg, Ma, ba, k2=np.zeros(3), lat=0.8, g=9.80, rate_hz=100.0, n_poses=12, still_s=4.0,
             move_s=3.0, tremor_deg=0.0, tremor_hz=8.0, arw=0.0, vrw=0.0, jitter=0.0, noise_rng=None, poses=None,
             turns=None, samples=False):
    """A log: still, move, still, ... (poses: C_b^n list, default :func:`random_poses`; ``still_s``: one
    duration or one per pose; ``turns``: {move index: (body axis, angle)} for moves that are not the
    shortest rotation between their poses, e.g. a whole turn, 2 pi, between two equal poses)."""
    poses = random_poses(rng, n_poses) if poses is None else poses
    still = np.broadcast_to(np.asarray(still_s, float), (len(poses),))
    wie = EARTH_RATE * np.array([0.0, math.cos(lat), math.sin(lat)])
    moves = []  # (t_m, T, C_j, e, Theta, e2)
    t = still[0]
    for j in range(len(poses) - 1):
        R = poses[j].T @ poses[j + 1]  # Rot(e, Theta) = C_j^T C_{j+1}
        ang = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
        e = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        e = e / np.linalg.norm(e) if np.linalg.norm(e) > 0 else np.array([0.0, 0.0, 1.0])
        if turns and j in turns:
            e, ang = np.asarray(turns[j][0], float), float(turns[j][1])
            assert np.allclose(rot(e, ang), R, atol=1e-9), "a turn must take pose j to pose j+1"
        e2 = rng.normal(size=3)
        e2 /= np.linalg.norm(e2)
        moves.append((t, move_s, poses[j], e, ang, e2))
        t += move_s + still[j + 1]
    t_end = t
    n = int(round(t_end * rate_hz))
    edges = np.arange(n + 1) / rate_hz
    if jitter:
        edges[1:-1] += rng.uniform(-jitter, jitter, n - 1) / rate_hz
    bps = sorted({m[0] for m in moves} | {m[0] + m[1] for m in moves})
    allp = np.union1d(edges, [b for b in bps if 0 < b < t_end])
    owner = np.searchsorted(edges, allp[:-1], side="right") - 1
    xg, wg = np.polynomial.legendre.leggauss(8)
    a, b = allp[:-1], allp[1:]
    tn = (0.5 * (a + b))[:, None] + 0.5 * (b - a)[:, None] * xg[None]  # (pieces, 8)
    wq = 0.5 * (b - a)[:, None] * wg[None]
    def signals(tt):
        """The measured rate and specific force (noise-free) at times tt."""
        Cbn = np.repeat(poses[-1][None], tt.size, axis=0)
        wnb = np.zeros((tt.size, 3))
        mstart = np.array([m[0] for m in moves])
        idx = np.searchsorted(mstart, tt, side="right") - 1
        for j, (tm, T, Cj, e, Th, e2) in enumerate(moves):
            before = idx == j
            s = np.clip((tt[before] - tm) / T, 0.0, 1.0)
            th = Th * (s - np.sin(2 * np.pi * s) / (2 * np.pi))
            thd = Th / T * (1.0 - np.cos(2 * np.pi * s))
            A = math.radians(tremor_deg)
            tau = A * np.sin(np.pi * s) ** 2 * np.sin(2 * np.pi * tremor_hz * tt[before])
            taud = A * (np.pi / T * np.sin(2 * np.pi * s) * np.sin(2 * np.pi * tremor_hz * tt[before])
                        + np.sin(np.pi * s) ** 2 * 2 * np.pi * tremor_hz * np.cos(2 * np.pi * tremor_hz * tt[before]))
            inmove = s < 1.0
            R1, R2 = _rot_many(e, th), _rot_many(e2, tau)
            C = np.einsum("ij,njk,nkl->nil", Cj, R1, R2)
            C[~inmove] = Cj @ rot(e, Th)
            Cbn[before] = C
            w = np.einsum("nji,j->ni", R2, e) * thd[:, None] + e2[None] * taud[:, None]
            w[~inmove] = 0.0
            wnb[before] = w
        first = idx < 0
        Cbn[first] = poses[0]
        wnb[first] = 0.0
        Cnb = np.transpose(Cbn, (0, 2, 1))
        wib = wnb + Cnb @ wie
        f = Cnb @ np.array([0.0, 0.0, g])
        gm = wib @ Mg.T + bg
        am = (f + k2 * f * f) @ Ma.T + ba
        return gm, am

    gm, am = signals(tn.ravel())
    ig = np.einsum("pq,pqi->pi", wq, gm.reshape(-1, 8, 3))
    ia = np.einsum("pq,pqi->pi", wq, am.reshape(-1, 8, 3))
    dth = np.zeros((n, 3))
    dv = np.zeros((n, 3))
    np.add.at(dth, owner, ig)
    np.add.at(dv, owner, ia)
    dt = np.diff(edges)
    if arw or vrw:
        nr = noise_rng if noise_rng is not None else rng
        dth += arw * np.sqrt(dt)[:, None] * nr.normal(size=(n, 3))
        dv += vrw * np.sqrt(dt)[:, None] * nr.normal(size=(n, 3))
    spans = [(0.0, still[0])] + [(m[0] + m[1], m[0] + m[1] + still[j + 1]) for j, m in enumerate(moves)]
    if samples:  # a logger's instantaneous readings at the (jittered) edges; white noise of the same density
        gs, as_ = signals(edges)
        if arw or vrw:
            nr = noise_rng if noise_rng is not None else rng
            h = np.median(np.diff(edges))
            gs = gs + arw / np.sqrt(h) * nr.normal(size=gs.shape)
            as_ = as_ + vrw / np.sqrt(h) * nr.normal(size=as_.shape)
        dth, dv = gs, as_
        edges = np.concatenate([[edges[0] - 1.0], edges])  # time = the edges themselves
    return HandheldLog(edges[1:], dth, dv, poses, spans, {"Mg": Mg, "bg": bg, "Ma": Ma, "ba": ba, "k2": k2,
                                                          "lat": lat, "g": g})


def canonical_truth(Mg, bg, Ma, ba):
    """The truth in inscal's parametrisation M = (I + K)(I + E): K = diag(M) - 1, E_ij = M_ij / M_ii."""
    def split(M):
        d = np.diag(M)
        E = M / d[:, None]
        return d - 1.0, np.array([E[0, 1], E[0, 2], E[1, 0], E[1, 2], E[2, 0], E[2, 1]])
    kg, eg = split(Mg)
    ka, ea = split(Ma)
    return {"gyro_scale_factor": kg, "gyro_misalignment": eg, "gyro_bias": np.asarray(bg, float),
            "accel_scale_factor": ka, "accel_misalignment": ea, "accel_bias": np.asarray(ba, float)}


def grade(name, rng):
    """Random true errors of a MEMS, tactical or navigation-grade IMU: (Mg, bg, Ma, ba, arw, vrw) SI."""
    deg, hour = math.pi / 180.0, 3600.0
    sf, mis, gb, ab, arw, vrw = {
        "mems": (3e-3, 2e-3, 0.3 * deg, 0.05, 0.3 * deg / 60, 1e-3),
        "tactical": (3e-4, 3e-4, 5 * deg / hour, 5e-3, 0.1 * deg / 60, 2e-4),
        "navigation": (5e-5, 5e-5, 0.01 * deg / hour, 5e-4, 0.002 * deg / 60, 2e-5),
    }[name]
    Mg = np.eye(3) + np.diag(rng.normal(0, sf, 3)) + (np.ones((3, 3)) - np.eye(3)) * rng.normal(0, mis, (3, 3))
    Ma = np.eye(3) + np.diag(rng.normal(0, sf, 3)) + np.tril(rng.normal(0, mis, (3, 3)), -1)
    return Mg, rng.normal(0, gb, 3), Ma, rng.normal(0, ab, 3), arw, vrw


def tilted_face(axis, sign, heading, tilt):
    """C_b^n of a face (body axis ``axis`` up with ``sign``) whose vertical in the body is tilted by the small
    angles ``tilt`` (2,) towards the two other axes (axis + 1, axis + 2 mod 3), at ``heading`` [rad]."""
    up = np.zeros(3)
    up[axis] = sign
    up[(axis + 1) % 3] += tilt[0]
    up[(axis + 2) % 3] += tilt[1]
    up /= np.linalg.norm(up)
    a = np.array([0.3, 0.5, 0.7])
    x = a - up * (a @ up)
    x /= np.linalg.norm(x)
    return (rot(up, heading) @ np.column_stack([x, np.cross(up, x), up])).T, up


def ferraris_session(rng, Mg, bg, Ma, ba, tilt_deg=0.3, rate_hz=102.4, arw=0.0, vrw=0.0, lat=0.8, g=9.80,
                     face_s=(4.0, 7.0), end_s=(1.0, 1.5), move_s=3.0, lsb=None, closure_deg=0.2):
    """A Ferraris session laid out like imucal's example: the six faces +x, -x, +y, -y, +z, -z held
    ``face_s`` s (uniform), then for x, y, z a pose on the + face of ``end_s`` s, one whole turn about the
    vertical (either sense) and the same pose again for ``end_s`` s.  Every placement on a face has its own
    heading and tilt (two components, each normal with sigma ``tilt_deg / sqrt(2)``); a turn is about the
    tilted vertical through 360 deg plus a closure error (normal, sigma ``closure_deg``: a turn by hand
    against a stop), so it ends in the attitude it started from turned by that error.  ``lsb`` (gyro rad/s, accel m/s^2): the
    mean rates of each interval rounded to a logger's counts."""
    sc = math.radians(tilt_deg) / math.sqrt(2.0)
    poses, stills, turns, tilts, ups = [], [], {}, [], []
    for k in range(6):
        t = rng.normal(0.0, sc, 2)
        C, up = tilted_face(k // 2, 1.0 if k % 2 == 0 else -1.0, rng.uniform(0, 2 * math.pi), t)
        poses.append(C)
        stills.append(rng.uniform(*face_s))
        tilts.append(t)
        ups.append(up)
    for j in range(3):
        t = rng.normal(0.0, sc, 2)
        C, up = tilted_face(j, 1.0, rng.uniform(0, 2 * math.pi), t)
        ang = rng.choice([-1.0, 1.0]) * (2 * math.pi + rng.normal(0.0, math.radians(closure_deg)))
        turns[len(poses)] = (up, ang)
        poses += [C, C @ rot(up, ang)]
        stills += [rng.uniform(*end_s), rng.uniform(*end_s)]
    lg = generate(rng, Mg, bg, Ma, ba, poses=poses, turns=turns, still_s=stills, rate_hz=rate_hz, lat=lat, g=g,
                  arw=arw, vrw=vrw, move_s=move_s)
    if lsb is not None:
        dt = np.diff(np.concatenate([[0.0], lg.time]))[:, None]
        lg.dtheta = np.round(lg.dtheta / dt / lsb[0]) * lsb[0] * dt
        lg.dvel = np.round(lg.dvel / dt / lsb[1]) * lsb[1] * dt
    lg.truth["tilts"] = np.array(tilts)
    lg.truth["ups"] = np.array(ups)
    return lg


def imucal_ferraris(acc, gyr, fs, g, expected_deg=360.0):
    """imucal's Ferraris calibration (mad-lab-fau/imucal, ``FerrarisCalibration.compute``), written here from
    its published equations: ``acc``, ``gyr`` dicts of the sample arrays (n, 3) of the regions ``x_p, x_a, y_p,
    y_a, z_p, z_a`` (the axis up / down) and ``x_rot, y_rot, z_rot`` (the turns); ``expected_deg``: the angle
    of each turn (its sign the sense).  Returns (K_a, R_a, b_a, K_g, R_g, K_ga, b_g): ``acc_raw = K_a R_a acc +
    b_a``, ``gyr_raw = K_g R_g gyr + K_ga acc + b_g`` (gyr in deg/s)."""
    mean = {k: np.mean(v, axis=0) for k, v in {**{"a" + k: v for k, v in acc.items()},
                                                **{"g" + k: v for k, v in gyr.items()}}.items()}
    up = np.column_stack([mean["a" + a + "_p"] for a in "xyz"])
    dn = np.column_stack([mean["a" + a + "_a"] for a in "xyz"])
    b_a = np.diag(up + dn) / 2.0  # the axis each face holds vertical
    d = up - dn
    K_a = np.diag(np.sqrt(np.diag(d @ d.T)) / (2.0 * g))
    R_a = np.linalg.solve(K_a, d / (2.0 * g))
    b_g = np.mean(np.vstack([gyr[a + s] for a in "xyz" for s in ("_p", "_a")]), axis=0)
    gu = np.column_stack([mean["g" + a + "_p"] for a in "xyz"])
    gd = np.column_stack([mean["g" + a + "_a"] for a in "xyz"])
    K_ga = (gu - gd) / (2.0 * g)
    W = np.zeros((3, 3))
    for j, a in enumerate("xyz"):
        ac = np.linalg.solve(K_a @ R_a, (acc[a + "_rot"] - b_a).T).T
        gc = gyr[a + "_rot"] - ac @ K_ga.T - b_g
        W[:, j] = gc.sum(axis=0) / fs
    Wn = W / expected_deg
    K_g = np.diag(np.sqrt(np.diag(Wn @ Wn.T)))
    R_g = np.linalg.solve(K_g, Wn)
    return K_a, R_a, b_a, K_g, R_g, K_ga, b_g


def _split(M):
    d = np.diag(M)
    E = M / d[:, None]
    return d - 1.0, np.array([E[0, 1], E[0, 2], E[1, 0], E[1, 2], E[2, 0], E[2, 1]])


def imucal_estimates(lg, fs, g=9.80, trim=0.25):
    """imucal's estimates (:func:`imucal_ferraris`) on the true regions of a :func:`ferraris_session` log (the
    faces trimmed by ``trim`` s at both ends, the turns' moves, each turn's expected angle with its own sign),
    as the parameters of the accelerometer frame (``Ma = L Q``, L lower triangular; the gyros ``Mg Q^T``), and
    the accelerometer bias of Ferraris 1995 eq. 6 as ``b = sum of the six faces / 6`` (``accel_bias_sum6``)."""
    dt = np.diff(np.concatenate([[0.0], lg.time]))[:, None]
    w, f = lg.dtheta / dt, lg.dvel / dt

    def region(t0, t1):
        return (lg.time - dt[:, 0] >= t0) & (lg.time <= t1)

    acc, gyr = {}, {}
    for k, name in enumerate(("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")):
        r = region(lg.still[k][0] + trim, lg.still[k][1] - trim)
        acc[name], gyr[name] = f[r], np.degrees(w[r])
    sense = []
    for j, a in enumerate("xyz"):
        r = region(lg.still[6 + 2 * j][1], lg.still[7 + 2 * j][0])
        acc[a + "_rot"], gyr[a + "_rot"] = f[r], np.degrees(w[r])
        sense.append(1.0 if np.sum(w[r][:, j]) > 0 else -1.0)
    est = {s: imucal_ferraris(acc, gyr, fs, g, expected_deg=360.0 * s) for s in (-1.0, 1.0)}
    K_a, R_a, b_a, _, _, _, b_g = est[1.0]
    Mg = np.column_stack([(est[sense[j]][3] @ est[sense[j]][4])[:, j] for j in range(3)])
    q, r = np.linalg.qr((K_a @ R_a).T)
    s = np.sign(np.diag(r))
    L, Q = r.T * s[None, :], (q * s[None, :]).T
    ka, ea = _split(L)
    kg, eg = _split(Mg @ Q.T)
    sum6 = np.mean([np.mean(acc[k], axis=0) for k in ("x_p", "x_a", "y_p", "y_a", "z_p", "z_a")], axis=0)
    return {"accel_bias": b_a, "accel_scale_factor": ka, "accel_misalignment": ea, "gyro_bias": np.radians(b_g),
            "gyro_scale_factor": kg, "gyro_misalignment": eg, "accel_bias_sum6": sum6}


def consumer_log(rng, tremor_dps=1.0, n_poses=10, start_s=35.0, rate_hz=100.0, lpf_hz=20.0, fast_turn=True,
                 lat=0.8, g=9.80):
    """A consumer 6-axis MEMS logged by hand, written from its datasheet-level description (NumPy only):
    int16 counts of +-250 deg/s and +-2 g, turn-on gyro biases of several deg/s, scale factors and
    misalignments of about 1 %, white noise 0.005 deg/s/sqrt(Hz) and 300 ug/sqrt(Hz), a first-order
    low-pass filter at ``lpf_hz`` run at 1 kHz before the chip keeps every tenth value, a gyro bias that
    drifts linearly by 0.002 deg/s over the session (temperature), a still start of ``start_s`` s on a
    table, then poses of 2-7 s held by hand with a tremor of ``tremor_dps`` rms (a sum of three sines of
    4-11 Hz about one axis per pose, faded in and out over 0.2 s), joined by moves of 1.5-2.5 s with the
    ``s - sin(2 pi s) / 2 pi`` profile; with ``fast_turn`` the middle move lasts 0.6 s, so its rate peaks
    near 2 Theta / 0.6 s and the gyro pins at its range.  Returns a dict: ``csv`` (text: time, gx..az
    counts), ``scales`` (rad/s and m/s^2 per count), ``truth`` (canonical_truth at the mean bias),
    ``still`` [(t0, t1)] and ``pinned`` (samples at a count limit)."""
    fs = 1000.0
    poses = [np.eye(3)] + random_poses(rng, n_poses)  # the still start: body axes along E, N, U
    dur = [start_s] + list(rng.uniform(2.0, 7.0, n_poses))
    mv = rng.uniform(1.5, 2.5, n_poses)
    if fast_turn:
        mv[n_poses // 2] = 0.6
    wie = EARTH_RATE * np.array([0.0, math.cos(lat), math.sin(lat)])
    spans, t = [], 0.0
    for j in range(n_poses + 1):
        spans.append((t, t + dur[j]))
        t += dur[j] + (mv[j] if j < n_poses else 0.0)
    tt = np.arange(int(t * fs)) / fs
    Cbn = np.zeros((tt.size, 3, 3))
    wnb = np.zeros((tt.size, 3))
    for j, (a, b) in enumerate(spans):
        m = (tt >= a) & (tt < b)
        Cbn[m] = poses[j]
        if j == 0 or tremor_dps == 0:
            continue
        ax = rng.normal(size=3)
        ax /= np.linalg.norm(ax)
        fr, amp, ph = rng.uniform(4.0, 11.0, 3), rng.uniform(0.5, 1.0, 3), rng.uniform(0, 2 * np.pi, 3)
        amp *= math.radians(tremor_dps) / math.sqrt(0.5 * np.sum((2 * np.pi * fr * amp) ** 2))
        x = tt[m]
        sines = np.sin(2 * np.pi * fr[None] * x[:, None] + ph[None]) @ amp
        dsines = (np.cos(2 * np.pi * fr[None] * x[:, None] + ph[None]) * 2 * np.pi * fr[None]) @ amp
        r = min(0.2, 0.5 * (b - a))
        fade = np.clip(np.minimum(x - a, b - x) / r, 0.0, 1.0)
        win = 0.5 - 0.5 * np.cos(np.pi * fade)
        dwin = np.where((fade > 0) & (fade < 1), 0.5 * np.pi / r * np.sin(np.pi * fade) * np.where(x - a < b - x, 1, -1), 0)
        tau = win * sines
        Cbn[m] = np.einsum("ij,njk->nik", poses[j], _rot_many(ax, tau))
        wnb[m] = ax[None] * (dwin * sines + win * dsines)[:, None]
    for j in range(n_poses):
        t0, T = spans[j][1], mv[j]
        m = (tt >= t0) & (tt < t0 + T)
        R = poses[j].T @ poses[j + 1]
        ang = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1.0) / 2.0)))
        e = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * math.sin(ang))
        assert np.allclose(rot(e, ang), R, atol=1e-9), "a half turn between poses: draw again"
        s = (tt[m] - t0) / T
        Cbn[m] = np.einsum("ij,njk->nik", poses[j], _rot_many(e, ang * (s - np.sin(2 * np.pi * s) / (2 * np.pi))))
        wnb[m] = e[None] * (ang / T * (1.0 - np.cos(2 * np.pi * s)))[:, None]
    deg = math.pi / 180
    Mg = np.eye(3) + np.diag(rng.normal(0, 0.01, 3)) + (np.ones((3, 3)) - np.eye(3)) * rng.normal(0, 0.005, (3, 3))
    Ma = np.eye(3) + np.diag(rng.normal(0, 0.01, 3)) + np.tril(rng.normal(0, 0.005, (3, 3)), -1)
    bg, ba = rng.normal(0, 3 * deg, 3), rng.normal(0, 0.4, 3)
    drift = (tt / tt[-1] - 0.5)[:, None] * (rng.choice([-1.0, 1.0], 3) * 0.002 * deg)[None]  # linear, mean zero
    Cnb = np.transpose(Cbn, (0, 2, 1))
    gyro = (wnb + Cnb @ wie) @ Mg.T + bg + drift
    acc = (Cnb @ np.array([0.0, 0.0, g])) @ Ma.T + ba
    gyro += 0.005 * deg * math.sqrt(fs) * rng.normal(size=gyro.shape)
    acc += 300e-6 * 9.80665 * math.sqrt(fs) * rng.normal(size=acc.shape)
    x = np.column_stack([gyro, acc])
    alpha = 1.0 - math.exp(-2 * math.pi * lpf_hz / fs)
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, x.shape[0]):  # the chip's first-order filter (RC), at 1 kHz
        y[k] = y[k - 1] + alpha * (x[k] - y[k - 1])
    step = int(fs / rate_hz)
    y = y[step - 1::step]
    sc = np.array([250 * deg / 32768] * 3 + [2 * 9.80665 / 32768] * 3)
    c = np.rint(y / sc)
    pinned = int(np.sum(np.any((c > 32766) | (c < -32767), axis=1)))
    c = np.clip(c, -32768, 32767).astype(int)
    times = (np.arange(c.shape[0]) + 1) * step / fs
    text = "time,gx,gy,gz,ax,ay,az\n" + "".join(f"{ti:.3f}," + ",".join(map(str, row)) + "\n" for ti, row in zip(times, c))
    return {"csv": text, "scales": (sc[0], sc[3]), "truth": canonical_truth(Mg, bg, Ma, ba), "still": spans,
            "pinned": pinned, "Mg": Mg, "Ma": Ma, "lat": lat, "g": g}
