"""Records too short for what is asked say so in one line: how many samples (seconds) they have and how
many the command needs.

``navigate`` on a 3-sample record printed NumPy's "zero-size array to reduction operation maximum
which has no identity"; now each command names the record, its samples and seconds, and what it needs
(``navigate``: one output row, after the alignment with ``--init align``; ``calibrate``: a coarse
alignment or a calibration window; ``report``: the noise section's first dwell, a warning since the
rest of the report is written).  ``compensate`` works on any record (two samples or more).
"""

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from inscal import io
from inscal import nav as nv
from inscal.cli.app import app
from inscal.nav.strapdown import NavConfig
from inscal.sim import scenarios
from inscal.sim.simulate import scenario_from_record, write_simulation


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    """``short(n)``: the first ``n`` samples of a 36 s error-free static record (100 Hz, with truth)."""
    d = tmp_path_factory.mktemp("short")
    full = d / "s.h5"
    write_simulation(full, scenarios.build("static", duration_s=36.0), None)
    rec = io.read_record(full)

    def cut(n: int):
        f = d / f"c{n}.h5"
        if not f.exists():
            io.write_record(f, dataclasses.replace(rec, time=rec.time[:n], dtheta=rec.dtheta[:n], dvel=rec.dvel[:n],
                                                   gimbal=None if rec.gimbal is None else rec.gimbal[:n]))
        return f

    cut.full = full
    return cut


def one_line_error(args, *phrases, outputs=()):
    """Exit 2, one ``inscal: error:`` line with every phrase, nothing written, the inputs unchanged."""
    inputs = [a for a in args if str(a).endswith(".h5") and a not in outputs]
    before = {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in inputs}
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 2, (r.exit_code, r.output, r.exception)
    assert r.stderr.startswith("inscal: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert "Traceback" not in r.output and "zero-size" not in r.stderr
    for ph in phrases:
        assert ph in r.stderr, (ph, r.stderr)
    for o in outputs:
        assert not o.exists()
    assert {str(p): hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in inputs} == before
    return r.stderr


@pytest.mark.parametrize("n", [2, 3, 99])
def test_navigate_names_the_samples_it_needs(short, tmp_path, n):
    out = tmp_path / "nav.h5"
    one_line_error(["navigate", short(n), "--out", out],
                   f"c{n}.h5: {n} samples ({n / 100:g} s at 100 Hz), too short to navigate: it needs 100 samples (1 s) "
                   "for one output at 1 Hz", outputs=[out])


def test_navigate_runs_once_one_output_fits(short):
    """The boundary: 100 samples give one output at 1 Hz; 3 samples one per sample at 100 Hz."""
    r = CliRunner().invoke(app, ["navigate", str(short(100)), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["samples"] == 100
    r = CliRunner().invoke(app, ["navigate", str(short(3)), "--output-rate-hz", "100", "--json"])
    assert r.exit_code == 0, r.output


def test_navigate_with_alignment_counts_the_alignment(short, tmp_path):
    one_line_error(["navigate", short.full, "--init", "align"],
                   "s.h5: 3600 samples (36 s at 100 Hz), too short to navigate: it needs 66100 samples (661 s) for "
                   "the alignment (60 s coarse + 600 s fine) and one output at 1 Hz")
    one_line_error(["navigate", short.full, "--init", "align", "--align-coarse-s", "30", "--align-fine-s", "5.5",
                    "--output-rate-hz", "0.1"], "it needs 4550 samples (45.5 s) for the alignment (30 s coarse + 5.5 s "
                   "fine) and one output at 0.1 Hz")


def test_the_navigator_itself_says_it(short):
    """:func:`inscal.nav.navigate` (the API under the command) refuses the same way, with the samples it saw."""
    rec = io.read_record(short(3))
    sc = scenario_from_record(io.record_info(short(3)))
    with pytest.raises(ValueError, match=r"^3 samples \(0\.03 s at 100 Hz\), too short to navigate: it needs 100 "):
        nv.navigate(nv.chunks_of(rec), rec.rate_hz, rec.site, init="truth", scenario=sc)
    assert nv.samples_needed(100.0, NavConfig(output_rate_hz=100.0)) == (1, "one output at 100 Hz")


@pytest.mark.parametrize("method, phrase", [
    ("systematic51", "coarse alignment needs at least 5 s of data, got 0.03 s"),
    ("unified", "coarse alignment needs at least 5 s of data, got 0.03 s"),
    ("joint", "record too short (3 samples, 0.0 s) to hold any calibration window"),
])
def test_calibrate_names_what_it_needs(short, tmp_path, method, phrase):
    out = tmp_path / "p.toml"
    one_line_error(["calibrate", short(3), "--method", method, "--out", out], "c3.h5: ", phrase, outputs=[out])


def test_compensate_works_on_two_samples(short, tmp_path):
    """Compensation is sample by sample (one sample of look-ahead for the asynchrony and size effect):
    a two-sample record is compensated, not refused."""
    params = tmp_path / "p.toml"
    params.write_text('kind = "inscal-parameters"\nschema_version = 1\nmethod = "manual"\n'
                      '[parameters.gyro_bias]\nvalue = [0.1, 0.0, 0.0]\nunit = "deg/h"\n'
                      '[parameters.time_asynchrony]\nvalue = 1.0\nunit = "ms"\n'
                      '[parameters.accel_lever_arm]\nvalue = [[1.0, 0, 0], [0, 2.0, 0], [0, 0, 3.0]]\nunit = "cm"\n')
    out = tmp_path / "c.h5"
    r = CliRunner().invoke(app, ["compensate", str(short(2)), "--params", str(params), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert io.read_record(out).n_samples == 2


def test_report_says_which_section_the_record_is_too_short_for(short, tmp_path):
    out = tmp_path / "r.html"
    r = CliRunner().invoke(app, ["report", str(short(3)), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    w = (f"{short(3)}: no noise (Allan deviation) section: the first dwell has 2 samples (0.02 s at 100 Hz), "
         "it needs 2000")
    assert r.stderr == f"inscal: warning: {w}\n"
    assert json.loads(r.stdout)["warnings"] == [w] and out.exists()


def test_nothing_is_said_when_the_record_is_long_enough(short, tmp_path):
    r = CliRunner().invoke(app, ["report", str(short.full), "--out", str(tmp_path / "r.html"), "--json"])
    assert r.exit_code == 0 and r.stderr == "" and json.loads(r.stdout)["warnings"] == []
    assert np.isfinite(json.loads(r.stdout)["arw_deg_rth"]).all()
