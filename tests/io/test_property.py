"""Property tests: randomly corrupted records (byte flips, truncation) and randomly
edited scenario files never produce a traceback: the exit code is 0 or 2, a failure is one
line on stderr, and no partial output (``.part``, half-written file) is left behind."""

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from inscal import io
from inscal.cli.app import app
from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
from inscal.core.earth import Site

runner = CliRunner()
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@pytest.fixture(scope="module")
def record_bytes(tmp_path_factory) -> bytes:
    n, dt = 1500, 0.01
    rng = np.random.default_rng(0)
    t = np.arange(1, n + 1) * dt
    dth = rng.normal(0, 1e-7, (n, 3)) + np.array([0, 5e-5, 5e-5]) * dt
    dv = rng.normal(0, 1e-6, (n, 3)) + np.array([0, 0, 9.8]) * dt
    p = tmp_path_factory.mktemp("prop") / "r.h5"
    io.write_record(p, io.Record(t, dth, dv, np.zeros((n, 2)), 100.0, Site(math.radians(45), 0, 0),
                                 truth=io.Truth(ImuErrors(), GimbalErrors(), ImuNoise()), scenario="prop"))
    return p.read_bytes()


def check(result, folder: Path, outputs: list[Path]):
    text = result.stdout + result.stderr
    assert result.exit_code in (0, 2), (result.exit_code, result.stderr, repr(result.exception))
    assert "Traceback" not in text, text
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".part")]
    if result.exit_code == 2:
        lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("inscal: error: "), result.stderr
        assert not any(o.exists() for o in outputs), "output left after a failure"


corruption = st.one_of(
    st.tuples(st.just("flip"), st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(1, 255)),
                                        min_size=1, max_size=24)),
    st.tuples(st.just("truncate"), st.floats(0, 1, exclude_max=True)),
)


def corrupt(data: bytes, how) -> bytes:
    kind, arg = how
    if kind == "truncate":
        return data[: int(arg * len(data))]
    b = bytearray(data)
    for pos, x in arg:
        b[int(pos * len(b))] ^= x
    return bytes(b)


@SETTINGS
@given(how=corruption, cmd=st.sampled_from(["allan", "report", "compensate"]))
def test_corrupted_record(record_bytes, how, cmd):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        rec = folder / "r.h5"
        rec.write_bytes(corrupt(record_bytes, how))
        if cmd == "allan":
            outs, args = [folder / "a.png"], ["allan", rec, "--json", "--plot", folder / "a.png"]
        elif cmd == "report":
            outs, args = [folder / "o.html"], ["report", rec, "--out", folder / "o.html", "--json"]
        else:
            p = folder / "p.toml"
            p.write_text('kind = "inscal-parameters"\nschema_version = 1\nmethod = "n25"\n'
                         '[parameters.accel_bias]\nvalue = [1.0, 2.0, 3.0]\nunit = "ug"\n')
            outs, args = [folder / "c.h5"], ["compensate", rec, "-p", p, "-o", folder / "c.h5", "--json"]
        check(runner.invoke(app, [str(a) for a in args]), folder, outs)


SCENARIO = """base = "n25"
[scenario]
name = "prop"
rate_hz = 20
[site]
latitude_deg = 45.0
height_m = 30
[errors]
gimbal_nonorthogonality = {value = 3, unit = "arcsec"}
accel_bias = [10, 20, 30]
[noise]
arw = 1
[path]
accel_dps2 = 20
moves = [{axis = "inner", angle_deg = 180, rate_dps = 10, dwell_s = 5},
         {axis = "inner", angle_deg = -180, rate_dps = 10, dwell_s = 5}]
"""

junk = st.sampled_from(['"x"', "[]", "{}", "nan", "inf", "-1e308", "1e308", "0", "-0", "true", '"deg"', "[1, 2]",
                        "{value = 1}", "=", "[[", '"""', "\\u0000", "ünïcode", "1_000", "0x10", "-", "9" * 40])
edit = st.one_of(
    st.tuples(st.just("delete"), st.integers(0, 100)),
    st.tuples(st.just("swap"), st.integers(0, 100), st.integers(0, 100)),
    st.tuples(st.just("junk"), st.integers(0, 100), junk),
    st.tuples(st.just("text"), st.integers(0, 100), st.text(max_size=12)),
)


def apply_edits(text: str, edits) -> str:
    lines = text.splitlines()
    for e in edits:
        if not lines:
            break
        k = e[1] % len(lines)
        if e[0] == "delete":
            del lines[k]
        elif e[0] == "swap":  # swap the values (right of '=') of two lines
            j = e[2] % len(lines)
            if "=" in lines[k] and "=" in lines[j]:
                (a, va), (b, vb) = lines[k].split("=", 1), lines[j].split("=", 1)
                lines[k], lines[j] = f"{a}={vb}", f"{b}={va}"
        else:
            if "=" in lines[k]:
                lines[k] = lines[k].split("=", 1)[0] + "= " + e[2]
            else:
                lines[k] = e[2]
    return "\n".join(lines) + "\n"


@SETTINGS
@given(edits=st.lists(edit, min_size=1, max_size=4))
def test_edited_scenario(edits):
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        f = folder / "s.toml"
        f.write_text(apply_edits(SCENARIO, edits), encoding="utf-8", errors="surrogatepass")
        out = folder / "o.h5"
        r = runner.invoke(app, ["simulate", str(f), "--out", str(out), "--rate-hz", "5", "--json"])
        check(r, folder, [out])
        if r.exit_code == 0:
            assert io.read_record(out).n_samples > 0
