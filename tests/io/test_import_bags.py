"""ROS 1 / ROS 2 (SQLite3, MCAP) bags written with the ``rosbags`` library's own writers and imported
back; rates sampled at jittered stamps (bags, csv) integrated within the stated rule's error; the same
calibration through a bag and through the HDF5 record; KF-GINS text and its imunoise block; raw-counts
words; and damaged inputs refused with one line, exit 2, nothing written."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from inscal import io
from inscal.calibrate import calibrate
from inscal.calibrate.result import param_value
from inscal.cli.app import app
from inscal.core.earth import Site
from inscal.core.error_model import ImuNoise
from inscal.io.formats.rosbag import decode_imu
from inscal.core.units import DEG, HOUR
from inscal.sim import scenarios
from inscal.sim.simulate import write_simulation

runner = CliRunner()
SITE = ["--lat", "30.5", "--lon", "114.0", "--height", "20.0"]
EPOCH = 1_700_000_000_123_456_789  # ns: a Unix time, as a robot's clock gives
TS1, TS2 = get_typestore(Stores.ROS1_NOETIC), get_typestore(Stores.ROS2_HUMBLE)
KINDS = ("ros1", "sqlite3", "mcap")


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def imu_msg(ts, ns: int, w, f, seq: int = 0, no_gyro: bool = False):
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    H = T["std_msgs/msg/Header"]
    header = H(seq=seq, stamp=stamp, frame_id="imu") if "seq" in H.__dataclass_fields__ else H(stamp=stamp, frame_id="imu")
    V = T["geometry_msgs/msg/Vector3"]
    return T["sensor_msgs/msg/Imu"](header=header, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                                    orientation_covariance=np.zeros(9), angular_velocity=V(x=w[0], y=w[1], z=w[2]),
                                    angular_velocity_covariance=np.r_[-1.0, np.zeros(8)] if no_gyro else np.zeros(9),
                                    linear_acceleration=V(x=f[0], y=f[1], z=f[2]),
                                    linear_acceleration_covariance=np.zeros(9))


def write_bag(path: Path, kind: str, stamps_ns, w, f, receive_ns=None, topic="/imu/data", extra=(), no_gyro=False):
    """A bag of ``sensor_msgs/Imu`` messages (header stamps ``stamps_ns``, received at ``receive_ns``)
    written with the library's writer for ``kind``; ``extra``: (topic, msgtype, [messages]) more."""
    receive_ns = stamps_ns if receive_ns is None else receive_ns
    ros1 = kind == "ros1"
    ts = TS1 if ros1 else TS2
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    w_ = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap"
                                            else StoragePlugin.SQLITE3)
    with w_ as wr:
        conns = []
        if topic is not None:
            c = wr.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts)
            for k, (ns, rns) in enumerate(zip(stamps_ns, receive_ns)):
                wr.write(c, int(rns), ser(imu_msg(ts, int(ns), w[k], f[k], k, no_gyro), "sensor_msgs/msg/Imu"))
        for t, typ, msgs in extra:
            conns.append(wr.add_connection(t, typ, typestore=ts))
            for k, m in enumerate(msgs):
                wr.write(conns[-1], EPOCH + k, ser(m, typ))
    return path


# ----------------------------------------------------------------------------- a smooth analytic motion
A_W, F_W, P_W = np.array([0.6, -0.4, 0.9]), np.array([1.3, 0.7, 2.1]), np.array([0.2, 1.1, -0.5])
A_F, F_F, P_F = np.array([0.8, 0.5, 0.3]), np.array([0.9, 1.7, 0.4]), np.array([0.3, -0.8, 1.2])
G_UP = np.array([0.0, 0.0, 9.79])


def rates(t):
    t = np.asarray(t)[:, None]
    return A_W * np.sin(2 * np.pi * F_W * t + P_W), G_UP + A_F * np.cos(2 * np.pi * F_F * t + P_F)


def exact_increments(a, b):
    """The closed-form integrals of :func:`rates` over [a, b]."""
    a, b = np.asarray(a)[:, None], np.asarray(b)[:, None]
    om_w, om_f = 2 * np.pi * F_W, 2 * np.pi * F_F
    dth = -A_W / om_w * (np.cos(om_w * b + P_W) - np.cos(om_w * a + P_W))
    dv = G_UP * (b - a) + A_F / om_f * (np.sin(om_f * b + P_F) - np.sin(om_f * a + P_F))
    return dth, dv


def max_second_derivative():
    return np.abs(np.concatenate([A_W * (2 * np.pi * F_W) ** 2, A_F * (2 * np.pi * F_F) ** 2]))


RATE, N = 100.0, 600  # 6 s at 100 Hz
H_NS = 10_000_000


@pytest.fixture(scope="module")
def smooth(tmp_path_factory):
    """The HDF5 record of the analytic motion (exact increments on the grid) and its bags (point rates at
    the stamps), of each storage kind."""
    d = tmp_path_factory.mktemp("bags")
    k = np.arange(N + 1)
    t = k / RATE
    w, f = rates(t)
    dth, dv = exact_increments(t[:-1], t[1:])
    rec = io.Record(t[1:], dth, dv, None, RATE, Site(30.5 * DEG, 114.0 * DEG, 20.0), None, None, "", "analytic")
    io.write_record(d / "ref.h5", rec)
    bags = {kind: write_bag(d / ("a.bag" if kind == "ros1" else f"b_{kind}"), kind, EPOCH + k * H_NS, w, f)
            for kind in KINDS}
    return d, io.read_record(d / "ref.h5"), bags


@pytest.mark.parametrize("kind", KINDS)
def test_fixed_offset_decoder_equals_the_librarys(smooth, kind):
    """The reader's fixed-offset decoding of sensor_msgs/Imu equals rosbags' deserializer, message for
    message (frame ids of several lengths: the CDR padding), and declines other layouts."""
    w, f = rates(np.arange(12) / RATE)
    ts = TS1 if kind == "ros1" else TS2
    ser = ts.serialize_ros1 if kind == "ros1" else ts.serialize_cdr
    seen = 0
    for frame in ("", "i", "imu", "imu_link", "base_imu_link_0"):
        m = imu_msg(ts, EPOCH + 123, w[1], f[1], 7)
        m.header.frame_id = frame
        m.angular_velocity_covariance[0] = -1.0
        raw = bytes(ser(m, "sensor_msgs/msg/Imu"))
        got = decode_imu(raw, kind == "ros1")
        assert got == ((EPOCH + 123) // 10**9, (EPOCH + 123) % 10**9, tuple(w[1]), -1.0, tuple(f[1]), 0.0)
        seen += 1
    assert decode_imu(raw[:-8], kind == "ros1") is None and decode_imu(raw + b"\0" * 8, kind == "ros1") is None
    with AnyReader([smooth[2][kind]]) as r:
        for conn, _, raw in r.messages():
            msg = r.deserialize(raw, conn.msgtype)
            v = decode_imu(raw, kind == "ros1")
            assert v == (msg.header.stamp.sec, msg.header.stamp.nanosec, (msg.angular_velocity.x,
                         msg.angular_velocity.y, msg.angular_velocity.z), msg.angular_velocity_covariance[0],
                         (msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z),
                         msg.linear_acceleration_covariance[0])
            seen += 1
    assert seen == 5 + N + 1


@pytest.mark.parametrize("kind", KINDS)
def test_bag_increments_within_the_rules_bound(smooth, kind):
    """Point rates at stamps on a 100 Hz grid: one increment per message, over the interval centred on its
    stamp (the midpoint rule), within the rule's bound D^3 / 24 max|x''|, which is tight; the noise is
    reported white."""
    d, ref, bags = smooth
    out = d / f"{kind}.h5"
    code, so, se = invoke("import", bags[kind], "--format", "rosbag", "--out", out, *SITE, "--json")
    assert code == 0, se
    res = json.loads(so)
    assert res["bag"] == {"topic": "/imu/data", "storage": kind, "stamps": "header", "epoch_ns": EPOCH,
                          "messages": N + 1}
    ig = res["integration"]
    assert ig["stamps_on_grid"] and ig["grid_rate_hz"] == RATE and ig["noise"]["white"]
    rec = io.read_record(out)
    h = 1.0 / RATE
    assert rec.n_samples == N + 1 and rec.rate_hz == RATE
    # stamp k at the centre of interval k
    np.testing.assert_allclose(rec.time, np.arange(N + 1) * h + h / 2, rtol=0, atol=1e-12)
    bound = h ** 3 / 24 * max_second_derivative()
    reported = np.array(ig["error_bound"]["dtheta_rad"] + ig["error_bound"]["dvel_m_s"])
    assert np.all(reported >= bound) and np.all(reported <= 1.5 * bound), reported / bound
    dth, dv = exact_increments(rec.time - h, rec.time)
    err = np.abs(np.column_stack([rec.dtheta - dth, rec.dvel - dv])).max(axis=0)
    assert np.all(err <= bound * (1 + 1e-9)), (err, bound)
    assert np.all(err >= 0.5 * bound)  # and the bound is tight: the rule is second order, not better


def test_jittered_stamps_and_receive_times(smooth, tmp_path):
    """Header stamps jittered by +-20 % of the step (a driver's clock) and received 1-3 ms later: the
    rule's reported bound covers its error on the 100 Hz grid and the noise is reported not white (the
    closed form's extremes); --stamps receive uses the receive times (their own jitter) instead."""
    rng = np.random.default_rng(3)
    k = np.arange(N + 1)
    ns = EPOCH + k * H_NS + rng.integers(-2_000_000, 2_000_001, N + 1)
    ns[0] = EPOCH
    recv = ns + rng.integers(1_000_000, 3_000_001, N + 1)
    t = (ns - EPOCH) * 1e-9
    w, f = rates(t)
    bag = write_bag(tmp_path / "jit", "mcap", ns, w, f, receive_ns=recv)
    code, so, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "j.h5", *SITE, "--rate-hz", RATE,
                          "--json")
    assert code == 0, se
    ig = json.loads(so)["integration"]
    assert not ig["stamps_on_grid"] and not ig["noise"]["white"]
    assert 0.5 < ig["noise"]["variance_ratio"][0] < 0.9 < ig["noise"]["variance_ratio"][1] < 1.1
    assert 0.05 < ig["noise"]["neighbour_correlation"] < 0.5
    rec = io.read_record(tmp_path / "j.h5")
    dth, dv = exact_increments(rec.time - 1 / RATE, rec.time)
    assert ig["largest_step_s"] == pytest.approx(np.diff(t).max(), rel=1e-12)
    err = np.abs(np.column_stack([rec.dtheta - dth, rec.dvel - dv])).max(axis=0)
    reported = np.array(ig["error_bound"]["dtheta_rad"] + ig["error_bound"]["dvel_m_s"])
    assert np.all(err <= reported) and np.all(err > 0.05 * reported), (err, reported)
    # receive times: another time base (shifted by the latency, jittered by it)
    code, so, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "r.h5", *SITE, "--rate-hz", RATE,
                          "--stamps", "receive", "--json")
    assert code == 0, se
    res = json.loads(so)
    assert res["bag"]["stamps"] == "receive" and res["bag"]["epoch_ns"] == int(recv[0])
    other = io.read_record(tmp_path / "r.h5")
    m = min(other.n_samples, rec.n_samples)
    assert not np.allclose(other.dvel[:m], rec.dvel[:m], rtol=1e-6, atol=0)


def test_sampled_rates_csv_with_jittered_stamps(tmp_path):
    """A csv of rates (deg/s, g) with a stamp per sample at a jittered rate: ``kind = "sampled-rates"``."""
    rng = np.random.default_rng(5)
    t = np.arange(N + 1) / RATE + np.concatenate([[0.0], rng.uniform(-2e-3, 2e-3, N)])
    w, f = rates(t)
    src = tmp_path / "r.csv"
    np.savetxt(src, np.column_stack([t, np.degrees(w), f / 9.80665]), delimiter=",", fmt="%.17g",
               header="t,wx,wy,wz,fx,fy,fz", comments="")
    m = tmp_path / "m.toml"
    m.write_text('kind = "sampled-rates"\nheader_rows = 1\n[columns]\ntime = "t"\ngx = "wx"\ngy = "wy"\ngz = "wz"\n'
                 'ax = "fx"\nay = "fy"\naz = "fz"\n[units]\ngyro = "deg/s"\naccel = "g"\n')
    code, so, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE,
                          "--rate-hz", RATE, "--json")
    assert code == 0, se
    rec = io.read_record(tmp_path / "o.h5")
    assert rec.rate_hz == RATE
    dth, dv = exact_increments(rec.time - 1 / rec.rate_hz, rec.time)
    ig = json.loads(so)["integration"]
    bound = np.array(ig["error_bound"]["dtheta_rad"] + ig["error_bound"]["dvel_m_s"])
    err = np.abs(np.column_stack([rec.dtheta - dth, rec.dvel - dv])).max(axis=0)
    assert np.all(err <= bound) and np.all(err > 0.05 * bound), (err, bound)


# ----------------------------------------------------------------------------- the same calibration
def test_same_calibration_through_a_bag_and_the_hdf5_record(tmp_path):
    """A noise-free N25 turntable record at 10 Hz (static positions and CW/CCW rate tests): its rates
    (the increments over dt, as an averaging driver publishes them, stamped at the centre of their
    interval, the instant they represent: REP 145) in an MCAP bag.  Imported back, the increments are the
    record's (one sample per increment), and the six-position calibration equals the HDF5 record's to
    1e-9 relative.  (A calibration that weights its windows by their measured noise, as ``joint`` does,
    weights a noise-free record by round-off, and so differs.)"""
    sc = replace(scenarios.build("n25", rate_hz=10.0), noise=ImuNoise())
    f = tmp_path / "n25.h5"
    write_simulation(f, sc, None)
    rec = io.read_record(f)
    dt = 1.0 / rec.rate_hz
    n = rec.n_samples
    ns = EPOCH + np.arange(n) * 100_000_000  # the centres of the intervals, t_k - dt / 2
    w, a = rec.dtheta / dt, rec.dvel / dt
    bag = write_bag(tmp_path / "n25bag", "mcap", ns, w, a)
    path_toml = tmp_path / "path.toml"
    assert invoke("export", f, "--format", "psins", "--out", tmp_path / "x.bin", "--path-out", path_toml)[0] == 0
    s = rec.site
    site = ["--lat", math.degrees(s.latitude), "--lon", math.degrees(s.longitude), "--height", s.height]
    code, _, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "b.h5", *site, "--path", path_toml)
    assert code == 0, se
    got = io.read_record(tmp_path / "b.h5")
    assert got.n_samples == n
    np.testing.assert_allclose(got.time, rec.time, rtol=1e-15, atol=0)
    np.testing.assert_allclose(got.dtheta, rec.dtheta, rtol=1e-15, atol=0)
    a_res = calibrate(replace(rec, gimbal=None), "six-position")
    b_res = calibrate(got, "six-position")
    assert a_res.estimated == b_res.estimated
    for name in a_res.estimated:
        x, y = param_value(a_res.imu, a_res.gimbal, name), param_value(b_res.imu, b_res.gimbal, name)
        scale = float(np.abs(x).max())
        assert scale > 0 and np.all(np.abs(y - x) <= 1e-9 * scale), (name, x, y)


# ----------------------------------------------------------------------------- KF-GINS, counts
def test_kfgins_text_and_imunoise(tmp_path):
    sc = replace(scenarios.build("n25-static", duration_s=20.0), noise=ImuNoise())
    f = tmp_path / "s.h5"
    write_simulation(f, sc, None)
    rec = io.read_record(f)
    assert invoke("export", f, "--format", "kf-gins", "--out", tmp_path / "imu.txt")[0] == 0
    first = (tmp_path / "imu.txt").read_text().splitlines()[0].split()
    assert len(first) == 7 and float(first[0]) == rec.time[0]
    cfg = tmp_path / "kf-gins.yaml"
    cfg.write_text("imudatarate: 100\nimunoise:\n  arw: [0.003, 0.003, 0.004]  # [deg/sqrt(hr)]\n"
                   "  vrw: [0.03, 0.03, 0.03]\n  gbstd: [0.027, 0.027, 0.027]\n  abstd: [15.0, 15.0, 15.0]\n"
                   "  gsstd: [300.0, 300.0, 300.0]\n  asstd: [300.0, 300.0, 300.0]\n  corrtime: 4.0\n")
    s = rec.site
    site = ["--lat", math.degrees(s.latitude), "--lon", math.degrees(s.longitude), "--height", s.height]
    code, so, se = invoke("import", tmp_path / "imu.txt", "--format", "kf-gins", "--out", tmp_path / "k.h5", *site,
                          "--config", cfg, "--json")
    assert code == 0, se
    back = io.read_record(tmp_path / "k.h5")
    for key in ("time", "dtheta", "dvel"):
        assert np.array_equal(getattr(back, key), getattr(rec, key)), key
    noise = json.loads(so)["imunoise"]
    np.testing.assert_allclose(noise["arw_rad_sqrt_s"][2], 0.004 * DEG / 60.0, rtol=1e-14)  # deg/sqrt(h)
    np.testing.assert_allclose(noise["vrw_m_s_sqrt_s"][0], 0.03 / 60.0, rtol=1e-14)  # m/s/sqrt(h)
    np.testing.assert_allclose(noise["gyro_bias_sigma_rad_s"][0], 0.027 * DEG / HOUR, rtol=1e-14)
    np.testing.assert_allclose(noise["accel_bias_sigma_m_s2"][0], 15e-5, rtol=1e-14)  # mGal
    assert noise["gyro_scale_sigma"][0] == pytest.approx(300e-6) and noise["correlation_time_s"] == 4 * 3600.0


def counts_case(tmp_path, words, bits=16):
    """A csv of increments as ``bits``-bit two's complement words (unsigned), with an offset."""
    t = np.arange(1, words.shape[0] + 1) / 100.0
    src = tmp_path / "c.csv"
    np.savetxt(src, np.column_stack([t, words]), delimiter=",", fmt="%.17g")
    m = tmp_path / "c.toml"
    m.write_text(f'[columns]\ntime = 0\ngx = 1\ngy = 2\ngz = 3\nax = 4\nay = 5\naz = 6\n[units]\n'
                 f'gyro = "counts"\ngyro_scale = "0.01 arcsec"\ngyro_bits = {bits}\ngyro_twos_complement = true\n'
                 f'accel = "counts"\naccel_scale = 1e-6\naccel_bits = {bits}\naccel_twos_complement = true\n'
                 f'accel_offset = 3\n')
    return src, m


def test_raw_counts_words(tmp_path):
    rng = np.random.default_rng(2)
    n = 400
    true_g = np.round(rng.normal(0, 30, (n, 3)))  # counts, signed
    true_a = np.round(rng.normal([0, 0, 9800], 20, (n, 3)))
    words = np.column_stack([np.where(true_g < 0, true_g + 65536, true_g),
                             np.where(true_a + 3 < 0, true_a + 3 + 65536, true_a + 3)])
    src, m = counts_case(tmp_path, words)
    code, _, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE,
                         "--skip-check", "magnitudes")
    assert code == 0, se
    rec = io.read_record(tmp_path / "o.h5")
    np.testing.assert_allclose(rec.dtheta, true_g * 0.01 * DEG / 3600, rtol=1e-15, atol=0)
    np.testing.assert_allclose(rec.dvel, true_a * 1e-6, rtol=1e-15, atol=0)


# ----------------------------------------------------------------------------- damaged inputs
def _string_bag(path):
    S = TS1.types["std_msgs/msg/String"]
    return write_bag(path, "ros1", [], None, None, topic=None,
                     extra=[("/chatter", "std_msgs/msg/String", [S(data="hi"), S(data="there")])])


def _gap_bag(path):
    k = np.delete(np.arange(40), [20, 21, 22])
    return write_bag(path, "sqlite3", EPOCH + k * H_NS, *rates(k / RATE))


def _backwards_bag(path):
    """Received in order; the header stamps of messages 11 and 12 swapped (a driver's clock stepped)."""
    recv = EPOCH + np.arange(40) * H_NS
    ns = recv.copy()
    ns[[10, 11]] = ns[[11, 10]]
    return write_bag(path, "ros1", ns, *rates(np.arange(40) / RATE), receive_ns=recv)


def _duplicate_bag(path):
    recv = EPOCH + np.arange(40) * H_NS
    ns = recv.copy()
    ns[15] = ns[14]
    return write_bag(path, "mcap", ns, *rates(np.arange(40) / RATE), receive_ns=recv)


def _truncated(kind):
    def make(path):
        bag = write_bag(path, kind, EPOCH + np.arange(400) * H_NS, *rates(np.arange(400) / RATE))
        f = bag if kind == "ros1" else next(bag.glob("*.mcap"))
        f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
        return bag
    return make


def _no_gyro_bag(path):
    return write_bag(path, "sqlite3", EPOCH + np.arange(40) * H_NS, *rates(np.arange(40) / RATE), no_gyro=True)


@pytest.mark.parametrize("make, name, needle", [
    (_string_bag, "s.bag", "no sensor_msgs/Imu topic; its topics: /chatter (std_msgs/msg/String, 2 messages)"),
    (_truncated("ros1"), "t.bag", "a damaged or truncated bag"),
    (_truncated("mcap"), "tm", "a damaged or truncated bag"),
    (_backwards_bag, "b.bag", "stamps go backwards at message 12"),
    (_duplicate_bag, "dup", "duplicated stamp at message 16"),
    (_gap_bag, "gap", "3 message(s) dropped before message 21"),
    (_no_gyro_bag, "nog", "40 of 40 messages say they carry no angular_velocity"),
])
def test_damaged_bags_are_one_line_exit_2_nothing_written(tmp_path, make, name, needle):
    bag = make(tmp_path / name)
    before = set(tmp_path.rglob("*"))
    code, so, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "o.h5", *SITE)
    lines = se.strip().splitlines()
    assert code == 2 and len(lines) == 1 and needle in lines[0], se
    assert set(tmp_path.rglob("*")) == before


def test_counts_beyond_their_bit_width_are_refused(tmp_path):
    words = np.tile([10, 20, 30, 40, 50, 9800], (50, 1)).astype(float)
    words[17, 4] = 70000  # beyond 16 bits
    src, m = counts_case(tmp_path, words)
    before = set(tmp_path.iterdir())
    code, _, se = invoke("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "o.h5", *SITE)
    lines = se.strip().splitlines()
    assert code == 2 and len(lines) == 1, se
    assert "ay (column 5) is 70000 at line 18: beyond its bit width (16-bit two's complement words 0 .. 65535" in se
    assert set(tmp_path.iterdir()) == before


def test_temperature_topic(tmp_path):
    """A sensor_msgs/Temperature topic at 2 Hz beside the IMU's: the record's temperature, its readings at
    their stamps on the IMU's clock; a topic of another type is refused with the topics listed."""
    k = np.arange(N + 1)
    Temp, H, Time = (TS2.types[n] for n in ("sensor_msgs/msg/Temperature", "std_msgs/msg/Header",
                                            "builtin_interfaces/msg/Time"))
    tk = EPOCH + 3_000_000 + np.arange(12) * 500_000_000  # 2 Hz, 3 ms after the first IMU stamp
    readings = 20.0 + 0.25 * np.arange(12)
    msgs = [Temp(header=H(stamp=Time(sec=int(ns // 10**9), nanosec=int(ns % 10**9)), frame_id="imu"),
                 temperature=float(v), variance=0.0) for ns, v in zip(tk, readings)]
    bag = write_bag(tmp_path / "tb", "sqlite3", EPOCH + k * H_NS, *rates(k / RATE),
                    extra=[("/imu/temperature", "sensor_msgs/msg/Temperature", msgs)])
    code, so, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "t.h5", *SITE,
                          "--temperature-topic", "/imu/temperature", "--json")
    assert code == 0, se
    rec = io.read_record(tmp_path / "t.h5")
    assert rec.temperature.sensors == ("imu/temperature",)
    np.testing.assert_allclose(rec.temperature.time, (tk - EPOCH) * 1e-9, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(rec.temperature.values[:, 0], readings)
    assert json.loads(so)["bag"]["temperature_topic"] == "/imu/temperature"
    code, _, se = invoke("import", bag, "--format", "rosbag", "--out", tmp_path / "u.h5", *SITE,
                         "--temperature-topic", "/imu/data")
    assert code == 2 and "temperature topic '/imu/data' holds sensor_msgs/msg/Imu, not sensor_msgs/msg/Temperature" in se
    assert not (tmp_path / "u.h5").exists()


def test_topic_choice(smooth, tmp_path):
    d, _, bags = smooth
    code, _, se = invoke("import", bags["ros1"], "--format", "rosbag", "--topic", "/nope", "--out", tmp_path / "o.h5",
                         *SITE)
    assert code == 2 and "no topic '/nope'; its topics: /imu/data (sensor_msgs/msg/Imu, 601 messages)" in se
    code, _, se = invoke("import", bags["ros1"], "--format", "csv", "--topic", "/imu/data", "--out", tmp_path / "o.h5",
                         *SITE)
    assert code == 2 and "--topic, --stamps and --temperature-topic apply to --format rosbag" in se
