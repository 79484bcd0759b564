"""The temperature of an experiment planned without data: the known input of the systematic filter's thermal
states (option ``thermal``; :mod:`inscal.calibrate.systematic.thermal_states`) in the observability analysis
and the Cramér-Rao bound, and the accuracy the plateau method would reach on the same IMU.

The known input (:class:`KnownTemperature`) is the temperature a record of the scenario carries and the
filter makes of it: the profile (:class:`inscal.sim.thermal.TemperatureProfile`) read at the scenario's
temperature-sensor rate (1 Hz by default; exact readings: the covariance does not depend on the sensor's
noise), interpolated to the middle of every sample, and ``dT/dt`` the filter's least-squares slope of the
readings over :data:`~inscal.core.thermal.RATE_WINDOW_S` (60 s), as
:func:`~inscal.calibrate.systematic.thermal_states.sample_inputs` computes them.  The slope smooths each corner of
a profile (a ramp starting or ending) over the window; the profile's exact ``dT/dt`` (a step at each corner,
``rate_window_s=None``, bound only) observes the dT/dt term slightly better (0.6 % on ``thermal-ramp``).  The
reference temperature is the scenario's thermal model's ``t_ref`` (default
:data:`~inscal.calibrate.systematic.thermal_states.T_REF_C`, 20 degC) and, as in the filter, must lie inside the
temperatures the path sees; the prior of every coefficient is the filter's (``THERMAL_SIGMA0`` spread over the
span ``max |T - t_ref|``, :func:`inscal.calibrate.systematic.states.prior_sigma`).

A constant temperature is no input: every coefficient's column is then a constant multiple of its base
term's (``b + c_1 dT + c_2 dT^2`` is seen as one number), and at ``T = t_ref`` it is zero, so nothing can be
reported beyond "every coefficient stays at its prior".  Both views refuse a scenario without a profile.

The plateau method (``thermal-plateaus``: a calibration at each plateau, then a generalised least-squares
polynomial per term, :mod:`inscal.calibrate.thermal`) reaches, with per-plateau sigmas ``s_i`` of a base
parameter (the bound of the per-plateau path) and the Vandermonde matrix ``X_ik = dT_i^k`` (k = 0 .. order)
of the plateau temperatures, ``Cov(c) = (X^T diag(s_i^-2) X)^-1`` per axis (:func:`plateau_sigma`; the
polynomial's order 0 is the base term at ``t_ref``).  It sees no dT/dt term: a plateau holds dT/dt = 0.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from inscal.calibrate.systematic.states import THERMAL_TERM_NAMES, thermal_group_name
from inscal.calibrate.systematic.thermal_states import T_REF_C
from inscal.core.thermal import RATE_WINDOW_S, temperature_rate
from inscal.io.records import Temperature

#: points per chunk when the temperature is evaluated over a long grid (memory independent of the path)
CHUNK = 1 << 20
#: the base state of each polynomial thermal term in the systematic filter's 51-state set: (group, components)
PLATEAU_STATES = {"gyro_bias": ("gyro_bias", ("x", "y", "z")),
                  "gyro_scale_factor": ("gyro_matrix", ("xx", "yy", "zz")),
                  "accel_bias": ("accel_bias", ("x", "y", "z")),
                  "accel_scale_factor": ("accel_matrix", ("xx", "yy", "zz"))}


def default_t_ref(scenario) -> float:
    """The reference temperature of a scenario's thermal states: its thermal model's, else 20 degC."""
    th = getattr(scenario, "thermal", None)
    return float(th.t_ref) if th is not None else T_REF_C


def need_profile(scenario, label: str, error=ValueError):
    """The scenario's temperature profile, or one line of ``error`` saying why there is none to use."""
    prof = getattr(scenario, "temperature", None)
    if prof is None:
        raise error(f"{label}: the thermal states need a temperature history and this path has none (a constant "
                    "temperature leaves every coefficient in one combination with its base term); take a thermal "
                    "scenario (thermal-ramp, thermal-plateaus-s16, ...) or a scenario TOML with a [temperature] table")
    return prof


@dataclass(frozen=True)
class KnownTemperature:
    """The filter's known temperature over an experiment of ``duration_s`` (module docstring): readings of
    ``profile`` every ``1 / sensor_rate_hz`` s from 0 to ``duration_s`` and their slope over ``rate_window_s``
    (None: the profile's exact ``T`` and ``dT/dt`` at every time asked)."""

    profile: object  # inscal.sim.thermal.TemperatureProfile
    duration_s: float
    sensor_rate_hz: float = 1.0
    rate_window_s: float | None = RATE_WINDOW_S

    def __post_init__(self):
        if not (math.isfinite(self.sensor_rate_hz) and self.sensor_rate_hz > 0):
            raise ValueError(f"temperature sensor rate must be > 0 Hz, got {self.sensor_rate_hz}")
        if self.rate_window_s is not None and not (math.isfinite(self.rate_window_s) and self.rate_window_s > 0):
            raise ValueError(f"the temperature-rate window must be > 0 s, got {self.rate_window_s}")
        if self.rate_window_s is not None:
            n = math.floor(self.duration_s * self.sensor_rate_hz + 1e-9) + 1
            t = np.arange(n) / self.sensor_rate_hz
            T, _ = self.profile.at(t)
            object.__setattr__(self, "_readings", (t, T, temperature_rate(t, T, self.rate_window_s)))

    @property
    def exact(self) -> bool:
        return self.rate_window_s is None

    def readings(self) -> Temperature:
        """The record's /temperature: one exact sensor at ``sensor_rate_hz`` (not with ``exact``)."""
        if self.exact:
            raise ValueError("the exact profile is no record's temperature: the filter reads a record's readings")
        t, T, _ = self._readings
        return Temperature(t, T[:, None], ("imu",))

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """``(T, dT/dt)`` [degC, degC/s] the filter takes at times ``t`` [s] (a sample's middle)."""
        t = np.asarray(t, float)
        if self.exact:
            return self.profile.at(t)
        tt, T, r = self._readings  # interpolated as the filter does (inscal.core.thermal.sample_temperature)
        return np.interp(t, tt, T), np.interp(t, tt, r)

    def grid_range(self, n: int, h: float) -> tuple[float, float, float]:
        """``(T_min, T_max, max |dT/dt|)`` [degC, degC, degC/s] at the mid-points ``(i + 0.5) h``, ``i = 0 .. n - 1``
        (in chunks of :data:`CHUNK`)."""
        lo, hi, rmax = math.inf, -math.inf, 0.0
        for i0 in range(0, int(n), CHUNK):
            T, r = self.at((np.arange(i0, min(int(n), i0 + CHUNK)) + 0.5) * h)
            lo, hi = min(lo, float(T.min())), max(hi, float(T.max()))
            rmax = max(rmax, float(np.max(np.abs(r))))
        return lo, hi, rmax

    def info(self, t_ref: float, n: int, h: float, label: str, error=ValueError) -> dict:
        """The temperature of ``n`` samples of ``h`` seconds: ``t_ref``, ``t_min``, ``t_max``, the span ``max |T -
        t_ref|`` (at least 1 degC, as the filter's prior), the largest rate [degC/min], the input and the profile
        (its JSON layout).  One line of ``error`` when ``t_ref`` lies outside the temperatures (the filter refuses it too)."""
        if not (isinstance(t_ref, (int, float)) and math.isfinite(t_ref)):
            raise error(f"t_ref must be a temperature in degC, got {t_ref!r}")
        lo, hi, rmax = self.grid_range(n, h)
        if not lo <= t_ref <= hi:
            raise error(f"{label}: t_ref {t_ref:g} degC lies outside the path's temperatures {lo:.4g} .. {hi:.4g} "
                        "degC (the thermal model would be extrapolated to its reference); give a t_ref inside them")
        src = ("the profile's exact T and dT/dt" if self.exact else
               f"the profile read at {self.sensor_rate_hz:g} Hz, dT/dt its {self.rate_window_s:g}-s least-squares slope")
        return {"t_ref": float(t_ref), "t_min": lo, "t_max": hi, "span": max(hi - t_ref, t_ref - lo, 1.0),
                "rate_max_c_per_min": 60.0 * rmax, "duration_s": float(self.duration_s), "input": src,
                "profile": json.loads(self.profile.to_json())}

    def steps(self, t_ref: float, k0: int, k1: int, T: float, n_sub: int) -> tuple[np.ndarray, np.ndarray]:
        """``(dT, rate)`` (k1 - k0, n_sub): ``T - t_ref`` [degC] and dT/dt [degC/s] at the sub-samples
        ``k T + (j + 0.5) T / n_sub`` of the filter steps ``k0 .. k1 - 1`` (the bound's grid)."""
        h = T / n_sub
        Tv, r = self.at(np.arange(k0, k1)[:, None] * T + (np.arange(n_sub)[None, :] + 0.5) * h)
        return np.ascontiguousarray(Tv - t_ref), np.ascontiguousarray(r)


def known_temperature(scenario, label: str, duration_s: float | None = None, rate_window_s: float | None = RATE_WINDOW_S,
                      error=ValueError) -> KnownTemperature:
    """The :class:`KnownTemperature` of a scenario (its profile, its temperature sensor's rate) over
    ``duration_s`` (default its path's)."""
    prof = need_profile(scenario, label, error)
    sensor = getattr(scenario, "temperature_sensor", None)
    try:
        return KnownTemperature(prof, float(scenario.path.duration if duration_s is None else duration_s),
                                float(getattr(sensor, "rate_hz", 1.0)), rate_window_s)
    except ValueError as exc:
        raise error(f"{label}: {exc}") from None


def polynomial_covariance(dT: np.ndarray, sigma: np.ndarray, order: int) -> np.ndarray:
    """``(X^T diag(sigma^-2) X)^-1`` of a polynomial of ``order`` in ``dT`` (n,) with per-point ``sigma`` (n,):
    the covariance of the coefficients of orders 0 .. order of a weighted least-squares fit."""
    dT = np.asarray(dT, float)
    if dT.size <= order:
        raise ValueError(f"a polynomial of order {order} needs more than {dT.size} temperatures")
    X = dT[:, None] ** np.arange(order + 1)[None, :] / np.asarray(sigma, float)[:, None]
    return np.linalg.inv(X.T @ X)


def plateau_sigma(base_sigma: dict, levels_c, t_ref: float, orders) -> dict:
    """The 1 sigma (SI per degC^k) of every polynomial coefficient the plateau method fits: ``base_sigma`` maps a
    thermal term (``gyro_bias``, ``gyro_scale_factor``, ``accel_bias``, ``accel_scale_factor``) to the sigma of
    its base parameter at each plateau, (3,) (the same at every plateau) or (n_levels, 3); ``orders`` the
    polynomial orders per term (:data:`~inscal.calibrate.systematic.states.THERMAL_TERM_NAMES` order; the dT/dt
    term is not fitted).  Returns ``{group: (3,) sigma}`` with the filter's group names (``gyro_bias_dT1``, ...)
    and the order 0 (the base term at ``t_ref``) under ``"<term>_dT0"``."""
    dT = np.asarray(levels_c, float) - float(t_ref)
    out = {}
    for term, o in zip(THERMAL_TERM_NAMES, orders):
        if term == "gyro_bias_rate" or not o:
            continue
        s = np.broadcast_to(np.asarray(base_sigma[term], float), (dT.size, 3))
        sig = np.empty((o + 1, 3))
        for a in range(3):
            sig[:, a] = np.sqrt(np.diag(polynomial_covariance(dT, s[:, a], o)))
        out[f"{term}_dT0"] = sig[0]
        for k in range(1, o + 1):
            out[thermal_group_name(term, k)] = sig[k]
    return out


def plateau_base_sigma(bound) -> dict:
    """The per-plateau sigma of each polynomial term's base parameter from the bound of the per-plateau path
    (:class:`inscal.plan.bound.Bound` of a 51-state set): ``{term: (3,) SI}`` (:data:`PLATEAU_STATES`)."""
    by = bound.by_label()
    return {term: np.array([by[f"{g}[{c}]"] for c in comps]) for term, (g, comps) in PLATEAU_STATES.items()}
