"""Imports trust the units they are told: a gyro magnitude that contradicts a unit the mapping (or a ROS
message type) declares is a warning naming the figure, not a refusal; an undeclared unit that reads like
another (rad/s read from values in deg/s) is still refused; a declared unit whose reading no gyro at rest
can have (arcsec declared as rad) is refused whatever is declared.  Plain ``.mcap`` files import as bag
folders do."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.io import importers

runner = CliRunner()
SITE = ["--lat", "30.5", "--lon", "114.0", "--height", "20.0"]
RATE, N = 100.0, 1000  # 10 s at 100 Hz
#: a consumer gyro's turn-on bias [deg/s]: |b| = 0.69 deg/s, 0.0121 rad/s (the figure a real session read)
BIAS_DPS = np.array([0.4, -0.4, 0.4])
G = 9.7936


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def still_rates(rng, bias_dps=BIAS_DPS):
    """A still IMU, z up: rates [deg/s] (the bias and white noise) and specific force [m/s^2]."""
    w = bias_dps + 0.02 * rng.normal(size=(N, 3))
    f = np.array([0.0, 0.0, G]) + 2e-3 * rng.normal(size=(N, 3))
    return w, f


def rates_csv(tmp_path, w_dps, f, gyro_unit="deg/s"):
    t = np.arange(1, N + 1) / RATE
    src = tmp_path / "r.csv"
    np.savetxt(src, np.column_stack([t, w_dps, f]), delimiter=",", fmt="%.12g", header="t,wx,wy,wz,fx,fy,fz",
               comments="")
    m = tmp_path / "m.toml"
    m.write_text('kind = "rates"\nheader_rows = 1\n[columns]\ntime = "t"\ngx = "wx"\ngy = "wy"\ngz = "wz"\nax = "fx"\n'
                 f'ay = "fy"\naz = "fz"\n[units]\ngyro = "{gyro_unit}"\naccel = "m/s^2"\n')
    return src, m


def test_declared_deg_s_with_a_mems_bias_imports_with_a_warning_naming_the_figure(tmp_path):
    rng = np.random.default_rng(1)
    w, f = still_rates(rng)
    src, m = rates_csv(tmp_path, w, f)
    code, so, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE)
    assert code == 0, se
    lines = se.strip().splitlines()
    p5 = np.percentile(np.linalg.norm(w.reshape(10, 100, 3).mean(axis=1), axis=1), 5) * math.pi / 180
    assert len(lines) == 1 and lines[0].startswith("inscal: warning: ") and "kept in the declared unit deg/s" in se
    assert f"gyros read at least {p5:.4g} rad/s" in se and "a MEMS gyro's bias reads so" in se, se
    rec = io.read_record(tmp_path / "o.h5")
    np.testing.assert_allclose(rec.dtheta.mean(axis=0) * RATE, np.radians(BIAS_DPS), atol=2e-4)
    with h5py.File(tmp_path / "o.h5", "r") as h:
        assert json.loads(h.attrs["source"])["warnings"] == [lines[0].removeprefix("inscal: warning: ")]
    # --json carries it too
    code, so, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "p.h5", *SITE, "--json")
    assert code == 0 and len(json.loads(so)["warnings"]) == 1 and f"{p5:.4g} rad/s" in json.loads(so)["warnings"][0]


def test_a_bias_of_1_deg_s_is_no_contradiction(tmp_path):
    """1 deg/s per axis (1.7 deg/s) is beyond what degrees read as radians would give at rest (0.08 .. 0.72
    deg/s): imported without a word."""
    rng = np.random.default_rng(2)
    w, f = still_rates(rng, np.array([1.0, -1.0, 1.0]))
    src, m = rates_csv(tmp_path, w, f)
    code, _, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE)
    assert code == 0 and se.strip() == "", se


def test_undeclared_rad_that_read_like_degrees_are_still_refused(tmp_path):
    """The same still IMU as increments in inscal's export layout (no mapping: rad and m/s assumed) whose
    gyro column holds degrees: refused in one line, nothing written."""
    rng = np.random.default_rng(3)
    w, f = still_rates(rng, np.array([0.0, 0.0, 0.0]))
    earth_dps = 15.04 / 3600 * np.array([0.0, math.cos(math.radians(30.5)), math.sin(math.radians(30.5))])
    dth_deg = (w * 0.01 + earth_dps) / RATE  # degrees per increment, written where radians belong
    t = np.arange(1, N + 1) / RATE
    src = tmp_path / "x.csv"
    src.write_text("\n".join([",".join(importers.EXPORT_HEADER)] + [",".join(f"{v:.12g}" for v in r) for r in
                                                                     np.column_stack([t, dth_deg, f / RATE])]) + "\n")
    code, _, se = invoke("import", src, "--format", "csv", "--out", tmp_path / "o.h5", *SITE)
    lines = se.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "the values look like degrees, not radians" in se, se
    assert not (tmp_path / "o.h5").exists()
    # declared, the same values are kept with a warning
    m = tmp_path / "m.toml"
    m.write_text('header_rows = 1\n[columns]\ntime = 0\ngx = 1\ngy = 2\ngz = 3\nax = 4\nay = 5\naz = 6\n'
                 '[units]\ngyro = "rad"\naccel = "m/s"\n')
    code, _, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE)
    assert code == 0 and "kept in the declared unit rad" in se, se


def test_a_declared_unit_no_gyro_at_rest_can_read_is_refused(tmp_path):
    """arcsec declared as rad/s: 15 rad/s at rest, beyond any bias (limit 10 deg/s): refused although declared."""
    rng = np.random.default_rng(4)
    w, f = still_rates(rng, np.array([0.0, 0.0, 0.0]))
    earth_as = 15.04 * np.array([0.0, math.cos(math.radians(30.5)), math.sin(math.radians(30.5))])  # arcsec/s
    src, m = rates_csv(tmp_path, earth_as + 0.02 * rng.normal(size=(N, 3)), f, gyro_unit="rad/s")
    code, _, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE)
    assert code == 2 and "look like arcsec, not radians beyond any gyro's bias at rest, whatever unit is declared" in se
    assert not (tmp_path / "o.h5").exists()


# ----------------------------------------------------------------------------- bags: REP 145 declares rad/s
TS2 = get_typestore(Stores.ROS2_HUMBLE)
EPOCH = 1_700_000_000_000_000_000


def imu_cdr(ns, w, f):
    T = TS2.types
    stamp = T["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))
    V = T["geometry_msgs/msg/Vector3"]
    msg = T["sensor_msgs/msg/Imu"](header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu"),
                                   orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                                   orientation_covariance=np.zeros(9), angular_velocity=V(x=w[0], y=w[1], z=w[2]),
                                   angular_velocity_covariance=np.zeros(9),
                                   linear_acceleration=V(x=f[0], y=f[1], z=f[2]),
                                   linear_acceleration_covariance=np.zeros(9))
    return TS2.serialize_cdr(msg, "sensor_msgs/msg/Imu")


def write_mcap_bag(folder, w_rad, f):
    with Writer2(folder, version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        c = wr.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=TS2)
        for k in range(w_rad.shape[0]):
            ns = EPOCH + k * 10_000_000
            wr.write(c, ns, imu_cdr(ns, w_rad[k], f[k]))
    return folder


def test_a_plain_mcap_file_imports_as_its_bag_folder_does_and_a_mems_bias_is_a_warning(tmp_path):
    """The .mcap file of a ROS 2 bag, given alone (no metadata.yaml beside it), imports to the same record as
    its folder; a consumer gyro's bias in rad/s (the unit sensor_msgs/Imu declares) is a warning."""
    rng = np.random.default_rng(5)
    w, f = still_rates(rng)
    folder = write_mcap_bag(tmp_path / "bag", np.radians(w), f)
    code, so, se = invoke("import", folder, "--format", "rosbag", "--out", tmp_path / "a.h5", *SITE, "--json")
    assert code == 0 and "kept in the declared unit rad/s" in se, se
    lone = tmp_path / "lone.mcap"
    lone.write_bytes(next(folder.glob("*.mcap")).read_bytes())
    code, so2, se2 = invoke("import", lone, "--format", "rosbag", "--out", tmp_path / "b.h5", *SITE, "--json")
    assert code == 0, se2
    assert json.loads(so2)["bag"]["storage"] == "mcap" and json.loads(so2)["bag"]["messages"] == N
    a, b = io.read_record(tmp_path / "a.h5"), io.read_record(tmp_path / "b.h5")
    for key in ("time", "dtheta", "dvel"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key


@pytest.mark.parametrize("name, needle", [("x.db3", "a ROS 1 bag ends in .bag, a plain MCAP file in .mcap"),
                                          ("x.mcap", "a damaged or truncated bag")])
def test_other_files_are_refused_in_one_line(tmp_path, name, needle):
    p = tmp_path / name
    p.write_bytes(b"not a bag at all" * 10)
    code, _, se = invoke("import", p, "--format", "rosbag", "--out", tmp_path / "o.h5", *SITE)
    assert code == 2 and len(se.strip().splitlines()) == 1 and needle in se, se
    assert not (tmp_path / "o.h5").exists()


def test_encoder_file_in_unix_time_beside_a_bag_gets_the_bag_clock_hint(tmp_path):
    """A bag's record counts from its first stamp; an encoder file in Unix time misses it by 1.7e9 s: refused
    in one line that says so and gives the shift."""
    rng = np.random.default_rng(6)
    w, f = still_rates(rng)
    folder = write_mcap_bag(tmp_path / "bag", np.radians(w), f)
    tg = EPOCH * 1e-9 + np.arange(-5, N + 5) / RATE
    gim = tmp_path / "enc.csv"
    np.savetxt(gim, np.column_stack([tg, np.zeros((tg.size, 2))]), delimiter=",", fmt="%.17g",
               header="time [s],outer [deg],inner [deg]", comments="")
    code, _, se = invoke("import", folder, "--format", "rosbag", "--gimbal", gim, "--out", tmp_path / "o.h5", *SITE)
    assert code == 2 and len(se.strip().splitlines()) == 1, se
    assert "they look like Unix times in seconds, while a bag's time counts from its first stamp" in se, se
    assert "(1700000000.000000000 s, Unix): subtract it" in se and not (tmp_path / "o.h5").exists()
