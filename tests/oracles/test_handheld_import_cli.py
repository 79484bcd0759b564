"""A hand-held logger's csv through the command line: samples at a jittered clock (time in ms), rates in
deg/s, accelerations as integer counts with a scale and an offset, written from the independent
generator (handheld_imu.py), imported with a ``kind = "sampled-rates"`` mapping (``inscal import``), then
calibrated by ``inscal calibrate --method multi-position`` with the method's defaults: every estimated
parameter within 3 sigma of the generator's truth.  A logger file with dropped samples (a gap) is
refused by the import in one line, nothing written."""

import json
import math

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.core import units

runner = CliRunner()
LAT = 0.8  # rad
SCALE, OFFSET = 1e-4 * units.G0, 32768.0  # 0.1 mg per count, the count at zero
MAPPING = """kind = "sampled-rates"
header_rows = 1
[columns]
time = "t_ms"
gx = "gx_dps"
gy = "gy_dps"
gz = "gz_dps"
ax = "ax_cnt"
ay = "ay_cnt"
az = "az_cnt"
[units]
time = "ms"
gyro = "deg/s"
accel = "counts"
accel_scale = "0.1 mg"
accel_offset = 32768
"""


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def logger(tmp_path_factory):
    d = tmp_path_factory.mktemp("logger")
    rng = np.random.default_rng(33)
    Mg, bg, Ma, ba, arw, vrw = grade("mems", rng)
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=100.0, lat=LAT, g=9.80, arw=arw, vrw=vrw, jitter=0.2,
                  tremor_deg=0.3, samples=True)
    rows = np.column_stack([lg.time * 1e3, np.degrees(lg.dtheta), np.round(lg.dvel / SCALE + OFFSET)])
    (d / "map.toml").write_text(MAPPING)
    return d, rows, canonical_truth(Mg, bg, Ma, ba)


def write_csv(path, rows):
    lines = ["t_ms,gx_dps,gy_dps,gz_dps,ax_cnt,ay_cnt,az_cnt"]
    lines += [f"{r[0]:.4f}," + ",".join(f"{x:.9g}" for x in r[1:4]) + "," + ",".join(f"{int(x)}" for x in r[4:])
              for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def site(d):
    return ("--mapping", d / "map.toml", "--lat", math.degrees(LAT), "--lon", 10.0, "--height", 0.0,
            "--gravity", 9.80)


def test_jittered_logger_csv_imports_and_calibrates_within_3_sigma(logger):
    d, rows, truth = logger
    csv = write_csv(d / "log.csv", rows)
    # a MEMS gyro bias (0.3 deg/s) is far above the Earth rate: the magnitude check takes it for degrees
    code, out, err = invoke("import", csv, "--format", "csv", *site(d), "--skip-check", "magnitudes",
                            "--out", d / "log.h5", "--json")
    assert code == 0, err
    imp = json.loads(out)
    assert imp["integration"] is not None and abs(imp["rate_hz"] - 100.0) < 0.1
    code, out, err = invoke("calibrate", d / "log.h5", "--method", "multi-position", "--out", d / "p.toml", "--json")
    assert code == 0, err
    rep = json.loads(out)
    assert rep["fit"]["consistent"], rep["notes"]
    for name, want in truth.items():
        e = rep["parameters"][name]
        v = units.to_si(np.array(e["value"], float), e["unit"])
        s = units.to_si(np.array([np.nan if x is None else x for x in e["sigma"]], float), e["unit"])
        free = np.isfinite(s)
        assert free.sum() >= 3 and np.all(np.abs(v - want)[free] < 3.0 * s[free]), (name, (v - want) / s)


def test_a_gap_in_the_logger_clock_is_refused_in_one_line(logger):
    d, rows, _ = logger
    csv = write_csv(d / "gap.csv", np.delete(rows[:3000], np.s_[1500:1504], axis=0))
    code, _, err = invoke("import", csv, "--format", "csv", *site(d), "--out", d / "gap.h5")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "dropped" in err and "gap" in err, err
    assert not (d / "gap.h5").exists()
