"""The hand-held scenario kind (inscal.sim.handheld): exact still poses, and simulate-then-calibrate
(multi-position) gives back the truth to 1e-9 of each parameter's size without noise (a tremor of 8 Hz
needs 200 Hz sampling for that: at 100 Hz the gyro scale factors come back to about 3e-10 absolute).
The Ferraris session on tilted faces: its poses and turns, and ferraris on its exact faces."""

import math
from dataclasses import replace

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.core.error_model import ImuNoise
from inscal.core.turntable import static
from inscal.sim import scenarios
from inscal.sim.handheld import FerrarisMotion
from inscal.sim.simulate import simulate

NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias")


def test_still_poses_read_gravity_and_the_earth_rate_exactly():
    sc = replace(scenarios.build("handheld-mems", rate_hz=50.0), imu=scenarios.build("static").imu, noise=ImuNoise())
    d = simulate(sc, keep_truth=True)
    m = sc.motion
    att = m.attitudes()
    dt = 1.0 / sc.rate_hz
    for j, (t0, t1) in enumerate(m.still_intervals()):
        k = (d.time > t0 + dt) & (d.time < t1)
        Cnb = att[j].T
        assert np.allclose(d.dvel[k] / dt, Cnb @ np.array([0, 0, sc.site.gravity]), rtol=0, atol=1e-11)
        assert np.allclose(d.dtheta[k] / dt, Cnb @ sc.site.earth_rate_n, rtol=0, atol=1e-16)


@pytest.mark.parametrize("grade,rate_hz,tremor_deg", [("mems", 200.0, 0.3), ("navigation", 50.0, 0.0)])
def test_simulate_then_calibrate_gives_back_the_truth(grade, rate_hz, tremor_deg):
    sc = replace(scenarios.build(f"handheld-{grade}", rate_hz=rate_hz), noise=ImuNoise())
    sc = replace(sc, motion=replace(sc.motion, poses=10, still_s=3.0, move_s=2.5, tremor_deg=tremor_deg))
    rec = simulate(sc).to_record()
    assert rec.gimbal is None and rec.path is None
    res = calibrate(rec, "multi-position", min_static=2.0, settle=0.25)
    for name in NAMES:
        err = res.error(rec.truth, name)
        ti, tg = res.truth_transform((rec.truth.imu, rec.truth.gimbal))
        size = max(np.max(np.abs(getattr(ti, name))), 7.292115e-5 if name == "gyro_bias" else 0.0)
        free = np.isfinite(res.sigma[name])
        assert np.all(np.abs(err[free]) <= 1e-9 * size), (name, err / size)


def test_ferraris_motion_rests_on_tilted_faces_and_turns_about_their_vertical():
    """The Ferraris session (inscal.sim.handheld.FerrarisMotion): each still pose reads gravity along its face's
    tilted vertical exactly (the tilt drawn: the angle between that vertical and the face's axis), the faces
    come in the order +x, -x, +y, -y, +z, -z, then +x, +x, +y, +y, +z, +z; the three turns integrate
    2 pi (and the closure error drawn) about the pose's vertical (plus the vertical Earth rate; the horizontal
    one at most W cos L T across), and the tilts spread as stated."""
    m = FerrarisMotion(seed=3, face_tilt_deg=0.5)
    sc = replace(scenarios.build("ferraris-mems"), imu=scenarios.build("static").imu, noise=ImuNoise(), motion=m,
                 path=static(m.duration))
    d = simulate(sc, keep_truth=True)
    dt = 1.0 / sc.rate_hz
    g = sc.site.gravity
    ups = []
    for j, ((t0, t1), C, tilt) in enumerate(zip(m.still_intervals(), m.attitudes(), m.tilts())):
        k = (d.time > t0 + dt) & (d.time < t1)
        up = C[2]  # the vertical in the body
        assert np.allclose(d.dvel[k] / dt, g * up, rtol=0, atol=1e-11)
        axis, sign = [(0, 1), (0, -1), (1, 1), (1, -1), (2, 1), (2, -1), (0, 1), (0, 1), (1, 1), (1, 1), (2, 1),
                      (2, 1)][j]
        assert np.sign(up[axis]) == sign
        assert math.isclose(math.acos(abs(up[axis])), math.atan(math.hypot(*tilt)), rel_tol=1e-6, abs_tol=1e-12)
        ups.append(up)
    moves = m.moves()
    for j in (6, 8, 10):
        t0, C, e, ang, _ = moves[j]
        k = (d.time > t0) & (d.time <= t0 + m.move_s + 1e-9)
        T = d.time[k].size * dt
        wie = C.T @ sc.site.earth_rate_n  # at the start; its part along the vertical stays through the turn
        turned = d.dtheta[k].sum(axis=0)
        assert abs(turned @ ups[j] - ang - T * (wie @ ups[j])) < 2e-4 * dt  # the samples straddle the move by < dt
        side = turned - (turned @ ups[j]) * ups[j]  # the horizontal Earth rate as the body turns, no more
        assert np.linalg.norm(side) <= (T + dt) * np.linalg.norm(wie - (wie @ ups[j]) * ups[j])
        assert 0 < abs(abs(ang) - 2 * math.pi) < math.radians(5 * m.turn_closure_deg)
    many = np.concatenate([FerrarisMotion(seed=s, face_tilt_deg=0.5).tilts()[:9] for s in range(40)])
    assert 0.42 < math.degrees(np.sqrt(np.mean(np.sum(many**2, axis=1)))) < 0.58


def test_ferraris_scenario_on_exact_faces_gives_back_the_accelerometers_exactly():
    """simulate ferraris-mems with exact faces and no noise, then calibrate --method ferraris: the
    accelerometer parameters to 1e-9 of their size (exact faces, exact equations), the gyros within the
    sigma of the horizontal Earth rate the method leaves in."""
    sc = scenarios.build("ferraris-mems")
    m = replace(sc.motion, face_tilt_deg=0.0, turn_closure_deg=0.0)
    sc = replace(sc, noise=ImuNoise(), motion=m, path=static(m.duration))
    rec = simulate(sc).to_record()
    res = calibrate(rec, "ferraris", face_tilt=0.0, turn_closure=0.0)
    ti, _ = res.truth_transform((rec.truth.imu, rec.truth.gimbal))
    for name in NAMES:
        err = res.error(rec.truth, name)
        free = np.isfinite(res.sigma[name])
        if name.startswith("accel"):
            assert np.all(np.abs(err[free]) <= 1e-9 * np.max(np.abs(getattr(ti, name)))), (name, err)
        else:
            assert np.all(np.abs(err[free]) <= 3 * res.sigma[name][free]), (name, err / res.sigma[name])
