"""Gauss-Markov bias states of the systematic filter (calibrate.systematic.gm_states): the GM columns of Phi
against finite differences of the nonlinear propagation, the exact AR(1) transition and noise, the noise model's
white and GM terms, and the refusals."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from inscal.calibrate.systematic.gm_states import gm_states, gm_step_arrays, noise_setup, white_noise
from inscal.calibrate.systematic.kernel import one_step
from inscal.calibrate.systematic.params import truth_in_frame
from inscal.calibrate.systematic.states import DEFAULT_SIGMA0, GMState, StateSet
from inscal.calibrate.windows import CalibrationError
from inscal.core import noise_models as nm
from inscal.core import units
from inscal.core.attitude import quat_from_dcm
from inscal.core.kinematics import true_attitude


def _model(gm_gyro=0.005, gm_accel=20.0, tc=600.0, bi=False):
    """A six-channel model: WN everywhere, one GM per channel (deg/h, ug), optionally a BI term on gx."""
    chans = []
    for name in ("gx", "gy", "gz", "ax", "ay", "az"):
        gyro = name[0] == "g"
        n = units.to_si(0.002, "deg/sqrt(h)") if gyro else units.to_si(10.0, "ug/sqrt(Hz)")
        s = units.to_si(gm_gyro, "deg/h") if gyro else units.to_si(gm_accel, "ug")
        terms = [nm.WhiteNoise(n), nm.GaussMarkov(s, tc)]
        if bi and name == "gx":
            terms.append(nm.BiasInstability(1e-8, 50.0))
        chans.append(nm.ChannelNoise(name, "gyro" if gyro else "accel", tuple(terms)))
    return nm.NoiseModel(tuple(chans), 100.0)


def test_noise_model_gives_white_noise_and_gm_states():
    m = _model()
    arw, vrw = white_noise(m)
    assert np.allclose(units.from_si(arw, "deg/sqrt(h)"), 0.002) and np.allclose(units.from_si(vrw, "ug/sqrt(Hz)"), 10)
    gm = gm_states(m)
    assert [(g.sensor, g.axis) for g in gm] == [("gyro", 0), ("gyro", 1), ("gyro", 2), ("accel", 0), ("accel", 1),
                                                ("accel", 2)]
    a, v, st, note = noise_setup(m, None, 1e-4, StateSet.parse("51"))
    assert v == 1e-4 and np.allclose(a, arw) and note is None
    assert st.n_dyn == 15 and st.n_states == 57 and st.labels()[9] == "gm_gyro_bias[x]"
    assert st.offsets()["gyro_matrix"] == 15
    _, _, _, note = noise_setup(_model(bi=True), None, None, StateSet.parse("51"))
    assert "gx: BI" in note
    with pytest.raises(CalibrationError, match="thermal"):
        noise_setup(m, None, None, StateSet.parse("51,thermal"))
    short = nm.NoiseModel(m.channels[:5], 100.0)
    with pytest.raises(CalibrationError, match="az"):
        noise_setup(short, None, None, StateSet.parse("51"))


def test_gm_step_constants_are_the_exact_ar1():
    st = StateSet(gm=(GMState("gyro", 1, 2e-8, 300.0), GMState("accel", 2, 1e-4, 50.0)))
    sig = np.ones(st.n_states)
    g = gm_step_arrays(st, sig, 2.0)
    assert np.allclose(g["phi"], [math.exp(-2.0 / 300.0), math.exp(-2.0 / 50.0)], rtol=1e-15)
    assert np.allclose(g["q"], [4e-16 * (1 - math.exp(-4.0 / 300.0)), 1e-8 * (1 - math.exp(-4.0 / 50.0))], rtol=1e-14)
    off = st.offsets()
    assert list(g["col"]) == [off["gyro_bias"] - st.n_dyn + 1, off["accel_bias"] - st.n_dyn + 2]


@pytest.mark.parametrize("t0", [180.2, 829.6])
def test_gm_columns_match_finite_differences(noise_free_data, nav_error, t0):
    """The navigation rows of each GM column over one 1-s step (a turning and a cruising one): central differences
    of the nonlinear propagation with the GM estimate offset (decaying sample by sample), and the transition
    exp(-T/tc) of the state itself."""
    sc, d = noise_free_data("s16")
    tc = 200.0  # the column's factor exp(-T/(2 tc)) is exact in the attitude rows to O((T/tc)^2), T/(6 tc) off in
    # the velocity rows (gm_states docstring): 8e-4 here, inside the tolerance of the parameter columns' test
    gm = (GMState("gyro", 0, 1e-7, tc), GMState("gyro", 2, 1e-7, tc), GMState("accel", 1, 1e-4, tc))
    st = StateSet(gm=gm)
    truth = truth_in_frame(sc.imu, StateSet())
    k0, n = int(round(t0 * sc.rate_hz)), int(sc.rate_hz)
    dth, dv, dt = d.dtheta[k0:k0 + n], d.dvel[k0:k0 + n], 1.0 / sc.rate_hz
    site = np.array([sc.site.latitude, sc.site.longitude, sc.site.height])
    C0, C1 = true_attitude(sc, np.array([t0, t0 + 1.0]))
    nav0 = np.concatenate([quat_from_dcm(C0), np.zeros(3), site])
    _, phinn, _ = one_step(dth, dv, dt, nav0, site, truth, st)
    rows = [0, 1, 2, 3, 4, 5, 8]  # horizontal positions in radians are too coarse for differences
    for g, gs in enumerate(gm):
        h = 1e-2 * DEFAULT_SIGMA0["gyro_bias" if gs.sensor == "gyro" else "accel_bias"]
        e = np.zeros(len(gm))
        e[g] = h
        xp = nav_error(one_step(dth, dv, dt, nav0, site, truth, st, gm_start=e)[0], C1, site)
        xm = nav_error(one_step(dth, dv, dt, nav0, site, truth, st, gm_start=-e)[0], C1, site)
        fd = (xp - xm) / (2 * h)
        col = phinn[:9, 9 + g]
        err = np.max(np.abs(fd[rows] - col[rows]))
        assert err <= 2e-3 * np.max(np.abs(fd[rows])) + 1e-14 / h, (g, fd, col)
        assert phinn[9 + g, 9 + g] == pytest.approx(math.exp(-1.0 / tc), rel=1e-14)
        assert np.all(phinn[9 + g, :9] == 0.0)


def test_calibration_setup_checks_the_noise_model_up_front(tmp_path):
    """``--noise``: read and checked before any record (one line each), and part of the options' identity."""
    from inscal.io.noisefile import write_noise
    from inscal.runs.calibration import CalibrationSetup

    good = tmp_path / "noise.toml"
    write_noise(good, _model())
    setup = CalibrationSetup("systematic51", states="51", noise=str(good))
    assert setup.problem() is None
    assert setup.options()["noise_model"][0]["term"][1]["type"] == "GM"
    assert setup.options() != CalibrationSetup("systematic51", states="51").options()
    assert "drop --arw" in CalibrationSetup("systematic51", arw=0.01, noise=str(good)).problem()
    assert CalibrationSetup("n25", noise=str(good)).problem() is None
    assert "window methods, not multi-position" in CalibrationSetup("multi-position", noise=str(good)).problem()
    assert "thermal" in CalibrationSetup("systematic51", states="51,thermal", noise=str(good)).problem()
    missing = CalibrationSetup("systematic51", noise=str(tmp_path / "none.toml")).problem()
    assert missing.startswith("--noise") and "\n" not in missing
    five = tmp_path / "five.toml"
    write_noise(five, nm.NoiseModel(_model().channels[:5], 100.0))
    assert "az" in CalibrationSetup("systematic51", noise=str(five)).problem()


def test_window_sigma_widened_by_the_slow_terms():
    """A rate random walk K widens each window by its Allan variance K^2 tau / 3 + K^2 dt^2 / (6 tau) (IEEE 952
    eq. C.12 with the discrete term) at the window's length or its spacing to the nearest window, whichever is
    longer; white noise alone widens nothing."""
    from inscal.calibrate.window_noise import widened

    rate, k = 100.0, 1e-7
    chans = tuple(nm.ChannelNoise(n, "gyro" if n[0] == "g" else "accel", (nm.WhiteNoise(1e-6), nm.RandomWalk(k)))
                  for n in ("gx", "gy", "gz", "ax", "ay", "az"))
    model = nm.NoiseModel(chans, rate)

    @dataclass(frozen=True)
    class Win:
        i0: int
        i1: int
        gyro_sigma: np.ndarray
        accel_sigma: np.ndarray

    wins = [Win(0, 2000, np.full(3, 1e-7), np.full(3, 1e-5)), Win(2500, 4500, np.full(3, 1e-7), np.full(3, 1e-5)),
            Win(20000, 21000, np.full(3, 1e-7), np.full(3, 1e-5))]
    out, info = widened(wins, model, rate)
    dt = 1.0 / rate
    for w, o, m in zip(wins, out, (2500.0, 2500.0, 17000.0)):  # spacing to the nearest centre, >= the length
        tau = m * dt
        add = k**2 * tau / 3 + k**2 * dt**2 / (6 * tau)
        assert np.allclose(o.gyro_sigma**2 - w.gyro_sigma**2, add, rtol=1e-12)
        assert np.allclose(o.accel_sigma**2 - w.accel_sigma**2, add, rtol=1e-9)
    assert [i["m"] for i in info] == [2500.0, 2500.0, 17000.0]
    white = nm.NoiseModel(tuple(nm.ChannelNoise(c.name, c.kind, c.terms[:1]) for c in chans), rate)
    same, _ = widened(wins, white, rate)
    assert all(np.array_equal(a.gyro_sigma, b.gyro_sigma) for a, b in zip(same, wins))


@pytest.fixture(scope="module")
def psins19_gm():
    """The psins19 unit and path (17 min, at 10 Hz) with gyro and accelerometer biases wandering as Gauss-Markov
    processes at 3x a navigation-grade level (0.009 deg/h, 30 ug, 300 s), seed 1, and the unit's noise model."""
    import dataclasses
    from types import SimpleNamespace

    from inscal.sim import scenarios
    from inscal.sim.simulate import simulate

    sc = scenarios.build("psins19", rate_hz=10.0)
    g, a, tc = units.to_si(0.009, "deg/h"), units.to_si(30.0, "ug"), 300.0
    sc = dataclasses.replace(sc, noise=dataclasses.replace(sc.noise, gyro_bias_instability=np.full(3, g),
                                                           gyro_bias_tau=tc, accel_bias_instability=np.full(3, a),
                                                           accel_bias_tau=tc))
    arw, vrw = np.broadcast_to(sc.noise.arw, (3,)), np.broadcast_to(sc.noise.vrw, (3,))
    chans = [nm.ChannelNoise(n, "gyro", (nm.WhiteNoise(float(arw[i])), nm.GaussMarkov(g, tc)))
             for i, n in enumerate(("gx", "gy", "gz"))]
    chans += [nm.ChannelNoise(n, "accel", (nm.WhiteNoise(float(vrw[i])), nm.GaussMarkov(a, tc)))
              for i, n in enumerate(("ax", "ay", "az"))]
    d = simulate(sc, np.random.default_rng(1))
    rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=sc.rate_hz, site=sc.site)
    return sc, rec, nm.NoiseModel(tuple(chans), 10.0)


def test_gm_states_cover_a_wandering_bias(psins19_gm):
    """The white-noise filter's sigma miss the error of a wandering bias by far (components beyond 10 sigma), the
    filter with the unit's model covers every component within 3 sigma (the seeds' statistics:
    bench/gm_states_study.py)."""
    from inscal.calibrate.systematic import systematic

    sc, rec, model = psins19_gm

    def worst(res):
        z = []
        for e in res.to_field((sc.imu, sc.gimbal)).values():
            err, s = np.asarray(e["error"], float), np.asarray(e["sigma"], float)
            z += list(np.abs(err[np.isfinite(s)] / s[np.isfinite(s)]))
        return max(z)

    assert worst(systematic(rec, "51")) > 10.0
    res = systematic(rec, "51", noise=model)
    assert worst(res) < 3.0
    assert res.diagnostics["states"] == 57 and len(res.diagnostics["noise"]["gauss_markov"]) == 6


def test_smoother_with_gm_states(psins19_gm):
    """The smoother of a pass with GM states (dynamic states 9 + 6): the constants' smoothed covariance at every
    stored step is the final filtered one, their smoothed error the feedback still to come, and the GM states'
    smoothed variances lie between 0 and their stationary prior (scaled: 1)."""
    from inscal.calibrate.systematic import systematic

    _, rec, model = psins19_gm
    out = systematic(rec, "51", noise=model, max_passes=1, keep_passes=True).pass_output
    n = 15
    assert out.smoother.phinn_st.shape[1:] == (n, n)
    pf = np.diag(out.Pf)[n:]
    d = np.diagonal(out.hist_P, axis1=1, axis2=2)
    np.testing.assert_allclose(d[:, n:], np.broadcast_to(pf, d[:, n:].shape), rtol=1e-10)
    assert np.all(d[:, 9:n] > 0) and np.all(d[:, 9:n] < 1.0 + 1e-9)
    for P in np.concatenate([out.P0s[None], out.hist_P]):  # positive definite at every stored step
        np.linalg.cholesky(P)
    sm = out.smoother
    fb = np.array([sm.K_st[k] @ np.linalg.solve(sm.Si_st[k], sm.sz_st[k]) for k in range(out.steps)])[:, n:]
    rem = np.cumsum(fb[::-1], axis=0)[::-1]
    assert np.max(np.abs(out.hist_x[:, n:] - rem[out.hist_step]) / np.sqrt(pf)) < 1e-6
