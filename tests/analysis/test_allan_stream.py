"""The streamed Allan deviation (bounded memory) equals allantools.oadev (the oracle); ``inscal allan`` is a
view of the noise engine: its ARW is ``inscal noise``'s, to the last printed digit."""

import json
import math

import numpy as np
import pytest

from inscal.analysis.allan import octave_taus
from typer.testing import CliRunner

from inscal import io
from inscal.core import units
from inscal.analysis.allan import StreamingAllan, allan
from inscal.cli.app import app
from inscal.cli.allan import run_allan
from inscal.cli.noise import run_noise
from inscal.core.earth import Site

RATE = 100.0


def _series(n, seed=1):
    rng = np.random.default_rng(seed)
    white = rng.normal(0, 1e-6, (n, 3))
    walk = np.cumsum(rng.normal(0, 1e-9, (n, 3)), axis=0)
    return white + walk + np.array([7e-7, 3e-6, 0.098])  # biases (the last one like gravity in dvel)


def _oadev(x, taus=None):
    """allantools.oadev of each column (the oracle; inscal does not run it)."""
    import allantools

    taus = octave_taus(x.shape[0], RATE) if taus is None else taus
    out = [allantools.oadev(x[:, c] * RATE, rate=RATE, data_type="freq", taus=taus) for c in range(x.shape[1])]
    return out[0][0], np.stack([o[1] for o in out], axis=1), np.stack([o[2] for o in out], axis=1)


@pytest.mark.parametrize("n, chunk", [(16, 7), (17, 1 << 20), (1000, 7), (1000, 4096), (12345, 4096),
                                      (200_003, 4096), (200_003, 1 << 20)])
def test_streaming_equals_allantools(n, chunk):
    x = _series(n)
    t_ref, ad_ref, err_ref = _oadev(x)
    ref = allan(x, RATE)  # the in-memory face of the engine
    acc = StreamingAllan(n, RATE, 3, piece=1024)
    for k in range(0, n, chunk):
        acc.update(x[k:k + chunk])
    r = acc.result()
    assert np.array_equal(r.taus, t_ref) and np.array_equal(ref.taus, t_ref)
    np.testing.assert_allclose(r.adev, ad_ref, rtol=1e-9)
    np.testing.assert_allclose(r.adev_err, err_ref, rtol=1e-9)
    np.testing.assert_allclose(ref.adev, ad_ref, rtol=1e-9)
    np.testing.assert_allclose(r.white, ref.white, rtol=1e-9)  # chunking moves the sums' last digits
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
    """The oracle: the whole record in memory, allantools on the window."""
    rec = io.read_record(path)
    sel = (rec.time > start) & (rec.time <= (stop if stop is not None else np.inf))
    return rec, sel, _oadev(rec.dtheta[sel])[1], _oadev(rec.dvel[sel])[1]


@pytest.mark.parametrize("rotate", [False, True])
@pytest.mark.parametrize("start, stop", [(0.0, None), (12.3, 2000.0), (100.0, 1111.11)])
def test_run_allan_matches_in_memory(tmp_path_factory, rotate, start, stop, monkeypatch):
    path = tmp_path_factory.getbasetemp() / f"stream_{rotate}.h5"
    if not path.exists():
        _record(path, 250_000, rotate)
    import inscal.analysis.allan as aa

    real = aa.stream_allan
    monkeypatch.setattr(aa, "stream_allan", lambda data, win: real(data, win, chunk_size=30_011))  # many chunks
    res = run_allan(path, start, stop, model="WN")  # a fixed model: the curves are what this test checks
    rec, sel, g, a = _in_memory(path, start, stop)
    assert res["window_s"] == pytest.approx([rec.time[sel][0] - 1 / RATE, rec.time[sel][-1]], rel=1e-12)
    np.testing.assert_allclose(res["gyro_adev_deg_h"], units.from_si(g, "deg/h").T, rtol=1e-6)
    np.testing.assert_allclose(res["accel_adev_ug"], units.from_si(a, "ug").T, rtol=1e-6)
    # B: sigma_min / 0.664 over the octave taus of at least 30 degrees of freedom, read where it says
    edf = np.asarray(res["edf"])
    keep = edf >= 30
    i = np.argmin(a[keep], axis=0)
    np.testing.assert_allclose(res["accel_bias_instability_ug"], units.from_si(a[keep].min(axis=0) / 0.664282, "ug"),
                               rtol=1e-5)
    np.testing.assert_allclose(res["accel_bias_instability_tau_s"], np.asarray(res["taus_s"])[keep][i])
    np.testing.assert_allclose(res["accel_bias_instability_edf"], edf[keep][i])
    assert bool(res["warnings"]) == rotate and all("not static" in w for w in res["warnings"])


def test_allan_cli_window_errors(tmp_path):
    path = _record(tmp_path / "r.h5", 3000)
    runner = CliRunner()
    r = runner.invoke(app, ["allan", str(path), "--start", "25", "--json"])
    assert r.exit_code == 2 and "only 500 samples" in r.stderr
    r = runner.invoke(app, ["allan", str(path), "--start", "nan", "--json"])
    assert r.exit_code == 2 and "finite" in r.stderr
    r = runner.invoke(app, ["allan", str(path), "--json", "--model", "WN"])
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
    res = run_allan(path, 0.0, None, model="WN")
    assert res["gyro_bias_instability_upper_bound"] == [True] * 3
    assert res["accel_bias_instability_upper_bound"] == [True] * 3
    r = CliRunner().invoke(app, ["allan", str(path), "--model", "WN"])
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
    res = run_allan(tmp_path / "rrw.h5", 0.0, None, model="WN+RW")
    assert not any(res["gyro_bias_instability_upper_bound"])


def test_allan_and_noise_print_the_same_arw(tmp_path):
    """One engine: ``inscal allan``'s ARW and VRW are the white-noise terms of the model ``inscal noise``
    identifies (auto), with the same 95 % interval, so the two commands print the same digits."""
    path = _record(tmp_path / "r.h5", 12_000, seed=4)
    res = run_allan(path)
    nz = run_noise(path, channels="gx,ay")
    for ch, key, k in (("gx", "arw_deg_rth", 0), ("ay", "vrw_ug_rthz", 1)):
        p = next(c for c in nz["channels"] if c["channel"] == ch)["parameters"]["WN.n"]
        assert res[key][k] == p["value"] and f"{res[key][k]:.4g}" == f"{p['value']:.4g}"
        assert res[key.replace("_", "_lower_95_", 1)][k] == p["lower_95"]
    assert res["gyro_white_source"][0].startswith("WN term of ") and res["model_asked"] == "auto"
