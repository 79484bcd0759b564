"""The package ``inscal.uncertainty``: every public name is its module's, none is also a submodule's name, reading a
station loads no estimator, and the examples of the public names' docstrings run as written (doctest)."""

import doctest
import importlib
import pkgutil
import subprocess
import sys

import pytest

from inscal import uncertainty


def test_every_public_name_is_its_modules_and_no_submodule_is_hidden():
    for name in uncertainty.__all__:
        assert getattr(uncertainty, name) is getattr(importlib.import_module(uncertainty.EXPORTS[name]), name), name
    subs = {m.name for m in pkgutil.iter_modules(uncertainty.__path__)}
    assert not subs & set(uncertainty.__all__)


def test_reading_a_station_loads_no_estimator():
    code = ("import sys, inscal.uncertainty as u; u.read_station; "
            "print(sorted(m for m in ('inscal.calibrate', 'numba', 'sqlalchemy') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]", r.stdout


@pytest.mark.parametrize("name", uncertainty.__all__)
def test_the_examples_run(name):
    obj = getattr(uncertainty, name)
    doc = obj.__doc__ or ""
    for section in ("Parameters\n", "Examples\n"):
        assert section in doc, (name, section)
    module = importlib.import_module(uncertainty.EXPORTS[name])
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    tests = finder.find(obj, name, module=module, globs=dict(vars(module)))
    assert tests and sum(len(t.examples) for t in tests) > 0
    for t in tests:
        runner.run(t)
    assert runner.failures == 0, name
