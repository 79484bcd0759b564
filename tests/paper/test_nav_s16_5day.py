"""S16's 5-day navigation claim (section 4.3, conclusions) on the ``s16-table3`` scenario: an
ultra-high-accuracy IMU (noise of a 0.1 nmi / 5 d INS) whose truth has the extra terms at the
magnitudes of S16 Table 3, calibrated with the 51-state and with the 30-state systematic filter
on the S16 Table 1 path, then navigated 5 days static, free inertial, level (x East, y North,
z Up) and noise-free (so the difference is the calibrations'), with each parameter set.

S16: with the 51-state parameters the position error is at least 20 % smaller.  This holds here
(seed 2016: 6.2 nmi against 64.6 nmi, 90 %; seeds 1-5: 25-96 %), but neither parameter set is near
0.1 nmi: the 1 h S16 path does not resolve the Table 3 g-sensitivity at this noise, and the
default 30-state filter does not converge.  In the other orientations of the full study (y-up,
tilt, rotation modulation) the claim fails at seed 2016.  The full study and its findings:
``python bench/nav5d.py`` and that module's docstring.
"""

import math

import numpy as np
import pytest

from inscal.core import error_model as errors, turntable, units
from inscal.sim import scenarios
from inscal.analysis import nav5d

SEED = 2016


def test_s16_table3_scenario_is_table3_in_s16_form_with_m_frame_equal_s_frame():
    sc = scenarios.build("s16-table3")
    assert sc.rate_hz == 100.0 and sc.path == turntable.s16_table1()
    s16, C_s_m = errors.to_s16(sc.imu)
    assert C_s_m == pytest.approx(np.eye(3), abs=1e-15)  # gyro misalignment lower triangular
    si = lambda v, u: units.to_si(np.asarray(v, float), u)  # noqa: E731
    # S16 Table 3, as printed
    G = 1e-5 * np.array([[0.09, 0.25, -0.22], [0.35, 0.81, -0.24], [-0.07, -0.50, -1.02]])
    assert s16.G == pytest.approx(si(G, "deg/h/g"), rel=1e-9)
    assert s16.K_a2 == pytest.approx(si([17.1, -20.4, 25.2], "ug/g^2"), rel=1e-9)
    kx = si([-2.0, -22.6, 7.8, 16.5, -0.5, 1.6], "ug/g^2")  # xy, xz, yx, yz, zx, zy (S16 eq. 12 rows)
    assert s16.K_cross == pytest.approx(np.array([[kx[0], kx[1], 0], [kx[2], 0, kx[3]], [0, kx[4], kx[5]]]), rel=1e-9)
    assert s16.lever_arm == pytest.approx([-0.041, 0.022, -0.024], rel=1e-9)
    # linear errors of a real unit: tens of ppm / arcsec
    f = errors.errors_to_field(sc.imu)
    for name in ("gyro_scale_factor", "accel_scale_factor"):
        assert 10 <= np.min(np.abs(f[name]["value"])) and np.max(np.abs(f[name]["value"])) <= 100, name
    assert sc.noise.arw == pytest.approx(np.full(3, units.to_si(5e-6, "deg/sqrt(h)")))
    assert sc.noise.vrw == pytest.approx(np.full(3, units.to_si(0.5, "ug/sqrt(Hz)")))
    # ARW alone: 5 days of angle random walk move a free-inertial position by ~ R N sqrt(t) << 0.1 nmi
    assert 6.4e6 * sc.noise.arw[0] * math.sqrt(5 * 86400) < 0.1 * 1852


@pytest.fixture(scope="module")
def study():
    return nav5d.compare_5day(SEED, orientations=("level",), consistent_30=False)


@pytest.mark.slow
def test_51_state_parameters_cut_the_5_day_error_by_at_least_20_percent(study):
    print()
    print(nav5d.format_table(study))
    m = study["orientations"]["level"]["max_m"]
    assert study["orientations"]["level"]["duration_s"] == pytest.approx(5 * 86400)
    # S16's claim for a 0.1 nmi / 5 d INS
    assert m["51-state"] <= 0.8 * m["30-state"]
    assert study["orientations"]["level"]["improvement_51_vs_30"] >= 0.2
    # the true parameters are the floor: only the mechanisation is left (noise-free record)
    assert m["truth"] < 1.0
    assert m["truth"] < m["51-state"] and m["truth"] < m["30-state"]
    # the 51-state filter's innovations agree with its noise model; the 30-state ones do not
    cal = study["calibrations"]
    assert 5.0 < cal["51-state"]["nis_mean"] < 7.0
    # (the velocity model-error term carries the 30-state misfit: a large factor on the noise, a rejected fit)
    assert cal["30-state"]["model_error_factor"] > 100.0 and not cal["30-state"]["fit_consistent"]
