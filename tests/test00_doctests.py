"""The docstring examples (``>>>``) of every module of mi_npr and mi_npr.plugins run and pass.

Modules are imported by their package name (``mi_npr.plugins.npr_lines``, not
``plugins.npr_lines``: plugins/ ships as ``mi_npr.plugins``), after conftest has imported
mi_npr (which picks LLVM before drjit loads) and set the suite's variant. Examples run from the
repository root, so ``"scenes_xml/scene1.xml"`` in a docstring names the scene that ships as
``mi_npr.data``; ``mi_npr`` and ``np`` are in their namespace, as after ``import mi_npr`` and
``import numpy as np``.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil

import numpy as np
import pytest

import mi_npr

from .helpers import ROOT

#: No option flags: an example that needs one says so itself, so it also passes under plain
#: ``python -m doctest``-style runners.
_FLAGS = 0


def _module_names() -> list[str]:
    """mi_npr, mi_npr.plugins and every module below them, by import name."""
    names = ["mi_npr", "mi_npr.plugins"]
    for package in (mi_npr, importlib.import_module("mi_npr.plugins")):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if info.name not in names:
                names.append(info.name)
    return names


MODULES = _module_names()


class _Finder(doctest.DocTestFinder):
    """Reports a decorated function's examples at their own line, not at the decorator's
    wrapper (``@exact`` and friends wrap the kernels)."""

    def _find_lineno(self, obj, source_lines):
        return super()._find_lineno(inspect.unwrap(obj) if callable(obj) else obj, source_lines)


def _doctests() -> list[doctest.DocTest]:
    finder = _Finder(exclude_empty=True)
    tests = []
    for name in MODULES:
        module = importlib.import_module(name)
        # A module re-exports functions of its submodules; find() keeps only those defined in
        # the module itself, so each example is collected once, under its home module.
        tests.extend(t for t in finder.find(module, name) if t.examples)
    return sorted(tests, key=lambda t: t.name)


DOCTESTS = _doctests()


def test_every_module_is_collected():
    """The walk reaches sub-packages and the plugins (a package-dir mapping it missed would
    silently drop their examples)."""
    for name in ("mi_npr.kernels.ink", "mi_npr.viewpoint.search", "mi_npr.plugins.npr_lines"):
        assert name in MODULES
    assert not any(m.startswith("plugins.") for m in MODULES)
    assert {t.name.rsplit(".", 1)[0] for t in DOCTESTS} >= {"mi_npr.kernels.ink"}


@pytest.mark.parametrize("test", DOCTESTS, ids=[t.name for t in DOCTESTS])
def test_docstring_examples(test: doctest.DocTest, monkeypatch):
    monkeypatch.chdir(ROOT)
    test.globs = {**test.globs, "mi_npr": mi_npr, "np": np}
    runner = doctest.DocTestRunner(optionflags=_FLAGS)
    report: list[str] = []
    result = runner.run(test, out=report.append, clear_globs=True)
    assert result.failed == 0, "".join(report)
