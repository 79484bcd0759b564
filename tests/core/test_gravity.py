"""The site's gravity model (WGS-84 normal gravity, the PSINS formula or a
measured value) in the record, the scenario files, the command line, every calibration
method and the navigator."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation
from inscal.core import earth, turntable
from inscal import io
from inscal import nav as nv
from inscal.sim import scenarios, simulate
from inscal.calibrate import calibrate
from inscal.calibrate.windows import window_means
from inscal.cli.app import app
from inscal.core.earth import GravityModel, parse_gravity
from inscal.core.error_model import ImuNoise
from inscal.sim.simulate import Scenario
from inscal.core.earth import Site
from inscal.nav.strapdown import NavConfig

DEG = math.pi / 180.0
LAT34 = 34.0 * DEG
PPM = 1e-6


def test_psins_formula_values():
    # PSINS: g(L=0, h=0) = g0; beta, beta1 from m = Re wie^2 / g0 and f = 1/298.257
    assert earth.psins_gravity(0.0, 0.0) == pytest.approx(9.7803267715, abs=1e-12)
    assert earth.PSINS_BETA == pytest.approx(5.3024e-3, rel=1e-4)
    assert earth.PSINS_BETA1 == pytest.approx(5.8615e-6, rel=1e-4)
    # the 0.14 ppm of the issue at 34 N
    d = earth.psins_gravity(LAT34, 0.0) / earth.normal_gravity(LAT34, 0.0) - 1.0
    assert 0.13 * PPM < d < 0.15 * PPM
    # free-air decrease ~3.08e-6 per metre
    assert earth.psins_gravity(LAT34, 0.0) - earth.psins_gravity(LAT34, 100.0) == pytest.approx(3.08e-4, rel=0.01)


def test_gravity_model_kinds_and_errors():
    assert Site(LAT34).gravity == earth.normal_gravity(LAT34, 0.0)
    assert Site(LAT34).gravity_scale == 1.0
    assert Site(LAT34, 0.0, 0.0, "psins").gravity == earth.psins_gravity(LAT34, 0.0)
    m = parse_gravity("9.7935")
    s = Site(LAT34, 1.0, 380.0, m)
    assert s.gravity == 9.7935  # measured at the site height
    assert s.gravity_scale == pytest.approx(9.7935 / earth.normal_gravity(LAT34, 380.0), rel=1e-15)
    m2 = GravityModel("measured", 9.7935, 0.0)  # taken at h = 0: free-air gradient to 380 m
    assert Site(LAT34, 0.0, 380.0, m2).gravity == pytest.approx(9.7935 - 1.1727e-3, abs=2e-6)
    for bad in ("nope", "12", "nan"):
        with pytest.raises(ValueError):
            parse_gravity(bad)
    with pytest.raises(ValueError):
        GravityModel("psins", 9.8)
    assert GravityModel.from_json(None) == earth.WGS84_GRAVITY
    assert GravityModel.from_json(m2.to_json()) == m2


# ---------------------------------------------------------------------- calibration
@pytest.fixture(scope="module")
def psins_record():
    sc = scenarios.build("n25")
    sc = replace(sc, noise=ImuNoise(), site=Site(LAT34, 108.0 * DEG, 0.0, earth.PSINS_GRAVITY))
    d = simulate.simulate(sc)
    rec = SimpleNamespace(time=d.time, dtheta=d.dtheta, dvel=d.dvel, gimbal=d.gimbal, rate_hz=sc.rate_hz,
                          site=sc.site, path=sc.path)
    return sc, rec


def _accel_sf_error(sc, rec, site):
    res = calibrate(window_means(SimpleNamespace(**{**vars(rec), "site": site})), "joint", uncertainty=False)
    return np.abs(res.imu.accel_scale_factor - sc.imu.accel_scale_factor)


def test_joint_with_the_data_gravity_model_has_no_scale_factor_error(psins_record):
    sc, rec = psins_record
    right = _accel_sf_error(sc, rec, rec.site)
    wrong = _accel_sf_error(sc, rec, rec.site.with_gravity("wgs84"))
    print(f"accel SF error: psins model {right / PPM} ppm, wgs84 model {wrong / PPM} ppm")
    assert np.all(right < 0.01 * PPM), right / PPM
    assert np.all(wrong > 0.05 * PPM), wrong / PPM  # ~0.14 ppm: the error the issue reports


def test_systematic_kernel_uses_the_site_gravity_model():
    sc = scenarios.build("psins19")  # 34 N, 380 m
    sc = replace(sc, noise=ImuNoise(), site=sc.site.with_gravity("psins"))
    d = simulate.simulate(sc)

    def err(gm):
        rec = SimpleNamespace(dtheta=d.dtheta, dvel=d.dvel, rate_hz=sc.rate_hz, site=sc.site.with_gravity(gm))
        return np.abs(calibrate(rec, "systematic51").imu.accel_scale_factor - sc.imu.accel_scale_factor)

    right, wrong = err("psins"), err("wgs84")
    print(f"systematic51 accel SF error: psins model {right / PPM} ppm, wgs84 model {wrong / PPM} ppm")
    assert np.all(right < 0.01 * PPM), right / PPM
    assert np.all(wrong > 0.05 * PPM), wrong / PPM


# ---------------------------------------------------------------------- files and CLI
def test_measured_gravity_round_trip_toml_hdf5_cli(tmp_path):
    toml = tmp_path / "g.toml"
    toml.write_text('[scenario]\nname = "grav"\nrate_hz = 10\nduration_s = 20\n'
                    '[site]\nlatitude_deg = 34.0\nheight_m = 380.0\n'
                    'gravity = {value = 9.79345, unit = "m/s^2"}\n')
    sc = scenarios.build(str(toml))
    assert sc.site.gravity_model == GravityModel("measured", 9.79345)
    assert sc.site.gravity == 9.79345
    out = tmp_path / "g.h5"
    r = CliRunner().invoke(app, ["simulate", str(toml), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["gravity"]["value"] == 9.79345
    rec = io.read_record(out)
    assert rec.site.gravity_model == GravityModel("measured", 9.79345)
    # static record: the mean specific force is the measured gravity
    assert np.linalg.norm(rec.dvel.sum(axis=0)) / (rec.n_samples / rec.rate_hz) == pytest.approx(9.79345, rel=1e-12)
    # CLI override and psins on the command line
    out2 = tmp_path / "p.h5"
    r = CliRunner().invoke(app, ["simulate", str(toml), "-o", str(out2), "--gravity", "psins", "--json"])
    assert r.exit_code == 0, r.output
    assert io.read_record(out2).site.gravity_model == earth.PSINS_GRAVITY
    r = CliRunner().invoke(app, ["simulate", str(toml), "-o", str(tmp_path / "x.h5"), "--gravity", "moon"])
    assert r.exit_code == 2 and "--gravity" in r.output and "Traceback" not in r.output
    r = CliRunner().invoke(app, ["navigate", str(out), "--json", "--gravity", "psins"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["gravity"]["kind"] == "psins"
    r = CliRunner().invoke(app, ["navigate", str(out), "--json"])
    assert json.loads(r.output)["gravity"] == {"kind": "measured", "value": 9.79345, "g_site_m_s2": 9.79345}
    r = CliRunner().invoke(app, ["calibrate", str(out), "-m", "joint", "-o", str(tmp_path / "c.toml"), "--gravity", "1e9"])
    assert r.exit_code == 2 and "--gravity" in r.output and "Traceback" not in r.output
    bad = tmp_path / "b.toml"
    bad.write_text('[site]\nlatitude_deg = 34.0\ngravity = {value = 9.79, unit = "deg"}\n')
    r = CliRunner().invoke(app, ["simulate", str(bad), "-o", str(tmp_path / "y.h5")])
    assert r.exit_code == 2 and "Traceback" not in r.output


def test_record_without_gravity_attr_reads_as_wgs84(tmp_path):
    import h5py

    sc = Scenario("s", turntable.static(2.0), Site(LAT34, 0.0, 0.0, "psins"), rate_hz=10)
    p = tmp_path / "r.h5"
    write_simulation(p, sc, None)
    assert io.read_record(p).site.gravity_model == earth.PSINS_GRAVITY
    with h5py.File(p, "a") as h5:
        del h5["site"].attrs["gravity_model"]
    assert io.read_record(p).site.gravity_model == earth.WGS84_GRAVITY


# ---------------------------------------------------------------------- navigator
def test_static_navigation_with_the_data_gravity_model():
    site = Site(LAT34, 108.0 * DEG, 380.0, earth.PSINS_GRAVITY)
    scn = Scenario("g", turntable.static(3600.0), site, rate_hz=10)
    d = simulate.simulate(scn)
    cfg = NavConfig(vertical="damped")

    def worst(nav_site):
        r = nv.navigate(nv.chunks_of(d), scn.rate_hz, nav_site, scenario=replace(scn, site=nav_site), config=cfg)
        return float(np.max(np.linalg.norm(r.errors.position, axis=1)))

    right, wrong = worst(site), worst(site.with_gravity("wgs84"))
    print(f"1 h static position error: psins navigator {right * 1e3:.4f} mm, wgs84 navigator {wrong * 1e3:.4f} mm")
    assert right < 1e-3
    assert wrong > 2e-3


def test_import_stores_the_gravity_model(tmp_path):
    from typer.testing import CliRunner

    from inscal import io
    from inscal.cli.app import app

    runner = CliRunner()
    rec = tmp_path / "st.h5"
    assert runner.invoke(app, ["simulate", "static", "--duration-h", "0.01", "--out", str(rec)]).exit_code == 0
    assert runner.invoke(app, ["export", str(rec), "--format", "psins", "--out", str(tmp_path / "x.bin")]).exit_code == 0
    base = ["import", str(tmp_path / "x.bin"), "--format", "psins", "--lat", "30.686651", "--lon", "120.664265",
            "--height", "0", "--skip-check", "constant", "--skip-check", "magnitudes"]
    r = runner.invoke(app, base + ["--gravity", "psins", "--out", str(tmp_path / "i.h5")])
    assert r.exit_code == 0, r.stdout
    assert io.read_record(tmp_path / "i.h5").site.gravity_model.kind == "psins"
    r = runner.invoke(app, base + ["--gravity", "nonsense", "--out", str(tmp_path / "j.h5")])
    assert r.exit_code == 2 and not (tmp_path / "j.h5").exists()
