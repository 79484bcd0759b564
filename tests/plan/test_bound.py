"""Cramér-Rao bound of an experiment without running it: inscal.plan.bound
and ``inscal observability --crlb``."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.core import kalman as filters, units
from inscal.plan import bound as C
from inscal.plan import rows as plan_rows
from inscal.plan.rows import register_rows
from inscal.plan.observability import observability
from inscal.calibrate.systematic.states import N_NAV, StateSet
from inscal.cli.app import app
from inscal.core.error_model import GimbalErrors
from inscal.sim.scenarios import S16_SITE
from inscal.sim.simulate import Scenario
from inscal.core.kinematics import kinematics, rates_at, segment_at, true_attitude, true_rates
from inscal.core.turntable import Move, RotationPath, s16_table1

DEG = math.pi / 180.0
runner = CliRunner()


def short_path():
    """Five minutes: turns about both axes at 10 deg/s (one with a triangular profile), dwells."""
    mv = (Move("outer", 90 * DEG, 10 * DEG, 40.0), Move("inner", 180 * DEG, 10 * DEG, 40.0),
          Move("outer", -90 * DEG, 10 * DEG, 40.0), Move("inner", 3 * DEG, 10 * DEG, 40.0),
          Move("outer", 270 * DEG, 10 * DEG, 40.0))
    return RotationPath("short", mv, accel=20 * DEG, initial_dwell=30.0, closed=False)


def test_kinematics_match_the_simulator():
    """C_s^n, w_is^s and f^s of the bound's kinematics = the simulator's (non-orthogonal gimbal, tilted mount)."""
    gim = GimbalErrors(units.to_si(20.0, "arcsec"), np.array([0.1, 0.1, 20.0]) * DEG)
    sc = Scenario("k", short_path(), S16_SITE, gimbal=gim)
    seg = sc.path.segments()
    t = np.linspace(0.0, sc.path.duration, 997)
    w_ref, f_ref = true_rates(sc, t)
    C_ref = true_attitude(sc, t)
    from inscal.core.turntable import outer_axis
    from inscal.core.attitude import dcm_from_euler

    u, Cbn = outer_axis(gim.nonorthogonality), dcm_from_euler(gim.mount_attitude)
    Cm, w, f = np.empty((3, 3)), np.empty(3), np.empty(3)
    for k, tk in enumerate(t):
        s = segment_at(tk, seg.t1)
        kinematics(tk, s, seg.t0, seg.th0, seg.w0, seg.acc, u, Cbn, sc.site.earth_rate_n, sc.site.gravity, Cm, w, f)
        assert np.allclose(w, w_ref[k], atol=1e-15, rtol=1e-12)
        assert np.allclose(f, f_ref[k], atol=1e-13)
        assert np.allclose(Cm, C_ref[k], atol=1e-14)
    assert rates_at is not None  # the simulator function the kinematics replicate


@pytest.mark.parametrize("name", ["s16", "psins19"])
def test_bound_equals_the_filter_covariance(name):
    """The fast bound = the covariance view of observability() (one pass of systematic() on a noise-free
    20 Hz simulation) within 1 % per parameter (measured: 3e-5 on s16, 5e-5 on psins19)."""
    b = C.crlb(name)
    o = observability(name)
    ref = np.sqrt(np.diag(o.covariance))
    assert b.labels == tuple(s.label for s in o.states)
    assert np.max(np.abs(b.sigma / ref - 1)) < 0.01
    # the bound over time ends at the bound
    assert np.allclose(b.sigma_history()[-1], b.sigma, rtol=1e-12)


def test_converged_in_the_filter_and_sub_sample_rates():
    """1 Hz vs 5 Hz filter steps: within 2 % per parameter (measured 0.9 % on psins19, worst the lever arm);
    20 vs 100 Hz sub-samples of the moves: within 0.1 %."""
    b1 = C.crlb("psins19")
    b5 = C.crlb("psins19", filter_rate_hz=5.0)
    bs = C.crlb("psins19", sub_rate_hz=100.0)
    assert np.max(np.abs(b1.sigma / b5.sigma - 1)) < 0.02
    assert np.max(np.abs(b1.sigma / bs.sigma - 1)) < 1e-3


@pytest.mark.parametrize("spec", ["30", "51,psins", "51,async"])
def test_state_options_match_the_filter(spec):
    """Other state sets through the same column kinds: the bound = observability() within 1 %."""
    b = C.crlb(short_path(), spec)
    o = observability(short_path(), spec)
    assert b.setup.n_params == StateSet.parse(spec).n_params
    assert np.max(np.abs(b.sigma / np.sqrt(np.diag(o.covariance)) - 1)) < 0.01


def test_lever_timing_columns_at_the_scenarios_lever_arms():
    """The lever-arm timing's columns scale with the lever arms: the bound linearises them at the scenario's, as
    observability() does, and equals it within 5 % (measured 2.6-3.8 %: the filter's 20-Hz second differences of
    the rate smear the angular-acceleration steps the bound takes exactly); at zero lever arms the prior."""
    b = C.crlb("psins19", "51,levtime")
    o = observability("psins19", "51,levtime")
    assert np.max(np.abs(b.sigma / np.sqrt(np.diag(o.covariance)) - 1)) < 0.05
    assert np.all(b.sigma[-3:] < 0.5 * b.setup.prior[-3:])
    bare = C.crlb(short_path(), "51,levtime")
    assert np.allclose(bare.sigma[-3:], bare.setup.prior[-3:], rtol=1e-9)


def _dense_bound(setup, path, q_extra):
    """Independent reference: the systematic filter's own per-step transitions (observability's pass,
    scaled states) through inscal.core.kalman' structured predict (with a parameter random walk) and
    Joseph update."""
    from inscal.calibrate.systematic.driver import systematic
    from inscal.sim.simulate import simulate
    from types import SimpleNamespace
    from dataclasses import replace

    sc = replace(setup.scenario(path), rate_hz=20.0)
    d = simulate(sc)
    rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=20.0, site=sc.site)
    res = systematic(rec, setup.states, max_passes=1, arw=setup.arw, vrw=setup.vrw, history_s=1e12, keep_passes=True)
    out = res.pass_output
    N = setup.sig.size
    P = np.eye(N)
    K, Si, x = np.empty((N, 6)), np.empty((6, 6)), np.empty(N)
    Qs = setup.qd / np.outer(setup.sig[:9], setup.sig[:9])
    for k in range(out.steps):
        filters.predict(P, 9, out.phinn[k], out.phinp[k], Qs, q_extra)
        filters.update(P, np.arange(3, 9), setup.rs, np.zeros(6), K, Si, x)
    sp = setup.sig[N_NAV:]
    return np.sqrt(np.diag(P)[N_NAV:]) * sp


def test_bias_random_walk_matches_the_filter_engine():
    """Bias random walk as process noise: the kernel = inscal.core.kalman.predict with q_p on the same steps."""
    bias = C.BiasNoise(gyro_rw=units.to_si(0.05, "deg/h") / 60.0, accel_rw=units.to_si(20.0, "ug") / 60.0)
    su = C.make_setup("51", bias_noise=bias)
    b = C.evaluate(su, short_path())
    ref = _dense_bound(su, short_path(), su.q_p)
    assert np.max(np.abs(b.sigma / ref - 1)) < 0.01
    b0 = C.evaluate(C.make_setup("51"), short_path())
    off = StateSet().offsets()
    for g in ("gyro_bias", "accel_bias"):
        i = off[g] - N_NAV
        assert np.all(b.sigma[i:i + 3] > 1.05 * b0.sigma[i:i + 3])  # more noise, a weaker bound


def test_bias_gauss_markov_limits():
    """Gauss-Markov bias states: a negligible sigma leaves the bound unchanged; a large one with a long
    correlation time weakens the bias bound; a white-ish one (tau = 1 s) acts as extra white noise."""
    path = short_path()
    b0 = C.evaluate(C.make_setup("51"), path).sigma
    tiny = C.evaluate(C.make_setup("51", bias_noise=C.BiasNoise(gyro_gm=1e-15, accel_gm=1e-12)), path)
    assert tiny.setup.n_gm == 6 and tiny.setup.sig.size == 51 + 6
    assert np.max(np.abs(tiny.sigma / b0 - 1)) < 1e-4
    big = C.evaluate(C.make_setup("51", bias_noise=C.BiasNoise(accel_gm=units.to_si(50.0, "ug"), accel_tau=3600.0)),
                     path).sigma
    i = StateSet().offsets()["accel_bias"] - N_NAV
    assert np.all(big[i:i + 3] > 3 * b0[i:i + 3])


def test_extra_rows_hook(monkeypatch):
    """A state set's extra measurement rows: a direct observation of accel_bias[x] every step with sigma s
    gives that state a bound of about s / sqrt(M) when it is far below the navigation's own."""
    s = units.to_si(0.01, "ug")
    off = StateSet().offsets()["accel_bias"]

    def rows(st, sc, t, options):
        H = np.zeros((t.size, 1, st.n_states))
        H[:, 0, off] = 1.0
        return H, np.full((t.size, 1), s * s)

    monkeypatch.setattr(plan_rows, "_ROW_BUILDERS", [])
    register_rows(lambda st: st.extended, rows)
    b = C.crlb(short_path())
    k = off - N_NAV
    assert b.sigma[k] == pytest.approx(s / math.sqrt(b.steps), rel=0.02)


def test_timing_and_history_shape():
    b = C.crlb(s16_table1())
    assert b.steps == 3861 and b.history.shape == (3861, 42)
    h = b.sigma_history()
    assert np.all(np.diff(h, axis=0) <= 1e-12 * h[:-1])  # constants: the bound never grows


def test_errors():
    with pytest.raises(C.BoundError):
        C.crlb(RotationPath("tiny", (Move("none", dwell=1.5),), closed=False))
    with pytest.raises(C.BoundError):
        C.make_setup("51", arw=-1.0)
    with pytest.raises(C.BoundError):
        C.make_setup("nonsense")
    with pytest.raises(C.BoundError):
        C.BiasNoise(gyro_tau=0.0)
    with pytest.raises(C.BoundError):
        C.crlb("no-such-path")


def test_cli_crlb_json_and_table():
    r = runner.invoke(app, ["observability", "psins19", "--crlb", "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["crlb"]
    assert d["n_params"] == 42 and d["steps"] == 1035
    lab = {p["label"]: p for p in d["parameters"]}
    assert lab["accel_lever_arm[x]"]["unit"] == "cm" and 0 < lab["accel_lever_arm[x]"]["bound"] < 5
    r = runner.invoke(app, ["observability", "psins19", "--crlb", "--gyro-bi", "0.01", "--accel-bi", "20"])
    assert r.exit_code == 0 and "bias instability" in r.output
    for bad in (["--crlb", "--arw", "-1"], ["--gyro-bi", "0.01"], ["--crlb", "--bi-tau", "0"]):
        r = runner.invoke(app, ["observability", "psins19", *bad])
        assert r.exit_code == 2 and r.output.count("\n") <= 2, r.output


def test_bound_vs_monte_carlo_psins19():
    """Eight seeded noise-only systematic51 calibrations of psins19 (20 Hz): the errors normalised by the
    predicted fixed-truth mean and spread of the bound (crlb.predicted_error) have an RMS in [0.6, 1.5]
    over all 42 states (the full 50-run comparison on three paths: bench/crlb_vs_mc.py)."""
    from dataclasses import replace
    from types import SimpleNamespace

    from inscal.calibrate.systematic.params import CompParams, truth_in_frame
    from inscal.calibrate.systematic.methods import systematic51
    from inscal.sim.scenarios import build
    from inscal.sim.simulate import simulate

    sc = replace(build("psins19"), rate_hz=20.0)
    b = C.crlb(sc)
    m, s = C.predicted_error(b, sc.imu)
    z = []
    for run in range(8):
        d = simulate(sc, np.random.default_rng(np.random.SeedSequence([7, run])))
        res = systematic51(SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=sc.rate_hz, site=sc.site))
        e = CompParams.from_imu(res.imu).error_state(res.states, truth_in_frame(sc.imu, res.states))
        z.append((e - m) / s)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.6 < rms < 1.5, rms
    assert np.all(s <= b.sigma * (1 + 1e-9))  # a fixed truth spreads at most as much as the Bayesian bound


def test_unified_encoder_rows_match_the_filter():
    """The unified state set (58 states: gimbal non-orthogonality and mount attitude observed through the
    encoder attitude rows, plugged in with register_rows): the bound = observability() within 1 %."""
    b = C.crlb("psins19", "unified")
    o = observability("psins19", "unified")
    assert b.setup.states.n_states == 58 and "mount_attitude[gamma0]" in b.labels
    assert np.max(np.abs(b.sigma / np.sqrt(np.diag(o.covariance)) - 1)) < 0.01
