"""The README's command block runs as written and gives meaningful results;
the README lists every built-in scenario and every subcommand."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def command_block() -> list[str]:
    """The first fenced block after '## Command line': one inscal command per line."""
    sec = README[README.index("## Command line"):]
    m = re.search(r"```\n(.*?)```", sec, re.S)
    lines = [ln.strip() for ln in m.group(1).splitlines() if ln.strip()]
    assert lines and all(ln.startswith("inscal ") for ln in lines), lines
    return lines


def test_readme_lists_every_scenario_and_subcommand():
    from inscal.sim import scenarios
    from inscal.cli.app import app
    from typer.main import get_command

    for name in scenarios.BUILTIN:
        assert f"`{name}`" in README, f"built-in scenario {name} is not in the README"
    names = set(get_command(app).commands)
    sub = README[README.index("Subcommands:"):][:400]
    for name in names:
        assert f"`{name}`" in sub, f"subcommand {name} is not listed in the README"
    block = " ".join(command_block())
    for name in names:
        assert f"inscal {name} " in block + " ", f"the README's command block never runs `inscal {name}`"


@pytest.mark.slow
def test_readme_command_block_runs(tmp_path):
    """Every line of the block, in an empty folder, with the installed `inscal`."""
    bindir = Path(sys.executable).parent
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "100"}
    outputs = {}
    for line in command_block():
        r = subprocess.run(["bash", "-c", line], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"{line}\n{r.stderr[-2000:]}"
        assert "Traceback" not in r.stderr, line
        outputs[line] = r
    # meaningful results: the calibration brings navigation errors down by an order of magnitude
    nav = [ln for ln in outputs if ln.startswith("inscal navigate")]
    raw = float(re.search(r"position error: max ([0-9.]+) m", outputs[nav[0]].stdout).group(1))
    comp = json.loads(outputs[nav[1]].stdout)["max_position_error_m"]
    assert raw > 10 * comp, (raw, comp)
    assert (tmp_path / "nav.png").stat().st_size > 10_000
    # the rounded duration of the rotation-modulation run is said
    sim = next(ln for ln in outputs if "n25-rotmod" in ln)
    assert "rounded up" in outputs[sim].stdout
    # Allan: the N25 noise is found (ARW 0.02 deg/sqrt(h), VRW 20 ug/sqrt(Hz))
    al = json.loads(outputs[next(ln for ln in outputs if ln.startswith("inscal allan"))].stdout)
    assert all(abs(a / 0.02 - 1) < 0.1 for a in al["arw_deg_rth"]), al["arw_deg_rth"]
    assert all(abs(v / 20 - 1) < 0.1 for v in al["vrw_ug_rthz"]), al["vrw_ug_rthz"]
    # the N25 calibration finds the gimbal non-orthogonality (20 arcsec) within its sigma budget
    cal = json.loads(outputs[next(ln for ln in outputs if "--method n25" in ln)].stdout)
    d = cal["parameters"]["gimbal_nonorthogonality"]
    assert abs(d["error"][0]) < 5 * d["sigma"][0] and abs(d["value"][0] - 20) < 2
    # the 30-state filter's misfit is reported; the 51-state fit is consistent
    s30 = outputs[next(ln for ln in outputs if "systematic30" in ln)].stdout
    assert "INCONSISTENT" in s30 and "try --states 51" in s30
    assert "consistent" in outputs[next(ln for ln in outputs if "systematic51" in ln)].stdout
    for f in ("s16-51.toml", "n25.html", "n25-comp.h5", "n25-imported.h5", "path20.toml",
              "mc-schemes/summary.json", "demo-output/report.html"):
        assert (tmp_path / f).is_file(), f
