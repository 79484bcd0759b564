"""Pages of the site whose console blocks run here as written, with their printed output compared: the landing
page's tour (``docs/index.md``), "Calibrate your own record" (``docs/getting-started/own-record.md``) and the
worked sessions of "Table-free calibration" (``docs/guide/table-free.md``).

A page's block marked ``% run: tests/cli/test_site_pages.py`` runs in one empty folder, in page order, each
``inscal`` line in this process (the Typer app: what the installed ``inscal`` runs).  A comment line after a
command, ``#   TEXT``, is its printed output: some line of what the command printed (standard output and error)
must read TEXT, its words equal and each number within one unit of the last digit the page shows (the
tolerance, for BLAS and platform rounding); a TEXT ending in ``...`` is the start of that line.  A command
whose comment reads ``# exits N`` must exit with status N (a refusal the page shows); the others with 0.  The log of
the own-record page is the simulated record ``lab.h5`` written in the page's lab units by the page's own Python
block (``# fog-log.csv``), and the two rows the page shows must be its first two."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from inscal.cli.app import app

ROOT = Path(__file__).resolve().parents[2]
OWN = ROOT / "docs" / "getting-started" / "own-record.md"
INDEX = ROOT / "docs" / "index.md"
TABLE_FREE = ROOT / "docs" / "guide" / "table-free.md"
NOISE = ROOT / "docs" / "guide" / "noise-identification.md"
MARK = "% run: tests/cli/test_site_pages.py"
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def marked_blocks(page: Path) -> list[list[str]]:
    """The lines of every fenced block of ``page`` right after the line ``MARK``."""
    text = page.read_text(encoding="utf-8")
    return [m.group(1).splitlines() for m in re.finditer(re.escape(MARK) + r"\n```\w*\n(.*?)```", text, re.S)]


def fenced(page: Path, lang: str, first: str) -> str:
    """The first ``lang`` block of ``page`` whose text starts with ``first``."""
    text = page.read_text(encoding="utf-8")
    return next(b for b in re.findall(rf"```{lang}\n(.*?)```", text, re.S) if b.startswith(first))


def steps(lines: list[str]) -> list[tuple[str, list[str], int]]:
    """``(command, [expected output lines], exit status)`` of a block."""
    out: list[tuple[str, list[str], int]] = []
    for ln in lines:
        if ln.startswith("#"):
            out[-1][1].append(ln.lstrip("#").strip())
        elif ln.strip():
            status = re.search(r" #\s*exits (\d+)", ln)
            out.append((ln.split(" #")[0].strip(), [], int(status.group(1)) if status else 0))
    return out


def _decimals(token: str) -> float:
    """One unit of the last digit of a number as printed."""
    mant = re.split(r"[eE]", token)[0]
    exp = int(re.split(r"[eE]", token)[1]) if re.search(r"[eE]", token) else 0
    dec = len(mant.split(".")[1]) if "." in mant else 0
    return 10.0 ** (exp - dec)


def matches(expected: str, line: str) -> bool:
    """Whether printed ``line`` reads ``expected`` (module docstring)."""
    prefix = expected.endswith("...")
    want = " ".join(expected.removesuffix("...").split())
    got = " ".join(line.split())
    w_nums, g_nums = NUMBER.findall(want), NUMBER.findall(got)
    w_text, g_text = NUMBER.split(want), NUMBER.split(got)
    if prefix:
        n = len(w_nums)
        g_nums = g_nums[:n]
        g_text = g_text[:n] + [g_text[n][: len(w_text[n].rstrip())] if n < len(g_text) else ""]
        w_text = w_text[:n] + [w_text[n].rstrip()]
    if w_text != g_text or len(w_nums) != len(g_nums):
        return False
    return all(abs(float(a) - float(b)) <= 1.0001 * _decimals(a) for a, b in zip(w_nums, g_nums))


def run_block(lines: list[str], folder: Path, monkeypatch) -> None:
    """Each command of the block in ``folder``; its printed lines compared with the block's."""
    monkeypatch.chdir(folder)
    for command, expected, status in steps(lines):
        words = shlex.split(command)
        assert words[0] == "inscal", command
        r = CliRunner().invoke(app, words[1:])
        assert r.exit_code == status, f"{command}\n{r.output[-2000:]}"
        printed = (r.stdout + "\n" + r.stderr).splitlines()
        for want in expected:
            assert any(matches(want, ln) for ln in printed), f"{command}: no line reads {want!r} in\n{r.output[-3000:]}"


def test_matching_rule():
    assert matches("p = 0.0926: consistent", "  fit: chi2 1 on 2 dof, p = 0.0927: consistent") is False  # words differ
    assert matches("fit: p = 0.0926: consistent", "fit: p = 0.0927: consistent")  # one unit of the last digit
    assert not matches("fit: p = 0.0926: consistent", "fit: p = 0.0929: consistent")
    assert matches("x: ARW 0.02024 deg/rt(h) ...", "  x: ARW 0.02024 deg/rt(h), VRW 20.21 ug/rt(Hz)")
    assert not matches("x: ARW 0.02024 deg/rt(h) ...", "  y: ARW 0.02024 deg/rt(h), VRW 20.21 ug/rt(Hz)")


@pytest.mark.slow
def test_the_landing_tour_and_the_own_record_page_run_as_written(tmp_path, monkeypatch):
    """The landing page's tour prints what the page quotes; the own-record page, from its "No log at hand?"
    block to the report, prints what it shows (the database block is the lab block of the database guide,
    which tests/cli/test_db_cli.py runs)."""
    tour = marked_blocks(INDEX)
    assert len(tour) == 1 and any(ln.startswith("#") for ln in tour[0])
    run_block(tour[0], tmp_path, monkeypatch)  # n25.h5 seed 1: the record of the own-record page too
    assert (tmp_path / "n25.html").stat().st_size > 10_000

    blocks = marked_blocks(OWN)
    assert len(blocks) >= 6
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "lab.h5").symlink_to(tmp_path / "n25.h5")  # the same command, already run by the tour
    first = [ln for ln in blocks[0] if not ln.startswith("inscal simulate n25 --out lab.h5 --seed 1")]
    assert len(first) == len(blocks[0]) - 1, "the page's log is no longer the tour's record"
    run_block(first, lab, monkeypatch)
    monkeypatch.chdir(lab)  # the page's block writes the log from lab.h5, as a reader without a log runs it
    exec(compile(fenced(OWN, "python", "# fog-log.csv"), str(OWN), "exec"), {})
    lines = (lab / "fog-log.csv").read_text().splitlines()
    shown = fenced(OWN, "text", "t_ms,").splitlines()
    assert shown[:3] == lines[:3], (shown[:3], lines[:3])
    (lab / "map.toml").write_text(fenced(OWN, "toml", "# map.toml"))
    for block in blocks[1:]:
        run_block(block, lab, monkeypatch)
    for f in ("run.h5", "run-check.html", "fog.toml", "run-comp.h5", "nav.png", "fog-report.html"):
        assert (lab / f).is_file(), f


@pytest.mark.slow
def test_the_table_free_sessions_run_as_written(tmp_path, monkeypatch):
    """The table-free guide's hand-held session, the detector's refusal of it with longer poses (exit 2, nothing
    written) and its Ferraris session print what the page shows."""
    blocks = marked_blocks(TABLE_FREE)
    assert len(blocks) == 3 and all(any(ln.startswith("#") for ln in b) for b in blocks)
    assert steps(blocks[1])[0][2] == 2
    for block in blocks:
        run_block(block, tmp_path, monkeypatch)
    assert not (tmp_path / "strict.toml").exists()
    for f in ("mp.toml", "fe.toml"):
        assert (tmp_path / f).is_file(), f


def same_file(shown: str, written: str) -> bool:
    """Whether a file a page shows reads as the one written: the same words, each number within 1e-6 of
    itself (the identification's last digits move with BLAS and platform rounding)."""
    a, b = shown.strip().splitlines(), written.strip().splitlines()
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        if NUMBER.split(x) != NUMBER.split(y):
            return False
        if not all(abs(float(u) - float(v)) <= 1e-6 * abs(float(u)) + 1e-12
                   for u, v in zip(NUMBER.findall(x), NUMBER.findall(y))):
            return False
    return True


@pytest.mark.slow
def test_the_noise_identification_page_runs_as_written(tmp_path, monkeypatch):
    """The noise guide's static record, its identification (auto and a fixed model), the allan view, the
    Kalibr export's refusal of a two-channel model (exit 2, nothing written) and the exports print what the
    page shows; the Kalibr and KF-GINS files read as the page shows them."""
    blocks = marked_blocks(NOISE)
    assert len(blocks) >= 7 and all(any(ln.startswith("#") for ln in b) for b in blocks)
    (tmp_path / "bench.toml").write_text(fenced(NOISE, "toml", "# bench.toml"))
    for block in blocks:
        run_block(block, tmp_path, monkeypatch)
    assert not (tmp_path / "two.yaml").exists()
    assert same_file(fenced(NOISE, "yaml", "# Kalibr"), (tmp_path / "imu.yaml").read_text())
    assert same_file(fenced(NOISE, "yaml", "imunoise:"), (tmp_path / "imunoise.yaml").read_text())
    assert (tmp_path / "noise_params.m").read_text().count("params(") == 2
