"""The measurement-uncertainty budget of a calibration (JCGM 100:2008, the GUM).

For every calibrated parameter component ``y`` the budget lists its inputs ``x_i``: the estimator's
own noise (Type A, the method's 1 sigma), the station's inputs (Type B, :mod:`inscal.uncertainty.station`)
with their sensitivity coefficients ``c_i = dy/dx_i`` (:mod:`inscal.uncertainty.sensitivity`), and, when the
unit has a history, the repeatability between runs (Type A).  The inputs are independent, so::

    u_i(y) = |c_i| u(x_i),    u_c(y)^2 = sum_i u_i(y)^2                    (GUM eq. 10, 5.1.3)

An input that acts independently at each of ``N`` stops (the table's angle, its encoder's rounding,
the wobble) has one coefficient per stop and axis; it enters as ``u(x) sqrt(sum_j c_j^2)`` and the
table shows that root-sum-square as its coefficient.  The effective degrees of freedom
(Welch-Satterthwaite, GUM eq. G.2b) and the coverage factor from Student's t (GUM G.3.4, G.6.4)::

    nu_eff = u_c^4 / sum_i (u_i^4 / nu_i),    k = t_{(1+p)/2}(nu_eff),    U = k u_c

When a non-normal input dominates (a rectangular rate error, say) the output is not normal and
``t`` over-covers (a rectangular one: 100 % instead of 95 %; GUM G.6.5-G.6.6).  So ``k`` is taken from
the distribution of the linear model itself (:func:`linear_coverage_factor`: the non-normal lines
convolved, the normal ones as one normal), times ``t_{(1+p)/2}(nu_eff) / z_{(1+p)/2}`` for a finite
``nu_eff``; with only normal inputs this is the GUM's ``t`` factor exactly.  The JCGM 101 Monte Carlo
of ``bench/budget_mc.py`` checks the result.

The chamber's temperature stability ``u(T)`` (the run's mean temperature within ``u(T)`` of the
temperature the result is stated at) enters through the unit's thermal model
``y(T) = y_0 + k_1 (T - T_ref) + k_2 (T - T_ref)^2 + k_3 (T - T_ref)^3`` (:mod:`inscal.core.thermal`)::

    c = dy/dT = k_1 + 2 k_2 (T - T_ref) + 3 k_3 (T - T_ref)^2             at the stated temperature T

(:func:`thermal_slope`, GUM 5.1.3; the model's own uncertainty enters at second order, ``u(k) u(T)``).
Where no model is known the input is not propagated and a note says so; a result that estimated its
own thermal model from the measured temperature has sensitivity 0 (:func:`temperature_measured`).

Repeatability from the database (GUM 4.2): the spread ``s`` of the unit's earlier results of a
component holds the estimator's noise once more, so only its excess enters,
``u_rep = sqrt(max(s^2 - mean(sigma^2), 0))`` with ``n - 1`` degrees of freedom.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats
from scipy.optimize import brentq

from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.core.thermal import THERMAL_TERMS, ThermalModel
from inscal.uncertainty.distributions import cdf, half_width
from inscal.uncertainty.station import INPUTS, Station

#: the coverage probability of the expanded uncertainty
COVERAGE = 0.95
#: the name of the estimator's own (Type A) input and of the repeatability between runs
ESTIMATOR = "estimator (Type A)"
REPEATABILITY = "repeatability (Type A)"
#: per-stop inputs and the coefficients they share (the encoder's rounding is an angle error at a stop)
STOP_COEFFICIENTS = {"table_angle": "table_angle", "encoder_resolution": "table_angle", "axis_wobble": "axis_wobble"}
#: the input the unit's thermal model propagates (:class:`TemperatureSensitivity`)
TEMPERATURE = "temperature_stability"
#: inputs no sensitivity is known for without more information: named in the budget's notes
NOT_PROPAGATED = {TEMPERATURE: "the unit's temperature sensitivity is not known to this calibration "
                               "(no thermal model): not propagated"}


@dataclass(frozen=True)
class TemperatureSensitivity:
    """How the chamber's temperature stability enters a budget: ``c`` the coefficients dy/dT (SI per K,
    flat over the budget's parameters; None: not propagated) and ``note`` (where they come from, or why
    there are none), which the budget's notes carry."""

    c: np.ndarray | None
    note: str


def thermal_slope(model: ThermalModel, name: str, t_c: float) -> np.ndarray:
    """``dy/dT`` of thermal term ``name`` at ``t_c`` [degC]: ``sum_k k c_k (t_c - T_ref)^(k-1)`` (SI per K,
    one value per component; zeros where the model holds the term constant)."""
    c = getattr(model, name)
    dT = float(t_c) - model.t_ref
    out = np.zeros(c.shape[1])
    for k in range(c.shape[0], 0, -1):  # Horner on the derivative: (3 c3 dT + 2 c2) dT + c1
        out = out * dT + k * c[k - 1]
    return out


def temperature_coefficients(model: ThermalModel, names, t_c: float) -> np.ndarray:
    """The coefficients ``dy/dT`` at ``t_c`` [degC] of the flat parameter vector of ``names`` (SI per K):
    :func:`thermal_slope` for the terms of :data:`inscal.core.thermal.THERMAL_TERMS`, 0 for the parameters
    the thermal model does not make depend on the temperature."""
    out = []
    for name in names:
        shape = PARAMETERS[name].shape
        n = int(np.prod(shape)) if shape else 1
        out.append(thermal_slope(model, name, t_c) if name in THERMAL_TERMS else np.zeros(n))
    return np.concatenate(out) if out else np.zeros(0)


def temperature_from_model(model: ThermalModel, names, t_c: float | None, source: str, where: str,
                           measured_c: float | None = None, u_t: float | None = None) -> TemperatureSensitivity:
    """The temperature coefficients of ``names`` from ``model`` (named by ``source``: "the thermal model of
    result 7 ...") at the stated temperature ``t_c`` [degC] (``where``: how it is known).  Without ``t_c`` a
    model linear in every term still gives its (constant) slopes; a curved one gives none.  ``measured_c``:
    the record's mean temperature when ``t_c`` is another one, noted when it lies more than ``3 u_t`` [K] (the
    station's stability) away: then the station's figure does not describe the run."""
    curved = [n for n in THERMAL_TERMS if n in names and model.order(n) > 1]
    if t_c is None and curved:
        return TemperatureSensitivity(None, f"{source} is curved ({', '.join(curved)}) but the temperature the "
                                            "result is stated at is not known (give --temperature-c, or a record with "
                                            "temperatures): not propagated")
    t_eval = model.t_ref if t_c is None else float(t_c)
    at = ("a linear model, its slopes hold at any temperature" if t_c is None
          else f"its slope dy/dT at {t_eval:g} degC ({where})")
    modelled = [n for n in THERMAL_TERMS if n in names and model.order(n) > 0]
    constant = [n for n in names if n not in modelled]
    note = (f"propagated through {source} (T_ref {model.t_ref:g} degC, range {model.t_min:g} .. {model.t_max:g} degC), "
            f"{at}: c = k1 + 2 k2 (T - T_ref) + 3 k3 (T - T_ref)^2 for {', '.join(modelled) or 'no parameter'}")
    if constant:
        note += f"; sensitivity 0 for {', '.join(constant)} (constant in that model)"
    if not model.t_min <= t_eval <= model.t_max:
        note += f"; {t_eval:g} degC lies outside the model's range: its slope is extrapolated"
    if t_c is not None and measured_c is not None and u_t is not None and abs(measured_c - t_c) > 3 * u_t:
        note += (f"; the record's mean temperature {measured_c:.4g} degC is {abs(measured_c - t_c):.3g} K from the "
                 f"stated {t_c:g} degC, more than 3 u(T): the station's stability does not describe this run")
    return TemperatureSensitivity(temperature_coefficients(model, names, t_eval), note)


def mean_temperature(temperature, sensor: str = "") -> float:
    """The time-weighted mean [degC] of a record's temperature readings (:class:`inscal.io.records.Temperature`):
    the thermal model's ``sensor`` when the record has it, else the mean of its sensors (trapezoids over the
    readings' own times; one reading: itself)."""
    y = temperature.series(sensor if sensor in temperature.sensors else "")
    t = np.asarray(temperature.time, float)
    if y.size < 2 or t[-1] <= t[0]:
        return float(np.mean(y))
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)) / (t[-1] - t[0]))


def temperature_measured(names, t_ref: float) -> TemperatureSensitivity:
    """A result that estimated its own thermal model from the record's measured temperature (thermal states)
    states its parameters at ``t_ref`` through that model: the chamber's stability moves the measured
    temperature, not the result (sensitivity 0; the sensor's own accuracy is another input)."""
    n = sum(int(np.prod(PARAMETERS[x].shape)) if PARAMETERS[x].shape else 1 for x in names)
    return TemperatureSensitivity(np.zeros(n), (
        f"sensitivity 0: this result estimated its thermal model with the parameters from the record's measured "
        f"temperature and states them at T_ref {t_ref:g} degC through that model, so the chamber's temperature "
        "wander is measured and compensated, not an error of the result (the temperature sensor's accuracy is)"))


@dataclass(frozen=True)
class Contribution:
    """One line of a component's budget (field units: ``unit`` for the input's value and ``u``, the
    parameter's unit for ``contribution``; ``sensitivity`` in parameter unit per input unit)."""

    input: str
    value: float | None
    unit: str
    distribution: str
    u: float
    sensitivity: float
    contribution: float
    share: float
    dof: float
    stops: int = 1
    value_unit: str = ""

    @classmethod
    def line(cls, input: str, value: float | None, unit: str, distribution: str, u: float, sensitivity: float,
             dof: float, stops: int = 1, value_unit: str = "") -> Contribution:
        """An input's line before it is combined: its ``contribution`` ``|sensitivity| u`` (GUM eq. 10); its
        ``share`` of ``u_c^2`` is set by :func:`combine`, 0 until then."""
        c = abs(sensitivity)
        return cls(input, value, unit, distribution, u, c, c * u, 0.0, dof, stops, value_unit)

    def to_dict(self) -> dict:
        """The line as JSON-able numbers (an infinite dof is ``None``)."""
        d = dict(self.__dict__)
        d["dof"] = None if math.isinf(self.dof) else self.dof
        return d


@dataclass(frozen=True)
class ComponentBudget:
    """The budget of one parameter component: ``u_c``, ``dof_eff``, ``k``, ``U`` in ``unit``."""

    parameter: str
    index: int
    unit: str
    value: float
    u_c: float
    dof_eff: float
    k: float
    U: float
    coverage: float
    contributions: tuple[Contribution, ...]

    @property
    def label(self) -> str:
        """``name[i]`` (a scalar parameter: its name)."""
        return self.parameter if not PARAMETERS[self.parameter].shape else f"{self.parameter}[{self.index}]"

    def to_dict(self) -> dict:
        """The component as JSON-able numbers."""
        d = {k: v for k, v in self.__dict__.items() if k != "contributions"}
        d["dof_eff"] = None if math.isinf(self.dof_eff) else self.dof_eff
        d["label"] = self.label
        d["contributions"] = [c.to_dict() for c in self.contributions]
        return d


@dataclass(frozen=True)
class Budget:
    """The budget of a calibration: per component (:class:`ComponentBudget`), with the station's
    name, the method and notes (inputs not propagated, checks).

    Parameters
    ----------
    station : str
        The station's name.
    method : str
        The calibration method (or what the budget before a run describes).
    coverage : float
        The coverage probability of every ``U``.
    components : tuple of ComponentBudget
        One budget per parameter component (:func:`combine`).
    notes : tuple of str, optional
        Inputs not propagated, checks.

    Examples
    --------
    >>> lines = [Contribution.line(ESTIMATOR, None, "ug", "normal", 3.0, 1.0, math.inf),
    ...          Contribution.line("gravity", 9.8, "mGal", "normal", 4.0, 1.0, math.inf)]
    >>> b = Budget("T-2", "n25", COVERAGE, (combine("accel_bias", 0, 0.0, lines),))
    >>> c = b.component("accel_bias[0]")
    >>> round(c.u_c, 9), [round(x.share, 2) for x in c.contributions]
    (5.0, [0.36, 0.64])
    >>> Budget.from_dict(b.to_dict()) == b
    True
    """

    station: str
    method: str
    coverage: float
    components: tuple[ComponentBudget, ...]
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The budget as a JSON document (what the database stores and ``--json`` prints)."""
        return {"station": self.station, "method": self.method, "coverage": self.coverage,
                "components": [c.to_dict() for c in self.components], "notes": list(self.notes)}

    @classmethod
    def from_dict(cls, d: dict) -> Budget:
        """The inverse of :meth:`to_dict`."""
        def inf(v):
            return math.inf if v is None else float(v)
        comps = []
        for c in d["components"]:
            lines = tuple(Contribution(**{**x, "dof": inf(x["dof"])}) for x in c["contributions"])
            comps.append(ComponentBudget(c["parameter"], int(c["index"]), c["unit"], float(c["value"]), float(c["u_c"]),
                                         inf(c["dof_eff"]), float(c["k"]), float(c["U"]), float(c["coverage"]), lines))
        return cls(d["station"], d["method"], float(d["coverage"]), tuple(comps), tuple(d.get("notes", ())))

    def component(self, label: str) -> ComponentBudget:
        """The component named ``label`` (``accel_scale_factor[0]``)."""
        for c in self.components:
            if c.label == label:
                return c
        raise KeyError(label)


def welch_satterthwaite(u, dof) -> float:
    """The effective degrees of freedom of ``sqrt(sum u_i^2)`` (GUM eq. G.2b); inputs with an
    infinite (or ``None``) dof add nothing to the denominator."""
    u = np.asarray(u, float)
    nu = np.array([math.inf if v is None else v for v in dof], float)
    uc4 = float(np.sum(u ** 2)) ** 2
    finite = np.isfinite(nu) & (u > 0)
    den = float(np.sum(u[finite] ** 4 / nu[finite]))
    return math.inf if den == 0.0 else uc4 / den


def coverage_factor(dof: float, p: float = COVERAGE) -> float:
    """``k`` for a coverage probability ``p`` with ``dof`` effective degrees of freedom (Student's t, GUM G.3.4)."""
    if math.isinf(dof):
        return float(stats.norm.ppf(0.5 + p / 2))
    return float(stats.t.ppf(0.5 + p / 2, dof))


#: points of the grid on which the non-normal contributions are convolved
GRID = 4001


def linear_coverage_factor(lines, p: float = COVERAGE) -> float:
    """``k`` of the linear model ``y = sum c_i x_i`` from the distributions themselves (GUM G.6.5-G.6.6,
    JCGM 101 on the linear model): the normal contributions combine into one normal of sigma ``s_N``;
    the others (``(distribution, half-width in y)``) are convolved on a grid (exact bin masses of their
    CDFs); ``P(|y| <= q) = p`` is solved and ``k = q / u_c``.  ``lines`` = ``(distribution, u_i(y))``."""

    s2 = sum(u * u for d, u in lines if d == "normal")
    other = [(d, half_width(d, u)) for d, u in lines if d != "normal" and u > 0]
    uc = math.sqrt(s2 + sum(u * u for d, u in lines if d != "normal"))
    if uc == 0.0:
        return coverage_factor(math.inf, p)
    if not other:
        return float(stats.norm.ppf(0.5 + p / 2))
    span = sum(a for _, a in other)
    h = 2.0 * span / (GRID - 1)
    mass = np.array([1.0])
    for d, a in other:
        n = int(math.ceil(a / h))
        edges = (np.arange(-n, n + 2) - 0.5) * h
        mass = np.convolve(mass, np.diff(cdf(d, edges, a)))
    x = (np.arange(mass.size) - (mass.size - 1) / 2) * h
    sN = math.sqrt(s2)

    def inside(q):
        if sN > 0:
            return float(np.sum(mass * (stats.norm.cdf((q - x) / sN) - stats.norm.cdf((-q - x) / sN))))
        return float(np.interp(q, x, np.cumsum(mass)) - np.interp(-q, x, np.cumsum(mass)))

    q = brentq(lambda q: inside(q) - p, 1e-9 * uc, 10.0 * uc, xtol=1e-6 * uc)
    return q / uc


def repeatability(values, sigmas) -> tuple[np.ndarray, float]:
    """``(u_rep, dof)`` per component from earlier results ``values`` (n_runs, n) and their sigmas
    (same shape, same unit): the excess of the between-run spread over the estimator's noise."""
    v, s = np.asarray(values, float), np.asarray(sigmas, float)
    n = v.shape[0]
    if n < 2:
        raise ValueError("repeatability needs at least two earlier results")
    spread = np.var(v, axis=0, ddof=1)
    noise = np.nanmean(s ** 2, axis=0)
    return np.sqrt(np.maximum(spread - np.nan_to_num(noise), 0.0)), float(n - 1)


def _factor(unit: str, kind: str) -> float:
    """SI per field unit (a temperature step: kelvin per ``unit``)."""
    return float(units.temperature_step_to_si(1.0, unit)) if kind == "temperature" else float(units.to_si(1.0, unit))


def combine(parameter: str, index: int, value_si: float, lines, coverage: float = COVERAGE) -> ComponentBudget:
    """One component's budget from its input ``lines`` (:class:`Contribution`, e.g. from :meth:`Contribution.line`;
    field units, sensitivity in parameter unit per input unit): ``u_c``, Welch-Satterthwaite's ``nu_eff`` and the
    coverage factor of the linear model (module docstring); each line's share of ``u_c^2`` filled in."""
    unit = PARAMETERS[parameter].unit
    ui = [c.contribution for c in lines]
    uc = math.sqrt(sum(x * x for x in ui))
    nu = welch_satterthwaite(ui, [c.dof for c in lines])
    # a per-stop input is a sum over its stops: normal; the others keep their distribution
    shape = linear_coverage_factor([(c.distribution if c.stops <= 1 else "normal", c.contribution) for c in lines],
                                   coverage)
    k = shape * coverage_factor(nu, coverage) / coverage_factor(math.inf, coverage)
    contribs = tuple(replace(c, share=(c.contribution * c.contribution / (uc * uc)) if uc > 0 else 0.0) for c in lines)
    return ComponentBudget(parameter, index, unit, float(units.from_si(value_si, unit)), uc, nu, k, k * uc, coverage,
                           contribs)


def budget(method: str, names, values_si: np.ndarray, sigma_si: np.ndarray, estimator_dof: float, station: Station,
           glob: dict[str, np.ndarray], per_stop: dict[str, np.ndarray], rep: tuple[np.ndarray, float] | None = None,
           coverage: float = COVERAGE, notes=(), temperature: TemperatureSensitivity | None = None) -> Budget:
    """The budget of a calibration: ``names`` the estimated parameters, ``values_si`` / ``sigma_si`` their
    flat estimate and 1 sigma (SI), ``glob`` / ``per_stop`` the coefficients of
    :class:`inscal.uncertainty.sensitivity.Sensitivities` (SI per SI), ``rep`` = ``(u_rep, dof)`` in SI,
    ``temperature`` the coefficients of the chamber's temperature stability (None: not propagated, with
    :data:`NOT_PROPAGATED`'s note).  A component whose sigma is NaN (held fixed by the method) has no budget."""
    if temperature is None:
        temperature = TemperatureSensitivity(None, NOT_PROPAGATED[TEMPERATURE])
    notes = list(notes) + [f"{TEMPERATURE}: {temperature.note}"]
    if temperature.c is not None and np.size(temperature.c) != np.size(values_si):
        raise ValueError(f"{TEMPERATURE}: {np.size(temperature.c)} coefficients for {np.size(values_si)} parameters")
    glob = {**glob, TEMPERATURE: temperature.c} if temperature.c is not None else glob
    comps, i = [], 0
    for name in names:
        shape = PARAMETERS[name].shape
        punit = PARAMETERS[name].unit
        pf = float(units.to_si(1.0, punit))
        for j in range(int(np.prod(shape)) if shape else 1):
            if not np.isfinite(sigma_si[i]):  # held fixed (a frame convention, unobservable): no uncertainty
                i += 1
                continue
            lines = [Contribution.line(ESTIMATOR, None, punit, "normal", float(sigma_si[i]) / pf, 1.0, estimator_dof)]
            for key, inp in station.inputs.items():
                if key == TEMPERATURE and temperature.c is None:  # not propagated: named in the notes
                    continue
                f = _factor(inp.uncertainty_unit, INPUTS[key].kind)
                if key in STOP_COEFFICIENTS:
                    c = per_stop[STOP_COEFFICIENTS[key]][:, :, i]
                    used = int(np.count_nonzero(c))
                    c_si = float(np.sqrt(np.sum(c * c)))
                else:
                    c_si, used = float(glob[key][i]), 1
                value = inp.field(inp.value, inp.unit) if INPUTS[key].needs_value else None
                lines.append(Contribution.line(key, value, inp.uncertainty_unit, inp.distribution, inp.u / f,
                                               c_si * f / pf, inp.dof, max(used, 1),
                                               inp.unit if value is not None else ""))
            if rep is not None:
                lines.append(Contribution.line(REPEATABILITY, None, punit, "normal", float(rep[0][i]) / pf, 1.0,
                                               rep[1]))
            comps.append(combine(name, j, float(values_si[i]), lines, coverage))
            i += 1
    return Budget(station.name, method, coverage, tuple(comps), tuple(notes))


def repeatability_of(calibrations, names) -> tuple[np.ndarray, float] | None:
    """:func:`repeatability` (SI, flat over ``names``) from a unit's earlier calibrations
    (:class:`inscal.lab.model.Calibration`, the same method) that hold every parameter of ``names``;
    None when fewer than two do."""
    vals, sigs = [], []
    for cal in calibrations:
        if not all(n in cal.parameters for n in names):
            continue
        v, s = zip(*(cal.parameters[n].si() for n in names))
        vals.append(np.concatenate([np.ravel(x) for x in v]))
        sigs.append(np.concatenate([np.ravel(x) for x in s]))
    if len(vals) < 2:
        return None
    return repeatability(np.array(vals), np.array(sigs))
