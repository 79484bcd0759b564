"""Twelve-position (inner-symmetric) discrete calibration (N25 eq. 24-26).

The six orientations of the six-position scheme are each visited at two inner-gimbal
angles differing by 180 deg (the twelve N25 positions, ``turntable.N25_TWELVE_POSITIONS``),
which cancels the leveling error in the installation angles to first order.  Inputs are
still the ideal ones (level, orthogonal turntable).  Gyro bias: the mean gyro output over
the twelve positions, where the ideal Earth-rate inputs sum to zero (N25 eq. 27).  Gyro
scale factors and installation angles from the CW/CCW rate tests (eq. 28).  Fit, sigma and
notes as for the six-position scheme (:func:`.six_position.finish_ideal`; known scheme
error N25 eq. 24-26, 29).
"""

from __future__ import annotations

import numpy as np

from inscal.calibrate.ideal import finish_ideal
from inscal.calibrate.positions import (
    accel_twelve,
    gyro_matrix_from_rate_tests,
    nominal_position,
    twelve_windows,
    values_from_matrices,
)
from inscal.calibrate.result import (
    IMU_LINEAR,
    CalibrationResult,
    errors_from_values,
    flatten,
)
from inscal.calibrate.windows import WindowSet


def _core(ws: WindowSet, idx: list[int]):
    Ma, nabla = accel_twelve(ws, idx)
    eps = np.mean([ws.windows[k].gyro for k in idx], axis=0)  # N25 eq. 27: ideal Earth inputs cancel
    Mg, used_rate = gyro_matrix_from_rate_tests(ws, ideal=True)  # N25 eq. 28
    return Ma, nabla, Mg, eps, used_rate


def twelve_position(ws: WindowSet, uncertainty: bool = True) -> CalibrationResult:
    """The inner-symmetric twelve-position scheme of N25 (eq. 24-26) with ideal inputs.

    The six orientations of the six-position scheme, each at two inner-gimbal angles 180 deg apart,
    which cancels the leveling error in the installation angles to first order; the gyro bias from
    the mean over the twelve positions (eq. 27), the gyro scale factors and installation angles from
    the CW/CCW rate tests (eq. 28).  The gimbal errors are not estimated.

    Parameters
    ----------
    ws : WindowSet
        The twelve static positions and the rate tests of a turntable record (:func:`window_means`).
    uncertainty : bool
        Propagate the windows' noise to the sigma (False: faster, no sigma).

    Returns
    -------
    CalibrationResult
        The accelerometer and gyro estimates of the twelve positions and the rate tests (SI), their
        1 sigma when ``uncertainty`` is set, and the parameters estimated (no gimbal errors).

    Examples
    --------
    >>> from numpy.random import default_rng
    >>> from inscal.calibrate import twelve_position, window_means
    >>> from inscal.sim.records import scenario_record
    >>> res = twelve_position(window_means(scenario_record("n25", default_rng(0), rate_hz=10.0)), uncertainty=False)
    >>> len(res.diagnostics["positions"])
    12
    """
    idx = twelve_windows(ws)
    Ma, nabla, Mg, eps, used_rate = _core(ws, idx)
    vals = values_from_matrices(Ma, nabla, Mg, eps)

    def est(w2):
        return flatten(*errors_from_values(values_from_matrices(*_core(w2, idx)[:4])), IMU_LINEAR)

    used = {k: (True, True) for k in idx}
    used.update({k: (True, False) for k in used_rate})
    diag = {"positions": [list(nominal_position(ws.windows[k])) for k in idx],
            "n_rate_windows": len(used_rate)}
    return finish_ideal("twelve-position", ws, vals, est, used, [ws.windows[k] for k in idx], uncertainty, diag,
                        ["ideal inputs (level, orthogonal turntable), inner-symmetric positions (N25 eq. 24-26); "
                         "gimbal non-orthogonality and mount attitude not estimated"], "N25 eq. 24-26, 29")
