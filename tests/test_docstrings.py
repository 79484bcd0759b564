"""Every public module, class, function and method of inscal has a docstring.

The API reference of the documentation site (docs/reference/python-api.md) is generated from the
docstrings: a public name without one would be a blank entry.  Public means: a module whose dotted
name has no part starting with ``_`` (``__init__`` aside), and a name defined in that module (not
imported into it) that does not start with ``_``; a class's public methods and properties likewise.

The names that had no docstring when this check was written are listed in
``tests/docstrings_missing.txt``: the list may only shrink.  A new public name without a docstring
fails the test; document a listed one and delete its line.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import pkgutil

from pathlib import Path

import inscal

#: public names still without a docstring (documented ones leave the list; none may join it)
MISSING = Path(__file__).with_name("docstrings_missing.txt")


def _public_modules():
    yield inscal
    for info in pkgutil.walk_packages(inscal.__path__, prefix="inscal."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            yield importlib.import_module(info.name)


def _function(obj) -> bool:
    """A Python function, or a numba kernel (its dispatcher keeps the Python function as ``py_func``)."""
    return inspect.isfunction(obj) or inspect.isfunction(getattr(obj, "py_func", None))


def _own(module, obj) -> bool:
    return getattr(obj, "__module__", None) == module.__name__


@functools.cache
def _undocumented() -> tuple[str, ...]:
    missing: list[str] = []
    for module in _public_modules():
        if not (module.__doc__ or "").strip():
            missing.append(f"module {module.__name__}")
        for name, obj in vars(module).items():
            if name.startswith("_") or not (_function(obj) or inspect.isclass(obj)) or not _own(module, obj):
                continue
            if not _documented(obj):
                missing.append(f"{module.__name__}.{name}")
            if inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    if attr.startswith("_"):
                        continue
                    func = member.fget if isinstance(member, property) else getattr(member, "__func__", member)
                    if inspect.isfunction(func) and not (func.__doc__ or "").strip():
                        missing.append(f"{module.__name__}.{name}.{attr}")
    return tuple(missing)


def _documented(obj) -> bool:
    doc = (obj.__doc__ or "").strip()
    if not doc:
        return False
    if inspect.isclass(obj):
        # a dataclass's or a NamedTuple's generated "Name(field, ...)", or a base class's docstring
        return not doc.startswith(f"{obj.__name__}(") and obj.__doc__ != _inherited_doc(obj)
    return True


def _inherited_doc(cls) -> str | None:
    """The docstring a class would show without its own (an exception's or a NamedTuple's generic one)."""
    for base in cls.__mro__[1:]:
        if base.__doc__:
            return base.__doc__
    return None


def _listed() -> set[str]:
    lines = MISSING.read_text(encoding="utf-8").splitlines()
    return {line.strip() for line in lines if line.strip() and not line.startswith("#")}


def test_every_public_name_has_a_docstring():
    new = sorted(set(_undocumented()) - _listed())
    assert not new, f"{len(new)} public names without a docstring (write one): " + ", ".join(new)


def test_the_list_of_missing_docstrings_names_only_undocumented_names():
    stale = sorted(_listed() - set(_undocumented()))
    assert not stale, ("documented or gone, delete their lines from tests/docstrings_missing.txt: "
                       + ", ".join(stale))
