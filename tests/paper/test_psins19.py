"""The PSINS-style 19-position path and the ``psins19`` scenario."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.core import error_model as errors
from inscal import io
from inscal.sim import scenarios
from inscal.core import turntable as tt
from inscal.core.attitude import axis_angle_dcm
from inscal.cli.app import app
from inscal.core.error_model import ImuNoise
from inscal.sim.simulate import simulate
from inscal.core.kinematics import true_attitude, true_rates

DEG = math.pi / 180
LETTER = {"E": [1, 0, 0], "N": [0, 1, 0], "U": [0, 0, 1], "W": [-1, 0, 0], "S": [0, -1, 0], "D": [0, 0, -1]}
AXIS = {"x": 0, "y": 1, "z": 2}


def _sc():
    return scenarios.build("psins19")


def _windows(path):
    """(start, end) of the 19 dwells and of the 18 turns."""
    seg = path.segments()
    static = np.all(seg.w0 == 0, axis=1) & np.all(seg.acc == 0, axis=1)
    dwells = [(seg.t0[k], seg.t1[k]) for k in np.flatnonzero(static)]
    turns = []
    for m in range(len(path.moves)):
        sel = (seg.move_index == m) & ~static
        turns.append((seg.t0[sel][0], seg.t1[sel][-1]))
    return dwells, turns


def test_table_of_attitudes_reproduced_by_the_kinematics():
    sc = _sc()
    dwells, _ = _windows(sc.path)
    assert len(dwells) == 19
    C = true_attitude(sc, [0.5 * (a + b) for a, b in dwells])
    for k, axes in enumerate(tt.PSINS19_ATTITUDES):
        expected = np.array([LETTER[c] for c in axes], dtype=float).T  # columns: IMU x, y, z in ENU
        assert C[k] == pytest.approx(expected, abs=1e-12), f"position {k}: {axes}"
    # and C_s^b of the gimbal angles alone (zero mount attitude: b = ENU)
    th = [0.0, 0.0]
    for k, m in enumerate((None,) + sc.path.moves):
        if m is not None:
            th[tt.AXES.index(m.axis)] += m.angle
        assert tt.C_s_b(*th) == pytest.approx(C[k], abs=1e-12)


def test_each_turn_is_90_deg_about_the_listed_imu_axis():
    sc = _sc()
    dwells, turns = _windows(sc.path)
    C = true_attitude(sc, [0.5 * (a + b) for a, b in dwells])
    seen = set()
    for k, (ax, ang, turn) in enumerate(tt.PSINS19_SEQUENCE):
        sign, name = (1.0 if turn[0] == "+" else -1.0), turn[1]
        e = np.eye(3)[AXIS[name]]
        R = C[k].T @ C[k + 1]  # body-frame rotation of the move: C_after = C_before R
        assert R == pytest.approx(axis_angle_dcm(e, sign * 90 * DEG), abs=1e-12), f"move {k + 1}: {turn}"
        # the gimbal rate at mid-turn is along that IMU axis with that sense
        tm = 0.5 * sum(turns[k])
        w, _ = true_rates(sc, [tm])
        w_gimbal = w[0] - true_attitude(sc, [tm])[0].T @ sc.site.earth_rate_n
        assert w_gimbal == pytest.approx(sign * 10 * DEG * e, abs=1e-12)
        seen.add(turn)
    assert seen == {"+x", "-x", "+y", "-y", "+z", "-z"}  # all 3 IMU axes, both senses
    counts = {t: sum(1 for s in tt.PSINS19_SEQUENCE if s[2] == t) for t in seen}
    assert set(counts.values()) == {3}


def test_every_axis_up_and_down_timing_and_closure():
    sc = _sc()
    path = sc.path
    dwells, turns = _windows(path)
    vertical = {(ax[i], c) for ax in tt.PSINS19_ATTITUDES for i, c in enumerate("xyz")}
    for c in "xyz":
        assert ("U", c) in vertical and ("D", c) in vertical, c
    assert len(turns) == 18
    durations = np.array([b - a for a, b in turns])
    assert np.all(np.abs(durations - 9.0) <= 0.5)
    assert durations == pytest.approx(np.full(18, 90 / 10 + 10 / 50))  # 9.2 s: 10 deg/s, 50 deg/s^2
    stops = np.array([b - a for a, b in dwells])
    assert np.all((stops >= 20 - 1e-9) & (stops <= 90 + 1e-9)) and stops[0] == pytest.approx(90)
    assert set(np.round(stops, 6)) == {20.0, 30.0, 60.0, 90.0}
    assert path.closed
    end = np.array(path.final_angles())
    assert end == pytest.approx([0.0, 0.0], abs=1e-12)  # no net winding on either gimbal
    assert true_attitude(sc, [path.duration])[0] == pytest.approx(np.eye(3), abs=1e-12)
    assert path.duration == pytest.approx(1035.6, abs=1e-9)  # 90 + 18 x 9.2 + 780 s = 17.3 min
    print(f"psins19 path duration {path.duration:.1f} s = {path.duration / 60:.2f} min")
    assert path.to_dict()["moves"][0]["label"].startswith("psins19 #1")
    assert tt.RotationPath.from_dict(path.to_dict()) == path


def test_scenario_errors_in_s16_form_with_m_frame_equal_s_frame():
    sc = _sc()
    assert sc.rate_hz == 100 and sc.site.latitude == pytest.approx(34 * DEG)
    assert sc.gimbal.nonorthogonality == 0 and not np.any(sc.gimbal.mount_attitude)
    s16, C_s_m = errors.to_s16(sc.imu)
    assert C_s_m == pytest.approx(np.eye(3), abs=1e-15)  # gyro misalignment lower triangular
    ref = scenarios.psins19_s16()
    for name in ("K_g", "gamma", "b_g", "G", "K_a", "alpha", "b_a", "K_a2", "K_cross", "lever_arm"):
        assert getattr(s16, name) == pytest.approx(getattr(ref, name), rel=1e-9, abs=1e-18), name
    f = errors.errors_to_field(sc.imu)
    assert np.max(np.abs(f["gyro_scale_factor"]["value"])) < 100  # ppm
    assert 50 <= np.min(np.abs(f["accel_bias"]["value"])) and np.max(np.abs(f["accel_bias"]["value"])) <= 100  # ug
    assert f["accel_lever_arm"]["value"] == pytest.approx(np.diag([2.0, 3.0, -1.5]))  # cm
    assert len(set(np.abs(f["accel_nonlinearity"]["value"]))) == 3
    assert sc.noise.arw == pytest.approx(np.full(3, 0.002 * DEG / 60))
    assert sc.noise.vrw == pytest.approx(np.full(3, 5e-6 * 9.80665))


def test_cli_simulate_psins19_no_noise_truth(tmp_path):
    out = tmp_path / "p.h5"
    r = CliRunner().invoke(app, ["simulate", "psins19", "--out", str(out), "--no-noise", "--json"])
    assert r.exit_code == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["samples"] == 103560 and s["path"] == "psins19" and s["moves"] == 18 and s["noise"] is False
    rec = io.read_record(out)
    sc = _sc()
    for name in ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "gyro_g_sensitivity", "accel_scale_factor",
                 "accel_misalignment", "accel_bias", "accel_nonlinearity", "accel_cross_coupling", "accel_lever_arm",
                 "time_asynchrony"):
        assert np.array_equal(getattr(rec.truth.imu, name), getattr(sc.imu, name)), name
    assert rec.truth.gimbal.nonorthogonality == 0 and not np.any(rec.truth.gimbal.mount_attitude)
    assert rec.truth.noise.is_zero
    assert rec.path == sc.path
    assert rec.site == sc.site
    # the record is the noise-free simulation of the scenario
    d = simulate(replace(sc, noise=ImuNoise()))
    assert np.array_equal(rec.dtheta, d.dtheta) and np.array_equal(rec.dvel, d.dvel)
