"""The package ``inscal.lab`` loads its modules on first use: calibrating without a database never imports
SQLAlchemy or Alembic, and every public name is what the module that defines it says."""

import importlib
import subprocess
import sys

from inscal import lab


def test_every_public_name_is_its_modules():
    for name in lab.__all__:
        assert getattr(lab, name) is getattr(importlib.import_module(lab.EXPORTS[name]), name), name
    assert set(lab.__all__) <= set(dir(lab))


def test_a_submodule_does_not_hide_the_function_of_the_same_name():
    importlib.import_module("inscal.lab.fleet")
    assert callable(lab.fleet) and lab.fleet.__module__ == "inscal.lab.fleet"
    from inscal.lab import batch, fleet

    assert fleet is lab.fleet and batch.__name__ == "inscal.lab.batch"


def test_calibrating_without_a_database_imports_no_database_library():
    code = ("import sys, inscal.lab.calibration, inscal.lab.record, inscal.cli.calibrate; "
            "print(sorted(m for m in ('sqlalchemy', 'alembic') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]", r.stdout
