"""The public API, imported by ``mi_npr/__init__.py`` once a usable LLVM is chosen."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import _llvm, _variant, layers
from ._variant import DEFAULT_VARIANT, register_plugins, set_variant
from .errors import (
    InputError,
    MemoryLimitError,
    NprError,
    OutputError,
    ParameterError,
    SceneError,
)
from .gbuffer import GBuffer, Projection

#: Why the requested variant could not be activated at import (the ``mi-npr`` command only,
#: which reports it on one line; anywhere else the import raises it).
STARTUP_ERROR: Exception | None = None

_variant.install()
if mi.variant() is None:
    try:
        set_variant(_llvm.requested_variant())
    except (ParameterError, _llvm.LLVMNotFoundError) as e:
        if not _llvm.cli_process():
            raise
        STARTUP_ERROR = e
        set_variant("scalar_rgb")  # the modules below need some variant to import
else:
    register_plugins()

from . import (  # noqa: E402
    batch,
    camera,
    coherence,
    contours,
    cryptomatte,
    data,
    drawings,
    foliage,
    io,
    kernels,
    paths,
    pipeline,
    raytree,
    viewpoint,
)
from .camera import Camera, camera_of, projection_of  # noqa: E402
from .pipeline import (  # noqa: E402
    render_contours,
    render_layers,
    render_raytree,
    render_vector_contours,
)
from .render import render, render_gbuffer  # noqa: E402
from .scene import load_scene, object_table  # noqa: E402

__all__ = [
    "DEFAULT_VARIANT",
    "Camera",
    "GBuffer",
    "InputError",
    "MemoryLimitError",
    "NprError",
    "OutputError",
    "ParameterError",
    "Projection",
    "SceneError",
    "batch",
    "camera",
    "camera_of",
    "coherence",
    "contours",
    "cryptomatte",
    "data",
    "dr",
    "drawings",
    "foliage",
    "io",
    "kernels",
    "layers",
    "load_scene",
    "mi",
    "object_table",
    "paths",
    "pipeline",
    "projection_of",
    "raytree",
    "render",
    "render_contours",
    "render_gbuffer",
    "render_layers",
    "render_raytree",
    "render_vector_contours",
    "set_variant",
    "viewpoint",
]
