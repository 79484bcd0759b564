"""
A ROS 2 bag in, a calibration out in other tools' conventions
=============================================================

A robot logs its IMU as ``sensor_msgs/Imu`` messages in a ROS 2 bag: rates (rad/s) and specific
force (m/s²) sampled at the header stamps, with the stamps' jitter. Write such a bag of a hand-held
session with the ``rosbags`` library, import it (the importer integrates the sampled rates into
increments on a regular grid, :mod:`inscal.io.formats.rates`), look at the rates and at the noise of
the imported increments, calibrate it with the multi-position model, and export the calibration to
Kalibr, imucal and KF-GINS (each convention written out in :mod:`inscal.io.exports`).

The same with commands (the bag written by this script)::

    inscal import hh_bag --format rosbag --out hh.h5 --lat 32.0 --lon 118.8
    inscal calibrate hh.h5 --method multi-position --out mp.toml
    inscal export mp.toml --format kalibr --out imu.yaml
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

from inscal import io
from inscal.analysis.allan import allan
from inscal.calibrate import calibrate
from inscal.core import units
from inscal.io.exports.calibration import export_calibration
from inscal.io.importers import import_file
from inscal.io.paramfile import save_params
from inscal.sim.scenarios import build
from inscal.sim.simulate import write_simulation

folder = Path(tempfile.mkdtemp())
write_simulation(folder / "truth.h5", build("handheld-mems"), np.random.default_rng(1))
sim = io.read_record(folder / "truth.h5")

# %%
# The bag: one message per sample, the rate of the interval at its stamp, the stamps jittered by 0.5 ms rms
# as a driver's clock reads them (the seeded generator draws the jitter).
rng = np.random.default_rng(7)
dt = np.diff(sim.time, prepend=sim.time[0] - np.median(np.diff(sim.time)))
w, f = sim.dtheta / dt[:, None], sim.dvel / dt[:, None]
jitter = 5e-4 * rng.standard_normal(sim.time.size)  # 0.5 ms of stamp jitter
stamps = 1_700_000_000 * 10**9 + np.round((sim.time - dt / 2 + jitter) * 1e9)
ts = get_typestore(Stores.ROS2_HUMBLE)
T = ts.types
with Writer(folder / "hh_bag", version=9) as bag:
    conn = bag.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=ts)
    for ns, wk, fk in zip(stamps.astype(np.int64), w, f):
        sec, nanosec = divmod(int(ns), 10**9)
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
        vec3 = T["geometry_msgs/msg/Vector3"]
        msg = T["sensor_msgs/msg/Imu"](
            header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu"),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.r_[-1.0, np.zeros(8)],
            angular_velocity=vec3(x=wk[0], y=wk[1], z=wk[2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=vec3(x=fk[0], y=fk[1], z=fk[2]),
            linear_acceleration_covariance=np.zeros(9))
        bag.write(conn, int(ns), ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))

# %%
# Import it (the site as the simulation's: a bag carries none), then calibrate and export.
summary = import_file(folder / "hh_bag", folder / "hh.h5", "rosbag", site=sim.site)
record = io.read_record(folder / "hh.h5")
topic = summary.get("topic", "/imu/data")
print(f"imported {record.time.size} samples at {record.rate_hz:.4g} Hz from {topic}")
result = calibrate(record, "multi-position")
save_params(folder / "mp.toml", result)
exports = (("kalibr", "imu.yaml"), ("imucal", "imucal.json"),
           ("kf-gins", "kfgins.yaml"))
for fmt, name in exports:
    export_calibration(folder / "mp.toml", folder / name, fmt)
    print(f"----- {name} ({fmt})")
    print((folder / name).read_text()[:700])

# %%
# The figure: the imported rates over the session, and the Allan deviation of the increments of the
# still first pose against the scenario's white noise (ARW, VRW).
first = (record.time > 0.8) & (record.time < 3.7)
gyro_ad = allan(record.dtheta[first], record.rate_hz)
acc_ad = allan(record.dvel[first], record.rate_hz)
noise = build("handheld-mems").noise
fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(11, 3.8), layout="constrained",
                                    gridspec_kw={"width_ratios": [2, 1, 1]})
rdt = np.diff(record.time, prepend=record.time[0] - 1 / record.rate_hz)
for k in range(3):
    ax1.plot(record.time, np.degrees(record.dtheta[:, k] / rdt), lw=0.5, label="xyz"[k])
ax1.set_xlabel("time [s]")
ax1.set_ylabel("rate [deg/s]")
ax1.set_title("gyro rates imported from the bag")
ax1.legend(ncol=3, fontsize=8)
for ax, res, white, scale, unit, what in (
        (ax2, gyro_ad, noise.arw, 180 / np.pi * 3600, "deg/h", "gyro"),
        (ax3, acc_ad, noise.vrw, 1e6 / units.G0, "µg", "accelerometer")):
    for k in range(3):
        ax.loglog(res.taus, res.adev[:, k] * scale, "o-", ms=3, label="xyz"[k])
    ax.loglog(res.taus, np.mean(white) / np.sqrt(res.taus) * scale, "k--", lw=1,
              label="simulated white noise")
    ax.set_xlabel("τ [s]")
    ax.set_ylabel(f"Allan deviation [{unit}]")
    ax.set_title(f"{what}: first pose")
    ax.grid(True, which="both", alpha=0.3)
ax3.legend(fontsize=7)
