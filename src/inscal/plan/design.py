"""Design of a calibration path from its Cramér-Rao bound.

Problem.  Find a sequence of turntable moves (axis, angle, rate, dwell) of a given total
duration that minimises a function of the bound (:mod:`inscal.plan.bound`) of the
systematic filter's parameters, within the turntable's limits.  Objectives, on the bound
``sigma_i`` normalised by a target ``t_i`` per parameter:

* ``worst-normalised``: ``max_i sigma_i / t_i`` (every parameter at least as good as its
  target when <= 1);
* ``weighted``: ``sum_i (sigma_i / t_i)^2 / n`` (a mean squared normalised bound).

With a station (a setup with ``consider`` inputs, :mod:`inscal.plan.consider`) ``sigma_i`` is the combined
standard uncertainty the path promises, the bound with the site's and the clock's contributions
(:attr:`~inscal.plan.bound.Bound.combined_sigma`, GUM eq. 10), and so are the targets of S16's own path: a path
is then not rewarded for a precision the station's gravity or latitude takes away again.

Targets (``targets=``): ``"s16-path"`` (default): the bound of S16's own 1-hour path
(:func:`inscal.core.turntable.s16_table1`, 5 deg/s, 180 s dwells) under the same site, gimbal and
noise; ``"s16-table2"``: the S16 Table 2 "after filter" figures for its four groups
(g-sensitivity 2e-4 deg/h/g, nonlinearity 1.3 and cross-coupling 1.5 ug/g^2, lever arm 0.01
cm) and the S16-path bound for the others.

Search space (:class:`Limits`).  A path is an initial dwell (``initial_dwell_s``, the
coarse alignment's) and a list of genes ``(axis, angle, rate fraction, dwell weight)``: the axis
among ``axes``; the angle among :data:`ANGLES_DEG` (turns of 90 deg and whole revolutions,
either sense); the cruise rate ``fraction * max_rate``; one trapezoidal acceleration
``max_accel`` for the whole path.  Dwells share the time left after the moves: ``dwell_i =
min_dwell + (budget - moves - initial - n min_dwell) w_i / sum w``, so every candidate lasts
exactly the budget (moves that do not fit are dropped from the end).  Angle limits
(``outer_range``/``inner_range``, absolute gimbal angles, and ``cable_wrap``, the largest net
rotation of each axis from its start) are kept by reversing a move that would leave them (and
dropping it if the reverse does too).

Search (:func:`design`).  A seeded (mu + lambda) evolutionary search: an initial population of
the S16 Table 1 and PSINS-19 sequences compressed to the budget plus random sequences;
each generation, ``lambda`` children by one-point crossover and one to three mutations (axis,
angle, rate, dwell weight, insert, delete, swap), evaluated in parallel (Dask: a LocalCluster
by default, a scheduler address, or in-process with ``scheduler="none"``), and the ``mu``
best of parents and children survive.  ``candidates`` is the total number of evaluations.
One evaluation of a 30-minute path costs ~30 ms (bench/bench_crlb.py).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from inscal.core import units
from inscal.core.parallel import start_client
from inscal.core.turntable import (
    AXES,
    DEG,
    Move,
    PathError,
    RotationPath,
    psins19,
    s16_table1,
)
from inscal.plan.bound import MAX_STEPS, Bound, Setup, bound_bytes, bound_steps, evaluate, make_setup
from inscal.plan.rows import BoundError
from inscal.sim.scenarios import S16_TABLE2

#: angles of a move [deg] (either sense): 45-deg positions excite the cross-coupling (f_i f_j) and put
#: a tilted gyro's g-sensitivity into the well-observed tilt channel; whole turns the lever arms
ANGLES_DEG = (45.0, 90.0, 135.0, 180.0, 270.0, 360.0, 720.0)
ANGLE_P = (0.15, 0.35, 0.1, 0.15, 0.05, 0.12, 0.08)
#: S16 Table 2 "after filter" figures (field units of the groups)
TABLE2_GROUPS = tuple(S16_TABLE2)
OBJECTIVES = ("worst-normalised", "weighted")
#: weight of the mean normalised bound added to the worst one when the search ranks candidates
TIE_BREAK = 0.05
TARGETS = ("s16-path", "s16-table2")
#: most filter steps of a whole search, candidates x steps of one candidate's bound (10^9: about 7 h of
#: CPU with 51 states on one core, inscal.plan.bound.STEP_SECONDS)
MAX_SEARCH_STEPS = 10**9
#: memory of one member of the population: its genes and the genes its path kept (6.6 kB measured with
#: 40 genes), its bound and the bookkeeping
MEMBER_BYTES = 16e3


class DesignError(ValueError):
    """Options the path design cannot use."""


@dataclass(frozen=True)
class Limits:
    """Turntable limits and the search's fixed choices (SI)."""

    axes: tuple[str, ...] = AXES
    max_rate: float = 10.0 * DEG  # [rad/s]
    max_accel: float = 10.0 * DEG  # [rad/s^2]
    min_rate_fraction: float = 0.25
    outer_range: tuple[float, float] | None = None  # absolute angle [rad]
    inner_range: tuple[float, float] | None = None
    cable_wrap: float | None = None  # largest |net rotation| of each axis from its start [rad]
    min_dwell: float = 5.0  # [s]
    initial_dwell: float = 60.0  # [s]
    max_moves: int = 40

    def __post_init__(self):
        if not self.axes or any(a not in AXES for a in self.axes):
            raise DesignError(f"axes must be among {', '.join(AXES)}, got {self.axes}")
        for n in ("max_rate", "max_accel"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v > 0):
                raise DesignError(f"{n} must be > 0, got {v}")
        if not 0 < self.min_rate_fraction <= 1:
            raise DesignError("min_rate_fraction must be in (0, 1]")
        for n in ("min_dwell", "initial_dwell"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v >= 0):
                raise DesignError(f"{n} must be >= 0 s, got {v}")
        for n in ("outer_range", "inner_range"):
            r = getattr(self, n)
            if r is not None and not (len(r) == 2 and r[0] < 0 < r[1] or len(r) == 2 and r[0] <= 0 <= r[1] and r[0] < r[1]):
                raise DesignError(f"{n} must be [lo, hi] with lo <= 0 <= hi, lo < hi (the start is 0), got {r}")
        if self.cable_wrap is not None and not (math.isfinite(self.cable_wrap) and self.cable_wrap >= 90 * DEG):
            raise DesignError(f"cable_wrap must be >= 90 deg, got {self.cable_wrap / DEG:g} deg")
        if self.max_moves < 1:
            raise DesignError("max_moves must be >= 1")

    def range_of(self, ax: int) -> tuple[float, float]:
        """The allowed angle range [rad] of axis ``ax`` (0 outer, 1 inner): its own range and the cable wrap."""
        lo, hi = -math.inf, math.inf
        r = self.outer_range if ax == 0 else self.inner_range
        if r is not None:
            lo, hi = max(lo, r[0]), min(hi, r[1])
        if self.cable_wrap is not None:
            lo, hi = max(lo, -self.cable_wrap), min(hi, self.cable_wrap)
        return lo, hi

    def to_dict(self) -> dict:
        """The turntable limits as JSON, in degrees and seconds."""
        f = lambda r: None if r is None else [r[0] / DEG, r[1] / DEG]  # noqa: E731
        return {"axes": list(self.axes), "max_rate_dps": self.max_rate / DEG, "max_accel_dps2": self.max_accel / DEG,
                "min_rate_fraction": self.min_rate_fraction, "outer_range_deg": f(self.outer_range),
                "inner_range_deg": f(self.inner_range),
                "cable_wrap_deg": None if self.cable_wrap is None else self.cable_wrap / DEG,
                "min_dwell_s": self.min_dwell, "initial_dwell_s": self.initial_dwell, "max_moves": self.max_moves}


# ----------------------------------------------------------------------------- genome -> path
Gene = tuple  # (axis index, angle [deg], rate fraction, dwell weight)


def build_path(genes: list, budget: float, limits: Limits, name: str = "designed") -> tuple[RotationPath, list]:
    """The path of ``genes`` lasting exactly ``budget`` seconds (module docstring), and the genes
    it kept (after the angle-limit repair and the time budget)."""
    th = [0.0, 0.0]
    kept = []
    for ax, ang, rf, w in genes:
        if len(kept) >= limits.max_moves:
            break
        if AXES[ax] not in limits.axes:
            continue
        lo, hi = limits.range_of(ax)
        a = float(ang)
        if not lo - 1e-9 <= th[ax] + a * DEG <= hi + 1e-9:
            a = -a
            if not lo - 1e-9 <= th[ax] + a * DEG <= hi + 1e-9:
                continue
        th[ax] += a * DEG
        kept.append((ax, a, float(min(1.0, max(limits.min_rate_fraction, rf))), float(max(w, 1e-3))))
    acc = limits.max_accel

    def move_time(a_deg, rf):
        A, W = abs(a_deg) * DEG, rf * limits.max_rate
        return A / W + W / acc if A >= W * W / acc else 2.0 * math.sqrt(A / acc)

    while True:
        t_moves = sum(move_time(a, rf) for _, a, rf, _ in kept)
        free = budget - limits.initial_dwell - t_moves - limits.min_dwell * len(kept)
        if free >= 0 or not kept:
            break
        kept.pop()
    if not kept:
        raise DesignError(f"a budget of {budget:g} s leaves no time for a single move")
    wsum = sum(g[3] for g in kept)
    moves = []
    for k, (ax, a, rf, w) in enumerate(kept):
        dwell = limits.min_dwell + free * w / wsum
        moves.append(Move(AXES[ax], a * DEG, rf * limits.max_rate, dwell, label=f"design #{k + 1}"))
    return RotationPath(name, tuple(moves), accel=acc, initial_dwell=limits.initial_dwell, closed=False), kept


def _genes_of(path: RotationPath, limits: Limits) -> list:
    """Genes of an existing path's moves (rates clipped to the limits, dwell weights = its dwells)."""
    out = []
    for m in path.moves:
        if m.axis == "none":
            continue
        out.append((AXES.index(m.axis), m.angle / DEG, min(1.0, m.rate / limits.max_rate), max(m.dwell, 1.0)))
    return out


def seed_genomes(limits: Limits) -> list:
    """Structured starting points: S16 Table 1 and PSINS-19 (their sequences, dwell weights equal,
    so the budget compresses them), and S16's sequence after 45-deg offsets of one or both axes."""
    s16 = _genes_of(s16_table1(rate_dps=5.0), limits)
    fast = [(ax, a, 1.0, w) for ax, a, _, w in s16]
    out = [s16, fast, _genes_of(psins19(), limits)]
    out.append([(0, 45.0, 1.0, 1.0)] + fast)
    out.append([(0, 45.0, 1.0, 1.0), (1, 45.0, 1.0, 1.0)] + fast)
    out.append(fast + fast)
    return out


def random_genes(rng: np.random.Generator, limits: Limits, n: int | None = None) -> list:
    """A random move sequence (8 to 30 moves unless ``n`` is given, at most ``limits.max_moves``) drawn from ``rng``."""
    axes = [AXES.index(a) for a in limits.axes]
    n = int(rng.integers(8, 31)) if n is None else n
    return [_random_gene(rng, axes, limits) for _ in range(min(n, limits.max_moves))]


def _random_gene(rng, axes, limits) -> Gene:
    ang = float(rng.choice(ANGLES_DEG, p=ANGLE_P)) * float(rng.choice([-1.0, 1.0]))
    rf = float(rng.uniform(limits.min_rate_fraction, 1.0)) if rng.random() < 0.5 else 1.0
    return (int(rng.choice(axes)), ang, rf, float(rng.lognormal(0.0, 0.7)))


def mutate(genes: list, rng: np.random.Generator, limits: Limits) -> list:
    """A copy of ``genes`` changed by one to three random operations drawn from ``rng``, within ``limits``:
    insert, delete or swap moves, or change one move's axis, angle, rate or dwell."""
    g = list(genes)
    axes = [AXES.index(a) for a in limits.axes]
    for _ in range(int(rng.integers(1, 4))):
        op = rng.integers(7) if g else 4
        if op == 4 or not g:  # insert
            if len(g) < limits.max_moves:
                g.insert(int(rng.integers(len(g) + 1)), _random_gene(rng, axes, limits))
            continue
        i = int(rng.integers(len(g)))
        ax, ang, rf, w = g[i]
        if op == 0:
            ax = int(rng.choice(axes))
        elif op == 1:
            ang = float(rng.choice(ANGLES_DEG, p=ANGLE_P)) * float(rng.choice([-1.0, 1.0]))
        elif op == 2:
            rf = float(np.clip(rf * math.exp(rng.normal(0.0, 0.3)), limits.min_rate_fraction, 1.0))
        elif op == 3:
            w = float(w * math.exp(rng.normal(0.0, 0.6)))
        elif op == 5:
            if len(g) > 1:
                del g[i]
            continue
        else:
            j = int(rng.integers(len(g)))
            g[i], g[j] = g[j], g[i]
            continue
        g[i] = (ax, ang, rf, w)
    return g


def crossover(a: list, b: list, rng: np.random.Generator) -> list:
    """A child of two move sequences: the head of ``a`` and the tail of ``b``, cut at random points drawn from ``rng``."""
    if not a or not b:
        return list(a or b)
    i = int(rng.integers(0, len(a) + 1))
    j = int(rng.integers(0, len(b) + 1))
    return list(a[:i]) + list(b[j:])


# ----------------------------------------------------------------------------- objective
@dataclass(frozen=True)
class Objective:
    """``kind`` over the bound normalised by ``targets`` (SI, per parameter)."""

    kind: str
    targets: np.ndarray
    source: str  # "s16-path" | "s16-table2"
    reference: np.ndarray  # bound of S16's 1-hour path under the same setup (SI)
    mask: np.ndarray  # parameters that count
    groups: tuple[str, ...]  # their groups

    def __post_init__(self):
        if self.kind not in OBJECTIVES:
            raise DesignError(f"objective must be one of {', '.join(OBJECTIVES)}, got {self.kind!r}")

    def value(self, sigma: np.ndarray) -> float:
        """The objective of the bound ``sigma``: the worst ratio to the targets (``worst-normalised``), or
        the mean squared ratio.
        """
        x = (np.asarray(sigma) / self.targets)[self.mask]
        return float(np.max(x)) if self.kind == "worst-normalised" else float(np.mean(x * x))

    def score(self, sigma: np.ndarray) -> float:
        """What the search minimises: :meth:`value`, with a tie-break for ``worst-normalised``
        (``+ TIE_BREAK * mean``), so the other parameters keep improving while the worst one is
        held by physics (e.g. the heading-only trace of the g-sensitivity)."""
        v = self.value(sigma)
        if self.kind == "worst-normalised":
            v += TIE_BREAK * float(np.mean((np.asarray(sigma) / self.targets)[self.mask]))
        return v


def s16_reference(setup: Setup) -> Bound:
    """The bound of S16's own 1-hour path (S16 Table 1) under ``setup``."""
    return evaluate(setup, s16_table1(), keep_history=False)


def parse_groups(spec, setup: Setup) -> tuple[str, ...]:
    """``None``/``"all"``: every group; ``"table2"``: the four S16 Table 2 groups; else a comma list."""
    have = tuple(dict.fromkeys(setup.groups))
    if spec is None or spec == "all":
        return have
    names = TABLE2_GROUPS if spec == "table2" else tuple(s.strip() for s in str(spec).split(",") if s.strip())
    bad = [g for g in names if g not in have]
    if bad or not names:
        raise DesignError(f"unknown group(s) {bad or spec!r}; groups of this state set: {', '.join(have)} "
                          "(or all, table2)")
    return names


def make_objective(setup: Setup, kind: str = "worst-normalised", targets: str = "s16-path",
                   groups=None) -> Objective:
    """The objective (module docstring) over the parameters of ``groups`` (:func:`parse_groups`)."""
    if targets not in TARGETS:
        raise DesignError(f"targets must be one of {', '.join(TARGETS)}, got {targets!r}")
    gs = parse_groups(groups, setup)
    mask = np.array([g in gs for g in setup.groups])
    ref = s16_reference(setup).combined_sigma
    t = ref.copy()
    if targets == "s16-table2":
        for k, g in enumerate(setup.groups):
            if g in S16_TABLE2:
                t[k] = units.to_si(S16_TABLE2[g], setup.units_[k])
    return Objective(kind, t, targets, ref, mask, gs)


def group_summary(sigma: np.ndarray, setup: Setup, reference: np.ndarray) -> dict:
    """Per group (field units): RMS bound (``sigma``: the bound, or the combined uncertainty with a station), RMS of
    the reference (S16 path), worst ratio to it, and the S16 Table 2 figure where there is one."""
    out: dict[str, dict] = {}
    for k, g in enumerate(setup.groups):
        u = setup.units_[k]
        d = out.setdefault(g, {"unit": u, "b": [], "r": [], "ratio": []})
        d["b"].append(float(units.from_si(sigma[k], u)))
        d["r"].append(float(units.from_si(reference[k], u)))
        d["ratio"].append(float(sigma[k] / reference[k]))
    res = {}
    for g, d in out.items():
        rms_b = float(np.sqrt(np.mean(np.square(d["b"]))))
        rms_r = float(np.sqrt(np.mean(np.square(d["r"]))))
        res[g] = {"unit": d["unit"], "bound_rms": rms_b, "s16_path_rms": rms_r, "rms_ratio": rms_b / rms_r,
                  "worst_ratio": float(np.max(d["ratio"])), "s16_table2": S16_TABLE2.get(g)}
    return res


# ----------------------------------------------------------------------------- size
@dataclass(frozen=True)
class SearchSize:
    """What a search asks for (:func:`search_size`)."""

    steps: float  # filter steps of one candidate's bound
    candidates: int
    members: int  # population held at once: the survivors and one generation of children
    history_bytes: float  # the history of the final bound (the only bound kept over time)
    population_bytes: float

    @property
    def total_steps(self) -> float:
        """The filter steps of the whole search (steps per candidate times candidates)."""
        return self.steps * self.candidates

    @property
    def memory(self) -> float:
        """Bytes that grow with the options (the search's own, beside the interpreter and the kernels)."""
        return self.history_bytes + self.population_bytes


def search_size(minutes: float, candidates: int, population: int, setup: Setup, workers: int = 1) -> SearchSize:
    """The size of :func:`design`'s search (``workers``: evaluators in parallel, which set the children
    per generation), before anything runs."""
    steps = bound_steps(60.0 * float(minutes), 1.0 / setup.T)
    mu = max(2, min(int(population), int(candidates) // 2))
    members = mu + max(4, 4 * int(workers))
    return SearchSize(steps, int(candidates), members, bound_bytes(setup, steps), members * MEMBER_BYTES)


# ----------------------------------------------------------------------------- evaluation
def evaluate_genes(setup: Setup, objective: Objective, budget: float, limits: Limits, batch: list) -> list:
    """Objective and bound of each genome of ``batch`` (a Dask task; also used in-process)."""
    out = []
    for genes in batch:
        try:
            path, kept = build_path(genes, budget, limits)
            b = evaluate(setup, path, keep_history=False)
            out.append((objective.score(b.combined_sigma), b.combined_sigma, kept))
        except (DesignError, BoundError, PathError):
            out.append((math.inf, None, genes))
    return out


class _Evaluator:
    """Evaluate batches in-process or on Dask (LocalCluster of ``workers`` processes, or a
    scheduler address)."""

    def __init__(self, scheduler: str | None, workers: int):
        self.client = None
        self.cluster = None
        if scheduler in ("none", "synchronous", "sync"):
            return

        self.client, self.cluster = start_client(scheduler, max(1, workers), 10, DesignError)
        self.n = max(1, sum(self.client.nthreads().values()))

    @property
    def workers(self) -> int:
        return 1 if self.client is None else self.n

    def setup(self, *args):
        self.args = args
        if self.client is not None:
            self.futs = [self.client.scatter(a, broadcast=True) for a in args]

    def run(self, genomes: list) -> list:
        if self.client is None:
            return evaluate_genes(*self.args, genomes)
        k = self.workers
        batches = [genomes[i::k] for i in range(k) if genomes[i::k]]
        futs = [self.client.submit(evaluate_genes, *self.futs, b, pure=False) for b in batches]
        res = self.client.gather(futs)
        out = [None] * len(genomes)
        for i, r in enumerate(res):
            for j, v in enumerate(r):
                out[i + j * k] = v
        return out

    def close(self):
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


@dataclass
class DesignResult:
    """A designed path with its bound, the objective and its value, the value of S16's own path for
    comparison, the time budget and the turntable limits.
    """
    path: RotationPath
    bound: Bound
    objective: Objective
    value: float
    reference_value: float  # the objective of S16's own path (compressed to nothing: its real 1 h)
    budget_s: float
    limits: Limits
    evaluations: int
    generations: int
    seed: int
    seconds: float
    trace: list = field(default_factory=list)  # best score (Objective.score) after each generation

    def groups(self) -> dict:
        """The bound per S16 Table 2 group against S16's own path."""
        return group_summary(self.bound.combined_sigma, self.bound.setup, self.objective.reference)

    def to_dict(self) -> dict:
        """The design as ``inscal design --json`` prints it."""
        g = self.groups()
        t2 = {k: {"bound_rms": g[k]["bound_rms"], "s16_path_rms": g[k]["s16_path_rms"],
                  "worst_ratio_to_s16_path": g[k]["worst_ratio"], "s16_table2": S16_TABLE2[k],
                  "meets_s16_path": g[k]["worst_ratio"] <= 1.0, "meets_s16_path_rms": g[k]["rms_ratio"] <= 1.0}
              for k in TABLE2_GROUPS if k in g}
        return {"objective": {"kind": self.objective.kind, "targets": self.objective.source,
                              "groups": list(self.objective.groups), "value": self.value,
                              "s16_path_value": self.reference_value},
                "budget_s": self.budget_s, "duration_s": self.path.duration, "moves": len(self.path.moves),
                "limits": self.limits.to_dict(), "evaluations": self.evaluations, "generations": self.generations,
                "seed": self.seed, "seconds": self.seconds, "trace": self.trace, "groups": g, "table2_groups": t2,
                "path": self.path.to_dict(), "bound": self.bound.to_dict()}


def design(minutes: float, states: str = "51", objective: str = "worst-normalised", targets: str = "s16-path",
           groups=None, limits: Limits | None = None, seed: int = 0, candidates: int = 256, population: int = 12,
           scheduler: str | None = "none", workers: int = 2, setup: Setup | None = None,
           progress: Callable[[int, int, float], None] | None = None, name: str | None = None) -> DesignResult:
    """Search a path of ``minutes`` minutes (module docstring).  ``setup``: the bound's site,
    gimbal and noise (default :func:`~inscal.plan.bound.make_setup` of ``states``: S16 site
    and noise); ``progress(done, total, best)`` after each generation."""
    t0 = time.perf_counter()
    if not (isinstance(minutes, (int, float)) and math.isfinite(minutes) and minutes > 0):
        raise DesignError(f"minutes must be > 0, got {minutes}")
    if candidates < 2:
        raise DesignError(f"candidates must be >= 2, got {candidates}")
    limits = limits or Limits()
    budget = 60.0 * float(minutes)
    if budget <= limits.initial_dwell + limits.min_dwell + 10.0:
        raise DesignError(f"{minutes:g} min is too short for the initial dwell ({limits.initial_dwell:g} s) and a move")
    setup = setup or make_setup(states)
    size = search_size(minutes, candidates, population, setup)
    if size.steps > MAX_STEPS:
        raise DesignError(f"{minutes:g} min at a {setup.T:g} s filter step is {size.steps:.3g} steps per candidate, "
                          f"more than the {MAX_STEPS:.0e} of a sensible bound")
    if size.total_steps > MAX_SEARCH_STEPS:
        raise DesignError(f"{candidates} candidates x {size.steps:.3g} steps is {size.total_steps:.3g} filter steps, "
                          f"more than the {MAX_SEARCH_STEPS:.0e} of a sensible search")
    obj = make_objective(setup, objective, targets, groups)
    ref_value = obj.value(obj.reference)
    rng = np.random.default_rng(seed)
    mu = max(2, min(population, candidates // 2))
    ev = _Evaluator(scheduler, workers)
    try:
        ev.setup(setup, obj, budget, limits)
        lam = max(4, 4 * ev.workers)
        init = [g for g in seed_genomes(limits) if g]
        while len(init) < mu:
            init.append(random_genes(rng, limits))
        init = init[:min(len(init), candidates)]
        pop = [(v, s, k) for v, s, k in ev.run(init)]
        n_eval = len(init)
        trace = [min(p[0] for p in pop)]
        gen = 0
        if progress:
            progress(n_eval, candidates, trace[-1])
        while n_eval < candidates:
            n = min(lam, candidates - n_eval)
            pop.sort(key=lambda p: p[0])
            parents = pop[:mu]
            kids = []
            for _ in range(n):
                i, j = rng.integers(len(parents), size=2)
                # tournament of two for each parent
                a = parents[min(i, int(rng.integers(len(parents))))][2]
                child = crossover(a, parents[j][2], rng) if rng.random() < 0.3 else list(a)
                kids.append(mutate(child, rng, limits))
            pop = parents + list(ev.run(kids))
            n_eval += n
            gen += 1
            trace.append(min(p[0] for p in pop))
            if progress:
                progress(n_eval, candidates, trace[-1])
    finally:
        ev.close()
    pop.sort(key=lambda p: p[0])
    best_v, _, best_genes = pop[0]
    if not math.isfinite(best_v):
        raise DesignError("no feasible path found (limits too tight for the budget?)")
    path, _ = build_path(best_genes, budget, limits, name or f"designed-{minutes:g}min")
    b = evaluate(setup, path)
    return DesignResult(path, b, obj, obj.value(b.combined_sigma), ref_value, budget, limits, n_eval, gen, seed,
                        time.perf_counter() - t0, trace)
