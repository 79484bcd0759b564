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


def test_no_public_name_is_a_submodule_so_an_import_hides_none():
    import pkgutil

    subs = {m.name for m in pkgutil.iter_modules(lab.__path__)}
    assert not subs & set(lab.EXPORTS), subs & set(lab.EXPORTS)
    importlib.import_module("inscal.lab.fleet_status")
    assert callable(lab.fleet) and lab.fleet.__module__ == "inscal.lab.fleet_status"
    from inscal.lab import fleet

    assert fleet is lab.fleet


def test_calibrating_without_a_database_imports_no_database_library():
    code = ("import sys, inscal.runs.calibration, inscal.lab.record, inscal.cli.calibrate; "
            "print(sorted(m for m in ('sqlalchemy', 'alembic') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]", r.stdout
