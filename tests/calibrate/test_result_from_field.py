"""``CalibrationResult.from_field``: field units in, SI inside, and back out by ``to_field`` unchanged."""

import math

import numpy as np
import pytest

from inscal.calibrate import CalibrationResult


def test_field_values_become_si_and_come_back_unchanged():
    values = {"gyro_bias": [1.0, -2.0, 0.5], "gimbal_nonorthogonality": 3.0}
    sigma = {"gyro_bias": [0.1, 0.1, 0.2], "gimbal_nonorthogonality": 0.5}
    res = CalibrationResult.from_field(values, sigma, "manual")
    assert res.method == "manual" and res.estimated == ("gyro_bias", "gimbal_nonorthogonality")
    # 1 deg/h = pi / 180 / 3600 rad/s; 1 arcsec = pi / 180 / 3600 rad (closed forms, not inscal.core.units)
    per = math.pi / 180.0 / 3600.0
    np.testing.assert_allclose(res.imu.gyro_bias, np.array([1.0, -2.0, 0.5]) * per, rtol=1e-14)
    assert res.gimbal.nonorthogonality == pytest.approx(3.0 * per, rel=1e-14)
    np.testing.assert_allclose(res.sigma["gyro_bias"], np.array([0.1, 0.1, 0.2]) * per, rtol=1e-14)
    back = res.to_field()
    for name in values:
        np.testing.assert_allclose(back[name]["value"], np.atleast_1d(values[name]), rtol=1e-12)
        np.testing.assert_allclose(back[name]["sigma"], np.atleast_1d(sigma[name]), rtol=1e-12)
    assert not np.any(res.imu.accel_bias)  # what is not named stays zero


@pytest.mark.parametrize("values, sigma, says", [
    ({"gyro_bais": [0, 0, 0]}, {"gyro_bais": [1, 1, 1]}, "unknown parameter"),
    ({"gyro_bias": [0, 0, 0]}, {}, "no sigma"),
    ({"gyro_bias": [0, 0]}, {"gyro_bias": [1, 1]}, "'gyro_bias'"),
])
def test_bad_input_is_one_clear_error(values, sigma, says):
    with pytest.raises(ValueError, match=says):
        CalibrationResult.from_field(values, sigma)
