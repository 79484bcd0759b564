"""Provenance checks of ``inscal compensate`` and ``inscal navigate``: one warning
line when the parameter file's data hash, scenario or IMU serial differ from the record's,
and no second compensation of a compensated record without ``--force``."""

from __future__ import annotations

import math

import h5py
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation
from inscal import io
from inscal.core import turntable
from inscal.cli.app import app
from inscal.core.error_model import ImuErrors, errors_to_field
from inscal.sim.simulate import Scenario
from inscal.core.earth import Site

UG = 9.80665e-6
IMU = ImuErrors(accel_bias=[100 * UG, -80 * UG, 50 * UG], gyro_scale_factor=[2e-4, -1e-4, 3e-4])


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    p = tmp_path_factory.mktemp("prov") / "rec.h5"
    write_simulation(p, Scenario("prov-a", turntable.static(120.0), Site(math.radians(30.0), 2.0, 10.0), imu=IMU,
                                    rate_hz=10.0), None)
    with h5py.File(p, "a") as h5:
        h5.attrs["imu_serial"] = "SN-1"
    return p


def params(path, data_hash=None, scenario=None, serial=None):
    doc = {"kind": "inscal-parameters", "schema_version": 1, "method": "truth",
           "parameters": {k: v for k, v in errors_to_field(IMU).items() if not k.startswith(("gimbal", "mount"))}}
    if data_hash:
        doc["data_hash"] = data_hash
    meta = {k: v for k, v in (("scenario", scenario), ("imu_serial", serial)) if v}
    if meta:
        doc["metadata"] = meta
    path.write_text(tomli_w.dumps(doc))
    return path


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def warnings(res):
    return [ln for ln in res.stderr.splitlines() if ln.startswith("inscal: warning:")]


def test_matching_or_absent_provenance_is_silent(record, tmp_path):
    good = params(tmp_path / "good.toml", io.file_hash(record), "prov-a", "SN-1")
    res = invoke("compensate", record, "--params", good, "--out", tmp_path / "c.h5")
    assert res.exit_code == 0, res.output
    assert warnings(res) == [] and res.stderr == ""
    bare = params(tmp_path / "bare.toml")  # a file without provenance: nothing to compare
    res = invoke("compensate", record, "--params", bare, "--out", tmp_path / "d.h5")
    assert res.exit_code == 0 and warnings(res) == []


def test_mismatch_gives_one_warning_line(record, tmp_path):
    bad = params(tmp_path / "bad.toml", "sha256:" + "0" * 64, "s16", "SN-2")
    res = invoke("compensate", record, "--params", bad, "--out", tmp_path / "c.h5")
    assert res.exit_code == 0, res.output
    w = warnings(res)
    assert len(w) == 1 and len(res.stderr.splitlines()) == 1
    assert "calibrated from another record" in w[0] and "scenario 's16'" in w[0] and "'prov-a'" in w[0]
    assert "IMU serial 'SN-2'" in w[0] and "'SN-1'" in w[0]
    # only the scenario differs: only the scenario is named
    res = invoke("compensate", record, "--params", params(tmp_path / "s.toml", io.file_hash(record), "n25", "SN-1"),
                 "--out", tmp_path / "e.h5")
    w = warnings(res)
    assert len(w) == 1 and "scenario 'n25'" in w[0] and "another record" not in w[0] and "serial" not in w[0]


def test_compensated_record_refused_unless_forced(record, tmp_path):
    p = params(tmp_path / "p.toml")
    once = tmp_path / "once.h5"
    assert invoke("compensate", record, "--params", p, "--out", once).exit_code == 0
    twice = tmp_path / "twice.h5"
    res = invoke("compensate", once, "--params", p, "--out", twice)
    assert res.exit_code == 2 and "already compensated" in res.stderr and "--force" in res.stderr
    assert not twice.exists()
    res = invoke("compensate", once, "--params", p, "--out", twice, "--force")
    assert res.exit_code == 0 and twice.exists()
    assert len(warnings(res)) == 1 and "already compensated" in warnings(res)[0]


def test_navigate_warns_on_mismatch_and_on_a_compensated_record(record, tmp_path):
    bad = params(tmp_path / "bad.toml", scenario="s16")
    res = invoke("navigate", record, "--params", bad, "--json")
    assert res.exit_code == 0, res.output
    w = warnings(res)
    assert len(w) == 1 and "scenario 's16'" in w[0]
    good = params(tmp_path / "good.toml", io.file_hash(record), "prov-a", "SN-1")
    res = invoke("navigate", record, "--params", good, "--json")
    assert res.exit_code == 0 and warnings(res) == []
    comp = tmp_path / "comp.h5"
    assert invoke("compensate", record, "--params", good, "--out", comp).exit_code == 0
    # the compensated record has no truth: a short alignment instead
    res = invoke("navigate", comp, "--params", good, "--json", "--align-coarse-s", 10, "--align-fine-s", 30)
    assert res.exit_code == 0, res.output
    w = warnings(res)
    assert any("already compensated" in x for x in w)
    assert any("another record" in x for x in w)  # the compensated file is not the calibrated one
