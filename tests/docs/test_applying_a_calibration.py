"""docs/guide/applying-a-calibration.md: the page's claims checked against the code -- its NumPy function
(extracted from the page and run) equals inscal's compensation to 1e-12 and inverts the simulator's
measurement form; its table of parameters, units and SI factors is the registry's; its inscal snippet
runs; the symbols and index layouts it states are those of the error model."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from inscal.core import units
from inscal.core.error_model import PARAMETERS, ImuErrors, cross_matrix, errors_to_field, off_diagonal
from inscal.core.units import ARCSEC, DEG, G0, HOUR

PAGE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "applying-a-calibration.md"
TEXT = PAGE.read_text(encoding="utf-8")
BLOCKS = re.findall(r"```python\n(.*?)```", TEXT, flags=re.S)
UG = 1e-6 * G0
IMU = ImuErrors(
    gyro_scale_factor=[120e-6, -80e-6, 200e-6], gyro_misalignment=np.array([15, -7, 30, 9, -24, 6]) * ARCSEC,
    gyro_bias=np.array([0.5, -0.3, 0.2]) * DEG / HOUR,
    gyro_g_sensitivity=np.array([[0.1, 0.02, -0.03], [0.01, -0.2, 0.04], [0.02, 0.01, 0.15]]) * DEG / HOUR / G0,
    accel_scale_factor=[150e-6, -90e-6, 60e-6], accel_misalignment=np.array([-18, 4, 26, -3, 10, 12]) * ARCSEC,
    accel_bias=np.array([80, -120, 50]) * UG, accel_nonlinearity=np.array([20, -15, 10]) * UG / G0 ** 2,
    accel_cross_coupling=np.array([5, -4, 3, 2, -6, 7]) * UG / G0 ** 2)
DT = 0.005


def page_function():
    block = next(b for b in BLOCKS if "def compensate(" in b)
    assert len(block.strip().splitlines()) <= 16  # short enough to copy
    ns: dict = {}
    exec(compile(block, str(PAGE), "exec"), ns)
    return ns["compensate"]


def page_args(imu):
    return dict(Kg=imu.gyro_scale_factor, Eg=imu.gyro_misalignment, eps=imu.gyro_bias, G=imu.gyro_g_sensitivity,
                Ka=imu.accel_scale_factor, Ea=imu.accel_misalignment, nab=imu.accel_bias,
                K2=imu.accel_nonlinearity, Kx=imu.accel_cross_coupling)


def samples(n=500, seed=11):
    rng = np.random.default_rng(seed)
    w = rng.uniform(-3.0, 3.0, (n, 3))
    f = rng.normal(0.0, 20.0, (n, 3)) + [0.0, 0.0, G0]  # up to ~8 g: the nonlinear terms show
    return w, f


def test_the_pages_function_equals_inscals_compensation():
    comp = page_function()
    w, f = samples()
    ng, na = IMU.measure(w, f)
    dth, dv = ng * DT, na * DT
    got = comp(dth, dv, DT, **page_args(IMU))
    want = IMU.compensate_increments(DT, dth, dv)
    for g, x in zip(got, want):
        assert np.abs(g - x).max() <= 1e-12 * np.abs(x).max()
    # and it inverts the measurement form (what the simulator applies): the truth back
    assert np.abs(got[0] - w * DT).max() <= 1e-12 * np.abs(w * DT).max()
    assert np.abs(got[1] - f * DT).max() <= 1e-12 * np.abs(f * DT).max()
    # the nonlinear terms matter at this size: leaving them out misses by far more
    lin = comp(dth, dv, DT, **{**page_args(IMU), "K2": np.zeros(3), "Kx": np.zeros(6)})
    assert np.abs(lin[1] - f * DT).max() > 1e4 * 1e-12 * np.abs(f * DT).max()


def test_the_pages_table_is_the_parameter_registry():
    rows = re.findall(r"^\| `(\w+)` \| (.+?) \| (.+?) \| (.+?) \| ([0-9.e+-]+)", TEXT, flags=re.M)
    table = {name: (shape.strip(), unit.strip(), float(factor)) for name, _sym, shape, unit, factor in rows}
    assert set(table) == set(PARAMETERS)
    for name, (_obj, _attr, kind, unit, shape) in PARAMETERS.items():
        t_shape, t_unit, t_factor = table[name]
        assert t_unit == unit, name
        assert t_shape == (" x ".join(map(str, shape)) if shape else "1"), name
        assert t_factor == pytest.approx(units.FACTOR[unit], rel=1e-14), name


def test_the_stated_layouts_are_the_error_models():
    # E[0,1] = xy, E[0,2] = xz, E[1,0] = yx, E[1,2] = yz, E[2,0] = zx, E[2,1] = zy
    e = off_diagonal([1, 2, 3, 4, 5, 6])
    assert [e[0, 1], e[0, 2], e[1, 0], e[1, 2], e[2, 0], e[2, 1]] == [1, 2, 3, 4, 5, 6]
    assert "E[0,1] = xy, E[0,2] = xz, E[1,0] = yx,\nE[1,2] = yz, E[2,0] = zx, E[2,1] = zy" in TEXT
    np.testing.assert_array_equal(cross_matrix([1, 2, 3, 4, 5, 6]), [[1, 2, 0], [3, 0, 4], [0, 5, 6]])
    assert "Kx = [[xy, xz, 0], [yx, 0, yz], [0, zx, zy]]" in TEXT
    np.testing.assert_allclose(IMU.M_g, (np.eye(3) + np.diag(IMU.gyro_scale_factor))
                               @ (np.eye(3) + off_diagonal(IMU.gyro_misalignment)), rtol=0, atol=0)


def test_the_pages_inscal_snippet_runs(tmp_path, monkeypatch):
    block = next(b for b in BLOCKS if "load_params" in b)
    (tmp_path / "params.toml").write_text(tomli_w.dumps({"kind": "inscal-parameters", "schema_version": 1,
                                                         "method": "manual", "parameters": errors_to_field(IMU)}))
    monkeypatch.chdir(tmp_path)
    w, f = samples(50)
    ng, na = IMU.measure(w, f)
    ns = {"dt": DT, "dth": ng * DT, "dv": na * DT}
    exec(compile(block, str(PAGE), "exec"), ns)
    np.testing.assert_allclose(ns["dth_c"], w * DT, rtol=0, atol=1e-12 * np.abs(w * DT).max())
    np.testing.assert_allclose(ns["dv_c"], f * DT, rtol=0, atol=1e-12 * np.abs(f * DT).max())
