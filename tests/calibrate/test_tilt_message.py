"""The still-pose detector's tilt test and its message agree: a pose rejected as tilted prints a trend above
the threshold printed beside it, also where the accelerometers' noise differs between axes (the trend
along the quiet axis, where the test is most sensitive)."""

import re

import numpy as np

from inscal.calibrate.static_detect import detect_still
from inscal.core.units import DEG


def record(trend_dps: float, seed: int):
    """60 s still, z up, 100 Hz; accelerometer noise 10x larger on z than on x and y; the x accelerometer
    drifting as a tilt about y at ``trend_dps`` deg/s."""
    rng = np.random.default_rng(seed)
    n, dt, g = 6000, 0.01, 9.8
    t = (np.arange(n) + 1) * dt
    dth = 1e-4 * np.sqrt(dt) * rng.normal(size=(n, 3))
    dv = np.array([2e-4, 2e-4, 2e-3]) * np.sqrt(dt) * rng.normal(size=(n, 3))
    dv[:, 2] += g * dt
    dv[:, 0] += g * np.sin(trend_dps * DEG * (t - 30.0)) * dt
    return t, dth, dv


def test_a_tilt_rejection_prints_its_trend_above_its_threshold():
    found = 0
    for k, trend in enumerate((2e-4, 3e-4, 5e-4, 1e-3)):
        si = detect_still(*record(trend, k), min_still=5.0)
        for c in si.candidates:
            m = re.match(r"tilted, (?:tilt )?([0-9.e+-]+) deg/s \(accelerometer trend\) above the ([0-9.e+-]+) deg/s threshold",
                         c.reason)
            if m:
                found += 1
                assert float(m.group(1)) > float(m.group(2)), c.reason
                assert abs(float(m.group(1)) / trend - 1.0) < 0.3, (c.reason, trend)  # the trend it was given
    assert found >= 2
