"""The systematic calibration's fast paths give what the straightforward forms give.

- the compiled scans of the record (inscal.calibrate.systematic.record_stats) equal, bit for bit, the NumPy
  expressions the driver used: the second-difference noise spread (exact medians), the quantum of a channel
  (radix-sorted distinct values), the first turn, the per-step rate features (NumPy's pairwise sums);
- the parameter columns of Phi_np from the per-step moments equal the sample-by-sample sum of
  e^{F (T - t_j)} F_np(t_j) dt to third order, for every column kind (asynchrony and shared pairs included);
- the reference-history error states and the canonical vector, computed on stacks and from the fields, equal
  the per-row ``error_state`` and ``flatten(to_imu())``;
- the adjoint recursion alone gives the smoothed states of the full smoother (bit for bit), so the driver runs
  the full smoother only for the pass it hands back (``keep_passes``), with the same result either way."""

from types import SimpleNamespace

import numpy as np
import pytest

from inscal.calibrate.result import flatten
from inscal.calibrate.systematic import driver
from inscal.calibrate.systematic import kernel as K
from inscal.calibrate.systematic import record_stats as R
from inscal.calibrate.systematic.dynamics import column_values, nav_F
from inscal.calibrate.systematic.jacobian import (
    N_BASIS,
    basis_values,
    column_layout,
    discretise,
    moment_weights,
    parameter_columns,
    step_moments,
)
from inscal.calibrate.systematic.params import (
    REF_SLICES,
    CompParams,
    canonical_flat,
    params_from_ref,
    ref_error_states,
)
from inscal.calibrate.systematic.states import K_GIM, K_LEVT, K_TAU, StateSet, estimated_names
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

SPECS = ("51", "30", "51,lever9,async", "psins", "unified", "51,gdiag,nocross", "51,lever9,async,levtime")


@pytest.fixture(scope="module")
def s16():
    """The first 1200 s of the s16 record (a dwell, then moves), with noise."""
    sc = scenarios.build("s16")
    d = simulate(sc, np.random.default_rng(3))
    n = int(1200 * sc.rate_hz)
    return SimpleNamespace(dtheta=d.dtheta[:n], dvel=d.dvel[:n], rate_hz=sc.rate_hz, site=sc.site)


def _channels(rec):
    rng = np.random.default_rng(4)
    quant = np.round(rng.standard_normal((5001, 3)) * 40.0) * 3e-7  # counts x scale factor
    spiked = rec.dtheta.copy()
    spiked[::997] *= 1e4  # outliers: a histogram over the full range puts the bulk in one bin
    return {"gyro": rec.dtheta, "accel": rec.dvel, "odd rows": rec.dtheta[:10001], "short": rec.dtheta[:7],
            "quantized": quant, "float32": rec.dvel.astype(np.float32).astype(float), "spiked": spiked,
            "constant": np.tile([1e-7, -2e-7, 0.0], (3000, 1)),
            "signed zeros": np.concatenate([np.zeros((20, 3)), -np.zeros((20, 3)), quant[:40]])}


def _old_noise(x, step):
    d2 = (x[2:] - 2.0 * x[1:-1] + x[:-2])[::step]
    return np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)


def _old_resolution(x, step):
    out = np.zeros(x.shape[1])
    for c in range(x.shape[1]):
        v = np.unique(x[::step, c])
        if v.size < 16:
            continue
        d = np.diff(v)
        d = d[d > 0]
        if d.size == 0:
            continue
        q = float(d.min())
        k = v / q
        if q > 0 and np.all(np.abs(k - np.round(k)) < 1e-3):
            out[c] = q
    return out


def _old_first_turn(dth, h, dt, thr):
    n = dth.shape[0]
    if n <= h:
        return n
    c = np.cumsum(dth, axis=0)
    idx = np.flatnonzero(np.linalg.norm(c[h:] - c[:-h], axis=1) / (h * dt) > thr)
    return int(idx[0]) if idx.size else n


def _old_rates(dtheta, dt, n_per, M):
    n = M * n_per
    w = dtheta[:n].reshape(M, n_per, 3) / dt
    mean_rate = np.linalg.norm(w, axis=2).mean(axis=1)
    dw = np.linalg.norm(np.diff(dtheta[:n + 1], axis=0), axis=1) / dt ** 2 if n > 1 else np.zeros(1)
    dw = np.concatenate([dw, np.zeros(max(0, n - dw.shape[0]))])[:n].reshape(M, n_per)
    return mean_rate, dw.max(axis=1), dw[:, -1]


def test_record_scans_equal_the_numpy_expressions(s16):
    for name, x in _channels(s16).items():
        x = np.ascontiguousarray(x, dtype=float)
        for step in (1, 3):
            assert np.array_equal(R.second_difference_mad(x, step), _old_noise(x, step)), (name, step)
            got = np.array([R.column_quantum(x, c, step) for c in range(3)])
            assert np.array_equal(got, _old_resolution(x, step)), (name, step)
            assert np.array_equal(R.sorted_column(x, 1, step), np.sort(x[::step, 1])), (name, step)
        assert R.first_turn(x, 50, 0.01, driver.ALIGN_STATIC_RATE) == _old_first_turn(x, 50, 0.01,
                                                                                        driver.ALIGN_STATIC_RATE), name
        for n_per in (1, 7, 100, 300):  # pairwise sums: below 8, up to 128 and above (halves)
            M = x.shape[0] // n_per
            for m in [m for m in {M, M - 1} if m > 0]:  # with and without the record's last sample
                for a, b in zip(R.step_rates(x, 0.01, 0.01 ** 2, n_per, m), _old_rates(x, 0.01, n_per, m)):
                    assert np.array_equal(a, b), (name, n_per, m)
    assert driver.data_resolution(_channels(s16)["quantized"]) == pytest.approx([3e-7] * 3, rel=1e-9)
    nan = s16.dtheta[:500].copy()
    nan[7, 1] = np.nan
    assert np.isnan(R.second_difference_mad(nan, 1)[1]) and np.all(np.isfinite(R.second_difference_mad(nan, 1)[[0, 2]]))


def test_pairwise_sum_is_numpy_reduce():
    rng = np.random.default_rng(6)
    for n in [1, 2, 7, 8, 9, 15, 16, 17, 127, 128, 129, 255, 256, 1000, 4099]:
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-6, 6, n)
        assert R.pairwise_sum(a, 0, n) == np.add.reduce(a), n


def _direct_columns(C, vals, wd, fdot, kinds, axes, F, T, dt, sd):
    """Phi_np column by column: sum_j (I + F s + F^2 s^2/2) G_j dt, s = T - t_j at the sample's middle (the
    expansion of the package docstring), G_j from dynamics.column_values."""
    n = C.shape[0]
    npar = kinds.shape[0]
    out = np.zeros((9, npar))
    for j in range(n):
        s = (n - j - 0.5) * dt
        E = np.eye(9) + F * s + F @ F * (s * s / 2.0)
        G = np.zeros((9, npar))
        for c in range(npar):
            rb = 0 if kinds[c] <= 2 else 3
            if kinds[c] == K_GIM:
                continue
            v = sd[j, axes[c]] if kinds[c] == K_LEVT else vals[j, c]  # the lever-arm timing: the basis' rate
            G[rb:rb + 3, c] = C[j] @ fdot[j] if kinds[c] == K_TAU else C[j][:, axes[c]] * v
        out += E[:, :6] @ G[:6] * dt
    return out


@pytest.mark.parametrize("spec", SPECS)
def test_parameter_columns_equal_the_sample_sum(spec):
    st = StateSet.parse(spec)
    kinds, axes, js = st.columns()
    npar = kinds.shape[0]
    rng = np.random.default_rng(7)
    n, dt = 50, 0.02
    T = n * dt
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    C = np.array([[[1 - 2 * (c * c + d * d), 2 * (b * c - a * d), 2 * (b * d + a * c)],
                   [2 * (b * c + a * d), 1 - 2 * (b * b + d * d), 2 * (c * d - a * b)],
                   [2 * (b * d - a * c), 2 * (c * d + a * b), 1 - 2 * (b * b + c * c)]] for a, b, c, d in q])
    ug, ua, w, f, wd, fdot, sd = (rng.standard_normal((n, 3)) for _ in range(7))
    vals = np.empty((n, npar))
    Bb = np.empty((N_BASIS, n))
    Cb = np.ascontiguousarray(C.reshape(n, 9).T)
    for j in range(n):
        column_values(kinds, axes, js, ug[j], ua[j], w[j], f[j], wd[j], fdot[j], vals[j])
        basis_values(ug[j], ua[j], w[j], f[j], wd[j], fdot[j], Bb, j, True, sd[j], True)
    start, src, col_sum, col_row, tau_pairs, _ = column_layout(kinds, axes, js, True)
    assert src.shape[0] < npar  # the biases of both triads share their pairs
    R_ = np.empty((src.shape[0], 3, 3))
    step_moments(Cb, Bb, moment_weights(n, dt), start, src, np.empty((3, 9, n)), R_)
    F = np.empty((9, 9))
    nav_F(0.6, 50.0, np.array([0.3, -0.2, 9.8]), F)
    F2, phinn, Qd, phinp = np.empty((9, 9)), np.empty((9, 9)), np.empty((9, 9)), np.empty((9, npar))
    sig = np.ones(9 + npar)
    discretise(F, T, 1e-12, 1e-10, sig, F2, phinn, Qd)
    parameter_columns(R_, col_sum, col_row, tau_pairs, F, F2, sig, phinp)
    ref = _direct_columns(C, vals, wd, fdot, kinds, axes, F, T, dt, sd)
    np.testing.assert_allclose(phinp, ref, rtol=1e-12, atol=1e-13 * np.max(np.abs(ref)))
    F3 = F @ F @ F
    np.testing.assert_allclose(phinn, np.eye(9) + F * T + F @ F * T * T / 2 + F3 * T ** 3 / 6, rtol=1e-14, atol=1e-16)
    np.testing.assert_array_equal(Qd, Qd.T)
    ev = np.linalg.eigvalsh(Qd)
    assert ev.min() >= -1e-12 * ev.max()


@pytest.mark.parametrize("spec", SPECS)
def test_stacked_error_states_and_fields_equal_the_objects(spec):
    st = StateSet.parse(spec)
    rng = np.random.default_rng(8)
    truth = CompParams.from_imu(scenarios.build("s16").imu)
    truth.gim = rng.standard_normal(4)
    rows = []
    for _ in range(20):
        p = truth.corrected(st, rng.standard_normal(st.n_params) * 1e-4)
        p.gim = truth.gim + rng.standard_normal(4) * 1e-3 + 2 * np.pi * rng.integers(-1, 2)
        rows.append(np.concatenate([np.ravel(getattr(p, k)) for k in REF_SLICES]))
    rows = np.array(rows)
    stacked = ref_error_states(rows, st, truth)
    assert np.array_equal(stacked, np.array([params_from_ref(r).error_state(st, truth) for r in rows]))
    names = estimated_names(st)
    for r in rows[:3]:
        p = params_from_ref(r)
        assert np.array_equal(canonical_flat(p, names), flatten(p.to_imu(), p.to_gimbal(), names))


@pytest.mark.parametrize("spec", ["51", "unified"])
def test_adjoint_recursion_alone_gives_the_smoothed_states(spec):
    sc = scenarios.build("s16")
    d = simulate(sc, np.random.default_rng(5))
    n = int(900 * sc.rate_hz)
    rec = SimpleNamespace(time=d.time[:n], dtheta=d.dtheta[:n], dvel=d.dvel[:n], gimbal=d.gimbal[:n],
                          rate_hz=sc.rate_hz, site=sc.site, path=sc.path)
    seen = {}

    def capture(*a, **kw):
        seen["args"] = (a, kw)
        raise RuntimeError("captured")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(driver, "run_pass", capture)
        with pytest.raises(RuntimeError, match="captured"):
            driver.systematic(rec, spec, filter_rate_hz=2.0, encoder_every=3)
    a, kw = seen["args"]
    light = K.run_pass(*[x.copy() if hasattr(x, "copy") else x for x in a], **(kw | {"smooth": False}))
    assert light.hist_P is None and light.P0s is None
    x_light, x0_light = light.hist_x.copy(), light.x0s.copy()
    full = K.smooth_pass(light)
    assert np.array_equal(full.hist_x, x_light) and np.array_equal(full.x0s, x0_light)
    # the driver: the same result with and without the pass kept (and its full smoother)
    r1 = driver.systematic(rec, spec, filter_rate_hz=2.0, encoder_every=3, max_passes=2)
    r2 = driver.systematic(rec, spec, filter_rate_hz=2.0, encoder_every=3, max_passes=2, keep_passes=True)
    assert np.array_equal(flatten(r1.imu, r1.gimbal, r1.estimated), flatten(r2.imu, r2.gimbal, r2.estimated))
    for key in ("filtered", "filtered_sigma", "mbf"):
        assert np.array_equal(r1.history[key], r2.history[key])
    assert r2.pass_output.hist_P is not None and r2.pass_output.P0s is not None


def test_lever_timing_rate_is_the_derivative_of_a_delayed_lever_arm_acceleration():
    """``lever_timing_rate`` against finite differences of its definition on a rotation about a fixed axis with a
    varying rate (angle ``0.3 sin(1.3 t)``, all three time derivatives known in closed form): the lever-arm
    acceleration of each accelerometer taken ``delta`` earlier in navigation axes and sensed along the body axis
    now, ``e_i . C_b^n(t)^T C_b^n(t - delta) L_i(t - delta)``, has the slope ``-sd_i`` in ``delta``."""
    from scipy.spatial.transform import Rotation

    from inscal.calibrate.systematic.dynamics import lever_timing_rate

    e = np.array([0.48, -0.6, 0.64])
    e /= np.linalg.norm(e)
    lev = np.array([[0.03, -0.04, 0.02], [0.041, -0.014, 0.009], [-0.043, 0.044, 0.044]])

    def th(t, k):  # k-th derivative of the angle
        return 0.3 * 1.3 ** k * (np.sin, np.cos, lambda x: -np.sin(x), lambda x: -np.cos(x))[k](1.3 * t)

    def C(t):
        return Rotation.from_rotvec(th(t, 0) * e).as_matrix()

    def L(t, i):
        w, wd = th(t, 1) * e, th(t, 2) * e
        return np.cross(wd, lev[i]) + np.cross(w, np.cross(w, lev[i]))

    t, h = 0.7, 1e-4
    sd = np.empty(3)
    lever_timing_rate(lev, th(t, 1) * e, th(t, 2) * e, th(t, 3) * e, sd)
    for i in range(3):
        g = [C(t).T @ C(t - d) @ L(t - d, i) for d in (h, -h)]
        slope = (g[0][i] - g[1][i]) / (2 * h)
        assert slope == pytest.approx(-sd[i], rel=1e-6, abs=1e-12)
    assert np.max(np.abs(sd)) > 1e-3  # a real rate: the check can fail
