"""The warm-up (``python -m inscal.cli.warmup``, run by ``make`` after the install) finds every numba
kernel of the package and compiles it.

``make`` empties the cache, runs the whole warm-up and keeps its JSON report beside the virtual environment
(``.venv/warmup-report.json``).  When that report is newer than every source file, it is the one the test
reads: every kernel, the systematic filter's too, must have been compiled there, into the cache the commands
use.  Otherwise (the suite run by hand after an edit) the test runs the warm-up itself, which compiles for
over a minute with the systematic filter (about 45 s of it): the subprocess then runs every step but the two
that run the filter (``systematic`` and ``observability``), in a fresh ``NUMBA_CACHE_DIR`` (the real cache
is not touched), and checks that every kernel outside the filter's own modules got compiled."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

from inscal.cli.warmup import STEPS, cache_root, dispatchers

SRC = Path(__file__).resolve().parents[2] / "src" / "inscal"
#: the steps that run the systematic filter: left to ``make``
FILTER_STEPS = ("systematic", "observability")
#: kernels only the systematic filter calls
FILTER_MODULES = ("inscal.calibrate.systematic.", "inscal.plan.observability.", "inscal.core.kalman.")


def njit_functions() -> set[str]:
    """``module.name`` of every function decorated with ``@njit`` / ``@njit(...)`` in the sources."""
    found = set()
    for path in SRC.rglob("*.py"):
        mod = ".".join(path.relative_to(SRC.parent).with_suffix("").parts)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef):
                for dec in node.decorator_list:
                    target = dec.func if isinstance(dec, ast.Call) else dec
                    if isinstance(target, (ast.Name, ast.Attribute)) and ast.unparse(target).split(".")[-1] == "njit":
                        found.add(f"{mod}.{node.name}")
    return found


def test_every_njit_function_is_a_dispatcher_the_check_sees():
    """The coverage check enumerates module attributes: a kernel it cannot see (a nested or renamed
    function) would never be reported missing."""
    declared = njit_functions()
    seen = set(dispatchers())
    assert declared, "no @njit function found in the sources"
    assert declared == seen, f"not seen: {sorted(declared - seen)}; not declared: {sorted(seen - declared)}"


def make_report() -> dict | None:
    """The report of ``make``'s warm-up when it is newer than every source file and was written for the cache
    this process uses, else None."""
    path = Path(sys.prefix) / "warmup-report.json"
    if not path.is_file():
        return None
    newest = max(p.stat().st_mtime for p in SRC.rglob("*.py"))
    if path.stat().st_mtime < newest:
        return None
    res = json.loads(path.read_text())
    return res if res.get("cache") == cache_root() else None


def check_compiled(res: dict, kernels_of) -> None:
    """No step failed, every dispatcher was seen, the kernels ``kernels_of(names)`` were all compiled with
    their signatures, and the inlined ones counted."""
    assert not res["errors"], res["errors"]
    kernels = res["kernels"]
    assert set(kernels) == set(dispatchers())
    checked = kernels_of([k for k, v in kernels.items() if v != "inlined"])
    assert checked and all(kernels[k] == "compiled" for k in checked), \
        {k: kernels[k] for k in checked if kernels[k] != "compiled"}
    assert all(res["signatures"][k] for k in checked)
    # a kernel declared inline="always" is compiled into its callers only
    assert res["inlined"] == sum(d.targetoptions.get("inline") == "always" for d in dispatchers().values())


def test_warm_up_compiles_every_kernel(tmp_path):
    res = make_report()
    if res is not None:  # make's whole warm-up, in the cache it had emptied: every kernel compiled there
        assert not res["missing"] and res["ready"] == res["total"], res["missing"]
        check_compiled(res, lambda names: names)
        return
    steps = [s for s in STEPS if s not in FILTER_STEPS]
    report = tmp_path / "warmup.json"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    r = subprocess.run([sys.executable, "-m", "inscal.cli.warmup", "--jobs", "1", "--steps", ",".join(steps),
                        "--report", str(report)], env=env, capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.startswith("inscal warm-up: ") and r.stdout.count("\n") == 1, r.stdout
    res = json.loads(report.read_text())
    assert Path(res["cache"]).resolve().is_relative_to((tmp_path / "numba-cache").resolve()), res["cache"]
    check_compiled(res, lambda names: [k for k in names if not k.startswith(FILTER_MODULES)])
