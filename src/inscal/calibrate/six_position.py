"""Classical discrete calibration (N25 section 3.1, scheme 2): six-position accelerometer
least squares (eq. 15-19), gyro bias from the Earth rate with each gyro axis up and down,
gyro scale factors and installation angles from clockwise/counter-clockwise rate tests
(eq. 28).  The turntable is assumed level and orthogonal (ideal inputs): this is the
scheme whose leveling and non-orthogonality errors N25 eq. 21-23 and 29 describe.

The helpers here (position matching, the eq. 19 least squares, the eq. 28 rate-test
solution, the fit of an ideal-input scheme) are shared with the twelve-position and n25
methods.

Fit: the estimated IMU errors predict every window mean through the exact model
(:func:`.window_model.predict`) for the turntable the scheme assumes (level, orthogonal), with the
heading ``gamma0`` (which the scheme does not need) fitted as a nuisance; chi^2, dof
(window-mean components minus 24 IMU errors minus the heading) and p are in
``diagnostics["fit"]``.  When the fit is inconsistent the note names the likely cause and
adds the scheme's known error (N25 eq. 21-23, 29: :func:`predicted_scheme_errors`) for
the tilt and non-orthogonality of this record, taken from a joint fit of the same windows.
"""

from __future__ import annotations

import numpy as np

from inscal.calibrate.ideal import finish_ideal
from inscal.calibrate.positions import (
    AXIS_NAMES,
    accel_least_squares,
    gyro_matrix_from_rate_tests,
    nominal_position,
    orientation,
    positions,
    values_from_matrices,
)
from inscal.calibrate.result import (
    IMU_LINEAR,
    CalibrationResult,
    errors_from_values,
    flatten,
)
from inscal.calibrate.window_model import ideal_up
from inscal.calibrate.windows import CalibrationError, WindowSet


def _need_orientations(ws: WindowSet, pos: dict) -> dict[str, int]:
    """For each of the six orientations, the index of its first static window."""
    by: dict[str, int] = {}
    for p, k in sorted(pos.items(), key=lambda q: q[1]):
        by.setdefault(orientation(p), k)
    missing = [o for o in ("+x", "-x", "+y", "-y", "+z", "-z") if o not in by]
    if missing:
        words = ", ".join(f"{o[1]} axis {'up' if o[0] == '+' else 'down'}" for o in missing)
        raise CalibrationError(f"six-position calibration needs a static window with each IMU axis up and down; "
                               f"missing: {words} (found {len(by)} of 6 orientations)")
    return by


def _six_core(ws: WindowSet, sel: dict[str, int]):
    g = ws.site.gravity
    order = ("+x", "-x", "+y", "-y", "+z", "-z")
    idx = [sel[o] for o in order]
    N = np.array([ws.windows[k].accel for k in idx])
    F = np.array([g * ideal_up(*ws.windows[k].theta) for k in idx])  # N25 eq. 17 (ideal inputs)
    F = np.round(F / g) * g
    Ma, nabla = accel_least_squares(N, F)  # N25 eq. 19
    # gyro bias from the Earth rate: axis j vertical up and down (its horizontal input is zero)
    eps = np.array([0.5 * (ws.windows[sel["+" + a]].gyro[j] + ws.windows[sel["-" + a]].gyro[j])
                    for j, a in enumerate(AXIS_NAMES)])
    Mg, used_rate = gyro_matrix_from_rate_tests(ws, ideal=True)  # N25 eq. 28
    return Ma, nabla, Mg, eps, used_rate


def six_position(ws: WindowSet, uncertainty: bool = True) -> CalibrationResult:
    """Scheme 2 of N25: six-position accelerometer least squares, Earth-rate gyro bias, rate tests.

    Accelerometers from six static positions with ideal (level, orthogonal) inputs (N25 eq. 15-19),
    the gyro bias from the Earth rate, the gyro scale factors and misalignments from CW/CCW rate
    tests (eq. 28).  The gimbal errors are not estimated.

    Parameters
    ----------
    ws : WindowSet
        The windows of a turntable record (:func:`window_means`).
    uncertainty : bool
        Propagate the windows' noise to the sigma.

    Returns
    -------
    CalibrationResult
        The accelerometer and gyro estimates of the six positions and the rate tests (SI), with their
        1 sigma (``uncertainty``) and the parameters estimated (no gimbal errors).

    Raises
    ------
    CalibrationError
        A position or a rate test that the windows do not hold.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import six_position, window_means
    >>> from inscal.sim.records import scenario_record
    >>> ws = window_means(scenario_record("n25", np.random.default_rng(0), rate_hz=10.0))
    >>> res = six_position(ws, uncertainty=False)  # no sigma: faster
    >>> "gimbal_nonorthogonality" in res.estimated
    False
    """
    pos = positions(ws)
    sel = _need_orientations(ws, pos)
    Ma, nabla, Mg, eps, used_rate = _six_core(ws, sel)
    vals = values_from_matrices(Ma, nabla, Mg, eps)

    def est(w2):
        return flatten(*errors_from_values(values_from_matrices(*_six_core(w2, sel)[:4])), IMU_LINEAR)

    used = {k: (True, True) for k in sel.values()}
    used.update({k: (True, False) for k in used_rate})
    static_used = [ws.windows[k] for k in sel.values()]
    return finish_ideal("six-position", ws, vals, est, used, static_used, uncertainty,
                        {"positions": {o: list(nominal_position(ws.windows[k])) for o, k in sel.items()},
                         "n_rate_windows": len(used_rate)},
                        ["ideal inputs: turntable assumed level and orthogonal (N25 scheme 2); "
                         "gimbal non-orthogonality and mount attitude not estimated"], "N25 eq. 21-23, 29")
