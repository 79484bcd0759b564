"""The simulator's compiled single pass gives the numbers of the simulator before it.

The reference is the code as it was (``reference_simulator.py``: the integrals kernel, then the gimbal
angles, the error model with BLAS matrix products and the noise in NumPy/SciPy), run on the same
scenario with the same seed.  The increments agree to round-off: ``|new - old| <= 1e-12 max|old|``
per column (what is left is the order of the sums in the 3 x 3 products, about 3e-16); the sample
times agree exactly.  The random draws are the same calls of the same generators, so the noise is the
same numbers.

Beside it: the compiled error model and noise give exactly the numbers of their NumPy forms
(:meth:`ImuErrors.measure_increments`, :meth:`NoiseState.apply`), each term whose parameters are zero
is skipped without changing a bit, and neither the chunk size nor the pass size changes a bit.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import reference_simulator as ref

from inscal.core import turntable as tt
from inscal.core.error_model import ImuErrors, ImuNoise
from inscal.sim import scenarios
from inscal.sim import simulate as sim
from inscal.sim.simulate import NoiseState, simulate

RTOL = 1e-12
FIELDS = ("time", "dtheta", "dvel", "gimbal", "true_dtheta", "true_dvel")


def _all_noise_async() -> sim.Scenario:
    """Asynchrony, every error term, every noise source (Gauss-Markov on two gyro axes, quantization,
    encoder noise), gimbal non-orthogonality and mount attitude, on a short S16 Table 1 path."""
    base = scenarios.build("s16-gimbal")
    noise = ImuNoise(arw=1e-5, vrw=1e-4, gyro_bias_instability=[1e-6, 2e-6, 0.0], accel_bias_instability=1e-5,
                     gyro_bias_tau=100.0, gyro_quantization=1e-6, accel_quantization=1e-5, encoder_noise=1e-5)
    return dataclasses.replace(base, path=tt.s16_table1(dwell_s=10.0), imu=base.imu.replace(time_asynchrony=2.5e-3),
                               noise=noise)


#: name -> (scenario builder, chunk size): the paper scenarios whole, a rotation modulation with errors and
#: noise over several chunks, the perfect IMU, and every option at once in many small chunks
CASES = {
    "s16": (lambda: scenarios.build("s16"), 1 << 19),
    "psins19": (lambda: scenarios.build("psins19"), 1 << 19),
    "n25": (lambda: scenarios.build("n25"), 1 << 19),
    "n25-rotmod-1h": (lambda: scenarios.build("n25-rotmod", 3600.0), 100_003),
    "rotmod16-1h-perfect": (lambda: scenarios.build("rotmod16", 3600.0), 1 << 19),
    "async-every-noise": (_all_noise_async, 7777),
}


def _close(name, new, old):
    new, old = np.asarray(new), np.asarray(old)
    assert new.shape == old.shape, name
    scale = np.abs(old).max(axis=0)
    err = np.abs(new - old).max(axis=0)
    assert np.all(err <= RTOL * scale), (name, err / np.maximum(scale, 1e-300))


@pytest.mark.parametrize("case", list(CASES))
def test_same_numbers_as_before(case):
    build, chunk = CASES[case]
    sc = build()
    new = simulate(sc, np.random.default_rng(20240611), keep_truth=True, chunk_size=chunk)
    old = ref.simulate(sc, np.random.default_rng(20240611), keep_truth=True, chunk_size=chunk)
    assert np.array_equal(new.time, old[0])
    for k, name in enumerate(FIELDS[1:], start=1):
        _close(name, getattr(new, name), old[k])


def _short(imu: ImuErrors, **kw) -> sim.Scenario:
    base = scenarios.build("n25")
    path = tt.RotationPath("p", (tt.Move("outer", 47 * tt.DEG, 10 * tt.DEG, 0.5), tt.Move("inner", -60 * tt.DEG, 10 * tt.DEG, 1.0)),
                           accel=50 * tt.DEG, initial_dwell=1.0, closed=False)
    return dataclasses.replace(base, path=path, imu=imu, noise=ImuNoise(), **kw)


S16 = scenarios.s16_errors()
ZERO3, ZERO6 = np.zeros(3), np.zeros(6)
MODELS = {
    "perfect": ImuErrors(),
    "linear": S16.replace(gyro_g_sensitivity=np.zeros((3, 3)), accel_nonlinearity=ZERO3, accel_cross_coupling=ZERO6,
                          accel_lever_arm=ZERO3),
    "g-sensitivity": S16.replace(accel_nonlinearity=ZERO3, accel_cross_coupling=ZERO6, accel_lever_arm=ZERO3),
    "nonlinearity": S16.replace(accel_cross_coupling=ZERO6, accel_lever_arm=ZERO3),
    "cross-coupling": S16.replace(accel_nonlinearity=ZERO3, accel_lever_arm=ZERO3),
    "lever-arm": S16.replace(accel_nonlinearity=ZERO3, accel_cross_coupling=ZERO6),
    "full": S16,
}


@pytest.mark.parametrize("model", list(MODELS))
def test_compiled_error_model_is_measure_increments(model):
    """Bit for bit: the pass's error model and ImuErrors.measure_increments on the integrals (all six
    of them, even where the model skips some), for each subset of the terms."""
    sc = _short(MODELS[model])
    seg, n, dt = sc.path.segments(), sc.n_samples, 1.0 / sc.rate_hz
    dth, dv, f2, fx, dw = (np.empty((n, 3)) for _ in range(5))
    ww = np.empty((n, 6))
    sim._simulate_kernel(0, n, dt, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, tt.outer_axis(sc.gimbal.nonorthogonality),
                         np.ascontiguousarray(tt.C_b_n(sc.gimbal.mount_attitude)), sc.site.earth_rate_n,
                         sc.site.gravity, sim._GL_X, sim._GL_W, True, dth, dv, f2, fx, ww, dw)
    mdth, mdv = sc.imu.measure_increments(dt, dth, dv, f2, fx, ww, dw)
    d = simulate(sc, keep_truth=True, chunk_size=333)
    assert np.array_equal(d.true_dtheta, dth) and np.array_equal(d.true_dvel, dv)
    assert np.array_equal(d.dtheta, mdth) and np.array_equal(d.dvel, mdv)


@pytest.mark.parametrize("tau", [2.5e-3, -12e-3])
def test_compiled_asynchrony_is_measure_increments(tau):
    """Bit for bit with an asynchrony: the accelerometer window from the boundary integrals and the
    g-sensitivity on the gyro window (``dv_gyro``)."""
    imu = S16.replace(time_asynchrony=tau)
    sc = _short(imu)
    seg, n, dt = sc.path.segments(), sc.n_samples, 1.0 / sc.rate_hz
    u, Cbn = tt.outer_axis(sc.gimbal.nonorthogonality), np.ascontiguousarray(tt.C_b_n(sc.gimbal.mount_attitude))
    wie, g = sc.site.earth_rate_n, sc.site.gravity
    dth, dv, f2, fx, dw = (np.empty((n, 3)) for _ in range(5))
    ww = np.empty((n, 6))
    sim._simulate_kernel(0, n, dt, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie, g, sim._GL_X, sim._GL_W,
                         True, dth, dv, f2, fx, ww, dw)
    iv, if2, ifx, wdel = (np.empty((n + 1, 3)) for _ in range(4))
    iww = np.empty((n + 1, 6))
    sim._asynchrony_kernel(0, n + 1, dt, tau, seg.t0, seg.t1, seg.th0, seg.w0, seg.acc, u, Cbn, wie, g, sim._GL_X,
                           sim._GL_W, True, iv, if2, ifx, iww, wdel)
    mdth, mdv = imu.measure_increments(dt, dth, dv - iv[1:] + iv[:-1], f2 - if2[1:] + if2[:-1], fx - ifx[1:] + ifx[:-1],
                                       ww - iww[1:] + iww[:-1], wdel[1:] - wdel[:-1], dv_gyro=dv)
    d = simulate(sc, chunk_size=500)
    assert np.array_equal(d.dtheta, mdth) and np.array_equal(d.dvel, mdv)


def _unquantized() -> sim.Scenario:
    sc = _all_noise_async()
    return dataclasses.replace(sc, noise=dataclasses.replace(sc.noise, gyro_quantization=0.0, accel_quantization=0.0))


@pytest.mark.parametrize("case", ["s16", "async-every-noise", "unquantized"])
def test_compiled_noise_is_noise_state_apply(case):
    """Bit for bit: the noise the pass adds and NoiseState.apply on the noise-free record, chunk by chunk
    (the "reuse" mode of the Monte Carlo studies relies on it)."""
    build, chunk = CASES.get(case, (_unquantized, 7777))
    sc = build()
    d = simulate(sc, np.random.default_rng(5), chunk_size=chunk)
    clean = simulate(dataclasses.replace(sc, noise=ImuNoise()), chunk_size=chunk)
    state = NoiseState(sc.noise, np.random.default_rng(5), 1.0 / sc.rate_hz)
    parts = [state.apply(clean.dtheta[k:k + chunk], clean.dvel[k:k + chunk], clean.gimbal[k:k + chunk])
             for k in range(0, clean.time.size, chunk)]
    for i, name in enumerate(("dtheta", "dvel", "gimbal")):
        assert np.array_equal(getattr(d, name), np.concatenate([p[i] for p in parts])), name


def test_pass_and_chunk_sizes_change_no_bit(monkeypatch):
    sc = _all_noise_async()
    a = simulate(sc, np.random.default_rng(3), keep_truth=True)
    monkeypatch.setattr(sim, "PASS_ROWS", 97)
    b = simulate(sc, np.random.default_rng(3), keep_truth=True)
    c = simulate(sc, np.random.default_rng(3), keep_truth=True, chunk_size=1000)
    for name in FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert np.array_equal(getattr(a, name), getattr(c, name)), name


def test_zero_terms_are_not_computed():
    """What the pass is asked to do follows the parameters: nothing for a perfect IMU, no size effect
    without lever arms, no quadratic integrals without nonlinearity and cross-coupling, no noise work
    without noise."""
    k = sim
    assert sim.ModelArrays.of(ImuErrors()).opts == 0
    assert sim.ModelArrays.of(MODELS["linear"]).opts == k.O_MEASURE
    assert sim.ModelArrays.of(MODELS["lever-arm"]).opts == k.O_MEASURE | k.O_LEVER | k.O_GSENS
    assert sim.ModelArrays.of(MODELS["nonlinearity"]).opts == k.O_MEASURE | k.O_QUAD | k.O_GSENS
    assert sim.ModelArrays.of(S16).opts == k.O_MEASURE | k.O_QUAD | k.O_LEVER | k.O_GSENS
    opts, _ = NoiseState(ImuNoise(arw=1e-6), np.random.default_rng(0), 0.01).pass_arguments(10)
    assert opts == k.O_ARW
