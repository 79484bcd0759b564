"""Observability of a rotation path without data: inscal.plan.observability
and ``inscal observability``."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.core import earth
from inscal.plan.observability import DEFAULT_VRW, RANK_TOL, ObservabilityError, _triangular_factor, observability, verdict
from inscal.cli.app import app
from inscal.sim.scenarios import S16_SITE
from inscal.core.turntable import Move, RotationPath, static

DEG = math.pi / 180.0
runner = CliRunner()

SCALE_AND_QUADRATIC = ("gyro_matrix", "accel_matrix", "gyro_g_sensitivity", "accel_nonlinearity",
                       "accel_cross_coupling")


def inner_only(dwell=60.0):
    """Turns about the inner axis only (IMU z stays up): 4 x +90 then 4 x -90 deg at 5 deg/s."""
    turns = [Move("inner", 90 * DEG, 5 * DEG, dwell)] * 4 + [Move("inner", -90 * DEG, 5 * DEG, dwell)] * 4
    return RotationPath("inner-only", tuple(turns), initial_dwell=dwell)


@pytest.fixture(scope="module")
def s16():
    return observability("s16", "51")


@pytest.fixture(scope="module")
def still():
    return observability(static(600.0), "51")  # bare path: S16 site and noise


@pytest.fixture(scope="module")
def inner():
    return observability(inner_only(), "51")


def test_verdict_thresholds():
    assert [verdict(r) for r in (0.0, 0.00999, 0.01, 0.0999, 0.1, 0.4999, 0.5, 1.0)] == [
        "well observed", "well observed", "observed", "observed", "weak", "weak", "unobservable", "unobservable"]


def test_s16_every_group_observed(s16):
    """S16 Table 1 with the S16 noise: every state observed, the diagonal g-sensitivity weak."""
    assert (s16.n_states, s16.n_params, s16.steps) == (51, 42, 3861)
    for s in s16.states:
        if s.group == "gyro_g_sensitivity" and s.component in ("xx", "yy", "zz"):
            assert s.verdict == "weak" and 0.1 < s.ratio < 0.3, s
        else:
            assert s.ratio < 0.1, s
        assert math.isclose(s.posterior, s.ratio * s.prior, rel_tol=1e-12)
    assert s16.by_label("accel_bias[x]").unit == "ug" and s16.by_label("accel_bias[x]").prior == pytest.approx(1000)
    assert s16.rank == 42 and s16.full_rank == 51
    # the weakest direction of the observability matrix is a diagonal g-sensitivity combination
    top = [lab for lab, _ in s16.weakest[0].components[:3]]
    assert sorted(top) == ["gyro_g_sensitivity[xx]", "gyro_g_sensitivity[yy]", "gyro_g_sensitivity[zz]"]
    assert np.all(np.diff(s16.singular_values) <= 0) and s16.singular_values[0] == 1.0
    # the transition pass reproduces systematic()'s posterior; finite over the 1.07 h path
    assert s16.consistency < 1e-4
    assert np.all(np.isfinite(s16.full_singular_values)) and 1e2 < s16.vertical_growth < 1e4


def test_state_counts():
    rep = observability(static(300.0), "30")
    assert (rep.n_states, rep.n_params) == (30, 21)
    assert {s.group for s in rep.states} == {"gyro_matrix", "gyro_bias", "accel_matrix", "accel_bias"}


def test_static_unobservable(still, s16):
    """No rotation: scale factors, misalignments and quadratic terms stay at their prior."""
    for s in still.states:
        if s.group in SCALE_AND_QUADRATIC + ("accel_lever_arm",):
            assert s.ratio > 0.5, s
    # three parameter combinations: the vertical accelerometer channel and the North and Up
    # gyro channels (East gyro and horizontal accelerometer errors look like initial attitude)
    assert still.rank == 3 < s16.rank
    assert still.full_rank == 9 + 3
    assert still.singular_values[2] > 1e3 * RANK_TOL > 1e3 * still.singular_values[3]


def test_static_vertical_channel_closed_form(still):
    """Static level IMU, z up: the filter sees only df_z = g dKA_zz - db_az - g^2 dK2_z, through
    the vertical velocity (measured every second, VRW white noise): sigma = VRW / sqrt(T)."""
    labels = [s.label for s in still.states]
    g = S16_SITE.gravity
    a = np.zeros(len(labels))
    a[labels.index("accel_matrix[zz]")] = g
    a[labels.index("accel_bias[z]")] = -1.0
    a[labels.index("accel_nonlinearity[z]")] = -g * g
    sig = math.sqrt(a @ still.covariance @ a)
    assert sig == pytest.approx(DEFAULT_VRW / math.sqrt(600.0), rel=0.1)
    # three terms of (nearly) equal prior, their sum known exactly: each keeps sqrt(2/3) of its sigma
    for lab in ("accel_matrix[zz]", "accel_bias[z]", "accel_nonlinearity[z]"):
        assert still.by_label(lab).ratio == pytest.approx(math.sqrt(2 / 3), rel=0.01)
    # vertical channel: an initial height error grows like cosh(t sqrt(2 g / R))
    rm, rn = earth.radii(S16_SITE.latitude)
    assert still.vertical_growth == pytest.approx(math.cosh(600 * math.sqrt(2 * g / math.sqrt(rm * rn))), rel=0.01)


def test_inner_axis_only(inner, still, s16):
    """Turning only about the inner axis (IMU z up throughout) leaves the z accelerometer
    channel, the z lever arm and the terms needing horizontal gravity unobservable."""
    r = inner.ratios()
    unobservable = ["accel_bias[z]", "accel_matrix[zz]", "accel_nonlinearity[z]", "accel_lever_arm[z]",
                    "accel_nonlinearity[x]", "accel_nonlinearity[y]", "gyro_g_sensitivity[xx]",
                    "gyro_g_sensitivity[yy]"] + [f"accel_cross_coupling[{c}]" for c in ("xy", "xz", "yx", "yz", "zx", "zy")]
    for lab in unobservable:
        assert r[lab] > 0.5, lab
    # horizontal bias and xz/yz misalignment: one combination each (g along z), 1/sqrt(2) each
    for lab in ("accel_bias[x]", "accel_matrix[xz]"):
        assert r[lab] == pytest.approx(math.sqrt(0.5), rel=0.02)
    # what turning about z does give: the z gyro scale factor, the horizontal lever arms
    for lab in ("gyro_matrix[zz]", "accel_lever_arm[x]", "accel_lever_arm[y]"):
        assert r[lab] < 0.01, lab
    assert still.rank < inner.rank < s16.rank


def test_triangular_factor_matches_dense():
    """R from the streaming Householder update has the singular values of the stacked O."""
    rng = np.random.default_rng(3)
    M, p = 200, 5
    phinn = np.eye(9) + 0.05 * rng.standard_normal((M, 9, 9))
    phinp = rng.standard_normal((M, 9, p))
    r = rng.uniform(0.5, 2.0, 6)
    rows, A, B, a88 = [], np.eye(9), np.zeros((9, p)), 1.0
    for k in range(M):
        A, B = phinn[k] @ A, phinn[k] @ B + phinp[k]
        rows.append(np.hstack([A[3:], B[3:]]) / np.sqrt(r)[:, None])
        a88 = max(a88, abs(A[8, 8]))
    O = np.vstack(rows)
    R, growth = _triangular_factor(phinn, phinp, r)
    assert np.allclose(np.tril(R, -1), 0.0)
    np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False), np.linalg.svd(O, compute_uv=False), rtol=1e-9)
    assert growth == pytest.approx(a88, rel=1e-12)


def test_triangular_factor_with_encoder_rows():
    """Encoder attitude rows (3 per step where used) are stacked with the velocity/position rows."""
    rng = np.random.default_rng(4)
    M, p = 150, 6
    phinn = np.eye(9) + 0.05 * rng.standard_normal((M, 9, 9))
    phinp = rng.standard_normal((M, 9, p))
    r = rng.uniform(0.5, 2.0, 6)
    W = rng.standard_normal((M, 3, 9 + p))
    used = (rng.uniform(size=M) < 0.5).astype(np.int8)
    rows, A, B = [], np.eye(9), np.zeros((9, p))
    for k in range(M):
        A, B = phinn[k] @ A, phinn[k] @ B + phinp[k]
        Psi = np.block([[A, B], [np.zeros((p, 9)), np.eye(p)]])
        rows.append(Psi[3:9] / np.sqrt(r)[:, None])
        if used[k]:
            rows.append(W[k] @ Psi)
    R, _ = _triangular_factor(phinn, phinp, r, W, used)
    np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False), np.linalg.svd(np.vstack(rows), compute_uv=False),
                               rtol=1e-9)


@pytest.fixture(scope="module")
def gimbal_s16():
    return observability("s16-gimbal", "unified")


def test_unified_encoder_rows_observe_gimbal(gimbal_s16):
    """With the encoder attitude rows in O, S16's path with encoders observes every parameter of
    the unified set, the four gimbal states included (without those rows they were a null space)."""
    rep = gimbal_s16
    assert (rep.n_states, rep.n_params) == (58, 49)
    assert rep.rank == rep.n_params
    for lab in ("gimbal_nonorthogonality", "mount_attitude[alpha0]", "mount_attitude[beta0]",
                "mount_attitude[gamma0]"):
        assert rep.null_weight(lab) < 1e-6, lab
        assert rep.by_label(lab).ratio < 0.1, lab  # the covariance view agrees


def test_unified_inner_axis_only_leaves_dth():
    """Only inner-axis turns: the outer axis never moves, so dth (the tilt of the outer axis in
    the gimbal's x-z plane) looks like a mount attitude / IMU frame rotation: in the null space."""
    rep = observability(inner_only(), "unified")
    assert rep.null_weight("gimbal_nonorthogonality") > 0.999
    assert rep.by_label("gimbal_nonorthogonality").ratio > 0.5
    # the mount attitude's level angles are seen by the encoder rows from the first step
    for lab in ("mount_attitude[alpha0]", "mount_attitude[beta0]"):
        assert rep.null_weight(lab) < 1e-6, lab
    assert rep.rank < rep.n_params


@pytest.mark.slow
def test_simulation_rate_does_not_matter():
    a, b = observability("psins19", rate_hz=20.0), observability("psins19", rate_hz=50.0)
    np.testing.assert_allclose([s.ratio for s in a.states], [s.ratio for s in b.states], rtol=1e-2)
    assert a.rank == b.rank


def test_noise_sources(tmp_path):
    p = static(120.0)
    rep = observability(p, arw=2e-6, vrw=5e-5)
    assert rep.kind == "path" and rep.noise["vrw_ug_sqrt_hz"] == pytest.approx([5e-5 / 9.80665e-6] * 3)
    assert rep.noise["arw_deg_sqrt_h"] == pytest.approx([2e-6 / (DEG / 60.0)] * 3)
    quiet, noisy = tmp_path / "quiet.toml", tmp_path / "noisy.toml"
    quiet.write_text("[scenario]\nduration_s = 120\n")  # static at the N25 site, no noise model
    noisy.write_text("[scenario]\nduration_s = 120\n[noise]\narw = 0.01\nvrw = 30\n")
    rep = observability(str(quiet))
    assert rep.kind == "scenario" and rep.noise["source"].startswith("S16 default")
    assert rep.noise["vrw_ug_sqrt_hz"] == pytest.approx([1.0] * 3) and rep.site["latitude_deg"] == pytest.approx(30.686651)
    rep = observability(str(noisy))
    assert rep.noise["source"] == "scenario" and rep.noise["arw_deg_sqrt_h"] == pytest.approx([0.01] * 3)
    with pytest.raises(ObservabilityError, match="unknown scenario"):
        observability("no-such-path")
    with pytest.raises(ObservabilityError, match="state option"):
        observability(p, "52")


# ----------------------------------------------------------------------------- CLI
def _path_toml(tmp_path, moves="", name="p.toml"):
    f = tmp_path / name
    f.write_text('[path]\nname = "short"\ninitial_dwell_s = 30\nmoves = [\n'
                 + (moves or '{axis = "outer", angle_deg = 90, rate_dps = 10, dwell_s = 30},\n'
                             '{axis = "inner", angle_deg = 90, rate_dps = 10, dwell_s = 30},\n'
                             '{axis = "outer", angle_deg = -90, rate_dps = 10, dwell_s = 30},\n'
                             '{axis = "inner", angle_deg = -90, rate_dps = 10, dwell_s = 30},\n') + "]\n")
    return f


def test_cli_json(tmp_path):
    f = _path_toml(tmp_path)
    r = runner.invoke(app, ["observability", str(f), "--states", "30", "--json", "--arw", "0.001", "--vrw", "2"])
    assert r.exit_code == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["kind"] == "path" and d["path"]["name"] == "short" and d["n_params"] == 21 and d["n_states"] == 30
    assert d["noise"]["arw_deg_sqrt_h"] == pytest.approx([0.001] * 3) and d["noise"]["vrw_ug_sqrt_hz"] == pytest.approx([2] * 3)
    assert d["site"]["latitude_deg"] == pytest.approx(30.0)
    assert set(d["parameters"][0]) == {"label", "group", "component", "unit", "prior", "posterior", "ratio", "verdict"}
    assert len(d["parameters"]) == 21 and d["thresholds"] == {"well observed": 0.01, "observed": 0.1, "weak": 0.5}
    svd = d["svd"]
    assert len(svd["singular_values"]) == 21 and 0 < svd["rank"] <= 21 and svd["rank_tolerance"] == RANK_TOL
    assert len(svd["weakest"]) == 5 and {"singular_value", "components"} <= set(svd["weakest"][0])
    assert set(d["groups"]["gyro_bias"]) >= {"unit", "max_ratio", "worst", "verdict"}


def test_cli_table(tmp_path):
    r = runner.invoke(app, ["observability", str(_path_toml(tmp_path)), "--states", "30"])
    assert r.exit_code == 0, r.stderr
    for word in ("gyro_matrix", "accel_bias", "ratio", "rank", "weakest directions"):
        assert word in r.stdout


def test_cli_bad_input(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[path\nmoves = ")
    open_path = _path_toml(tmp_path, '{axis = "inner", angle_deg = 90, rate_dps = 10, dwell_s = 30},\n', "open.toml")
    for args, msg in ((["no-such-scenario"], "unknown scenario"), ([str(bad)], "malformed TOML"),
                      ([str(tmp_path / "none.toml")], "no such file"), ([str(open_path)], "closed path"),
                      (["s16", "--states", "52"], "state option"), (["s16", "--rate-hz", "0"], "--rate-hz")):
        r = runner.invoke(app, ["observability", *args])
        assert r.exit_code == 2, (args, r.stdout)
        assert r.stderr.count("\n") == 1 and r.stderr.startswith("inscal: error:") and msg in r.stderr, r.stderr
