"""Hand-held sessions without a turntable: random still poses joined by smooth rotations of a few
seconds with a human tremor (the motion of a multi-position or Ferraris calibration, Tedaldi 2014).

Motion.  Pose j has the attitude ``C_j = C_b^n`` (uniformly random, from the motion's own ``seed``); the
move from pose j to j+1 turns the body about the fixed body axis ``e_j`` through the angle ``Theta_j`` of
``C_j^T C_{j+1}`` with the minimum-jerk profile ``theta = Theta (10 s^3 - 15 s^4 + 6 s^5)``, ``s = (t - t_j) / T``
(Flash & Hogan 1985: zero rate and acceleration at both ends), and a tremor about a second body axis
``k_j``, ``tau = A sin^2(pi s) sin(2 pi f t)``::

    C_b^n(t) = C_j Rot(e_j, theta) Rot(k_j, tau)
    w_nb^b   = Rot(k_j, -tau) e_j theta' + k_j tau'
    w_ib^b   = w_nb^b + C_n^b w_ie^n,      f^b = C_n^b (0, 0, g)      (n: East-North-Up, at rest on the Earth)

Increments.  ``int w_ib`` and ``int f`` (and ``int f^(2)``, ``int f^(x)`` for the accelerometer nonlinearity and
cross-coupling) over each sample interval by 4-point Gauss-Legendre on every piece between the move
breakpoints, then the error model of :meth:`inscal.core.error_model.ImuErrors.measure_increments` and
the noise of :class:`inscal.sim.simulate.NoiseState` (the same as for a turntable record).  The size
effect and the time asynchrony need the rates' products and are refused here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.core.attitude import axis_angle_dcm_array
from inscal.core.earth import Site

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class HandheldMotion:
    """A hand-held session: ``poses`` still poses of ``still_s`` s, moves of ``move_s`` s, tremor of
    ``tremor_deg`` at ``tremor_hz``; the poses and axes are drawn from ``seed`` (the motion is part of the
    scenario, not of its noise)."""

    poses: int = 12
    still_s: float = 4.0
    move_s: float = 3.0
    tremor_deg: float = 0.3
    tremor_hz: float = 8.0
    seed: int = 0

    def __post_init__(self):
        if self.poses < 2 or self.still_s <= 0 or self.move_s <= 0 or self.tremor_deg < 0 or self.tremor_hz <= 0:
            raise ValueError(f"hand-held motion: poses >= 2, still_s > 0, move_s > 0, tremor_deg >= 0, tremor_hz > 0; "
                             f"got {self}")

    @property
    def duration(self) -> float:
        """The session's length [s]: every still pose and the moves between them."""
        return self.poses * self.still_s + (self.poses - 1) * self.move_s

    def attitudes(self) -> list[np.ndarray]:
        """``C_b^n`` of every pose (uniform random rotations: normalised 4-D normal draws)."""
        rng = np.random.default_rng(self.seed)
        out = []
        for _ in range(self.poses):
            q = rng.normal(size=4)
            w, x, y, z = q / np.linalg.norm(q)
            out.append(np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                                 [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                                 [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]))
        return out

    def moves(self) -> list[tuple[float, np.ndarray, np.ndarray, float, np.ndarray]]:
        """(start time, C_j, axis e_j, angle Theta_j, tremor axis k_j) of every move."""
        rng = np.random.default_rng([self.seed, 1])
        att = self.attitudes()
        out = []
        for j in range(self.poses - 1):
            R = att[j].T @ att[j + 1]
            v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
            ang = math.atan2(0.5 * np.linalg.norm(v), 0.5 * (np.trace(R) - 1.0))
            e = v / np.linalg.norm(v) if np.linalg.norm(v) > 0 else np.array([0.0, 0.0, 1.0])
            if ang > math.pi - 1e-6:  # a half turn: the axis from the symmetric part
                e = np.sqrt(np.maximum(np.diag(R) + 1.0, 0.0) / 2.0)
            k = rng.normal(size=3)
            out.append(((j + 1) * self.still_s + j * self.move_s, att[j], e, ang, k / np.linalg.norm(k)))
        return out

    def still_intervals(self) -> list[tuple[float, float]]:
        """``(start, end)`` [s] of every still pose, in time order (the body is at rest on the Earth there:
        the tremor only rides on the moves)."""
        return [(j * (self.still_s + self.move_s), j * (self.still_s + self.move_s) + self.still_s)
                for j in range(self.poses)]

    def kinematics(self, t: np.ndarray, site: Site) -> tuple[np.ndarray, np.ndarray]:
        """True ``w_ib^b`` and ``f^b`` (n, 3) at times ``t`` (module docstring)."""
        t = np.asarray(t, float)
        att = self.attitudes()
        C = np.repeat(att[0][None], t.size, axis=0)
        wnb = np.zeros((t.size, 3))
        A = math.radians(self.tremor_deg)
        om = 2.0 * math.pi * self.tremor_hz
        T = self.move_s
        for t0, Cj, e, Th, k in self.moves():
            after = t >= t0
            s = np.clip((t[after] - t0) / T, 0.0, 1.0)
            th = Th * s**3 * (10.0 - 15.0 * s + 6.0 * s * s)
            thd = Th / T * 30.0 * s * s * (1.0 - s) ** 2
            win = np.sin(math.pi * s) ** 2
            tau = A * win * np.sin(om * t[after])
            taud = A * (math.pi / T * np.sin(2 * math.pi * s) * np.sin(om * t[after]) + win * om * np.cos(om * t[after]))
            C[after] = Cj @ axis_angle_dcm_array(e, th) @ axis_angle_dcm_array(k, tau)
            back = axis_angle_dcm_array(k, -tau)
            wnb[after] = np.einsum("nij,j->ni", back, e) * thd[:, None] + k[None] * taud[:, None]
        Cnb = np.transpose(C, (0, 2, 1))
        w = wnb + Cnb @ np.asarray(site.earth_rate_n, float)
        f = Cnb @ np.array([0.0, 0.0, float(site.gravity)])
        return w, f


def true_increments(motion: HandheldMotion, site: Site, rate_hz: float, quadratic: bool = False):
    """Time (end of each interval), ``int w_ib``, ``int f`` and (``quadratic``) ``int f^(2)``, ``int f^(x)``
    over the intervals ``[k/rate, (k+1)/rate]`` (module docstring)."""
    n = int(math.floor(motion.duration * rate_hz + 1e-9))
    edges = np.arange(n + 1) / rate_hz
    bps = sorted({t0 for t0, *_ in motion.moves()} | {t0 + motion.move_s for t0, *_ in motion.moves()})
    allp = np.union1d(edges, [b for b in bps if 0.0 < b < edges[-1]])
    owner = np.searchsorted(edges, allp[:-1], side="right") - 1
    a, b = allp[:-1], allp[1:]
    tn = (0.5 * (a + b))[:, None] + 0.5 * (b - a)[:, None] * _GL_X[None]
    wq = (0.5 * (b - a))[:, None] * _GL_W[None]
    w, f = motion.kinematics(tn.ravel(), site)

    def integrate(x):
        piece = np.einsum("pq,pqi->pi", wq, x.reshape(-1, _GL_X.size, x.shape[1]))
        out = np.zeros((n, x.shape[1]))
        np.add.at(out, owner, piece)
        return out

    dth, dv = integrate(w), integrate(f)
    if not quadratic:
        return edges[1:], dth, dv, None, None
    f2 = integrate(f * f)
    fx = integrate(np.column_stack([f[:, 0] * f[:, 1], f[:, 0] * f[:, 2], f[:, 1] * f[:, 2]]))
    return edges[1:], dth, dv, f2, fx


# ------------------------------------------------------------------------------- Ferraris sessions
def tilted_face(axis: int, sign: float, heading: float, tilt: np.ndarray) -> np.ndarray:
    """``C_b^n`` of the body resting on a face: body axis ``axis`` up (``sign`` +-1), its vertical
    ``sign e_axis + t_1 e_(axis+1) + t_2 e_(axis+2)`` normalised (``tilt`` = (t_1, t_2): the tangents of the
    small tilt angles towards the body axes ``axis + 1``, ``axis + 2`` mod 3), at ``heading`` [rad] about the
    vertical."""
    up = np.zeros(3)
    up[axis] = sign
    up[(axis + 1) % 3] += tilt[0]
    up[(axis + 2) % 3] += tilt[1]
    up /= np.linalg.norm(up)
    ref = np.eye(3)[(axis + 1) % 3]
    e = ref - up * (ref @ up)
    e /= np.linalg.norm(e)
    Cbn = np.vstack([e, np.cross(up, e), up])  # rows: the n-frame axes in the body, before the heading
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ Cbn


@dataclass(frozen=True)
class FerrarisMotion(HandheldMotion):
    """A Ferraris session (Ferraris 1995; laid out like imucal's example): the faces ``+x, -x, +y, -y, +z, -z``
    up for ``face_s`` s each (uniform in the range), then for x, y, z a pose on the + face for ``end_s`` s,
    one whole turn (360 deg, either sense, plus a closure error: normal, sigma ``turn_closure_deg``, a turn
    by hand against a stop) about the vertical and the pose it ends in for ``end_s`` s; the moves last
    ``move_s`` s.  Every placement on a face has its own heading (uniform) and its own tilt: two
    angles, each normal with the sigma ``face_tilt_deg / sqrt(2)`` (``face_tilt_deg`` the rms angle between
    the face and the horizontal); a turn is about the tilted vertical, so it ends on the face it started on.  All drawn
    from ``seed``; ``tremor_deg``/``tremor_hz`` ride on the moves (:class:`HandheldMotion`)."""

    face_s: tuple[float, float] = (4.0, 7.0)
    end_s: tuple[float, float] = (1.0, 1.5)
    face_tilt_deg: float = 0.3
    turn_closure_deg: float = 0.2
    tremor_deg: float = 0.0

    def __post_init__(self):
        if not (0 < self.face_s[0] <= self.face_s[1] and 0 < self.end_s[0] <= self.end_s[1] and self.move_s > 0
                and 0 <= self.face_tilt_deg < 10 and 0 <= self.turn_closure_deg < 10 and self.tremor_deg >= 0
                and self.tremor_hz > 0):
            raise ValueError(f"Ferraris motion: 0 < face_s[0] <= face_s[1], 0 < end_s[0] <= end_s[1], move_s > 0, "
                             f"0 <= face_tilt_deg, turn_closure_deg < 10, tremor_deg >= 0, tremor_hz > 0; got {self}")

    def _layout(self):
        """(C_b^n, still duration, tilt (2,)) of the 12 poses, and the turns {move index: angle}."""
        rng = np.random.default_rng([self.seed, 2])
        sc = math.radians(self.face_tilt_deg) / math.sqrt(2.0)
        out, turns = [], {}
        for k in range(6):
            t = rng.normal(0.0, sc, 2)
            out.append((tilted_face(k // 2, 1.0 if k % 2 == 0 else -1.0, rng.uniform(0, 2 * math.pi), t),
                        rng.uniform(*self.face_s), t))
        for j in range(3):
            t = rng.normal(0.0, sc, 2)
            C = tilted_face(j, 1.0, rng.uniform(0, 2 * math.pi), t)
            ang = float(rng.choice([-1.0, 1.0])) * (2.0 * math.pi + rng.normal(0.0, math.radians(self.turn_closure_deg)))
            turns[len(out)] = ang
            turned = C @ axis_angle_dcm_array(C[2], [ang])[0]
            out += [(C, rng.uniform(*self.end_s), t), (turned, rng.uniform(*self.end_s), t)]
        return out, turns

    @property
    def duration(self) -> float:
        """The session's length [s]."""
        lay, _ = self._layout()
        return sum(d for _, d, _ in lay) + (len(lay) - 1) * self.move_s

    def attitudes(self) -> list[np.ndarray]:
        """``C_b^n`` of every pose, in time order."""
        return [C for C, _, _ in self._layout()[0]]

    def tilts(self) -> np.ndarray:
        """The tilt of every pose (12, 2): the tangents of the angles (:func:`tilted_face`); the tilt angle is
        ``atan(hypot(t))``."""
        return np.array([t for _, _, t in self._layout()[0]])

    def still_intervals(self) -> list[tuple[float, float]]:
        """``(start, end)`` [s] of every still pose, in time order."""
        out, t = [], 0.0
        for _, d, _ in self._layout()[0]:
            out.append((t, t + d))
            t += d + self.move_s
        return out

    def moves(self) -> list[tuple[float, np.ndarray, np.ndarray, float, np.ndarray]]:
        """(start time, C_j, axis e_j, angle Theta_j, tremor axis k_j) of every move: the shortest rotation
        between two faces, or a whole turn about the pose's vertical."""
        lay, turns = self._layout()
        rng = np.random.default_rng([self.seed, 3])
        out = []
        for j, (t0, _) in enumerate(self.still_intervals()[:-1]):
            C0, d0, _ = lay[j]
            if j in turns:
                e, ang = C0[2].copy(), turns[j]  # the vertical in the body: the third row of C_b^n
            else:
                R = C0.T @ lay[j + 1][0]
                v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
                ang = math.atan2(0.5 * np.linalg.norm(v), 0.5 * (np.trace(R) - 1.0))
                e = v / max(float(np.linalg.norm(v)), 1e-300)
                if ang > math.pi - 1e-6:  # a half turn (from a face to its opposite): R + I = 2 e e^T
                    S = R + np.eye(3)
                    c = S[:, int(np.argmax(np.diag(S)))]
                    e = c / np.linalg.norm(c)
            k = rng.normal(size=3)
            out.append((t0 + d0, C0, e, ang, k / np.linalg.norm(k)))
        return out
