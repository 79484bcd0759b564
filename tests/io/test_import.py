"""inscal import / export: round trips that calibrate identically, the mapping's
conversions, and a corpus of malformed files each refused with one line, exit 2, nothing written."""

import json
import math
import tomllib
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
import scipy.io
from typer.testing import CliRunner

from inscal.sim.simulate import write_simulation
from inscal.core import earth
from inscal import io
from inscal.io import importers
from inscal.sim import scenarios
from inscal.calibrate import calibrate
from inscal.calibrate.result import param_value
from inscal.cli.app import app
from inscal.core.error_model import ImuNoise

runner = CliRunner()
BAD = Path(__file__).resolve().parents[1] / "data" / "bad"


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


def listing(d: Path) -> set:
    return {p.name for p in d.iterdir()}


def same_parameters(a, b, rel=1e-9):
    """Every estimated parameter of ``b`` equals ``a``'s to ``rel`` (relative to the parameter's size)."""
    assert a.estimated == b.estimated
    for name in a.estimated:
        x, y = param_value(a.imu, a.gimbal, name), param_value(b.imu, b.gimbal, name)
        scale = float(np.abs(x).max())
        assert scale > 0, f"{name}: estimate is zero; the comparison would prove nothing"
        assert np.all(np.abs(y - x) <= rel * scale), f"{name}: {y} != {x}"


# ----------------------------------------------------------------------------- round trips
@pytest.fixture(scope="module")
def p19(tmp_path_factory):
    """A noise-free psins19 record (19 positions, +-90 deg turns) at 20 Hz, its path TOML and
    calibrations of the original, cached."""
    d = tmp_path_factory.mktemp("p19")
    sc = replace(scenarios.build("psins19", rate_hz=20.0), noise=ImuNoise())
    f = d / "p19.h5"
    write_simulation(f, sc, None)
    rec = io.read_record(f)
    path_toml = d / "path.toml"
    assert run("export", f, "--format", "psins", "--out", d / "first.bin", "--path-out", path_toml)[0] == 0
    assert tomllib.loads(path_toml.read_text())["path"] == rec.path.to_dict()
    s = rec.site
    site = ["--lat", math.degrees(s.latitude), "--lon", math.degrees(s.longitude), "--height", s.height]

    @lru_cache(maxsize=None)
    def cal(method, encoders=True):
        return calibrate(rec if encoders else replace(rec, gimbal=None), method)

    return SimpleNamespace(dir=d, file=f, rec=rec, path_toml=path_toml, site=site, cal=cal)


@pytest.fixture(scope="module")
def imported(p19):
    """Export the record as PSINS .bin, .mat and csv and import each back (CLI both ways):
    psins with the encoder angles from a separate file, mat with the path TOML (no encoders),
    csv with its gimbal columns, and csv-path: the encoder-less record exported as csv and
    imported with the path."""
    d = p19.dir
    out = {}
    assert run("export", p19.file, "--format", "psins", "--out", d / "r.bin", "--gimbal-out", d / "ang.csv")[0] == 0
    code, so, se = run("import", d / "r.bin", "--format", "psins", "--out", d / "bin.h5", *p19.site,
                       "--gimbal", d / "ang.csv", "--json")  # the file's header says rad: no --gimbal-unit
    assert code == 0, se
    out["psins"] = (io.read_record(d / "bin.h5"), json.loads(so))
    assert run("export", p19.file, "--format", "mat", "--out", d / "r.mat")[0] == 0
    code, so, se = run("import", d / "r.mat", "--format", "mat", "--out", d / "mat.h5", *p19.site,
                       "--path", p19.path_toml, "--json")
    assert code == 0, se
    out["mat"] = (io.read_record(d / "mat.h5"), json.loads(so))
    assert run("export", p19.file, "--format", "csv", "--out", d / "r.csv")[0] == 0
    code, so, se = run("import", d / "r.csv", "--format", "csv", "--out", d / "csv.h5", *p19.site, "--json")
    assert code == 0, se
    out["csv"] = (io.read_record(d / "csv.h5"), json.loads(so))
    assert run("export", d / "mat.h5", "--format", "csv", "--out", d / "nogim.csv")[0] == 0
    code, so, se = run("import", d / "nogim.csv", "--format", "csv", "--out", d / "csvpath.h5", *p19.site,
                       "--path", p19.path_toml, "--json")
    assert code == 0, se
    out["csv-path"] = (io.read_record(d / "csvpath.h5"), json.loads(so))
    return out


@pytest.mark.parametrize("fmt", ["psins", "mat", "csv", "csv-path"])
def test_round_trip_gives_back_the_same_doubles(p19, imported, fmt):
    rec, summary = imported[fmt]
    o = p19.rec
    assert summary["samples"] == o.n_samples == 20712 and summary["rate_hz"] == 20.0
    assert rec.rate_hz == o.rate_hz and rec.site == o.site and rec.truth is None
    for k in ("time", "dtheta", "dvel"):
        assert np.array_equal(getattr(rec, k), getattr(o, k)), k  # bit-exact, not merely close
    if fmt in ("psins", "csv"):
        assert np.array_equal(rec.gimbal, o.gimbal) and rec.path is None
        assert summary["gimbal"] == ("file" if fmt == "psins" else "columns")
    else:
        assert rec.gimbal is None and rec.path.to_dict() == o.path.to_dict() and summary["path"] == "psins19"
    with h5py.File(p19.dir / {"psins": "bin.h5", "mat": "mat.h5", "csv": "csv.h5", "csv-path": "csvpath.h5"}[fmt]) as h5:
        src = json.loads(h5.attrs["source"])
    assert src["format"] == fmt.split("-")[0] and src["hash"].startswith("sha256:")


def test_export_layouts(p19, imported):
    d, n = p19.dir, p19.rec.n_samples
    assert (d / "r.bin").stat().st_size == n * 7 * 8  # float64 rows [dθ dv t]
    rows = np.fromfile(d / "r.bin", dtype="<f8").reshape(n, 7)
    assert np.array_equal(rows[:, 6], p19.rec.time) and np.array_equal(rows[:, 3:6], p19.rec.dvel)
    assert scipy.io.loadmat(d / "r.mat")["imu"].shape == (n, 7)
    lines = (d / "r.csv").read_text().splitlines()
    assert lines[0] == ",".join(importers.EXPORT_HEADER + importers.EXPORT_HEADER_GIMBAL) and len(lines) == n + 1
    assert (d / "nogim.csv").read_text().splitlines()[0] == ",".join(importers.EXPORT_HEADER)
    assert (d / "ang.csv").read_text().splitlines()[0] == ",".join(importers.GIMBAL_HEADER)


@pytest.mark.parametrize("fmt", ["psins", "mat", "csv", "csv-path"])
def test_round_trip_joint_gives_the_same_parameters(p19, imported, fmt):
    rec, _ = imported[fmt]
    same_parameters(p19.cal("joint", encoders=rec.gimbal is not None), calibrate(rec, "joint"))


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["psins", "mat", "csv"])
def test_round_trip_systematic30_gives_the_same_parameters(p19, imported, fmt):
    same_parameters(p19.cal("systematic30"), calibrate(imported[fmt][0], "systematic30"))


@pytest.mark.slow
def test_path_only_record_calibrates_with_joint_and_systematic51(p19, imported):
    """The 19-position +-90 deg record without encoder angles, imported with the path TOML."""
    rec, _ = imported["mat"]
    truth = p19.rec.truth
    joint = calibrate(rec, "joint")
    assert joint.windows.info["source"] == "increments"  # windows found without encoders
    same_parameters(p19.cal("joint", encoders=True), joint)  # the same as with the encoder angles
    sys51 = calibrate(rec, "systematic51")
    same_parameters(p19.cal("systematic51"), sys51)
    # close to the truth (joint fits the linear N25 model; psins19's nonlinear accelerometer
    # terms, which systematic51 estimates, bias its scale factors)
    tol = [(joint, {"gyro_bias": 1e-3, "gyro_misalignment": 5.0, "accel_misalignment": 3.0}),
           (sys51, {"gyro_bias": 2e-3, "gyro_scale_factor": 0.5, "accel_scale_factor": 0.5, "accel_bias": 0.5,
                    "accel_lever_arm": 0.02})]  # deg/h, arcsec, ppm, ug, cm
    for res, limits in tol:
        f = res.to_field(truth)
        for name, lim in limits.items():
            assert np.abs(f[name]["error"]).max() < lim, (res.method, name, f[name])


# ----------------------------------------------------------------------------- mapping, units, time
def _slice(rec, n):
    return SimpleNamespace(time=rec.time[:n], dtheta=rec.dtheta[:n], dvel=rec.dvel[:n], dt=1.0 / rec.rate_hz)


def test_mapping_rates_units_axes_signs_names_and_ms(p19, tmp_path):
    """deg/s and g rates on permuted, sign-flipped axes, time in ms, columns by name,
    ';' delimiter, two header rows and a comment: imported back to the record's increments."""
    r = _slice(p19.rec, 4000)  # 200 s: the 90 s dwell and the first turns
    perm, sign = [1, 2, 0], np.array([1.0, -1.0, 1.0])  # file channel i measures IMU axis perm[i]
    w = np.degrees(r.dtheta / r.dt)[:, perm] * sign
    f = (r.dvel / r.dt / 9.80665)[:, perm] * sign
    lines = ["# lab run 7", "wx;wy;wz;fx;fy;fz;t_ms"]
    lines += [";".join("%.17g" % v for v in row) for row in np.column_stack([w, f, r.time * 1e3])]
    lines.insert(500, "# operator note")
    src = tmp_path / "run.csv"
    src.write_text("\n".join(lines) + "\n")
    m = tmp_path / "m.toml"
    m.write_text('kind = "rates"\ndelimiter = ";"\nheader_rows = 2\naxes = ["y", "z", "x"]\nsigns = [1, -1, 1]\n'
                 '[columns]\ntime = "t_ms"\ngx = "wx"\ngy = "wy"\ngz = "wz"\nax = "fx"\nay = "fy"\naz = "fz"\n'
                 '[units]\ntime = "ms"\ngyro = "deg/s"\naccel = "g"\n'
                 '[site]\nlatitude_deg = 34.0\nlongitude_deg = 108.0\nheight_m = 380.0\n')
    out = tmp_path / "o.h5"
    code, so, se = run("import", src, "--format", "csv", "--mapping", m, "--out", out, "--json")
    assert code == 0, se
    assert json.loads(so)["kind"] == "rates"
    rec = io.read_record(out)
    assert rec.rate_hz == 20.0 and rec.site == p19.rec.site
    assert np.allclose(rec.time, r.time, rtol=1e-14, atol=0)
    assert np.allclose(rec.dtheta, r.dtheta, rtol=1e-13, atol=1e-22)
    assert np.allclose(rec.dvel, r.dvel, rtol=1e-13, atol=1e-20)
    # without the axes/signs the channels land on the wrong axes: the mapping is applied
    m.write_text(m.read_text().replace('axes = ["y", "z", "x"]\nsigns = [1, -1, 1]\n', ""))
    assert run("import", src, "--format", "csv", "--mapping", m, "--out", tmp_path / "p.h5")[0] == 0
    assert not np.allclose(io.read_record(tmp_path / "p.h5").dtheta, r.dtheta, rtol=1e-6)


def test_mapping_counts_whitespace_and_no_time_column(p19, tmp_path):
    r = _slice(p19.rec, 4000)
    q_g, q_a = 0.001, 1e-6  # arcsec, m/s per count
    g = np.round(np.degrees(r.dtheta) * 3600 / q_g)
    a = np.round(r.dvel / q_a)
    src = tmp_path / "counts.txt"
    np.savetxt(src, np.column_stack([g, a]), fmt="%d")
    m = tmp_path / "m.toml"
    m.write_text('[columns]\ngx = 0\ngy = 1\ngz = 2\nax = 3\nay = 4\naz = 5\n'
                 '[units]\ngyro = "counts"\ngyro_scale = "0.001 arcsec"\naccel = "counts"\naccel_scale = 1e-6\n')
    out = tmp_path / "o.h5"
    code, _, se = run("import", src, "--format", "txt", "--mapping", m, "--out", out, *p19.site)
    assert code == 2 and "no time column; give --rate-hz" in se and not out.exists()
    code, _, se = run("import", src, "--format", "txt", "--mapping", m, "--out", out, *p19.site, "--rate-hz", 20)
    assert code == 0, se
    rec = io.read_record(out)
    assert np.allclose(rec.time, r.time, rtol=1e-14, atol=0)
    assert np.abs(rec.dtheta - r.dtheta).max() <= 0.5 * q_g * math.pi / 180 / 3600 * (1 + 1e-9)
    assert np.abs(rec.dvel - r.dvel).max() <= 0.5 * q_a * (1 + 1e-9)


def test_psins_float32_needs_a_rate_and_is_regridded(p19, tmp_path):
    rows = np.column_stack([p19.rec.dtheta, p19.rec.dvel, p19.rec.time]).astype("<f4")
    src = tmp_path / "f32.bin"
    rows.tofile(src)
    out = tmp_path / "o.h5"
    code, _, se = run("import", src, "--format", "psins", "--out", out, *p19.site)
    assert code == 2 and "try --dtype float32" in se and not out.exists()
    code, _, se = run("import", src, "--format", "psins", "--dtype", "float32", "--out", out, *p19.site)
    assert code == 2 and "not uniform" in se and "give --rate-hz" in se and not out.exists()
    code, so, se = run("import", src, "--format", "psins", "--dtype", "float32", "--rate-hz", 20, "--out", out,
                       *p19.site, "--json")
    assert code == 0, se
    assert json.loads(so)["time_regridded"] is True
    rec = io.read_record(out)
    assert np.abs(rec.time - p19.rec.time).max() < 1e-5  # float32 timestamps near 1000 s: 6e-5 s steps
    assert np.array_equal(rec.dtheta, rows[:, :3].astype(float))


def test_psins_rate_form_and_absolute_time_with_the_path(p19, tmp_path):
    """Rate rows [w f t] (--rates) with GPS-like absolute times: the path starts at the first sample."""
    o = p19.rec
    rows = np.column_stack([o.dtheta * o.rate_hz, o.dvel * o.rate_hz, o.time + 345600.0])
    src = tmp_path / "rates.bin"
    rows.astype("<f8").tofile(src)
    out = tmp_path / "o.h5"
    code, _, se = run("import", src, "--format", "psins", "--out", out, *p19.site)
    assert code == 2 and "rates, not increments" in se
    code, so, se = run("import", src, "--format", "psins", "--rates", "--out", out, *p19.site,
                       "--path", p19.path_toml, "--json")
    assert code == 0, se
    s = json.loads(so)
    assert s["kind"] == "rates" and s["time_offset_s"] == pytest.approx(345600.0, abs=1e-9)
    rec = io.read_record(out)
    assert np.allclose(rec.time, o.time, rtol=0, atol=1e-9)
    assert np.allclose(rec.dtheta, o.dtheta, rtol=1e-15, atol=0) and np.allclose(rec.dvel, o.dvel, rtol=1e-15, atol=0)


def test_path_that_does_not_follow_the_increments_is_refused(p19, tmp_path):
    """The record cut short and the path started 2 s early: the turns do not line up."""
    o = p19.rec
    rows = np.column_stack([o.dtheta, o.dvel, o.time])[:20000]
    src = tmp_path / "cut.bin"
    rows.astype("<f8").tofile(src)
    base = ["import", src, "--format", "psins", *p19.site, "--path", p19.path_toml]
    code, _, se = run(*base, "--out", tmp_path / "a.h5", "--path-start-s", -2.0)
    assert code == 2 and "do not follow the path 'psins19'" in se and not (tmp_path / "a.h5").exists()
    code, _, se = run(*base, "--out", tmp_path / "a.h5", "--path-start-s", -2.0, "--skip-check", "motion")
    assert code == 0, se
    code, _, se = run(*base, "--out", tmp_path / "b.h5", "--path-start-s", 0.5)
    assert code == 2 and "before the path start" in se
    assert run(*base, "--out", tmp_path / "c.h5")[0] == 0  # aligned: accepted


def test_gimbal_file_units_from_its_header_and_a_unit_mix_up_named(p19, tmp_path):
    """An exported gimbal file says its unit in its header and is read back in it; a header that
    contradicts --gimbal-unit is refused; angles in radians read as degrees (no header) turn 57.3
    times too slowly and the motion check says so (this once calibrated to 8e6 ppm silently)."""
    o = p19.rec
    src = tmp_path / "r.bin"
    np.column_stack([o.dtheta, o.dvel, o.time]).astype("<f8").tofile(src)
    rad = tmp_path / "rad.csv"
    rad.write_text("time [s],outer [rad],inner [rad]\n" + "".join(
        f"{t:.17g},{a:.17g},{b:.17g}\n" for t, (a, b) in zip(o.time, o.gimbal)))
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "a.h5", *p19.site, "--gimbal", rad)
    assert code == 0, se
    assert np.abs(io.read_record(tmp_path / "a.h5").gimbal - o.gimbal).max() < 0.3 * math.pi / 180
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "b.h5", *p19.site, "--gimbal", rad,
                      "--gimbal-unit", "deg")
    assert code == 2 and "header says the angles are in rad, --gimbal-unit says deg" in se
    bare = tmp_path / "bare.csv"
    bare.write_text("".join(f"{t:.17g},{a:.17g},{b:.17g}\n" for t, (a, b) in zip(o.time, o.gimbal)))
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "c.h5", *p19.site, "--gimbal", bare)
    assert code == 2 and "radians read as degrees" in se and not (tmp_path / "c.h5").exists(), se
    assert len(se.strip().splitlines()) == 1
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "d.h5", *p19.site, "--gimbal", bare,
                      "--gimbal-unit", "rad")
    assert code == 0, se
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("time [s],outer [rad],inner [deg]\n0,0,0\n1,0,0\n")
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "e.h5", *p19.site, "--gimbal", mixed)
    assert code == 2 and "different or missing units" in se


def test_encoder_file_at_a_lower_rate_wrapped_in_degrees(p19, tmp_path):
    o = p19.rec
    k = np.arange(0, o.n_samples, 4)  # 5 Hz encoder samples, starting at the first record sample
    k = np.append(k, o.n_samples - 1)
    wrapped = np.mod(np.degrees(o.gimbal[k]), 360.0)  # 0..360 deg readings (outer goes to +540 deg)
    ang = tmp_path / "enc.txt"
    np.savetxt(ang, np.column_stack([o.time[k], wrapped]), fmt="%.12f", header="t outer inner", comments="")
    src = tmp_path / "r.bin"
    np.column_stack([o.dtheta, o.dvel, o.time]).astype("<f8").tofile(src)
    out = tmp_path / "o.h5"
    code, _, se = run("import", src, "--format", "psins", "--out", out, *p19.site, "--gimbal", ang)
    assert code == 0, se
    g = io.read_record(out).gimbal
    assert np.abs(g - o.gimbal).max() < 0.3 * math.pi / 180  # linear interpolation through the accelerations
    moved = np.any(np.diff(o.gimbal, axis=0, prepend=o.gimbal[:1]) != 0, axis=1).astype(float)
    static = np.convolve(moved, np.ones(9), mode="same") == 0  # 4 samples either side at rest
    assert static.sum() > 15000 and np.abs(g - o.gimbal)[static].max() < 1e-10
    # encoder times 2 s late: the angles no longer follow the increments
    np.savetxt(ang, np.column_stack([o.time[k] + 2.0, wrapped]), fmt="%.12f")
    np.column_stack([o.dtheta, o.dvel, o.time])[40:-40].astype("<f8").tofile(src)
    code, _, se = run("import", src, "--format", "psins", "--out", tmp_path / "p.h5", *p19.site, "--gimbal", ang)
    assert code == 2 and "do not follow the gimbal angles" in se and not (tmp_path / "p.h5").exists()


def test_matlab_v73_file(p19, tmp_path):
    """v7.3 MAT files are HDF5 with a 512-byte MATLAB header; arrays are stored transposed."""
    o = p19.rec
    src = tmp_path / "v73.mat"
    with h5py.File(src, "w", userblock_size=512) as h5:
        h5.create_dataset("imu", data=np.column_stack([o.dtheta, o.dvel, o.time]).T)
    with open(src, "r+b") as fh:
        head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
        fh.write(head.ljust(116) + b"\0" * 8 + b"\x00\x02IM")
    out = tmp_path / "o.h5"
    code, _, se = run("import", src, "--format", "mat", "--out", out, *p19.site, "--path", p19.path_toml)
    assert code == 0, se
    assert np.array_equal(io.read_record(out).dvel, o.dvel)


# ----------------------------------------------------------------------------- refusals and --force
SITE = ["--lat", 45, "--lon", 10, "--height", 50]


def _static_base(tmp_path):
    """The good files the corpus was cut from: a static E-N-U IMU, 10 Hz, 50 samples, 45 deg N."""
    rng = np.random.default_rng(1)
    lat, dt, n = math.radians(45.0), 0.1, 50
    t = (np.arange(n) + 1) * dt
    dth = np.tile(earth.OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)]) * dt, (n, 1)) + 1e-8 * rng.standard_normal((n, 3))
    dv = np.tile([0.0, 0.0, earth.normal_gravity(lat, 50.0) * dt], (n, 1)) + 1e-5 * rng.standard_normal((n, 3))
    good = tmp_path / "good.csv"
    good.write_text("\n".join([",".join(importers.EXPORT_HEADER)] + [",".join("%.10g" % v for v in r)
                                                                     for r in np.column_stack([t, dth, dv])]) + "\n")
    txt = tmp_path / "good.txt"
    np.savetxt(txt, np.column_stack([np.degrees(dth) * 3600, dv, t]), fmt="%.10g")
    mapping = tmp_path / "good.toml"
    mapping.write_text('[columns]\ngx = 0\ngy = 1\ngz = 2\nax = 3\nay = 4\naz = 5\ntime = 6\n'
                       '[units]\ngyro = "arcsec"\naccel = "m/s"\n')
    gimbal = tmp_path / "gimbal.csv"
    gimbal.write_text("time,outer,inner\n" + "".join(f"{x:.2f},0,0\n" for x in np.arange(0, 5.01, 0.05)))
    path = tmp_path / "path.toml"
    path.write_text('[path]\nname = "rest"\nmoves = [{axis = "none", dwell_s = 6.0}]\n')
    return SimpleNamespace(csv=good, txt=txt, mapping=mapping, gimbal=gimbal, path=path)


#: file -> (role, expected one-line message, extra arguments).  Roles: "data" (the file is the
#: source, format from its suffix), "mapping" (good.txt read through it), "gimbal" / "path"
#: (good.csv imported with it).
CORPUS = {
    "empty.csv": ("data", "empty.csv: file is empty", []),
    "header_only.csv": ("data", "no data rows after the 1 header row(s)", []),
    "no_header.csv": ("data", "the first line is not the inscal export header", []),
    "wrong_column_count.csv": ("data", "line 12 has 6 field(s), expected 7 (as on line 2)", []),
    "text_in_number.csv": ("data", "line 8, column 3 ('dtheta_z [rad]'): '7.3O3e-06' is not a number", []),
    "empty_field.csv": ("data", "line 15, column 2 ('dtheta_y [rad]'): empty field", []),
    "not_utf8.csv": ("data", "not a text file (not UTF-8)", []),
    "nan_value.csv": ("data", "ay (column 5 'dvel_y [m/s]') has 1 NaN/Inf value(s), first at line 20", []),
    "inf_time.csv": ("data", "time (column 0) has 1 NaN/Inf value(s), first at line 27", []),
    "backwards_time.csv": ("data", "time (column 0) goes backwards at line 31 (t = 2.9 s after 3 s", []),
    "repeated_time.csv": ("data", "time (column 0) repeats at line 35 (t = 3.3 s twice", []),
    "time_gap.csv": ("data", "1 gap(s) over 1.5 sample intervals; the largest is 1.2 s (about 11 missing sample(s)) "
                             "at line 22", []),
    "jittery_time.csv": ("data", "is not uniform: steps vary by up to 0.0144", []),
    "rate_mismatch.csv": ("data", "--rate-hz 10 is inconsistent with the timestamps: 12.5 Hz", ["--rate-hz", 10]),
    "degrees_not_radians.csv": ("data", "the values look like degrees, not radians", []),
    "g_not_mps.csv": ("data", "accelerometers read 0.999935 m/s^2", []),
    "rates_not_increments.csv": ("data", "or rates, not increments", []),
    "integer_counts.csv": ("data", "gy (column 2 'dtheta_y [rad]') holds only whole numbers", []),
    "constant_channel.csv": ("data", "gx (column 1 'dtheta_x [rad]') is constant (0) over all 50 samples", []),
    "saturated_channel.csv": ("data", "gz (column 3 'dtheta_z [rad]') looks saturated: pinned at its maximum", []),
    "truncated.bin": ("data", "2797 bytes is not a whole number of 7-value float64 rows", []),
    "float32_as_float64.bin": ("data", "(is the file float32? try --dtype float32)", []),
    "nan_sample.bin": ("data", "dvx (column 4) has 1 NaN/Inf value(s), first at row 10", []),
    "backwards_time.bin": ("data", "time goes backwards at row 30 (t = 2.8 s after 2.9 s", []),
    "rates_not_increments.bin": ("data", "or rates, not increments", []),
    "int32.mat": ("data", "variable 'imu' holds integers (int32)", []),
    "six_columns.mat": ("data", "no 2-D numeric variable with 7 columns [dθ dv t]; variables: imu (50x6 float64)", []),
    "strings_only.mat": ("data", "no 2-D numeric variable with 7 columns [dθ dv t]; variables: name", []),
    "not_a_mat.mat": ("data", "not a readable MAT file", []),
    "mapping_unknown_key.toml": ("mapping", "mapping: unknown key(s) ['colums']", []),
    "mapping_unknown_unit.toml": ("mapping", "[units] gyro: unknown unit 'furlong'", []),
    "mapping_rate_unit_for_increments.toml": ("mapping", "unit 'deg/s' is a rate unit, expected a angle unit", []),
    "mapping_axes_not_permutation.toml": ("mapping", "axes must be a permutation", []),
    "mapping_column_out_of_range.toml": ("mapping", "column index 9 (for az) is out of range: rows have 7 columns", []),
    "mapping_malformed.toml": ("mapping", "mapping_malformed.toml: malformed TOML", []),
    "mapping_counts_without_scale.toml": ("mapping", "gyro = \"counts\" needs gyro_scale", []),
    "mapping_swapped_units.toml": ("mapping", "the values look like arcsec, not radians", []),
    "mapping_name_without_header.toml": ("mapping", "columns given by name need header_rows >= 1", []),
    "gimbal_short.csv": ("gimbal", "gimbal_short.csv: the angles cover t = 0 .. 3 s; the record needs t = 0.1 .. 5 s",
                         []),
    "gimbal_backwards.csv": ("gimbal", "gimbal time does not increase at line 42", []),
    "path_too_short.toml": ("path", "path 'short' lasts 2 s, but the record runs 5 s", []),
    "path_unknown_key.toml": ("path", "[path]: unknown path keys ['speed']", []),
    "path_in_scenario_file.toml": ("path", "a path file holds one [path] table", []),
}
FORMAT = {".csv": "csv", ".txt": "txt", ".bin": "psins", ".mat": "mat"}


def _corpus_args(name, good):
    role, _, extra = CORPUS[name]
    f = BAD / name
    src = {"data": f, "mapping": good.txt, "gimbal": good.csv, "path": good.csv}[role]
    args = [src, "--format", FORMAT[src.suffix]]
    if role == "mapping":
        args += ["--mapping", f]
    elif role in ("gimbal", "path"):
        args += [f"--{role}", f]
    return args + extra


def test_corpus_is_complete_and_small():
    files = sorted(p.name for p in BAD.iterdir())
    assert files == sorted(CORPUS) and len(files) >= 20
    assert sum(p.stat().st_size for p in BAD.iterdir()) < 200_000


def test_corpus_base_files_import(tmp_path):
    """The control: the good files the corpus cases start from import with the same arguments."""
    good = _static_base(tmp_path)
    for args in ([good.csv, "--format", "csv"], [good.txt, "--format", "txt", "--mapping", good.mapping],
                 [good.csv, "--format", "csv", "--gimbal", good.gimbal], [good.csv, "--format", "csv", "--path", good.path]):
        out = tmp_path / "ok.h5"
        code, _, se = run("import", *args, "--out", out, *SITE)
        assert code == 0, (args, se)
        assert io.read_record(out).n_samples == 50
        out.unlink()


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus_file_is_refused_with_one_line(tmp_path, name):
    good = _static_base(tmp_path)
    before = listing(tmp_path)
    out = tmp_path / "out.h5"
    code, stdout, stderr = run("import", *_corpus_args(name, good), "--out", out, *SITE)
    assert code == 2, stdout + stderr
    assert stderr.startswith("inscal: error: ") and stderr.count("\n") == 1, stderr
    assert CORPUS[name][1] in stderr, stderr
    assert listing(tmp_path) == before  # no output, no temporary file left


def test_site_is_required_and_may_come_from_the_mapping(tmp_path):
    good = _static_base(tmp_path)
    out = tmp_path / "o.h5"
    code, _, se = run("import", good.csv, "--format", "csv", "--out", out)
    assert code == 2 and "no site: give --lat, --lon and --height" in se
    code, _, se = run("import", good.csv, "--format", "csv", "--out", out, "--lat", 45)
    assert code == 2 and "missing --lon, --height" in se
    assert not out.exists()
    good.mapping.write_text(good.mapping.read_text() + "[site]\nlatitude_deg = 45\nlongitude_deg = 10\nheight_m = 50\n")
    assert run("import", good.txt, "--format", "txt", "--mapping", good.mapping, "--out", out)[0] == 0
    assert io.read_record(out).site.height == 50.0
    code, _, se = run("import", good.txt, "--format", "txt", "--mapping", good.mapping, "--out", tmp_path / "p.h5",
                      "--height", 1000)  # a partial override of the mapping's site
    assert code == 0, se
    assert io.read_record(tmp_path / "p.h5").site.height == 1000.0
    # --gravity with the site from the mapping's [site] table (was an AttributeError on the missing site)
    code, _, se = run("import", good.txt, "--format", "txt", "--mapping", good.mapping, "--out", tmp_path / "g.h5",
                      "--gravity", "9.780327")
    assert code == 0, se
    site = io.read_record(tmp_path / "g.h5").site
    assert site.height == 50.0 and site.gravity == pytest.approx(9.780327)


def test_force_semantics_for_import_and_export(tmp_path):
    good = _static_base(tmp_path)
    out = tmp_path / "o.h5"
    assert run("import", good.csv, "--format", "csv", "--out", out, *SITE)[0] == 0
    first = out.read_bytes()
    code, _, se = run("import", good.txt, "--format", "txt", "--mapping", good.mapping, "--out", out, *SITE)
    assert code == 2 and "exists; use --force" in se and out.read_bytes() == first
    code, _, se = run("import", good.txt, "--format", "txt", "--mapping", good.mapping, "--out", out, *SITE, "--force")
    assert code == 0, se
    assert json.loads(h5py.File(out)["/"].attrs["source"])["format"] == "txt"
    code, _, se = run("import", good.csv, "--format", "csv", "--out", good.csv, *SITE, "--force")
    assert code == 2 and "--out must differ from the source" in se
    csv = tmp_path / "e.csv"
    assert run("export", out, "--format", "csv", "--out", csv)[0] == 0
    text = csv.read_text()
    code, _, se = run("export", out, "--format", "psins", "--out", csv)
    assert code == 2 and "exists; use --force" in se and csv.read_text() == text
    assert run("export", out, "--format", "psins", "--out", csv, "--force")[0] == 0
    assert csv.stat().st_size == 50 * 56
    # a record without gimbal angles has none to export; a csv export carries them itself
    before = listing(tmp_path)
    code, _, se = run("export", out, "--format", "psins", "--out", tmp_path / "x.bin", "--gimbal-out", tmp_path / "g.csv")
    assert code == 2 and "no gimbal angles" in se and listing(tmp_path) == before
    code, _, se = run("export", out, "--format", "csv", "--out", tmp_path / "x.csv", "--gimbal-out", tmp_path / "g.csv")
    assert code == 2 and "applies to psins/mat" in se and listing(tmp_path) == before
    code, _, se = run("export", out, "--format", "psins", "--out", tmp_path / "x.bin", "--path-out", tmp_path / "p.toml")
    assert code == 2 and "no rotation path" in se and listing(tmp_path) == before
    code, _, se = run("export", out, "--format", "psins", "--out", tmp_path / "x.bin", "--path-out", tmp_path / "x.bin")
    assert code == 2 and "must be different files" in se and listing(tmp_path) == before
    code, _, se = run("export", out, "--format", "xls", "--out", tmp_path / "x.xls")
    assert code == 2 and "unknown --format 'xls'" in se


def test_bad_options_are_one_line_errors(tmp_path):
    good = _static_base(tmp_path)
    before = listing(tmp_path)
    out = tmp_path / "o.h5"
    cases = [
        (["--format", "xlsx"], "unknown --format 'xlsx'"),
        (["--format", "csv", "--skip-check", "units"], "--skip-check units: unknown"),
        (["--format", "csv", "--dtype", "float32"], "--dtype applies to --format psins"),
        (["--format", "csv", "--rates"], "set kind = \"rates\" in the mapping"),
        (["--format", "csv", "--gimbal-unit", "grad"], "--gimbal-unit must be deg or rad"),
        (["--format", "txt"], "--format txt needs --mapping"),
        (["--format", "csv", "--rate-hz", -5], "--rate-hz must be positive"),
        (["--format", "csv", "--lat", 95, "--lon", 0, "--height", 0], "latitude must be within"),
    ]
    for extra, msg in cases:
        args = ["import", good.csv, "--out", out] + extra + ([] if "--lat" in extra else SITE)
        code, _, se = run(*args)
        assert code == 2 and msg in se and se.count("\n") == 1, (extra, se)
    assert listing(tmp_path) == before


def test_skip_check_imports_a_flagged_file(tmp_path):
    out = tmp_path / "o.h5"
    code, _, se = run("import", BAD / "constant_channel.csv", "--format", "csv", "--out", out, *SITE,
                      "--skip-check", "constant")
    assert code == 0, se
    assert np.all(io.read_record(out).dtheta[:, 0] == 0)
    code, so, se = run("import", BAD / "jittery_time.csv", "--format", "csv", "--out", tmp_path / "j.h5", *SITE,
                       "--rate-hz", 10, "--json")
    assert code == 0, se
    assert json.loads(so)["time_regridded"] is True


# ----------------------------------------------------------------------------- PSINS compact .imu
def _write_psins_imu(path, time, dtheta, dvel, lat_deg, lon_deg, h, scales=(0.1, 0.1, 0.1, 125.0, 125.0, 125.0),
                     g=9.7803267714, dither=False):
    """A PSINS compact text log written from the format's description (header comment, attitude /
    site / scale-factor rows, then whole counts of the running sums, so the rounding does not
    accumulate), independently of inscal's reader."""
    q = np.array(scales[:3]) * math.pi / 180 / 3600
    qa = np.array(scales[3:]) * 1e-6 * g
    counts = np.diff(np.vstack([np.zeros((1, 6)), np.trunc(np.cumsum(np.hstack([dtheta / q, dvel / qa]), axis=0))]),
                     axis=0).astype(np.int64)
    ts = float(time[1] - time[0])
    t0 = float(time[0] - ts)
    with open(path, "w") as fh:
        fh.write("% PSINS-format SIMU log file. (DO NOT MODIFY!)\n% written by the inscal tests\n\n")
        fh.write("0.000000 0.000000 0.000000 0.000000 0.000000 0.000000\n")
        fh.write(f"{lat_deg:.8f} {lon_deg:.8f} {h:.3f} {t0:.8f} {ts * 1000:.8f} {g:f}\n")
        fh.write(" ".join(f"{s:f}" for s in scales) + "\n\n")
        if dither:
            d = np.zeros((len(counts), 1), np.int64)
            np.savetxt(fh, np.hstack([counts, d]), fmt="%d")
        else:
            np.savetxt(fh, counts, fmt="%d")
    return q, qa


def test_psins_imu_log_imports_with_its_header_site_rate_and_scales(p19, tmp_path):
    """``--format psins-imu`` reads the site, start time, interval, g and scale factors from the
    header (no --lat/--lon/--height): increments within one quantum of the original's running sums,
    and the calibration of the quantized record within the quantum's share of the truth."""
    o = p19.rec
    lat, lon, h = math.degrees(o.site.latitude), math.degrees(o.site.longitude), o.site.height
    src = tmp_path / "run.imu"
    q, qa = _write_psins_imu(src, o.time, o.dtheta, o.dvel, lat, lon, h, dither=True)
    out = tmp_path / "imu.h5"
    code, so, se = run("import", src, "--format", "psins-imu", "--out", out, "--path", p19.path_toml, "--json")
    assert code == 0, se
    s = json.loads(so)
    assert s["site"]["latitude_deg"] == pytest.approx(lat, abs=1e-8) and s["site"]["height_m"] == pytest.approx(h, abs=1e-3)
    r = io.read_record(out)
    assert r.rate_hz == pytest.approx(o.rate_hz, rel=1e-9) and np.allclose(r.time, o.time, atol=1e-9)
    assert np.abs(np.cumsum(r.dtheta, 0) - np.cumsum(o.dtheta, 0)).max() <= 1.0001 * q.max()
    assert np.abs(np.cumsum(r.dvel, 0) - np.cumsum(o.dvel, 0)).max() <= 1.0001 * qa.max()
    res, ref = calibrate(r, "joint"), p19.cal("joint", encoders=False)
    sf = np.abs(param_value(res.imu, res.gimbal, "gyro_scale_factor") - param_value(ref.imu, ref.gimbal, "gyro_scale_factor"))
    ab = np.abs(param_value(res.imu, res.gimbal, "accel_bias") - param_value(ref.imu, ref.gimbal, "accel_bias"))
    # a window mean's rounding error is at most two quanta over the window: 125 ug*s over >= 20 s dwells
    assert sf.max() < 1e-6 and ab.max() < 2 * qa.max() / 20.0, (sf, ab)
    # a site given on the command line wins over the header's
    code, so, se = run("import", src, "--format", "psins-imu", "--out", tmp_path / "site.h5", "--lat", 10, "--lon", 0,
                       "--height", 0, "--skip-check", "magnitudes", "--json")
    assert code == 0, se
    assert json.loads(so)["site"]["latitude_deg"] == 10


@pytest.mark.parametrize("edit, phrase", [
    (lambda t: t.replace("% PSINS-format SIMU log file", "% some other log"), "not a PSINS .imu log"),
    (lambda t: t.rsplit("\n", 2)[0] + "\n1 2 3\n", "has 3 values, the rows before 7"),
    (lambda t: t.rsplit("\n", 2)[0] + "\n1 2 3 4.5 5 6 0\n", "counts must be whole numbers"),
    (lambda t: t.replace("9.780327", "0.000000", 1), "not a gravity value"),
    (lambda t: "\n".join(t.splitlines()[:6]) + "\n", "needs 3 header rows and at least 2 samples"),
    (lambda t: "\n".join(ln for ln in t.splitlines() if not ln.startswith("0.100000 0.100000")) + "\n",
     "scale-factor row (the 3rd) is missing"),
])
def test_psins_imu_damaged_logs_are_refused_in_one_line(p19, tmp_path, edit, phrase):
    o = p19.rec
    src = tmp_path / "run.imu"
    _write_psins_imu(src, o.time[:200], o.dtheta[:200], o.dvel[:200], 34.0, 108.0, 400.0, dither=True)
    src.write_text(edit(src.read_text()))
    code, _, se = run("import", src, "--format", "psins-imu", "--out", tmp_path / "x.h5")
    assert code == 2 and phrase in se and len(se.strip().splitlines()) == 1, se
    assert not (tmp_path / "x.h5").exists()


def test_psins_imu_log_refuses_a_mapping_of_columns(p19, tmp_path):
    """A .imu log's columns and scales are its header's: a mapping with [columns] is refused, not ignored."""
    o = p19.rec
    src = tmp_path / "run.imu"
    _write_psins_imu(src, o.time[:200], o.dtheta[:200], o.dvel[:200], 34.0, 108.0, 400.0)
    (tmp_path / "m.toml").write_text('[columns]\ngx = 1\ngy = 2\ngz = 3\nax = 4\nay = 5\naz = 6\ntime = 0\n')
    code, _, se = run("import", src, "--format", "psins-imu", "--mapping", tmp_path / "m.toml", "--out", tmp_path / "x.h5")
    assert code == 2 and "a psins-imu mapping may only hold [site]" in se and len(se.strip().splitlines()) == 1, se
    assert not (tmp_path / "x.h5").exists()


def test_ug_seconds_is_a_velocity_increment_unit_of_mappings():
    from inscal.core import units
    from inscal.io.mapping import parse_mapping

    assert units.to_si(125.0, "ug*s", "velocity") == pytest.approx(125e-6 * units.G0)
    assert units.to_si(1.0, "µg*s", "velocity") == units.to_si(1.0, "ug*s")
    m, _ = parse_mapping({"columns": {"time": 0, "gx": 1, "gy": 2, "gz": 3, "ax": 4, "ay": 5, "az": 6},
                                    "units": {"gyro": "counts", "gyro_scale": "0.1 arcsec", "accel": "counts",
                                              "accel_scale": "125 ug*s"}}, "csv")
    assert m.accel_scale == pytest.approx(125e-6 * units.G0) and m.gyro_scale == pytest.approx(0.1 * math.pi / 648000)


def test_systematic_calibrates_a_quantized_psins_imu_log_with_its_defaults(p19, tmp_path):
    """A noise-free log quantized to 0.1" and 125 ug*s estimates a noise of exactly zero (most second
    differences vanish); the filter's noise then comes from the data's own quantum, found in the
    counts, and every parameter lies within 3 sigma of the truth (the sigma is conservative: the
    running-sum rounding of a PSINS log does not accumulate as white noise would)."""
    o = p19.rec
    src = tmp_path / "run.imu"
    _write_psins_imu(src, o.time, o.dtheta, o.dvel, math.degrees(o.site.latitude), math.degrees(o.site.longitude),
                     o.site.height)
    out = tmp_path / "imu.h5"
    assert run("import", src, "--format", "psins-imu", "--out", out)[0] == 0
    res = calibrate(io.read_record(out), "systematic51")
    noise = res.diagnostics["noise"]
    assert noise["resolution_floored"]
    assert noise["resolution"]["gyro_arcsec"] == pytest.approx([0.1] * 3, rel=1e-6)
    assert noise["resolution"]["accel_ug_s"] == pytest.approx([125.0 * 9.7803267714 / 9.80665] * 3, rel=1e-6)
    truth = p19.rec.truth
    bad = []
    for name, e in res.to_field((truth.imu, truth.gimbal)).items():
        err, sig = np.abs(np.asarray(e["error"], float)), np.asarray(e["sigma"], float)
        if np.any(err > 3 * sig):
            bad.append((name, err.tolist(), sig.tolist()))
    assert not bad, bad
