"""``inscal export PARAMS --format c``: the generated C99 compiled with the system compiler (strict, no
warnings) and run on a simulated record, equal to ``inscal compensate`` to 1e-12 relative, with every
term of the model (S16 extended accelerometer terms, g-sensitivity, lever arms, time asynchrony) and a
thermal model (polynomials, misalignment, temperature-rate term, clamped range)."""

from __future__ import annotations

import math
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import ImuErrors, ImuNoise, errors_to_field
from inscal.core.thermal import thermal_to_field
from inscal.core.turntable import Move, RotationPath
from inscal.core.units import ARCSEC, DEG, G0, HOUR
from inscal.nav.stream import ThermalCompensation
from inscal.sim import scenarios
from inscal.sim.simulate import write_simulation
from inscal.sim.thermal import Piece, TemperatureProfile

runner = CliRunner()
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
UG = 1e-6 * G0

#: every term of the error model, at sizes where each one shows in the compensated increments
IMU = ImuErrors(
    gyro_scale_factor=[120e-6, -80e-6, 200e-6], gyro_misalignment=np.array([5, -7, 3, 9, -4, 6]) * ARCSEC,
    gyro_bias=np.array([0.05, -0.03, 0.02]) * DEG / HOUR,
    gyro_g_sensitivity=np.array([[0.01, 0.002, -0.003], [0.001, -0.02, 0.004], [0.002, 0.001, 0.015]]) * DEG / HOUR / G0,
    accel_scale_factor=[150e-6, -90e-6, 60e-6], accel_misalignment=np.array([-8, 4, 6, -3, 10, 2]) * ARCSEC,
    accel_bias=np.array([80, -120, 50]) * UG, accel_nonlinearity=np.array([20, -15, 10]) * UG / G0 ** 2,
    accel_cross_coupling=np.array([5, -4, 3, 2, -6, 7]) * UG / G0 ** 2,
    accel_lever_arm=np.array([[0.03, 0.004, -0.002], [0.001, -0.025, 0.003], [-0.002, 0.001, 0.02]]),
    time_asynchrony=3e-4)
PROFILE = TemperatureProfile(15.0, (Piece("hold", duration_s=20.0), Piece("ramp", target_c=40.0, rate_c_per_min=30.0)))


def invoke(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "comp.h"
/* reads n, dt, then n rows of dth[3] dv[3] T dTdt (doubles); writes n rows of the compensated dth dv */
int main(int argc, char **argv)
{
    FILE *in = fopen(argv[1], "rb"), *out = fopen(argv[2], "wb");
    double head[2], *row, *ref, res[6];
    long n, k;
    (void)argc;
    if (!in || !out || fread(head, sizeof(double), 2, in) != 2) return 3;
    n = (long)head[0];
    row = malloc(sizeof(double) * 8 * (size_t)n);
    ref = malloc(sizeof(double) * 6 * (size_t)n);
    if (!row || !ref || fread(row, sizeof(double), 8 * (size_t)n, in) != 8 * (size_t)n) return 4;
    for (k = 0; k < n; ++k) {
        double *r = row + 8 * k;
        if (inscal_to_reference(head[1], r, r + 3, r[6], r[7], ref + 6 * k, ref + 6 * k + 3) == INSCAL_OUT_OF_RANGE)
            return 5;
    }
    for (k = 0; k < n; ++k) {
        const double *p = k > 0 ? ref + 6 * (k - 1) : NULL, *q = k + 1 < n ? ref + 6 * (k + 1) : NULL;
        inscal_compensate(head[1], ref + 6 * k, ref + 6 * k + 3, p, p ? p + 3 : NULL, q, q ? q + 3 : NULL,
                          res, res + 3);
        fwrite(res, sizeof(double), 6, out);
    }
    fclose(out);
    return 0;
}
"""


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A 100 s record at 50 Hz turning about both axes through a temperature ramp, its parameter file
    (thermal model clamped at 35 degC, below the ramp's end) and the record compensated by inscal."""
    d = tmp_path_factory.mktemp("cexport")
    path = RotationPath("c-test", (Move("outer", 90 * DEG, 20 * DEG, 5.0), Move("inner", -180 * DEG, 30 * DEG, 5.0),
                                   Move("outer", 450 * DEG, 60 * DEG, 3.0), Move("inner", 180 * DEG, 45 * DEG, 40.0)),
                        initial_dwell=10.0, closed=False)
    th = scenarios.thermal_model()
    th = replace(th, t_min=0.0, t_max=35.0, out_of_range="clamp",
                 gyro_misalignment=np.array([[1, -2, 0.5, 1.5, -1, 2]]) * 0.2 * ARCSEC,
                 accel_misalignment=np.array([[-1, 0.5, 2, -1.5, 1, -0.5]]) * 0.3 * ARCSEC,
                 gyro_bias_rate=np.array([0.002, -0.001, 0.003]) * DEG / HOUR * 60.0)
    sc = replace(scenarios.build("n25-rotmod", duration_s=100.0, rate_hz=50.0), path=path, imu=IMU, noise=ImuNoise(),
                 thermal=th, temperature=PROFILE)
    rec = d / "rec.h5"
    write_simulation(rec, sc, None)
    params = d / "p.toml"
    params.write_text(tomli_w.dumps({"kind": "inscal-parameters", "schema_version": 1, "method": "truth",
                                     "parameters": errors_to_field(IMU), "thermal": thermal_to_field(th)}))
    comp = d / "comp.h5"
    code, _, err = invoke("compensate", rec, "--params", params, "--out", comp)
    assert code == 0, err
    return d, rec, params, comp, th


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")
def test_generated_c_equals_inscal_compensate(case):
    d, rec_file, params, comp_file, th = case
    code, out, err = invoke("export", params, "--format", "c", "--out", d / "comp.c", "--json")
    assert code == 0, err
    assert (d / "comp.h").is_file() and "malloc" not in (d / "comp.c").read_text()
    (d / "main.c").write_text(DRIVER)
    exe = d / "run"
    cmd = [CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-o", str(exe), str(d / "comp.c"),
           str(d / "main.c"), "-lm"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rec = io.read_record(rec_file)
    n = rec.n_samples
    T, rate = ThermalCompensation(th, IMU, rec.temperature, rec.rate_hz).at(rec.time)
    assert T.max() > th.t_max + 3.0 and np.abs(rate).max() > 0.4  # the clamp and the rate term are exercised
    rows = np.column_stack([rec.dtheta, rec.dvel, T, rate])
    np.concatenate([[n, 1.0 / rec.rate_hz], rows.ravel()]).astype("<f8").tofile(d / "in.bin")
    r = subprocess.run([str(exe), str(d / "in.bin"), str(d / "out.bin")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = np.fromfile(d / "out.bin", dtype="<f8").reshape(n, 6)
    ref = io.read_record(comp_file)
    for k, want in ((0, ref.dtheta), (3, ref.dvel)):
        scale = np.abs(want).max(axis=0)
        err_rel = np.abs(got[:, k:k + 3] - want).max(axis=0) / scale
        print("C vs inscal compensate, max relative error", err_rel)
        assert np.all(err_rel < 1e-12), err_rel
    # and the compensation did something at every term's size: far from the raw increments
    assert np.abs(ref.dvel - rec.dvel).max() > 1e3 * 1e-12 * np.abs(rec.dvel).max()
    assert math.isfinite(float(got.sum()))


@pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")
def test_generated_c_without_thermal_or_neighbours(tmp_path):
    """A linear calibration (no thermal model, no lever arm, no asynchrony): the other branches of the
    template, compiled as strictly, equal ``ImuErrors.compensate_increments`` on random samples."""
    imu = IMU.replace(accel_lever_arm=np.zeros((3, 3)), time_asynchrony=0.0)
    params = tmp_path / "lin.toml"
    params.write_text(tomli_w.dumps({"kind": "inscal-parameters", "schema_version": 1, "method": "manual",
                                     "parameters": errors_to_field(imu)}))
    code, _, err = invoke("export", params, "--format", "c", "--out", tmp_path / "comp.c")
    assert code == 0, err
    assert "#define INSCAL_HAS_THERMAL 0" in (tmp_path / "comp.h").read_text()
    assert "#define INSCAL_NEEDS_NEIGHBOURS 0" in (tmp_path / "comp.h").read_text()
    (tmp_path / "main.c").write_text(DRIVER)
    exe = tmp_path / "run"
    r = subprocess.run([CC, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-o", str(exe),
                        str(tmp_path / "comp.c"), str(tmp_path / "main.c"), "-lm"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rng = np.random.default_rng(4)
    n, dt = 300, 0.01
    dth, dv = rng.uniform(-0.03, 0.03, (n, 3)), rng.normal(0, 0.2, (n, 3)) + [0, 0, 0.098]
    rows = np.column_stack([dth, dv, np.full(n, 99.0), np.zeros(n)])  # a temperature the C ignores
    np.concatenate([[n, dt], rows.ravel()]).astype("<f8").tofile(tmp_path / "in.bin")
    r = subprocess.run([str(exe), str(tmp_path / "in.bin"), str(tmp_path / "out.bin")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    got = np.fromfile(tmp_path / "out.bin", dtype="<f8").reshape(n, 6)
    want = np.column_stack(imu.compensate_increments(dt, dth, dv))
    assert np.abs(got - want).max(axis=0).max() <= 1e-12 * np.abs(want).max()
