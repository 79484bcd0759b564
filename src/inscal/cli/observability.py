"""``inscal observability``: which systematic-filter states a rotation path makes observable,
from the path alone (no data).  See :mod:`inscal.plan.observability`."""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from inscal.cli.common import CliError, call, fail, print_json, short
from inscal.cli.limits import check_count, check_mc_trials, check_memory, human_seconds
from inscal.cli.observability_text import print_budget, print_crlb, print_report
from inscal.cli.options import (
    JsonOption,
    McWorkersOption,
    SeedOption,
    arw_option,
    noise_option,
    option,
    options_of,
    states_option,
    station_option,
    vrw_option,
    with_options,
)

def run_observability(source: str, states: str = "51", rate_hz: float = 20.0, arw: float | None = None,
                      vrw: float | None = None, t_ref: float | None = None):
    """The :class:`~inscal.plan.observability.ObservabilityReport` of ``source``; ``arw`` in
    deg/sqrt(h), ``vrw`` in ug/sqrt(Hz) (field units, converted here); ``t_ref`` [degC] the reference
    temperature of thermal states."""
    from inscal.calibrate.systematic.states import StateSet
    from inscal.calibrate.windows import CalibrationError
    from inscal.core import units
    from inscal.plan.observability import (
        MAX_SAMPLES,
        ObservabilityError,
        load_source,
        observability,
        observability_bytes,
    )

    try:  # the size first: the simulation is held in memory, and the filter's per-step stores
        sc, _, label = load_source(source)
        st = StateSet.parse(states)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None
    except CalibrationError:
        st = None  # observability() names the bad state set
    _check_t_ref(t_ref, st)
    if st is not None:
        dur = sc.path.duration
        what = f"--rate-hz {rate_hz:g} over the {dur:.4g} s path of {short(label, 60)} ({dur * rate_hz:.3g} samples)"
        hint = "lower --rate-hz (the default 20 Hz is enough for the filter) or take a shorter path"
        check_memory(observability_bytes(dur * rate_hz, dur, st), what, hint)
        check_count(dur * rate_hz, MAX_SAMPLES, what, hint)
    try:
        return observability(source, states, rate_hz=rate_hz,
                             arw=None if arw is None else units.to_si(arw, "deg/sqrt(h)"),
                             vrw=None if vrw is None else units.to_si(vrw, "ug/sqrt(Hz)"), t_ref=t_ref)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None


@dataclass(frozen=True)
class CrlbOptions:
    """What ``inscal observability --crlb`` is asked: the Cramér-Rao bound of ``source`` for the ``states`` set
    at ``filter_rate_hz``.  Field units: ``arw`` deg/sqrt(h), ``vrw`` ug/sqrt(Hz); bias instability as a
    Gauss-Markov process ``gyro_bi`` deg/h, ``accel_bi`` ug with correlation time ``bi_tau`` s, or a random walk
    ``gyro_rrw`` deg/h/sqrt(h), ``accel_rrw`` ug/sqrt(s); ``t_ref`` degC (thermal states).  ``noise``: a
    noise.toml whose white, Gauss-Markov and random-walk terms are the bound's noise
    (:func:`inscal.plan.noise_model.bound_noise`), instead of those options.  ``station``: a station
    (:class:`inscal.uncertainty.station.Station`): the bound at its site, carrying the site and clock
    sensitivities."""

    source: Annotated[str, typer.Argument(metavar="PATH_OR_SCENARIO", help=(
        "built-in scenario (s16, psins19, n25, ...) or path (s16-table1, n25-twelve, ...), a scenario TOML, or a "
        "path TOML (a [path] table)"))]
    states: states_option("state set: 51 | 30, options ,lever9 ,async ,psins, ,thermal (or ,thermal=GSABR: "
                          "needs a temperature profile)") = "51"
    arw: arw_option("the scenario's, else S16's 5e-5") = None
    vrw: vrw_option("the scenario's, else S16's 1") = None
    filter_rate_hz: Annotated[float, typer.Option("--filter-rate-hz", help="filter rate of the bound [Hz]")] = 1.0
    gyro_bi: option("--gyro-bi", "with --crlb: gyro bias instability, Gauss-Markov sigma [deg/h]",
                    metavar="DEG/H") = None
    accel_bi: option("--accel-bi", "with --crlb: accelerometer bias instability, Gauss-Markov sigma [ug]",
                     metavar="UG") = None
    bi_tau: Annotated[float, typer.Option("--bi-tau", metavar="SECONDS", help=(
        "with --crlb: correlation time of the bias instability [s]"))] = 3600.0
    gyro_rrw: option("--gyro-rrw", "with --crlb: gyro bias random walk [deg/h/sqrt(h)]", metavar="DEG/H/SQRT(H)") = None
    accel_rrw: option("--accel-rrw", "with --crlb: accelerometer bias random walk [ug/sqrt(s)]",
                      metavar="UG/SQRT(S)") = None
    t_ref: option("--t-ref", "reference temperature of the thermal states [degC] (default: the scenario's thermal "
                  "model's, else 20)", metavar="DEGC") = None
    noise: noise_option("with --crlb: an identified noise model (noise.toml of inscal noise): its white, "
                        "Gauss-Markov and random-walk terms are the bound's noise") = None
    station: object = None  # a Station (read from --station FILE.toml)


def run_crlb(o: CrlbOptions):
    """The Cramér-Rao bound (:func:`inscal.plan.bound.crlb`) of ``o.source`` (the options: :class:`CrlbOptions`)."""
    from inscal.calibrate.systematic.states import StateSet
    from inscal.calibrate.windows import CalibrationError
    from inscal.core import units
    from inscal.plan.bound import MAX_STEPS, STEP_SECONDS, bound_steps, crlb
    from inscal.plan.observability import ObservabilityError, load_source
    from inscal.plan.rows import BiasNoise, BoundError

    model_noise = None
    if o.noise is not None:
        model_noise = _model_noise(o.noise, o.arw, o.vrw, o.gyro_bi, o.accel_bi, o.gyro_rrw, o.accel_rrw)
    try:  # the size first: memory does not grow with the steps (no history kept), the time does
        sc, _, label = load_source(o.source)
    except ObservabilityError as exc:
        raise CliError(str(exc)) from None
    try:
        st = StateSet.parse(o.states)
    except CalibrationError:
        st = None  # crlb() names the bad state set
    _check_t_ref(o.t_ref, st)
    dur = sc.path.duration
    steps = bound_steps(dur, o.filter_rate_hz)
    check_count(steps, MAX_STEPS, f"--filter-rate-hz {o.filter_rate_hz:g} over the {dur:.4g} s path of {short(label, 60)} "
                f"is {steps:.3g} filter steps, about {human_seconds(steps * STEP_SECONDS)} of CPU",
                "lower --filter-rate-hz (1 Hz is the systematic filter's rate) or take a shorter path")
    bias = None
    if any(v is not None for v in (o.gyro_bi, o.accel_bi, o.gyro_rrw, o.accel_rrw)):
        per_sqrt_h = 1.0 / math.sqrt(3600.0)  # x per sqrt(h) = x / 60 per sqrt(s)
        bias = BiasNoise(gyro_rw=units.to_si(o.gyro_rrw or 0.0, "deg/h") * per_sqrt_h,
                         accel_rw=units.to_si(o.accel_rrw or 0.0, "ug"),
                         gyro_gm=units.to_si(o.gyro_bi or 0.0, "deg/h"), gyro_tau=o.bi_tau,
                         accel_gm=units.to_si(o.accel_bi or 0.0, "ug"), accel_tau=o.bi_tau)
    arw_si = None if o.arw is None else units.to_si(o.arw, "deg/sqrt(h)")
    vrw_si = None if o.vrw is None else units.to_si(o.vrw, "ug/sqrt(Hz)")
    if model_noise is not None:
        arw_si, vrw_si, bias, _ = model_noise
    extra = {}
    if o.station is not None:
        from inscal.uncertainty.before_run import consider_u, station_site

        extra = {"consider": consider_u(o.station), "site": station_site(sc.site, o.station)}
    try:
        return crlb(o.source, o.states, arw=arw_si, vrw=vrw_si, bias_noise=bias,
                    filter_rate_hz=o.filter_rate_hz, keep_history=False, t_ref=o.t_ref, **extra)
    except BoundError as exc:
        raise CliError(str(exc)) from None


def _model_noise(noise, arw, vrw, gyro_bi, accel_bi, gyro_rrw, accel_rrw):
    """The bound's noise of the noise.toml ``noise`` (:func:`inscal.plan.noise_model.bound_noise`); CliError
    (one line) for an unreadable file, a model the bound cannot take, or other noise options beside it."""
    from inscal.calibrate.windows import CalibrationError
    from inscal.io.noisefile import NoiseFileError, read_noise
    from inscal.plan.noise_model import bound_noise
    from inscal.plan.rows import BoundError

    if any(v is not None for v in (arw, vrw, gyro_bi, accel_bi, gyro_rrw, accel_rrw)):
        raise CliError("--noise gives the white and bias noise: drop --arw, --vrw, --gyro-bi, --accel-bi, --gyro-rrw "
                       "and --accel-rrw, or drop --noise")
    try:
        return bound_noise(read_noise(noise)[0])
    except (NoiseFileError, OSError) as exc:
        raise CliError(f"--noise: {exc}") from None
    except (CalibrationError, BoundError) as exc:
        raise CliError(f"--noise {noise}: {exc}") from None


def _check_t_ref(t_ref: float | None, st) -> None:
    if t_ref is None:
        return
    if not math.isfinite(t_ref):
        raise CliError(f"--t-ref must be a temperature in degC, got {t_ref:g}")
    if st is not None and not st.thermal:
        raise CliError("--t-ref is the reference temperature of the thermal states: add them (--states 51,thermal)")


def _simulated(source: str, st, method: str, seed: int, full: bool, json_: bool, mc: int | None = None,
               mc_workers: int = 1) -> None:
    """``--crlb --station --method M``: the budget of a window-mean method from one simulated run (and its JCGM 101
    Monte Carlo with ``mc`` trials at most)."""
    from inscal.calibrate.windows import CalibrationError
    from inscal.uncertainty.before_run import dominant_inputs, simulated_budget
    from inscal.uncertainty.sensitivity import WINDOW_METHODS
    from inscal.plan.observability import ObservabilityError, load_source

    if st is None:
        raise fail("--method needs --station (the budget of a window-mean method at a station)")
    if method not in WINDOW_METHODS:
        raise fail(f"--method must be a window-mean method ({', '.join(WINDOW_METHODS)}); the systematic filter's "
                   "budget is the bound's (leave --method out)")
    try:
        check_mc_trials(mc)
    except CliError as exc:
        raise fail(str(exc)) from None
    try:
        sc, _, _ = load_source(source)
        bud, res = simulated_budget(sc, st, method, seed)
    except (ObservabilityError, CalibrationError, ValueError) as exc:
        raise fail(f"{source} with --method {method}: {exc}") from None
    doc = bud.to_dict()
    if mc is not None:
        from inscal.cli.budget_mc import run_budget_mc

        try:
            doc["monte_carlo"] = run_budget_mc(res, st, bud, mc, seed, mc_workers)
        except CliError as exc:
            raise fail(str(exc)) from None
    if json_:
        print_json({"source": source, "method": method, "seed": seed, "station": st.to_dict(), "budget": doc,
                    "dominant_inputs": dominant_inputs(bud)})
        return
    print_budget(source, None, bud, full, f"{method} on one simulated run (seed {seed})", doc)


def register(app: typer.Typer) -> None:
    @app.command("observability")
    @with_options(CrlbOptions, before="rate_hz")
    def observability_cmd(
        rate_hz: Annotated[float, typer.Option("--rate-hz", help="rate of the noise-free simulation [Hz]")] = 20.0,
        crlb: bool = typer.Option(False, "--crlb", help="print the Cramér-Rao bound of every parameter (fast, "
                                                        "from the path kinematics; no simulation)"),
        station: station_option("with --crlb: a station description (station.toml): the bound at its site, and "
                                "the uncertainty budget the path promises with its inputs (which dominate, before "
                                "the run)", Path) = None,
        full: bool = typer.Option(False, "--full", help="with --station: every component's budget table"),
        method: str = typer.Option(None, "--method", metavar="METHOD", help="with --station: a window-mean method (n25, six-position, "
                                   "twelve-position, joint): its budget from one run simulated on the path at the "
                                   "station (the scenario's unit and noise) instead of the systematic filter's bound"),
        seed: SeedOption = 0,
        mc: Annotated[int | None, typer.Option("--mc", metavar="N", help=(
            "with --method: the JCGM 101 Monte Carlo of that budget, at most N trials (does the linear budget hold "
            "for this path at this station?)"))] = None,
        mc_workers: McWorkersOption = 1,
        json_: JsonOption = False,
        **options,
    ):
        """Observability of the systematic filter's states on a rotation path, without data: posterior /
        prior σ per state and the SVD of the observability matrix."""
        o = options_of(CrlbOptions, options)
        source = o.source
        if crlb:
            from inscal.cli.bound_budget import read_station_option

            st = read_station_option(station)
            if method is not None:
                _simulated(source, st, method, seed, full, json_, mc, mc_workers)
                return
            if mc is not None:
                raise fail("--mc needs --method (the Monte Carlo of a window-mean method's budget; the filter's site "
                           "and clock enter it linearly)")
            b = call(run_crlb, dataclasses.replace(o, station=st))
            bud = None
            if st is not None:
                from inscal.uncertainty.before_run import bound_budget, dominant_inputs
                from inscal.plan.observability import load_source

                bud = bound_budget(b, st, scenario=load_source(source)[0])
            if json_:
                doc = {"source": source, "crlb": b.to_dict()}
                if bud is not None:
                    doc.update(station=st.to_dict(), budget=bud.to_dict(), dominant_inputs=dominant_inputs(bud))
                print_json(doc)
            elif bud is not None:
                print_budget(source, b, bud, full)
            else:
                print_crlb(source, b)
            return
        if station is not None or full or method is not None or mc is not None:
            raise fail("--station, --full, --method and --mc apply to the bound (--crlb)")
        if o.noise is not None:
            raise fail("--noise applies to the bound (--crlb)")
        if any(v is not None for v in (o.gyro_bi, o.accel_bi, o.gyro_rrw, o.accel_rrw)):
            raise fail("--gyro-bi, --accel-bi, --gyro-rrw and --accel-rrw need --crlb (the systematic filter has no "
                       "bias process noise)")
        if o.filter_rate_hz != 1.0 or o.bi_tau != 3600.0:
            raise fail("--filter-rate-hz and --bi-tau apply to the bound (--crlb); the observability analysis runs at "
                       "--rate-hz")
        rep = call(run_observability, source, o.states, rate_hz, o.arw, o.vrw, o.t_ref)
        if json_:
            print_json(rep.to_dict())
            return
        print_report(rep)
