"""The unified estimator: S16's systematic filter with N25's gimbal states.

One closed-loop error-state Kalman filter and smoother (:mod:`inscal.calibrate.systematic`) over
the whole turntable record estimates, at once, the 51 S16 states (navigation errors, linear IMU
errors, g-sensitivity, accelerometer nonlinearity, cross-coupling, lever arms) and the gimbal
errors of N25: the non-orthogonality ``dth`` of the two gimbal axes and the mount (carrier)
attitude ``[alpha0, beta0, gamma0]`` (N25 eq. 5-8).  The state set is ``StateSet.parse("unified")``
= ``"51,gimbal"`` (58 states; ``"30,gimbal"``, ``"51,lever9,gimbal"``, ... work too).

Measurements, every filter step ``T`` (1 s by default):

* zero velocity and the known position (S16 eq. 25-26), as in ``systematic51``;
* the encoder angles as an attitude observation: the navigated attitude of the IMU against the
  one the gimbal model predicts from the encoder angles, the mount attitude and ``dth``
  (N25 eq. 5-8, 34-36)::

      C_pred = C_b^n(alpha0, beta0, gamma0) Rot(u, theta_x) R_z(theta_z),   u = [cos dth, 0, sin dth]
      z = vee(C_nav C_pred^T) ~ phi - psi(d dth, d alpha0, d beta0, d gamma0)       (3 rows, n-frame)

  ``H`` has ``I`` on the attitude error ``phi`` and ``-d psi / d(gimbal)`` on the four gimbal
  states (:func:`measurement`; exact expressions in the docstring of the systematic module,
  tested against finite differences of this nonlinear ``z`` in ``tests/calibrate/test_unified.py``).  Noise:
  each encoder angle white with sigma ``encoder_sigma`` (default 1", ``--encoder-sigma``), i.e.
  ``R = s^2 (a a^T + c c^T)`` along the outer axis ``a`` and the inner axis ``c`` (n-frame), plus an
  isotropic floor ``(s / 10)^2``.

Frames (the choice).  ``systematic51`` refers the IMU errors to S16's gyro-defined m-frame (gyro
matrix lower-triangular): the velocity data cannot see a rotation of the whole IMU, so the gyro
triad defines the frame.  The encoder rows do see it: the navigated attitude is that of the IMU
frame, the predicted one that of N25's s-frame (z = the inner axis, x = the outer axis's
projection at zero angles, the encoders' zero).  Keeping the m-frame would need three more states
for the rotation ``C_s^m`` in ``H``; instead the unified filter works in the s-frame itself, the
canonical frame of :mod:`inscal.core.error_model`, with a *full* gyro matrix (9 states instead of 6: the
same three degrees of freedom).  Its misalignments are then N25's six installation angles per
triad referred to the gimbal frame, directly comparable with ``n25`` and with the simulator's truth,
and no frame conversion is needed.  The quadratic terms (``K_a2``, ``K_cross``) and lever arms are
per-axis quantities of the s-frame triad (exact for the simulator, which applies them there).

Comparison (``bench/unified_table.py``): ``systematic51`` on the same record does not estimate
``dth`` or the mount attitude (it uses no gimbal angles); ``n25`` on the N25 path estimates
``dth`` but ignores the extended S16 terms, which then bias its linear estimates.
"""

from __future__ import annotations

import numpy as np

from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.systematic.driver import systematic
from inscal.calibrate.systematic.dynamics import gimbal_attitude
from inscal.calibrate.systematic.selection import select_states, with_auto
from inscal.calibrate.systematic.states import ENCODER_SIGMA, StateSet

__all__ = ["unified", "predicted_attitude", "measurement", "residual", "ENCODER_SIGMA", "STATES"]

#: the state set of the unified method
STATES = "unified"


def unified(ws_or_record, **kw) -> CalibrationResult:
    """The unified estimator: S16's systematic filter with N25's gimbal states (module docstring).

    :func:`~inscal.calibrate.systematic.systematic` with the ``unified`` state set (58 states: the
    51 of S16 and the gimbal non-orthogonality and mount attitude, observed through the encoder
    angles).

    Parameters
    ----------
    ws_or_record : Record
        The turntable record (with its gimbal angles).
    **kw
        ``states`` (more states, e.g. ``"lever9"``; ``"auto"`` selects them), ``encoder_sigma``
        [rad], ``encoder_every`` and the other options of
        :func:`~inscal.calibrate.systematic.systematic` (``max_passes``, ``filter_rate_hz``, ...).

    Returns
    -------
    CalibrationResult
        The estimates (SI) in the gimbal-defined frame, their 1 sigma and the filter's history.

    Examples
    --------
    One pass of the filter, a step every 5 s, over the S16 path at 10 Hz (a real calibration
    iterates, a step a second):

    >>> import numpy as np
    >>> from inscal.calibrate import unified
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("s16", np.random.default_rng(0), rate_hz=10.0)
    >>> res = unified(rec, max_passes=1, filter_rate_hz=0.2)
    >>> res.method, "gimbal_nonorthogonality" in res.estimated, len(res.estimated) > 10
    ('unified', True, True)
    """
    extra, auto = with_auto(kw.pop("states", None), "")
    spec = STATES + ("," + extra if extra else "")
    if auto:
        return select_states(ws_or_record, spec, method_name="unified", **kw)
    return systematic(ws_or_record, spec, method_name="unified", **kw)


def predicted_attitude(gimbal, theta_x: float, theta_z: float) -> np.ndarray:
    """``C_s^n`` the gimbal model predicts (N25 eq. 5-8): ``gimbal = [dth, alpha0, beta0, gamma0]`` [rad]."""
    C, a, c, Hg = np.empty((3, 3)), np.empty(3), np.empty(3), np.empty((3, 4))
    gimbal_attitude(np.asarray(gimbal, float), float(theta_x), float(theta_z), C, a, c, Hg)
    return C


def residual(C_nav, gimbal, theta_x: float, theta_z: float) -> np.ndarray:
    """The encoder attitude measurement ``z = vee(C_nav C_pred^T)`` [rad] (n-frame), nonlinear."""
    E = np.asarray(C_nav, float) @ predicted_attitude(gimbal, theta_x, theta_z).T
    return 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])


def measurement(gimbal, theta_x: float, theta_z: float, encoder_sigma: float = ENCODER_SIGMA):
    """``(H_phi, H_gimbal, R)`` of the encoder attitude rows (as the kernel builds them, physical
    units): ``z ~ H_phi phi + H_gimbal d[dth, alpha0, beta0, gamma0]`` with ``H_phi = I`` and
    ``R = s^2 (a a^T + c c^T) + (s/10)^2 I``."""
    C, a, c, Hg = np.empty((3, 3)), np.empty(3), np.empty(3), np.empty((3, 4))
    gimbal_attitude(np.asarray(gimbal, float), float(theta_x), float(theta_z), C, a, c, Hg)
    s2 = float(encoder_sigma) ** 2
    R = s2 * (np.outer(a, a) + np.outer(c, c)) + 0.01 * s2 * np.eye(3)
    return np.eye(3), -Hg, R


def state_set(extra: str | None = None) -> StateSet:
    """``StateSet.parse("unified" + extra)``."""
    return StateSet.parse(STATES + ("," + extra if extra else ""))
