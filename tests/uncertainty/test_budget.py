"""The GUM budget: the arithmetic against hand-computed cases, and the sensitivity coefficients of the
N25 estimator against closed forms and against the other route (what the estimator believes)."""

from __future__ import annotations

import math
import types
from dataclasses import dataclass, replace

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from inscal.calibrate import calibrate, window_means
from inscal.calibrate.result import flatten
from inscal.core.attitude import dcm_from_euler
from inscal.core.earth import OMEGA_IE, Site
from inscal.core.error_model import GimbalErrors, ImuNoise
from inscal.uncertainty import budget as gum
from inscal.uncertainty import sensitivity as S
from inscal.lab.model import Parameter
from inscal.uncertainty.station import INPUTS
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

ARCSEC = math.pi / 180 / 3600
NAMES = ("gyro_scale_factor", "gyro_misalignment", "gyro_bias", "accel_scale_factor", "accel_misalignment",
         "accel_bias", "gimbal_nonorthogonality", "mount_attitude")
# flat layout of NAMES: 3 + 6 + 3 + 3 + 6 + 3 + 1 + 3
SL = {"gsf": slice(0, 3), "gmis": slice(3, 9), "gb": slice(9, 12), "asf": slice(12, 15), "amis": slice(15, 21),
      "ab": slice(21, 24), "dth": 24, "mount": slice(25, 28)}
KINDS = {k: v.kind for k, v in INPUTS.items()}


def test_welch_satterthwaite_and_k_by_hand():
    # two equal inputs with 10 dof each: nu_eff = (2 u^2)^2 / (2 u^4 / 10) = 20 (GUM eq. G.2b)
    assert gum.welch_satterthwaite([1.0, 1.0], [10, 10]) == pytest.approx(20.0)
    assert gum.welch_satterthwaite([3.0, 4.0], [None, 4]) == pytest.approx(625 / 64)  # 25^2 / (256 / 4)
    assert math.isinf(gum.welch_satterthwaite([1.0, 2.0], [math.inf, None]))
    assert gum.coverage_factor(20) == pytest.approx(2.085963, abs=1e-6)  # t_0.975(20), tables
    assert gum.coverage_factor(math.inf) == pytest.approx(1.959964, abs=1e-6)
    c = gum.combine("accel_bias", 1, 9.80665e-6, [gum.Contribution.line("a", None, "ug", "normal", 3.0, 1.0, math.inf),
                                                  gum.Contribution.line("b", None, "ug", "normal", 2.0, 2.0, 4.0)])
    assert c.value == pytest.approx(1.0) and c.u_c == pytest.approx(5.0) and c.label == "accel_bias[1]"
    assert c.dof_eff == pytest.approx(625 / 64) and c.k == pytest.approx(stats.t.ppf(0.975, 625 / 64))
    assert [x.share for x in c.contributions] == pytest.approx([9 / 25, 16 / 25])
    assert c.U == pytest.approx(c.k * 5.0)


def test_repeatability_is_the_excess_over_the_estimator_noise():
    v = np.array([[1.0, 0.0], [3.0, 0.1], [2.0, -0.1]])  # spreads: var 1, var 0.01
    u, dof = gum.repeatability(v, np.full_like(v, 0.5))
    assert dof == 2 and u == pytest.approx([math.sqrt(0.75), 0.0])
    with pytest.raises(ValueError):
        gum.repeatability(v[:1], v[:1])


@pytest.fixture(scope="module")
def n25(noise_free_data, as_record):
    sc, d = noise_free_data("n25")
    ws = window_means(as_record(d, sc))
    r = calibrate(ws, "n25", uncertainty=False)
    return sc, ws, r, S.Geometry.of(r), S.estimator("n25", NAMES)


@pytest.fixture(scope="module")
def glob(n25):
    _, ws, _, geo, x = n25
    return S.sensitivities(ws, geo, x, KINDS, stop_inputs=()).glob


def test_gravity_enters_the_accelerometer_scale_factors_one_to_one(n25, glob):
    g = n25[1].site.gravity
    c = glob["gravity"] * g  # d(scale factor) / (dg / g)
    assert c[SL["asf"]] == pytest.approx(1.0, abs=2e-4)
    rest = np.delete(c, np.r_[SL["asf"]])
    assert np.abs(rest[:-3]).max() < 2e-3  # gyro, misalignments [rad/rad], biases [(m/s^2) / 1]: ~0


def test_rate_and_time_base_closed_forms(glob):
    assert glob["table_rate"][SL["gsf"]] == pytest.approx(1.0, abs=2e-4)  # the rate tests' scale 1:1
    assert np.abs(glob["table_rate"][SL["asf"]]).max() < 1e-6
    # one acquisition clock: the means and the recorded rates scale together -> gyro scale unchanged,
    # the accelerometer scale (against the site's gravity) 1:1
    assert glob["time_base"][SL["asf"]] == pytest.approx(1.0, abs=2e-4)
    assert np.abs(glob["time_base"][SL["gsf"]]).max() < 2e-4


def test_latitude_moves_the_earth_rate_not_the_gyro_biases(n25, glob):
    """N25 fits ``N_g = M_g C_b^s w^b + eps`` with w^b free: a latitude error moves w^b by
    ``C_n^b dw^n``, ``dw^n = Omega (0, -sin L, cos L) dL`` (ENU), and leaves eps exactly."""
    sc, ws, r, geo, _ = n25
    assert np.abs(glob["latitude"][SL["gb"]]).max() < 1e-9 * OMEGA_IE
    h = 1e-4
    lat = ws.site.latitude
    dwn = OMEGA_IE * np.array([0.0, -math.sin(lat), math.cos(lat)]) * h
    r2 = calibrate(S.perturb(ws, geo, S.Deviation(latitude=h)), "n25", uncertainty=False)
    dwb = np.asarray(r2.diagnostics["earth_rate_b"]) - np.asarray(r.diagnostics["earth_rate_b"])
    assert dwb == pytest.approx(dcm_from_euler(sc.gimbal.mount_attitude).T @ dwn, abs=2e-3 * OMEGA_IE * h)
    assert np.abs(r2.imu.gyro_bias - r.imu.gyro_bias).max() < 1e-12


def test_common_table_angle_offsets_closed_forms(n25):
    """A reading off by e at every stop: on the inner axis the IMU turns by e about z_s, so
    ``M' = M R_z(-e)``: the xy misalignments +e and yx -e (N25 eq. 3, gyros and accelerometers);
    on the outer axis the whole path turns about the outer axis: the mounting roll +e, IMU unchanged."""
    _, ws, r, geo, x = n25
    e = 3e-5
    x0 = x(ws)
    nw = len(ws.windows)
    dz = x(S.perturb(ws, geo, S.Deviation(angle=np.tile([0.0, e], (nw, 1))))) - x0
    for mis in (SL["gmis"], SL["amis"]):
        assert dz[mis][[0, 2]] == pytest.approx([e, -e], rel=1e-3)  # [xy, yx]
        assert np.abs(dz[mis][[1, 3, 4, 5]]).max() < 1e-3 * e
    dx = x(S.perturb(ws, geo, S.Deviation(angle=np.tile([e, 0.0], (nw, 1))))) - x0
    assert dx[SL["mount"]][0] == pytest.approx(e, rel=1e-3)
    assert np.abs(dx[:24]).max() < 2e-3 * e


def test_truth_route_equals_belief_route(n25, glob):
    """The same errors written into the truth (the means) and into the estimator's belief (readings,
    rates, site) give the same coefficients: two independent paths through the kinematics."""
    _, ws, _, geo, x = n25
    x0 = x(ws)
    nw = len(ws.windows)
    static = [k for k, w in enumerate(ws.windows) if w.kind == "static"]
    for k, j in ((static[1], 0), (static[3], 1), (static[5], 0), (static[10], 1)):
        a = np.zeros((nw, 2))
        a[k, j] = 2e-5
        dev = S.Deviation(angle=a)
        ta, be = x(S.perturb(ws, geo, dev)) - x0, x(S.believe(ws, dev)) - x0
        assert np.abs(ta).max() > 1e-6 and np.abs(ta - be).max() < 2e-3 * np.abs(ta).max()
    for dev, key, h in ((S.Deviation(gravity=2e-4), "gravity", 2e-4), (S.Deviation(rate_scale=2e-5), "table_rate", 2e-5),
                        (S.Deviation(latitude=1e-4), "latitude", 1e-4)):
        be = (x(S.believe(ws, dev)) - x0) / h
        assert np.abs(be - glob[key]).max() < 2e-3 * max(np.abs(glob[key]).max(), 1.0)
    # no estimator reads the partial turns' means: the per-stop loop skips them
    turn = [k for k, w in enumerate(ws.windows) if w.kind == "turn"]
    a = np.zeros((nw, 2))
    a[turn] = 1e-4
    assert np.abs(x(S.perturb(ws, geo, S.Deviation(angle=a, tilt=a))) - x0).max() == 0.0


def test_rate_test_axis_turned_by_an_inner_angle_error(n25):
    """An outer-axis rate test with the inner gimbal off by e turns the rate axis a = R_z^T u by
    ``da = -e [z x] a`` (N25 eq. 9); eq. 28 (one window of the CW/CCW pair) then moves that column of
    M_g by ``-(e/2) [z x] a``, i.e. one gyro misalignment by e/2.  (The estimator rounds the rate
    tests' fixed angle, so only the truth route sees this error.)"""
    _, ws, _, geo, x = n25
    x0 = x(ws)
    nw = len(ws.windows)
    for k in [k for k, w in enumerate(ws.windows) if w.kind == "rate" and w.axis == "outer"]:
        e = 2e-5
        a = np.zeros((nw, 2))
        a[k, 1] = e
        dz = (x(S.perturb(ws, geo, S.Deviation(angle=a))) - x0) / e
        ax = np.array([math.cos(ws.windows[k].theta[1]), -math.sin(ws.windows[k].theta[1]), 0.0])
        j = int(np.argmax(np.abs(ax)))
        col = -0.5 * np.cross([0.0, 0.0, 1.0], np.round(ax)) * np.sign(ax[j])  # the move of M_g's column j
        E = np.zeros((3, 3))
        E[:, j] = col
        want = np.array([E[0, 1], E[0, 2], E[1, 0], E[1, 2], E[2, 0], E[2, 1]])  # [xy, xz, yx, yz, zx, zy]
        assert dz[SL["gmis"]] == pytest.approx(want, abs=1e-3)
        assert np.abs(dz[SL["asf"].start:SL["mount"].start]).max() < 1e-3


def test_common_tilt_is_a_mounting_attitude_change(n25):
    """A wobble tilt t (ENU) that is the same at every stop turns the whole table: the base attitude
    becomes ``(I + [t x]) C_b^n`` and the IMU errors stay; expected mounting angles by inverting the
    Euler angles of that matrix (scipy, not the package's own code)."""

    _, ws, r, geo, x = n25
    x0 = x(ws)
    t = np.array([3e-5, -2e-5])
    dx = x(S.perturb(ws, geo, S.Deviation(tilt=np.tile(t, (len(ws.windows), 1))))) - x0
    C = Rotation.from_euler("ZYX", r.gimbal.mount_attitude[::-1]).as_matrix()  # R_z(yaw) R_y(pitch) R_x(roll)
    tv = np.array([t[0], t[1], 0.0])
    C2 = Rotation.from_rotvec(tv).as_matrix() @ C
    want = Rotation.from_matrix(C2).as_euler("ZYX")[::-1] - r.gimbal.mount_attitude
    assert dx[SL["mount"]] == pytest.approx(want, abs=2e-3 * 3e-5)
    assert np.abs(dx[:24]).max() < 2e-3 * 3e-5


def test_coverage_factor_of_non_normal_outputs():
    """Closed forms of P(|y| <= k u) = 0.95: rectangular 0.95 sqrt(3); arcsine sqrt(2) sin(0.95 pi / 2);
    two equal rectangulars (a triangle on [-2a, 2a]) 2 (1 - sqrt(0.05)) / sqrt(2/3); normal 1.96."""
    k = gum.linear_coverage_factor
    assert k([("rectangular", 1.0)]) == pytest.approx(0.95 * math.sqrt(3), rel=1e-5)
    assert k([("arcsine", 2.0)]) == pytest.approx(math.sqrt(2) * math.sin(0.95 * math.pi / 2), rel=1e-4)
    assert k([("rectangular", 1.0), ("rectangular", 1.0)]) == pytest.approx(2 * (1 - math.sqrt(0.05)) / math.sqrt(2 / 3),
                                                                              rel=1e-5)
    assert k([("triangular", 1.0)]) == pytest.approx((1 - math.sqrt(0.05)) * math.sqrt(6), rel=1e-5)
    assert k([("normal", 1.0), ("normal", 2.0)]) == pytest.approx(1.959964, abs=1e-6)
    # a small rectangular beside a large normal: almost normal
    assert 1.95 < k([("normal", 1.0), ("rectangular", 0.2)]) < 1.96
    c = gum.combine("gyro_scale_factor", 0, 0.0, [gum.Contribution.line("rate", None, "ppm", "rectangular", 10.0, 1.0, math.inf),
                                                  gum.Contribution.line("est", None, "ppm", "normal", 1.0, 1.0, 10.0)])
    assert c.k < 1.96 and c.U == pytest.approx(c.k * c.u_c)


def test_repeatability_from_a_units_history():
    """Earlier results (field units in the database) -> SI, flat over the names; fewer than two: None."""

    def cal(bias_ug, sf_ppm):
        return types.SimpleNamespace(parameters={
            "accel_bias": Parameter("accel_bias", "ug", np.array(bias_ug), np.full(3, 0.5), None, ("x", "y", "z")),
            "gyro_scale_factor": Parameter("gyro_scale_factor", "ppm", np.array(sf_ppm), np.full(3, 1.0), None,
                                           ("x", "y", "z"))})

    cals = [cal([10, 0, 5], [1, 2, 3]), cal([12, 0, 5], [1, 2, 3]), cal([11, 0, 5], [1, 2, 6])]
    u, dof = gum.repeatability_of(cals, ("gyro_scale_factor", "accel_bias"))
    assert dof == 2
    ug = 1e-6 * 9.80665
    assert u == pytest.approx([0, 0, math.sqrt(3.0 - 1.0) * 1e-6, math.sqrt(1.0 - 0.25) * ug, 0, 0], abs=1e-15)
    assert gum.repeatability_of(cals[:1], ("accel_bias",)) is None


def test_the_filters_belief_route():
    """The filter methods' route: the site's gravity, latitude and height and the clock moved into what the
    estimator reads (the truth moves the other way), the gravity held at its value when the latitude moves."""
    site = Site(math.radians(30.0), 1.0, 10.0)

    @dataclass
    class Rec:
        site: Site
        rate_hz: float
        time: np.ndarray

    r = Rec(site, 100.0, np.arange(5) / 100.0)
    b = S.believe_record(r, S.Deviation(gravity=1e-5, latitude=1e-6, time_base=2e-6))
    assert b.site.gravity == pytest.approx(site.gravity - 1e-5, abs=1e-12)
    assert b.site.latitude == site.latitude - 1e-6 and b.rate_hz == pytest.approx(100.0 * (1 + 2e-6))
    assert b.time[1] == pytest.approx(0.01 / (1 + 2e-6))
    h = S.believe_record(r, S.Deviation(height=100.0))  # free-air gradient, about -0.3086 mGal/m
    assert (site.gravity - h.site.gravity) / 100.0 == pytest.approx(-3.086e-6, rel=2e-3)
    assert r.site is site  # the record itself is not changed


def test_the_window_route_equals_the_simulator():
    """The truth route against the simulator, which shares no code with it: the site's gravity and latitude
    and the table's non-orthogonality put into a simulated n25 record's truth, and an inner-axis reading
    off by e at every moment (the path started e further, the recorded angles the nominal ones), give the
    N25 estimate the window means' perturbation gives, to rounding."""
    sc = replace(scenarios.build("n25", rate_hz=20.0), noise=ImuNoise())

    def est(rec):
        ws = window_means(rec)
        r = calibrate(ws, "n25", uncertainty=False)
        return ws, r, flatten(r.imu, r.gimbal, r.estimated)

    ws0, r0, x0 = est(simulate(sc).to_record())
    geo, x = S.Geometry.of(r0), S.estimator("n25", r0.estimated)
    dg, dl, dd, e = 2e-4, 1e-4, 2e-5, 2e-5
    site = sc.site
    true = replace(sc, site=Site(site.latitude + dl, site.longitude, site.height).with_gravity(site.gravity + dg),
                   gimbal=GimbalErrors(sc.gimbal.nonorthogonality + dd, sc.gimbal.mount_attitude))
    _, _, x1 = est(replace(simulate(true).to_record(), site=site))
    xp = x(S.perturb(ws0, geo, S.Deviation(gravity=dg, latitude=dl, nonorthogonality=dd)))
    assert np.abs(x1 - x0).max() > 1e-5 and np.abs(x1 - xp).max() < 1e-12
    turned = replace(sc, path=replace(sc.path, initial=(sc.path.initial[0], sc.path.initial[1] + e)))
    rec = simulate(turned).to_record()
    _, _, x2 = est(replace(rec, gimbal=rec.gimbal - np.array([0.0, e])))
    xq = x(S.perturb(ws0, geo, S.Deviation(angle=np.tile([0.0, e], (len(ws0.windows), 1)))))
    assert np.abs(x2 - x0).max() > 1e-5 and np.abs(x2 - xq).max() < 1e-12
