"""inscal simulate on the thermal scenarios: the record's temperature and thermal truth, and the summary."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app

runner = CliRunner()


def test_simulate_warmup_writes_temperature_and_says_so(tmp_path):
    out = tmp_path / "w.h5"
    r = runner.invoke(app, ["simulate", "thermal-warmup", "--duration-h", "0.25", "--out", str(out), "--seed", "4", "--json"])
    assert r.exit_code == 0, r.stdout
    s = json.loads(r.stdout)
    t = s["temperature"]
    # 20 -> 45 degC with tau = 20 min: after 15 min, 45 - 25 exp(-0.75) = 33.19 degC; the largest rate at the start
    assert t["min_c"] == pytest.approx(20.0) and t["max_c"] == pytest.approx(45.0 - 25.0 * np.exp(-0.75), rel=1e-9)
    assert t["max_rate_c_per_min"] == pytest.approx(25.0 / 20.0, rel=1e-3)  # sampled on a 2001-point grid
    assert t["thermal_model"] is True and t["sensors"] == ["imu"]
    rec = io.read_record(out)
    assert rec.temperature.values.shape == (901, 1)
    assert rec.truth.thermal.t_ref == 20.0
    r = runner.invoke(app, ["simulate", "thermal-warmup", "--duration-h", "0.25", "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 0 and "temperature 20.0 .. 33.2 degC" in r.stdout and "/truth/thermal" in r.stdout


def test_simulate_without_temperature_has_no_temperature_entry(tmp_path):
    r = runner.invoke(app, ["simulate", "static", "--duration-h", "0.01", "--out", str(tmp_path / "s.h5"), "--json"])
    assert r.exit_code == 0 and "temperature" not in json.loads(r.stdout)
    assert io.read_record(tmp_path / "s.h5").temperature is None
