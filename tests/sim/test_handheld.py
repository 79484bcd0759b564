"""The hand-held scenario kind (inscal.sim.handheld): exact still poses, and simulate-then-calibrate
(multi-position) gives back the truth to 1e-9 of each parameter's size without noise (a tremor of 8 Hz
needs 200 Hz sampling for that: at 100 Hz the gyro scale factors come back to about 3e-10 absolute)."""

from dataclasses import replace

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.core.error_model import ImuNoise
from inscal.sim import scenarios
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
