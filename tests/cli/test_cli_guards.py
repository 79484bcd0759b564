"""Hardening: no traceback and no destroyed input.  Every refusal is one line on
stderr with exit code 2, the input is untouched and no output is left behind."""

import hashlib
import math

import h5py
import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import __version__
from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import GimbalErrors, ImuErrors, errors_to_field
from inscal.io.paramfile import ParamFileError, load_params
from inscal.core.earth import Site

runner = CliRunner()
RATE = 100.0
EARTH = 7.292115e-5


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def one_line_error(code, stderr):
    assert code == 2, stderr
    lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inscal: error:"), stderr
    assert "Traceback" not in stderr
    return lines[0]


def digest(p):
    return hashlib.sha256(p.read_bytes()).hexdigest()


def make_record(path, n=4000, rotate=False, seed=0):
    """A small static (or, with ``rotate``, turning about z at 10 deg/s) record, noise 0.02 deg/sqrt(h)."""
    rng = np.random.default_rng(seed)
    dt = 1 / RATE
    t = np.arange(1, n + 1) * dt
    arw = 0.02 * math.pi / 180 / 60  # rad/sqrt(s)
    dth = rng.normal(0, arw * math.sqrt(dt), (n, 3)) + np.array([0, EARTH * 0.7, EARTH * 0.7]) * dt
    gim = np.zeros((n, 2))
    if rotate:
        dth[:, 2] += math.radians(10) * dt
        gim[:, 1] = np.cumsum(dth[:, 2])
    dv = rng.normal(0, 1e-5 * math.sqrt(dt), (n, 3)) + np.array([0, 0, 9.8]) * dt
    rec = io.Record(t, dth, dv, gim, RATE, Site(math.radians(45), 0.0, 0.0), scenario="guards")
    io.write_record(path, rec)
    return path


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return make_record(tmp_path_factory.mktemp("rec") / "r.h5")


def params_file(path, method="n25", drop=(), **override):
    field = errors_to_field(ImuErrors(), GimbalErrors())
    for k in drop:
        field.pop(k)
    for k, v in override.items():
        field[k]["value"] = v
    doc = {"kind": "inscal-parameters", "schema_version": 1, "inscal_version": __version__, "method": method,
           "created": "2026-01-01T00:00:00Z", "parameters": field}
    path.write_text(tomli_w.dumps(doc))
    return path


def test_version():
    code, out, _ = run("--version")
    assert code == 0 and out.strip() == f"inscal {__version__}"


# --------------------------------------------------------------------------- input given as output
def test_report_out_is_input_refused(rec, tmp_path):
    before = digest(rec)
    line = one_line_error(*run("report", rec, "--out", rec, "--force")[::2])
    assert "must differ" in line and digest(rec) == before
    p = params_file(tmp_path / "p.toml")
    before_p = digest(p)
    one_line_error(*run("report", rec, "--params", p, "--out", p, "--force")[::2])
    assert digest(p) == before_p


def test_compensate_out_is_input_refused(rec, tmp_path):
    p = params_file(tmp_path / "p.toml")
    before, before_p = digest(rec), digest(p)
    assert "must differ" in one_line_error(*run("compensate", rec, "--params", p, "--out", rec, "--force")[::2])
    assert "must differ" in one_line_error(*run("compensate", rec, "--params", p, "--out", p, "--force")[::2])
    assert digest(rec) == before and digest(p) == before_p


def test_allan_plot_guards(rec, tmp_path):
    before = digest(rec)
    # the input itself, and a non-image suffix: refused before anything is computed or written
    line = one_line_error(*run("allan", rec, "--plot", rec, "--force")[::2])
    assert "plot format" in line and digest(rec) == before
    line = one_line_error(*run("allan", rec, "--plot", tmp_path / "x.h5")[::2])
    assert ".png, .pdf or .svg" in line and not (tmp_path / "x.h5").exists()
    link = tmp_path / "r.png"
    link.symlink_to(rec)
    one_line_error(*run("allan", rec, "--plot", link, "--force")[::2])
    assert digest(rec) == before


def test_allan_unwritable_plot(rec, tmp_path, monkeypatch):
    import inscal.report.figures as report

    def denied(fig, path, overwrite=False):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(report, "save_figure", denied)
    line = one_line_error(*run("allan", rec, "--plot", tmp_path / "a.svg")[::2])
    assert "Permission denied" in line and list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- allan on a turning record
def test_allan_warns_on_a_rotating_record(rec, tmp_path):
    code, _, err = run("allan", rec, "--json", "--model", "WN")
    assert code == 0 and "not static" not in err
    turning = make_record(tmp_path / "t.h5", rotate=True)
    code, out, err = run("allan", turning, "--json", "--model", "WN")
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 0 and len(lines) == 1 and lines[0].startswith("inscal: warning:") and "not static" in lines[0]
    assert '"warnings"' in out


# --------------------------------------------------------------------------- malformed records
def _edit(src, dst, fn):
    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "a") as h5:
        fn(h5)
    return dst


def _retype(dtype):
    def fn(h5):
        a = h5["dtheta"][()]
        del h5["dtheta"]
        h5.create_dataset("dtheta", data=a.astype(dtype) if dtype != "S" else a.astype("S32"))
    return fn


@pytest.mark.parametrize("what, fn, cmd", [
    ("no rate_hz", lambda h5: h5.attrs.__delitem__("rate_hz"), "report"),
    ("no rate_hz", lambda h5: h5.attrs.__delitem__("rate_hz"), "allan"),
    ("string dtheta", _retype("S"), "allan"),
    ("integer dtheta", _retype("i8"), "allan"),
    ("integer dtheta", _retype("i8"), "report"),
])
def test_malformed_record_one_line(rec, tmp_path, what, fn, cmd):
    bad = _edit(rec, tmp_path / "bad.h5", fn)
    before = digest(bad)
    args = ["--out", tmp_path / "o.html"] if cmd == "report" else []
    one_line_error(*run(cmd, bad, *args)[::2])
    assert digest(bad) == before and not (tmp_path / "o.html").exists()


def test_compensate_empty_record(rec, tmp_path):
    def empty(h5):
        for k, cols in (("time", None), ("dtheta", 3), ("dvel", 3), ("gimbal", 2)):
            del h5[k]
            h5.create_dataset(k, shape=(0,) if cols is None else (0, cols), dtype="f8")
    bad = _edit(rec, tmp_path / "empty.h5", empty)
    p = params_file(tmp_path / "p.toml")
    line = one_line_error(*run("compensate", bad, "--params", p, "--out", tmp_path / "c.h5")[::2])
    assert "sample" in line and not (tmp_path / "c.h5").exists()


# --------------------------------------------------------------------------- parameter files
@pytest.mark.parametrize("kw, msg", [
    ({"drop": ("accel_bias",)}, "accel_bias"),
    ({"method": "systematic51", "drop": ("gyro_bias",)}, "gyro_bias"),
    ({"accel_bias": [1e300, 0.0, 0.0]}, "implausible"),
    ({"gyro_scale_factor": [0.0, 2e5, 0.0]}, "implausible"),
    ({"accel_misalignment": [0.0, 0.0, 0.0, 0.0, 0.0, 4e4]}, "implausible"),
    ({"accel_lever_arm": [[0.0, 0, 0], [0, 150.0, 0], [0, 0, 0]]}, "implausible"),
    ({"gyro_bias": [float("nan"), 0.0, 0.0]}, "non-finite"),
])
def test_bad_parameter_files(tmp_path, rec, kw, msg):
    p = params_file(tmp_path / "p.toml", **kw)
    with pytest.raises(ParamFileError, match=msg):
        load_params(p)
    line = one_line_error(*run("report", rec, "--params", p, "--out", tmp_path / "o.html")[::2])
    assert msg in line and not (tmp_path / "o.html").exists()


def test_plausible_parameter_files_load(tmp_path):
    for method in ("n25", "joint", "six-position", "twelve-position", "systematic51", "systematic30", "truth"):
        imu, _, meta = load_params(params_file(tmp_path / f"{method}.toml", method=method,
                                               accel_bias=[5e5, -100.0, 0.0], accel_lever_arm=[[5.0, 0, 0], [0, 5.0, 0], [0, 0, 5.0]]))
        assert meta["method"] == method and imu.accel_bias[0] == pytest.approx(5e5 * 9.80665e-6)
    # a hand-written file (no inscal_version) may list a subset
    p = tmp_path / "hand.toml"
    p.write_text('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n'
                 '[parameters.accel_bias]\nvalue = [1.0, 2.0, 3.0]\nunit = "ug"\n')
    assert load_params(p)[2]["estimated"] == ("accel_bias",)


# --------------------------------------------------------------------------- montecarlo
def test_montecarlo_unwritable_leaves_no_folder(tmp_path, monkeypatch):
    from inscal.analysis import montecarlo as mc

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", "runs.jsonl")

    monkeypatch.setattr(mc, "open_study", denied)
    out = tmp_path / "a" / "study"
    line = one_line_error(*run("montecarlo", "n25-fig5", "--runs", 1, "--out", out, "--no-dask", "--no-progress")[::2])
    assert "Permission denied" in line and list(tmp_path.iterdir()) == []
    # a folder that was there already is kept
    (tmp_path / "keep").mkdir()
    one_line_error(*run("montecarlo", "n25-fig5", "--runs", 1, "--out", tmp_path / "keep", "--no-dask")[::2])
    assert (tmp_path / "keep").is_dir()


def test_montecarlo_out_under_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    one_line_error(*run("montecarlo", "n25-fig5", "--runs", 1, "--out", tmp_path / "f" / "s", "--no-dask")[::2])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


# --------------------------------------------------------------------------- long names
def test_long_names_are_cut():
    name = "x" * 100_000
    line = one_line_error(*run("montecarlo", name, "--runs", 1, "--out", "/nonexistent/s", "--no-dask")[::2])
    assert len(line) < 1200 and "characters)" in line and "available:" in line


def test_short_helper():
    from inscal.cli.common import short

    assert short("abc") == "abc"
    s = short("y" * 500)
    assert len(s) < 230 and s.endswith("(500 characters)")


def test_demo_unwritable_folder(tmp_path):
    (tmp_path / "f").write_text("x")
    one_line_error(*run("demo", "--out", tmp_path / "f" / "d", "--quick", "--json")[::2])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]
