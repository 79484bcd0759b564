"""noise.toml round trip and the exports of a noise model (Kalibr, KF-GINS, MATLAB): unit conversions
written out by hand here."""

import math

import numpy as np
import pytest

from inscal.core import noise_models as nm
from inscal.io.exports.noise import kalibr_imu_yaml, kfgins_imunoise, matlab_params, matlab_script
from inscal.io.noisefile import NoiseFileError, model_from_document, noise_document, read_noise, write_noise

D2R = math.pi / 180


def model():
    g = [nm.ChannelNoise(n, "gyro", (nm.Quantization(1e-7), nm.WhiteNoise(0.003 * D2R / 60 * (1 + i)),
                                     nm.RandomWalk(1e-9), nm.GaussMarkov(0.02 * D2R / 3600, 3600.0 * (1 + i))))
         for i, n in enumerate(("gx", "gy", "gz"))]
    a = [nm.ChannelNoise(n, "accel", (nm.WhiteNoise(0.03 / 60), nm.GaussMarkov(15e-5, 7200.0),
                                      nm.BiasInstability(1e-5, 5.0), nm.RateRamp(1e-9)))
         for n in ("ax", "ay", "az")]
    return nm.NoiseModel(tuple(g + a), 200.0)


def test_noise_toml_round_trip(tmp_path):
    m = model()
    write_noise(tmp_path / "n.toml", m, meta={"source": "x.h5"})
    back, meta = read_noise(tmp_path / "n.toml")
    assert meta == {"source": "x.h5"} and back.rate_hz == 200.0
    for c0, c1 in zip(m.channels, back.channels):
        assert c0.name == c1.name and c0.kind == c1.kind and c0.model == c1.model
        for t0, t1 in zip(c0.terms, c1.terms):
            for p in t0.params:
                assert getattr(t1, p) == pytest.approx(getattr(t0, p), rel=1e-14)
    doc = noise_document(m)
    assert doc["channel"][0]["term"][1] == {"type": "WN", "n": pytest.approx(0.003), "n_unit": "deg/sqrt(h)"}
    assert doc["channel"][3]["term"][0]["n"] == pytest.approx(0.03 / 60 / 9.80665e-6)  # ug/sqrt(Hz)
    with pytest.raises(FileExistsError):
        write_noise(tmp_path / "n.toml", m)
    doc["channel"][0]["term"][1]["n_unit"] = "deg/h"
    with pytest.raises(NoiseFileError, match="rate unit, expected a arw unit"):
        model_from_document(doc)


def test_kalibr():
    text = kalibr_imu_yaml(model())
    vals = {ln.split(":")[0]: float(ln.split(":")[1].split("#")[0]) for ln in text.splitlines()
            if ln and not ln.startswith("#") and "rostopic" not in ln}
    assert vals["gyroscope_noise_density"] == pytest.approx(0.009 * D2R / 60)  # 0.009 deg/sqrt(h), largest axis
    assert vals["gyroscope_random_walk"] == pytest.approx(1e-9)
    assert vals["accelerometer_noise_density"] == pytest.approx(0.0005)
    # no random walk term: the slowest GM's sigma sqrt(2 / tc)
    assert vals["accelerometer_random_walk"] == pytest.approx(15e-5 * math.sqrt(2 / 7200.0))
    assert vals["update_rate"] == 200.0 and "Gauss-Markov" in text


def test_kfgins():
    text = kfgins_imunoise(model(), gsstd_ppm=[300] * 3)
    rows = {ln.split(":")[0].strip(): ln.split(":")[1].split("#")[0].strip() for ln in text.splitlines()[1:]}
    arw = np.array(eval(rows["arw"]))  # noqa: S307 (our own text)
    np.testing.assert_allclose(arw, [0.003, 0.006, 0.009])
    np.testing.assert_allclose(eval(rows["vrw"]), [0.03] * 3)  # noqa: S307 (0.03/60 m/s/sqrt(s) = 0.03 m/s/sqrt(h))
    np.testing.assert_allclose(eval(rows["gbstd"]), [0.02] * 3)  # noqa: S307
    np.testing.assert_allclose(eval(rows["abstd"]), [15.0] * 3)  # noqa: S307 (15e-5 m/s^2 = 15 mGal)
    assert float(rows["corrtime"]) == pytest.approx(3.0) and "gsstd" in rows and "asstd" not in rows


def test_matlab():
    p = matlab_params(model())
    g = p["gyroparams"]
    phi = math.exp(-1 / 200 / (3600 * 3))
    assert g["BiasInstabilityCoefficients"]["Denominator"] == [1.0, pytest.approx(-phi)]
    # white noise of std BiasInstability through 1/(1 - phi z^-1) has the GM's stationary std
    assert g["BiasInstability"][2] / math.sqrt(1 - phi**2) == pytest.approx(0.02 * D2R / 3600)
    assert g["NoiseDensity"][0] == pytest.approx(0.003 * D2R / 60)
    assert "gyroparams('NoiseDensity'" in matlab_script(model())


def test_inscal_export_writes_a_noise_model_in_each_tool_convention(tmp_path):
    """``inscal export noise.toml --format kalibr|kf-gins|matlab``: the same text as the library's, atomically,
    one line for a format the noise model has no export for, nothing written."""
    from typer.testing import CliRunner

    from inscal.cli.app import app

    m = model()
    write_noise(tmp_path / "noise.toml", m)
    m, _ = read_noise(tmp_path / "noise.toml")  # what the file holds (field units, printed digits)
    for fmt, fn, name in (("kalibr", kalibr_imu_yaml, "imu.yaml"), ("kf-gins", kfgins_imunoise, "kfgins.yaml"),
                          ("matlab", matlab_script, "params.m")):
        r = CliRunner().invoke(app, ["export", str(tmp_path / "noise.toml"), "--format", fmt, "--out",
                                     str(tmp_path / name)])
        assert r.exit_code == 0, r.output
        assert (tmp_path / name).read_text() == fn(m)
    r = CliRunner().invoke(app, ["export", str(tmp_path / "noise.toml"), "--format", "imucal", "--out",
                                 str(tmp_path / "x.json")])
    assert r.exit_code == 2 and "a noise model exports as kalibr | kf-gins | matlab" in r.output
    assert not (tmp_path / "x.json").exists()


def test_every_export_names_what_it_drops(tmp_path):
    """A model with BI, RW and GM in every format: the values by hand, and each term the convention
    cannot hold named with its reason, in the file and in ``dropped`` (never ``[]`` beside a lost term)."""
    from inscal.io.exports.calibration import export_noise
    from inscal.io.exports.noise import dropped

    g = [nm.ChannelNoise(n, "gyro", (nm.WhiteNoise(0.01 * D2R / 60), nm.BiasInstability(0.05 * D2R / 3600, 100.0),
                                     nm.RandomWalk(0.02 * D2R / 3600 / 60), nm.GaussMarkov(0.1 * D2R / 3600, 300.0)))
         for n in ("gx", "gy", "gz")]
    a = [nm.ChannelNoise(n, "accel", (nm.WhiteNoise(5e-4), nm.BiasInstability(2e-5, 100.0)))
         for n in ("ax", "ay", "az")]
    m = nm.NoiseModel(tuple(g + a), 100.0)
    write_noise(tmp_path / "n.toml", m)
    m, _ = read_noise(tmp_path / "n.toml")
    for fmt, name in (("kalibr", "k.yaml"), ("kf-gins", "f.yaml"), ("matlab", "p.m")):
        res = export_noise(tmp_path / "n.toml", tmp_path / name, fmt)
        text = (tmp_path / name).read_text()
        assert res["dropped"] == dropped(m, fmt) and res["dropped"]
        for d in res["dropped"]:
            assert f"dropped: {d}" in text
    kal, kfg, mat = (dropped(m, f) for f in ("kalibr", "kf-gins", "matlab"))
    assert any(d.startswith("BI of gx, gy, gz, ax, ay, az: no bias-instability field") for d in kal)
    assert any(d.startswith("GM of gx, gy, gz: no Gauss-Markov field") for d in kal)
    assert any(d.startswith("RW of gx, gy, gz: no random-walk field") for d in kfg)
    assert any(d.startswith("BI of gx, gy, gz, ax, ay, az") for d in kfg)
    assert kfg and not any(d.startswith("GM") for d in kfg)  # the one GM per axis is kept
    assert mat == ["BI of gx, gy, gz: one BiasInstability field, taken by the Gauss-Markov term"]
    # the kept values, by hand
    vals = {ln.split(":")[0]: float(ln.split(":")[1].split("#")[0]) for ln in kalibr_imu_yaml(m).splitlines()
            if ln and not ln.startswith("#") and "rostopic" not in ln}
    assert vals["gyroscope_noise_density"] == pytest.approx(0.01 * D2R / 60, rel=1e-9)  # 0.01 deg/sqrt(h)
    assert vals["gyroscope_random_walk"] == pytest.approx(0.02 * D2R / 3600 / 60, rel=1e-9)  # 0.02 deg/h/sqrt(h)
    assert vals["accelerometer_random_walk"] == 0.0  # BI only: dropped, not turned into a random walk
    p = matlab_params(m)
    phi = math.exp(-0.01 / 300.0)
    assert p["gyroparams"]["BiasInstability"][0] == pytest.approx(0.1 * D2R / 3600 * math.sqrt(1 - phi**2), rel=1e-9)
    assert p["gyroparams"]["RandomWalk"][1] == pytest.approx(0.02 * D2R / 3600 / 60, rel=1e-9)
    # an accelerometer BI without a GM: MATLAB's BiasInstability is B itself, with its default filter
    assert p["accelparams"]["BiasInstability"] == [pytest.approx(2e-5, rel=1e-9)] * 3
    assert p["accelparams"]["BiasInstabilityCoefficients"]["Denominator"] == [1.0, -0.5]
    rows = {ln.split(":")[0].strip(): ln.split(":")[1].split("#")[0].strip()
            for ln in kfgins_imunoise(m).splitlines() if ln.startswith("    ")}
    np.testing.assert_allclose(eval(rows["gbstd"]), [0.1] * 3)  # noqa: S307 (our own text)
    np.testing.assert_allclose(eval(rows["abstd"]), [0.0] * 3)  # noqa: S307 (BI only: named, not mapped)
    assert float(rows["corrtime"]) == pytest.approx(300.0 / 3600)
