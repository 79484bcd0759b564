"""inscal import: values no IMU can give, and time columns in the wrong unit.

Two classes of input were accepted with a NumPy overflow warning, or blamed on the wrong cause:

1. a value beyond the physical limits (1e300, an angular increment of 1e3 rad per sample, a velocity
   increment implying over 1,000 g, a gimbal angle of 1e300 or a jump no encoder makes, a timestamp
   of 1e300 or one out of line with its neighbours, absurd counts in a PSINS ``.imu`` log): refused
   with the file, the column, the line (row), the value and the limit;
2. a time column in milliseconds (microseconds) read as seconds, or seconds declared as milliseconds:
   named as such with the fix (the mapping's ``[units] time``, a gimbal file's header, the PSINS
   format's seconds), whether the sample interval, ``--rate-hz`` or gravity gives it away, for
   increments and for rates.

Each refusal is one line ``inscal: error: ...`` on stderr, exit 2, no warning, nothing written,
the inputs unchanged.
"""

import hashlib
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.io import importers
from inscal import io
from inscal.sim import scenarios
from inscal.sim.simulate import write_simulation

SITE = ["--lat", "34", "--lon", "108", "--height", "400"]
HEADER = "t,gx,gy,gz,ax,ay,az,outer,inner"
MAPPING = """header_rows = 1
{kind}
[columns]
time = 0
gx = 1
gy = 2
gz = 3
ax = 4
ay = 5
az = 6
[units]
gyro = "{gyro}"
accel = "{accel}"
{time}
"""


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """20 s of the n25 IMU (errors and noise) on a static base at 100 Hz, as rows
    ``[t, dtheta(3), dvel(3), outer, inner]`` (s, rad, m/s)."""
    d = tmp_path_factory.mktemp("values")
    f = d / "n.h5"
    write_simulation(f, scenarios.build("n25-static", duration_s=20.0), np.random.default_rng(3))
    r = io.read_record(f)
    rows = np.column_stack([r.time, r.dtheta, r.dvel, r.gimbal])
    return rows


def _csv(path: Path, rows: np.ndarray, header: str = HEADER, cells: dict | None = None) -> Path:
    """``rows`` as csv, with ``cells`` {(row, column): text} written verbatim (1e300, inf ...)."""
    lines = [header]
    for i, row in enumerate(rows):
        lines.append(",".join((cells or {}).get((i, c), f"{v:.17g}") for c, v in enumerate(row)))
    path.write_text("\n".join(lines) + "\n")
    return path


def _mapping(path: Path, kind="increments", time=None, gimbal=False) -> Path:
    gyro, accel = ("rad", "m/s") if kind == "increments" else ("rad/s", "m/s^2")
    text = MAPPING.format(kind=f'kind = "{kind}"', gyro=gyro, accel=accel,
                          time="" if time is None else f'time = "{time}"')
    if gimbal:
        text = text.replace("az = 6\n", "az = 6\nouter = 7\ninner = 8\n") + 'gimbal = "rad"\n'
    path.write_text(text)
    return path


def _psins_imu(path: Path, rows: np.ndarray, interval_ms: float = 10.0, edit=None) -> Path:
    """A PSINS compact text log of ``rows`` (0.1" and 125 ug*s per count); ``edit(counts)`` may alter
    the counts (N, 6) before they are written."""
    g = 9.7803267714
    q = np.r_[[0.1 * math.pi / 648000] * 3, [125e-6 * g] * 3]
    counts = np.diff(np.vstack([np.zeros((1, 6)), np.trunc(np.cumsum(rows[:, 1:7] / q, axis=0))]), axis=0)
    if edit is not None:
        edit(counts)
    with open(path, "w") as fh:
        fh.write("% PSINS-format SIMU log file. (DO NOT MODIFY!)\n")
        fh.write("0 0 0 0 0 0\n")
        fh.write(f"34.0 108.0 400.0 0.0 {interval_ms:.8f} {g:f}\n")
        fh.write("0.1 0.1 0.1 125 125 125\n")
        np.savetxt(fh, counts, fmt="%d")
    return path


def _digest(paths) -> dict:
    return {p: hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in paths}


def refused(tmp_path, args, *phrases):
    """Run ``inscal import ARGS --out OUT``: exit 2, one line with every phrase, nothing written, the
    inputs unchanged, no warning; returns the line."""
    inputs = [a for a in args if isinstance(a, Path)]
    before = _digest(inputs)
    listing = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "out.h5"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a NumPy overflow warning on the way is a failure
        r = CliRunner().invoke(app, ["import", *map(str, args), "--out", str(out)])
    assert r.exit_code == 2, (r.exit_code, r.output, r.exception)
    assert r.stderr.startswith("inscal: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.output and "Warning" not in r.stderr, r.output
    for ph in phrases:
        assert ph in r.stderr, (ph, r.stderr)
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == listing
    assert _digest(inputs) == before
    return r.stderr


def imports(tmp_path, args) -> io.Record:
    out = tmp_path / "ok.h5"
    r = CliRunner().invoke(app, ["import", *map(str, args), "--out", str(out), "--force"])
    assert r.exit_code == 0, r.output
    return io.read_record(out)


# ----------------------------------------------------------------------------- 1. values beyond physics
@pytest.mark.parametrize("cell, value, phrases", [
    # the brief's case: 1e300 in a gyro column
    ((5, 1), "1e300", ["gx (column 1 'gx') is 1e+300 at line 7", "beyond any gyro (limit 628 rad/s = 100 rev/s)"]),
    # an angular increment of 1e3 rad in one sample (1e5 rad/s at 100 Hz)
    ((9, 3), "1000", ["gz (column 3 'gz') is 1000 at line 11", "an angular rate of 1e+05 rad/s"]),
    # a velocity increment of 100 m/s in 10 ms: 1,020 g
    ((20, 5), "-100", ["ay (column 5 'ay') is -100 at line 22", "1.02e+03 g", "(limit 1000 g)"]),
    ((3, 6), "1e300", ["az (column 6 'az') is 1e+300 at line 5", "beyond any accelerometer"]),
    # gimbal angle columns: an absurd reading, and a jump no turntable makes
    ((30, 7), "1e300", ["outer angle is 1e+300 rad", "at line 32", "limit 1.01e+07 rad"]),
    ((30, 8), "5000", ["inner angle is 5000 rad", "at line 32", "a jump of 5e+03 rad in one interval"]),
    # timestamps: beyond any clock, and one corrupt value between good ones
    ((7, 0), "1e300", ["time (column 0) is 1e+300 s at line 9: beyond any clock (limit 1e+12 s"]),
    ((7, 0), "5000", ["time (column 0) is 5000 s at line 9, out of line with its neighbours (0.07 and 0.09 s)"]),
])
def test_csv_value_beyond_physics_is_named(base, tmp_path, cell, value, phrases):
    src = _csv(tmp_path / "log.csv", base, cells={cell: value})
    m = _mapping(tmp_path / "map.toml", gimbal=True)
    refused(tmp_path, [src, "--format", "csv", "--mapping", m, *SITE], "log.csv: ", *phrases)


def test_a_channel_of_zeros_with_one_absurd_value_is_not_taken_for_counts(base, tmp_path):
    """A noise-free record's x gyro reads 0 on every sample: one 1e300 made it 'whole numbers only'
    and the message blamed raw counts."""
    rows = base.copy()
    rows[:, 1] = 0.0
    src = _csv(tmp_path / "log.csv", rows, cells={(5, 1): "1e300"})
    msg = refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), *SITE],
                  "gx (column 1 'gx') is 1e+300 at line 7", "beyond any gyro")
    assert "whole numbers" not in msg


def test_rates_beyond_physics(base, tmp_path):
    """As rates (rad/s, m/s^2) the limit applies to the value itself: 2,000 g in one accelerometer row."""
    rows = base.copy()
    rows[:, 1:7] *= 100.0
    src = _csv(tmp_path / "rates.csv", rows[:, :7], header="t,gx,gy,gz,ax,ay,az", cells={(12, 4): "19613.3"})
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml", "rates"), *SITE],
            "ax (column 4 'ax') is 19613.3 at line 14", "2e+03 g, a rate in m/s^2", "(limit 1000 g)")


def test_every_value_beyond_physics_is_a_unit_error(base, tmp_path):
    """All values over the limit (velocity increments in mm/s declared m/s, times 1000 more): a scale
    error, said so, not a corrupt row."""
    rows = base.copy()
    rows[:, 6] *= 1e6
    src = _csv(tmp_path / "log.csv", rows[:, :7], header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), *SITE],
            "az (column 6 'az')", "of the 2000 values: a unit or scale error, not a corrupt value")


def test_psins_bin_value_beyond_physics(base, tmp_path):
    a = np.column_stack([base[:, 1:7], base[:, 0]]).astype("<f8")
    a[4, 0] = 1e300
    src = tmp_path / "log.bin"
    a.tofile(src)
    refused(tmp_path, [src, "--format", "psins", *SITE],
            "log.bin: dthx (column 1) is 1e+300 at row 5", "beyond any gyro (limit 628 rad/s")
    a[4, 0] = base[4, 1]
    a[17, 5] = 120.0  # 120 m/s in 10 ms: 1,220 g
    a.tofile(src)
    refused(tmp_path, [src, "--format", "psins", *SITE], "dvz (column 6) is 120 at row 18", "1.22e+03 g")


def test_psins_imu_counts_beyond_physics(base, tmp_path):
    def edit(c):
        c[10, 1] = 1e15  # 1e15 counts of 0.1": 4.8e10 rad in 10 ms
    src = _psins_imu(tmp_path / "log.imu", base, edit=edit)
    refused(tmp_path, [src, "--format", "psins-imu"], "log.imu: gy (counts) is 1e+15 at line 15", "beyond any gyro")


def test_gimbal_file_value_beyond_physics(base, tmp_path):
    src = _csv(tmp_path / "log.csv", base[:, :7], header="t,gx,gy,gz,ax,ay,az")
    g = tmp_path / "enc.csv"
    _csv(g, np.column_stack([np.r_[0.0, base[:, 0]], np.zeros((base.shape[0] + 1, 2))]), header="time,outer,inner",
         cells={(40, 1): "1e300"})
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), "--gimbal", g, *SITE],
            "enc.csv: outer angle is 1.74533e+298 rad (1e+300 deg) at line 42", "beyond any turntable")


def test_values_within_the_limits_import(base, tmp_path):
    """The control: 500 g and 300 rad/s in one row are extreme but possible."""
    rows = base.copy()
    rows[6, 4] = 500 * 9.80665 / 100.0
    rows[6, 1] = 3.0
    src = _csv(tmp_path / "log.csv", rows[:, :7], header="t,gx,gy,gz,ax,ay,az")
    rec = imports(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), *SITE])
    assert rec.n_samples == base.shape[0] and rec.dvel[6, 0] == rows[6, 4]


# ----------------------------------------------------------------------------- 2. the time column's unit
def _ms(rows: np.ndarray, factor: float = 1e3) -> np.ndarray:
    out = rows[:, :7].copy()
    out[:, 0] *= factor
    return out


def test_milliseconds_read_as_seconds_names_the_mapping_fix(base, tmp_path):
    src = _csv(tmp_path / "log.csv", _ms(base), header="t,gx,gy,gz,ax,ay,az")
    m = _mapping(tmp_path / "map.toml")
    refused(tmp_path, [src, "--format", "csv", "--mapping", m, *SITE],
            "log.csv: the time column (column 0) looks like milliseconds, not seconds (median sample interval 10 s: "
            "0.1 Hz as read, 100 Hz as milliseconds", f'set [units] time = "ms" in {m}')
    # the fix it names works
    rec = imports(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "ms.toml", time="ms"), *SITE])
    assert rec.rate_hz == 100.0 and np.allclose(rec.time, base[:, 0], atol=1e-12)


def test_milliseconds_with_rates(base, tmp_path):
    """Rates are not divided by the interval, so gravity looks right: the interval gives it away."""
    rows = _ms(base)
    rows[:, 1:7] *= 100.0
    src = _csv(tmp_path / "rates.csv", rows, header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml", "rates"), *SITE],
            "looks like milliseconds, not seconds", 'set [units] time = "ms"')


def test_milliseconds_at_one_kilohertz_are_found_by_gravity(base, tmp_path):
    """1 ms steps read as 1 s are a possible interval; increments over it read gravity / 1000."""
    rows = base[:, :7].copy()
    rows[:, 0] = np.arange(1, rows.shape[0] + 1, dtype=float)
    rows[:, 1:7] /= 10.0  # increments of 1 ms
    src = _csv(tmp_path / "log.csv", rows, header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), *SITE],
            "looks like milliseconds, not seconds (the accelerometers read",
            "of gravity: the interval is 1000 times too long")


def test_microseconds_and_seconds_declared_as_milliseconds(base, tmp_path):
    src = _csv(tmp_path / "us.csv", _ms(base, 1e6), header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), *SITE],
            "looks like microseconds, not seconds", 'set [units] time = "us"')  # a unit inscal reads
    src = _csv(tmp_path / "s.csv", base[:, :7], header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "ms.toml", time="ms"), *SITE],
            "looks like seconds, not milliseconds (median sample interval 0.01 ms: 100 kHz as read",
            'set [units] time = "s"')


def test_milliseconds_against_the_given_rate(base, tmp_path):
    src = _csv(tmp_path / "log.csv", _ms(base), header="t,gx,gy,gz,ax,ay,az")
    refused(tmp_path, [src, "--format", "csv", "--mapping", _mapping(tmp_path / "m.toml"), "--rate-hz", "100", *SITE],
            "looks like milliseconds, not seconds (median sample interval 10 s, 1000 times the 0.01 s of "
            "--rate-hz 100)")


def test_milliseconds_in_psins_and_in_a_csv_without_mapping(base, tmp_path):
    a = np.column_stack([base[:, 1:7], base[:, 0] * 1e3]).astype("<f8")
    src = tmp_path / "log.bin"
    a.tofile(src)
    refused(tmp_path, [src, "--format", "psins", *SITE], "log.bin: the time column looks like milliseconds",
            "the format holds seconds: divide its time column by 1000")
    src = _csv(tmp_path / "export.csv", _ms(base), header=",".join(importers.EXPORT_HEADER))
    refused(tmp_path, [src, "--format", "csv", *SITE], "looks like milliseconds",
            'import it with --mapping M.toml that sets [units] time = "ms"')


def test_gimbal_file_in_milliseconds(base, tmp_path):
    src = _csv(tmp_path / "log.csv", base[:, :7], header="t,gx,gy,gz,ax,ay,az")
    m = _mapping(tmp_path / "m.toml")
    t = np.r_[0.0, base[:, 0]] * 1e3
    g = _csv(tmp_path / "enc.csv", np.column_stack([t, np.zeros((t.size, 2))]), header="time,outer,inner")
    refused(tmp_path, [src, "--format", "csv", "--mapping", m, "--gimbal", g, *SITE],
            "enc.csv: the angles span t = 0 .. 20000 s", "its time column looks like milliseconds, not seconds",
            "give its header the unit, as 'time [ms],outer [deg],inner [deg]'")
    # ... and its header fixes it
    _csv(g, np.column_stack([t, np.zeros((t.size, 2))]), header="time [ms],outer [deg],inner [deg]")
    rec = imports(tmp_path, [src, "--format", "csv", "--mapping", m, "--gimbal", g, *SITE])
    assert rec.gimbal is not None and np.all(rec.gimbal == 0.0)


def test_psins_imu_header_interval_in_seconds(base, tmp_path):
    src = _psins_imu(tmp_path / "log.imu", base, interval_ms=0.01)
    refused(tmp_path, [src, "--format", "psins-imu"],
            "header sampling interval 0.01 ms (100000 Hz) is no IMU's", "it looks like seconds: write 10 (ms)")
