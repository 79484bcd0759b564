"""The JCGM 101 Monte Carlo of a calibration's budget (:mod:`inscal.uncertainty.montecarlo`): the tolerance and verdict of
JCGM 101 section 8 by hand; on a six-position calibration of the N25 record at the test station, the Monte Carlo
agrees with the linear budget (no component "not validated", every standard deviation within 20 % of u_c); at a
gross station (table angles +-3 deg) the linear budget misses the second-order response of the scale factors and the
Monte Carlo says so; the batches are reproducible whatever runs them."""

from __future__ import annotations

import concurrent.futures

import numpy as np
import pytest

from inscal.calibrate import calibrate, window_means
from inscal.calibrate.windows import WindowSet
from inscal.uncertainty import budget as gum
from inscal.uncertainty import montecarlo as M
from inscal.uncertainty import sensitivity as S
from inscal.uncertainty.station import INPUTS, read_station, station_from_dict
from inscal.sim import scenarios
from inscal.sim.simulate import simulate

from pathlib import Path

STATION = Path(__file__).resolve().parents[1] / "data" / "station.toml"


def test_tolerance_and_verdict_by_hand():
    """JCGM 101 8.1.2: u = 0.0345 with one digit is 3 x 10^-2, delta 0.005; with two digits 35 x 10^-3, 0.0005;
    9.97 rounds to 1 x 10^1 (delta 5); 8.2 with the numerical accuracy."""
    assert M.tolerance(0.0345) == pytest.approx(0.005)
    assert M.tolerance(0.0345, 2) == pytest.approx(0.0005)
    assert M.tolerance(9.97) == pytest.approx(5.0)
    assert M.tolerance(1.0) == pytest.approx(0.5)
    assert M.verdict(0.1, 0.2, 0.5, 0.1) == "validated"
    assert M.verdict(0.1, 0.9, 0.5, 0.1) == "not validated"
    assert M.verdict(0.1, 0.4, 0.5, 0.1) == "undecided"


def test_endpoint_accuracy_is_the_spread_of_a_quantile():
    """The order-statistics accuracy of a 2.5 % quantile of 1000 normal draws against the spread of that quantile
    over 400 repetitions (asymptotically sqrt(p (1 - p) / N) / phi(z_p) = 0.085)."""
    rng = np.random.default_rng(1)
    x = np.sort(rng.standard_normal((400, 1000)), axis=1)
    spread = np.quantile(x, 0.025, axis=1).std(ddof=1)
    acc = np.mean([M.endpoint_accuracy(v, 0.025) for v in x])
    assert spread == pytest.approx(0.085, rel=0.12)
    assert acc == pytest.approx(spread, rel=0.15)


def test_line_draws_have_the_lines_u():
    rng = np.random.default_rng(0)
    for dist in ("normal", "rectangular", "triangular", "arcsine"):
        x = M.line_draw(dist, 2.0, np.inf, rng, 200_000)
        assert x.std() == pytest.approx(2.0, rel=0.01), dist
    t = M.line_draw("normal", 1.0, 5.0, rng, 400_000)  # u t_5: variance 5/3
    assert t.var() == pytest.approx(5.0 / 3.0, rel=0.03)


@pytest.fixture(scope="module")
def six():
    """A six-position calibration of the N25 record (its static and rate windows) and its coefficients."""
    sc = scenarios.build("n25")
    ws = window_means(simulate(sc, np.random.default_rng(1)).to_record())
    ws = WindowSet([w for w in ws.windows if w.kind != "turn"], ws.site, ws.rate_hz, ws.info)
    r = calibrate(ws, "six-position")
    sens = S.sensitivities(ws, S.Geometry.of(r), S.estimator("six-position", r.estimated),
                           {k: v.kind for k, v in INPUTS.items()})
    return r, sens


def _budget(r, sens, station):
    from inscal.calibrate.result import flatten

    values = flatten(r.imu, r.gimbal, r.estimated)
    sigma = np.concatenate([np.ravel(r.sigma[n]) for n in r.estimated])
    return gum.budget(r.method, r.estimated, values, sigma, float(r.fit["dof"]), station, sens.glob, sens.per_stop)


def test_a_typical_station_validates(six):
    r, sens = six
    st = read_station(STATION)
    b = _budget(r, sens, st)
    mc = M.monte_carlo(r, st, b, runs=200, seed=3)
    assert mc.runs == 200 and len(mc.components) == len(b.components)
    assert "not validated" not in mc.counts(), [(c.label, c.d_low, c.d_high, c.delta) for c in mc.components]
    ratio = np.array([c.u / cb.u_c for c, cb in zip(mc.components, b.components)])
    assert np.all(np.abs(ratio - 1) < 0.2), ratio
    assert abs(np.median(ratio) - 1) < 0.07
    for c, cb in zip(mc.components, b.components):
        assert c.low < c.value < c.high and c.U == cb.U


def test_a_gross_station_is_not_validated_and_batches_reproduce(six):
    """+-3 deg table angles (rectangular): the scale factors see 1 - cos(angle), a bias of order 1000 ppm the linear
    budget cannot carry; the same batches in a thread pool give the same numbers."""
    r, sens = six
    doc = read_station(STATION).to_dict()
    doc["inputs"]["table_angle"] = {"unit": "deg", "distribution": "rectangular", "half_width": 3.0,
                                    "source": "a gross table"}
    st = station_from_dict(doc)
    b = _budget(r, sens, st)
    mc = M.monte_carlo(r, st, b, runs=100, seed=5, batches=2)
    sf = [c for c in mc.components if c.label.startswith("accel_scale_factor")]
    assert all(c.verdict == "not validated" for c in sf), [(c.label, c.verdict) for c in sf]
    assert all(abs(c.mean - c.value) > 5 * cb.u_c for c, cb in zip(mc.components, b.components) if c in sf)
    with concurrent.futures.ThreadPoolExecutor(2) as ex:
        again = M.monte_carlo(r, st, b, runs=100, seed=5, batches=2, map_fn=ex.map)
    assert again.to_dict() == mc.to_dict()
    assert M.MonteCarloBudget.from_dict(mc.to_dict()) == mc


def test_only_window_methods():
    class R:
        method = "systematic51"
        windows = None

    with pytest.raises(ValueError, match="window-mean method"):
        M.monte_carlo(R(), None, None)
