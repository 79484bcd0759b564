"""Systematic calibration (S16 section 3): a closed-loop error-state Kalman filter with RTS
smoother on the navigation errors of a static-site turntable record.

Formulation
-----------
Frames: n = local ENU at the (fixed, known) site; m = the IMU frame the calibration
defines, the gyro-defined frame of S16 section 2.1 (gyro matrix lower-triangular), or
with ``psins`` the accelerometer-defined frame (accelerometer matrix lower-triangular,
gyro matrix full).  No gimbal angles are used: the base is static, so the record may
come from any path, with or without encoders.

Compensation (the S16 form, eq. 3, 6-8, 12; rates = increments / dt)::

    u_g = A_g dtheta/dt,   u_a = A_a dv/dt
    f0  = u_a - b_a  (+ tau (f0_k - f0_{k-1}) / dt       time asynchrony, when estimated)
    f~  = f0 - K2 f~^(2) - Kx f~^(x) - a_size(w~, w~-dot)           (fixed point, eq. 7-8)
    w~  = u_g - b_g - G f~

``a_size`` is the size effect of :func:`inscal.core.error_model.size_effect`: with S16's diagonal
lever arm ``a_size_i = -(|w|^2 - w_i^2) r_i`` (S16 eq. 9-11, the physics).  **S16 eq. 12 and
block F29 as printed have the opposite sign; inscal keeps eq. 9, so inscal's r is the
position of each accelerometer (S16's printed convention would report -r).**

Error states (estimate minus truth).  Navigation (n = 9): attitude ``phi`` with
``C_est = (I + [phi x]) C_true`` (n-frame), velocity ``dv`` (ENU), position ``dp`` (ENU
metres).  Parameters: ``A_g,true = (I - dKG) A_g``, ``A_a,true = (I - dKA) A_a`` (dKG lower
triangular in the S16 set, eq. 20), every other parameter additive (``b_true = b - db``).
Then, to first order (S16 eq. 18-19 in this sign convention)::

    dw = dKG u_g - db_g - dG f~                                            # S16 eq. 18
    df = dKA u_a - db_a - dK2 f~^(2) - dKx f~^(x) + (d a_size / d r) dr + dtau f-dot  # eq. 19

and the error dynamics on the static base (S16 eq. 17, ENU, v = 0)::

    phi' = phi x w_ie^n - dw_ie(dL) - dw_en(dv) + C_m^n dw
    dv'  = phi x f^n + C_m^n df - 2 w_ie^n x dv + dg(dh)
    dp'  = dv

The parameter rows of F are zero (eq. 21).  F-blocks are checked against finite
differences of the nonlinear error propagation in ``tests/calibrate/test_systematic.py``.

Discretisation.  The navigation runs at the IMU rate (compiled kernel, two-sample coning
and sculling); the filter steps every ``T`` (default 1 s).  Over one step ``F_nn`` is constant
on a static base (``f^n`` = the step's mean of ``C f~``), while ``F_np(t)`` follows the rotation
sample by sample, so::

    Phi_nn = I + F T + F^2 T^2/2 + F^3 T^3/6
    Phi_np = sum_k e^{F (T - t_k)} F_np(t_k) dt = M0 + F M1 + F^2 M2,  M_i = sum_k (T - t_k)^i / i! F_np(t_k) dt

(``M_i`` over the step's samples: :mod:`inscal.calibrate.systematic.jacobian`), and
``Q_d = int_0^T Phi(s) Q_c Phi(s)^T ds`` of the white gyro
and accelerometer noise by 3-point Gauss-Legendre quadrature (positive weights: PSD by
construction, which the square-root prediction's Cholesky needs).  Measurements at each step: zero velocity and the
known position (S16 eq. 25-26 plus the fixed-position observation).

Feedback and smoothing.  After every update the whole estimate is fed back (S16 eq. 27):
the attitude, velocity and position of the navigator and every parameter of the
compensation, so the filter's state is zero between updates.  The smoother
(:mod:`inscal.core.kalman`, the RTS smoother of S16 eq. 13-16 in modified Bryson-Frazier form)
returns the smoothed error of the *pre-update reference* at each stored step; adding it to the
reference kept at that step gives the smoothed estimate, consistent with the feedback.  The
parameters are constants (zero process noise), so their smoothed estimate and covariance at
every step equal the final filtered ones: the result and the smoothed history use that
identity, and the recursion supplies the smoothed navigation states (the initial attitude
of the next pass).  The smoothed covariances come from a square-root information filter run backwards and
the two-filter form (:func:`inscal.core.kalman.sr_smoothed`, :mod:`~inscal.calibrate.systematic.smoother`):
positive definite at every stored step, where the MBF ``Pm - Pm Lam Pm`` cancels catastrophically when
zero-velocity updates are ~1e8 times more informative than the prior; their constants' block is that identity.

Robust scheme (:mod:`~inscal.calibrate.systematic.model_error`).  The first passes run with bounded influence
as a velocity jump (a step whose NIS passes a cap has its accelerometer noise raised until it meets it); then a
velocity model-error term (a factor on the accelerometer noise per motion state, held to the dwells' own noise
level) and frozen outlier weights on R are estimated from the innovations and frozen, so the remaining passes are
a Gauss-Newton iteration of one weighted problem.  A run that does not converge, an estimate beyond 5 prior sigma
or a position innovation beyond 10 m ends with :class:`~inscal.calibrate.systematic.driver.NotConverged` unless
``accept_unconverged`` (the exception's ``result`` is the last iterate that option keeps, from the same run).  The
site latitude and the time scale the sigma assume are stated
(:mod:`~inscal.calibrate.systematic.sensitivity`).

Sample-to-sample terms.  The time asynchrony and the size effect's w-dot use centred
differences of the neighbouring samples (one sample of look-ahead), as
:meth:`inscal.core.error_model.ImuErrors.compensate` and the navigator do.

Passes.  Pass 1 linearises around the nominal parameters (prior mean); each later pass
re-runs the record with the compensation of the previous result and the smoothed initial
attitude (an iterated, Gauss-Newton smoother).  Each pass runs with a prior centred on its own
start; after pass 1 its widths are deflated to at most ``DEFLATE`` (30) previous posterior
sigmas.  The exact linear-Gaussian change of prior then restores the real one, centred on the
nominal parameters: with the pass's data information ``L_d = P_f^-1 - P_pass^-1``,
``P = (L_d + P_0^-1)^-1`` and ``x = P (P_f^-1 x_pass + P_0^-1 mu)``.  The deflation is
numerical: with the full prior the covariance spans ~1e10 and, on a quiet IMU (VRW 0.5 ug/sqrt(Hz)),
round-off made the 51-state filter inconsistent (NEES 240 on 42 parameters; 39 with deflation).  Passes stop when no parameter moved by more than ``tol`` of its sigma (default 0.2:
the iteration converges about quadratically, 24 -> 0.14 -> 0.001 sigma on the s16 record).

Gimbal states and encoder observations (state option ``gimbal``; ``unified`` = ``51,gimbal``; the
``unified`` method of :mod:`inscal.calibrate.unified`).  With the record's encoder angles the filter
also estimates the gimbal non-orthogonality ``dth`` and the mount (base) attitude ``[alpha0, beta0,
gamma0]`` of N25 eq. 5-8 (errors estimate minus truth, additive; ``K_GIM`` columns, zero in
``Phi_np``: they do not enter the navigation error dynamics).  The IMU frame is then N25's s-frame
(z = the inner axis, x = the outer axis's projection at zero angles, i.e. the encoders' zero; the
canonical frame of :mod:`inscal.core.error_model`), not the gyro-defined m-frame: the gimbal, not the gyro
triad, fixes the frame, so the gyro matrix is full (9) like the accelerometer's (18 matrix states
= 6 scale factors + the 12 installation angles of N25 eq. 1-4; without encoders the three extra
states would be a frame rotation the velocity data cannot see).  At every ``encoder_every``-th
filter step the navigated attitude ``C_nav`` (of the s-frame) is compared with the gimbal model's::

    C_pred = C_b^n(alpha0, beta0, gamma0) Rot(u, theta_x) R_z(theta_z),  u = [cos dth, 0, sin dth]  # N25 eq. 5-8, 34
    z = vee(C_nav C_pred^T) ~ phi - psi      (3 rows, n-frame; vee(I + [a x]) = a)                  # N25 eq. 35-36
    psi = e_z dgamma0 + R_z(g0) e_y dbeta0 + R_z(g0) R_y(b0) e_x dalpha0 + C_b^n (sin tx du + (1 - cos tx) u x du) ddth
    R = s_enc^2 (a a^T + c c^T) + (s_enc / 10)^2 I,   a = C_b^n u,  c = C_b^n Rot(u, tx) e_z

``psi`` is the n-frame rotation of ``C_pred`` for an error of the gimbal parameters (``du = du/d dth``;
the ``dth`` term is the left Jacobian of a rotation about a tilting axis: with ``dth = 0`` it is
``C_b^n ddth [0, -(1 - cos tx), sin tx]``: the derivative of ``Rot(u(dth), tx)`` with
``u = [cos dth, 0, sin dth]``, checked against finite differences in the tests).  White encoder noise (``s_enc`` per
angle) turns ``C_pred`` about the outer axis ``a`` and the inner axis ``c`` only; the isotropic tenth
is a floor for the third direction (unmodelled wobble; it keeps ``S`` well conditioned).  The
encoder sample at the end of each filter step (``gimbal[(k+1) n_per - 1]``, the time of the
navigation) is used; a record without encoders but with its path uses the path's angles.  The
attitude rows are a second, sequential update at the same step (innovation ``z - H x_v`` after the
velocity/position update's ``x_v``, one feedback of the sum), stored beside the first (``K``,
``S^-1``, ``S^-1 nu`` and the dense ``H``) so the MBF smoother runs both backwards, the attitude
rows first: exact, as one 9-row update would be.  The velocity/position innovations keep their own
NIS (dof 6 per step: the fit); the encoder rows' are in ``diagnostics["encoder"]`` with their
expectation ``3 - floor tr(S^-1)`` (between 2 and 3: the floor direction carries no encoder noise).
"""

from inscal.calibrate.systematic.driver import (
           estimate_white_noise,
           systematic,
)
from inscal.calibrate.systematic.methods import systematic30, systematic51
from inscal.calibrate.systematic.selection import select_states
from inscal.calibrate.systematic.params import (
           CompParams,
           frame_rotation,
           truth_in_frame,
)
from inscal.calibrate.systematic.states import STATE_OPTIONS, StateSet

__all__ = ["systematic", "systematic51", "systematic30", "select_states", "estimate_white_noise", "StateSet", "STATE_OPTIONS",
           "CompParams", "frame_rotation", "truth_in_frame"]
