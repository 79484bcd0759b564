"""The faces of inscal's packages carry full numpydoc docstrings, and their Examples run.

A face is a public function or class that a package offers its users: every name in the
``__all__`` of ``inscal.io``, ``inscal.nav``, ``inscal.calibrate``, ``inscal.lab`` and ``inscal.uncertainty``, and the
entry points of the packages that re-export nothing (:data:`ENTRY_POINTS`: the functions the
guide pages import).  For each face, numpydoc's own parser (``numpydoc.docscrape``) must find

- a non-empty **Parameters** section when it takes a named parameter (a class: its constructor's);
- a non-empty **Returns** (or **Yields**) section when it is a function that returns something
  (its return annotation is not ``None``);
- a non-empty **Raises** section when its body raises an exception itself (``raise X``);
- a non-empty **Examples** section, which runs here as a doctest (tiny inputs, seeded
  generators: each face's examples well under a second).

A face without them fails, naming the sections it lacks.
"""

from __future__ import annotations

import ast
import doctest
import functools
import importlib
import inspect
import os
import textwrap
import time

import numpy as np

from numpydoc.docscrape import ClassDoc, FunctionDoc

#: packages whose ``__all__`` is their face
PACKAGES = ("inscal.io", "inscal.nav", "inscal.calibrate", "inscal.lab", "inscal.uncertainty")
#: packages whose Examples run with their modules' globals in their own tests (the budget's examples
#: share the example station of ``inscal.uncertainty.station``): tests/uncertainty/test_uncertainty_package.py
EXAMPLES_RUN_ELSEWHERE = ("inscal.uncertainty.",)

#: the faces of the packages that re-export nothing: what the guide pages and the gallery import
ENTRY_POINTS = (
    "inscal.core.error_model.ImuErrors",
    "inscal.core.error_model.ImuNoise",
    "inscal.sim.scenarios.build",
    "inscal.sim.records.scenario_record",
    "inscal.sim.simulate.simulate",
    "inscal.sim.simulate.write_simulation",
    "inscal.analysis.allan.allan",
    "inscal.plan.bound.crlb",
    "inscal.report.path.path_figure",
    "inscal.report.history.history_figure",
    "inscal.report.certificate.certificate_html",
)

@functools.cache
def faces() -> dict[str, object]:
    """{dotted name as the user imports it: the object} for every face, each object once."""
    out: dict[str, object] = {}
    seen: set[int] = set()
    for package in PACKAGES:
        module = importlib.import_module(package)
        for name in module.__all__:
            obj = getattr(module, name)
            if (inspect.isfunction(obj) or inspect.isclass(obj)) and id(obj) not in seen:
                seen.add(id(obj))
                out[f"{package}.{name}"] = obj
    for dotted in ENTRY_POINTS:
        module, name = dotted.rsplit(".", 1)
        out[dotted] = getattr(importlib.import_module(module), name)
    return out


def _named_parameters(obj) -> list[str]:
    target = obj
    if inspect.isclass(obj):
        if issubclass(obj, BaseException):
            return []  # an exception takes its message
        target = obj.__init__ if "__init__" in vars(obj) or hasattr(obj, "__dataclass_fields__") else None
        if target is None or target is object.__init__:
            return []
    params = inspect.signature(target).parameters.values()
    named = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD,
             inspect.Parameter.KEYWORD_ONLY)
    return [p.name for p in params if p.kind in named and p.name not in ("self", "cls")]


def _returns(obj) -> bool:
    if inspect.isclass(obj):
        return False
    annotation = inspect.signature(obj).return_annotation
    return annotation not in (None, "None")


def _raises(obj) -> bool:
    """Whether the function's own body (not a nested function's) raises an exception by name."""
    if inspect.isclass(obj):
        return False
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(obj)))
    except (OSError, TypeError):
        return False
    func = tree.body[0]

    def walk(node) -> bool:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef | ast.Lambda):
                continue
            if isinstance(child, ast.Raise) and child.exc is not None:
                return True
            if walk(child):
                return True
        return False

    return walk(func)


def lacks(obj) -> list[str]:
    """The numpydoc sections ``obj``'s docstring lacks (empty: complete)."""
    doc = ClassDoc(obj, config={"show_class_members": False}) if inspect.isclass(obj) else FunctionDoc(obj)
    missing = []
    if _named_parameters(obj) and not doc["Parameters"]:
        missing.append("Parameters")
    if _returns(obj) and not (doc["Returns"] or doc["Yields"]):
        missing.append("Returns")
    if _raises(obj) and not doc["Raises"]:
        missing.append("Raises")
    if not "".join(doc["Examples"]).strip() or ">>>" not in "\n".join(doc["Examples"]):
        missing.append("Examples")
    return missing


@functools.cache
def incomplete() -> dict[str, list[str]]:
    return {name: gaps for name, obj in faces().items() if (gaps := lacks(obj))}


def test_every_face_has_numpydoc_sections():
    assert len(faces()) > 100  # the packages' faces were found
    gaps = incomplete()
    assert not gaps, "faces without full numpydoc sections: " + "; ".join(
        f"{name} lacks {', '.join(sections)}" for name, sections in sorted(gaps.items()))


def test_the_check_sees_a_missing_section():
    def documented(x: int) -> int:
        """Twice x.

        Parameters
        ----------
        x : int
            A number.

        Returns
        -------
        int
            ``2 x``.

        Examples
        --------
        >>> 2 * 2
        4
        """
        return 2 * x

    def bare(x: int) -> int:
        """Twice x, raising on a negative one."""
        if x < 0:
            raise ValueError("negative")
        return 2 * x

    assert lacks(documented) == []
    assert lacks(bare) == ["Parameters", "Returns", "Raises", "Examples"]


def _examples(name: str, obj) -> list[doctest.DocTest]:
    module = importlib.import_module(obj.__module__)
    finder = doctest.DocTestFinder(recurse=False)
    return [t for t in finder.find(obj, name, module=module, globs={"np": np}) if t.examples]


def test_the_examples_run(tmp_path, monkeypatch):
    """Every face's Examples, run by doctest in a scratch directory of its own; the whole set within
    5 s of CPU."""
    monkeypatch.delenv("INSCAL_DB", raising=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    slow = []
    start = time.process_time()
    for name, obj in faces().items():
        if name.startswith(EXAMPLES_RUN_ELSEWHERE):
            continue
        (tmp_path / name).mkdir()
        monkeypatch.chdir(tmp_path / name)
        for test in _examples(name, obj):
            t0 = time.process_time()
            runner.run(test)
            # 1 s each, and a half more for the first call of a numba kernel in the process (its
            # machine code loaded from the cache the warm-up filled)
            if (spent := time.process_time() - t0) > 1.5:
                slow.append(f"{name} ({spent:.1f} s)")
    cpu = time.process_time() - start
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} example lines failed (printed above)"
    assert not slow, "examples over 1.5 s of CPU: " + ", ".join(slow)
    assert cpu < 5.0 or os.environ.get("INSCAL_SLOW_DOCTESTS"), f"the examples took {cpu:.1f} s of CPU"
