"""A clean ROS 2 bag of a simulated ``n25`` run against its HDF5 record: the n25 calibration of both, its
chi^2 against the 99 % band and the ratio of every reported sigma (bag over HDF5).

The bag (MCAP, written with the ``rosbags`` library) holds the record's rates, each increment over the
sample interval, stamped at the interval's centre (the instant an averaging sensor's rate represents, REP
145); the encoder angles go beside it as a gimbal file on the bag's clock (seconds from its first stamp).
``--end-stamps`` stamps each rate at the end of its interval instead (a driver that stamps when it
publishes: a half-sample offset between the bag's and the encoders' times); ``--jitter J`` moves each
stamp by a uniform draw within +-J samples (a driver's clock; imported with --rate-hz).

    python bench/bag_n25.py [--seeds 3] [--end-stamps] [--jitter 0.1]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from scipy import stats

from inscal import io
from inscal.calibrate import calibrate
from inscal.sim import scenarios
from inscal.sim.simulate import write_simulation

TS = get_typestore(Stores.ROS2_HUMBLE)
EPOCH = 1_700_000_000_000_000_000


def write_bag(folder: Path, ns: np.ndarray, w: np.ndarray, f: np.ndarray) -> None:
    T = TS.types
    V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    H, Time, Imu = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"], T["sensor_msgs/msg/Imu"]
    z9 = np.zeros(9)
    with Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        c = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=TS)
        for k in range(ns.shape[0]):
            s = int(ns[k])
            msg = Imu(header=H(stamp=Time(sec=s // 10**9, nanosec=s % 10**9), frame_id="imu"),
                      orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=z9,
                      angular_velocity=V(x=w[k, 0], y=w[k, 1], z=w[k, 2]), angular_velocity_covariance=z9,
                      linear_acceleration=V(x=f[k, 0], y=f[k, 1], z=f[k, 2]), linear_acceleration_covariance=z9)
            wr.write(c, s, TS.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def one(seed: int, d: Path, end_stamps: bool, jitter: float = 0.0) -> dict:
    sc = scenarios.build("n25")
    h5 = d / f"n25_{seed}.h5"
    write_simulation(h5, sc, np.random.default_rng(seed), overwrite=True)
    rec = io.read_record(h5)
    dt = 1.0 / rec.rate_hz
    t_stamp = rec.time - (0.0 if end_stamps else 0.5 * dt)
    if jitter:
        t_stamp = t_stamp + np.concatenate([[0.0], np.random.default_rng(100 + seed).uniform(-jitter, jitter,
                                                                                            t_stamp.size - 1) * dt])
    ns = EPOCH + np.round((t_stamp - t_stamp[0]) * 1e9).astype(np.int64)
    bag = d / f"bag_{seed}"
    if bag.exists():
        for p in bag.iterdir():
            p.unlink()
        bag.rmdir()
    write_bag(bag, ns, rec.dtheta / dt, rec.dvel / dt)
    gim = d / f"gimbal_{seed}.csv"
    with open(gim, "w") as fh:  # the encoders on the bag's clock (seconds from its first stamp), true times
        fh.write("time [s],outer [rad],inner [rad]\n")
        tg = np.concatenate([[rec.time[0] - dt], rec.time, [rec.time[-1] + dt]]) - t_stamp[0]
        ag = np.vstack([rec.gimbal[:1], rec.gimbal, rec.gimbal[-1:]])  # at rest before and after the run
        np.savetxt(fh, np.column_stack([tg, ag]), delimiter=",", fmt="%.17g")
    s = rec.site
    out = d / f"bag_{seed}.h5"
    cmd = [sys.executable, "-c", "from inscal.cli.app import main; main()", "import", str(bag), "--format", "rosbag",
           "--out", str(out),
           "--gimbal", str(gim), "--lat", repr(math.degrees(s.latitude)), "--lon", repr(math.degrees(s.longitude)),
           "--height", repr(s.height), "--force"] + (["--rate-hz", repr(rec.rate_hz)] if jitter else [])
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(r.stderr)
    got = io.read_record(out)
    a, b = calibrate(rec, "n25"), calibrate(got, "n25")
    if end_stamps:  # the command line, whose misfit diagnosis knows the encoder check's latency
        r2 = subprocess.run([sys.executable, "-c", "from inscal.cli.app import main; main()", "calibrate", str(out),
                             "--method", "n25", "--out", str(d / f"p_{seed}.toml"), "--force"],
                            capture_output=True, text=True)
        print(r2.stdout[-3000:], r2.stderr[-2000:])
    ratios = {n: float(np.nanmax(np.abs(b.sigma[n] / a.sigma[n] - 1.0))) for n in a.estimated}
    z = {n: float(np.nanmax(np.abs(b.value(n) - a.value(n)) / a.sigma[n])) for n in a.estimated}
    return {"hdf5": a.fit, "bag": b.fit, "sigma_ratio_dev": ratios, "estimate_shift_sigma": z,
            "import": r.stdout.strip(), "bag_notes": b.notes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--end-stamps", action="store_true")
    ap.add_argument("--jitter", type=float, default=0.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            t0 = time.perf_counter()
            r = one(seed, Path(tmp), args.end_stamps, args.jitter)
            band = [stats.chi2.ppf(q, r["bag"]["dof"]) for q in (0.005, 0.995)]
            print(f"seed {seed}: {r['import']}")
            for key in ("hdf5", "bag"):
                fit = r[key]
                print(f"  {key:5s} chi2 {fit['chi2']:.1f} on {fit['dof']} dof (99 % band {band[0]:.1f} .. "
                      f"{band[1]:.1f}), "
                      f"consistent {fit['consistent']}, cause {fit['cause']}")
            worst = max(r["sigma_ratio_dev"], key=r["sigma_ratio_dev"].get)
            print(f"  sigma bag / hdf5: largest deviation {100 * r['sigma_ratio_dev'][worst]:.2f} % ({worst}); "
                  f"estimates differ by at most {max(r['estimate_shift_sigma'].values()):.3f} sigma; "
                  f"took {time.perf_counter() - t0:.1f} s")
            for note in r["bag_notes"]:
                print(f"  note: {note}")


if __name__ == "__main__":
    main()
