"""The thermal error model: biases, scale factors and misalignments that follow the temperature.

Neither paper models temperature (both calibrate at one; N25 notes its scheme is susceptible to
temperature drift).  This is the model every thermal-chamber calibration of a navigation-grade IMU
uses, written on top of the canonical error model (:mod:`inscal.core.error_model`)::

    eps(T)   = eps_0   + sum_k c_eps,k  dT^k  + D dT/dt      gyro bias; D: thermal-gradient (Shupe) term
    K_g(T)   = K_g,0   + sum_k c_Kg,k   dT^k                 gyro scale factors (diagonal)
    E_g(T)   = E_g,0   + c_Eg dT                             gyro misalignment angles (optional, linear)
    nabla(T) = nabla_0 + sum_k c_nab,k  dT^k                 accelerometer bias
    K_a(T)   = K_a,0   + sum_k c_Ka,k   dT^k                 accelerometer scale factors
    E_a(T)   = E_a,0   + c_Ea dT                             accelerometer misalignment angles (optional)

with ``dT = T - T_ref`` and ``k = 1 .. order`` (order chosen per term, at most 3).  The base values
(index 0) are those of the :class:`~inscal.core.error_model.ImuErrors` the model goes with, i.e. the
errors at ``T_ref`` and ``dT/dt = 0``; the g-sensitivity, the quadratic terms, the lever arms and the
time asynchrony do not depend on the temperature.

Every thermal term changes only ``M = (I + K)(I + E)`` and the bias of the measurement model
``N = M u + b`` (``u`` = the true rate plus the g-sensitivity for the gyros, the true specific force
plus the nonlinear and size-effect terms for the accelerometers), so the increments measured at T
and those the same IMU would give at ``T_ref`` carry the same ``u``::

    N(T) = M(T) M_0^-1 (N_0 - b_0 dt) + b(T) dt       forward (simulator): :meth:`ThermalModel.to_temperature`
    N_0  = M_0 M(T)^-1 (N(T) - b(T) dt) + b_0 dt      inverse (compensation): :meth:`ThermalModel.to_reference`

Both are exact (to round-off) whatever else the error model holds: compensating ``to_reference``'s
output with the base errors gives back what compensating data at ``T_ref`` would.

Temperatures are in degrees Celsius (:mod:`inscal.core.units`); the temperature of a sample is the
sensor's temperature at the middle of the sample interval (:func:`sample_temperature`), and ``dT/dt``
comes from a local least-squares slope over a window (:func:`temperature_rate`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from inscal.core import units
from inscal.core.error_model import ImuErrors, off_diagonal, rows_times

#: the terms that follow the temperature: name -> (ImuErrors attribute, unit kind, field unit of the
#: base quantity, components, largest order).  A coefficient of order k is in ``<unit>/degC^k``.
THERMAL_TERMS: dict[str, tuple[str, str, str, int, int]] = {
    "gyro_bias": ("gyro_bias", "rate", "deg/h", 3, 3),
    "gyro_scale_factor": ("gyro_scale_factor", "dimensionless", "ppm", 3, 3),
    "gyro_misalignment": ("gyro_misalignment", "angle", "arcsec", 6, 1),
    "accel_bias": ("accel_bias", "accel", "ug", 3, 3),
    "accel_scale_factor": ("accel_scale_factor", "dimensionless", "ppm", 3, 3),
    "accel_misalignment": ("accel_misalignment", "angle", "arcsec", 6, 1),
}
#: the gyro bias per rate of change of temperature, D [rad/s per degC/s = rad/degC]
RATE_TERM = ("gyro_bias_rate", "rate-per-temperature-rate", "deg/h/(degC/min)")
MAX_ORDER = 3
#: what compensation does with a temperature outside the calibrated range
OUT_OF_RANGE = ("warn", "clamp", "error")
#: default window of the least-squares temperature slope [s]
RATE_WINDOW_S = 60.0


class ThermalError(ValueError):
    """Temperature data or a thermal model that cannot be used, with the reason (one line)."""


def _coef(value, name: str, size: int, max_order: int) -> np.ndarray:
    a = np.array(value, dtype=float)
    if a.size == 0:
        a = np.zeros((0, size))
    if a.ndim == 1 and a.shape[0] == size:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != size:
        raise ValueError(f"thermal {name}: expected shape (order, {size}), got {np.shape(value)}")
    if a.shape[0] > max_order:
        raise ValueError(f"thermal {name}: order {a.shape[0]} > {max_order}, the largest this term takes")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"thermal {name}: contains NaN or infinite values")
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class ThermalModel:
    """Thermal coefficients (SI per degC^k; row k-1 of each array is the coefficient of ``dT^k``),
    the reference temperature and the range the model is valid in [degC]."""

    t_ref: float = 20.0
    t_min: float = -math.inf
    t_max: float = math.inf
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gyro_scale_factor: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gyro_misalignment: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    accel_scale_factor: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    accel_misalignment: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    gyro_bias_rate: np.ndarray = field(default_factory=lambda: np.zeros(3))  # D [rad/degC]
    out_of_range: str = "warn"
    #: the temperature sensor that drives the model ("": the mean of the record's sensors)
    sensor: str = ""

    def __post_init__(self):
        for name in ("t_ref", "t_min", "t_max"):
            v = float(getattr(self, name))
            if math.isnan(v) or (name == "t_ref" and not math.isfinite(v)):
                raise ValueError(f"thermal {name}: must be a number of degC, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        if not self.t_min <= self.t_ref <= self.t_max:
            raise ValueError(f"thermal range [{self.t_min:g}, {self.t_max:g}] degC does not contain t_ref "
                             f"{self.t_ref:g} degC")
        if self.out_of_range not in OUT_OF_RANGE:
            raise ValueError(f"thermal out_of_range: {self.out_of_range!r}, expected one of {', '.join(OUT_OF_RANGE)}")
        for name, (_, _, _, size, max_order) in THERMAL_TERMS.items():
            object.__setattr__(self, name, _coef(getattr(self, name), name, size, max_order))
        d = np.array(self.gyro_bias_rate, dtype=float)
        if d.shape == ():
            d = np.full(3, float(d))
        if d.shape != (3,) or not np.all(np.isfinite(d)):
            raise ValueError(f"thermal gyro_bias_rate: expected 3 finite values, got {self.gyro_bias_rate!r}")
        d.setflags(write=False)
        object.__setattr__(self, "gyro_bias_rate", d)

    def replace(self, **kw) -> ThermalModel:
        """A copy with the fields given in ``kw`` replaced (:func:`dataclasses.replace`)."""
        return dataclasses.replace(self, **kw)

    # -- structure
    def order(self, name: str) -> int:
        """The polynomial order of term ``name`` (0: it does not follow the temperature)."""
        return int(getattr(self, name).shape[0])

    @property
    def orders(self) -> dict[str, int]:
        """The polynomial order of every thermal term, by name (0: the term is constant)."""
        return {name: self.order(name) for name in THERMAL_TERMS}

    @property
    def has_rate(self) -> bool:
        """Whether the gyro bias has a non-zero dT/dt term."""
        return bool(np.any(self.gyro_bias_rate))

    @property
    def has_misalignment(self) -> bool:
        """Whether either triad's misalignment follows the temperature."""
        return bool(np.any(self.gyro_misalignment) or np.any(self.accel_misalignment))

    @property
    def is_zero(self) -> bool:
        """Whether the model changes nothing (every coefficient zero)."""
        return not (self.has_rate or any(np.any(getattr(self, n)) for n in THERMAL_TERMS))

    # -- evaluation
    def delta(self, name: str, dT) -> np.ndarray:
        """``sum_k c_k dT^k`` of term ``name`` for temperature differences ``dT`` (...,): shape (..., size)."""
        c = getattr(self, name)
        dT = np.asarray(dT, dtype=float)
        out = np.zeros(dT.shape + (c.shape[1],))
        for k in range(c.shape[0] - 1, -1, -1):  # Horner: ((c3 dT + c2) dT + c1) dT
            out = (out + c[k]) * dT[..., None]
        return out

    def clamp(self, T) -> np.ndarray:
        """``T`` limited to the valid range."""
        return np.clip(np.asarray(T, dtype=float), self.t_min, self.t_max)

    def outside(self, T) -> int:
        """How many of the temperatures ``T`` lie outside the valid range."""
        T = np.asarray(T, dtype=float)
        return int(np.count_nonzero((T < self.t_min) | (T > self.t_max)))

    def effective(self, T) -> np.ndarray:
        """The temperatures the model is evaluated at under its out-of-range policy: clamped with
        ``clamp``, unchanged with ``warn`` (the caller reports :meth:`outside`), refused with ``error``."""
        T = np.asarray(T, dtype=float)
        if self.out_of_range == "clamp":
            return self.clamp(T)
        if self.out_of_range == "error":
            n = self.outside(T)
            if n:
                raise ThermalError(f"{n} sample(s) at {float(np.min(T)):.2f} .. {float(np.max(T)):.2f} degC, outside "
                                   f"the calibrated range {self.t_min:g} .. {self.t_max:g} degC")
        return T

    def errors_at(self, base: ImuErrors, T: float, dTdt: float = 0.0) -> ImuErrors:
        """The IMU errors at one temperature ``T`` [degC] and rate ``dTdt`` [degC/s] (no policy applied)."""
        dT = float(T) - self.t_ref
        kw = {}
        for name, (attr, *_rest) in THERMAL_TERMS.items():
            kw[attr] = getattr(base, attr) + self.delta(name, dT)
        kw["gyro_bias"] = kw["gyro_bias"] + self.gyro_bias_rate * float(dTdt)
        return base.replace(**kw)

    def _matrices(self, base: ImuErrors, dT: np.ndarray, triad: str):
        """Per-sample scale factors (n, 3), misalignment matrices (n, 3, 3) or None, and biases (n, 3)."""
        k = getattr(base, f"{triad}_scale_factor") + self.delta(f"{triad}_scale_factor", dT)
        E = None
        if self.order(f"{triad}_misalignment"):
            dE = self.delta(f"{triad}_misalignment", dT)
            E = np.broadcast_to(off_diagonal(getattr(base, f"{triad}_misalignment")), dT.shape + (3, 3)).copy()
            for idx, (i, j) in enumerate(((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))):
                E[..., i, j] += dE[..., idx]
        b = getattr(base, f"{triad}_bias") + self.delta(f"{triad}_bias", dT)
        return k, E, b

    def _inputs(self, dt, T, dTdt):
        """``(T - T_ref, dT/dt or zeros, dt broadcastable against (n, 3))`` of :meth:`to_temperature` and
        :meth:`to_reference`."""
        dT = np.asarray(T, dtype=float) - self.t_ref
        rate = np.zeros_like(dT) if dTdt is None else np.asarray(dTdt, dtype=float)
        dtc = np.asarray(dt, dtype=float)
        return dT, rate, dtc[..., None] if dtc.ndim else dtc

    def to_temperature(self, base: ImuErrors, dt, dth, dv, T, dTdt=None) -> tuple[np.ndarray, np.ndarray]:
        """Forward model: increments ``(dth, dv)`` (n, 3) measured by ``base`` (the IMU at ``T_ref``) ->
        those the IMU gives at temperatures ``T`` (n,) and rates ``dTdt`` (n,) [degC/s]."""
        dT, rate, dtc = self._inputs(dt, T, dTdt)
        out = []
        for triad, N, M0 in (("gyro", dth, base.M_g), ("accel", dv, base.M_a)):
            N = np.asarray(N, dtype=float)
            u = rows_times(np.linalg.inv(M0), N - getattr(base, f"{triad}_bias") * dtc)
            k, E, b = self._matrices(base, dT, triad)
            if E is None:
                v = rows_times(np.eye(3) + off_diagonal(getattr(base, f"{triad}_misalignment")), u)
            else:
                v = u + np.einsum("...ij,...j->...i", E, u)
            if triad == "gyro":
                b = b + self.gyro_bias_rate * rate[..., None]
            out.append((1.0 + k) * v + b * dtc)
        return out[0], out[1]

    def to_reference(self, base: ImuErrors, dt, dth, dv, T, dTdt=None) -> tuple[np.ndarray, np.ndarray]:
        """Inverse model: increments measured at temperatures ``T`` (n,) and rates ``dTdt`` -> those the
        IMU would give at ``T_ref`` (compensate them with ``base`` afterwards)."""
        dT, rate, dtc = self._inputs(dt, T, dTdt)
        out = []
        for triad, N, M0 in (("gyro", dth, base.M_g), ("accel", dv, base.M_a)):
            N = np.asarray(N, dtype=float)
            k, E, b = self._matrices(base, dT, triad)
            if triad == "gyro":
                b = b + self.gyro_bias_rate * rate[..., None]
            v = (N - b * dtc) / (1.0 + k)
            if E is None:
                u = rows_times(np.linalg.inv(np.eye(3) + off_diagonal(getattr(base, f"{triad}_misalignment"))), v)
            else:
                u = np.linalg.solve(np.eye(3) + E, v[..., None])[..., 0]
            out.append(rows_times(M0, u) + getattr(base, f"{triad}_bias") * dtc)
        return out[0], out[1]


# ----------------------------------------------------------------------------- field units
def thermal_to_field(model: ThermalModel, sigma: dict | None = None) -> dict:
    """``{"t_ref", "t_min", "t_max", "out_of_range", "sensor", "terms": {name: [{"order", "value", "unit"
    [, "sigma"]}, ...]}}`` in field units (``sigma``: name -> (order, size) SI 1-sigma arrays)."""
    terms = {}
    for name, (_, kind, unit, _, _) in THERMAL_TERMS.items():
        c = getattr(model, name)
        rows = []
        for k in range(c.shape[0]):
            fu = units.per_degree_unit(unit, k + 1)
            row = {"order": k + 1, "value": units.from_si(c[k], unit).tolist(), "unit": fu}
            if sigma is not None and name in sigma:
                row["sigma"] = units.from_si(np.asarray(sigma[name], dtype=float)[k], unit).tolist()
            rows.append(row)
        if rows:
            terms[name] = rows
    if model.has_rate or (sigma is not None and RATE_TERM[0] in sigma):
        row = {"order": 1, "value": units.from_si(model.gyro_bias_rate, RATE_TERM[2]).tolist(), "unit": RATE_TERM[2]}
        if sigma is not None and RATE_TERM[0] in sigma:
            row["sigma"] = units.from_si(np.asarray(sigma[RATE_TERM[0]], dtype=float).reshape(3), RATE_TERM[2]).tolist()
        terms[RATE_TERM[0]] = [row]
    return {"t_ref": model.t_ref, "t_min": model.t_min, "t_max": model.t_max, "out_of_range": model.out_of_range,
            "sensor": model.sensor, "terms": terms}


def _coefficient_si(name: str, value, row: dict, unit: str, kind: str, order: int):
    """A coefficient (or its sigma) of ``row`` in SI: the dT/dt term in its own unit, the others per degree^order."""
    if name == RATE_TERM[0]:
        return units.to_si(value, row.get("unit", unit), kind)
    return units.thermal_to_si(value, row.get("unit", units.per_degree_unit(unit, order)), kind, order)


def thermal_from_field(d: dict) -> tuple[ThermalModel, dict]:
    """Inverse of :func:`thermal_to_field`: the model and the 1-sigma arrays it carries (SI)."""
    if not isinstance(d, dict):
        raise ValueError("thermal: expected a table")
    unknown = set(d) - {"t_ref", "t_min", "t_max", "out_of_range", "sensor", "terms"}
    if unknown:
        raise ValueError(f"thermal: unknown keys {sorted(unknown)}")
    terms = d.get("terms", {})
    if not isinstance(terms, dict):
        raise ValueError("thermal.terms: expected a table of terms")
    bad = set(terms) - set(THERMAL_TERMS) - {RATE_TERM[0]}
    if bad:
        raise ValueError(f"thermal: unknown term(s) {sorted(bad)}; known: {', '.join([*THERMAL_TERMS, RATE_TERM[0]])}")
    kw, sig = {}, {}
    for name, rows in terms.items():
        if isinstance(rows, dict):
            rows = [rows]
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise ValueError(f"thermal.terms.{name}: expected a list of {{order, value, unit}} tables")
        if name == RATE_TERM[0]:
            kind, unit, size, max_order = RATE_TERM[1], RATE_TERM[2], 3, 1
        else:
            _, kind, unit, size, max_order = THERMAL_TERMS[name]
        orders = sorted(int(r.get("order", 0)) for r in rows)
        if orders != list(range(1, len(rows) + 1)) or len(rows) > max_order:
            raise ValueError(f"thermal.terms.{name}: orders {orders}, expected 1 .. n with n <= {max_order}")
        vals, sigs = np.zeros((len(rows), size)), np.full((len(rows), size), np.nan)
        for r in rows:
            extra = set(r) - {"order", "value", "unit", "sigma"}
            if extra:
                raise ValueError(f"thermal.terms.{name}: unknown keys {sorted(extra)}")
            k = int(r["order"])
            try:
                vals[k - 1] = np.broadcast_to(_coefficient_si(name, r["value"], r, unit, kind, k), (size,))
                if "sigma" in r:
                    sigs[k - 1] = np.broadcast_to(_coefficient_si(name, r["sigma"], r, unit, kind, k), (size,))
            except units.UnitError as exc:
                raise ValueError(f"thermal.terms.{name} order {k}: {exc}") from None
            except (KeyError, TypeError, ValueError) as exc:
                raise ValueError(f"thermal.terms.{name} order {k}: bad value ({exc})") from None
        if name == RATE_TERM[0]:
            kw[name] = vals[0]
        else:
            kw[name] = vals
        if np.any(np.isfinite(sigs)):
            sig[name] = sigs[0] if name == RATE_TERM[0] else sigs
    def num(key, default):
        v = d.get(key, default)
        try:
            return float(v)
        except (TypeError, ValueError):
            raise ValueError(f"thermal.{key}: not a number of degC ({v!r})") from None
    model = ThermalModel(t_ref=num("t_ref", 20.0), t_min=num("t_min", -math.inf), t_max=num("t_max", math.inf),
                         out_of_range=str(d.get("out_of_range", "warn")), sensor=str(d.get("sensor", "")), **kw)
    return model, sig


# ----------------------------------------------------------------------------- temperature data
def select_sensor(values, names, sensor: str = "") -> np.ndarray:
    """The temperature series that drives the model: column ``sensor`` of ``values`` (M, S), or the mean
    of the columns when ``sensor`` is empty."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    names = list(names)
    if sensor:
        if sensor not in names:
            raise ThermalError(f"no temperature sensor {sensor!r} in the record (it has {', '.join(names) or 'none'})")
        return values[:, names.index(sensor)]
    return values.mean(axis=1)


def temperature_rate(time, T, window_s: float = RATE_WINDOW_S) -> np.ndarray:
    """dT/dt [degC/s] at each time of a temperature series: the least-squares slope of the samples within
    ``window_s / 2`` of it (a first-order Savitzky-Golay filter on any time grid).  Sensor noise and
    quantization average out; a ramp is returned exactly; a bend is smoothed over the window."""
    t = np.asarray(time, dtype=float)
    y = np.asarray(T, dtype=float)
    n = t.shape[0]
    if n < 2:
        return np.zeros(n)
    t0 = t[0]
    tc = t - t0
    cs = lambda a: np.concatenate([[0.0], np.cumsum(a)])  # noqa: E731
    S1, St, Sy, Stt, Sty = cs(np.ones(n)), cs(tc), cs(y), cs(tc * tc), cs(tc * y)
    lo = np.searchsorted(t, t - 0.5 * window_s, side="left")
    hi = np.searchsorted(t, t + 0.5 * window_s, side="right")
    m = S1[hi] - S1[lo]
    st, sy, stt, sty = St[hi] - St[lo], Sy[hi] - Sy[lo], Stt[hi] - Stt[lo], Sty[hi] - Sty[lo]
    den = m * stt - st * st
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (m * sty - st * sy) / den
    # a window with one sample (a sensor slower than the window): the slope between the neighbours
    few = ~(den > 1e-12 * np.maximum(1.0, m * stt))
    if np.any(few):
        slope[few] = np.interp(t[few], 0.5 * (t[1:] + t[:-1]), np.diff(y) / np.diff(t))
    return slope


def sample_temperature(sample_time, rate_hz: float, temp_time, T, dTdt=None,
                       where: str = "record") -> tuple[np.ndarray, np.ndarray]:
    """Temperature and its rate for each IMU sample: the values at the middle of each sample interval
    (``time - 0.5/rate``), linearly interpolated from the sensor's own grid.  A temperature series that
    starts or ends more than one of its own steps (or one second) away from the samples is refused."""
    ts = np.asarray(sample_time, dtype=float) - 0.5 / rate_hz
    tt = np.asarray(temp_time, dtype=float)
    y = np.asarray(T, dtype=float)
    if tt.ndim != 1 or y.shape != tt.shape or tt.shape[0] < 1:
        raise ThermalError(f"{where}: temperature time and values must be 1-D of one length, got {tt.shape} and {y.shape}")
    if not (np.all(np.isfinite(tt)) and np.all(np.isfinite(y))):
        raise ThermalError(f"{where}: temperature has NaN or infinite values")
    if tt.shape[0] > 1 and np.any(np.diff(tt) <= 0):
        k = int(np.argmax(np.diff(tt) <= 0))
        raise ThermalError(f"{where}: temperature time does not increase at sample {k + 1} (t = {tt[k + 1]} s)")
    step = float(np.max(np.diff(tt))) if tt.shape[0] > 1 else 0.0
    slack = max(step, 1.0)
    if ts.size and (ts[0] < tt[0] - slack or ts[-1] > tt[-1] + slack):
        raise ThermalError(f"{where}: temperature covers {tt[0]:.3f} .. {tt[-1]:.3f} s, the IMU samples "
                           f"{ts[0]:.3f} .. {ts[-1]:.3f} s")
    if dTdt is None:
        dTdt = temperature_rate(tt, y)
    return np.interp(ts, tt, y), np.interp(ts, tt, np.asarray(dTdt, dtype=float))
