"""A hand-held logger's csv through the command line: samples at a jittered clock (time in ms, +-0.3 of
a sample) with gaps (dropped samples, in the still poses), rates in deg/s, accelerations as integer counts with a scale and
an offset, written from the independent generator (handheld_imu.py), imported with a
``kind = "sampled-rates"`` mapping whose ``max_gap_s`` bridges the gaps (``inscal import``), then
calibrated by ``inscal calibrate --method multi-position`` with the method's defaults: every estimated
parameter within 3 sigma of the generator's truth.  Without ``max_gap_s`` the gaps are refused by the
import in one line, nothing written.  (A gap during a move is bridged by a straight line through the hand's
rotation and tremor: it biases that rotation, e.g. the gyro misalignment by 3.5 sigma with six 30-ms gaps
in the moves of this log; the import's error bound, from the longest step, says so, not the calibration.)"""

import json
import math

import numpy as np
import pytest
from handheld_imu import canonical_truth, generate, grade
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.core import units
from inscal.io.mapping import ImportFileError, parse_mapping

runner = CliRunner()
LAT = 0.8  # rad
SCALE, OFFSET = 1e-4 * units.G0, 32768.0  # 0.1 mg per count, the count at zero
MAPPING = """kind = "sampled-rates"
max_gap_s = 0.05
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
    lg = generate(rng, Mg, bg, Ma, ba, n_poses=12, rate_hz=100.0, lat=LAT, g=9.80, arw=arw, vrw=vrw, jitter=0.3,
                  tremor_deg=0.3, samples=True)
    rows = np.column_stack([lg.time * 1e3, np.degrees(lg.dtheta), np.round(lg.dvel / SCALE + OFFSET)])
    still = [k for k in range(100, len(rows) - 100, 10) if any(a + 0.5 < lg.time[k] < b - 0.5 for a, b in lg.still)]
    gaps = rng.choice(still, 6, replace=False)
    rows = np.delete(rows, np.concatenate([g + np.arange(3) for g in gaps]), axis=0)  # 6 gaps of 3 samples
    (d / "map.toml").write_text(MAPPING)
    (d / "strict.toml").write_text(MAPPING.replace("max_gap_s = 0.05\n", ""))
    return d, rows, canonical_truth(Mg, bg, Ma, ba)


def write_csv(path, rows):
    lines = ["t_ms,gx_dps,gy_dps,gz_dps,ax_cnt,ay_cnt,az_cnt"]
    lines += [f"{r[0]:.4f}," + ",".join(f"{x:.9g}" for x in r[1:4]) + "," + ",".join(f"{int(x)}" for x in r[4:])
              for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def site(d, mapping="map.toml"):
    return ("--mapping", d / mapping, "--lat", math.degrees(LAT), "--lon", 10.0, "--height", 0.0,
            "--gravity", 9.80)


def test_jittered_logger_csv_imports_and_calibrates_within_3_sigma(logger):
    d, rows, truth = logger
    csv = write_csv(d / "log.csv", rows)
    # a MEMS gyro bias (0.3 deg/s) is far above the Earth rate: the magnitude check cannot tell it from degrees
    code, out, err = invoke("import", csv, "--format", "csv", *site(d), "--skip-check", "magnitudes",
                            "--out", d / "log.h5", "--json")
    assert code == 0, err
    imp = json.loads(out)
    ig = imp["integration"]
    assert ig["gaps_bridged"] >= 6 and 0.035 < ig["largest_step_s"] < 0.05 and abs(imp["rate_hz"] - 100.0) < 0.5
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


def test_gaps_in_the_logger_clock_are_refused_in_one_line_without_max_gap(logger):
    d, rows, _ = logger
    csv = write_csv(d / "gap.csv", rows)
    code, _, err = invoke("import", csv, "--format", "csv", *site(d, "strict.toml"), "--out", d / "gap.h5")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "dropped before" in err and "max_gap_s in the mapping" in err, err
    assert not (d / "gap.h5").exists()


@pytest.mark.parametrize("doc,msg", [({"kind": "rates", "max_gap_s": 0.1}, "applies to kind = \"sampled-rates\""),
                                     ({"kind": "sampled-rates", "max_gap_s": -1.0}, "must be a duration > 0 s"),
                                     ({"kind": "sampled-rates", "max_gap_s": "1 s"}, "must be a duration > 0 s")])
def test_max_gap_refusals(doc, msg):
    cols = {c: i for i, c in enumerate(("time", "gx", "gy", "gz", "ax", "ay", "az"))}
    with pytest.raises(ImportFileError, match=msg):
        parse_mapping({**doc, "columns": cols, "units": {"gyro": "rad/s", "accel": "m/s^2"}}, "csv")
