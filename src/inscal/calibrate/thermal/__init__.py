"""Thermal-chamber calibration from temperature plateaus (method ``thermal-plateaus``).

The lab procedure every navigation-grade IMU goes through (beyond both papers, which calibrate at one
temperature): the chamber steps through plateaus, the turntable runs the same calibration path at each
one, and the thermal model (:mod:`inscal.core.thermal`) is fitted to the per-plateau results.

1. **Plateaus.**  When the record's path holds the chamber's transitions as ``"none"`` moves whose
   label starts with ``chamber_label`` (the simulator's ``sim.scenarios.CHAMBER_LABEL``, "chamber: to
   X degC"), each plateau is the copy of the base path between two transitions, cut exactly: it starts
   ``path.initial_dwell`` before the end of the transition (the copy's own first dwell, which the
   simulator folds into the transition) and ends where the next transition starts; the temperature must
   stay within ``plateau_tol`` of its mean over the copy.  Without such moves the plateaus are found in
   the temperature itself: intervals where the least-squares slope over ``min_plateau_s / 2`` stays
   below ``plateau_tol / min_plateau_s`` and the readings within ``plateau_tol`` of their mean, at least
   ``min_plateau_s`` long; the path is then cut at the nearest static instants inside each interval
   (:func:`cut_path`).  Each plateau becomes a record-like :class:`PlateauRecord` (time rebased to 0,
   the cut path, the encoder angles, site and rate) that every method of :data:`inscal.calibrate.METHODS`
   takes.
2. **Per plateau.**  The chosen method (``per_plateau``, default ``n25``) gives the estimates, their
   1 sigma and, where the method reports one, their covariance (the systematic filter's state
   covariance mapped to the canonical parameters with its Jacobian; a ``diagnostics["covariance"]``
   in the parameter basis); otherwise the covariance is diagonal and the result's notes say so.  The
   plateau temperature is the mean of the sensor readings over the cut, their spread recorded.
3. **Fit.**  Each parameter is a polynomial in ``dT = T - t_ref`` of the order chosen for it (order 0 =
   constant: every parameter that is not a thermal term, and the misalignments unless asked), fitted by
   generalised least squares over the plateaus with the per-plateau covariance block of its components
   (the plateaus' noise is independent, so the block-diagonal weight is the exact one).  The value at
   ``t_ref`` goes to ``result.imu``/``result.gimbal``, the coefficients of order 1.. to
   ``result.thermal`` with their 1 sigma from the fit covariance.  Each fit reports chi^2, dof and
   p-value; an inconsistent fit (p < :data:`inscal.calibrate.fit.P_INCONSISTENT`) has its misfit treated
   as systematic, as the window fits do (:data:`inscal.calibrate.fit.SIGMA_RULE`): the sigma of every
   coefficient becomes ``sum_p |d coef / d y_p| s_c sigma_p`` (the largest error a misfit of the observed
   size, of either sign on every plateau, can cause; ``s_c = sqrt(chi2_c / dof_c)``, at least 1, the
   Birge ratio of each component), at least ``s_c`` times the formal sigma, and the note says so.  A
   polynomial of too low an order leaves a misfit of that kind: the values extrapolated to ``t_ref``
   carry it, and the formal sigma would not cover it.  So the order of a thermal term the caller did not
   name is raised (up to the term's largest, while a degree of freedom remains to test it) until its fit is
   consistent: on a noise-free record the plateau estimates have zero sigma and are fitted unweighted, and
   a residual above :data:`~.polyfit.NOISE_FREE_REL` of their size is such a misfit (the built-in model's
   cubic accelerometer bias, left quadratic, leaves 17 ug rms and puts the linear term 18 % off).  The dT/dt term of the gyro bias
   (``gyro_bias_rate``) is invisible on plateaus: it stays zero, with NaN sigma and a note.

The model is the sensor's: a constant offset between the sensor and the gyros shifts every plateau
equally and is absorbed in ``t_ref``; the readings' own noise averages out over a plateau.
"""

from inscal.calibrate.thermal.method import (
    DEFAULT_ORDERS,
    METHOD,
    check_orders,
    combine,
    fit_raising_order,
    thermal_plateaus,
    thermal_truth,
)
from inscal.calibrate.thermal.plateaus import (
    CHAMBER_LABEL,
    MIN_PLATEAU_S,
    PLATEAU_TOL_C,
    Plateau,
    PlateauRecord,
    chamber_cuts,
    cut_path,
    find_plateaus,
    moving_mean,
    plateau_records,
    stable_intervals,
)
from inscal.calibrate.thermal.polyfit import TermFit, fit_term, result_covariance

__all__ = [
    "CHAMBER_LABEL",
    "DEFAULT_ORDERS",
    "METHOD",
    "MIN_PLATEAU_S",
    "PLATEAU_TOL_C",
    "Plateau",
    "PlateauRecord",
    "TermFit",
    "chamber_cuts",
    "check_orders",
    "combine",
    "cut_path",
    "find_plateaus",
    "fit_raising_order",
    "fit_term",
    "moving_mean",
    "plateau_records",
    "result_covariance",
    "stable_intervals",
    "thermal_plateaus",
    "thermal_truth",
]
