"""Inputs of the Cramér-Rao bound beyond white noise: the bias noise of the sensors (random walk or
Gauss-Markov) and the extra measurement rows a state set brings (the encoder attitude rows of the
unified gimbal model, N25 eq. 5-8)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from inscal.calibrate.systematic.dynamics import gimbal_attitude
from inscal.calibrate.systematic.states import ENCODER_SIGMA, K_GIM, N_NAV, StateSet
from inscal.core import units


@dataclass(frozen=True)
class BiasNoise:
    """Bias instability as process noise on the bias states (SI, per axis).

    ``*_rw``: rate random walk PSD root [rad/s/sqrt(s)], [m/s^2/sqrt(s)]; ``*_gm``: first-order
    Gauss-Markov sigma [rad/s], [m/s^2] with correlation time ``*_tau`` [s]."""

    gyro_rw: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_rw: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_gm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_tau: float = 3600.0
    accel_gm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_tau: float = 3600.0

    def __post_init__(self):
        for n in ("gyro_rw", "accel_rw", "gyro_gm", "accel_gm"):
            a = np.broadcast_to(np.asarray(getattr(self, n), float), (3,)).copy()
            if not np.all(np.isfinite(a)) or np.any(a < 0):
                raise BoundError(f"bias noise {n} must be >= 0, got {getattr(self, n)}")
            object.__setattr__(self, n, a)
        for n in ("gyro_tau", "accel_tau"):
            v = float(getattr(self, n))
            if not (math.isfinite(v) and v > 0):
                raise BoundError(f"bias noise {n} must be > 0 s, got {v}")
            object.__setattr__(self, n, v)

    @property
    def active(self) -> bool:
        """Whether any bias random walk or Gauss-Markov term is non-zero."""
        return bool(np.any(self.gyro_rw) or np.any(self.accel_rw) or np.any(self.gyro_gm) or np.any(self.accel_gm))

    @classmethod
    def from_imu_noise(cls, noise) -> "BiasNoise":
        """The Gauss-Markov bias instability of an :class:`inscal.core.error_model.ImuNoise` (the simulator's model)."""
        return cls(gyro_gm=noise.gyro_bias_instability, gyro_tau=noise.gyro_bias_tau,
                   accel_gm=noise.accel_bias_instability, accel_tau=noise.accel_bias_tau)

    def to_dict(self) -> dict:
        """The bias noise as JSON, in field units."""
        return {"gyro_rw_deg_h_sqrt_h": (units.from_si(self.gyro_rw, "deg/h") * math.sqrt(3600.0)).tolist(),
                "accel_rw_ug_sqrt_s": units.from_si(self.accel_rw, "ug").tolist(),
                "gyro_gm_deg_h": units.from_si(self.gyro_gm, "deg/h").tolist(), "gyro_tau_s": self.gyro_tau,
                "accel_gm_ug": units.from_si(self.accel_gm, "ug").tolist(), "accel_tau_s": self.accel_tau}


_ROW_BUILDERS: list[tuple[Callable, Callable]] = []


def register_rows(applies: Callable[[StateSet], bool], builder: Callable) -> None:
    """Plug in a state set's extra measurement rows.  ``builder(states, scenario, t, options)`` gets
    the :class:`StateSet`, the :class:`~inscal.sim.simulate.Scenario`, the update times ``t`` (M,) [s]
    (the end of each filter step) and the setup's ``row_options`` dict, and returns ``(H, r)``:
    rows ``H`` (M, m, n_states) on the physical error state (navigation first, then the parameters
    in ``states.groups`` order) and their noise variances ``r`` (M, m), independent rows (whiten
    correlated ones first).  Used for every state set where ``applies(states)``."""
    _ROW_BUILDERS.append((applies, builder))


def encoder_rows(st: StateSet, sc, t: np.ndarray, options: dict):
    """The unified model's encoder attitude rows (:mod:`inscal.calibrate.unified`, the systematic
    filter's ``gimbal`` option): ``z = vee(C_nav C_pred^T) ~ phi - psi(d dth, d alpha0, d beta0,
    d gamma0)`` with ``R = s^2 (a a^T + c c^T) + (s/10)^2 I`` at the path's encoder angles at the end
    of each step, linearised at the scenario's gimbal geometry (:func:`~inscal.calibrate.systematic._gimbal_attitude`);
    whitened by the Cholesky factor of ``R`` (three independent unit-variance rows).
    ``options["encoder_sigma"]``: encoder white noise [rad] (default the filter's 1")."""

    s = float(options.get("encoder_sigma") or ENCODER_SIGMA)
    th, _, _ = sc.path.segments().angles(t)
    gim = np.concatenate([[sc.gimbal.nonorthogonality], np.asarray(sc.gimbal.mount_attitude, float)])
    kinds, _, js = st.columns()
    cols = [(N_NAV + c, int(js[c])) for c in range(kinds.size) if kinds[c] == K_GIM]
    M = t.size
    # a, c, Hg and R depend on the outer angle only (not on the inner one): one evaluation per distinct angle
    tx_u, inv = np.unique(th[:, 0], return_inverse=True)
    Hu = np.zeros((tx_u.size, 3, st.n_states))
    Cp, a, c3, Hg = np.empty((3, 3)), np.empty(3), np.empty(3), np.empty((3, 4))
    for k, tx in enumerate(tx_u):
        gimbal_attitude(gim, float(tx), 0.0, Cp, a, c3, Hg)
        R = s * s * (np.outer(a, a) + np.outer(c3, c3)) + 0.01 * s * s * np.eye(3)
        Li = np.linalg.inv(np.linalg.cholesky(R))
        Hk = np.zeros((3, st.n_states))
        Hk[:, 0:3] = np.eye(3)
        for col, j in cols:
            Hk[:, col] = -Hg[:, j]
        Hu[k] = Li @ Hk
    H = Hu[inv.ravel()]
    return H, np.ones((M, 3))


def extra_rows(st: StateSet, sc, t: np.ndarray, sig: np.ndarray, options: dict | None = None):
    """The measurement rows (H of shape (steps, rows, states), their noise) that the state set ``st``
    adds to the zero-velocity and position updates (e.g. the encoder rows of the gimbal states),
    from the registered row builders; none: empty arrays.
    """
    Hs, rs = [], []
    for applies, builder in _ROW_BUILDERS:
        if applies(st):
            H, r = builder(st, sc, t, options or {})
            H = np.asarray(H, float)
            r = np.asarray(r, float)
            if H.ndim != 3 or H.shape[0] != t.size or H.shape[2] != st.n_states or r.shape != H.shape[:2]:
                raise BoundError(f"extra measurement rows: expected H ({t.size}, m, {st.n_states}) and r "
                                 f"({t.size}, m), got {H.shape} and {r.shape}")
            Hs.append(H)
            rs.append(r)
    if not Hs:
        return np.zeros((t.size, 0, sig.size)), np.ones((t.size, 0))
    H = np.concatenate(Hs, axis=1)
    r = np.concatenate(rs, axis=1)
    return H, r

register_rows(lambda st: bool(getattr(st, "gimbal", False)), encoder_rows)


class BoundError(ValueError):
    """A path, state set or noise model the bound cannot use."""
