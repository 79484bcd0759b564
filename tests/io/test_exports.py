"""``inscal export PARAMS --format kalibr|imucal|imu-tk|kf-gins``: each file read back as its tool would, and each
tool's published compensation formula (written here from its documentation, not imported) applied to
raw increments gives inscal's compensated increments back to 1e-12; the terms a convention cannot hold
are named; the refusals are one line, exit 2, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tomli_w
from ruamel.yaml import YAML
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.core.error_model import ImuErrors, errors_to_field
from inscal.core.units import ARCSEC, DEG, G0, HOUR

runner = CliRunner()
UG = 1e-6 * G0
LINEAR = ImuErrors(
    gyro_scale_factor=[120e-6, -80e-6, 200e-6], gyro_misalignment=np.array([15, -7, 30, 9, -24, 6]) * ARCSEC,
    gyro_bias=np.array([0.5, -0.3, 0.2]) * DEG / HOUR,
    gyro_g_sensitivity=np.array([[0.1, 0.02, -0.03], [0.01, -0.2, 0.04], [0.02, 0.01, 0.15]]) * DEG / HOUR / G0,
    accel_scale_factor=[150e-6, -90e-6, 60e-6], accel_misalignment=np.array([-18, 4, 26, -3, 10, 12]) * ARCSEC,
    accel_bias=np.array([80, -120, 50]) * UG)
DT = 0.01


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def params_file(path, imu, sigma=None):
    field = errors_to_field(imu)
    for name, s in (sigma or {}).items():
        field[name]["sigma"] = s
    path.write_text(tomli_w.dumps({"kind": "inscal-parameters", "schema_version": 1, "method": "manual",
                                   "parameters": field}))
    return path


def raw_samples(n=400, seed=7):
    """Raw increments of a tumbling IMU: rates up to 2 rad/s, specific force around g."""
    rng = np.random.default_rng(seed)
    w = rng.uniform(-2.0, 2.0, (n, 3))
    f = rng.normal(0.0, 1.0, (n, 3)) + np.array([0.0, 0.0, G0])
    return w * DT, f * DT


def inscal_compensated(imu, dth, dv):
    return imu.compensate_increments(DT, dth, dv)


def close(a, b, rel=1e-12):
    scale = np.abs(b).max()
    assert np.abs(a - b).max() <= rel * scale, np.abs(a - b).max() / scale


def test_kalibr_round_trip(tmp_path):
    p = params_file(tmp_path / "p.toml", LINEAR)
    code, out, err = invoke("export", p, "--format", "kalibr", "--out", tmp_path / "imu.yaml", "--json")
    assert code == 0, err
    assert json.loads(out)["dropped"] == []
    doc = YAML(typ="safe", pure=True).load((tmp_path / "imu.yaml").read_text())["imu0"]
    assert doc["model"] == "scale-misalignment"
    acc, gyr, ins = doc["accelerometers"], doc["gyroscopes"], doc["inscal"]
    Ma, Mg, A, Cgi, Cis = (np.array(x) for x in (acc["M"], gyr["M"], gyr["A"], gyr["C_gyro_i"], ins["C_i_s"]))
    ba, bg = np.array(ins["b_accel"]), np.array(ins["b_gyro"])
    # Kalibr's structure: lower-triangular scale-misalignment matrices, rotations
    assert np.all(np.triu(Ma, 1) == 0) and np.all(np.triu(Mg, 1) == 0)
    for C in (Cgi, Cis):
        assert np.allclose(C @ C.T, np.eye(3), atol=1e-15) and np.linalg.det(C) > 0
    dth, dv = raw_samples()
    am, wm = dv / DT, dth / DT
    # Kalibr (Rehder et al. 2016; kalibr's ScaledMisalignedImu: w = M C_gyro_i w_i + Ma C_gyro_i a_i + b):
    # a_i = M_accel^-1 (a_m - b_a); w_i = C_gyro_i^T M_gyro^-1 (w_m - b_g - A C_gyro_i a_i)
    a_i = np.linalg.solve(Ma, (am - ba).T).T
    w_i = (Cgi.T @ np.linalg.solve(Mg, (wm - bg - a_i @ Cgi.T @ A.T).T)).T
    # back to inscal's s-frame
    f_s, w_s = a_i @ Cis, w_i @ Cis
    cdth, cdv = inscal_compensated(LINEAR, dth, dv)
    close(w_s * DT, cdth)
    close(f_s * DT, cdv)


def test_kalibr_size_effect_within_the_stated_frame_error(tmp_path):
    lever = np.array([[0.03, 0.004, -0.002], [0.001, -0.025, 0.003], [-0.002, 0.001, 0.02]])
    imu = LINEAR.replace(accel_lever_arm=lever)
    p = params_file(tmp_path / "p.toml", imu)
    code, out, err = invoke("export", p, "--format", "kalibr", "--out", tmp_path / "imu.yaml", "--json")
    assert code == 0, err
    res = json.loads(out)
    doc = YAML(typ="safe", pure=True).load((tmp_path / "imu.yaml").read_text())["imu0"]
    assert doc["model"] == "scale-misalignment-size-effect"
    Cis = np.array(doc["inscal"]["C_i_s"])
    r = np.array([doc["accelerometers"][k] for k in ("rx_i", "ry_i", "rz_i")])
    # positions are the lever arms in Kalibr's frame: r_k = C_i_s p_k
    np.testing.assert_allclose(r @ Cis, lever, rtol=0, atol=1e-16)
    # static size effect (w-dot = 0): Kalibr's e_k^i . (w x (w x r_k)) vs inscal's e_k^s . (w x (w x p_k))
    w = np.array([1.5, -2.0, 0.7])
    w_i = Cis @ w
    kal = np.array([np.cross(w_i, np.cross(w_i, r[k]))[k] for k in range(3)])
    ins = np.array([np.cross(w, np.cross(w, lever[k]))[k] for k in range(3)])
    diff = np.abs(Cis.T @ kal - ins).max()
    bound = 2.0 * res["size_effect_frame_error"] * np.abs(w) @ np.abs(w) * np.abs(lever).sum(axis=1).max()
    assert 0 < diff <= bound


def test_imucal_round_trip(tmp_path):
    p = params_file(tmp_path / "p.toml", LINEAR)
    code, out, err = invoke("export", p, "--format", "imucal", "--out", tmp_path / "cal.json", "--json")
    assert code == 0, err
    doc = json.loads((tmp_path / "cal.json").read_text())
    assert doc["cal_type"] == "Ferraris" and doc["gyr_unit"] == "deg/s" and doc["from_gyr_unit"] == "rad/s"
    K_a, R_a, b_a, K_g, R_g, K_ga, b_g = (np.array(doc[k]) for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g"))
    assert np.all(K_a == np.diag(np.diag(K_a))) and np.allclose(np.linalg.norm(R_a, axis=1), 1.0, rtol=0, atol=1e-15)
    dth, dv = raw_samples()
    acc_raw, gyr_raw = dv / DT, dth / DT
    # imucal (Ferraris 1995): acc = R_a^-1 K_a^-1 (acc_raw - b_a); gyr = R_g^-1 K_g^-1 (gyr_raw - K_ga acc - b_g)
    acc = (np.linalg.inv(R_a) @ np.linalg.inv(K_a) @ (acc_raw - b_a).T).T
    gyr = (np.linalg.inv(R_g) @ np.linalg.inv(K_g) @ (gyr_raw - acc @ K_ga.T - b_g).T).T
    cdth, cdv = inscal_compensated(LINEAR, dth, dv)
    close(np.radians(gyr) * DT, cdth)
    close(acc * DT, cdv)


def imutk_load(path):
    """imu_tk's ``CalibratedTriad_::load``: 9 + 9 + 3 whitespace-separated numbers, the matrices row-major."""
    x = np.array(path.read_text().split(), float)
    assert x.size == 21
    return x[:9].reshape(3, 3), x[9:18].reshape(3, 3), x[18:]


def test_imutk_round_trip(tmp_path):
    imu = LINEAR.replace(gyro_g_sensitivity=np.zeros((3, 3)))  # imu_tk's gyro model has no g-sensitivity
    p = params_file(tmp_path / "p.toml", imu)
    code, out, err = invoke("export", p, "--format", "imu-tk", "--out", tmp_path / "imu_acc.calib", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["dropped"] == [] and res["files"][1].endswith("imu_gyro.calib")
    (Ta, Ka, Ba), (Tg, Kg, Bg) = imutk_load(tmp_path / "imu_acc.calib"), imutk_load(tmp_path / "imu_gyro.calib")
    Cbs = np.array(res["C_b_s"])
    # imu_tk's structure: unit-diagonal T, the accelerometers' upper triangular ("body" frame), diagonal K
    assert np.all(np.diag(Ta) == 1.0) and np.all(np.diag(Tg) == 1.0) and np.all(np.tril(Ta, -1) == 0)
    assert np.all(Ka == np.diag(np.diag(Ka))) and np.all(Kg == np.diag(np.diag(Kg)))
    assert np.allclose(Cbs @ Cbs.T, np.eye(3), rtol=0, atol=1e-15) and np.linalg.det(Cbs) > 0
    assert 0 < res["frame_angle_rad"] < 1e-3  # a rotation of the size of the misalignments
    dth, dv = raw_samples()
    # imu_tk (Tedaldi et al. 2014; CalibratedTriad_::unbiasNormalize): X' = T K (X - B), in its body frame
    acc_b = (Ta @ Ka @ (dv / DT - Ba).T).T
    gyr_b = (Tg @ Kg @ (dth / DT - Bg).T).T
    cdth, cdv = inscal_compensated(imu, dth, dv)
    close(gyr_b @ Cbs * DT, cdth)  # x_s = C_b_s^T x_b
    close(acc_b @ Cbs * DT, cdv)
    # the g-sensitivity is named when there is one
    q = params_file(tmp_path / "q.toml", LINEAR)
    code, out, err = invoke("export", q, "--format", "imu-tk", "--out", tmp_path / "q_acc.calib")
    assert code == 0 and "imu-tk cannot hold gyro_g_sensitivity" in err, err


def test_kfgins_round_trip_and_dropped_terms(tmp_path):
    diag = ImuErrors(gyro_scale_factor=LINEAR.gyro_scale_factor, gyro_bias=LINEAR.gyro_bias,
                     accel_scale_factor=LINEAR.accel_scale_factor, accel_bias=LINEAR.accel_bias)
    p = params_file(tmp_path / "p.toml", diag, sigma={"gyro_bias": [0.01, 0.02, 0.03]})
    code, out, err = invoke("export", p, "--format", "kf-gins", "--out", tmp_path / "kf.yaml", "--json")
    assert code == 0, err
    doc = YAML(typ="safe", pure=True).load((tmp_path / "kf.yaml").read_text())
    bg = np.array(doc["initgyrbias"]) * DEG / HOUR  # deg/h
    ba = np.array(doc["initaccbias"]) * 1e-5  # mGal
    sg, sa = np.array(doc["initgyrscale"]) * 1e-6, np.array(doc["initaccscale"]) * 1e-6  # ppm
    np.testing.assert_allclose(doc["initbgstd"], [0.01, 0.02, 0.03], rtol=1e-15)
    dth, dv = raw_samples()
    # KF-GINS (GIEngine::imuCompensate): dth_c = (dth - b_g dt) / (1 + s_g), dv_c = (dv - b_a dt) / (1 + s_a)
    cdth, cdv = inscal_compensated(diag, dth, dv)
    close((dth - bg * DT) / (1 + sg), cdth)
    close((dv - ba * DT) / (1 + sa), cdv)
    # a calibration with misalignments: exported, the terms KF-GINS cannot hold named (and warned)
    q = params_file(tmp_path / "q.toml", LINEAR)
    code, out, err = invoke("export", q, "--format", "kf-gins", "--out", tmp_path / "kq.yaml")
    assert code == 0 and "cannot hold gyro_misalignment, gyro_g_sensitivity, accel_misalignment" in err
    assert "NOT representable" in (tmp_path / "kq.yaml").read_text()


def test_refusals_are_one_line_and_write_nothing(tmp_path):
    p = params_file(tmp_path / "p.toml", LINEAR)
    before = set(tmp_path.iterdir())
    for args, needle in ((("--format", "c", "--out", tmp_path / "x.txt"), "give --out NAME.c"),
                         (("--format", "csv", "--out", tmp_path / "x.csv"), "a parameter file exports as"),
                         (("--format", "kalibr", "--out", tmp_path / "no" / "x.yaml"), "does not exist"),
                         (("--format", "imu-tk", "--out", tmp_path / "x.calib"), "give --out NAME_acc.calib")):
        code, out, err = invoke("export", p, *args)
        assert code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    (tmp_path / "x.yaml").write_text("keep")
    code, _, err = invoke("export", p, "--format", "kalibr", "--out", tmp_path / "x.yaml")
    assert code == 2 and (tmp_path / "x.yaml").read_text() == "keep"
    assert set(tmp_path.iterdir()) == before | {tmp_path / "x.yaml"}


@pytest.mark.parametrize("fmt", ["kalibr", "imucal", "imu-tk"])
def test_nonlinear_terms_are_named(tmp_path, fmt):
    imu = LINEAR.replace(accel_nonlinearity=np.array([20, -15, 10]) * UG / G0 ** 2, time_asynchrony=1e-4)
    p = params_file(tmp_path / "p.toml", imu)
    code, out, err = invoke("export", p, "--format", fmt, "--out", tmp_path / "o_acc.calib", "--json")
    assert code == 0, err
    g = ["gyro_g_sensitivity"] if fmt == "imu-tk" else []
    assert json.loads(out)["dropped"] == g + ["accel_nonlinearity", "time_asynchrony"]
