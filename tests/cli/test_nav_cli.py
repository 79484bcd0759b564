"""``inscal navigate`` end to end on small simulated records."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation, scenario_from_record
from inscal import io
from inscal.core import turntable
from inscal.cli.app import app
from inscal.core.error_model import ImuErrors, errors_to_field
from inscal.sim.simulate import Scenario
from inscal.core.earth import Site

DEGH = math.pi / 180 / 3600
UG = 9.80665e-6
LAT = math.radians(30.686651)
IMU = ImuErrors(gyro_bias=[0.02 * DEGH, -0.02 * DEGH, 0.02 * DEGH], accel_bias=[100 * UG, -80 * UG, 50 * UG],
                gyro_scale_factor=[2e-4, -1e-4, 3e-4], accel_scale_factor=[1e-4, 2e-4, -2e-4])


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    p = tmp_path_factory.mktemp("nav") / "rec.h5"
    scn = Scenario("nav-test", turntable.rotmod16(2400.0), Site(LAT, 2.1, 20.0), imu=IMU, rate_hz=20)
    write_simulation(p, scn, None)
    return p


def params_file(path, imu):
    doc = {"kind": "inscal-parameters", "schema_version": 1, "inscal_version": "0.1.0", "method": "truth",
           "created": "2025-01-01T00:00:00Z", "parameters": errors_to_field(imu)}
    doc["parameters"].pop("gimbal_nonorthogonality", None)
    doc["parameters"].pop("mount_attitude", None)
    path.write_text(tomli_w.dumps(doc))
    return path


def invoke(*args):
    return CliRunner().invoke(app, ["navigate", *map(str, args)])


def test_navigate_json_reports_truth_errors_and_compensation_helps(record, tmp_path):
    r = invoke(record, "--json")
    assert r.exit_code == 0, r.output
    raw = json.loads(r.stdout)
    for key in ("max_position_error_m", "final_position_error_m", "max_velocity_error_mps"):
        assert raw[key] > 0
    assert set(raw["max_attitude_error_arcsec"]) == {"roll", "pitch", "yaw"}
    assert raw["max_position_error_nmi"] == pytest.approx(raw["max_position_error_m"] / 1852.0)
    assert raw["init"] == "truth" and raw["truth"] is True
    p = params_file(tmp_path / "p.toml", IMU)
    r = invoke(record, "--params", p, "--json")
    assert r.exit_code == 0, r.output
    comp = json.loads(r.stdout)
    assert comp["max_position_error_m"] < 0.01 * raw["max_position_error_m"]
    assert comp["max_position_error_m"] < 1.0


def test_navigate_writes_nav_file_and_refuses_to_overwrite(record, tmp_path):
    out = tmp_path / "nav.h5"
    r = invoke(record, "--out", out, "--output-rate-hz", "0.5")
    assert r.exit_code == 0, r.output
    assert "position error" in r.stdout
    with h5py.File(out) as h5:
        assert h5.attrs["kind"] == "inscal-navigation"
        t = h5["time"][:]
        assert np.allclose(np.diff(t), 2.0)
        assert h5["quaternion"].shape == (t.size, 4) and h5["errors/position"].shape == (t.size, 3)
        s = json.loads(h5.attrs["summary"])
        assert s["max_position_error_m"] == pytest.approx(np.max(np.hypot(*h5["errors/position"][:, 0:2].T)))
    r = invoke(record, "--out", out)
    assert r.exit_code == 2 and "exists" in r.output
    r = invoke(record, "--out", out, "--force", "--mode", "damped", "--vertical", "damped")
    assert r.exit_code == 0, r.output


def test_navigate_alignment_and_errors(record, tmp_path):
    r = invoke(record, "--init", "align", "--align-coarse-s", "60", "--align-fine-s", "300", "--json")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["init"] == "align" and "alignment" in rep
    T = io.record_info(record).n_samples / 20.0
    assert rep["alignment"]["end_time_s"] == pytest.approx(360.0)
    assert rep["duration_h"] == pytest.approx((T - 360.0 - 1.0) / 3600.0)
    for args, msg in (
        (["--mode", "sideways"], "mode"),
        (["--init", "guess"], "init"),
        (["--init", "align", "--align-fine-s", "100000"], "alignment"),
        (["--params", tmp_path / "missing.toml"], "no such"),
    ):
        r = invoke(record, *args)
        assert r.exit_code == 2, (args, r.output)
        assert msg in r.output
        assert "Traceback" not in r.output
    r = invoke(tmp_path / "nothing.h5")
    assert r.exit_code == 2 and "Traceback" not in r.output


def test_record_without_truth_is_aligned_and_checked_against_the_site(record, tmp_path):
    rec = io.read_record(record)
    rec.truth = None
    rec.path = None
    bare = tmp_path / "bare.h5"
    io.write_record(bare, rec)
    r = invoke(bare, "--init", "truth")
    assert r.exit_code == 2 and "no truth" in r.output
    r = invoke(bare, "--json", "--align-fine-s", "300")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["init"] == "align" and rep["truth"] is False
    assert "max_attitude_error_arcsec" not in rep
    assert rep["max_position_error_m"] > 0


def test_navigate_plot_and_heading_beside_yaw(record, tmp_path):
    png = tmp_path / "nav.png"
    r = invoke(record, "--plot", png, "--json")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["plot"] == str(png)
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    assert img.shape[0] > 400 and img.shape[1] > 600 and np.ptp(img[..., :3]) > 0.5  # drawn, not blank
    att = rep["final_attitude_deg"]
    # yaw: counter-clockwise from East; heading: clockwise from North = 90 deg - yaw, in [0, 360)
    assert 0.0 <= att["heading"] < 360.0
    assert att["heading"] == pytest.approx((90.0 - att["yaw"]) % 360.0)
    scn = scenario_from_record(io.record_info(record))
    assert att["yaw"] == pytest.approx(math.degrees(scn.gimbal.mount_attitude[2]), abs=0.01)
    r = invoke(record, "--plot", png)  # never overwritten without --force
    assert r.exit_code == 2 and "exists" in r.output
    r = invoke(record, "--plot", png, "--force")
    assert r.exit_code == 0 and "heading" in r.stdout and "clockwise from North" in r.stdout
    r = invoke(record, "--plot", tmp_path / "nav.jpeg")
    assert r.exit_code == 2 and "plot format" in r.output
    r = invoke(record, "--plot", record, "--force")  # never the input record
    assert r.exit_code == 2 and "plot format" in r.output and record.exists()


def test_navigate_vertical_free_and_height_reference(record, tmp_path):
    r = invoke(record, "--vertical", "free", "--json")
    assert r.exit_code == 0, r.output
    free = json.loads(r.stdout)
    assert free["vertical_channel"] == "free" and free["max_height_error_m"] > 0
    r = invoke(record, "--vertical", "damped", "--height-ref", "25.5", "--json")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["height_reference"] == {"height_m": 25.5}
    # the site is at 20 m: the loop settles on the reference, 5.5 m above it
    assert rep["final_height_error_m"] == pytest.approx(5.5, abs=0.05) and rep["max_height_error_m"] >= 5.5
    csv = tmp_path / "baro.csv"
    csv.write_text("time_s,height_m\n0,20\n1200,30\n2400,20\n")
    out = tmp_path / "v.h5"
    # compensated (the record's 50-100 ug biases, modulated by the rotation, would move the loop by ~b tau^2 = 5 m)
    pf = params_file(tmp_path / "p.toml", IMU)
    r = invoke(record, "--vertical", "damped", "--height-ref", csv, "--params", pf, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["height_reference"]["points"] == 3
    with h5py.File(out) as h5:
        t, h = h5["time"][:], h5["position"][:, 2]
    late = t > 600
    assert np.max(np.abs(h[late] - np.interp(t[late], [0, 1200, 2400], [20, 30, 20]))) < 0.5
    for args, msg in ((["--vertical", "free", "--height-ref", "3"], "free vertical"),
                      (["--vertical", "damped", "--height-ref", tmp_path / "none.csv"], "neither a number"),
                      (["--vertical", "sideways"], "vertical")):
        r = invoke(record, *args)
        assert r.exit_code == 2 and msg in r.output and "Traceback" not in r.output, (args, r.output)
    csv.write_text("time_s,height_m\n0,20\n10,x\n")
    r = invoke(record, "--vertical", "damped", "--height-ref", csv)
    assert r.exit_code == 2 and "row 3" in r.output and len(r.output.strip().splitlines()) == 1
