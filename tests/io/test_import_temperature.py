"""Temperature through inscal import / export: temperature columns of a csv or text file named in the
mapping (one or several sensors, degC / K / degF, empty cells of a slower sensor), readings at their
own times from a separate file, malformed temperature data refused with one line and nothing
written, and export -> import round trips of a record's temperature."""

import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.core import earth
from inscal.core.earth import Site
from inscal import io
from inscal.io import importers
from inscal.io.mapping import ImportFileError, parse_mapping
from inscal.io.records import Record, Temperature

runner = CliRunner()
SITE = ["--lat", 45, "--lon", 10, "--height", 50]
N, DT = 60, 0.1


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def listing(d: Path) -> set:
    return {p.name for p in d.iterdir()}


def _imu(n=N, t0=0.0):
    """A static E-N-U IMU at 45 deg N, 10 Hz: sample end times, increments (rad, m/s)."""
    rng = np.random.default_rng(3)
    lat = math.radians(45.0)
    t = t0 + (np.arange(n) + 1) * DT
    dth = np.tile(earth.OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)]) * DT, (n, 1))
    dth = dth + 1e-8 * rng.standard_normal((n, 3))
    dv = np.tile([0.0, 0.0, earth.normal_gravity(lat, 50.0) * DT], (n, 1)) + 1e-5 * rng.standard_normal((n, 3))
    return t, dth, dv


def _csv(path: Path, temps: dict, delim=",", t0=0.0) -> tuple:
    """A csv ``time, gx..az (rad, m/s), then one column per entry of temps`` (header names = keys;
    a value: (N,) array, NaN written as an empty cell, or a list of cell strings)."""
    t, dth, dv = _imu(t0=t0)
    names = ["t", "gx", "gy", "gz", "ax", "ay", "az", *temps]
    lines = [delim.join(names)]
    for i in range(N):
        cells = ["%.17g" % v for v in (t[i], *dth[i], *dv[i])]
        for col in temps.values():
            x = col[i]
            cells.append(x if isinstance(x, str) else ("" if np.isnan(x) else "%.17g" % x))
        lines.append(delim.join(cells))
    path.write_text("\n".join(lines) + "\n")
    return t, dth, dv


MAPPING = ('header_rows = 1\n[columns]\ntime = "t"\ngx = "gx"\ngy = "gy"\ngz = "gz"\nax = "ax"\nay = "ay"\n'
           'az = "az"\n{temperature}[units]\ngyro = "rad"\naccel = "m/s"\n{unit}')


def _mapping(path: Path, temperature: str = 'temperature = "T_imu"\n', unit: str = "", extra: str = "") -> Path:
    path.write_text(extra + MAPPING.format(temperature=temperature, unit=unit))
    return path


def _import(tmp_path, src, *args, fmt="csv", name="o.h5"):
    out = tmp_path / name
    code, so, se = run("import", src, "--format", fmt, "--out", out, *SITE, "--json", *args)
    assert code == 0, se
    return io.read_record(out), json.loads(so), out


# ----------------------------------------------------------------------------- mapping columns
def test_one_sensor_on_every_row_is_on_the_record_grid(tmp_path):
    T = 20.0 + 0.05 * np.arange(N) + 0.001 * np.sin(np.arange(N))
    t, dth, _ = _csv(tmp_path / "run.csv", {"T_imu": T})
    rec, summary, out = _import(tmp_path, tmp_path / "run.csv", "--mapping", _mapping(tmp_path / "m.toml"))
    assert np.array_equal(rec.time, t) and np.array_equal(rec.dtheta, dth)
    assert rec.temperature.sensors == ("T_imu",)
    assert np.array_equal(rec.temperature.time, rec.time) and np.array_equal(rec.temperature.values[:, 0], T)
    assert summary["temperature"] == {"sensors": ["T_imu"], "readings": N, "grid": "record", "source": "columns",
                                      "span_s": [t[0], t[-1]]}
    with h5py.File(out) as h5:
        assert "temperature_time" not in h5


@pytest.mark.parametrize("unit, to_file", [("K", lambda c: c + 273.15), ("degF", lambda c: c * 1.8 + 32.0),
                                           ("degC", lambda c: c), ("kelvin", lambda c: c + 273.15)])
def test_declared_unit_is_converted_to_celsius(tmp_path, unit, to_file):
    T = np.linspace(-40.0, 60.0, N)
    _csv(tmp_path / "run.csv", {"T_imu": to_file(T)})
    m = _mapping(tmp_path / "m.toml", unit=f'temperature = "{unit}"\n')
    rec, _, _ = _import(tmp_path, tmp_path / "run.csv", "--mapping", m)
    assert np.allclose(rec.temperature.values[:, 0], T, rtol=0, atol=1e-12)


def test_slower_sensor_keeps_its_own_times(tmp_path):
    """A 1 Hz sensor in a 10 Hz csv: empty cells between its readings; the readings keep the times of
    their rows, stored with /temperature_time."""
    T = np.full(N, np.nan)
    T[4::10] = 30.0 + np.arange(6) * 0.25
    t, _, _ = _csv(tmp_path / "run.csv", {"T_imu": T})
    rec, summary, out = _import(tmp_path, tmp_path / "run.csv", "--mapping", _mapping(tmp_path / "m.toml"))
    assert np.array_equal(rec.temperature.time, t[4::10])
    assert np.array_equal(rec.temperature.values[:, 0], T[4::10])
    assert summary["temperature"]["grid"] == "own" and summary["temperature"]["readings"] == 6
    with h5py.File(out) as h5:
        assert np.array_equal(h5["temperature_time"][()], t[4::10])


def test_several_sensors_by_table_list_and_index(tmp_path):
    """Two sensors reading on different rows share the rows where either reads; each is interpolated
    between its own readings on the other's rows (held beyond its first and last)."""
    g = np.full(N, np.nan)
    g[0::10] = 20.0 + np.arange(6)
    a = np.full(N, np.nan)
    a[5::10] = 40.0 - 2.0 * np.arange(6)
    t, _, _ = _csv(tmp_path / "run.csv", {"Tg": g, "Ta": a})
    m = _mapping(tmp_path / "m.toml", 'temperature = {gyro = "Tg", accel = 8}\n')
    rec, summary, _ = _import(tmp_path, tmp_path / "run.csv", "--mapping", m)
    rows = np.sort(np.r_[0:N:10, 5:N:10])
    assert rec.temperature.sensors == ("gyro", "accel") and summary["temperature"]["readings"] == 12
    assert np.array_equal(rec.temperature.time, t[rows])
    ig, ia = ~np.isnan(g), ~np.isnan(a)
    expect_g = np.interp(t[rows], t[ig], g[ig])
    expect_a = np.interp(t[rows], t[ia], a[ia])
    assert np.allclose(rec.temperature.values, np.column_stack([expect_g, expect_a]), rtol=0, atol=1e-12)
    assert np.array_equal(rec.temperature.values[0::2, 0], g[ig])  # each sensor's own readings untouched
    assert np.array_equal(rec.temperature.values[1::2, 1], a[ia])
    # a list: names from the header, and an index column is sensor T<k>
    m = _mapping(tmp_path / "m2.toml", 'temperature = ["Tg", 8]\n')
    rec, _, _ = _import(tmp_path, tmp_path / "run.csv", "--mapping", m, name="o2.h5")
    assert rec.temperature.sensors == ("Tg", "T1")


def test_whitespace_text_with_a_temperature_column(tmp_path):
    T = 15.0 + 0.1 * np.arange(N)
    _csv(tmp_path / "run.txt", {"T_imu": T}, delim=" ")
    m = _mapping(tmp_path / "m.toml")
    rec, _, _ = _import(tmp_path, tmp_path / "run.txt", "--mapping", m, fmt="txt")
    assert np.array_equal(rec.temperature.values[:, 0], T)


def test_mapping_temperature_keys_are_checked():
    base = {"header_rows": 1, "columns": {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6},
            "units": {"gyro": "rad", "accel": "m/s"}}

    def parsed(columns=None, units=None):
        d = {**base, "columns": {**base["columns"], **(columns or {})}, "units": {**base["units"], **(units or {})}}
        return parse_mapping(d, "csv")[0]

    m = parsed({"temperature": "T"}, {"temperature": "K"})
    assert m.temperature == (("T", "T"),) and m.temperature_unit == "K"
    assert parsed({"temperature": 7}).temperature == (("T0", 7),)
    for columns, units, words in [
        ({"temperature": "T"}, {"temperature": "kelvinn"}, "[units] temperature: unknown temperature unit 'kelvinn'"),
        ({}, {"temperature": "degC"}, "[units] temperature applies with a [columns] temperature"),
        ({"temperature": 3}, {}, "[columns] gz and temperature sensor 'T0' both read column 3"),
        ({"temperature": ["T", "T"]}, {}, "sensor names repeat"),
        ({"temperature": []}, {}, "names no column"),
        ({"temperature": -1}, {}, "must be a 0-based index or a header name, got -1"),
        ({"temperature": {"gyro": 1.5}}, {}, "the column of sensor 'gyro' must be a 0-based index"),
    ]:
        with pytest.raises(ImportFileError) as exc:
            parsed(columns, units)
        assert words in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


# ----------------------------------------------------------------------------- malformed temperature data
def _cells(T, **at):
    """Temperature cells as strings, with some replaced: ``{row: text}``."""
    c = ["%.6g" % x for x in T]
    for row, text in at.items():
        c[int(row.strip("r"))] = text
    return c


T_OK = 20.0 + 0.05 * np.arange(N)
#: case -> (temperature columns of the csv, mapping's [columns] temperature line, [units] temperature line,
#: the words of the one-line error)
MALFORMED = {
    "column_absent": ({"T_imu": T_OK}, 'temperature = "T_chamber"\n', "",
                      "no column named 'T_chamber' (for temperature sensor 'T_chamber'); header: ['t', 'gx'"),
    "index_out_of_range": ({"T_imu": T_OK}, "temperature = 9\n", "",
                           "column index 9 (for temperature sensor 'T0') is out of range: rows have 8 columns"),
    "not_a_number": ({"T_imu": _cells(T_OK, r11="21.3x")}, 'temperature = "T_imu"\n', "",
                     "run.csv: line 13, column 7 ('T_imu'): '21.3x' is not a number"),
    "not_a_number_beside_empty_cells": ({"T_imu": _cells(T_OK, r11="warm", r3="", r4="")}, 'temperature = "T_imu"\n',
                                        "", "run.csv: line 13, column 7 ('T_imu'): 'warm' is not a number"),
    "all_empty": ({"T_imu": [""] * N}, 'temperature = "T_imu"\n', "",
                  "temperature 'T_imu' (column 7 'T_imu') has no reading: all its 60 cells are empty"),
    "nan": ({"T_imu": _cells(T_OK, r20="nan")}, 'temperature = "T_imu"\n', "",
            "line 22, column 7 ('T_imu'): 'nan' is not a temperature reading (leave the cell empty"),
    "inf_beside_empty_cells": ({"T_imu": _cells(T_OK, r20="inf", r2="")}, 'temperature = "T_imu"\n', "",
                               "line 22, column 7 ('T_imu'): 'inf' is not a temperature reading"),
    "kelvin_declared_celsius": ({"T_imu": T_OK + 273.15}, 'temperature = "T_imu"\n', "",
                                "temperature 'T_imu' (column 7 'T_imu') reads 293.15 degC at line 2 "
                                "(its readings 293.15 .. 296.1 degC), outside the plausible -100 .. 200 degC; as K "
                                "they would read 20 .. 22.95 degC: set [units] temperature = \"K\" in "),
    "celsius_declared_kelvin": ({"T_imu": T_OK}, 'temperature = "T_imu"\n', 'temperature = "K"\n',
                                "reads 20 K = -253.15 degC at line 2 (its readings -253.15 .. -250.2 degC), outside "
                                "the plausible -100 .. 200 degC; as degC they would read 20 .. 22.95 degC: set "
                                "[units] temperature = \"degC\""),
    "unknown_unit": ({"T_imu": T_OK}, 'temperature = "T_imu"\n', 'temperature = "Kelvins"\n',
                     "[units] temperature: unknown temperature unit 'Kelvins'; known: degC, K, degF"),
    "raw_counts": ({"T_imu": np.full(N, 4095.0)}, 'temperature = "T_imu"\n', "",
                   "reads 4095 degC at line 2 (its readings 4095 .. 4095 degC), outside the plausible"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_temperature_is_refused_with_one_line(tmp_path, case):
    cols, tline, uline, words = MALFORMED[case]
    _csv(tmp_path / "run.csv", cols)
    m = _mapping(tmp_path / "m.toml", tline, uline)
    before = listing(tmp_path)
    code, so, se = run("import", tmp_path / "run.csv", "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5",
                       *SITE)
    assert code == 2, so + se
    assert se.startswith("inscal: error: ") and se.count("\n") == 1, se
    assert words in se, se
    assert listing(tmp_path) == before  # nothing written, no temporary file left


def test_malformed_cases_start_from_a_good_file(tmp_path):
    """The control: the same csv and mapping with good temperature cells import."""
    _csv(tmp_path / "run.csv", {"T_imu": _cells(T_OK, r3="", r4="")})
    rec, _, _ = _import(tmp_path, tmp_path / "run.csv", "--mapping", _mapping(tmp_path / "m.toml"))
    assert rec.temperature.time.shape == (N - 2,)


# ----------------------------------------------------------------------------- a separate temperature file
def _plain_csv(tmp_path, t0=0.0) -> Path:
    """The sample csv without temperature, imported with the default mapping (the export header)."""
    t, dth, dv = _imu(t0=t0)
    f = tmp_path / "imu.csv"
    rows = np.column_stack([t, dth, dv])
    f.write_text(",".join(importers.EXPORT_HEADER) + "\n" + "".join(",".join("%.17g" % v for v in r) + "\n"
                                                                       for r in rows))
    return f


def test_temperature_file_at_its_own_times(tmp_path):
    f = _plain_csv(tmp_path)
    tf = tmp_path / "chamber.csv"
    tt = np.arange(0.0, 6.5, 0.5)
    tf.write_text("# chamber log\ntime [ms],inner [K],outer [degF]\n"
                  + "".join(f"{x * 1e3:g},{293.15 + x:.17g},{68 + 1.8 * x:.17g}\n" for x in tt))
    rec, summary, out = _import(tmp_path, f, "--temperature", tf)
    assert rec.temperature.sensors == ("inner", "outer")
    assert np.allclose(rec.temperature.time, tt, rtol=0, atol=1e-15)
    assert np.allclose(rec.temperature.values, np.column_stack([20 + tt, 20 + tt]), rtol=0, atol=1e-11)
    assert summary["temperature"]["source"] == "file" and summary["temperature"]["grid"] == "own"
    with h5py.File(out) as h5:
        assert json.loads(h5.attrs["source"])["temperature_file"] == str(tf)


def test_whitespace_temperature_file(tmp_path):
    f = _plain_csv(tmp_path)
    tf = tmp_path / "T.txt"
    tf.write_text("time [s]  imu [degC]   case\n0 20.5 19\n3 21.5 19.5\n6 22.5 20\n")
    rec, _, _ = _import(tmp_path, f, "--temperature", tf)
    assert rec.temperature.sensors == ("imu", "case")
    assert np.array_equal(rec.temperature.values, [[20.5, 19.0], [21.5, 19.5], [22.5, 20.0]])
    tf.write_text("time [s]  imu [degC]   case\n0 20.5 19\n3 21.5 warm\n")
    code, _, se = run("import", f, "--format", "csv", "--out", tmp_path / "o2.h5", *SITE, "--temperature", tf)
    assert code == 2 and "T.txt: line 3, column 2 ('case'): 'warm' is not a number" in se, se


def test_temperature_file_moves_with_the_path_start(tmp_path):
    """With --path and --path-start-s the record's time starts at the path: the readings are shifted with it."""
    f = _plain_csv(tmp_path, t0=100.0)
    path = tmp_path / "path.toml"
    path.write_text('[path]\nname = "rest"\nmoves = [{axis = "none", dwell_s = 7.0}]\n')
    tf = tmp_path / "T.csv"
    tf.write_text("time [s],imu [degC]\n" + "".join(f"{100 + k},{20 + k}\n" for k in range(8)))
    rec, summary, _ = _import(tmp_path, f, "--path", path, "--path-start-s", 100, "--temperature", tf)
    assert summary["time_offset_s"] == 100.0 and abs(rec.time[0] - DT) < 1e-12
    assert np.allclose(rec.temperature.time, np.arange(8.0), rtol=0, atol=1e-12)
    assert np.array_equal(rec.temperature.values[:, 0], 20.0 + np.arange(8))


#: temperature file text -> the words of the one-line error
BAD_FILES = {
    "time_not_increasing": ("time [s],imu [degC]\n0,20\n1,21\n2,22\n1.5,23\n4,24\n",
                            "the time does not increase at line 5 (t = 1.5 s after 2 s)"),
    "no_header": ("0,20\n1,21\n", "line 1: a temperature file starts with a header row naming its columns"),
    "unknown_unit": ("time [s],imu [Kelvins]\n0,20\n1,21\n", "header cell 'imu [Kelvins]': unknown temperature unit"),
    "no_sensor": ("time [s]\n0\n1\n", "names no temperature column after the time"),
    "not_a_number": ("time [s],imu [degC]\n0,20\n1,2l\n", "line 3, column 1 ('imu [degC]'): '2l' is not a number"),
    "nan": ("time [s],imu [degC]\n0,20\n1,NaN\n", "line 3, column 1 ('imu [degC]'): 'NaN' is not a temperature reading"),
    "all_empty": ("time [s],imu [degC],case [degC]\n0,20,\n1,21,\n", "temperature 'case' (column 2) has no reading"),
    "kelvin_as_celsius": ("time [s],imu\n0,293.2\n1,293.4\n",
                          "as K they would read 20.05 .. 20.25 degC: give the column's unit in the header, as "
                          "'imu [K]'"),
    "no_overlap": ("time [s],imu [degC]\n100,20\n101,21\n",
                   "the temperature readings cover t = 100 .. 101 s; the record runs t = 0 .. 6 s: no overlap"),
    "repeated_sensor": ("time [s],imu,imu\n0,20,20\n", "temperature sensor names repeat in the header"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_temperature_file_is_refused_with_one_line(tmp_path, case):
    f = _plain_csv(tmp_path)
    text, words = BAD_FILES[case]
    tf = tmp_path / "T.csv"
    tf.write_text(text)
    before = listing(tmp_path)
    code, so, se = run("import", f, "--format", "csv", "--out", tmp_path / "o.h5", *SITE, "--temperature", tf)
    assert code == 2, so + se
    assert se.startswith("inscal: error: ") and se.count("\n") == 1 and words in se, se
    assert listing(tmp_path) == before


def test_a_temperature_file_must_cover_the_record(tmp_path):
    """One reading held over a 2-min record (or readings that stop long before its end) is refused."""
    t, dth, dv = _imu(n=1200)
    f = tmp_path / "imu.csv"
    f.write_text(",".join(importers.EXPORT_HEADER) + "\n" + "".join(",".join("%.17g" % v for v in r) + "\n"
                                                                       for r in np.column_stack([t, dth, dv])))
    tf = tmp_path / "T.csv"
    for text, words in (("time [s],imu [degC]\n0,20\n", "1 reading at t = 0 .. 0 s leave 120 s of the record"),
                        ("time [s],imu [degC]\n0,20\n10,21\n20,21\n", "leave 100 s of the record")):
        tf.write_text(text)
        before = listing(tmp_path)
        code, so, se = run("import", f, "--format", "csv", "--out", tmp_path / "o.h5", *SITE, "--temperature", tf)
        assert code == 2 and se.count("\n") == 1 and words in se and "after its last" in se, se
        assert listing(tmp_path) == before
    tf.write_text("time [s],imu [degC]\n0,20\n60,21\n110,21\n")  # within 60 s of both ends: taken
    assert run("import", f, "--format", "csv", "--out", tmp_path / "o.h5", *SITE, "--temperature", tf)[0] == 0


def test_temperature_columns_and_a_temperature_file_are_refused_together(tmp_path):
    _csv(tmp_path / "run.csv", {"T_imu": T_OK})
    tf = tmp_path / "T.csv"
    tf.write_text("time [s],imu [degC]\n0,20\n6,21\n")
    code, _, se = run("import", tmp_path / "run.csv", "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"),
                      "--out", tmp_path / "o.h5", *SITE, "--temperature", tf)
    assert code == 2 and "has temperature columns; --temperature would give the temperature twice" in se, se


# ----------------------------------------------------------------------------- export -> import
def _record_file(tmp_path, temp: Temperature, name="rec.h5") -> Path:
    t, dth, dv = _imu()
    f = tmp_path / name
    io.write_record(f, Record(t, dth, dv, None, 1.0 / DT, Site(math.radians(45.0), math.radians(10.0), 50.0),
                              temperature=temp))
    return f


def _export_import(tmp_path, f, *args):
    code, so, se = run("export", f, "--format", "csv", "--out", tmp_path / "x.csv", "--json", *args)
    assert code == 0, se
    rec, _, _ = _import(tmp_path, tmp_path / "x.csv", name="back.h5")
    return json.loads(so), (tmp_path / "x.csv").read_text().splitlines(), rec


def test_round_trip_on_the_record_grid(tmp_path):
    t, _, _ = _imu()
    temp = Temperature(t, np.column_stack([20 + np.sqrt(t), 25 - t / 3]), ("gyro", "accel"))
    res, lines, rec = _export_import(tmp_path, _record_file(tmp_path, temp))
    assert res["temperature"] == "columns"
    assert lines[0].endswith(",temperature gyro [degC],temperature accel [degC]") and not lines[1].startswith("#")
    assert rec.temperature.sensors == temp.sensors
    assert np.array_equal(rec.temperature.time, t) and np.array_equal(rec.temperature.values, temp.values)


def test_round_trip_readings_at_some_sample_times_leave_cells_empty(tmp_path):
    t, _, _ = _imu()
    temp = Temperature(t[9::10], 30.0 + np.arange(6) / 7.0, ("imu",))
    res, lines, rec = _export_import(tmp_path, _record_file(tmp_path, temp))
    assert res["temperature"] == "columns" and lines[1].startswith("# temperature: the 6 readings")
    assert sum(line.endswith(",") for line in lines[2:]) == N - 6
    assert np.array_equal(rec.temperature.time, temp.time) and np.array_equal(rec.temperature.values, temp.values)


def test_round_trip_readings_off_the_sample_times_are_interpolated(tmp_path):
    """A 1 Hz sensor from t = 0 (before the first sample ends): the csv carries the readings interpolated
    onto the sample times and says so; --temperature-out carries the readings themselves."""
    t, _, _ = _imu()
    tt = np.arange(0.0, 6.5, 1.0) + 0.03
    vals = np.column_stack([-10.0 + tt ** 2, 5.0 + tt])
    temp = Temperature(tt, vals, ("gyro", "case"))
    res, lines, rec = _export_import(tmp_path, _record_file(tmp_path, temp), "--temperature-out", tmp_path / "T.csv")
    assert res["temperature"] == "interpolated" and res["temperature_out"] == str(tmp_path / "T.csv")
    assert lines[1].startswith("# temperature: interpolated linearly onto the sample times from the 7 readings")
    assert np.array_equal(rec.temperature.time, t)
    expect = np.column_stack([np.interp(t, tt, vals[:, k]) for k in range(2)])
    assert np.allclose(rec.temperature.values, expect, rtol=0, atol=1e-12)
    assert not np.allclose(rec.temperature.values[:, 0], np.interp(t, t[::10], np.interp(t[::10], tt, vals[:, 0])),
                           rtol=0, atol=1e-3)  # interpolated at every sample, not at a coarser grid
    # the readings file imports back exactly, with the psins export of the same record
    assert run("export", tmp_path / "rec.h5", "--format", "psins", "--out", tmp_path / "x.bin")[0] == 0
    back, _, _ = _import(tmp_path, tmp_path / "x.bin", "--temperature", tmp_path / "T.csv", fmt="psins", name="b2.h5")
    assert back.temperature.sensors == ("gyro", "case")
    assert np.array_equal(back.temperature.time, tt) and np.array_equal(back.temperature.values, vals)


def test_export_of_a_record_without_temperature_is_unchanged(tmp_path):
    t, dth, dv = _imu()
    f = tmp_path / "plain.h5"
    io.write_record(f, Record(t, dth, dv, None, 1.0 / DT, Site(0.7, 0.1, 50.0)))
    code, so, se = run("export", f, "--format", "csv", "--out", tmp_path / "x.csv", "--json")
    assert code == 0 and json.loads(so)["temperature"] is None, se
    assert (tmp_path / "x.csv").read_text().splitlines()[0] == ",".join(importers.EXPORT_HEADER)
    code, _, se = run("export", f, "--format", "psins", "--out", tmp_path / "x.bin", "--temperature-out",
                      tmp_path / "T.csv")
    assert code == 2 and "the record has no temperature for --temperature-out" in se, se
    assert not (tmp_path / "x.bin").exists() and not (tmp_path / "T.csv").exists()


def test_export_refuses_a_sensor_name_that_cannot_head_a_column(tmp_path):
    t, _, _ = _imu()
    f = _record_file(tmp_path, Temperature(t, np.full(N, 20.0), ("gyro,x",)))
    code, _, se = run("export", f, "--format", "csv", "--out", tmp_path / "x.csv")
    assert code == 2 and "temperature sensor 'gyro,x' cannot name a column of a csv" in se, se
    assert not (tmp_path / "x.csv").exists()


def test_a_source_replaced_while_it_is_imported_is_refused(tmp_path, monkeypatch):
    """The source is replaced between the hash and the end of its reading: refused (its hash would not be the
    data's), nothing written."""
    f = _plain_csv(tmp_path)
    real = importers.read_source

    def read_then_replace(src, *a, **kw):
        raw = real(src, *a, **kw)
        new = tmp_path / "new.csv"
        new.write_text(f.read_text() + f.read_text().splitlines()[-1] + "\n")
        new.replace(f)  # another program saves a new version under the same name
        return raw

    monkeypatch.setattr(importers, "read_source", read_then_replace)
    code, _, se = run("import", f, "--format", "csv", "--out", tmp_path / "o.h5", *SITE)
    assert code == 2 and se.count("\n") == 1 and "changed while it was imported" in se, se
    assert not (tmp_path / "o.h5").exists()
