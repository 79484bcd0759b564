"""A corpus of malformed inputs.  Every case must end with exit code 2, exactly one
line on stderr (``inscal: error: ...``) holding a key phrase, no traceback, and no file left
behind (the folder holds the same files as before, no ``.part``)."""

import builtins
import math
import os
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
import tomli_w
from typer.testing import CliRunner

from inscal import __version__
from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise, errors_to_field
from inscal.core.earth import Site

RATE = 100.0
runner = CliRunner()


# --------------------------------------------------------------------------- inputs
def record(path, n=3000, truth=True, seed=0):
    rng = np.random.default_rng(seed)
    dt = 1 / RATE
    t = np.arange(1, n + 1) * dt
    dth = rng.normal(0, 1e-7, (n, 3)) + np.array([0, 5e-5, 5e-5]) * dt
    dv = rng.normal(0, 1e-6, (n, 3)) + np.array([0, 0, 9.8]) * dt
    tr = io.Truth(ImuErrors(), GimbalErrors(), ImuNoise()) if truth else None
    io.write_record(path, io.Record(t, dth, dv, np.zeros((n, 2)), RATE, Site(math.radians(45), 0, 0), truth=tr,
                                    scenario="corpus"))
    return path


def edited(tmp, fn, name="bad.h5", **kw):
    p = record(tmp / name, **kw)
    with h5py.File(p, "a") as h5:
        fn(h5)
    return p


def params(tmp, name="p.toml", drop=(), **override):
    field = errors_to_field(ImuErrors(), GimbalErrors())
    for k in drop:
        field.pop(k)
    for k, v in override.items():
        field[k]["value"] = v
    doc = {"kind": "inscal-parameters", "schema_version": 1, "inscal_version": __version__, "method": "n25",
           "created": "2026-01-01T00:00:00Z", "parameters": field}
    p = tmp / name
    p.write_text(tomli_w.dumps(doc))
    return p


def scenario(tmp, text, name="sc.toml"):
    p = tmp / name
    p.write_text(text)
    return p


def _del_attr(name):
    return lambda h5: h5.attrs.__delitem__(name)


def _set_attr(name, value):
    def fn(h5):
        h5.attrs[name] = value
    return fn


def _retype(name, conv):
    def fn(h5):
        a = h5[name][()]
        del h5[name]
        h5.create_dataset(name, data=conv(a))
    return fn


def _empty(h5):
    for k, cols in (("time", None), ("dtheta", 3), ("dvel", 3), ("gimbal", 2)):
        del h5[k]
        h5.create_dataset(k, shape=(0,) if cols is None else (0, cols), dtype="f8")


def _set(name, idx, value):
    def fn(h5):
        h5[name][idx] = value
    return fn


def _delete(name):
    def fn(h5):
        del h5[name]
    return fn


def _unknown_truth(h5):
    h5["truth/imu"].create_dataset("gyro_drift", data=np.zeros(3))


def truncated(tmp):
    p = record(tmp / "trunc.h5", n=20000)
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    return p


def not_hdf5(tmp):
    p = tmp / "notes.h5"
    p.write_text("this is not HDF5\n")
    return p


# --------------------------------------------------------------------------- read-only folders
def readonly(folder: Path, monkeypatch):
    """Make ``folder`` unwritable: chmod when not root; as root (which ignores the mode) refuse
    the creation of files and folders inside it, as the kernel would (EACCES)."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return
    root = str(folder.resolve())

    def inside(p):
        try:
            return os.path.abspath(os.fspath(p)).startswith(root + os.sep)
        except TypeError:
            return False

    def denied(p):
        return PermissionError(13, "Permission denied", os.fspath(p))

    real_open, real_mkdir, real_bopen = os.open, os.mkdir, builtins.open

    def os_open(p, flags, *a, **k):
        if flags & (os.O_CREAT | os.O_WRONLY | os.O_RDWR) and inside(p):
            raise denied(p)
        return real_open(p, flags, *a, **k)

    def mkdir(p, *a, **k):
        if inside(p):
            raise denied(p)
        return real_mkdir(p, *a, **k)

    def bopen(p, mode="r", *a, **k):
        if isinstance(p, (str, os.PathLike)) and any(c in mode for c in "wax+") and inside(p):
            raise denied(p)
        return real_bopen(p, mode, *a, **k)

    monkeypatch.setattr(os, "open", os_open)
    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(builtins, "open", bopen)


# --------------------------------------------------------------------------- the corpus
#: (id, setup(tmp, monkeypatch) -> argv, key phrase of the error line)
CASES = [
    # malformed records
    ("allan-no-rate", lambda t, m: ["allan", edited(t, _del_attr("rate_hz"))], "rate_hz"),
    ("report-no-rate", lambda t, m: ["report", edited(t, _del_attr("rate_hz")), "--out", t / "o.html"], "rate_hz"),
    ("compensate-no-rate", lambda t, m: ["compensate", edited(t, _del_attr("rate_hz")), "-p", params(t), "-o", t / "c.h5"],
     "rate_hz"),
    ("allan-rate-text", lambda t, m: ["allan", edited(t, _set_attr("rate_hz", "fast"))], "rate_hz is not a number"),
    ("allan-rate-negative", lambda t, m: ["allan", edited(t, _set_attr("rate_hz", -100.0))], "positive"),
    ("allan-string-dtheta", lambda t, m: ["allan", edited(t, _retype("dtheta", lambda a: a.astype("S32")))],
     "floating point"),
    ("allan-int-dtheta", lambda t, m: ["allan", edited(t, _retype("dtheta", lambda a: a.astype("i8")))], "floating point"),
    ("report-int-dtheta", lambda t, m: ["report", edited(t, _retype("dtheta", lambda a: a.astype("i8"))), "--out",
                                        t / "o.html"], "floating point"),
    ("compensate-int-dvel", lambda t, m: ["compensate", edited(t, _retype("dvel", lambda a: a.astype("i4"))), "-p",
                                          params(t), "-o", t / "c.h5"], "floating point"),
    ("allan-dtheta-shape", lambda t, m: ["allan", edited(t, _retype("dtheta", lambda a: a[:, :2].copy()))], "shape"),
    ("allan-missing-dvel", lambda t, m: ["allan", edited(t, _delete("dvel"))], "missing /dvel"),
    ("compensate-0-samples", lambda t, m: ["compensate", edited(t, _empty), "-p", params(t), "-o", t / "c.h5"], "sample"),
    ("allan-0-samples", lambda t, m: ["allan", edited(t, _empty)], "samples"),
    ("allan-nan", lambda t, m: ["allan", edited(t, _set("dtheta", (1500, 1), np.nan))], "NaN"),
    ("report-inf", lambda t, m: ["report", edited(t, _set("dvel", (7, 0), np.inf)), "--out", t / "o.html"], "NaN/inf"),
    ("report-time-gap", lambda t, m: ["report", edited(t, _set("time", 2000, 99.0)), "--out", t / "o.html"],
     "not uniform"),
    ("allan-schema", lambda t, m: ["allan", edited(t, _set_attr("schema_version", 99))], "schema version 99"),
    ("allan-kind", lambda t, m: ["allan", edited(t, _set_attr("kind", "something-else"))], "not an inscal record"),
    ("allan-units", lambda t, m: ["allan", edited(t, _set_attr("units", '{"time": "s", "dtheta": "deg", "dvel": "m/s", '
                                                                   '"gimbal": "rad"}'))], "is in 'deg', expected 'rad'"),
    ("allan-not-hdf5", lambda t, m: ["allan", not_hdf5(t)], "not a readable HDF5"),
    ("allan-truncated", lambda t, m: ["allan", truncated(t)], "truncated"),
    ("allan-no-file", lambda t, m: ["allan", t / "missing.h5"], "no such file"),
    ("report-partial-truth-field", lambda t, m: ["report", edited(t, _delete("truth/imu/gyro_bias")), "--out",
                                                 t / "o.html"], "partial truth: /truth lacks imu/gyro_bias"),
    ("compensate-partial-truth-group", lambda t, m: ["compensate", edited(t, _delete("truth/noise")), "-p", params(t),
                                                     "-o", t / "c.h5"], "noise/ (all of it)"),
    ("calibrate-partial-truth", lambda t, m: ["calibrate", edited(t, _delete("truth/gimbal/mount_attitude")),
                                              "--method", "six-position", "--out", t / "p.toml"], "gimbal/mount_attitude"),
    ("report-unknown-truth", lambda t, m: ["report", edited(t, _unknown_truth), "--out", t / "o.html"],
     "unknown parameters"),
    # allan options
    ("allan-plot-h5", lambda t, m: ["allan", record(t / "r.h5"), "--plot", t / "x.h5"], ".png, .pdf or .svg"),
    ("allan-plot-exists", lambda t, m: ["allan", record(t / "r.h5"), "--plot", (t / "a.png").write_bytes(b"x") and t / "a.png"],
     "exists"),
    ("allan-start-nan", lambda t, m: ["allan", record(t / "r.h5"), "--start", "nan"], "finite"),
    ("allan-short-window", lambda t, m: ["allan", record(t / "r.h5"), "--start", "25"], "only 500 samples"),
    ("allan-plot-readonly", lambda t, m: ["allan", record(t / "r.h5"), "--plot",
                                          (t / "ro").mkdir() or readonly(t / "ro", m) or t / "ro" / "a.png"],
     "Permission denied"),
    # simulate
    ("simulate-negative-duration", lambda t, m: ["simulate", "static", "--duration-h", "-1", "--out", t / "s.h5"],
     "duration must be > 0"),
    ("simulate-absurd-duration", lambda t, m: ["simulate", "static-24h", "--duration-h", "1e9", "--out", t / "s.h5"],
     "not a sensible record"),
    ("simulate-absurd-rate", lambda t, m: ["simulate", "static-24h", "--rate-hz", "1e7", "--out", t / "s.h5"],
     "not a sensible record"),
    ("simulate-huge-path", lambda t, m: ["simulate", scenario(t, 'base = "n25"\n[path]\nmoves = [{axis = "inner", '
                                                             'angle_deg = 1e12, rate_dps = 10, dwell_s = 5}, {axis = '
                                                             '"inner", angle_deg = -1e12, rate_dps = 10, dwell_s = 5}]\n'),
                                         "--out", t / "s.h5"], "not a sensible record"),
    ("simulate-no-free-space", lambda t, m: m.setattr("shutil.disk_usage", lambda p: SimpleNamespace(total=10**9, used=10**9 - 10**6, free=10**6))
     or ["simulate", "static", "--duration-h", "1", "--out", t / "s.h5"], "free"),
    ("simulate-unknown-key", lambda t, m: ["simulate", scenario(t, "[site]\nlatitude = 30\n"), "--out", t / "s.h5"],
     "unknown key"),
    ("simulate-unknown-top-key", lambda t, m: ["simulate", scenario(t, "colour = 'red'\n"), "--out", t / "s.h5"],
     "colour"),
    ("simulate-malformed-toml", lambda t, m: ["simulate", scenario(t, "[scenario\nname = 'x'"), "--out", t / "s.h5"],
     "malformed TOML"),
    ("simulate-unknown-scenario", lambda t, m: ["simulate", "s17", "--out", t / "s.h5"], "unknown scenario"),
    ("simulate-negative-seed", lambda t, m: ["simulate", "static", "--seed", "-3", "--out", t / "s.h5"], "--seed"),
    ("simulate-bad-gravity", lambda t, m: ["simulate", "static", "--gravity", "heavy", "--out", t / "s.h5"], "--gravity"),
    ("simulate-zero-rate", lambda t, m: ["simulate", "static", "--rate-hz", "0", "--out", t / "s.h5"], "--rate-hz"),
    ("simulate-no-folder", lambda t, m: ["simulate", "static", "--out", t / "nope" / "s.h5"], "does not exist"),
    ("simulate-readonly", lambda t, m: (t / "ro").mkdir() or readonly(t / "ro", m) or
     ["simulate", "static", "--duration-h", "0.001", "--out", t / "ro" / "s.h5"], "Permission denied"),
    # parameter files
    ("report-1e300-bias", lambda t, m: ["report", record(t / "r.h5"), "-p", params(t, accel_bias=[1e300, 0.0, 0.0]),
                                        "--out", t / "o.html"], "implausible"),
    ("compensate-1e300-bias", lambda t, m: ["compensate", record(t / "r.h5"), "-p", params(t, accel_bias=[1e300, 0.0, 0.0]),
                                            "-o", t / "c.h5"], "implausible"),
    ("compensate-missing-table", lambda t, m: ["compensate", record(t / "r.h5"), "-p", params(t, drop=("accel_bias",)),
                                               "-o", t / "c.h5"], "accel_bias"),
    ("report-nan-parameter", lambda t, m: ["report", record(t / "r.h5"), "-p", params(t, gyro_bias=[float("nan"), 0.0, 0.0]),
                                           "--out", t / "o.html"], "non-finite"),
    ("compensate-params-not-toml", lambda t, m: ["compensate", record(t / "r.h5"), "-p",
                                                 scenario(t, "kind = [", name="p.toml"), "-o", t / "c.h5"], "p.toml"),
    ("compensate-out-is-input", lambda t, m: ["compensate", record(t / "r.h5"), "-p", params(t), "-o", t / "r.h5",
                                              "--force"], "must differ"),
    ("report-out-is-params", lambda t, m: ["report", record(t / "r.h5"), "-p", params(t), "--out", t / "p.toml",
                                           "--force"], "must differ"),
    # montecarlo, import
    ("montecarlo-readonly", lambda t, m: (t / "ro").mkdir() or readonly(t / "ro", m) or
     ["montecarlo", "n25-fig5", "--runs", "1", "--out", t / "ro" / "study", "--no-dask", "--no-progress"],
     "Permission denied"),
    ("montecarlo-zero-runs", lambda t, m: ["montecarlo", "n25-fig5", "--runs", "0", "--out", t / "study", "--no-dask"],
     "--runs"),
    ("import-unknown-format", lambda t, m: ["import", not_hdf5(t), "--format", "xlsx", "--out", t / "i.h5"],
     "unknown --format"),
    ("import-no-source", lambda t, m: ["import", t / "none.bin", "--format", "psins", "--out", t / "i.h5"], "no such file"),
]


def _listing(folder: Path):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("setup, phrase", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_corpus(tmp_path, monkeypatch, setup, phrase):
    args = [str(a) for a in setup(tmp_path, monkeypatch)]
    before = _listing(tmp_path)
    r = runner.invoke(app, args)
    monkeypatch.undo()
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2, (r.exit_code, r.stderr, r.exception)
    assert len(lines) == 1 and lines[0].startswith("inscal: error: "), r.stderr
    assert phrase in lines[0], lines[0]
    assert "Traceback" not in r.stderr + r.stdout
    after = _listing(tmp_path)
    assert after == before, set(after) ^ set(before)


def test_corpus_size():
    """The corpus holds at least 40 malformed-input cases."""
    assert len(CASES) >= 40 and len({c[0] for c in CASES}) == len(CASES)


def test_partial_truth_in_the_library(tmp_path):
    """Truth is optional as a whole (None), but a partial one is an error naming what is missing."""
    p = record(tmp_path / "full.h5")
    assert io.read_record(p).truth is not None
    q = record(tmp_path / "none.h5", truth=False)
    assert io.read_record(q).truth is None and io.record_info(q).truth is None
    bad = edited(tmp_path, _delete("truth/imu/accel_bias"))
    with pytest.raises(io.DataFileError, match="lacks imu/accel_bias"):
        io.read_record(bad)
    with pytest.raises(io.DataFileError, match="lacks imu/accel_bias"):
        io.record_info(bad)
