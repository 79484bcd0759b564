"""ROS bags: ROS 1 ``.bag`` files, ROS 2 bags (a folder with ``metadata.yaml`` and SQLite3 ``.db3`` or
MCAP ``.mcap`` storage) and plain ``.mcap`` files (an MCAP recording without its folder, as ``ros2 bag
record -s mcap`` and Foxglove write them; the channels' schemas name the message types) holding
``sensor_msgs/Imu`` messages, read with the pure-Python ``rosbags`` library (no ROS installation).

A ``sensor_msgs/Imu`` message (REP 145) gives ``angular_velocity`` [rad/s] and
``linear_acceleration`` [m/s^2, the specific force: +g up at rest] in the frame ``header.frame_id``
at the instant ``header.stamp``; the orientation is not read, and a message whose covariance says a
field is absent (its first element -1) is refused rather than read as zeros.  The channels
are taken axis for axis as the IMU's axes (ROS's body convention is x forward, y left, z up, REP 103).
The time of each sample is its header stamp, or with ``stamps="receive"`` the time the bag recorded
it (the receive time, which carries the transport's latency and jitter).  Stamps are read as
integer nanoseconds and made relative to the first one (a Unix time as a double keeps only 0.2 us);
the epoch is returned with the samples.

The rates are integrated onto a uniform grid by the second-order rule of
:mod:`inscal.io.formats.rates`, after :func:`~inscal.io.formats.rates.check_stamps` has refused a
duplicated stamp, a stamp going backwards and dropped messages.

The topic: the one ``sensor_msgs/Imu`` topic of the bag, or the one named; a bag without one, or
with several and none named, is refused with the list of its topics and their types.  A
``sensor_msgs/Temperature`` topic (``temperature`` [degC]) can give the record's temperature, its
readings at their own stamps on the IMU samples' clock (:func:`read_bag_temperature`).
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from inscal.io.files import file_hash
from inscal.io.formats.base import Raw, RawTemperature, ReadOptions
from inscal.io.formats.rates import check_stamps, integrate_rates
from inscal.io.mapping import ImportFileError

IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
STAMPS = ("header", "receive")


@dataclass(frozen=True)
class BagSamples:
    """The IMU messages of one topic: ``time`` (N,) [s from ``epoch_ns``], ``gyro`` [rad/s] and ``accel``
    [m/s^2] (N, 3), the ``topic``, the ``storage`` (``ros1``, ``sqlite3``, ``mcap``) and which
    ``stamps`` gave the time."""

    time: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    epoch_ns: int
    topic: str
    storage: str
    stamps: str


def _storage(p: Path) -> str:
    if p.is_file():
        return "ros1" if p.suffix == ".bag" else "mcap"
    files = [f.suffix for f in p.iterdir()] if p.is_dir() else []
    return "mcap" if ".mcap" in files else "sqlite3"


def _reader(p: Path):
    from rosbags.highlevel import AnyReader

    if not p.exists():
        raise ImportFileError(f"{p}: no such file or folder")
    if p.is_file() and p.suffix not in (".bag", ".mcap"):
        raise ImportFileError(f"{p}: a ROS 1 bag ends in .bag, a plain MCAP file in .mcap; a ROS 2 bag is the folder "
                              f"holding metadata.yaml (give {p.parent})")
    if p.is_dir() and not (p / "metadata.yaml").is_file():
        raise ImportFileError(f"{p}: a ROS 2 bag folder holds metadata.yaml, and this one has none")
    return AnyReader([p])


def _damaged(p: Path, exc: Exception) -> ImportFileError:
    msg = " ".join(str(a) for a in exc.args) or type(exc).__name__
    return ImportFileError(f"{p}: a damaged or truncated bag ({msg.splitlines()[0] if msg else type(exc).__name__})")


def _describe(topics: dict) -> str:
    return ", ".join(f"{t} ({typ}, {n} messages)" for t, (typ, n) in sorted(topics.items())) or "none"


#: a serialized sensor_msgs/Imu ends with 37 float64: orientation (4) and its covariance (9),
#: angular_velocity (3) and its covariance (9), linear_acceleration (3) and its covariance (9)
_DOUBLES = struct.Struct("<37d")
_CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation header of little-endian CDR (ROS 2)


def decode_imu(raw, ros1: bool):
    """``(sec, nanosec, angular_velocity, its covariance[0], linear_acceleration, its covariance[0])`` of a
    serialized ``sensor_msgs/Imu`` read at its fixed offsets, or None when the bytes do not have that
    layout (then the library's deserializer reads it).  ROS 1: ``seq`` u32, ``stamp`` u32 u32,
    ``frame_id`` (u32 length and bytes), the 37 doubles, little endian, unaligned.  ROS 2 (CDR): the
    4-byte encapsulation header, ``stamp`` i32 u32, ``frame_id`` (u32 length with its NUL, bytes), padding
    to 8 bytes from the end of the header, the 37 doubles.  About 1.6 us of CPU a message, against 12 us
    for the library's deserializer."""
    raw = bytes(raw)
    if ros1:
        if len(raw) < 16:
            return None
        _seq, sec, nsec, n = struct.unpack_from("<4I", raw, 0)
        start = 16 + n
    else:
        if len(raw) < 16 or raw[:4] != _CDR_LE:
            return None
        sec, nsec, n = struct.unpack_from("<iII", raw, 4)
        start = 4 + 12 + n + (-(12 + n)) % 8
    if len(raw) != start + _DOUBLES.size:
        return None
    d = _DOUBLES.unpack_from(raw, start)
    return sec, nsec, d[13:16], d[16], d[25:28], d[28]


def read_bag_samples(path, topic: str | None = None, stamps: str = "header") -> BagSamples:
    """The ``sensor_msgs/Imu`` messages of ``topic`` (see the module docstring), in the bag's order."""
    p = Path(path)
    if stamps not in STAMPS:
        raise ImportFileError(f"--stamps must be one of {', '.join(STAMPS)}, got {stamps!r}")
    try:
        with _reader(p) as r:
            topics = {name: (info.msgtype or "?", int(info.msgcount)) for name, info in r.topics.items()}
            imu = [t for t, (typ, _) in topics.items() if typ == IMU_TYPE]
            if topic is None:
                if len(imu) != 1:
                    why = "no sensor_msgs/Imu topic" if not imu else f"{len(imu)} sensor_msgs/Imu topics (give --topic)"
                    raise ImportFileError(f"{p}: {why}; its topics: {_describe(topics)}")
                topic = imu[0]
            elif topic not in topics:
                raise ImportFileError(f"{p}: no topic {topic!r}; its topics: {_describe(topics)}")
            elif topics[topic][0] != IMU_TYPE:
                raise ImportFileError(f"{p}: topic {topic!r} holds {topics[topic][0]}, not {IMU_TYPE}; its topics: "
                                      f"{_describe(topics)}")
            if topics[topic][1] > MAX_BAG_MESSAGES:
                raise ImportFileError(f"{p}: topic {topic} holds {topics[topic][1]} messages, more than the "
                                      f"{MAX_BAG_MESSAGES} one import reads (a 1 kHz IMU for 5.5 h; about 250 bytes "
                                      "each in memory): split the bag by time and import each part")
            conns = [c for c in r.connections if c.topic == topic]
            ros1 = _storage(p) == "ros1"
            ns, g, a, absent = [], [], [], [0, 0]
            for conn, recv, raw in r.messages(connections=conns):
                v = decode_imu(raw, ros1)
                if v is None:  # another layout: the library's deserializer
                    msg = r.deserialize(raw, conn.msgtype)
                    w, f, hs = msg.angular_velocity, msg.linear_acceleration, msg.header.stamp
                    v = (hs.sec, hs.nanosec, (w.x, w.y, w.z), msg.angular_velocity_covariance[0], (f.x, f.y, f.z),
                         msg.linear_acceleration_covariance[0])
                ns.append(recv if stamps == "receive" else v[0] * 1_000_000_000 + v[1])
                g.append(v[2])
                a.append(v[4])
                # REP 145: a covariance whose first element is -1 says the field is not provided
                absent[0] += v[3] == -1
                absent[1] += v[5] == -1
    except ImportFileError:
        raise
    except Exception as exc:  # the library's ReaderError, struct / sqlite / yaml errors of a damaged file
        raise _damaged(p, exc) from None
    if len(ns) < 3:
        raise ImportFileError(f"{p}: topic {topic} has {len(ns)} message(s); at least 3 are needed")
    for k, name in enumerate(("angular_velocity", "linear_acceleration")):
        if absent[k]:
            raise ImportFileError(f"{p}: topic {topic}: {absent[k]} of {len(ns)} messages say they carry no {name} "
                                  f"({name}_covariance[0] = -1, REP 145)")
    ns = np.asarray(ns, dtype=np.int64)
    epoch = int(ns[0])
    t = (ns - epoch).astype(float) * 1e-9
    return BagSamples(t, np.asarray(g, dtype=float), np.asarray(a, dtype=float), epoch, topic, _storage(p), stamps)


def read_bag(path, topic: str | None = None, stamps: str = "header",
             rate_hz: float | None = None) -> tuple[Raw, BagSamples]:
    """A bag's IMU topic as a :class:`~inscal.io.formats.base.Raw` block of increments on a uniform grid
    (time from the first stamp; ``raw.integration`` holds the grid and the rule's bound), with the
    samples as read."""
    s = read_bag_samples(path, topic, stamps)
    where = f"{path} topic {s.topic}"
    bad = ~(np.all(np.isfinite(s.gyro), axis=1) & np.all(np.isfinite(s.accel), axis=1))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ImportFileError(f"{where}: message {i + 1} (t = {s.time[i]:.9f} s) has a NaN or infinite rate")
    check_stamps(s.time, where, "message", remedy="the rosbag import bridges no gap (it takes no mapping): "
                 "record the bag again, or with --stamps receive if only the header stamps jump")
    integ = integrate_rates(s.time, s.gyro, s.accel, rate_hz)
    labels = tuple(f"{n} (angular_velocity.{c})" for n, c in zip(("dthx", "dthy", "dthz"), "xyz")) + tuple(
        f"{n} (linear_acceleration.{c})" for n, c in zip(("dvx", "dvy", "dvz"), "xyz"))
    raw = Raw(integ.time, integ.gyro, integ.accel, "increments", None, labels, None, "",
              np.column_stack([integ.gyro, integ.accel]),
              time_fix="the bag's stamps are nanoseconds; check --stamps header|receive", integration=integ,
              source_info={"bag": {"topic": s.topic, "storage": s.storage, "stamps": s.stamps,
                                   "epoch_ns": s.epoch_ns, "messages": int(s.time.shape[0])}})
    return raw, s


#: the most IMU messages one import reads (they are held as Python objects until the grid is built)
MAX_BAG_MESSAGES = 20_000_000


def bag_hash(path) -> str:
    """SHA-256 of a bag: of the file, or of a ROS 2 bag folder's files (names and bytes, sorted by name)."""
    p = Path(path)
    if p.is_file():
        return file_hash(p)
    h = hashlib.sha256()
    for f in sorted(x for x in p.iterdir() if x.is_file()):
        h.update(f.name.encode() + b"\0" + file_hash(f).encode() + b"\0")
    return "sha256:" + h.hexdigest()


def read_bag_temperature(path, topic: str, epoch_ns: int, stamps: str = "header") -> RawTemperature:
    """The ``sensor_msgs/Temperature`` readings [degC] of ``topic`` at their stamps (``stamps`` as for the
    IMU), in seconds from ``epoch_ns`` (the IMU's first stamp), as readings at their own times; a
    stamp that does not increase is refused."""
    p = Path(path)
    try:
        with _reader(p) as r:
            topics = {name: (info.msgtype or "?", int(info.msgcount)) for name, info in r.topics.items()}
            if topics.get(topic, ("",))[0] != TEMPERATURE_TYPE:
                what = f"holds {topics[topic][0]}, not {TEMPERATURE_TYPE}" if topic in topics else "is not in the bag"
                raise ImportFileError(f"{p}: temperature topic {topic!r} {what}; its topics: {_describe(topics)}")
            ns, val = [], []
            for conn, recv, raw in r.messages(connections=[c for c in r.connections if c.topic == topic]):
                msg = r.deserialize(raw, conn.msgtype)
                ns.append(recv if stamps == "receive" else msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
                val.append(msg.temperature)
    except ImportFileError:
        raise
    except Exception as exc:  # the library's ReaderError, struct / sqlite / yaml errors of a damaged file
        raise _damaged(p, exc) from None
    t = (np.asarray(ns, dtype=np.int64) - int(epoch_ns)).astype(float) * 1e-9
    where = f"{p} topic {topic}"
    if t.shape[0] and np.any(np.diff(t) <= 0):
        k = int(np.argmax(np.diff(t) <= 0)) + 1
        raise ImportFileError(f"{where}: the stamp of message {k + 1} (t = {t[k]:.9f} s) does not follow "
                              f"{t[k - 1]:.9f} s")
    name = topic.strip("/") or topic
    return RawTemperature(t, np.asarray(val, dtype=float)[:, None], (name,), (f"temperature {name!r}",),
                          None, ("degC",), "", where)


def read(src, opts: ReadOptions) -> Raw:
    """The reader of :data:`~inscal.io.formats.REGISTRY`: the bag's IMU topic (``opts.topic``, ``opts.stamps``)."""
    return read_bag(Path(src), opts.topic, opts.stamps, opts.rate_hz)[0]


def source_hash(src) -> str:
    """The source's hash for the record's provenance (a bag folder: its files; :func:`bag_hash`)."""
    return bag_hash(src)
