"""The package's layout rules, checked mechanically (the layers themselves: ``lint-imports`` in
``make test``, contracts in pyproject.toml):

- a function-local import only in ``inscal.cli`` (start time of the command line), for the
  optional heavy dependencies, and for the core modules that reading a record must not load
  (numba and SciPy come with them; ``inscal allan`` starts in a third of a second);
- no private name (``_x``) imported from another module;
- no library module over 800 lines (docstrings included: a module that outgrows it with its faces'
  numpydoc sections is split by idea);
- each field-unit constant and paper table has one home.
"""

from __future__ import annotations

import ast
import importlib.metadata
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "inscal"
#: heavy modules imported where used, so that commands that do not need them start faster (rosbags: 0.13 s,
#: loaded only to read a bag; ruamel.yaml: only for a KF-GINS configuration)
OPTIONAL = ("matplotlib", "dask", "distributed", "scipy.io", "allantools", "rosbags", "ruamel")
#: (module file, imported package): function-local imports kept for start time, with the reason above
START_TIME = {("io/recordfile.py", "inscal.core")}
MAX_LINES = 800


def modules():
    return sorted(p for p in SRC.rglob("*.py"))


def rel(p: Path) -> str:
    return p.relative_to(SRC).as_posix()


def module_name(p: Path) -> str:
    parts = list(p.relative_to(SRC.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(node) -> list[str]:
    return [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]


def under(m: str, pkg: str) -> bool:
    return m == pkg or m.startswith(pkg + ".")


@pytest.mark.parametrize("path", modules(), ids=rel)
def test_no_function_local_import_outside_the_cli(path):
    if rel(path).startswith("cli/"):
        return
    bad = []
    for fn in ast.walk(ast.parse(path.read_text())):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for m in imported(node):
                    if any(under(m, o) for o in OPTIONAL) or any(r == rel(path) and under(m, k) for r, k in START_TIME):
                        continue
                    bad.append(f"line {node.lineno}: {ast.unparse(node)}")
    assert not bad, f"{rel(path)} imports inside functions: {bad}"


@pytest.mark.parametrize("path", modules(), ids=rel)
def test_no_private_name_imported_across_modules(path):
    me = module_name(path)
    bad = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and under(node.module, "inscal") and node.module != me:
            bad += [a.name for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
    assert not bad, f"{rel(path)} imports private names {bad}"


@pytest.mark.parametrize("path", modules(), ids=rel)
def test_module_size(path):
    n = len(path.read_text().splitlines())
    assert n <= MAX_LINES, f"{rel(path)} has {n} lines (> {MAX_LINES}): split it by idea"


def test_no_import_cycle_counting_function_local_imports():
    """Tarjan over every inscal import (module-level and function-local; a package face counts as
    the modules it re-exports from): no strongly connected component of more than one module."""
    graph = {}
    for p in modules():
        me = module_name(p)
        deps = set()
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and under(node.module, "inscal"):
                for a in node.names:
                    sub = f"{node.module}.{a.name}"
                    deps.add(sub if (SRC.parent / (sub.replace(".", "/") + ".py")).exists() else node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if under(a.name, "inscal")}
        deps.discard(me)
        # importing a package's submodule runs the package face first: parents are not edges here
        graph[me] = {d for d in deps if not under(me, d)}
    index, low, stack, on, sccs = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in graph:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                sccs.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not sccs, f"import cycles: {sccs}"


def test_one_home_for_deg_and_the_paper_tables():
    text = {rel(p): p.read_text() for p in modules()}
    deg = [f for f, s in text.items() if re.search(r"^DEG\s*=", s, re.M)]
    assert deg == ["core/units.py"], deg
    for name, home in (("S16_TABLE2", "sim/scenarios.py"), ("CROSS_NAMES", "core/error_model.py")):
        defs = [f for f, s in text.items() if re.search(rf"^{name}\s*=", s, re.M)]
        assert defs == [home], (name, defs)


def test_no_issue_numbers_in_the_library():
    hits = [f"{rel(p)}:{i + 1}" for p in modules() for i, line in enumerate(p.read_text().splitlines())
            if re.search(r"\bissue\s*\d|\(issue\b", line, re.I)]
    assert not hits, hits


def test_the_longest_test_files_named_for_the_scheduler_exist():
    """``tests/conftest.py`` starts these files first (``make test``): a name left behind by a rename would
    silently drop out of the ordering."""
    tests = Path(__file__).resolve().parent
    tree = ast.parse((tests / "conftest.py").read_text())  # not imported: "conftest" names several modules
    (node,) = [n for n in tree.body if isinstance(n, ast.Assign) and ast.unparse(n.targets[0]) == "LONGEST"]
    longest = ast.literal_eval(node.value)
    missing = [name for name in longest if not (tests / name).is_file()]
    assert longest and not missing, missing
    # the page test checks the README block's demo run (tests/cli/demo_share.py): it is scheduled after that part
    assert "cli/test_readme_block_0.py" in longest and "cli/test_demo_html.py" not in longest


def test_make_test_names_every_installed_pytest_plugin():
    """``make test`` turns the plugins' automatic loading off and names them (``PLUGINS`` in the Makefile): a
    plugin installed later and not named there would silently not load."""
    make = (Path(__file__).resolve().parents[1] / "Makefile").read_text()
    (line,) = [ln for ln in make.splitlines() if ln.startswith("PLUGINS")]
    named = set(re.findall(r"-p\s+(\S+)", line))
    installed = {ep.name for dist in importlib.metadata.distributions() for ep in dist.entry_points
                 if ep.group == "pytest11"}
    assert installed and installed <= named, sorted(installed - named)
    assert "PYTEST_DISABLE_PLUGIN_AUTOLOAD=1" in make and "$(PLUGINS)" in make
