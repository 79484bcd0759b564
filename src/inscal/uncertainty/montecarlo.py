"""The JCGM 101 Monte Carlo of a window-mean calibration's uncertainty budget (propagation of distributions,
JCGM 101:2008 sections 5-8), beside the linear budget of :mod:`inscal.uncertainty.budget`.

The model is the calibration itself, where the linear budget may be doubtful: the station's errors
(:mod:`inscal.uncertainty.station`, each from its own distribution: a table-angle error and an encoder rounding at every
stop on both axes, a wobble tilt at every stop about east and north, one rate-scale error, the axes'
non-orthogonality, the site's gravity, latitude and height, the time base).  Every trial draws them all, writes
them whole into the measured window means (:func:`inscal.uncertainty.sensitivity.perturb`: rotation matrices, not their
linearisation, at the estimated geometry) and calibrates again.  The other lines of the budget enter as the
budget states them, ``c_i x_i`` with ``x_i`` from the line's own distribution (JCGM 101 6.4; a finite dof: the
scaled and shifted t of 6.4.9): the estimator's own Type A (the method's sigma, which for an ideal-input scheme
holds the systematic effect of its misfit beside the window noise: no draw of the noise alone would give it), the
repeatability between runs, a chamber's temperature through a thermal model.

Per component (JCGM 101 7.5-7.7): the average ``y~`` and standard deviation ``u(y~)`` of the trials, the
probabilistically symmetric 95 % coverage interval ``[y_low, y_high]`` (the 2.5 and 97.5 percentiles).

Validation of the linear budget (JCGM 101 section 8): with ``u_c`` written to ``n_dig`` significant digits
(one by default) as ``c x 10^l``, the numerical tolerance is ``delta = 10^l / 2`` (8.1.2); the budget's interval
``y +- U`` is validated when ``d_low = |y - U - y_low|`` and ``d_high = |y + U - y_high|`` are both within
``delta`` (8.2).  The Monte Carlo's own numerical accuracy ``s`` of each end point comes from the order statistics
that bracket it (:func:`endpoint_accuracy`: the distribution-free 95 % interval of a quantile, ranks
``N p +- 1.96 sqrt(N p (1 - p))``, its half-width over 1.96).  JCGM 101 7.9.4 takes it from the spread of ``h``
batches of at least ``100 / (1 - p)`` trials each; with a few thousand trials in all that spread rests on a few
batches and can come out small by chance, the order statistics cannot.  A difference within ``delta`` by less than
``2 s``, or beyond it by less than ``2 s``, is "undecided" (more trials), never "validated".

Trials are grouped in batches, each with its own child of one seed sequence (``SeedSequence(seed).spawn``), so the
result does not depend on how the batches are spread over processes (``map_fn``).  :func:`budget_monte_carlo` runs
them on the shared Monte Carlo engine (:func:`inscal.analysis.montecarlo.ordered_map`: this process, or a local
Dask cluster), with its progress on stderr; the engine's resumable studies (:func:`~inscal.analysis.montecarlo.run_study`,
one seed per run and a results folder) do not fit a budget computed inside ``inscal calibrate``: the batches' seeds
are laid out here, and the trials of an adaptive round are known only when the previous round is summarised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from inscal.analysis.montecarlo import ordered_map
from inscal.calibrate import calibrate
from inscal.calibrate.result import CalibrationResult, flatten
from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.core.progress import ProgressBar
from inscal.uncertainty import budget as gum
from inscal.uncertainty import distributions
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.station import Station

#: inputs a trial draws through the calibration itself (the others enter as their budget line)
SIMULATED = {"table_angle", "encoder_resolution", "axis_wobble", "table_rate", "axis_nonorthogonality", "gravity",
             "latitude", "height", "time_base"}
#: the default number of trials and of batches (JCGM 101 7.9: h batches for the numerical accuracy)
RUNS = 2000
BATCHES = 10
#: trials per round of the adaptive procedure
ROUND = 1000


@dataclass(frozen=True)
class ComponentMC:
    """One component's Monte Carlo (field units of the parameter): the calibration's estimate ``value``, the
    trials' average ``mean`` and standard deviation ``u``, the coverage interval ``[low, high]``, the linear
    budget's ``U`` with the validation (``d_low``, ``d_high``, ``delta``, the numerical accuracy ``s_num`` of the
    endpoints and the verdict ``validated``, ``not validated`` or ``undecided``)."""

    label: str
    unit: str
    value: float
    mean: float
    u: float
    low: float
    high: float
    U: float
    d_low: float
    d_high: float
    delta: float
    s_num: float
    verdict: str

    def to_dict(self) -> dict:
        """The component as JSON-able numbers."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class MonteCarloBudget:
    """The Monte Carlo of a budget: ``runs`` trials from ``seed`` in ``batches``, the coverage probability and the
    components (:class:`ComponentMC`), with notes."""

    runs: int
    seed: int
    batches: int
    coverage: float
    n_dig: int
    components: tuple[ComponentMC, ...]
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """As JSON (stored beside the linear budget, under its ``monte_carlo`` key)."""
        return {"runs": self.runs, "seed": self.seed, "batches": self.batches, "coverage": self.coverage,
                "n_dig": self.n_dig, "components": [c.to_dict() for c in self.components], "notes": list(self.notes)}

    @classmethod
    def from_dict(cls, d: dict) -> MonteCarloBudget:
        """The inverse of :meth:`to_dict`."""
        return cls(int(d["runs"]), int(d["seed"]), int(d["batches"]), float(d["coverage"]), int(d["n_dig"]),
                   tuple(ComponentMC(**c) for c in d["components"]), tuple(d.get("notes", ())))

    def counts(self) -> dict[str, int]:
        """How many components have each verdict."""
        out: dict[str, int] = {}
        for c in self.components:
            out[c.verdict] = out.get(c.verdict, 0) + 1
        return out


def draw_deviation(station: Station, n_windows: int, rng: np.random.Generator) -> S.Deviation:
    """One draw of the station's errors (SI), each input from its distribution
    (:meth:`inscal.uncertainty.station.StationInput.draw`): per stop and axis the table angle plus the encoder's rounding,
    per stop the wobble about east and north, once the rest."""
    angle = station["table_angle"].draw(rng, (n_windows, 2)) + station["encoder_resolution"].draw(rng, (n_windows, 2))
    tilt = station["axis_wobble"].draw(rng, (n_windows, 2))
    one = {k: float(station[k].draw(rng)) for k in ("table_rate", "axis_nonorthogonality", "gravity", "latitude",
                                                  "height", "time_base")}
    return S.Deviation(angle=angle, tilt=tilt, nonorthogonality=one["axis_nonorthogonality"],
                       rate_scale=one["table_rate"], gravity=one["gravity"], latitude=one["latitude"],
                       height=one["height"], time_base=one["time_base"])


def line_draw(distribution: str, u: float, dof: float, rng: np.random.Generator, size: int) -> np.ndarray:
    """Draws of a budget line's contribution: zero-centred, standard uncertainty ``u``, its distribution; a normal
    one with a finite ``dof`` is the scaled and shifted t of JCGM 101 6.4.9 (``u t_nu``)."""
    return distributions.draw(distribution, rng, size, u=u, dof=dof)


def _starts(names) -> dict[str, int]:
    """The flat index (over ``names``) where each parameter's components start."""
    start, k = {}, 0
    for n in names:
        start[n] = k
        shape = PARAMETERS[n].shape
        k += int(np.prod(shape)) if shape else 1
    return start


def _flat_index(names, budget: gum.Budget) -> list[int]:
    """The flat index (over ``names``) of every budget component."""
    start = _starts(names)
    return [start[c.parameter] + c.index for c in budget.components]


@dataclass(frozen=True)
class Trials:
    """What one batch of trials needs (picklable: it travels to worker processes)."""

    result: CalibrationResult
    station: Station
    options: dict

    def run(self, seed_seq: np.random.SeedSequence, n: int) -> np.ndarray:
        """``n`` trials: (n, n_flat) estimates of the result's parameters (SI), the table's own non-orthogonality
        taken out of ``gimbal_nonorthogonality`` (the method estimates the table's, the budget its error)."""
        rng = np.random.default_rng(seed_seq)
        res = self.result
        ws, geo, names = res.windows, S.Geometry.of(res), res.estimated
        nw = len(ws.windows)
        base = S.window_baseline(ws, geo)
        dth = _starts(names).get("gimbal_nonorthogonality")
        out = []
        for _ in range(n):
            dev = draw_deviation(self.station, nw, rng)
            r = calibrate(S.perturb(ws, geo, dev, base), res.method, uncertainty=False, **self.options)
            y = flatten(r.imu, r.gimbal, names)
            if dth is not None:
                y[dth] -= dev.nonorthogonality
            out.append(y)
        return np.array(out)


def endpoint_accuracy(y_sorted: np.ndarray, p: float) -> float:
    """The standard uncertainty of the ``p`` quantile of the sorted trials ``y_sorted`` (module docstring): the
    half-width of the distribution-free 95 % interval between its bracketing order statistics, over 1.96."""
    n = y_sorted.size
    half = 1.96 * math.sqrt(n * p * (1.0 - p))
    j = max(0, math.floor(n * p - half) - 1)
    k = min(n - 1, math.ceil(n * p + half) - 1)
    return float(y_sorted[k] - y_sorted[j]) / (2.0 * 1.96)


def tolerance(u: float, n_dig: int = 1) -> float:
    """JCGM 101 8.1.2: ``u`` as ``c x 10^l`` with ``c`` an ``n_dig``-digit integer; the tolerance ``10^l / 2``."""
    if not (u > 0 and math.isfinite(u)):
        return 0.0
    l_ = math.floor(math.log10(u)) - (n_dig - 1)
    if round(u / 10.0**l_) >= 10**n_dig:  # 9.97 with one digit is 10 x 10^0 = 1 x 10^1
        l_ += 1
    return 0.5 * 10.0**l_


def verdict(d_low: float, d_high: float, delta: float, s_num: float) -> str:
    """JCGM 101 8.2 with the Monte Carlo's numerical accuracy: validated when both differences are within
    ``delta`` by more than ``2 s_num``, not validated when one exceeds it by more, else undecided."""
    d = max(d_low, d_high)
    if d + 2.0 * s_num <= delta:
        return "validated"
    if d - 2.0 * s_num > delta:
        return "not validated"
    return "undecided"


def monte_carlo(result: CalibrationResult, station: Station, budget: gum.Budget, runs: int = RUNS, seed: int = 0,
                batches: int = BATCHES, n_dig: int = 1, options: dict | None = None, adaptive: bool = False,
                round_size: int = ROUND, map_fn: Callable = map,
                progress: Callable[[int, int], None] | None = None) -> MonteCarloBudget:
    """The JCGM 101 Monte Carlo (module docstring) of a window-mean calibration ``result`` (it keeps its windows)
    at ``station``, beside its linear ``budget`` (:func:`inscal.uncertainty.sensitivity.calibration_budget`); ``options``:
    the method's options the result was computed with.  ``runs`` trials in ``batches`` batches; ``adaptive``
    (JCGM 101 7.9): rounds of ``round_size`` trials (each in ``batches`` batches) until every component is decided
    (validated or not) or ``runs`` trials are done.  ``map_fn(fn, seeds, sizes)``: how the batches run (the builtin
    ``map`` in-process, a Dask client's, a process pool's; in order); ``progress(done, total)`` per batch."""
    if result.method not in S.WINDOW_METHODS or result.windows is None:
        raise ValueError(f"a Monte Carlo of the budget needs a window-mean method ({', '.join(S.WINDOW_METHODS)}) "
                         f"and its windows, not {result.method}")
    if not (isinstance(runs, int) and runs >= 100):
        raise ValueError(f"the Monte Carlo needs at least 100 trials, got {runs}")
    trials = Trials(result, station, dict(options or {}))
    ss = np.random.SeedSequence(seed)
    parts: list[np.ndarray] = []
    done = 0
    while True:
        n = min(runs - done, round_size if adaptive else runs)
        k = max(2, min(int(batches), n // 50))
        sizes = [n // k + (1 if b < n % k else 0) for b in range(k)]
        for part in map_fn(trials.run, ss.spawn(k), sizes):
            parts.append(part)
            done += part.shape[0]
            if progress:
                progress(done, runs)
        mc = _summary(result, budget, parts, seed, n_dig)
        if not adaptive or done >= runs or "undecided" not in mc.counts():
            return mc


def _summary(result: CalibrationResult, budget: gum.Budget, parts: list[np.ndarray], seed: int,
             n_dig: int) -> MonteCarloBudget:
    """Per component the Monte Carlo's figures and the validation (module docstring) from the batches ``parts``."""
    idx = _flat_index(result.estimated, budget)
    x0 = flatten(result.imu, result.gimbal, result.estimated)
    sizes = [p.shape[0] for p in parts]
    runs = sum(sizes)
    rng = np.random.default_rng([seed, runs])  # the budget lines' draws: one stream per trial count
    q = (1.0 - budget.coverage) / 2.0
    comps, notes = [], []
    linear_inputs = sorted({x.input for c in budget.components for x in c.contributions} - SIMULATED)
    if linear_inputs:
        notes.append(f"{', '.join(linear_inputs)}: drawn as the budget states them (c_i x_i)")
    for c, i in zip(budget.components, idx):
        f = float(units.to_si(1.0, c.unit))
        y = np.concatenate([p[:, i] for p in parts]) / f
        for x in c.contributions:
            if x.input not in SIMULATED and x.contribution > 0:
                y = y + line_draw(x.distribution, x.contribution, x.dof, rng, y.size)
        lo, hi = np.quantile(y, [q, 1.0 - q])
        ys = np.sort(y)
        s_num = max(endpoint_accuracy(ys, q), endpoint_accuracy(ys, 1.0 - q))
        value = float(x0[i] / f)
        d_low, d_high = abs(value - c.U - lo), abs(value + c.U - hi)
        delta = tolerance(c.u_c, n_dig)
        comps.append(ComponentMC(c.label, c.unit, value, float(y.mean()), float(y.std(ddof=1)), float(lo), float(hi),
                                 c.U, float(d_low), float(d_high), delta, s_num, verdict(d_low, d_high, delta, s_num)))
    return MonteCarloBudget(runs, seed, len(parts), budget.coverage, n_dig, tuple(comps), tuple(notes))




def budget_monte_carlo(result: CalibrationResult, station: Station, budget: gum.Budget, runs: int, seed: int = 0,
                       workers: int = 1, options: dict | None = None) -> MonteCarloBudget:
    """The adaptive JCGM 101 Monte Carlo (7.9) of a calibration's linear ``budget``, as ``inscal calibrate --mc``
    and ``inscal observability --crlb --station --mc`` run it.

    At most ``runs`` trials, in rounds of :data:`ROUND`, on the shared Monte Carlo engine
    (:func:`inscal.analysis.montecarlo.ordered_map`: this process for one worker, else a local Dask cluster of
    ``workers`` processes), the trials done on stderr (:class:`~inscal.core.progress.ProgressBar`: a line at every 10 % in a log).

    Parameters
    ----------
    result : inscal.calibrate.result.CalibrationResult
        A window-mean calibration that keeps its windows (:data:`inscal.uncertainty.sensitivity.WINDOW_METHODS`).
    station : inscal.uncertainty.station.Station
        The station whose errors every trial draws.
    budget : inscal.uncertainty.budget.Budget
        The linear budget of ``result`` at ``station`` that the Monte Carlo validates.
    runs : int
        The most trials (at least 100).
    seed : int, optional
        The seed of the trials' seed sequence.
    workers : int, optional
        1: in this process; more: a local Dask cluster of that many processes.
    options : dict, optional
        The method's options ``result`` was computed with.

    Returns
    -------
    MonteCarloBudget
        Per component the trials' mean, standard deviation, coverage interval and the validation verdict.

    Raises
    ------
    ValueError
        ``result`` is not of a window-mean method or keeps no windows; fewer than 100 trials.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> budget_monte_carlo(SimpleNamespace(method="systematic51"), None, None, 100)
    Traceback (most recent call last):
    ...
    ValueError: the Monte Carlo of the budget runs the window-mean methods (n25, six-position, twelve-position, \
joint), not systematic51: its site and clock inputs enter the filter linearly, and a thousand filter runs would take \
hours
    """
    if result.method not in S.WINDOW_METHODS:
        raise ValueError(f"the Monte Carlo of the budget runs the window-mean methods ({', '.join(S.WINDOW_METHODS)}),"
                         f" not {result.method}: its site and clock inputs enter the filter linearly, and a thousand "
                         "filter runs would take hours")
    with ordered_map(workers) as map_fn:
        with ProgressBar("JCGM 101 Monte Carlo", runs, every_s=None) as bar:
            return monte_carlo(result, station, budget, runs=runs, seed=seed, adaptive=True, options=options,
                               map_fn=map_fn, progress=lambda done, total: bar.update(
                                   done, total, line=f"budget Monte Carlo: {done} trials (at most {total})"))
