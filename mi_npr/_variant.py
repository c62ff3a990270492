"""Mitsuba variants and the registration of mi-npr's plugins for each of them.

Python integrators subclass the *current* variant's ``mi.SamplingIntegrator`` and are registered
per variant, so every time a variant becomes active (through :func:`set_variant` or a plain
``mi.set_variant``) the base module :mod:`mi_npr.integrator` and every ``plugins/npr_*.py`` are
(re)imported, which re-runs their ``mi.register_integrator(...)`` (or ``register_bsdf``,
``register_shape``) line, like Mitsuba's own
``mitsuba.ad.integrators`` does.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys

import mitsuba as mi

import mi_npr.plugins as pkg

from . import _llvm
from .errors import ParameterError

DEFAULT_VARIANT = "llvm_ad_rgb"


def plugin_modules() -> list[str]:
    """Names of the plugin modules shipped in ``mi_npr.plugins`` (``npr_gbuffer``, ...)."""

    return sorted(m.name for m in pkgutil.iter_modules(pkg.__path__) if m.name.startswith("npr_"))


_registered_for: str | None = None


def register_plugins() -> list[str]:
    """(Re)import the integrator base and every plugin for the active variant; their names."""
    global _registered_for
    if mi.variant() is None:
        return []
    base = "mi_npr.integrator"
    if base in sys.modules:
        importlib.reload(sys.modules[base])
    else:
        importlib.import_module(base)
    names = plugin_modules()
    for name in names:
        full = f"mi_npr.plugins.{name}"
        if full in sys.modules:
            importlib.reload(sys.modules[full])
        else:
            importlib.import_module(full)
    _registered_for = mi.variant()
    return names


def _on_variant_change(old: str | None, new: str | None) -> None:
    if new is not None:
        register_plugins()


def set_variant(name: str | None = None) -> str:
    """Activate a Mitsuba variant (default ``$MI_NPR_VARIANT`` or ``llvm_ad_rgb``) and register
    mi-npr's plugins for it. Returns the variant's name.

    JIT variants only (``llvm_*``, ``cuda_*`` where a GPU is present): a scalar variant can be
    activated, but mi-npr's plugins and functions then raise a one-line error.
    """
    name = name or os.environ.get("MI_NPR_VARIANT") or DEFAULT_VARIANT
    if name not in mi.variants():
        raise ParameterError(
            f"variant {name!r} is not available (available: {', '.join(mi.variants())})"
        )
    sel = _llvm.LAST_SELECTION
    if name.startswith("llvm") and sel is not None and sel.disabled:
        raise _llvm.LLVMNotFoundError(sel.note)
    if mi.variant() == name:
        if _registered_for != name:
            register_plugins()
        return name
    try:
        mi.set_variant(name)  # the variant callback registers the plugins
    except ImportError as e:
        hint = ""
        if name.startswith("llvm") and sel is not None and sel.chosen is not None:
            hint = f" (libLLVM in use: {sel.chosen.describe()})"
        raise ParameterError(f"variant {name!r} cannot be activated: {e}{hint}") from None
    return name


def install() -> None:
    """Called once by ``import mi_npr``: register the plugins again at every variant change."""
    mi.detail.add_variant_callback(_on_variant_change)
