"""History, repeatability and drift of a unit's calibrations, parameter component by component.

For one component with calibrations i = 1..n at times t_i (months of 365.25/12 days since the
first; the date of each calibration's record), values y_i and reported 1 sigma s_i (field units):

- repeatability: the spread between calibrations against the within-calibration sigma, the Birge
  ratio ``R = sqrt(chi2 / (n - 1))`` with ``chi2 = sum w_i (y_i - ybar_w)^2``, ``w_i = 1 / s_i^2``,
  ``ybar_w`` the weighted mean (R ~ 1: the calibrations agree within their sigma; R >> 1: the unit
  moves, or its sigma are too small), with the chi2 p-value; also the plain sample standard
  deviation and the RMS of the s_i;
- drift rate: the weighted least-squares line ``y = a + b (t - tbar_w)`` (Aitken's estimator),
  ``b = sum w (t - tbar_w) y / S_tt``, ``sigma_b = 1 / sqrt(S_tt)``, ``S_tt = sum w (t - tbar_w)^2``,
  in field units per month; ``sigma_b`` is from the reported sigma (the line's own Birge ratio is
  reported beside it, not folded in);
- flags at ``k`` (default 3), each a two-sided test of a Gaussian statistic under "the unit is
  stable and its sigma are right":
  ``drift``: n >= 3 and ``|b| > k sigma_b`` (the same as ``|b span| > k sigma_b span``: the change
  over the history against its sigma);
  ``step``: n >= 2 and the newest calibration differs from the one before by more than
  ``k sqrt(s_n^2 + s_{n-1}^2)``.
  Each test raises a false alarm with probability ``erfc(k / sqrt 2)`` (0.27 % at k = 3); a unit
  with m tests expects ``m erfc(k / sqrt 2)`` of them by chance (:attr:`History.expected_false_alarms`).

A calibration whose sigma is not a finite positive number (a component held fixed) is left out
of that component's history.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import numpy as np

from inscal.core.stats import chi2_sf
from inscal.io.jsonfile import to_jsonable
from inscal.lab.model import Calibration, iso

#: the month of the drift rates [days]: a Julian year over 12
MONTH_DAYS = 365.25 / 12
DEFAULT_K = 3.0


def tail(k: float) -> float:
    """P(``|z|`` > k) of a standard Gaussian: the false-alarm probability of one test.

    Parameters
    ----------
    k : float
        The threshold.

    Returns
    -------
    float
        ``erfc(k / sqrt 2)``.

    Examples
    --------
    >>> from inscal import lab
    >>> round(lab.tail(3.0), 5)
    0.0027
    """
    return math.erfc(k / math.sqrt(2.0))


def months_between(t0: dt.datetime, t: dt.datetime) -> float:
    """The time from ``t0`` to ``t`` in months of :data:`MONTH_DAYS` days."""
    return (t - t0).total_seconds() / 86400.0 / MONTH_DAYS


@dataclass(frozen=True)
class ComponentDrift:
    """The history of one parameter component: repeatability, drift and step, with their flags.

    Values in the field ``unit``; rates per month (:data:`MONTH_DAYS`).

    Parameters
    ----------
    name, label, unit : str
        The parameter, the component's label, its field unit.
    ids : tuple of int
        The results, oldest first.
    months : numpy.ndarray
        Their records' dates, months after the first.
    values, sigma : numpy.ndarray
        The values and their 1 sigma.
    n : int
        The number of calibrations.
    span_months : float
        The span of the history.
    mean, mean_sigma : float
        The weighted mean and its sigma.
    spread, within_sigma : float
        The scatter of the values and their typical 1 sigma.
    repeatability_ratio, repeatability_p : float
        The scatter against the sigma, and the chi^2 test's p-value.
    rate, rate_sigma, rate_z : float
        The fitted drift per month, its sigma and z.
    line_ratio : float
        The misfit of the drift line against the sigma.
    step, step_sigma, step_z : float
        The last step, its sigma and z.
    flags : tuple of str
        The flags raised (``drift``, ``step``).
    tests : int
        The number of tests made.

    Examples
    --------
    >>> from inscal import lab
    >>> db, ids = lab.example_history("calib.sqlite", (0.010, 0.020, 0.030))  # a month between results
    >>> c = lab.unit_history(db, "IMU-1").components[0]
    >>> c.label, c.n, round(c.rate, 4), c.flags  # deg/h a month
    ('gyro_bias[x]', 3, 0.0101, ('step', 'drift'))
    >>> db.close()
    """

    name: str
    label: str
    unit: str
    ids: tuple[int, ...]
    months: np.ndarray
    values: np.ndarray
    sigma: np.ndarray
    n: int
    span_months: float
    mean: float
    mean_sigma: float
    spread: float
    within_sigma: float
    repeatability_ratio: float
    repeatability_p: float
    rate: float
    rate_sigma: float
    rate_z: float
    line_ratio: float
    step: float
    step_sigma: float
    step_z: float
    flags: tuple[str, ...]
    tests: int

    @property
    def change(self) -> float:
        """The drift over the history, ``rate * span``."""
        return self.rate * self.span_months

    def to_json(self) -> dict:
        """The component's history as JSON: values and 1 sigma over time, repeatability, drift rate and flags."""
        return to_jsonable({
            "label": self.label, "unit": self.unit, "n": self.n, "ids": list(self.ids),
            "months": self.months, "values": self.values, "sigma": self.sigma, "span_months": self.span_months,
            "mean": self.mean, "mean_sigma": self.mean_sigma,
            "repeatability": {"spread": self.spread, "within_sigma": self.within_sigma,
                              "ratio": self.repeatability_ratio, "p_value": self.repeatability_p},
            "drift": {"rate_per_month": self.rate, "rate_sigma": self.rate_sigma, "z": self.rate_z,
                      "change_over_span": self.change, "change_sigma": self.rate_sigma * self.span_months,
                      "line_ratio": self.line_ratio},
            "last_step": {"change": self.step, "sigma": self.step_sigma, "z": self.step_z},
            "flags": list(self.flags), "tests": self.tests})


def component_drift(name: str, label: str, unit: str, ids, months, values, sigma, k: float = DEFAULT_K) -> ComponentDrift:
    """The repeatability, drift and flags (see the module docstring) of one component's calibrations.

    Parameters
    ----------
    name, label, unit : str
        The parameter's name (``gyro_bias``), the label of the component (``gyro_bias[x]``) and the
        field unit the values are in.
    ids : sequence of int
        The ids of the results, oldest first.
    months : array_like
        Their records' dates, months after the first.
    values, sigma : array_like
        The values and their 1 sigma.
    k : float
        The flag threshold (``|z| > k``).

    Returns
    -------
    ComponentDrift
        The component's history and flags.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal import lab
    >>> c = lab.component_drift("gyro_bias", "gyro_bias[x]", "deg/h", (1, 2, 3), np.array([0.0, 6.0, 12.0]),
    ...                         np.array([0.010, 0.0105, 0.0095]), np.full(3, 0.001))
    >>> c.flags, round(c.repeatability_ratio, 2)
    ((), 0.5)
    """
    months, values, sigma = (np.asarray(a, dtype=float) for a in (months, values, sigma))
    ok = np.isfinite(months) & np.isfinite(values) & np.isfinite(sigma) & (sigma > 0)
    ids = tuple(int(i) for i, good in zip(ids, ok) if good)
    t, y, s = months[ok], values[ok], sigma[ok]
    n = int(y.size)
    nan = float("nan")
    mean = mean_sigma = spread = within = ratio = rp = nan
    rate = rate_sigma = rate_z = line_ratio = nan
    step = step_sigma = step_z = nan
    flags, tests = [], 0
    if n >= 1:
        w = 1.0 / s**2
        mean = float(np.sum(w * y) / np.sum(w))
        mean_sigma = float(1.0 / math.sqrt(np.sum(w)))
        within = float(np.sqrt(np.mean(s**2)))
    if n >= 2:
        chi2 = float(np.sum(w * (y - mean) ** 2))
        spread = float(np.std(y, ddof=1))
        ratio = math.sqrt(chi2 / (n - 1))
        rp = chi2_sf(chi2, n - 1)
        step = float(y[-1] - y[-2])
        step_sigma = float(math.hypot(s[-1], s[-2]))
        step_z = step / step_sigma
        tests += 1
        if abs(step_z) > k:
            flags.append("step")
        tbar = float(np.sum(w * t) / np.sum(w))
        stt = float(np.sum(w * (t - tbar) ** 2))
        if stt > 0:
            rate = float(np.sum(w * (t - tbar) * y) / stt)
            rate_sigma = 1.0 / math.sqrt(stt)
            rate_z = rate / rate_sigma
            if n >= 3:
                res = y - mean - rate * (t - tbar)
                line_ratio = math.sqrt(float(np.sum(w * res**2)) / (n - 2))
                tests += 1
                if abs(rate_z) > k:
                    flags.append("drift")
    span = float(t[-1] - t[0]) if n else 0.0
    return ComponentDrift(name, label, unit, ids, t, y, s, n, span, mean, mean_sigma, spread, within, ratio, rp, rate,
                          rate_sigma, rate_z, line_ratio, step, step_sigma, step_z, tuple(flags), tests)


@dataclass(frozen=True)
class History:
    """A unit's calibrations of one method over time, with every component's :class:`ComponentDrift`.

    Parameters
    ----------
    serial : str
        The unit.
    method : str
        The method.
    k : float
        The flag threshold (``|z| > k``).
    ids : tuple of int
        The results, oldest first (one per session).
    dates : tuple of datetime.datetime
        Their records' dates.
    components : tuple of ComponentDrift
        One per parameter component.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> h = lab.unit_history(db, "IMU-1")
    >>> h.ids == (first, second), len(h.components), h.flagged
    (True, 3, [])

    >>> db.close()
    """

    serial: str
    method: str
    k: float
    ids: tuple[int, ...]
    dates: tuple[dt.datetime, ...]
    components: tuple[ComponentDrift, ...]

    @property
    def flagged(self) -> list[ComponentDrift]:
        """The components that raised a drift or step flag."""
        return [c for c in self.components if c.flags]

    @property
    def tests(self) -> int:
        """The number of tests made over all components (to weigh the flags expected by chance)."""
        return sum(c.tests for c in self.components)

    @property
    def expected_false_alarms(self) -> float:
        """The number of flags a stable unit with right sigma raises by chance: ``tests * erfc(k / sqrt 2)``."""
        return self.tests * tail(self.k)

    def to_json(self) -> dict:
        """The unit's history as ``inscal db history --json`` prints it, per parameter and component."""
        params: dict[str, dict] = {}
        for c in self.components:
            params.setdefault(c.name, {"unit": c.unit, "components": []})["components"].append(c.to_json())
        return {"serial": self.serial, "method": self.method, "k": self.k, "month_days": MONTH_DAYS,
                "calibrations": [{"id": i, "date": iso(d)} for i, d in zip(self.ids, self.dates)],
                "flagged": [{"label": c.label, "flags": list(c.flags), "rate_z": to_jsonable(c.rate_z),
                             "step_z": to_jsonable(c.step_z)} for c in self.flagged],
                "tests": self.tests, "expected_false_alarms": self.expected_false_alarms, "parameters": params}


def history(calibrations: list[Calibration], serial: str, method: str, k: float = DEFAULT_K) -> History:
    """The :class:`History` of a unit's calibrations of one method: one point per session, its newest result.

    Parameters
    ----------
    calibrations : list of Calibration
        One unit's calibrations of one method, oldest first.
    serial, method : str
        The unit and the method, as the history names them.
    k : float
        The flag threshold (``|z| > k``).

    Returns
    -------
    History
        The components' repeatability, drift and flags.

    Raises
    ------
    ValueError
        ``k`` not positive.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> h = lab.history(lab.calibrations(db, "IMU-1"), "IMU-1", "six-position")
    >>> h.components[0].label, round(h.components[0].step, 4)
    ('gyro_bias[x]', 0.002)

    >>> db.close()
    """
    if not (math.isfinite(k) and k > 0):
        raise ValueError(f"k must be > 0, got {k}")
    by_session: dict[int, Calibration] = {}
    for c in calibrations:
        if c.method == method:
            by_session[c.session.id] = c  # ordered by date then id: the newest of a session wins
    cals = sorted(by_session.values(), key=lambda c: (c.date, c.id))
    if not cals:
        return History(serial, method, float(k), (), (), ())
    t0 = cals[0].date
    months = np.array([months_between(t0, c.date) for c in cals])
    ids = [c.id for c in cals]
    names = [n for c in cals for n in c.parameters]
    comps = []
    for name in dict.fromkeys(names):
        have = [c.parameters.get(name) for c in cals]
        first = next(p for p in have if p is not None)
        for j, label in enumerate(first.labels):
            vals = np.array([np.ravel(p.value)[j] if p is not None else np.nan for p in have])
            sig = np.array([np.ravel(p.sigma)[j] if p is not None else np.nan for p in have])
            comps.append(component_drift(name, label, first.unit, ids, months, vals, sig, k))
    return History(serial, method, float(k), tuple(ids), tuple(c.date for c in cals), tuple(comps))
