"""Motion, steps and stuck stretches are caught at a block's resolution (analysis.noise.motion and the
channel checks): short turns in a long static record, a bias step, a frozen stretch; a static record
passes."""

import math

import numpy as np
import pytest

from inscal.analysis.noise.identify import ChannelChecks
from inscal.analysis.noise.motion import MotionStats

RATE = 10.0
N = 100_000  # 10,000 s


def _static(seed=0):
    rng = np.random.default_rng(seed)
    dt = 1 / RATE
    g = rng.normal(0, 2e-6, (N, 3)) * math.sqrt(dt) + 7e-5 * dt  # rad: ARW ~0.007 deg/sqrt(h), Earth rate
    walk = np.cumsum(rng.normal(0, 3e-9, (N, 3)), axis=0) * dt  # a random walk of the bias: not motion
    a = rng.normal(0, 2e-4, (N, 3)) * math.sqrt(dt) + np.array([0, 0, 9.8]) * dt
    return np.concatenate([g + walk, a], axis=1)


def _stats(x, chunk=7919):
    m = MotionStats(x.shape[0], RATE, 6)
    for i in range(0, x.shape[0], chunk):
        m.update(x[i:i + chunk])
    return m


def test_a_static_record_passes():
    assert _stats(_static()).reason() is None


@pytest.mark.parametrize("k, seconds", [(1, 10.0), (2, 30.0), (4, 9.0), (4, 25.0)])
def test_short_turns_are_caught_with_their_times(k, seconds):
    """k turns of 90 deg about z, each ``seconds`` long (0.09-1 % of the 10,000-s record in all)."""
    x = _static(k)
    starts = np.linspace(1500, 8500, k)
    for s in starts:
        i0, n = int(s * RATE), int(seconds * RATE)
        x[i0:i0 + n, 2] += math.radians(90) / n
    m = _stats(x)
    why = m.reason(0.0, ["gx", "gy", "gz", "ax", "ay", "az"])
    assert why is not None and ("gz" in why or "gyro rate departs" in why)
    mask, _ = m.event_mask()
    for s in starts:  # each turn's start and end are marked, to a block (1 s)
        for edge in (s, s + seconds):
            assert mask[int(edge) - 1: int(edge) + 2].any(), (s, edge)
    marked = np.flatnonzero(mask)  # and nothing far from a turn (the widest pair spans 2 x 64 blocks)
    assert np.all(np.min(np.abs(marked[:, None] - starts[None, :] - seconds / 2), axis=1) < 70)


def test_a_bias_step_is_caught():
    x = _static(3)
    x[60_000:, 0] += 2e-5 / RATE  # a 4 deg/h step of the gyro bias (ARW 0.007 deg/sqrt(h))
    m = _stats(x)
    assert m.reason() is not None and 5990 <= m.moving_span()[0] <= 6001


def test_a_stuck_stretch_is_found_with_its_times():
    x = _static(4)
    x[40_000:40_050, 4] = x[40_000, 4]  # ay frozen for 5 s
    chk = ChannelChecks(6)
    for i in range(0, N, 7919):
        chk.update(x[i:i + 7919])
    assert chk.stuck_stretch(4) == (40_000, 40_049)
    assert chk.stuck_stretch(3) is None
    probs = chk.problems(["gx", "gy", "gz", "ax", "ay", "az"], 0.0, 1 / RATE)
    assert probs == ["ay is stuck or saturated from 4000 s to 4005 s (50 equal increments in a row; use "
                     "--start/--stop to leave it out)"]
