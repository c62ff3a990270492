"""The public API, imported by ``mi_npr/__init__.py`` once a usable LLVM is chosen."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import _variant, layers
from ._variant import DEFAULT_VARIANT, register_plugins, set_variant
from .errors import InputError, NprError, OutputError, ParameterError, SceneError
from .gbuffer import Camera, GBuffer

_variant.install()
if mi.variant() is None:
    set_variant()
else:
    register_plugins()

from . import contours, foliage, io, kernels, raytree, viewpoint  # noqa: E402
from .render import render, render_gbuffer  # noqa: E402
from .scene import camera_of, load_scene, object_table  # noqa: E402

__all__ = [
    "DEFAULT_VARIANT",
    "Camera",
    "GBuffer",
    "InputError",
    "NprError",
    "OutputError",
    "ParameterError",
    "SceneError",
    "camera_of",
    "contours",
    "dr",
    "foliage",
    "io",
    "kernels",
    "layers",
    "load_scene",
    "mi",
    "object_table",
    "raytree",
    "render",
    "render_gbuffer",
    "set_variant",
    "viewpoint",
]
