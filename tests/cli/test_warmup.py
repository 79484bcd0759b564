"""The warm-up (``python -m inscal.cli.warmup``, run by ``make`` after the install) finds every numba
kernel of the package and compiles it.

The whole warm-up compiles for over a minute (the systematic filter alone for about 45 s), too long for
the suite: the subprocess here runs every step but the two that run the systematic filter
(``systematic`` and ``observability``), in a fresh ``NUMBA_CACHE_DIR`` (the real cache is not touched),
and checks that every kernel outside the filter's own modules got compiled.  ``make`` runs the whole
warm-up, whose summary line names any kernel it did not reach."""

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

from inscal.cli.warmup import STEPS, dispatchers

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


def test_warm_up_compiles_every_kernel_outside_the_filter_in_a_fresh_cache(tmp_path):
    steps = [s for s in STEPS if s not in FILTER_STEPS]
    report = tmp_path / "warmup.json"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    r = subprocess.run([sys.executable, "-m", "inscal.cli.warmup", "--jobs", "1", "--steps", ",".join(steps),
                        "--report", str(report)], env=env, capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.startswith("inscal warm-up: ") and r.stdout.count("\n") == 1, r.stdout
    res = json.loads(report.read_text())
    assert not res["errors"], res["errors"]
    assert Path(res["cache"]).resolve().is_relative_to((tmp_path / "numba-cache").resolve()), res["cache"]
    kernels = res["kernels"]
    assert set(kernels) == set(dispatchers())
    outside = [k for k, v in kernels.items() if v != "inlined" and not k.startswith(FILTER_MODULES)]
    assert outside and all(kernels[k] == "compiled" for k in outside), \
        {k: kernels[k] for k in outside if kernels[k] != "compiled"}
    assert all(res["signatures"][k] for k in outside)
    # a kernel declared inline="always" is compiled into its callers only
    assert res["inlined"] == sum(d.targetoptions.get("inline") == "always" for d in dispatchers().values())
