"""``inscal calibrate --method multi-position`` on a simulated hand-held record (``inscal simulate
handheld-mems``) with the defaults of the method (0.25-s settling, 2-s still poses: no --settle-s or
--min-static-s), within 3.5 sigma of the truth; ``--quadratic`` (the quadratic accelerometer terms) and
its refusal for the other methods (one line, exit 2, nothing written); the result exported in imucal's
(Ferraris) and imu_tk's conventions, each tool's formula (written here from its documentation) giving
inscal's compensated increments back to 1e-12."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.io.paramfile import load_params
from inscal.runs.calibration import CalibrationSetup
from inscal.lab.record import calibration_options

runner = CliRunner()
DT = 0.02


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    d = tmp_path_factory.mktemp("handheld")
    code, _, err = invoke("simulate", "handheld-mems", "--rate-hz", "50", "--seed", "3", "--out", d / "h.h5")
    assert code == 0, err
    return d / "h.h5"


def raw_samples(n=300, seed=5):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.0, 2.0, (n, 3)) * DT, (rng.normal(0.0, 1.0, (n, 3)) + [0.0, 0.0, 9.8]) * DT


def within(rep, k=3.5):
    for name, e in rep["parameters"].items():
        err, sig = np.array(e["error"], float), np.array([np.nan if s is None else s for s in e["sigma"]], float)
        free = np.isfinite(sig)
        assert np.all(np.abs(err[free]) < k * sig[free]), (name, err / sig)


def imucal_round_trip(params, out):
    code, o, err = invoke("export", params, "--format", "imucal", "--out", out, "--json")
    assert code == 0, err
    doc = json.loads(out.read_text())
    K_a, R_a, b_a, K_g, R_g, K_ga, b_g = (np.array(doc[k]) for k in ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g"))
    dth, dv = raw_samples()
    # imucal (Ferraris 1995): acc = R_a^-1 K_a^-1 (acc_raw - b_a); gyr = R_g^-1 K_g^-1 (gyr_raw - K_ga acc - b_g)
    acc = np.linalg.solve(K_a @ R_a, (dv / DT - b_a).T).T
    gyr = np.linalg.solve(K_g @ R_g, (dth / DT - acc @ K_ga.T - b_g).T).T
    return json.loads(o), np.radians(gyr) * DT, acc * DT


def imutk_round_trip(params, out):
    code, o, err = invoke("export", params, "--format", "imu-tk", "--out", out, "--json")
    assert code == 0, err
    res = json.loads(o)
    tri = [np.array(open(f).read().split(), float) for f in res["files"]]  # imu_tk's load: 9 + 9 + 3 numbers
    (Ta, Ka, Ba), (Tg, Kg, Bg) = ((x[:9].reshape(3, 3), x[9:18].reshape(3, 3), x[18:]) for x in tri)
    dth, dv = raw_samples()
    # imu_tk (Tedaldi 2014): X' = T K (X - B) in its body frame b; x_s = C_b_s^T x_b
    Cbs = np.array(res["C_b_s"])
    return res, (Tg @ Kg @ (dth / DT - Bg).T).T @ Cbs * DT, (Ta @ Ka @ (dv / DT - Ba).T).T @ Cbs * DT


def close(a, b, rel=1e-12):
    assert np.abs(a - b).max() <= rel * np.abs(b).max()


def test_hand_held_record_with_the_method_defaults_and_its_exports(record, tmp_path):
    out = tmp_path / "p.toml"
    code, o, err = invoke("calibrate", record, "--method", "multi-position", "--out", out, "--json")
    assert code == 0, err
    rep = json.loads(o)
    assert rep["fit"]["consistent"] and "accel_nonlinearity" not in rep["parameters"]
    within(rep)
    imu, _, _ = load_params(out)
    dth, dv = raw_samples()
    cdth, cdv = imu.compensate_increments(DT, dth, dv)
    for export, name in ((imucal_round_trip, "cal.json"), (imutk_round_trip, "imu_acc.calib")):
        res, w, f = export(out, tmp_path / name)
        assert res["dropped"] == []
        close(w, cdth)
        close(f, cdv)


def test_quadratic_terms(record, tmp_path):
    out = tmp_path / "q.toml"
    code, o, err = invoke("calibrate", record, "--method", "multi-position", "--quadratic", "--out", out, "--json")
    assert code == 0, err
    rep = json.loads(o)
    k2 = rep["parameters"]["accel_nonlinearity"]
    assert k2["unit"] == "ug/g^2" and all(s is not None and s > 0 for s in k2["sigma"])
    within(rep)
    res, _, _ = imutk_round_trip(out, tmp_path / "q_acc.calib")
    assert res["dropped"] == ["accel_nonlinearity"]


@pytest.mark.parametrize("method", ["ferraris", "n25"])
def test_quadratic_refused_for_other_methods(record, tmp_path, method):
    out = tmp_path / "z.toml"
    code, _, err = invoke("calibrate", record, "--method", method, "--quadratic", "--out", out)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and f"--quadratic applies to --method multi-position, not {method}" in err
    assert list(tmp_path.iterdir()) == []


def test_defaults_are_the_methods_own():
    # a turntable method keeps its 1-s / 20-s windows (and the database's options, so its hashes)
    assert CalibrationSetup("n25").options() == calibration_options("n25", settle=1.0, min_static=20.0)
    assert CalibrationSetup("multi-position").window_options == {"settle": 0.25, "min_static": 1.0}
    assert CalibrationSetup("ferraris", settle=0.5).window_options == {"settle": 0.5, "min_static": 2.0}
    assert CalibrationSetup("multi-position", quadratic=True).options()["quadratic"] is True
    assert "--min-static-s must be" in CalibrationSetup("ferraris", min_static=float("nan")).problem()
    # the stated hand tremor: multi-position only, in deg/s rms, SI for the method, in the database's options
    assert CalibrationSetup("multi-position", tremor=2.0).window_options["tremor"] == pytest.approx(math.radians(2.0))
    assert CalibrationSetup("multi-position", tremor=2.0).options()["tremor_dps"] == 2.0
    assert "--tremor-dps applies to --method multi-position" in CalibrationSetup("ferraris", tremor=1.0).problem()
    assert "--tremor-dps must be" in CalibrationSetup("multi-position", tremor=-1.0).problem()
