"""Discrete calibration of the IMU and the dual-axis gimbal from turntable records.

Public API::

    from inscal.calibrate import calibrate, window_means, CalibrationResult, CalibrationError, METHODS

    res = calibrate(record_like, "n25")          # or "six-position", "twelve-position", "joint"
    res.imu, res.gimbal                          # ImuErrors / GimbalErrors estimates (SI; zeros if not estimated)
    res.sigma["accel_bias"]                      # 1-sigma (SI), names of errors.PARAMETERS
    res.estimated                                # names the method estimates
    res.to_field(truth)                          # {NAME: {"value", "sigma", "unit", "error"}} in field units

``record_like`` is anything with ``.time, .dtheta, .dvel, .gimbal, .rate_hz, .site``
(``io.Record``, ``simulate.SimData`` plus site/rate, or a simple namespace); ``gimbal``
may be None when the record has a ``.path`` (windows are then found from the increments).
A :class:`WindowSet` from :func:`window_means` may be passed instead of a record.

Methods (N25 = NAVIGATION 72(4) 2025, navi.726):

``six-position``
    scheme 2: eq. 15-19 accelerometers (ideal inputs), Earth-rate gyro
    bias, CW/CCW rate tests (eq. 28).
``twelve-position``
    inner-symmetric version (eq. 24-26).
``n25``
    scheme 1: rough alpha0 (eq. 38), the eq. 40-44 least squares for
    [tan beta0, alpha0, dth], refined accelerometer and gyro errors.
``unified``
    the systematic filter (S16, 51 states) with the gimbal non-orthogonality
    and mount attitude estimated from the encoder angles (58 states;
    :mod:`.unified`); reads the record like the systematic methods.
``thermal-plateaus``
    a thermal-chamber calibration: another method (``per_plateau``, default
    ``n25``) on each temperature plateau of the record, then a weighted polynomial
    fit of every thermal term over the plateaus (:mod:`.thermal`; ``result.thermal``).
``multi-position``
    no turntable: still poses at unknown orientations found by
    :mod:`.static_detect`, the accelerometer model from the gravity magnitude and
    the gyro model from the rotations between poses (:mod:`.multiposition`,
    Tedaldi 2014); options ``min_static``, ``settle``, ``quadratic``, ...
``ferraris``
    no turntable: six faces and three whole turns (:mod:`.ferraris`, Ferraris 1995), the faces' tilt
    (``face_tilt``, stated) in the sigma; options ``min_static``, ``min_turn_end``, ``face_tilt``, ...
``joint``
    one nonlinear least-squares fit of all IMU errors, dth and the mounting
    attitude to every window, 1 sigma from the Jacobian and the measured
    window noise; unobservable directions are reported and held fixed.

Options (``**options``) go to :func:`window_means` (``settle``, ``min_static``, ...) and to
the method (``uncertainty=False`` skips the error propagation; ``joint``: ``fix``,
``initial``, ``sv_tol``).
"""

from __future__ import annotations

import inspect

from inscal.calibrate.ferraris import ferraris
from inscal.calibrate.joint import joint
from inscal.calibrate.multiposition import multi_position
from inscal.calibrate.n25 import n25
from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.six_position import six_position
from inscal.calibrate.systematic.driver import systematic
from inscal.calibrate.systematic.methods import systematic30, systematic51
from inscal.calibrate.thermal import thermal_plateaus
from inscal.calibrate.twelve_position import twelve_position
from inscal.calibrate.unified import unified
from inscal.calibrate.window_noise import widened
from inscal.calibrate.windows import CalibrationError, Window, WindowSet, window_means

#: the calibration methods by name: the functions :func:`calibrate` dispatches to
METHODS = {
    "six-position": six_position,
    "twelve-position": twelve_position,
    "n25": n25,
    "joint": joint,
    "systematic51": systematic51,
    "systematic30": systematic30,
    "unified": unified,
    "thermal-plateaus": thermal_plateaus,
    "multi-position": multi_position,
    "ferraris": ferraris,
}
#: methods that read the increments directly (no window segmentation)
RECORD_METHODS = {"systematic51", "systematic30", "unified"}
#: methods for records without a turntable: they find their own still poses in the increments
NO_TABLE_METHODS = {"multi-position", "ferraris"}
#: methods that run another method (``per_plateau``) on parts of the record and combine the results
PLATEAU_METHODS = {"thermal-plateaus"}

__all__ = ["calibrate", "window_means", "CalibrationResult", "CalibrationError", "Window", "WindowSet", "METHODS",
           "RECORD_METHODS", "PLATEAU_METHODS", "NO_TABLE_METHODS", "six_position", "twelve_position", "n25", "joint",
           "unified", "multi_position", "ferraris"]


def calibrate(record_like, method: str, **options) -> CalibrationResult:
    """Calibrate an IMU (and its gimbal) from a record with one of the methods of :data:`METHODS`.

    The methods are described in the module docstring: the window-mean methods (``six-position``,
    ``twelve-position``, ``n25``, ``joint``) average the static and constant-rate windows of a
    turntable record first (:func:`window_means`, whose options pass through); the systematic filters
    (``systematic51``, ``systematic30``, ``unified``) read the increments; ``multi-position`` and
    ``ferraris`` find their own still poses in a record without a turntable; ``thermal-plateaus`` runs
    another method on each temperature plateau.

    Parameters
    ----------
    record_like : Record or WindowSet
        Anything with ``time``, ``dtheta``, ``dvel``, ``gimbal``, ``rate_hz`` and ``site``
        (:class:`inscal.io.Record`; ``gimbal`` may be None when the record has a ``path``), or the
        :class:`WindowSet` of :func:`window_means` for the window-mean methods.
    method : str
        A name of :data:`METHODS`.
    **options
        Options of :func:`window_means` (``settle``, ``min_static``, ...) and of the method
        (``uncertainty=False`` skips the error propagation; ``joint``: ``fix``, ``initial``,
        ``sv_tol``; ``noise``: an identified noise model that widens the window sigma).

    Returns
    -------
    CalibrationResult
        The estimates (SI), their 1 sigma, the parameters estimated, the diagnostics.

    Raises
    ------
    CalibrationError
        An unknown method or option, window means given to a method that reads the record, or data
        the method cannot calibrate (too few windows, jumps in the gimbal angles, ...).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.calibrate import calibrate, window_means
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("n25", np.random.default_rng(0), rate_hz=10.0)  # N25 path, errors, noise
    >>> res = calibrate(window_means(rec), "joint")
    >>> res.method, len(res.estimated)
    ('joint', 8)
    >>> z = (res.imu.accel_bias - rec.truth.imu.accel_bias) / res.sigma["accel_bias"]
    >>> bool(np.all(np.abs(z) < 3))  # within 3 sigma of the truth
    True
    """
    if method not in METHODS:
        raise CalibrationError(f"unknown method {method!r}; choose one of: {', '.join(METHODS)}")
    fn = METHODS[method]
    if method in PLATEAU_METHODS:  # it checks its own options and hands the rest to the per-plateau method
        if isinstance(record_like, WindowSet):
            raise CalibrationError(f"{method} needs the record (increments and temperature), not window means")
        return fn(record_like, run=calibrate, **options)
    if method in NO_TABLE_METHODS:
        unknown = set(options) - (set(inspect.signature(fn).parameters) - {"record_like"})
        if unknown:
            raise CalibrationError(f"unknown option(s) for {method}: {sorted(unknown)}")
        if isinstance(record_like, WindowSet):
            raise CalibrationError(f"{method} needs the record (increments), not window means")
        return fn(record_like, **options)
    if method in RECORD_METHODS:

        meth_keys = set(inspect.signature(systematic).parameters) - {"ws_or_record", "method_name"}
        unknown = set(options) - meth_keys
        if unknown:
            raise CalibrationError(f"unknown option(s) for {method}: {sorted(unknown)}")
        if isinstance(record_like, WindowSet):
            raise CalibrationError(f"{method} needs the record (increments), not window means")
        return fn(record_like, **options)
    noise = options.pop("noise", None)  # an identified noise model: the window sigma widened (window_noise)
    seg_keys = set(inspect.signature(window_means).parameters) - {"record_like"}
    seg_opts = {k: v for k, v in options.items() if k in seg_keys}
    meth_keys = set(inspect.signature(fn).parameters) - {"ws"}
    unknown = set(options) - seg_keys - meth_keys
    if unknown:
        raise CalibrationError(f"unknown option(s) for {method}: {sorted(unknown)}")
    ws = record_like if isinstance(record_like, WindowSet) else window_means(record_like, **seg_opts)
    if noise is not None:
        wins, info = widened(ws.windows, noise, ws.rate_hz)
        ws = WindowSet(wins, ws.site, ws.rate_hz, dict(ws.info) | {"noise_widening": info})
    res = fn(ws, **{k: v for k, v in options.items() if k in meth_keys})
    if noise is not None:
        res.notes.append("window sigma widened for the bias drift of the noise model (GM, BI, RW, DR terms: their "
                         "Allan variance at each window's length or spacing; inscal.calibrate.window_noise)")
    return res
