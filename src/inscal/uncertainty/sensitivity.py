"""Sensitivity coefficients of a window-mean calibration to the station's inputs (GUM 5.1.3),
by finite differences through the estimator itself.

The station's errors change what the IMU senses, not what the estimator believes: a table stop
``e`` off its reading turns the IMU by ``e`` about that gimbal axis; a wobble tilts the table top
about a horizontal axis; a rate error scales the table rate; the site's gravity, latitude and height
change the specific force and the Earth rate.  :func:`perturb` writes such a :class:`Deviation` into
the window means of a record (the "truth" route): the mean inputs of every affected window are
recomputed from the gimbal kinematics (N25 eq. 7-9: ``C_s^b = Rot(u, theta_x) R_z(theta_z)``,
``C_b^n`` from the mounting attitude) averaged over the window's sweep, and their change is added
to the measured means through the unit's own ``M_g`` / ``M_a`` (N25 eq. 1-2).  The estimator is
then run again: ``c = (x(+h) - x(-h)) / 2h`` (central differences).

The other route, through what the estimator believes (:func:`believe`: the recorded angles, the
recorded rates, the site's gravity and latitude shifted the other way) gives the same coefficients
to first order; the tests check the two against each other and against closed forms
(a gravity error ``dg/g`` is an accelerometer scale factor error of ``dg/g``, 1:1).

The time base (acquisition clock fast by ``eps``): every mean, and every rate taken from the
recorded angles on the same clock, is ``(1 + eps)`` times the truth.

Per-stop inputs (table angle, encoder resolution, wobble) act independently at every window: their
coefficients come per window and per axis (:attr:`Sensitivities.per_stop`); the budget combines them
as independent inputs (GUM 5.1.2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from inscal.calibrate import calibrate
from inscal.calibrate.result import CalibrationResult, flatten, nparams
from inscal.calibrate.windows import Window, WindowSet
from inscal.core.attitude import skew
from inscal.core.earth import Site, earth_rate_n
from inscal.core.turntable import C_b_n, C_s_b, outer_axis
from inscal.uncertainty import budget as gum
from inscal.uncertainty.station import INPUTS, site_check

#: finite-difference steps of the inputs (SI): well above rounding, well inside the linear range
STEPS = {"angle": 2e-5, "dimensionless": 2e-5, "accel": 2e-4, "length": 10.0}
#: the steps of the filter methods' differences (SI): 100 mGal, 100 ppm, 20 arcsec, 100 m
FILTER_STEPS = {"accel": 1e-3, "dimensionless": 1e-4, "angle": 1e-4, "length": 100.0}
#: samples per degree of sweep when a turning window's mean input is averaged (midpoint rule)
SAMPLES_PER_DEG = 2.0
#: the inputs whose coefficients :func:`sensitivities` computes by finite differences
GLOBAL_INPUTS = ("table_rate", "axis_nonorthogonality", "gravity", "latitude", "height", "time_base")
#: the per-stop inputs (window x axis) and the deviation field each perturbs
STOP_INPUTS = {"table_angle": "angle", "axis_wobble": "tilt"}


@dataclass(frozen=True)
class Deviation:
    """The station's errors in one run (SI; truth minus what the estimator assumes).

    ``angle[k] = (e_x, e_z)``: the outer / inner gimbal's true angle minus its reading during window
    ``k``; ``tilt[k] = (t_E, t_N)``: the table top's tilt about the east / north axes in window ``k``
    (rotation vector of the true s-frame against the nominal one, ENU); ``None`` = zeros."""

    angle: np.ndarray | None = None
    tilt: np.ndarray | None = None
    nonorthogonality: float = 0.0
    rate_scale: float = 0.0
    gravity: float = 0.0
    latitude: float = 0.0
    height: float = 0.0
    time_base: float = 0.0


@dataclass(frozen=True)
class Geometry:
    """What the window inputs are computed with: the gimbal's non-orthogonality and mounting
    attitude [rad] and the unit's ``M_g``, ``M_a`` (from the calibration's own estimates)."""

    dth: float
    mount: np.ndarray
    M_g: np.ndarray = field(default_factory=lambda: np.eye(3))
    M_a: np.ndarray = field(default_factory=lambda: np.eye(3))

    @classmethod
    def of(cls, result: CalibrationResult) -> Geometry:
        """The geometry a calibration estimated."""
        return cls(float(result.gimbal.nonorthogonality), np.asarray(result.gimbal.mount_attitude, float),
                   result.imu.M_g, result.imu.M_a)


def window_inputs(w: Window, site: Site, geo: Geometry, angle=(0.0, 0.0), tilt=(0.0, 0.0), dth: float = 0.0,
                  rate_scale: float = 0.0, gravity: float = 0.0, latitude: float = 0.0,
                  height: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The true mean angular rate and specific force ``(w^s, f^s)`` [rad/s, m/s^2] of window ``w``
    with the given deviations (see :class:`Deviation`), averaged over the window's angle sweep."""
    span = np.abs(np.asarray(w.theta1) - np.asarray(w.theta0)).max()
    n = 1 if w.kind == "static" else max(64, int(math.degrees(span) * SAMPLES_PER_DEG))
    s = (np.arange(n) + 0.5) / n
    tx = w.theta0[0] + (w.theta1[0] - w.theta0[0]) * s + angle[0]
    tz = w.theta0[1] + (w.theta1[1] - w.theta0[1]) * s + angle[1]
    # the mean of C_s^n over the sweep (N25 eq. 7-8): w_ie^n and f^n are constant, so the mean inputs are
    # mean(C_s^n)^T w_ie^n and mean(C_s^n)^T f^n, and C_b^n and the tilt factor out of the mean
    C_sn = C_b_n(geo.mount) @ C_s_b(tx, tz, geo.dth + dth).reshape(n, 3, 3).mean(axis=0)
    if tilt[0] or tilt[1]:
        C_sn = (np.eye(3) + skew(np.array([tilt[0], tilt[1], 0.0]))) @ C_sn
    lat = site.latitude + latitude
    g = site.gravity + gravity + (site.gravity_model.g(site.latitude, site.height + height) - site.gravity)
    wie, f_n = earth_rate_n(lat), np.array([0.0, 0.0, g])  # ENU: the specific force at rest points up
    W = C_sn.T @ wie
    F = C_sn.T @ f_n
    if w.kind != "static":
        rate = w.rate * (1.0 + rate_scale)
        if w.axis == "inner":  # N25 eq. 9: the inner axis is z_s, the outer one R_z^T u
            W = W + rate * np.array([0.0, 0.0, 1.0])
        else:
            u = outer_axis(geo.dth + dth)
            c, sn = np.cos(tz), np.sin(tz)
            W = W + rate * np.array([np.mean(c * u[0] + sn * u[1]), np.mean(-sn * u[0] + c * u[1]), u[2]])
    return W, F


def window_baseline(ws: WindowSet, geo: Geometry) -> list[tuple[np.ndarray, np.ndarray]]:
    """The error-free mean inputs of every window (:func:`window_inputs` without deviations), which
    :func:`perturb` subtracts: computed once for many perturbations (a Monte Carlo)."""
    return [window_inputs(w, ws.site, geo) for w in ws.windows]


def perturb(ws: WindowSet, geo: Geometry, dev: Deviation, base=None) -> WindowSet:
    """The window means the IMU would have produced with the station's errors ``dev`` (truth route);
    ``base``: :func:`window_baseline` of ``ws`` (computed here when None)."""
    glob = any((dev.nonorthogonality, dev.rate_scale, dev.gravity, dev.latitude, dev.height))
    out = []
    for k, w in enumerate(ws.windows):
        a = (0.0, 0.0) if dev.angle is None else tuple(dev.angle[k])
        t = (0.0, 0.0) if dev.tilt is None else tuple(dev.tilt[k])
        if glob or any(a) or any(t):
            W0, F0 = window_inputs(w, ws.site, geo) if base is None else base[k]
            W1, F1 = window_inputs(w, ws.site, geo, a, t, dev.nonorthogonality, dev.rate_scale, dev.gravity,
                                   dev.latitude, dev.height)
            w = replace(w, gyro=w.gyro + geo.M_g @ (W1 - W0), accel=w.accel + geo.M_a @ (F1 - F0))
        if dev.time_base:
            f = 1.0 + dev.time_base
            w = replace(w, gyro=w.gyro * f, accel=w.accel * f, rate=w.rate * f)
        out.append(w)
    return WindowSet(out, ws.site, ws.rate_hz, ws.info)


def believe(ws: WindowSet, dev: Deviation) -> WindowSet:
    """The other route: the same errors as what the estimator believes instead (readings minus the
    angle errors, rates divided by the rate error, the site's gravity and latitude shifted back);
    equal to :func:`perturb` to first order.  Tilts and the non-orthogonality have no such route."""
    out = []
    for k, w in enumerate(ws.windows):
        a = np.zeros(2) if dev.angle is None else np.asarray(dev.angle[k], float)
        out.append(replace(w, theta0=w.theta0 - a, theta1=w.theta1 - a, rate=w.rate / (1.0 + dev.rate_scale)))
    site = ws.site
    if dev.gravity or dev.latitude:
        site = Site(site.latitude - dev.latitude, site.longitude, site.height).with_gravity(site.gravity - dev.gravity)
    return WindowSet(out, site, ws.rate_hz, ws.info)


def estimator(method: str, names, **options) -> Callable[[WindowSet], np.ndarray]:
    """``x(ws)``: the flat estimate (SI) of ``names`` by ``method`` without its error propagation."""
    def run(ws: WindowSet) -> np.ndarray:
        r = calibrate(ws, method, uncertainty=False, **options)
        return flatten(r.imu, r.gimbal, names)
    return run


@dataclass(frozen=True)
class Sensitivities:
    """``glob[input]`` (n_components,) and ``per_stop[input]`` (n_windows, 2, n_components): the
    partial derivatives of the flat estimate by each input (SI per SI)."""

    glob: dict[str, np.ndarray]
    per_stop: dict[str, np.ndarray]


def _deviation(name: str, h: float, n_windows: int, k: int | None = None, j: int | None = None) -> Deviation:
    if name in STOP_INPUTS:
        a = np.zeros((n_windows, 2))
        a[k, j] = h
        return Deviation(**{STOP_INPUTS[name]: a})
    key = {"table_rate": "rate_scale", "axis_nonorthogonality": "nonorthogonality"}.get(name, name)
    return Deviation(**{key: h})


def sensitivities(ws: WindowSet, geo: Geometry, x: Callable[[WindowSet], np.ndarray], kinds: dict[str, str],
                  stop_inputs=tuple(STOP_INPUTS), windows=None) -> Sensitivities:
    """Central differences of the estimate ``x`` through :func:`perturb` for every global input;
    forward differences for every (window, axis) of ``stop_inputs`` (a stop moves one window's
    means, in which the window-mean estimators are linear to second order in the small angles:
    half the estimator runs); ``windows``: the window indices to do (default: all but the partial
    turns, whose means no estimator reads); ``kinds[input]`` picks the step (:data:`STEPS`)."""
    nw = len(ws.windows)
    x0 = x(ws)

    def diff(name, k=None, j=None, central=True):
        h = STEPS[kinds[name]]
        lo = x(perturb(ws, geo, _deviation(name, -h, nw, k, j))) if central else x0
        return (x(perturb(ws, geo, _deviation(name, h, nw, k, j))) - lo) / (2 * h if central else h)

    glob = {name: diff(name) for name in GLOBAL_INPUTS}
    if windows is None:
        windows = [k for k, w in enumerate(ws.windows) if w.kind != "turn"]
    per = {}
    for name in stop_inputs:
        c = np.zeros((nw, 2, x0.size))
        for k in windows:
            for j in range(2):
                c[k, j] = diff(name, k, j, central=False)
        per[name] = c
    return Sensitivities(glob, per)


#: the methods whose budget this module computes: those that read window means
WINDOW_METHODS = ("n25", "six-position", "twelve-position", "joint")
#: the systematic filter (S16): its budget from the record (:func:`record_sensitivities`)
FILTER_METHODS = ("systematic51", "systematic30")
#: the table-free methods (hand-held still poses): their budget from the record, as the filter's
NO_TABLE_METHODS = ("multi-position", "ferraris")
#: every method with a budget
BUDGET_METHODS = WINDOW_METHODS + FILTER_METHODS + NO_TABLE_METHODS
#: what the budget of a filter method says of the table's inputs
FILTER_TABLE_NOTE = ("table_angle, table_rate, axis_wobble, axis_nonorthogonality, encoder_resolution: the systematic "
                     "filter reads neither the table's angles nor its rates (its observations are the dwells' zero "
                     "velocity), so they enter with sensitivity 0 (bench/budget_s16.py moves every stop of a "
                     "simulated path to check it)")
#: what the budget of a table-free method says of the table's inputs
NO_TABLE_NOTE = ("table_angle, table_rate, axis_wobble, axis_nonorthogonality, encoder_resolution: a table-free "
                 "method uses no turntable (its poses are estimated from the data), so they enter with sensitivity 0")


def believe_record(record, dev: Deviation):
    """The record as the estimator would read it with the site and clock errors ``dev`` moved into its
    belief (gravity, latitude and height of the site, the rate of the time base); the filter methods'
    route.  The gravity stays the site's value when the latitude or height moves (their own inputs)."""
    site = record.site
    g = site.gravity - dev.gravity
    if dev.height:  # a height error moves the true gravity by the model's free-air gradient
        g -= site.gravity_model.g(site.latitude, site.height + dev.height) - site.gravity
    new_site = Site(site.latitude - dev.latitude, site.longitude, site.height).with_gravity(g) \
        if (dev.gravity or dev.latitude or dev.height) else site
    f = 1.0 + dev.time_base
    return replace(record, site=new_site, rate_hz=record.rate_hz * f, time=np.asarray(record.time) / f)


def record_sensitivities(record, x: Callable, kinds: dict[str, str], nwin: int = 1) -> Sensitivities:
    """Central differences of a filter method's estimate ``x(record)`` through :func:`believe_record`
    for the site and clock inputs; the table's inputs are zero (:data:`FILTER_TABLE_NOTE`)."""
    glob = {}
    for name in GLOBAL_INPUTS:
        if name in ("table_rate", "axis_nonorthogonality"):
            continue
        h = FILTER_STEPS[kinds[name]]  # the filter iterates to a tolerance: steps well above its noise
        glob[name] = (x(believe_record(record, Deviation(**{name: h})))
                      - x(believe_record(record, Deviation(**{name: -h})))) / (2 * h)
    n = next(iter(glob.values())).size
    glob.update({k: np.zeros(n) for k in ("table_rate", "axis_nonorthogonality")})
    return Sensitivities(glob, {k: np.zeros((nwin, 2, n)) for k in STOP_INPUTS})


def calibration_budget(result: CalibrationResult, station, rep=None, coverage: float = 0.95, windows=None, record=None,
                       temperature: gum.TemperatureSensitivity | None = None, **options):
    """The GUM budget (:class:`inscal.uncertainty.budget.Budget`) of a calibration ``result`` at ``station``.

    A window-mean method's result keeps its windows: the coefficients come from :func:`sensitivities` at the
    estimated geometry, the estimator's sigma is Type A with the fit's dof.  A filter or table-free method
    (:data:`FILTER_METHODS`, :data:`NO_TABLE_METHODS`) needs its ``record``: :func:`record_sensitivities` (the
    filter's sigma is Type A with infinite dof: it is the propagated noise of the whole record).

    Parameters
    ----------
    result : inscal.calibrate.result.CalibrationResult
        The calibration.
    station : inscal.uncertainty.station.Station
        The station's inputs.
    rep : tuple, optional
        ``(u_rep, dof)`` (SI, flat over the estimated parameters): the repeatability between runs, or None.
    coverage : float, optional
        The coverage probability of the expanded uncertainties.
    windows : list of int, optional
        The windows whose per-stop coefficients are computed (:func:`sensitivities`).
    record : inscal.io.records.Record, optional
        The calibrated record (a filter or table-free method).
    temperature : inscal.uncertainty.budget.TemperatureSensitivity, optional
        How the chamber's temperature stability enters (None: not propagated, with a note).
    **options
        The method's options the result was computed with.

    Returns
    -------
    inscal.uncertainty.budget.Budget
        Per component ``u_c``, ``nu_eff``, ``k``, ``U`` and every input's line.

    Raises
    ------
    ValueError
        A method without a budget, or one whose windows or record are missing.
    inscal.uncertainty.station.StationError
        The station's site is another one than the record's.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> calibration_budget(SimpleNamespace(method="unified", estimated=[], windows=None), None)
    Traceback (most recent call last):
    ...
    ValueError: an uncertainty budget needs a window-mean method (n25, six-position, twelve-position, joint) or \
the record of a filter or table-free method (systematic51, systematic30, multi-position, ferraris), not unified
    """
    names = result.estimated
    kinds = {k: v.kind for k, v in INPUTS.items()}
    notes = []
    if result.method in FILTER_METHODS + NO_TABLE_METHODS and record is not None:
        def xr(rec):
            r = calibrate(rec, result.method, **options)
            return flatten(r.imu, r.gimbal, names)
        sens = record_sensitivities(record, xr, kinds)
        notes.append(FILTER_TABLE_NOTE if result.method in FILTER_METHODS else NO_TABLE_NOTE)
        site = record.site
    elif result.method in WINDOW_METHODS and result.windows is not None:
        ws = result.windows
        sens = sensitivities(ws, Geometry.of(result), estimator(result.method, names, **options), kinds,
                             windows=windows)
        site = ws.site
    else:
        raise ValueError(f"an uncertainty budget needs a window-mean method ({', '.join(WINDOW_METHODS)}) or the "
                         f"record of a filter or table-free method ({', '.join(FILTER_METHODS + NO_TABLE_METHODS)}), "
                         f"not {result.method}")
    if "gimbal_nonorthogonality" in names:  # the method estimates the table's dth: its error, not its value
        sens.glob["axis_nonorthogonality"][nparams(names[:names.index("gimbal_nonorthogonality")])] -= 1.0
    values = flatten(result.imu, result.gimbal, names)
    sigma = np.concatenate([np.atleast_1d(np.asarray(result.sigma.get(n, np.nan), float)).ravel() for n in names])
    fit = result.fit or {}
    dof = float(fit.get("dof") or math.inf) if result.method in WINDOW_METHODS + NO_TABLE_METHODS else math.inf
    notes += site_check(station, site.latitude, site.height, site.gravity)  # StationError: another site
    return gum.budget(result.method, names, values, sigma, dof, station, sens.glob, sens.per_stop, rep,
                      coverage, notes, temperature)
