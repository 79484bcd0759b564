"""The streamed Allan deviation (bounded memory) equals the in-memory one (allantools.oadev)."""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal.core import units
from inscal.analysis.allan import StreamingAllan, allan
from inscal.cli.app import app
from inscal.analysis.allan import MotionStats
from inscal.cli.allan import run_allan
from inscal.core.earth import Site

RATE = 100.0


def _series(n, seed=1):
    rng = np.random.default_rng(seed)
    white = rng.normal(0, 1e-6, (n, 3))
    walk = np.cumsum(rng.normal(0, 1e-9, (n, 3)), axis=0)
    return white + walk + np.array([7e-7, 3e-6, 0.098])  # biases (the last one like gravity in dvel)


@pytest.mark.parametrize("n, chunk", [(16, 7), (17, 1 << 20), (1000, 7), (1000, 4096), (12345, 4096),
                                      (200_003, 4096), (200_003, 1 << 20)])
def test_streaming_equals_allantools(n, chunk):
    x = _series(n)
    ref = allan(x, RATE)
    acc = StreamingAllan(n, RATE, 3, piece=1024)
    for k in range(0, n, chunk):
        acc.update(x[k:k + chunk])
    r = acc.result()
    assert np.array_equal(r.taus, ref.taus)
    np.testing.assert_allclose(r.adev, ref.adev, rtol=1e-9)
    np.testing.assert_allclose(r.adev_err, ref.adev_err, rtol=1e-9)
    np.testing.assert_allclose(r.white, ref.white, rtol=1e-9)
    np.testing.assert_allclose(r.bias_instability, ref.bias_instability, rtol=1e-9)
    np.testing.assert_array_equal(r.tau_bi, ref.tau_bi)


def test_streaming_guards():
    acc = StreamingAllan(100, RATE)
    with pytest.raises(ValueError, match="announced"):
        acc.update(np.zeros((101, 3)))
    with pytest.raises(ValueError, match="NaN"):
        acc.update(np.full((5, 3), np.nan))
    acc.update(np.zeros((50, 3)))
    with pytest.raises(ValueError, match="fed 50"):
        acc.result()
    with pytest.raises(ValueError, match="16"):
        StreamingAllan(10, RATE)


def _record(path, n, rotate=False, seed=0):
    rng = np.random.default_rng(seed)
    dt = 1 / RATE
    t = np.arange(1, n + 1) * dt
    dth = rng.normal(0, 5.8e-6 * math.sqrt(dt), (n, 3)) + np.array([0, 5e-5, 5e-5]) * dt
    gim = np.zeros((n, 2))
    if rotate:
        dth[:, 2] += math.radians(10) * dt
        gim[:, 1] = np.cumsum(dth[:, 2])
    dv = rng.normal(0, 1e-5 * math.sqrt(dt), (n, 3)) + np.array([0, 0, 9.8]) * dt
    io.write_record(path, io.Record(t, dth, dv, gim, RATE, Site(math.radians(45), 0.0, 0.0), scenario="stream"))
    return path


def _in_memory(path, start, stop):
    """The former implementation: the whole record in memory, allantools on the window."""
    rec = io.read_record(path)
    sel = (rec.time > start) & (rec.time <= (stop if stop is not None else np.inf))
    g, a = allan(rec.dtheta[sel], RATE), allan(rec.dvel[sel], RATE)
    return rec, sel, g, a


@pytest.mark.parametrize("rotate", [False, True])
@pytest.mark.parametrize("start, stop", [(0.0, None), (12.3, 2000.0), (100.0, 1111.11)])
def test_run_allan_matches_in_memory(tmp_path_factory, rotate, start, stop, monkeypatch):
    path = tmp_path_factory.getbasetemp() / f"stream_{rotate}.h5"
    if not path.exists():
        _record(path, 250_000, rotate)
    import inscal.analysis.allan as aa

    real = aa.stream_allan
    monkeypatch.setattr(aa, "stream_allan", lambda data, win: real(data, win, chunk_size=30_011))  # many chunks
    res = run_allan(path, start, stop)
    rec, sel, g, a = _in_memory(path, start, stop)
    assert res["window_s"] == pytest.approx([rec.time[sel][0] - 1 / RATE, rec.time[sel][-1]], rel=1e-12)
    np.testing.assert_allclose(res["gyro_adev_deg_h"], units.from_si(g.adev, "deg/h").T, rtol=1e-6)
    np.testing.assert_allclose(res["accel_adev_ug"], units.from_si(a.adev, "ug").T, rtol=1e-6)
    np.testing.assert_allclose(res["arw_deg_rth"], units.from_si(g.white, "deg/sqrt(h)"), rtol=1e-6)
    np.testing.assert_allclose(res["accel_bias_instability_ug"], units.from_si(a.bias_instability, "ug"), rtol=1e-6)
    # the motion check sees the same blocks as on the whole window
    mot = MotionStats(int(sel.sum()), RATE)
    mot.update(rec.dtheta[sel], rec.gimbal[sel])
    assert res["warnings"] == ([mot.warning()] if mot.warning() else [])
    assert bool(res["warnings"]) == rotate


def test_allan_cli_window_errors(tmp_path):
    path = _record(tmp_path / "r.h5", 3000)
    runner = CliRunner()
    r = runner.invoke(app, ["allan", str(path), "--start", "25", "--json"])
    assert r.exit_code == 2 and "only 500 samples" in r.stderr
    r = runner.invoke(app, ["allan", str(path), "--start", "nan", "--json"])
    assert r.exit_code == 2 and "finite" in r.stderr
    r = runner.invoke(app, ["allan", str(path), "--json"])
    assert r.exit_code == 0 and len(json.loads(r.stdout)["taus_s"]) == 9


def test_nan_in_window_is_one_line(tmp_path):
    import h5py

    path = _record(tmp_path / "r.h5", 3000)
    with h5py.File(path, "a") as h5:
        h5["dvel"][2500, 1] = np.nan
    r = CliRunner().invoke(app, ["allan", str(path)])
    assert r.exit_code == 2 and "dvel has NaN" in r.stderr and "sample 2500" in r.stderr


def test_bias_instability_without_flat_bottom_is_an_upper_bound(tmp_path):
    """White noise only: the deviation falls to the longest tau, so the 'bias instability'
    read at the minimum is only an upper bound, flagged in the JSON and shown as '< x'."""
    path = _record(tmp_path / "white.h5", 60_000)
    res = run_allan(path, 0.0, None)
    assert res["gyro_bias_instability_upper_bound"] == [True] * 3
    assert res["accel_bias_instability_upper_bound"] == [True] * 3
    r = CliRunner().invoke(app, ["allan", str(path)])
    assert r.exit_code == 0 and "< " in r.stdout and "not measured" in r.stdout
    assert "ARW [deg/rt(h)]" in r.stdout  # the units of the table (Rich markup ate them once)
    # a flicker floor (a slowly wandering bias) gives a measured minimum
    rng = np.random.default_rng(3)
    n, dt = 200_000, 1 / RATE
    walk = np.cumsum(rng.normal(0, 2e-7, (n, 3)), axis=0)  # rad/s rate random walk: the deviation rises again
    rec = io.read_record(path)
    dth = rng.normal(0, 5.8e-6 * math.sqrt(dt), (n, 3)) + walk * dt
    t = np.arange(1, n + 1) * dt
    io.write_record(tmp_path / "rrw.h5", io.Record(t, dth, rec.dvel[:1].repeat(n, 0), np.zeros((n, 2)), RATE, rec.site,
                                                   scenario="rrw"))
    res = run_allan(tmp_path / "rrw.h5", 0.0, None)
    assert not any(res["gyro_bias_instability_upper_bound"])
