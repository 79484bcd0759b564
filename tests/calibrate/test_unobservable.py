"""Parameters the record does not observe are named, not written silently at their prior.

On a static record the systematic filter returned every parameter, most with the prior's sigma
(a scale factor of 0 +- 1000 ppm), and said nothing.  Now each component whose formal posterior
sigma is at least :data:`~inscal.calibrate.systematic.diagnostics.UNOBSERVABLE_RATIO` (0.5) of its
prior sigma is listed in ``diagnostics["unobservable"]`` (component, sigma ratio, both sigmas in the
field unit) and named in one note; on the s16 path nothing is.
"""

import numpy as np
import pytest

from inscal.calibrate import calibrate
from inscal.calibrate.systematic.diagnostics import UNOBSERVABLE_RATIO, unobservable
from inscal.core import units
from inscal.sim import scenarios
from inscal.sim.simulate import simulate


def _record(name: str, rate_hz: float, duration_s: float | None = None, seed: int = 1):
    sc = scenarios.build(name, duration_s=duration_s, rate_hz=rate_hz)
    d = simulate(sc, np.random.default_rng(seed))
    return type("Rec", (), dict(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal, rate_hz=sc.rate_hz,
                                site=sc.site, path=sc.path))()


@pytest.fixture(scope="module")
def static_rec():
    """18 minutes on a static base, level (the ``static`` scenario at 20 Hz)."""
    return _record("static", 20.0, 1080.0)


@pytest.fixture(scope="module")
def s16_rec():
    """The s16 path (1 h, 18 moves) with its IMU's errors and noise, at 20 Hz."""
    return _record("s16", 20.0)


def flagged(res) -> set:
    return {(e["parameter"], e["component"]) for e in res.diagnostics["unobservable"]}


@pytest.mark.parametrize("method, states", [("systematic51", "51"), ("systematic30", "30"), ("unified", None)])
def test_static_record_names_what_it_cannot_observe(static_rec, method, states):
    res = calibrate(static_rec, method, **({"states": states} if states else {}))
    got = flagged(res)
    # a static base turns nothing: no scale factor is seen (the vertical accelerometer's only as one sum
    # with its bias), the East gyro bias is inseparable from the heading, the horizontal accelerometer
    # biases from the level attitude
    for p in ("gyro_scale_factor", "accel_scale_factor"):
        assert {(p, c) for c in "xyz"} <= got, got
    assert ("gyro_bias", "x") in got and ("accel_bias", "x") in got and ("accel_bias", "y") in got
    # ... while the North and Up gyro biases are (Earth rate): not listed
    assert ("gyro_bias", "y") not in got and ("gyro_bias", "z") not in got
    e = next(e for e in res.diagnostics["unobservable"]
             if (e["parameter"], e["component"]) == ("gyro_scale_factor", "x"))
    assert e["unit"] == "ppm" and e["prior_sigma"] == pytest.approx(1000.0, rel=1e-6)
    assert e["sigma_ratio"] == pytest.approx(1.0, abs=0.02) and e["sigma"] == pytest.approx(1000.0, rel=0.02)
    # every entry's sigma is the reported formal sigma, in the field unit
    for e in res.diagnostics["unobservable"]:
        assert e["sigma_ratio"] >= UNOBSERVABLE_RATIO
        formal = np.ravel(res.diagnostics["formal_sigma"][e["parameter"]])
        assert np.any(np.isclose(units.from_si(formal, e["unit"]), e["sigma"], rtol=1e-9))
    note = [n for n in res.notes if n.startswith("not observable from this record")]
    assert len(note) == 1
    assert "gyro scale factor x, y, z (prior sigma 1000 ppm)" in note[0]
    if method == "unified":  # the encoders see the mount attitude, not the non-orthogonality, at rest
        assert ("gimbal_nonorthogonality", "") in got
        assert not any(p == "mount_attitude" for p, _ in got)


def test_s16_record_observes_every_parameter(s16_rec):
    for method in ("systematic51", "unified"):
        res = calibrate(s16_rec, method, states="51" if method == "systematic51" else None)
        assert res.diagnostics["unobservable"] == [], (method, res.diagnostics["unobservable"])
        assert not any(n.startswith("not observable") for n in res.notes)


def test_threshold_and_fixed_components():
    """The rule itself: at the threshold a component is listed, below it not; a fixed (NaN) one never."""
    names = ("gyro_bias", "time_asynchrony")
    prior = np.array([1e-6, 1e-6, 1e-6, 1e-3])
    sigma = np.array([0.5e-6, 0.49e-6, np.nan, 1e-3])
    entries, note = unobservable(names, sigma, prior)
    assert [(e["parameter"], e["component"]) for e in entries] == [("gyro_bias", "x"), ("time_asynchrony", "")]
    assert entries[1]["unit"] == "ms" and entries[1]["prior_sigma"] == pytest.approx(1.0)
    assert "gyro bias x (prior sigma 0.206 deg/h); time asynchrony (prior sigma 1 ms)" in note
    assert unobservable(names, prior * 0.1, prior) == ([], None)
