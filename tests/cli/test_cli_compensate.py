"""inscal compensate: compensating with the true parameters gives back the true increments."""

import json

import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal.sim.simulate import scenario_from_record
from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import errors_to_field
from inscal.sim.simulate import simulate

runner = CliRunner()


def test_compensate_with_true_parameters_round_trip(tmp_path):
    scen = tmp_path / "nf.toml"
    scen.write_text('base = "s16"\n[noise]\narw = 0\nvrw = 0\n')  # S16 extended model, noise-free
    rec = tmp_path / "r.h5"
    assert runner.invoke(app, ["simulate", str(scen), "--out", str(rec)]).exit_code == 0
    r = io.read_record(rec)
    params = tmp_path / "true.toml"
    doc = {"kind": "inscal-parameters", "schema_version": 1, "method": "truth",
           "parameters": errors_to_field(r.truth.imu, r.truth.gimbal)}
    params.write_text(tomli_w.dumps(doc))
    out = tmp_path / "c.h5"
    res = runner.invoke(app, ["compensate", str(rec), "--params", str(params), "--out", str(out), "--json"])
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["samples"] == r.n_samples
    c = io.read_record(out)
    assert c.truth is None
    truth = simulate(scenario_from_record(r), keep_truth=True)
    static = np.all(np.abs(truth.true_dtheta) < 1e-6, axis=1)  # dwell samples (Earth rate only)
    assert static.sum() > 300000
    assert np.abs(c.dtheta[static] - truth.true_dtheta[static]).max() < 1e-16  # rad per sample
    assert np.abs(c.dvel[static] - truth.true_dvel[static]).max() < 1e-14  # m/s per sample
    # refusals: existing output, bad parameter file
    res = runner.invoke(app, ["compensate", str(rec), "--params", str(params), "--out", str(out)])
    assert res.exit_code != 0 and "exists" in res.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "inscal-parameters"\nschema_version = 99\n[parameters.gyro_bias]\nvalue=[0,0,0]\nunit="deg/h"\n')
    res = runner.invoke(app, ["compensate", str(rec), "--params", str(bad), "--out", str(tmp_path / "d.h5")])
    assert res.exit_code != 0 and "schema_version 99" in res.stderr and not (tmp_path / "d.h5").exists()
