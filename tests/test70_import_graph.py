"""mi_npr's import graph, built from the source: no cycles, and data flows one way.

Every ``import`` statement counts, at the top of a module or inside a function (an import inside
a function hides a cycle from Python but not from a reader); only ``if TYPE_CHECKING:`` blocks are
left out. Modules are named as installed: ``plugins/`` is ``mi_npr.plugins`` and ``scenes_xml/``
is ``mi_npr.data`` (pyproject's package-dir). ``from mi_npr.kernels import lines`` is an edge to
the package ``mi_npr.kernels`` (its ``__init__`` runs), ``from mi_npr import kernels`` one to
the module ``mi_npr.kernels``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from .helpers import ROOT

#: Source folders and the package each one is installed as.
PACKAGES = {"mi_npr": "mi_npr", "plugins": "mi_npr.plugins", "scenes_xml": "mi_npr.data"}

#: The stages of the data flow, first to last: a module of a stage imports no later stage.
ALGORITHMS = (
    "mi_npr.kernels",
    "mi_npr.contours",
    "mi_npr.raytree",
    "mi_npr.viewpoint",
    "mi_npr.foliage",
    "mi_npr.camera",
    "mi_npr.strokes",
)
LATER = ("mi_npr.drawings", "mi_npr.pipeline", "mi_npr.batch", "mi_npr.paths", "mi_npr.cli")


def modules(root: Path, packages: dict[str, str]) -> dict[str, Path]:
    """Module name -> file, for every ``.py`` file of the source folders."""
    out = {}
    for folder, package in packages.items():
        for f in sorted((root / folder).rglob("*.py")):
            parts = list(f.relative_to(root / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([package, *parts])] = f
    return out


def _type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(tree: ast.AST):
    """Every import node, skipping ``if TYPE_CHECKING:`` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if _type_checking(node):
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        stack.extend(ast.iter_child_nodes(node))


def graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules of ``mods`` it imports."""

    def known(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    edges: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1])
                    base = f"{base}.{node.module}" if node.module else base
                else:
                    base = node.module or ""
                targets = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names
                ]
            for t in targets:
                k = known(t)
                if k is not None and k != mod:
                    edges[mod].add(k)
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
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
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def _cycle_text(comp: list[str], edges: dict[str, set[str]]) -> str:
    inside = set(comp)
    return "; ".join(f"{m} -> {', '.join(sorted(edges[m] & inside))}" for m in comp)


@pytest.fixture(scope="module")
def edges() -> dict[str, set[str]]:
    return graph(modules(ROOT, PACKAGES))


def test01_the_checker_finds_a_hidden_cycle(tmp_path):
    """A cycle through an import inside a function, and one through a package's __init__."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("def f():\n    from . import b\n")
    (pkg / "b.py").write_text("from .a import f\n")
    (pkg / "sub" / "__init__.py").write_text("from .x import y\n")
    (pkg / "sub" / "x.py").write_text("from ..c import z\ny = 1\n")
    (pkg / "c.py").write_text("from pkg.sub import y\nz = 2\n")
    (pkg / "d.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import e\n"
    )
    (pkg / "e.py").write_text("from . import d\n")
    found = cycles(graph(modules(tmp_path, {"pkg": "pkg"})))
    assert sorted(found) == [["pkg.a", "pkg.b"], ["pkg.c", "pkg.sub", "pkg.sub.x"]]


def test02_every_source_folder_is_seen(edges):
    assert {"mi_npr", "mi_npr.plugins.npr_lines", "mi_npr.data", "mi_npr.cli"} <= set(edges)
    assert "mi_npr.drawings" in edges["mi_npr.plugins.npr_lines"]
    assert "mi_npr.pipeline" in edges["mi_npr.cli.render"]


def test03_no_import_cycles(edges):
    found = cycles(edges)
    assert not found, "import cycles: " + " | ".join(_cycle_text(c, edges) for c in found)


@pytest.mark.parametrize("package", ALGORITHMS)
def test04_algorithms_never_import_the_pipeline(edges, package):
    """Kernels, contours, ray trees, viewpoints, foliage and cameras serve the drawings, the
    pipeline, batches and the command line; they import none of them."""
    bad = {
        (m, t)
        for m, targets in edges.items()
        if m == package or m.startswith(package + ".")
        for t in targets
        if any(t == later or t.startswith(later + ".") for later in LATER)
    }
    assert not bad


def test05_no_module_imports_the_root_package(edges):
    """``import mi_npr`` runs the whole public API: inside the package it is always a cycle
    (the command line alone reads the start-up state from it)."""
    assert {m for m, t in edges.items() if "mi_npr" in t} <= {"mi_npr.cli"}


def _unexplained_inner_imports(path: Path) -> list[int]:
    """Lines of imports inside functions with no comment saying why: on the line itself, on the
    line above, or above the first import of the run of import lines it belongs to."""
    lines = path.read_text(encoding="utf-8").splitlines()
    tree = ast.parse("\n".join(lines))
    out = []
    for fn in ast.walk(tree):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in _imports(fn):
            k = node.lineno - 1  # 0-based
            explained = "#" in lines[k]
            j = k
            while not explained and j > 0:
                above = lines[j - 1].strip()
                code = above.partition("#")[0].rstrip()
                if above.startswith(("import ", "from ")):
                    explained = "#" in above  # a comment on the run of imports it belongs to
                    j -= 1
                    continue
                # a comment line, or one on the block's opener (try:)
                explained = above.startswith("#") or ("#" in above and code.endswith(":"))
                break
            if not explained:
                out.append(node.lineno)
    return sorted(set(out))


def test06_the_checker_of_inner_imports(tmp_path):
    f = tmp_path / "m.py"
    f.write_text(
        "def a():\n    import os\n"  # 2: unexplained
        "def b():\n    # slow to import\n    import json\n    import re\n"
        "def c():\n    import csv  # optional\n"
        "def d():\n    x = 1  # a comment that is not about the import\n    import io\n"  # 11
        "def e():\n    try:  # optional\n        import yaml\n    except ImportError:\n"
        "        pass\n"
    )
    assert _unexplained_inner_imports(f) == [2, 11]


def test07_imports_inside_functions_say_why():
    """An import inside a function only where it keeps a start fast or a dependency optional,
    with a comment saying so."""
    bad = {
        str(f.relative_to(ROOT)): lines
        for f in modules(ROOT, PACKAGES).values()
        if (lines := _unexplained_inner_imports(f))
    }
    assert not bad


def test08_the_command_starts_without_scipy():
    """``import mi_npr.cli`` (every command's start) loads no SciPy: its import costs ~0.15 s,
    and only some drawings need it, where they use it."""
    import subprocess
    import sys

    code = "import sys, mi_npr.cli; print(sorted(m for m in sys.modules if m.startswith('scipy')))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "[]", out.stdout[:500]
