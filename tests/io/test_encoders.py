"""Encoder checks (inscal.io.encoders): the encoder angles against the gyros move by move, the
latency estimate, and the import with --gimbal / --encoder-latency.  Each corruption of the angles
(a radian/degree mix-up, a flipped sign, swapped columns, a 20-ms shift either way) is named,
by the library function and by ``inscal import`` (one line, exit 2, nothing written)."""

import dataclasses
import json
import math
import re
import time
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal.calibrate import calibrate
from inscal.cli.app import app
from inscal.core.attitude import quat_to_dcm
from inscal.core.earth import OMEGA_IE
from inscal.core.error_model import ImuNoise
from inscal.core.turntable import C_s_b
from inscal import io
from inscal.io.encoders import (
    EncoderError,
    apply_latency,
    body_rates,
    check_record_encoders,
    compare_encoders,
    estimate_latency,
    gimbal_quaternion,
    moving_runs,
)
from inscal.sim import scenarios
from inscal.sim.simulate import simulate, write_simulation

runner = CliRunner()
MS = 1e-3


def run(*args):
    r = runner.invoke(app, [str(a) for a in args])
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def sims():
    """Noise-free and noisy (seeded) simulations of n25 and psins19 (both dual-axis, 100 Hz)."""
    out = {}
    for name in ("n25", "psins19"):
        sc = scenarios.build(name)
        out[name, "noise-free"] = simulate(dataclasses.replace(sc, noise=ImuNoise()), None, keep_truth=True)
        out[name, "noisy"] = simulate(sc, np.random.default_rng(7))
    return out


#: corruption -> (what it does to the angles (time, gimbal), the cause named, phrases of the message)
CORRUPTIONS = {
    "radians as degrees": (lambda t, g: g * (math.pi / 180), "radians-as-degrees",
                           ["radians read as degrees", "--gimbal-unit rad", 'gimbal = "rad"']),
    "degrees as radians": (lambda t, g: g * (180 / math.pi), "degrees-as-radians",
                           ["degrees read as radians", "--gimbal-unit deg", 'gimbal = "deg"']),
    "outer sign": (lambda t, g: g * [-1.0, 1.0], "outer-sign", ["the outer angle has the wrong sign"]),
    "inner sign": (lambda t, g: g * [1.0, -1.0], "inner-sign", ["the inner angle has the wrong sign"]),
    "swapped": (lambda t, g: g[:, ::-1], "swapped", ["the outer and inner columns are swapped"]),
    "+20 ms": (lambda t, g: apply_latency(t, g, -0.020), "latency", ["the encoders lag the IMU by ", " ms +- "]),
    "-20 ms": (lambda t, g: apply_latency(t, g, 0.020), "latency", ["the encoders lead the IMU by ", " ms +- "]),
}


def suggested_latency(message: str) -> float:
    """The value a latency message tells to give to --encoder-latency."""
    m = re.search(r"--encoder-latency (\S+) to correct", message)
    assert m, message
    return float(m.group(1))
CASES = [(n, k) for n in ("n25", "psins19") for k in ("noise-free", "noisy")]


# ----------------------------------------------------------------------------- geometry
def test_gimbal_quaternion_is_the_turntable_attitude():
    rng = np.random.default_rng(1)
    ang = rng.uniform(-7, 7, size=(20, 2))
    for (tx, tz), q in zip(ang, gimbal_quaternion(ang)):
        assert np.abs(quat_to_dcm(q) - C_s_b(tx, tz)).max() < 1e-14


def test_body_rates_are_the_true_increments_less_earth_rate(sims):
    """The body rate of the encoders over each interval is the simulator's (kinematics.rates_at)
    true increment over it, to the Earth rate: exact for one axis turning at a time."""
    d = sims["psins19", "noise-free"]
    w = body_rates(d.gimbal, 100.0)
    err = np.linalg.norm(d.true_dtheta[1:] * 100.0 - w, axis=1)
    assert np.abs(w).max() > 0.17 and err.max() < 1.0001 * OMEGA_IE


def test_apply_latency_shifts_and_holds_the_ends():
    t = (np.arange(1000) + 1) * 0.01
    g = np.column_stack([np.sin(t), t**2])
    late = apply_latency(t, g, -0.02)  # encoders that lag by 20 ms
    assert np.allclose(late[2:], g[:-2]) and np.array_equal(late[:2], np.tile(g[0], (2, 1)))
    assert np.allclose(apply_latency(t, late, 0.02)[:-2], g[:-2])
    half = apply_latency(t, g, 0.005)
    assert np.allclose(half[:-1], 0.5 * (g[:-1] + g[1:])) and np.array_equal(half[-1], g[-1])
    assert np.array_equal(apply_latency(t, g, 0.0), g)


# ----------------------------------------------------------------------------- library
@pytest.mark.parametrize("name,kind", CASES)
def test_as_given_agree_with_no_latency(sims, name, kind):
    d = sims[name, kind]
    res = compare_encoders(d.dtheta, d.gimbal, 100.0, d.time)
    assert res.ok and res.cause == "ok" and res.message == "", res.message
    assert res.n_moves == {"n25": 27, "psins19": 18}[name] and res.max_residual_deg < 0.05
    assert abs(res.latency_s) < 0.5 * MS and 0 <= res.latency_sigma_s < 0.2 * MS, (res.latency_s, res.latency_sigma_s)
    assert all(m.residual_deg <= m.tolerance_deg for m in res.moves)
    assert json.loads(json.dumps(res.to_dict()))["moves"] == res.n_moves


@pytest.mark.parametrize("name,kind", CASES)
@pytest.mark.parametrize("corruption", CORRUPTIONS)
def test_each_corruption_is_named(sims, name, kind, corruption):
    d = sims[name, kind]
    change, cause, phrases = CORRUPTIONS[corruption]
    res = compare_encoders(d.dtheta, change(d.time, d.gimbal), 100.0, d.time)
    assert not res.ok and res.cause == cause, res.message
    assert "\n" not in res.message and all(p in res.message for p in phrases), res.message
    if cause == "latency":
        sign = 1.0 if corruption.startswith("+") else -1.0
        assert abs(res.latency_s - sign * 0.020) < 0.5 * MS and res.latency_sigma_s < 0.2 * MS
        assert abs(suggested_latency(res.message) - sign * 0.020) < 0.5 * MS
    else:
        assert {h[0]: h[2] for h in res.hypotheses}[cause] == res.n_moves  # every move agrees changed so


def test_latency_estimates_are_sub_sample_and_large_ones_are_found(sims):
    d = sims["psins19", "noisy"]
    for shift in (-0.0123, 0.003, 0.5):
        delta, sigma = estimate_latency(d.dtheta, apply_latency(d.time, d.gimbal, -shift), 100.0, d.time)
        assert abs(delta - shift) < 0.2 * MS and sigma < 0.1 * MS, (shift, delta, sigma)
    # a 3-ms latency (under a sample) is reported, not refused
    res = compare_encoders(d.dtheta, apply_latency(d.time, d.gimbal, -0.003), 100.0, d.time)
    assert res.ok and abs(res.latency_s - 0.003) < 0.2 * MS
    # half a second: the moves no longer agree as given, and the latency explains it
    res = compare_encoders(d.dtheta, apply_latency(d.time, d.gimbal, -0.5), 100.0, d.time)
    assert res.cause == "latency" and "--encoder-latency 0.5 to correct" in res.message, res.message


def test_an_encoder_glitch_is_a_disagreement_named_with_its_move_and_time(sims):
    d = sims["n25", "noisy"]
    g = d.gimbal.copy()
    g[d.time > 700.0, 1] += 0.5 * math.pi / 180  # the inner encoder jumps by 0.5 deg in a dwell
    res = compare_encoders(d.dtheta, g, 100.0, d.time)
    assert res.cause == "disagree", res.message
    assert "disagree by 0.5 deg on move 6 of 28 at t = 700.0" in res.message, res.message
    assert "no unit, sign, column or latency error explains it" in res.message


def test_encoders_interpolated_from_5_hz_agree_with_no_latency(sims):
    """Encoder readings at 5 Hz interpolated to 100 Hz: the chords cut the accelerations, but the
    rotations agree and no latency appears (the chord errors cancel between speeding up and
    slowing down)."""
    d = sims["psins19", "noise-free"]
    k = np.append(np.arange(0, d.time.size, 20), d.time.size - 1)
    g = np.column_stack([np.interp(d.time, d.time[k], d.gimbal[k, j]) for j in range(2)])
    res = compare_encoders(d.dtheta, g, 100.0, d.time)
    assert res.ok and abs(res.latency_s) < 2 * MS, res


def test_record_api_and_a_record_without_moves(sims):
    d = sims["psins19", "noisy"]
    rec = SimpleNamespace(time=d.time, dtheta=d.dtheta, gimbal=d.gimbal * [-1, 1], rate_hz=100.0)
    assert check_record_encoders(SimpleNamespace(**(vars(rec) | {"gimbal": None}))) is None
    assert check_record_encoders(rec).cause == "outer-sign"
    with pytest.raises(EncoderError, match="the outer angle has the wrong sign"):
        check_record_encoders(rec, strict=True)
    rest = slice(0, 8000)  # the first 80 s: at rest
    res = compare_encoders(d.dtheta[rest], d.gimbal[rest], 100.0)
    assert res.ok and res.cause == "no-moves" and res.n_moves == 0 and math.isnan(res.latency_s)
    a, b = moving_runs(d.dtheta, d.gimbal, 100.0)
    assert a.size == 18 and np.all(np.abs(np.diff(d.gimbal, axis=0))[np.r_[a, b]].max() < 1e-12)


def test_one_hour_record_in_well_under_a_second():
    sc = dataclasses.replace(scenarios.build("n25-rotmod", duration_s=3600.0), noise=ImuNoise())
    d = simulate(sc)
    n = 360_000
    dth, g, t = d.dtheta[:n], d.gimbal[:n], d.time[:n]
    for gimbal, cause in ((g, "ok"), (g * [-1, 1], "outer-sign"), (apply_latency(t, g, -0.02), "latency")):
        best = math.inf
        for _ in range(2):
            t0 = time.process_time()  # CPU seconds: the limit holds on a loaded machine too
            res = compare_encoders(dth, gimbal, 100.0, t)
            best = min(best, time.process_time() - t0)
        assert res.cause == cause and best < 0.5, (cause, best)


# ----------------------------------------------------------------------------- inscal import
def _write_gimbal(path, t, g, unit="rad"):
    """The rows of ``np.savetxt(fmt="%.17g", delimiter=",")`` under a header, formatted in one go (the same
    bytes, in half the time: these files have 100 000 - 250 000 rows)."""
    rows = np.column_stack([t, g])
    body = ("%.17g,%.17g,%.17g\n" * len(rows)) % tuple(rows.ravel())
    path.write_text(f"time [s],outer [{unit}],inner [{unit}]\n" + body)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """Noisy psins19 and n25 records exported as PSINS .bin plus the gimbal csv (export --gimbal-out)."""
    out = {}
    for name in ("psins19", "n25"):
        d = tmp_path_factory.mktemp(name)
        f = d / "rec.h5"
        write_simulation(f, scenarios.build(name), np.random.default_rng(3))
        assert run("export", f, "--format", "psins", "--out", d / "r.bin", "--gimbal-out", d / "g.csv")[0] == 0
        rec = io.read_record(f)
        s = rec.site
        site = ["--lat", math.degrees(s.latitude), "--lon", math.degrees(s.longitude), "--height", s.height]
        out[name] = SimpleNamespace(dir=d, rec=rec, site=site, bin=d / "r.bin", gimbal=d / "g.csv")
    return out


def test_export_import_round_trip_agrees_with_no_latency(exported, n25_imports):
    x = exported["n25"]
    assert x.gimbal.read_text().split("\n", 1)[0] == "time [s],outer [rad],inner [rad]"
    s = n25_imports.plain_json  # import --gimbal (the exported file) --json
    enc = s["encoders"]
    assert enc["ok"] and enc["moves"] == 27 and abs(enc["latency_s"]) < 0.5 * MS and enc["latency_sigma_s"] < 0.2 * MS
    assert s["encoder_latency_s"] == 0.0
    code, so, _ = run("import", x.bin, "--format", "psins", "--gimbal", x.gimbal, *x.site, "--out", x.dir / "b.h5")
    assert code == 0 and "encoders agree with the gyros on 27 moves" in so


@pytest.mark.parametrize("corruption", CORRUPTIONS)
def test_import_names_each_corruption_in_one_line(exported, corruption, tmp_path):
    x = exported["psins19"]
    change, cause, phrases = CORRUPTIONS[corruption]
    g = x.rec.gimbal
    if cause == "radians-as-degrees":  # radians in a file whose header says degrees
        _write_gimbal(tmp_path / "g.csv", x.rec.time, g, "deg")
    elif cause == "degrees-as-radians":
        _write_gimbal(tmp_path / "g.csv", x.rec.time, np.degrees(g), "rad")
    else:
        _write_gimbal(tmp_path / "g.csv", x.rec.time, change(x.rec.time, g))
    code, _, se = run("import", x.bin, "--format", "psins", "--gimbal", tmp_path / "g.csv", *x.site,
                      "--out", tmp_path / "o.h5")
    assert code == 2 and se.startswith("inscal: error: ") and se.count("\n") == 1, se
    assert all(p in se for p in phrases), se
    assert "--skip-check" in se and not (tmp_path / "o.h5").exists()
    if cause == "latency":
        assert suggested_latency(se) == (0.02 if corruption.startswith("+") else -0.02), se
    if cause in ("radians-as-degrees", "degrees-as-radians"):  # the motion check names those first; past it:
        assert "(--skip-check motion to import anyway)" in se
        code, _, se = run("import", x.bin, "--format", "psins", "--gimbal", tmp_path / "g.csv", *x.site,
                          "--out", tmp_path / "o.h5", "--skip-check", "motion")
        assert code == 2 and se.count("\n") == 1 and all(p in se for p in phrases), se
        assert "to correct (--skip-check encoders to import anyway)" in se
    else:
        code, _, se = run("import", x.bin, "--format", "psins", "--gimbal", tmp_path / "g.csv", *x.site,
                          "--out", tmp_path / "o.h5", "--skip-check", "encoders")
        assert code == 0, se  # the motion check (magnitudes only) passes them


@pytest.fixture(scope="module")
def n25_imports(exported):
    """The n25 export imported with its own encoder file (``plain``, ``plain_json``: what ``--json`` said) and
    with that file 20 ms late (``late``) past the encoder check (``raw``); both imports exit 0."""
    x = exported["n25"]
    late = x.dir / "late.csv"
    _write_gimbal(late, x.rec.time, apply_latency(x.rec.time, x.rec.gimbal, -0.020))
    base = ("import", x.bin, "--format", "psins", *x.site, "--json")
    code, _, se = run(*base, "--gimbal", late, "--out", x.dir / "raw.h5", "--skip-check", "encoders")
    assert code == 0, se
    code, so, se = run(*base, "--gimbal", x.gimbal, "--out", x.dir / "plain.h5")
    assert code == 0, se
    return SimpleNamespace(late=late, raw=x.dir / "raw.h5", plain=x.dir / "plain.h5", plain_json=json.loads(so))


def test_encoder_latency_option_corrects_a_20_ms_shift_for_calibration(exported, n25_imports):
    """A 20-ms late encoder file is refused, imports clean with --encoder-latency 0.02, and the
    joint calibration of that import recovers the truth as well as the unshifted one (while the
    shifted angles imported as they are spoil it)."""
    x = exported["n25"]
    late = n25_imports.late
    base = ("import", x.bin, "--format", "psins", *x.site, "--json")
    code, _, se = run(*base, "--gimbal", late, "--out", x.dir / "late.h5")
    assert code == 2 and abs(suggested_latency(se) - 0.02) < 0.5 * MS, se
    assert not (x.dir / "late.h5").exists()
    code, so, se = run(*base, "--gimbal", late, "--out", x.dir / "fixed.h5", "--encoder-latency", 0.02)
    assert code == 0, se
    s = json.loads(so)
    assert s["encoder_latency_s"] == 0.02 and abs(s["encoders"]["latency_s"]) < 0.5 * MS
    err = {}
    for tag in ("plain", "fixed", "raw"):
        res = calibrate(io.read_record(x.dir / f"{tag}.h5"), "joint")
        f = res.to_field(x.rec.truth)
        err[tag] = {k: float(np.abs(f[k]["error"]).max()) for k in
                    ("gyro_scale_factor", "gyro_misalignment", "accel_scale_factor", "accel_misalignment", "accel_bias",
                     "gimbal_nonorthogonality")}
    for k, e in err["plain"].items():
        assert err["fixed"][k] <= 1.05 * e + 1e-3, (k, err["fixed"][k], e)
    assert err["raw"]["accel_misalignment"] > 10 * err["plain"]["accel_misalignment"], err


def test_encoder_latency_needs_encoder_angles_and_a_finite_value(exported, tmp_path):
    x = exported["psins19"]
    code, _, se = run("import", x.bin, "--format", "psins", *x.site, "--out", tmp_path / "o.h5",
                      "--encoder-latency", 0.01)
    assert code == 2 and "--encoder-latency applies to encoder angles" in se, se
    code, _, se = run("import", x.bin, "--format", "psins", *x.site, "--gimbal", x.gimbal, "--out", tmp_path / "o.h5",
                      "--encoder-latency", "nan")
    assert code == 2 and "--encoder-latency must be a finite shift" in se, se
    code, _, se = run("import", x.bin, "--format", "psins", *x.site, "--gimbal", x.gimbal, "--out", tmp_path / "o.h5",
                      "--skip-check", "encoder")
    assert code == 2 and "known checks: constant, saturation, magnitudes, motion, encoders" in se, se


def test_calibrate_checks_the_encoders_and_applies_a_latency(n25_imports, tmp_path):
    """``inscal calibrate`` compares the record's encoders with the gyros too: a record imported past the
    check with 20-ms late encoders is refused in one line naming the fix; ``--encoder-latency 0.02``
    calibrates it as the clean one; ``--skip-encoder-check`` calibrates it as it is."""
    raw = n25_imports.raw
    out = tmp_path / "p.toml"
    code, _, se = run("calibrate", raw, "--method", "joint", "--out", out)
    assert code == 2 and se.count("\n") == 1 and "the encoders lag the IMU by" in se and "--skip-encoder-check" in se, se
    assert abs(suggested_latency(se) - 0.02) < 0.5 * MS, se
    assert not out.exists()
    code, so, se = run("calibrate", raw, "--method", "joint", "--out", out, "--encoder-latency", 0.02,
                       "--json")
    assert code == 0, se
    rep = json.loads(so)
    assert rep["encoders"]["ok"] and abs(rep["encoders"]["latency_s"]) < 0.5 * MS
    assert rep["encoders"]["latency_applied_s"] == 0.02
    code, _, se = run("calibrate", raw, "--method", "joint", "--out", tmp_path / "q.toml",
                      "--skip-encoder-check")
    assert code == 0, se
    code, _, se = run("calibrate", raw, "--method", "joint", "--out", tmp_path / "r.toml",
                      "--encoder-latency", "nan")
    assert code == 2 and "--encoder-latency must be" in se


def test_a_half_sample_offset_is_named_at_import_and_as_the_cause_of_the_misfit(exported, tmp_path):
    """Encoders half a sample ahead of the increments (a driver that stamps each rate at the end of its
    averaging interval): the import passes it (under a sample) with a warning naming it, and the n25 fit,
    inconsistent by it, names it as the cause with the chi2 it leaves once shifted (within the 99 % band)."""
    x = exported["n25"]
    lead = tmp_path / "lead.csv"
    _write_gimbal(lead, x.rec.time, apply_latency(x.rec.time, x.rec.gimbal, 0.005))
    code, _, se = run("import", x.bin, "--format", "psins", *x.site, "--gimbal", lead, "--out", tmp_path / "o.h5")
    assert code == 0 and "inscal: warning: " in se and "the encoders lead the IMU by 5" in se, se
    assert "samples, half a sample: rates stamped at the end of their averaging interval" in se, se
    assert abs(float(re.search(r"--encoder-latency (\S+)\)", se).group(1)) + 0.005) < 0.3 * MS, se
    code, so, se = run("calibrate", tmp_path / "o.h5", "--method", "n25", "--out", tmp_path / "p.toml", "--json")
    assert code == 0, se
    fit = json.loads(so)["fit"]
    assert not fit["consistent"] and fit["chi2"] > 1e4, fit["chi2"]
    assert fit["cause"].startswith("the encoders lead the IMU by 5") and "half a sample" in fit["cause"], fit["cause"]
    after = float(fit["cause"].split(" the chi2 falls from ")[1].split(" to ")[1].split(" on ")[0])
    assert 173.2 < after < 282.3 and fit["cause"].endswith("on 224 dof (consistent)"), fit["cause"]
