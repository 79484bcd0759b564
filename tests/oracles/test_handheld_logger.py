"""Hand-held logger samples (rates in deg/s, accelerations as integer counts with a scale and an offset,
time in ms with jitter) turned into increments by the midpoint rule (inscal.io.logger), then calibrated
without a turntable: within 3.5 sigma of the independent generator's truth."""

from types import SimpleNamespace

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade

from inscal.calibrate import calibrate
from inscal.core import units
from inscal.core.earth import Site
from inscal.io.logger import increments_from_samples
from inscal.io.records import DataFileError

NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias")


def test_logger_samples_in_field_units_and_counts_calibrate_within_their_sigma():
    rng = np.random.default_rng(21)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=100.0, lat=0.8, g=9.80, arw=arw, vrw=vrw, jitter=0.3,
                  tremor_deg=0.3, samples=True)
    scale, offset = 1e-4 * units.G0, 32768.0  # 0.1 mg per count, counts offset at zero
    counts = np.round(lg.dvel / scale + offset)
    inc = increments_from_samples(lg.time * 1e3, units.from_si(lg.dtheta, "deg/s"), counts, time_unit="ms",
                                  gyro_unit="deg/s", accel_unit="counts", accel_counts=(scale, offset))
    rec = SimpleNamespace(time=inc.time, dtheta=inc.dtheta, dvel=inc.dvel, site=Site(0.8, gravity_model=9.80))
    res = calibrate(rec, "multi-position", min_static=2.0, settle=0.25)
    assert res.fit["consistent"], res.notes
    truth = canonical_truth(Mg, bg, Ma, ba)
    for name in NAMES:
        s = res.sigma[name]
        free = np.isfinite(s)
        assert np.all(np.abs(res.value(name) - truth[name])[free] < 3.5 * s[free]), (name, (res.value(name) -
                                                                                           truth[name]) / s)


@pytest.mark.parametrize("kw,msg", [({"gyro_unit": "m/s^2"}, "gyro"), ({"accel_unit": "counts"}, "scale and offset"),
                                    ({"time_unit": "deg"}, "time")])
def test_wrong_units_are_one_line(kw, msg):
    t = np.arange(10.0)
    with pytest.raises(DataFileError, match=msg):
        increments_from_samples(t, np.zeros((10, 3)), np.ones((10, 3)), **kw)
