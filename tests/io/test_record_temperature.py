"""The record's /temperature (degC, one or several sensors, on the record's time grid or on its own
/temperature_time) and /truth/thermal: write/read round trips through every reader, damaged
datasets each refused with one DataFileError line, and a record without temperature."""

import json
import math

import h5py
import numpy as np
import pytest

from inscal.core import earth
from inscal.core.earth import Site
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
from inscal.core.thermal import THERMAL_TERMS
from inscal import io
from inscal.io.records import DataFileError, Record, Temperature, Truth
from inscal.sim import scenarios

RATE = 10.0
N = 120


def _record(temperature=None, truth=None) -> Record:
    """A static E-N-U record, 12 s at 10 Hz, 45 deg N (values need only be finite and uniform in time)."""
    lat = math.radians(45.0)
    dt = 1.0 / RATE
    t = (np.arange(N) + 1) * dt
    rng = np.random.default_rng(7)
    dth = np.tile(earth.OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)]) * dt, (N, 1))
    dv = np.tile([0.0, 0.0, 9.8 * dt], (N, 1)) + 1e-6 * rng.standard_normal((N, 3))
    return Record(t, dth, dv, None, RATE, Site(lat, 0.2, 30.0), truth=truth, temperature=temperature)


def _readers(f):
    """The temperature as each reader of a record gives it."""
    with io.open_record(f) as lazy:
        from_open = lazy.temperature
    return {"read_record": io.read_record(f).temperature, "record_info": io.record_info(f).temperature,
            "open_record": from_open}


def test_on_the_record_grid_has_no_temperature_time(tmp_path):
    rec = _record()
    values = 20.0 + 0.01 * np.arange(N)  # one sensor, 1-D: a column
    rec.temperature = Temperature(rec.time.copy(), values, ("imu",))
    f = tmp_path / "grid.h5"
    io.write_record(f, rec)
    with h5py.File(f) as h5:
        assert "temperature_time" not in h5 and h5["temperature"].shape == (N, 1)
        assert json.loads(h5["temperature"].attrs["sensors"]) == ["imu"]
        assert json.loads(h5.attrs["units"])["temperature"] == "degC"
    for how, temp in _readers(f).items():
        assert temp.sensors == ("imu",), how
        assert np.array_equal(temp.time, rec.time) and np.array_equal(temp.values[:, 0], values), how
        assert np.array_equal(temp.series("imu"), values) and np.array_equal(temp.series(), values), how


def test_own_grid_and_several_sensors(tmp_path):
    rec = _record()
    tt = np.arange(0.0, 13.0, 1.0)  # a 1 Hz sensor from t = 0, off the sample times at its first reading
    vals = np.column_stack([-40.0 + 2.0 * tt, -38.5 + 2.0 * tt, 25.0 + 0.0 * tt])
    rec.temperature = Temperature(tt, vals, ("gyro", "accel", "case"))
    f = tmp_path / "own.h5"
    io.write_record(f, rec)
    with h5py.File(f) as h5:
        assert np.array_equal(h5["temperature_time"][()], tt) and h5["temperature"].shape == (13, 3)
    for how, temp in _readers(f).items():
        assert temp.sensors == ("gyro", "accel", "case"), how
        assert np.array_equal(temp.time, tt) and np.array_equal(temp.values, vals), how
        assert np.array_equal(temp.series("accel"), vals[:, 1]), how
        assert np.allclose(temp.series(), vals.mean(axis=1), rtol=0, atol=1e-12), how
    with pytest.raises(DataFileError, match="no temperature sensor 'fan'"):
        io.read_record(f).temperature.series("fan")


def test_same_length_as_the_record_but_other_times_keeps_its_times(tmp_path):
    """N readings at times that are not the samples': /temperature_time is written, the times kept."""
    rec = _record()
    tt = rec.time - 0.05
    rec.temperature = Temperature(tt, np.full(N, 21.5), ("imu",))
    f = tmp_path / "shifted.h5"
    io.write_record(f, rec)
    with h5py.File(f) as h5:
        assert "temperature_time" in h5
    assert np.array_equal(io.read_record(f).temperature.time, tt)


def test_record_without_temperature_reads_as_none(tmp_path):
    f = tmp_path / "plain.h5"
    io.write_record(f, _record())
    with h5py.File(f) as h5:
        assert "temperature" not in h5 and "temperature_time" not in h5
    assert all(temp is None for temp in _readers(f).values())
    assert io.read_record(f).truth is None


def test_truth_thermal_round_trip(tmp_path):
    model = scenarios.thermal_model()
    assert not model.is_zero and model.has_rate  # the comparison below covers every kind of term
    truth = Truth(ImuErrors(), GimbalErrors(), ImuNoise(), model)
    rec = _record(Temperature(np.array([0.0, 12.0]), np.array([[-40.0], [60.0]]), ("imu",)), truth)
    f = tmp_path / "truth.h5"
    io.write_record(f, rec)
    back = io.read_record(f).truth.thermal
    for key in ("t_ref", "t_min", "t_max", "out_of_range", "sensor"):
        assert getattr(back, key) == getattr(model, key), key
    for name in (*THERMAL_TERMS, "gyro_bias_rate"):
        a, b = np.asarray(getattr(model, name)), np.asarray(getattr(back, name))
        assert a.shape == b.shape and np.array_equal(a, b), name
    assert io.record_info(f).truth.thermal.t_ref == model.t_ref
    # a truth without a thermal model stays without one
    io.write_record(tmp_path / "plain_truth.h5", _record(truth=Truth(ImuErrors(), GimbalErrors(), ImuNoise())))
    assert io.read_record(tmp_path / "plain_truth.h5").truth.thermal is None


# ----------------------------------------------------------------------------- damaged /temperature
def _replace(h5, name, data, sensors=None):
    del h5[name]
    h5.create_dataset(name, data=data)
    if sensors is not None:
        h5[name].attrs["sensors"] = sensors


def _wrong_shape(h5):
    _replace(h5, "temperature", np.zeros((13, 2, 2)), json.dumps(["a", "b"]))


def _not_numeric(h5):
    _replace(h5, "temperature", np.array([b"warm"] * 13), json.dumps(["a"]))


def _sensors_not_json(h5):
    h5["temperature"].attrs["sensors"] = "gyro, accel"


def _sensors_not_a_list(h5):
    h5["temperature"].attrs["sensors"] = json.dumps({"gyro": 0})


def _sensor_count(h5):
    h5["temperature"].attrs["sensors"] = json.dumps(["a", "b", "c"])


def _time_not_increasing(h5):
    t = np.arange(13.0)
    t[5] = t[3]
    _replace(h5, "temperature_time", t)


def _length_without_time(h5):
    del h5["temperature_time"]


def _nan_value(h5):
    v = h5["temperature"][()]
    v[4, 1] = np.nan
    _replace(h5, "temperature", v, json.dumps(["gyro", "accel"]))


def _kelvin(h5):
    _replace(h5, "temperature", h5["temperature"][()] + 273.15, json.dumps(["gyro", "accel"]))


#: damage -> the words the one line must hold
DAMAGE = {
    _wrong_shape: "values have shape (13, 2, 2), expected (13, sensors)",
    _not_numeric: "/temperature is not a numeric dataset",
    _sensors_not_json: "attribute sensors is not a JSON list of names",
    _sensors_not_a_list: "attribute sensors is not a JSON list of names",
    _sensor_count: "2 column(s) but 3 sensor name(s)",
    _time_not_increasing: "time does not increase at reading 5",
    _length_without_time: "/temperature has 13 readings and no /temperature_time, but the record has 120 samples",
    _nan_value: "1 NaN/inf values, first at reading 4",
    _kelvin: "(kelvin? give the column's unit as K)",
}


@pytest.mark.parametrize("damage", list(DAMAGE), ids=lambda f: f.__name__.strip("_"))
def test_damaged_temperature_is_one_line(tmp_path, damage):
    rec = _record()
    tt = np.arange(13.0)
    rec.temperature = Temperature(tt, np.column_stack([20.0 + tt, 21.0 + tt]), ("gyro", "accel"))
    f = tmp_path / "damaged.h5"
    io.write_record(f, rec)
    io.read_record(f)  # the control: the record reads before the damage
    with h5py.File(f, "r+") as h5:
        damage(h5)
    for reader in (io.read_record, io.record_info):
        with pytest.raises(DataFileError) as exc:
            reader(f)
        msg = str(exc.value)
        assert DAMAGE[damage] in msg and "\n" not in msg and msg.startswith(str(f)), msg
    with pytest.raises(DataFileError, match="temperature"):
        with io.open_record(f):
            pass


def test_temperature_refuses_bad_input_in_memory():
    t = np.arange(3.0)
    with pytest.raises(DataFileError, match="time does not increase"):
        Temperature(np.array([0.0, 2.0, 1.0]), np.zeros(3), ("a",))
    with pytest.raises(DataFileError, match="sensor names repeat"):
        Temperature(t, np.zeros((3, 2)), ("a", "a"))
    with pytest.raises(DataFileError, match="outside the plausible"):
        Temperature(t, np.full(3, -300.0), ("a",))
