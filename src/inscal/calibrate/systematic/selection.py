"""Automatic choice of the systematic filter's error terms (``--states auto``).

The state set is chosen from the record by nested-model tests on the innovations of the converged
fits.  The filter's innovations ``nu_k`` with covariances ``S_k`` are the prediction-error
decomposition of the likelihood, so for two nested state sets (``k`` extra parameters) the drop in

    chi2 = sum_k nu_k^T S_k^-1 nu_k          (6 rows per filter step, velocity and position)

from the smaller to the larger model is chi2(k)-distributed when the extra terms are zero and the
noise model is right.  A model misfit (a term still missing, or data from another integration
scheme) inflates every step's NIS; the drop is then divided by the dispersion
``phi = max(1, chi2 / dof)`` of the larger model (a quasi-likelihood F-type test).  ``phi`` is never
taken below 1: on a noise-free record the floors of the noise model make ``chi2 / dof`` tiny, and a
test scaled by it would accept any term that removes round-off.

The search runs backwards from the full model: the base set plus every candidate term (``async``: the
gyro-accelerometer time asynchrony; ``lever9``: the full inner lever arm; ``levtime``: the lever-arm timing
nuisance, for a record whose generator left the lever-arm terms out of its asynchrony) with every droppable group
(the six off-diagonal g-sensitivity terms, dropped by ``gdiag``; the six cross-coupling terms, dropped
by ``nocross``).  Each candidate is removed alone and tested against the full model; those whose
removal is not significant (p >= ``alpha``) are then removed cumulatively, least significant first,
while the joint removal stays insignificant against the full model.  Forward steps (adding one term
at a time) fail on a record that needs two terms: with both missing the misfit is so large that
either alone shows nothing; the full model fits when the truth is among the candidates.
The full model starts from the nominal parameters; each smaller model starts from the full model's
estimate with its removed terms at zero, so a removal that changes nothing converges in one or two
passes (a start from the estimate of a model that misfits, as forward steps would use, crawls).

The lever-arm timing is nested in the full lever arm: the lever-arm test removes both (``levtime`` without the
lever arms it times is the same weak column on the three diagonal ones), and ``levtime`` alone is tested only when
the full lever arm stays.  The removals are first tried all at once (one fit, the common case of a record that needs
none of them), then one by one as above when the joint removal is significant.

The frame convention (``psins``) is decided from the data when the chosen set has the full lever arm.  Both frames
hold the same linear model, but the size effect (and the quadratic terms) act along the frame's axes: the gyro-defined
frame of S16 (its ``T_g`` triangular, inscal's simulator) or the accelerometer-defined frame of PSINS (``Ka``
triangular: a generator in PSINS's conventions takes ``e_i . (w x (w x p_i) + w-dot x p_i)`` along the accelerometer
triad's axes).  The two frames differ by the triads' relative misalignment (1e-4 rad on a navigation-grade unit), so
the size effects differ by 1e-4 of themselves: below the noise of a noisy record, but several sigma of the lever arms
on a noise-free one.  The two models have the same number of parameters and are not nested: the one with the lower
chi2 is taken (the likelihood ratio at equal dimension).  Not decided from the data: the gimbal states (they add the
encoder observations, so the likelihoods are of different data; ``--method unified`` chooses them).

A named set (:func:`check_named`, run by the named methods on a set the user named) gets the same tests for what
models the record rather than the unit where its fit weighted steps away as misfit: the lever-arm timing and the
frame, on the named fit's own frozen model-error factors (so its chi2 is the smaller model's, and each test costs one
short fit from its estimate).  On the independent oracle's noise-free record ``51,async,lever9`` weighted the turns'
misfit away (outlier steps) and left the lever arms 3.8-5.5 sigma off with sigma at the record's bound; the misfit
follows the lever-arm timing and the accelerometer-defined frame, and with both (refitted with factors of their own)
the lever arms are within 1.34 sigma.  A named set's frame changes only where the other frame's chi2 is lower by
more than the ``alpha`` quantile of chi2(1) (times the dispersion): the user's frame stands where the data cannot
tell.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.systematic.driver import MIN_VERDICT_PASSES, systematic
from inscal.calibrate.systematic.params import truth_in_frame
from inscal.calibrate.systematic.states import StateSet, state_spec
from inscal.calibrate.windows import CalibrationError
from inscal.core.error_model import ImuErrors
from inscal.core.stats import chi2_ppf, chi2_sf

#: terms added when significant: option -> (StateSet field, value)
ADD = {"async": ("asynchrony", True), "lever9": ("lever9", True), "levtime": ("lever_timing", True)}
#: groups dropped when not significant
DROP = {"gdiag": ("gsens_offdiag", False), "nocross": ("cross", False)}
#: significance level of every test
ALPHA = 1e-3


@dataclass(frozen=True)
class Decision:
    """One nested-model test: ``term`` added or dropped (``accepted``), with its statistic."""

    step: str  # "add" or "drop"
    term: str  # the state option (async, lever9, levtime, gdiag, nocross)
    chi2_small: float  # chi2 of the smaller model
    chi2_large: float  # chi2 of the larger model
    dk: int  # parameters the larger model has in addition
    dispersion: float  # phi = max(1, chi2_large / dof)
    statistic: float  # (chi2_small - chi2_large) / phi, chi2(dk) under the smaller model
    p_value: float
    accepted: bool
    status: str = "tested"  # "tested"; "not converged" or "nesting violated": not compared, the term stays

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    def line(self) -> str:
        verb = {("add", True): "added", ("add", False): "not added", ("drop", True): "dropped",
                ("drop", False): "kept"}[(self.step, self.accepted)]
        what = self.term if self.step == "add" else {"gdiag": "g-sensitivity off-diagonals",
                                                     "nocross": "cross-coupling"}[self.term]
        if self.status == "not converged":
            return f"{what} {verb}: the fit without it did not converge, so it was not compared (the term stays)"
        if self.status == "nesting violated":
            return (f"{what} {verb}: NESTING VIOLATED, the smaller model ends with the lower chi2 ({self.chi2_small:.6g} "
                    f"< {self.chi2_large:.6g}): no test is possible, the term stays")
        return (f"{what} {verb}: chi2 {self.chi2_small:.6g} -> {self.chi2_large:.6g} with {self.dk} more "
                f"parameters, dispersion {self.dispersion:.3g}, statistic {self.statistic:.4g}, p = {self.p_value:.3g}")


def _chi2(res: CalibrationResult) -> tuple[float, int]:
    inn = res.diagnostics["innovations"]
    return float(inn["chi2"]), int(inn["dof"])


#: a chi2 of the smaller model below the larger one's by more than this (in units of the test statistic, after the
#: dispersion) is a violated nesting; less is the round-off of two equal fits (the term adds nothing: statistic 0)
NESTING_TOL = 1.0


def _test(step: str, term: str, small: CalibrationResult, large: CalibrationResult, dk: int,
          alpha: float) -> Decision:
    """The nested test of ``small`` against ``large`` (module docstring).  A smaller fit that did not converge
    is not compared, nor one whose chi2 is below the larger model's by more than :data:`NESTING_TOL` (a violated
    nesting is no evidence for dropping anything): the term stays in both cases."""
    c_s, _ = _chi2(small)
    c_l, dof = _chi2(large)
    phi = max(1.0, c_l / max(dof - dk, 1))
    keep = step == "add"  # a term that stays: accepted when it is an added one, not accepted (kept) when droppable
    if not small.diagnostics.get("convergence", {}).get("converged", True):
        return Decision(step, term, c_s, c_l, dk, phi, float("nan"), float("nan"), keep, "not converged")
    if (c_l - c_s) / phi > NESTING_TOL:
        return Decision(step, term, c_s, c_l, dk, phi, (c_s - c_l) / phi, float("nan"), keep, "nesting violated")
    stat = max(0.0, (c_s - c_l) / phi)
    p = chi2_sf(stat, dk)
    return Decision(step, term, c_s, c_l, dk, phi, stat, p, p < alpha if step == "add" else p >= alpha)


def _removed(imu: ImuErrors, terms) -> ImuErrors:
    """The full model's estimate with the removed terms at zero: the start of a smaller model's fit (a
    removed term keeps the value it starts with, so it must start at zero; the lever-arm timing is not an
    ImuErrors term and starts at zero in every fit)."""
    kw = {}
    for t in terms:
        if t == "async":
            kw["time_asynchrony"] = 0.0
        elif t == "lever9":
            kw["accel_lever_arm"] = np.diag(np.diag(imu.accel_lever_arm))
        elif t == "gdiag":
            kw["gyro_g_sensitivity"] = np.diag(np.diag(imu.gyro_g_sensitivity))
        elif t == "nocross":
            kw["accel_cross_coupling"] = np.zeros(6)
    return imu.replace(**kw)


def _candidates(base_st: StateSet, add, drop) -> dict[str, tuple[str, bool]]:
    """The candidates of the search from ``base_st``: terms it lacks (added in the full model) and groups it
    has (droppable)."""
    ext_only = ("lever9", "gsens_offdiag", "cross", "lever_timing")
    cands = {t: ADD[t] for t in add if getattr(base_st, ADD[t][0]) != ADD[t][1]
             and (base_st.extended or ADD[t][0] not in ext_only)}
    cands.update({t: DROP[t] for t in drop if getattr(base_st, DROP[t][0]) != DROP[t][1] and base_st.extended})
    return cands


def _full(base_st: StateSet, cands: dict[str, tuple[str, bool]]) -> StateSet:
    return dataclasses.replace(base_st, **{f: v for t, (f, v) in cands.items() if t in ADD})


def largest_states(base: str, spec: str | None) -> StateSet:
    """The largest state set a fit of ``base`` (``"51"``, ``"30"``, ``"unified"``) with the options ``spec``
    runs: the full model of the search (every candidate term added) when ``spec`` asks for ``auto``
    (the default), else the set itself.  For a memory estimate before the record is read."""
    extra, auto = with_auto("auto" if spec is None else spec, "")
    st = StateSet.parse(base + ("," + extra if extra else ""))
    return _full(st, _candidates(st, tuple(ADD), tuple(DROP))) if auto else st


def select_states(record, base: str | StateSet = "51", *, alpha: float = ALPHA, add=tuple(ADD),
                  drop=tuple(DROP), fit: Callable[..., CalibrationResult] = systematic, frames: bool = True,
                  **options) -> CalibrationResult:
    """The systematic calibration of ``record`` with its error terms chosen from the data (module
    docstring).  ``base``: the starting state set (``"51"``, ``"30"``, ``"51,psins"``, ``"unified"``...);
    ``add``/``drop``: the candidate options; ``frames``: decide the frame convention when the full lever arm is
    chosen (module docstring); ``options`` go to ``fit`` (:func:`systematic`).  The result
    is the fit of the chosen set; ``diagnostics["selection"]`` lists every test and ``notes`` the
    decisions."""
    base_st = base if isinstance(base, StateSet) else StateSet.parse(base)
    if not 0.0 < alpha < 1.0:
        raise CalibrationError(f"alpha must be in (0, 1), got {alpha}")
    for name in list(add) + list(drop):
        if name not in ADD and name not in DROP:
            raise CalibrationError(f"unknown candidate term {name!r}; candidates: {', '.join(ADD | DROP)}")
    options = dict(options)
    options.pop("initial", None)
    cands = _candidates(base_st, add, drop)
    full_st = _full(base_st, cands)
    full = fit(record, full_st, **options)
    fits = 1
    # the smaller fits share the full model's frozen model-error factors (model_error): their chi2 are then of
    # one noise model and compare; one that does not converge is kept as it ends and not compared (_test)
    options["weights"] = full.model_error
    options["accept_unconverged"] = True

    def without(st: StateSet, terms) -> StateSet:
        kw = {}
        for t in terms:
            f, v = cands[t]
            kw[f] = (not v) if t in ADD else v
        return dataclasses.replace(st, **kw)

    # each candidate removed from the full model alone (the full model fits the record when the truth
    # is among the candidates; a model missing two terms may misfit so badly that adding either alone
    # shows nothing, which is why the search runs backwards); the lever-arm timing nested in the full lever arm
    nested = {"lever9": ["levtime"]} if "lever9" in cands and "levtime" in cands else {}
    tests: dict[str, Decision] = {}
    singles: dict[str, CalibrationResult] = {}
    order = [t for t in cands if t != "levtime"] + (["levtime"] if "levtime" in cands else [])
    for t in order:
        if t == "levtime" and nested and not tests["lever9"].accepted:  # goes with the lever arm it times
            tests[t] = dataclasses.replace(tests["lever9"], term=t)  # the joint test decided it
            continue
        small_st = without(full_st, [t] + nested.get(t, []))
        fits += 1
        step = "drop" if t in DROP else "add"
        try:
            singles[t] = fit(record, small_st, initial=_removed(full.imu, [t]), **options)
        except CalibrationError:  # the smaller model fails on this record (a numerical failure): it cannot be compared
            tests[t] = Decision(step, t, float("nan"), _chi2(full)[0], full_st.n_params - small_st.n_params, 1.0,
                                float("nan"), float("nan"), step == "add", "not converged")
            continue
        tests[t] = _test(step, t, singles[t], full, full_st.n_params - small_st.n_params, alpha)
    # remove the insignificant ones: all at once when that stays insignificant, else one by one, least
    # significant first, while the joint removal stays insignificant
    removable = sorted((t for t, d in tests.items() if d.status == "tested" and d.p_value >= alpha
                        and not (t == "levtime" and nested and not tests["lever9"].accepted)),
                       key=lambda t: -tests[t].p_value)

    def with_nested(ts: list) -> list:  # the terms and those nested in them
        return ts + [n for t in ts for n in nested.get(t, []) if n not in ts]

    st, cur, gone = full_st, full, []
    if len(removable) > 1:
        trial_st = without(full_st, with_nested(removable))
        fits += 1
        try:
            trial = fit(record, trial_st, initial=_removed(full.imu, removable), **options)
            joint = _test("drop", "all", trial, full, full_st.n_params - trial_st.n_params, alpha)
        except CalibrationError:
            joint = None
        if joint is not None and joint.status == "tested" and joint.p_value >= alpha:
            gone, st, cur = list(removable), trial_st, trial
            removable = []
    for t in removable:
        trial_st = without(full_st, with_nested(gone + [t]))
        if gone:
            fits += 1
            try:
                trial = fit(record, trial_st, initial=_removed(full.imu, gone + [t]), **options)
            except CalibrationError:
                break
            joint = _test("drop", t, trial, full, full_st.n_params - trial_st.n_params, alpha)
            if joint.status != "tested" or joint.p_value < alpha:
                break
        else:
            trial = singles[t]
        gone.append(t)
        st, cur = trial_st, trial
    gone = with_nested(gone)
    frame = None
    if frames and st.lever9 and not (st.psins or st.gimbal):
        st, cur, frame = _frame_choice(record, st, cur, fit, options)
        fits += 1
    decided = {t: dataclasses.replace(d, accepted=(t not in gone) if t in ADD else (t in gone))
               for t, d in tests.items()}
    if cur is not full:
        cur.diagnostics["model_error"]["shared"] = True
    cur.diagnostics["selection"] = {"base": state_spec(base_st), "chosen": state_spec(st), "alpha": alpha,
                                    "fits": fits, "full": state_spec(full_st),
                                    "tests": [d.to_json() for d in decided.values()], "frame": frame}
    cur.notes.append(f"state set chosen from the data (--states auto): {state_spec(st)}; "
                     + "; ".join(d.line() for d in decided.values()) + (f"; {frame['line']}" if frame else ""))
    return cur


def model_error_on(res: CalibrationResult) -> bool:
    """Whether the fit weighted steps away (a motion state's model-error factor above 1, or outlier steps): the
    record misfits the model beyond its noise somewhere (:mod:`~inscal.calibrate.systematic.model_error`)."""
    return res.model_error is not None and res.model_error.weighted_away


def check_named(record, res: CalibrationResult, *, alpha: float = ALPHA,
                fit: Callable[..., CalibrationResult] = systematic, **options) -> CalibrationResult:
    """A named state set's fit ``res`` checked for the misfit it weighted away (module docstring).

    The velocity model-error term is the last resort: it weights away the steps that misfit, and a misfit that
    follows the motion is structure a term can model.  A named set with the full lever arm whose fit needed the
    term (:func:`model_error_on`) is tested for what models the record and not the unit: the lever-arm timing
    (``levtime``, three nuisance states, the nested test against chi2(3)) and, unless ``psins`` is named, the frame
    whose axes the size effect follows; both on ``res``'s frozen factors, from its estimate.  Where the record holds
    either, the set with them is fitted again with factors of its own and returned, with one note naming what was
    added and the chi2 it removed (``diagnostics["selection"]``, ``named`` true); every parameter named is still
    estimated.  Else ``res`` is returned with the tests in a note.  A truncated, unrobust or nested run
    (``max_passes`` below four, ``robust=False``, given ``weights``), an accepted unconverged one and one without the
    full lever arm are returned as they are."""
    st = res.states
    if (st is None or not (st.extended and st.lever9) or st.gimbal or (st.lever_timing and st.psins)
            or options.get("weights") is not None or options.get("robust", True) is False
            or options.get("max_passes", 10) < MIN_VERDICT_PASSES
            or (res.diagnostics.get("convergence") or {}).get("verdict") or not model_error_on(res)):
        return res
    named = state_spec(st)
    frozen = {k: v for k, v in options.items() if k != "initial"} | {"weights": res.model_error,
                                                                      "accept_unconverged": True}
    cur_st, cur, tests, fits, full_st = st, res, [], 0, st
    try:
        if not st.lever_timing:
            full_st = dataclasses.replace(st, lever_timing=True)
            big = fit(record, full_st, initial=res.imu, **frozen)
            fits += 1
            if big.diagnostics.get("convergence", {}).get("converged", True):
                d = _test("add", "levtime", res, big, full_st.n_params - st.n_params, alpha)
            else:
                d = Decision("add", "levtime", _chi2(res)[0], _chi2(big)[0], full_st.n_params - st.n_params, 1.0,
                             float("nan"), float("nan"), False, "not converged")
            tests.append(d)
            if d.accepted and d.status == "tested":
                cur_st, cur = full_st, big
        frame = None
        if not st.psins:
            cur_st, cur, frame = _frame_choice(record, cur_st, cur, fit, frozen, chi2_ppf(1.0 - alpha, 1))
            fits += 1
        if cur_st != st:  # what the record holds, with factors of its own (the named set's weighted its misfit away)
            cur = fit(record, cur_st, initial=cur.imu, **{k: v for k, v in options.items() if k != "initial"})
            fits += 1
    except CalibrationError as exc:
        res.notes.append(f"the states named ({named}) weighted steps away as misfit, and the check for the "
                         f"lever-arm timing and the frame could not run: {exc}")
        return res
    sel = {"base": named, "chosen": state_spec(cur_st), "alpha": alpha, "fits": fits, "full": state_spec(full_st),
           "tests": [d.to_json() for d in tests], "frame": frame, "named": True}
    cur.diagnostics["selection"] = sel
    if cur_st == st:
        found = [d.line() for d in tests] + ([frame["line"]] if frame else [])
        res.notes.append(f"the states named ({named}) weighted steps away as misfit; checked for what the misfit could "
                         f"follow: {'; '.join(found)}: the states named stand")
        return res
    parts = [f"the lever-arm timing (levtime: chi2 {d.chi2_small:.6g} -> {d.chi2_large:.6g} with {d.dk} more "
             f"nuisance states, p = {d.p_value:.2g})" for d in tests if d.accepted and d.status == "tested"]
    if frame and frame["chosen"] == "psins":
        parts.append(f"the size effect along the accelerometers' axes (the accelerometer-defined frame, psins: chi2 "
                     f"{frame['chi2_gyro']:.6g} -> {frame['chi2_accel']:.6g} at equal parameters)")
    cur.notes.append(f"the states named ({named}) leave out what the turns' residuals follow: {' and '.join(parts)}; "
                     f"fitted with {sel['chosen']}: every parameter named, the misfit modelled instead of weighted away")
    return cur


def _frame_choice(record, st: StateSet, cur: CalibrationResult, fit, options, margin: float = 0.0) -> tuple:
    """The chosen set ``st`` (fit ``cur``, gyro-defined frame) against the same set in the accelerometer-defined
    frame (``psins``), started from ``cur``'s estimate in that frame: ``(states, fit, record of the choice)`` of the
    one with the lower chi2 (module docstring), the accelerometer-defined one only where lower by more than ``margin``
    times the dispersion (a named set's frame stands where the data cannot tell); a fit in the other frame that
    fails or does not converge loses."""
    alt_st = dataclasses.replace(st, psins=True)
    try:
        alt = fit(record, alt_st, initial=truth_in_frame(cur.imu, alt_st).to_imu(), **options)
    except CalibrationError:
        alt = None
    c_g, dof = _chi2(cur)
    ok = alt is not None and alt.diagnostics.get("convergence", {}).get("converged", True)
    c_a = _chi2(alt)[0] if ok else float("nan")
    take = bool(ok and c_a < c_g - margin * max(1.0, c_g / max(dof, 1)))
    why = ("the size effect's axes fit better" if take or not c_a < c_g else
           f"kept: the accelerometer-defined one fits better by less than {margin:.3g} (the named frame stands)")
    line = (f"frame: {'accelerometer-defined (psins)' if take else 'gyro-defined'}, {why} "
            f"(chi2 {c_g:.6g} gyro-defined, {c_a:.6g} accelerometer-defined, equal parameters)" if ok else
            "frame: gyro-defined (the fit in the accelerometer-defined frame did not converge)")
    rec = {"chi2_gyro": c_g, "chi2_accel": c_a, "chosen": "psins" if take else "gyro", "line": line}
    return (alt_st, alt, rec) if take else (st, cur, rec)


def with_auto(spec: str | None, default: str) -> tuple[str, bool]:
    """``(spec without 'auto', auto requested)`` of a state spec; ``default`` when it names no base."""
    toks = [t.strip() for t in str(spec or "").replace("+", ",").split(",") if t.strip()]
    auto = "auto" in toks
    toks = [t for t in toks if t != "auto"]
    return ",".join(toks) if toks else default, auto
