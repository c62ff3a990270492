"""Every parameter table of mi-npr by name: the drawings', the plugins', the lines chain's and
each command's, for the tests that try every parameter with bad values and for the CLI
reference. A table is owned by the library module that checks its values; the command line
only reads them."""

from __future__ import annotations

import importlib
import pkgutil

from .. import plugins as plugin_pkg
from ..drawings import DRAWINGS
from ..kernels import LINES_PARAMS
from ..params import Param
from ..views import VIEW_PARAMS
from . import commands


def command_tables() -> dict[str, tuple[Param, ...]]:
    """Each command's own flags' parameters (``mi-npr render``: width, height, spp, seed)."""
    mods = commands() or {}
    return {name: tuple(p for t in m.TABLES for p in t) for name, m in mods.items()}


def all_tables() -> dict[str, tuple[Param, ...]]:
    """Every table: ``lines`` (the chain's), each plugin's ``PARAMS`` (module- or
    class-level), each drawing's, and ``mi-npr COMMAND`` for each command's own flags."""
    tables: dict[str, tuple[Param, ...]] = {"lines": LINES_PARAMS}
    for info in pkgutil.iter_modules(plugin_pkg.__path__):
        mod = importlib.import_module(f"{plugin_pkg.__name__}.{info.name}")
        found = [getattr(mod, "PARAMS", None)]
        found += [getattr(v, "PARAMS", None) for v in vars(mod).values() if isinstance(v, type)]
        for t in found:
            if t and all(isinstance(p, Param) for p in t):
                tables[info.name] = tuple(dict.fromkeys([*tables.get(info.name, ()), *t]))
    for name, d in DRAWINGS.items():
        if d.params:
            tables[f"drawing {name}"] = d.params
    for cmd, t in command_tables().items():
        if t:
            tables[f"mi-npr {cmd}"] = t
    tables["mi-npr batch --views"] = VIEW_PARAMS
    return tables
