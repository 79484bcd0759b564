"""Options that were tracebacks, clamped or ignored: ``--scheduler`` of ``design`` and ``montecarlo`` (a
value neither a keyword nor a Dask address), ``--arw``/``--vrw``/``--filter-rate-hz`` of calibrate,
``navigate --output-rate-hz`` above the sample rate, and ``observability --filter-rate-hz`` without
``--crlb``: each is one line (exit 2), nothing written."""

import json
import os

import pytest
from typer.testing import CliRunner

from inscal.cli.app import app
from inscal.cli.common import CliError, check_scheduler


@pytest.mark.parametrize("value", ["not an address", "nohostport", "tcp://host:notaport", "ftp://host:1",
                                   "host:70000", ":8786"])
def test_bad_addresses_are_refused(value):
    with pytest.raises(CliError, match="not a Dask scheduler address"):
        check_scheduler(value, ("local",))


@pytest.mark.parametrize("value", [None, "local", "tcp://10.0.0.5:8786", "127.0.0.1:8786", "tls://h.example:443",
                                   "inproc://a:1"])
def test_good_values_pass(value):
    assert check_scheduler(value, ("local",)) == value


@pytest.mark.parametrize("args", [["design", "--minutes", "10"], ["montecarlo", "fig5", "--runs", "2"]])
def test_cli_one_line_and_nothing_written(tmp_path, args):
    out = tmp_path / ("d.toml" if args[0] == "design" else "mc")
    r = CliRunner().invoke(app, args + ["--out", str(out), "--scheduler", "not an address"])
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and "not a Dask scheduler address" in r.stderr, r.output
    assert not out.exists()


# ----------------------------------------------------------------------------- options no longer ignored
@pytest.fixture(scope="module")
def small(tmp_path_factory):
    d = tmp_path_factory.mktemp("opts")
    f = d / "p19.h5"
    r = CliRunner().invoke(app, ["simulate", "psins19", "--out", str(f), "--seed", "1", "--rate-hz", "20"])
    assert r.exit_code == 0, r.output
    return f


@pytest.mark.parametrize("args,msg", [
    (["calibrate", "{rec}", "--method", "systematic51", "--arw", "-1"], "--arw must be a white-noise level > 0"),
    (["calibrate", "{rec}", "--method", "systematic51", "--vrw", "-5"], "--vrw must be a white-noise level > 0"),
    (["calibrate", "{rec}", "--method", "systematic51", "--vrw", "nan"], "--vrw must be a white-noise level > 0"),
    (["calibrate", "{rec}", "--method", "systematic51", "--filter-rate-hz", "0"], "--filter-rate-hz must be > 0"),
    (["navigate", "{rec}", "--output-rate-hz", "1e6"], "output rate 1e+06 Hz is above the sample rate 20 Hz"),
    (["observability", "psins19", "--filter-rate-hz", "100"], "apply to the bound (--crlb)"),
])
def test_options_refused_not_clamped_or_ignored(small, tmp_path, args, msg):
    out = tmp_path / "x.toml"
    argv = [a.format(rec=small) for a in args] + (["--out", str(out)] if args[0] == "calibrate" else [])
    r = CliRunner().invoke(app, argv)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and msg in r.stderr, r.output
    assert not out.exists()


# ----------------------------------------------------------------------------- directories and FIFOs as inputs
@pytest.mark.parametrize("kind", ["fifo", "dir"])
@pytest.mark.parametrize("args,what", [
    (["navigate", "{x}"], "file"),
    (["calibrate", "{x}", "--method", "joint", "--out", "{o}"], "data file"),
    (["export", "{x}", "--format", "csv", "--out", "{o}"], "data file"),
    (["import", "{x}", "--format", "csv", "--out", "{o}", "--lat", "1", "--lon", "1", "--height", "1"], "file"),
    (["compensate", "{rec}", "--params", "{x}", "--out", "{o}"], "parameter file"),
    (["simulate", "{xt}", "--out", "{o}"], "scenario file"),
])
def test_directory_or_fifo_named_as_such_and_nothing_blocks(small, tmp_path, kind, args, what):
    """A FIFO given for a file blocked ``navigate`` forever (h5py opened it); a directory or FIFO was
    reported as 'no such file'.  Now each is named for what it is."""
    x, xt = tmp_path / "x.h5", tmp_path / "x.toml"
    for p in (x, xt):
        os.mkfifo(p) if kind == "fifo" else p.mkdir()
    o = tmp_path / "o.out"
    argv = [a.format(x=x, xt=xt, o=o, rec=small) for a in args]
    r = CliRunner().invoke(app, argv)
    phrase = "is a directory" if kind == "dir" else "not a regular file (a FIFO, socket or device)"
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and phrase in r.stderr, r.output
    assert f"not a {what}" in r.stderr and not o.exists()


# ----------------------------------------------------------------------------- inputs accepted silently before
def test_a_scenario_naming_no_motion_is_refused(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[scenario]\nname = "x"\nrate_hz = 100\n')
    r = CliRunner().invoke(app, ["simulate", str(f), "--out", str(tmp_path / "o.h5")])
    assert r.exit_code == 2 and "names no motion" in r.stderr and not (tmp_path / "o.h5").exists(), r.output
    f.write_text('[scenario]\nname = "x"\nrate_hz = 10\nduration_s = 30\n')  # a static record, asked for
    assert CliRunner().invoke(app, ["simulate", str(f), "--out", str(tmp_path / "o.h5")]).exit_code == 0


@pytest.fixture(scope="module")
def joint_params(small, tmp_path_factory):
    p = tmp_path_factory.mktemp("jp") / "j.toml"
    r = CliRunner().invoke(app, ["calibrate", str(small), "--method", "joint", "--out", str(p)])
    assert r.exit_code == 0, r.output
    return p


@pytest.mark.parametrize("cmd", ["compensate", "report", "navigate"])
def test_a_parameter_file_of_an_unknown_method_is_refused(small, joint_params, tmp_path, cmd):
    bogus = tmp_path / "b.toml"
    bogus.write_text(joint_params.read_text().replace('method = "joint"', 'method = "bogus"'))
    out = tmp_path / ("o.html" if cmd == "report" else "o.h5")
    argv = [cmd, str(small), "--params", str(bogus)] + ([] if cmd == "navigate" else ["--out", str(out)])
    r = CliRunner().invoke(app, argv)
    assert r.exit_code == 2 and "method 'bogus' is not an inscal calibration method" in r.stderr, r.output
    assert not out.exists()


def test_report_warns_when_the_parameters_come_from_another_record(joint_params, tmp_path):
    other = tmp_path / "n25.h5"
    assert CliRunner().invoke(app, ["simulate", "n25", "--out", str(other), "--seed", "1", "--rate-hz", "10"]).exit_code == 0
    r = CliRunner().invoke(app, ["report", str(other), "--params", str(joint_params), "--out", str(tmp_path / "r"),
                                 "--json"])
    assert r.exit_code == 0, r.output
    assert "inscal: warning:" in r.stderr and "calibrated from another record" in r.stderr
    assert any("scenario 'psins19' vs the record's 'n25'" in w for w in json.loads(r.stdout)["warnings"])


def test_a_read_only_output_folder_is_named_as_such(small, tmp_path, monkeypatch):
    """A read-only folder was reported as too small ('would take about 855 kB ... but has 1.05 MB free').
    (Run as root, permissions do not bind: the test makes os.access report the folder unwritable, as a
    read-only mount does for every user.)"""
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if os.fspath(p) == os.fspath(ro) else real(p, mode))
    for argv in (["simulate", "psins19", "--out", str(ro / "s.h5")],
                 ["calibrate", str(small), "--method", "joint", "--out", str(ro / "p.toml")]):
        r = CliRunner().invoke(app, argv)
        assert r.exit_code == 2 and "is read-only" in r.stderr and "free" not in r.stderr, r.output
    assert not any(ro.iterdir())
