"""Start-up hook: let ``import mitsuba`` (and the ``mitsuba`` command) find a usable libLLVM.

Dr.Jit 1.5 aborts the process on the LLVM 14-16 that Debian ships, and it loads the library named
by ``DRJIT_LIBLLVM_PATH`` when it is imported. ``import mi_npr`` chooses one before that, but a
Mitsuba user writes ``import mitsuba as mi; mi.set_variant("llvm_ad_rgb"); import mi_npr``, and
Mitsuba's own ``mitsuba`` command never imports mi-npr at all. So mi-npr installs
``mi_npr_llvm.pth`` into site-packages; Python runs its one line at start-up, which calls
:func:`install`. That only puts a finder at the front of ``sys.meta_path``: nothing else happens
until some code imports ``drjit``. Then, *unless the user has set* ``DRJIT_LIBLLVM_PATH``, the
finder runs mi-npr's own choice (:func:`mi_npr._llvm.select`, loaded from its file so that the
``mi_npr`` package, which imports Dr.Jit, is not imported) and exports the library it picks, plus
``MI_NPR_LLVM_HOOK`` = that path, so one can tell the hook chose it. The finder then steps aside
and the normal import of ``drjit`` goes on.

The hook never raises: any problem leaves the environment as it was (``import mi_npr`` still
reports a missing LLVM clearly). ``MI_NPR_NO_LLVM_HOOK=1`` switches it off.
"""

from __future__ import annotations

import os
import sys

ENV = "DRJIT_LIBLLVM_PATH"
MARK = "MI_NPR_LLVM_HOOK"
OFF = "MI_NPR_NO_LLVM_HOOK"


def _select_module():
    """``mi_npr._llvm`` (already imported, or loaded from its file without its package)."""
    mod = sys.modules.get("mi_npr._llvm")
    if mod is not None:
        return mod
    import importlib.util

    pkg = importlib.util.find_spec("mi_npr")  # finds the package without running it
    if pkg is None or not pkg.submodule_search_locations:
        return None
    for folder in pkg.submodule_search_locations:
        path = os.path.join(folder, "_llvm.py")
        if os.path.isfile(path):
            name = "mi_npr_llvm_hook._select"
            spec = importlib.util.spec_from_file_location(name, path)
            if spec is None or spec.loader is None:
                return None
            mod = importlib.util.module_from_spec(spec)
            sys.modules[name] = mod  # dataclasses look their module up while the file runs
            spec.loader.exec_module(mod)
            return mod
    return None


def choose() -> str | None:
    """Export a usable libLLVM unless ``DRJIT_LIBLLVM_PATH`` is set; the path, or ``None``."""
    try:
        if os.environ.get(ENV):
            return None
        mod = _select_module()
        if mod is None:
            return None
        sel = mod.select()
        if sel.chosen is None:
            return None
        os.environ[ENV] = sel.chosen.path
        os.environ[MARK] = sel.chosen.path
        return sel.chosen.path
    except Exception:  # a start-up hook must never break the interpreter
        return None


class _Finder:
    """A meta-path finder that acts once, on the first ``import drjit``, and finds nothing."""

    def find_spec(self, name: str, path: object = None, target: object = None) -> None:
        if name == "drjit":
            uninstall()
            choose()
        return None


def install() -> None:
    """Called from ``mi_npr_llvm.pth`` at interpreter start-up: cheap, never raises."""
    try:
        if os.environ.get(ENV) or os.environ.get(OFF) or "drjit" in sys.modules:
            return
        if not any(isinstance(f, _Finder) for f in sys.meta_path):
            sys.meta_path.insert(0, _Finder())
    except Exception:
        pass


def uninstall() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _Finder)]
