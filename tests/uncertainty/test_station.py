"""The station description (station.toml): SI conversion of every distribution, one-line refusals."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from inscal.uncertainty.station import INPUTS, StationError, read_station, station_from_dict

DATA = Path(__file__).resolve().parents[1] / "data" / "station.toml"
ARCSEC = math.pi / 180 / 3600


def doc():
    return tomllib.loads(DATA.read_text())


def test_typical_station_in_si():
    st = read_station(DATA)
    assert st.name == "T-2, lab 3" and set(st.inputs) == set(INPUTS)
    assert st["table_angle"].u == pytest.approx(2.0 * ARCSEC, rel=1e-12)
    assert st["table_rate"].u == pytest.approx(17.32e-6 / math.sqrt(3), rel=1e-12)  # rectangular: a / sqrt(3)
    assert st["encoder_resolution"].half_width == pytest.approx(0.18 * ARCSEC)
    assert st["gravity"].u == pytest.approx(1e-5, rel=1e-12)  # 1 mGal
    assert st["gravity"].value == pytest.approx(9.793788)
    assert st["latitude"].value == pytest.approx(math.radians(30.686)) and st["latitude"].u == pytest.approx(ARCSEC)
    assert st["temperature_stability"].u == pytest.approx(0.1 / math.sqrt(2))  # arcsine: a / sqrt(2)
    d = doc()
    d["inputs"]["axis_wobble"] = {"unit": "arcsec", "distribution": "triangular", "half_width": 6.0, "source": "x",
                                  "dof": 12}
    st2 = station_from_dict(d)
    assert st2["axis_wobble"].u == pytest.approx(6.0 / math.sqrt(6) * ARCSEC) and st2["axis_wobble"].dof == 12
    assert station_from_dict(st2.to_dict()) == st2  # field units out and back


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["inputs"]["gravity"].pop("uncertainty"), "input gravity: missing field 'uncertainty'"),
    (lambda d: d["inputs"]["latitude"].pop("value"), "input latitude: missing field 'value'"),
    (lambda d: d["inputs"]["table_angle"].pop("source"), "input table_angle: missing field 'source'"),
    (lambda d: d["inputs"]["table_angle"].update(uncertainty=-1.0), "input table_angle: negative uncertainty -1"),
    (lambda d: d["inputs"]["table_rate"].update(half_width=-3.0), "input table_rate: negative half-width -3"),
    (lambda d: d["inputs"]["table_rate"].update(distribution="lognormal"), "unknown distribution 'lognormal'"),
    (lambda d: d["inputs"]["table_rate"].update(unit="arcsec"), "input table_rate: unit 'arcsec' is a angle unit"),
    (lambda d: d["inputs"].pop("time_base"), "missing input(s) time_base"),
    (lambda d: d["inputs"].update(humidity={}), "unknown input(s) ['humidity']"),
    (lambda d: d["inputs"]["gravity"].update(uncertainty=float("nan")), "uncertainty must be a finite number"),
])
def test_refusals_are_one_line(edit, message):
    d = doc()
    edit(d)
    with pytest.raises(StationError) as exc:
        station_from_dict(d)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_unreadable_file(tmp_path):
    p = tmp_path / "station.toml"
    p.write_text("[station\nname = 1")
    with pytest.raises(StationError, match="malformed TOML"):
        read_station(p)


def test_draws_have_the_stated_standard_uncertainty():
    st = read_station(DATA)
    rng = np.random.default_rng(5)
    for name in ("table_angle", "table_rate", "temperature_stability"):  # normal, rectangular, arcsine
        x = st[name].draw(rng, 40000)
        assert np.std(x) == pytest.approx(st[name].u, rel=0.02) and abs(np.mean(x)) < 0.02 * st[name].u
    d = doc()
    d["inputs"]["axis_wobble"] = {"unit": "arcsec", "distribution": "triangular", "half_width": 6.0, "source": "x"}
    w = station_from_dict(d)["axis_wobble"]
    assert np.std(w.draw(rng, 40000)) == pytest.approx(w.u, rel=0.02)
