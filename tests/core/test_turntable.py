"""Dual-axis turntable kinematics, rotation paths and the gimbal non-orthogonality pattern."""

import math

import numpy as np
import pytest

from inscal.core import turntable as tt
from inscal.core.attitude import euler_from_dcm, rot_x, rot_z
from inscal.core.error_model import GimbalErrors
from inscal.sim.simulate import Scenario
from inscal.core.earth import Site
from inscal.core.kinematics import true_attitude

DEG = math.pi / 180
ARCSEC = DEG / 3600
LETTER = {"E": [1, 0, 0], "N": [0, 1, 0], "U": [0, 0, 1], "W": [-1, 0, 0], "S": [0, -1, 0], "D": [0, 0, -1]}


def end_of_moves(path):
    seg = path.segments()
    return np.array([seg.t1[seg.move_index == k][-1] for k in range(len(path.moves))])


def test_s16_table1_all_18_attitudes():
    path = tt.s16_table1()
    assert len(path.moves) == 18 and all(m.rate == pytest.approx(5 * DEG) and m.dwell == 180 for m in path.moves)
    t = np.concatenate([[1.0], end_of_moves(path) - 1.0])  # inside each dwell
    C = true_attitude(Scenario("t", path, Site(0.5)), t)
    for k, axes in enumerate(tt.S16_TABLE1_ATTITUDES):
        expected = np.array([LETTER[c] for c in axes], dtype=float).T  # columns: IMU x, y, z in ENU
        assert C[k] == pytest.approx(expected, abs=1e-12), f"row {k}: {axes}"
    assert path.duration / 3600 == pytest.approx(1.07, abs=0.01)  # ~1 h (S16 section 4.1)


def test_n25_twelve_positions_each_axis_up_and_down_inner_symmetric():
    up = {}
    for tx, tz in tt.N25_TWELVE_POSITIONS:
        C = tt.C_s_b(tx * DEG, tz * DEG)
        ax = int(np.argmax(np.abs(C[2])))  # which IMU axis is vertical
        up.setdefault((ax, int(np.sign(C[2, ax]))), []).append((tx, tz))
    assert len(up) == 6 and all(len(v) == 2 for v in up.values())
    for pair in up.values():  # the two positions of each attitude are inner-symmetric
        (a, b), (c, d) = pair
        assert (a - c) % 360 in (0, 180) and (b - d) % 180 == 0
    # the path visits every position and returns to the start
    path = tt.n25_twelve(rate_tests=False)
    end = np.array(path.final_angles()) / (2 * math.pi)
    assert end == pytest.approx(np.round(end), abs=1e-12)  # whole turns on both axes


def test_trapezoid_and_triangle_profiles():
    p = tt.RotationPath("p", (tt.Move("inner", 90 * DEG, 5 * DEG, 10.0), tt.Move("inner", -90 * DEG, 5 * DEG, 0.0)), accel=10 * DEG)
    seg = p.segments()
    assert p.duration == pytest.approx(2 * (18.0 + 0.5) + 10.0)  # A/w + w/a per move
    th, w, a = seg.angles(np.array([0.25, 9.0, 18.5, 20.0]))
    assert th[2, 1] == pytest.approx(90 * DEG, abs=1e-15) and w[2, 1] == 0.0
    assert w[1, 1] == pytest.approx(5 * DEG) and a[0, 1] == pytest.approx(10 * DEG)
    # small move: triangular profile reaches sqrt(A alpha) < cruise rate
    q = tt.RotationPath("q", (tt.Move("outer", 1 * DEG, 5 * DEG, 0.0), tt.Move("outer", -1 * DEG, 5 * DEG, 0.0)), accel=10 * DEG)
    _, w, _ = q.segments().angles(np.linspace(0, q.duration, 1001))
    assert np.max(np.abs(w[:, 0])) == pytest.approx(math.sqrt(10) * DEG, rel=1e-3)


@pytest.mark.parametrize("bad, msg", [
    (dict(moves=(tt.Move("outer", 90 * DEG, 5 * DEG, 10.0),)), "not at its start"),
    (dict(moves=(tt.Move("outer", 90 * DEG, 5 * DEG, 10.0),), accel=-1.0), "acceleration"),
    (dict(moves=()), "no moves"),
])
def test_path_validation(bad, msg):
    with pytest.raises(tt.PathError, match=msg):
        tt.RotationPath("bad", **bad)


def test_move_validation_and_dict_round_trip():
    with pytest.raises(tt.PathError, match="rate"):
        tt.Move("outer", 90 * DEG, -5 * DEG)
    with pytest.raises(tt.PathError, match="axis"):
        tt.Move("middle", 90 * DEG, 5 * DEG)
    with pytest.raises(tt.PathError, match="dwell"):
        tt.Move("none", dwell=-1.0)
    p = tt.n25_twelve()
    q = tt.RotationPath.from_json(p.to_json())
    assert q.duration == pytest.approx(p.duration) and len(q.moves) == len(p.moves)
    with pytest.raises(tt.PathError, match="unknown path keys"):
        tt.RotationPath.from_dict({"moves": [], "speed": 1})
    assert tt.RotationPath.from_dict({"moves": [{"axis": "outer", "angle_deg": 90, "rate_dps": 5}], "closed": False}).final_angles()[0] == pytest.approx(90 * DEG)


def test_rotmod16_returns_to_start_each_cycle():
    p = tt.rotmod16(duration_s=1.0)
    assert len(p.moves) == 16
    th = np.zeros(2)
    for m in p.moves:
        th[tt.AXES.index(m.axis)] += m.angle
    assert th == pytest.approx([0.0, 0.0], abs=1e-12)
    assert tt.rotmod16(6 * 3600).duration >= 6 * 3600


def test_gimbal_matrix_exact_and_first_order_eq5():
    d = 20 * ARCSEC
    for tx in (0.3, 1.7, math.pi):
        C = tt.C_s_b(tx, 0.0, d)
        # N25 eq. 5 (first order in d theta; signs from Rodrigues' formula with u = [1, 0, d])
        # agrees to O(d theta^2)
        s, c = math.sin(tx), math.cos(tx)
        eq5 = np.array([[1, -d * s, d * (1 - c)], [d * s, c, -s], [d * (1 - c), s, c]])
        assert C == pytest.approx(eq5, abs=2 * d * d)
        assert C @ C.T == pytest.approx(np.eye(3), abs=1e-15)
    # the outer axis is invariant under its own rotation
    u = tt.outer_axis(d)
    assert tt.C_s_b(1.1, 0.0, d) @ u == pytest.approx(u, abs=1e-15)


def test_nonorthogonality_attitude_pattern_eq37():
    """dtheta = 20": vehicle attitude from the IMU attitude through an orthogonal gimbal model.

    Exact physics: the error depends only on theta_x: [0, -2 dth sin^2(tx/2), dth sin(tx)].
    N25 eq. 37 prints [0, 2 dth sin^2(tx/2) cos(tz), dth sin(tx)]; it agrees in the yaw term and
    in the pitch magnitude at tz = 0, 180 deg (see turntable.attitude_error_nonorthogonality).
    """
    d = 20 * ARCSEC
    mount = np.array([0.1, 0.1, 20]) * DEG
    Cbn = tt.C_b_n(mount)
    tx = np.linspace(0, 2 * math.pi, 73)
    for tz in (0.0, 0.7, math.pi):
        Csn = Cbn @ tt.C_s_b(tx, tz, d)
        est = tt.vehicle_attitude_from_imu(Csn, tx, np.full_like(tx, tz), dtheta_model=0.0)
        # error as a rotation in the body frame: C_true^T C_est
        Cest = np.stack([tt.C_b_n(e) for e in est])
        E = np.einsum("ji,njk->nik", Cbn, Cest)
        phi = np.stack([E[:, 2, 1], E[:, 0, 2], E[:, 1, 0]], axis=1)
        assert phi == pytest.approx(tt.attitude_error_nonorthogonality(tx, d), abs=d * d * 4)
        # amplitude about d theta (N25 Fig. 3): pitch peaks 2 dth at tx = 180, yaw dth at 90
        assert np.max(np.abs(phi[:, 2])) == pytest.approx(d, rel=1e-6)
        assert np.max(np.abs(phi[:, 1])) == pytest.approx(2 * d, rel=1e-6)
        if tz in (0.0, math.pi):
            eq37_pitch = 2 * d * np.sin(tx / 2) ** 2 * math.cos(tz)
            assert np.abs(phi[:, 1]) == pytest.approx(np.abs(eq37_pitch), abs=4 * d * d)
        # the model with the true dtheta removes the error completely
        exact = tt.vehicle_attitude_from_imu(Csn, tx, np.full_like(tx, tz), dtheta_model=d)
        assert exact == pytest.approx(np.tile(mount, (tx.size, 1)), abs=1e-14)
