"""The unified estimator (calibrate.unified: the systematic filter with the N25 gimbal states and
the encoder attitude rows): H columns and the new Phi columns against finite differences of the
nonlinear models, the sequential update and its MBF smoother against the dense RTS form, the
state-set options, noise-free recovery on the s16-gimbal scenario, and what systematic51 and n25
leave out on such records."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from inscal.core import kalman as filters, units
from inscal.sim import scenarios
from inscal.calibrate.windows import CalibrationError
from inscal.calibrate import calibrate
from inscal.calibrate.systematic.params import CompParams, truth_in_frame
from inscal.calibrate.systematic.states import DEFAULT_SIGMA0, FRAME_GIMBAL, StateSet
from inscal.core.kalman import update_dense
from inscal.calibrate.unified import measurement, predicted_attitude, residual, state_set
from inscal.core.error_model import ImuNoise
from inscal.sim.simulate import simulate

AS = units.to_si(1.0, "arcsec")
TOL = {"ppm": 0.05, "arcsec": 0.03, "deg/h": 0.001, "ug": 0.05, "ug/g^2": 0.05, "cm": 0.005, "deg/h/g": 0.001}
GIMBALS = [np.array([20 * AS, math.radians(0.1), math.radians(0.1), math.radians(20.0)]),
           np.array([2e-3, -0.3, 0.2, 2.5])]  # the s16-gimbal values, and a large tilt of the outer axis
ANGLES = [(0.0, 0.0), (0.5 * math.pi, 0.3), (math.pi, -1.1), (-2.0, 2.9), (1.234, 0.5 * math.pi)]


def _rotvec(v):
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(v).as_matrix()


def smoother_step_dense(lam, Lam, H, K, Sinv, sz):
    """The MBF step of :func:`inscal.core.kalman.smoother_step` for a dense ``H`` (the reference the
    square-root smoother replaced; kept here as the textbook form): ``lam <- H^T S^-1 nu + (I - K H)^T lam``,
    ``Lam <- H^T S^-1 H + (I - K H)^T Lam (I - K H)``, in place."""
    N = lam.shape[0]
    m = H.shape[0]
    d = np.empty(m)
    for a in range(m):
        s = sz[a]
        for i in range(N):
            s -= K[i, a] * lam[i]
        d[a] = s
    for i in range(N):
        s = 0.0
        for a in range(m):
            s += H[a, i] * d[a]
        lam[i] += s
    LK = Lam @ K  # (N, m)
    C = K.T @ LK + Sinv  # (m, m)
    B = LK @ H  # Lam K H (N, N)
    HtC = H.T @ C  # (N, m)
    add = HtC @ H
    for i in range(N):
        for j in range(i, N):
            v = 0.5 * (Lam[i, j] + Lam[j, i]) - B[i, j] - B[j, i] + 0.5 * (add[i, j] + add[j, i])
            Lam[i, j] = v
            Lam[j, i] = v


# ----------------------------------------------------------------------------- H and R
@pytest.mark.parametrize("gim", GIMBALS)
@pytest.mark.parametrize("tx,tz", ANGLES)
def test_H_columns_match_finite_differences(gim, tx, tz):
    """z = vee(C_nav C_pred^T): columns on the attitude error (I) and on [dth, alpha0, beta0, gamma0]
    (N25 eq. 5-8, 34-36) against central differences of the nonlinear residual; the encoder-noise
    directions of R against differences in the encoder angles."""
    C = predicted_attitude(gim, tx, tz)
    H_phi, H_g, R = measurement(gim, tx, tz, encoder_sigma=AS)
    np.testing.assert_allclose(residual(C, gim, tx, tz), 0.0, atol=1e-15)
    h = 1e-6
    for j in range(3):  # C_nav = exp([phi x]) C_true
        e = np.zeros(3)
        e[j] = h
        fd = (residual(_rotvec(e) @ C, gim, tx, tz) - residual(_rotvec(-e) @ C, gim, tx, tz)) / (2 * h)
        np.testing.assert_allclose(fd, H_phi[:, j], atol=1e-9)
    for j in range(4):  # gimbal estimate = truth + h e_j
        e = np.zeros(4)
        e[j] = h
        fd = (residual(C, gim + e, tx, tz) - residual(C, gim - e, tx, tz)) / (2 * h)
        np.testing.assert_allclose(fd, H_g[:, j], atol=1e-9)
    # encoder noise: z moves along -a (outer) and -c (inner) per unit angle, R = s^2 J J^T + floor
    J = np.column_stack([(residual(C, gim, tx + h, tz) - residual(C, gim, tx - h, tz)) / (2 * h),
                         (residual(C, gim, tx, tz + h) - residual(C, gim, tx, tz - h)) / (2 * h)])
    np.testing.assert_allclose(R, AS**2 * (J @ J.T + 0.01 * np.eye(3)), rtol=0, atol=1e-9 * AS**2)
    # with dth = 0 the dth column is the derivative of Rot(u(dth), tx) at dth = 0: C_b^n [0, -(1 - cos tx), sin tx]
    g0 = gim.copy()
    g0[0] = 0.0
    Cbn = predicted_attitude(g0, 0.0, 0.0)
    np.testing.assert_allclose(-measurement(g0, tx, tz)[1][:, 0], Cbn @ [0.0, -(1 - math.cos(tx)), math.sin(tx)],
                               atol=1e-15)


def test_predicted_attitude_is_the_turntable_model():
    from inscal.core.turntable import C_b_n, C_s_b

    for gim in GIMBALS:
        for tx, tz in ANGLES:
            np.testing.assert_allclose(predicted_attitude(gim, tx, tz),
                                       C_b_n(gim[1:]) @ C_s_b(tx, tz, gim[0]), atol=1e-15)


# ----------------------------------------------------------------------------- sequential update + smoother
def test_sequential_dense_update_and_smoother_equal_the_dense_rts():
    """Two updates per step (selection rows with filters.update, then dense rows with _update_h) and
    their MBF smoother (_smoother_step_h first) equal one stacked update and the textbook RTS
    smoother (filters.dense_rts) on a random linear system; _update_h / _smoother_step_h with a
    selection H equal filters.update / filters.smoother_step."""
    rng = np.random.default_rng(3)
    n, p, M = 4, 3, 12
    N = n + p
    idx = np.array([1, 3], np.int64)
    r = np.array([0.3, 0.5])
    Phis = [np.block([[np.eye(n) + 0.1 * rng.standard_normal((n, n)), 0.2 * rng.standard_normal((n, p))],
                      [np.zeros((p, n)), np.eye(p)]]) for _ in range(M)]
    Q = np.zeros((N, N))
    Q[:n, :n] = 0.01 * np.eye(n)
    Hb = rng.standard_normal((3, N))
    A = rng.standard_normal((3, 3))
    Rb = A @ A.T + 0.1 * np.eye(3)
    zs = rng.standard_normal((M, 5))
    # ---- sequential filter (open loop), stored as the kernel stores it
    x, P = np.zeros(N), np.eye(N)
    xf, Pf, xp, Pp = [x.copy()], [P.copy()], [None], [None]
    store = []
    for k in range(M):
        x = Phis[k] @ x
        filters.predict(P, n, np.ascontiguousarray(Phis[k][:n, :n]), np.ascontiguousarray(Phis[k][:n, n:]),
                        Q[:n, :n].copy(), np.zeros(p))
        xp.append(x.copy())
        Pp.append(P.copy())
        Ka, Sa, xa = np.empty((N, 2)), np.empty((2, 2)), np.empty(N)
        nu_a = zs[k, :2] - x[idx]
        filters.update(P, idx, r, nu_a, Ka, Sa, xa)
        x = x + xa
        Kb, Sb, xb = np.empty((N, 3)), np.empty((3, 3)), np.empty(N)
        nu_b = zs[k, 2:] - Hb @ x
        update_dense(P, Hb, Rb, nu_b, Kb, Sb, xb)
        x = x + xb
        xf.append(x.copy())
        Pf.append(P.copy())
        store.append((Ka, Sa, Sa @ nu_a, Kb, Sb, Sb @ nu_b))
    # ---- the same with one stacked update
    H = np.vstack([np.eye(N)[idx], Hb])
    Rf = np.zeros((5, 5))
    Rf[:2, :2] = np.diag(r)
    Rf[2:, 2:] = Rb
    for k in range(M):
        Sk = H @ Pp[k + 1] @ H.T + Rf
        K = Pp[k + 1] @ H.T @ np.linalg.inv(Sk)
        np.testing.assert_allclose(xp[k + 1] + K @ (zs[k] - H @ xp[k + 1]), xf[k + 1], atol=1e-10)
        np.testing.assert_allclose((np.eye(N) - K @ H) @ Pp[k + 1], Pf[k + 1], atol=1e-10)
    xs_d, Ps_d = filters.dense_rts(xf, Pf, xp, Pp, [None] + Phis)
    # ---- MBF backwards, the dense rows first
    lam, Lam = np.zeros(N), np.zeros((N, N))
    for k in range(M - 1, -1, -1):
        Ka, Sa, sza, Kb, Sb, szb = store[k]
        smoother_step_dense(lam, Lam, Hb, Kb, Sb, szb)
        filters.smoother_step(lam, Lam, idx, Ka, Sa, sza)
        dx, Ps = filters.smoothed(Pp[k + 1], lam, Lam)
        np.testing.assert_allclose(xp[k + 1] + dx, xs_d[k + 1], atol=1e-9)
        np.testing.assert_allclose(Ps, Ps_d[k + 1], atol=1e-9)
        filters.adjoint_back(lam, Lam, n, np.ascontiguousarray(Phis[k][:n, :n]), np.ascontiguousarray(Phis[k][:n, n:]))
    dx, Ps = filters.smoothed(np.eye(N), lam, Lam)
    np.testing.assert_allclose(dx, xs_d[0], atol=1e-9)
    np.testing.assert_allclose(Ps, Ps_d[0], atol=1e-9)
    # ---- dense routines with a selection H equal the selection ones
    P0 = Pp[5].copy()
    P1, P2 = P0.copy(), P0.copy()
    K1, S1, x1, K2, S2, x2 = np.empty((N, 2)), np.empty((2, 2)), np.empty(N), np.empty((N, 2)), np.empty((2, 2)), np.empty(N)
    n1 = filters.update(P1, idx, r, zs[0, :2], K1, S1, x1)
    n2 = update_dense(P2, np.eye(N)[idx], np.diag(r), zs[0, :2], K2, S2, x2)
    np.testing.assert_allclose([n1, *x1, *P1.ravel()], [n2, *x2, *P2.ravel()], rtol=1e-12, atol=1e-14)
    l1, L1 = rng.standard_normal(N), np.eye(N) + 0.1
    l2, L2 = l1.copy(), L1.copy()
    filters.smoother_step(l1, L1, idx, K1, S1, S1 @ zs[0, :2])
    smoother_step_dense(l2, L2, np.eye(N)[idx], K1, S1, S1 @ zs[0, :2])
    np.testing.assert_allclose(l1, l2, atol=1e-13)
    np.testing.assert_allclose(L1, L2, atol=1e-13)


# ----------------------------------------------------------------------------- state sets
def test_state_set_options():
    st = StateSet.parse("unified")
    assert st.n_states == 58 and st.gimbal and st.extended and st.frame == "gimbal"
    assert st == state_set()
    assert StateSet.parse("51,gimbal") == st
    assert StateSet.parse("30,gimbal").n_states == 30 + 3 + 4
    assert StateSet.parse("unified,lever9").n_states == 58 + 6
    labels = st.labels()
    assert labels[-4:] == ["gimbal_nonorthogonality", "mount_attitude[alpha0]", "mount_attitude[beta0]",
                           "mount_attitude[gamma0]"]
    assert sum(1 for lab in labels if lab.startswith("gyro_matrix")) == 9
    with pytest.raises(CalibrationError, match="exclude"):
        StateSet.parse("51,psins,gimbal")
    # round trip of the gimbal part of the parameters
    p = CompParams()
    p.gim = GIMBALS[0].copy()
    x = np.linspace(-1, 1, st.n_params) * 1e-6
    np.testing.assert_allclose(p.corrected(st, x).error_state(st, p), -x, rtol=1e-5, atol=1e-14)
    g = p.to_gimbal()
    assert g.nonorthogonality == p.gim[0] and np.all(g.mount_attitude == p.gim[1:])


# ----------------------------------------------------------------------------- records
def _rec(d, sc, gimbal=True):
    return SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal if gimbal else None, time=d.time,
                           rate_hz=sc.rate_hz, site=sc.site, path=sc.path)


@pytest.fixture(scope="module")
def s16_gimbal_noise_free(noise_free_data):
    return noise_free_data("s16-gimbal")


def test_new_Phi_columns_match_finite_differences(s16_gimbal_noise_free, step_columns):
    """The columns the unified set adds to Phi_np: the upper gyro-matrix entries (the s-frame set) and
    the gimbal states (zero: they do not enter the navigation), over 1 s at the start of an outer
    rotation, against differences of the nonlinear propagation (the harness of test_systematic.py)."""
    sc, d = s16_gimbal_noise_free
    st = StateSet.parse("unified")
    truth = truth_in_frame(sc.imu, st, sc.gimbal)
    x0, phinn, phinp, propagate, _, _ = step_columns(sc, d, st, truth, 180.2)
    assert np.max(np.abs(x0)) < 1e-6
    labels = st.labels()[9:]
    cols = [labels.index(f"gyro_matrix[{ij}]") for ij in ("xy", "xz", "yz")]
    cols += [c for c, lab in enumerate(labels) if lab.startswith(("gimbal_", "mount_"))]
    rows = [0, 1, 2, 3, 4, 5, 8]
    for c in cols:
        gname = labels[c].split("[")[0]
        h = 1e-2 * DEFAULT_SIGMA0[gname]
        e = np.zeros(st.n_params)
        e[c] = h
        fd = (propagate(truth.corrected(st, -e)) - propagate(truth.corrected(st, e))) / (2 * h)
        if gname == "gyro_matrix":
            assert np.max(np.abs(fd[rows] - phinp[rows, c])) <= 2e-3 * np.max(np.abs(fd[rows])) + 1e-12, labels[c]
            assert np.max(np.abs(fd[rows])) > 1e-5  # a rotation about x turns the outer-rotation rate into y, z
        else:
            assert np.all(phinp[:, c] == 0.0) and np.all(fd == 0.0), labels[c]


def test_noise_free_recovery_s16_gimbal(s16_gimbal_noise_free):
    """S16 section 4.1 errors plus dth = 20" and mount [0.1, 0.1, 20] deg on the S16 path with encoders:
    every S16 parameter (with all 6 installation angles per triad, in the gimbal frame) and the
    gimbal parameters to the noise-free tolerances; systematic51 on the same record does not
    estimate the gimbal (its dth stays 0, i.e. 20" off) and refers its errors to the gyro frame."""
    sc, d = s16_gimbal_noise_free
    rec = _rec(d, sc)
    res = calibrate(rec, "unified")
    assert res.method == "unified" and res.diagnostics["states"] == 58 and res.diagnostics["converged"]
    assert res.diagnostics["frame"] == FRAME_GIMBAL and res.diagnostics["encoder"]["updates"] > 3800
    errs = {}
    for name, e in res.to_field((sc.imu, sc.gimbal)).items():
        errs[name] = float(np.nanmax(np.abs(e["error"])))
        assert errs[name] <= TOL[e["unit"]], (name, e)
        if name.endswith("misalignment"):  # no angle is fixed by a frame definition
            assert np.all(np.isfinite(e["sigma"])), name
    assert errs["gimbal_nonorthogonality"] < 1e-3 and errs["mount_attitude"] < 1e-2  # arcsec
    assert res.gimbal.nonorthogonality == pytest.approx(20 * AS, abs=1e-3 * AS)
    # systematic51: no gimbal states, gyro-frame parameters (= the s-frame here: the truth's gyro
    # misalignment is lower-triangular), the IMU errors are still recovered
    r51 = calibrate(_rec(d, sc, gimbal=False), "systematic51")
    assert "gimbal_nonorthogonality" not in r51.estimated and r51.gimbal.nonorthogonality == 0.0
    assert abs(r51.gimbal.nonorthogonality - sc.gimbal.nonorthogonality) == pytest.approx(20 * AS)
    assert "gyro-defined" in r51.diagnostics["frame"]


def test_unified_uses_the_path_without_encoders_and_refuses_without_either(s16_gimbal_noise_free):
    sc, d = s16_gimbal_noise_free
    n = int(600 * sc.rate_hz)  # 10 min: enough to run, not to converge
    rec = SimpleNamespace(dtheta=d.dtheta[:n], dvel=d.dvel[:n], gimbal=None, time=d.time[:n], rate_hz=sc.rate_hz,
                          site=sc.site, path=sc.path)
    res = calibrate(rec, "unified", max_passes=1, encoder_every=5)
    assert res.diagnostics["encoder"]["updates"] == 120
    rec.path = None
    with pytest.raises(CalibrationError, match="encoder angles"):
        calibrate(rec, "unified", max_passes=1)
    rec.gimbal = d.gimbal[:n]
    with pytest.raises(CalibrationError, match="encoder sigma"):
        calibrate(rec, "unified", max_passes=1, encoder_sigma=0.0)


def test_n25_ignores_the_extended_terms():
    """n25 on the N25 path with the S16 IMU (quadratic terms, lever arms, g-sensitivity): the terms it
    does not model leave ~100 ug in its accelerometer bias and ~0.1" in dth (noise-free)."""
    g = scenarios.build("s16-gimbal")
    sc = dataclasses.replace(scenarios.build("n25"), imu=g.imu, gimbal=g.gimbal, noise=ImuNoise())
    res = calibrate(_rec(simulate(sc), sc), "n25")
    f = res.to_field((sc.imu, sc.gimbal))
    assert "accel_nonlinearity" not in res.estimated
    assert np.max(np.abs(f["accel_bias"]["error"])) > 50.0  # ug: 300 ug/g^2 x g^2 taken for a bias
    assert np.max(np.abs(f["gimbal_nonorthogonality"]["error"])) > 0.03  # arcsec


def test_cli_unified_on_a_noisy_record(tmp_path):
    """``inscal simulate s16-gimbal`` (noise, 1" encoders; 50 Hz to save time) then ``inscal calibrate
    --method unified --encoder-sigma 1``: the parameter file carries the gimbal, the errors stay
    within a few sigma, the encoder innovations match their expectation; the option is refused for
    a window-mean method."""
    import json

    from typer.testing import CliRunner

    from inscal.cli.app import app
    from inscal.io.paramfile import load_params

    runner = CliRunner()
    run = lambda *a: runner.invoke(app, [str(x) for x in a])  # noqa: E731
    data = tmp_path / "r.h5"
    assert run("simulate", "s16-gimbal", "--out", data, "--seed", 7, "--rate-hz", 50).exit_code == 0
    r = run("calibrate", data, "--method", "unified", "--encoder-sigma", 1, "--out", tmp_path / "p.toml", "--json")
    assert r.exit_code == 0, r.stdout
    rep = json.loads(r.stdout)
    assert rep["method"] == "unified" and rep["states"] == 58 and rep["frame"] == FRAME_GIMBAL
    enc = rep["encoder"]
    assert enc["sigma_arcsec"] == 1.0 and 2.0 <= enc["nis_expected"] <= 3.0
    assert abs(enc["nis_mean"] - enc["nis_expected"]) < 0.05 * enc["nis_expected"]
    par = rep["parameters"]
    for name in ("gimbal_nonorthogonality", "mount_attitude", "accel_bias", "accel_nonlinearity", "gyro_misalignment"):
        e, s = np.array(par[name]["error"]), np.array(par[name]["sigma"])
        assert np.all(np.abs(e) < 5 * s), (name, e, s)
    assert par["gimbal_nonorthogonality"]["sigma"][0] < 0.05  # arcsec
    imu, gim, meta = load_params(tmp_path / "p.toml")
    assert gim.nonorthogonality == pytest.approx(units.to_si(par["gimbal_nonorthogonality"]["value"][0], "arcsec"))
    r = run("calibrate", data, "--method", "n25", "--encoder-sigma", 1, "--out", tmp_path / "q.toml")
    assert r.exit_code != 0 and "--encoder-sigma" in r.output
