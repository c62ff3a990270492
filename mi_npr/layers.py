"""Every layer (EXR channel) name mi-npr reads or writes, defined once.

Names follow OpenEXR's ``layer.channel`` convention, so Nuke and Blender group ``P.X P.Y P.Z`` into
a ``P`` layer and ``edges.real`` into an ``edges`` layer. Integer layers are ``uint32`` in the
:class:`~mi_npr.gbuffer.GBuffer` and in EXR files; in the tensor that ``mi.render`` returns they are
stored as float32 (exact below 2**24).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LayerSpec:
    """What a layer holds: its name, its pixel type and its value where nothing is hit."""

    name: str
    dtype: type
    description: str
    background: float = 0.0


R, G, B = "R", "G", "B"
RGB = (R, G, B)
#: The beauty before lines or overlays were composited onto R G B (kept for compositing apps).
RAW_RGB = ("beauty.R", "beauty.G", "beauty.B")
Z = "Z"
P = ("P.X", "P.Y", "P.Z")
N = ("N.X", "N.Y", "N.Z")
OBJECT_ID = "object_id"
PRIM_ID = "prim_id"

LINES = "lines"
CONTOUR = "contour"
EDGES_REAL = "edges.real"
EDGES_REFLECTION = "edges.reflection"
EDGES_REFRACTION = "edges.refraction"
EDGES_SHADOW = "edges.shadow"
EDGES = (EDGES_REAL, EDGES_REFLECTION, EDGES_REFRACTION, EDGES_SHADOW)
RAYTREE_HI = "raytree.hi"
RAYTREE_LO = "raytree.lo"
#: Foliage (issue 8): which leaf primitive a pixel sees.
LEAF_ID = "leaf_id"

#: The G-buffer channels, in the order they follow the beauty channels in ``mi.render``'s output.
GBUFFER_AOVS = (Z, *P, *N, OBJECT_ID, PRIM_ID)
#: Everything the ``npr_gbuffer`` integrator produces, in EXR order.
GBUFFER = (*RGB, *GBUFFER_AOVS)

_f32, _u32 = np.float32, np.uint32

SPECS: dict[str, LayerSpec] = {
    s.name: s
    for s in (
        LayerSpec(R, _f32, "beauty, linear Rec.709 red (nested integrator, film filter and spp)"),
        LayerSpec(G, _f32, "beauty, linear green"),
        LayerSpec(B, _f32, "beauty, linear blue"),
        LayerSpec(
            Z,
            _f32,
            "camera-space depth along the view axis; +inf where nothing is hit",
            float("inf"),
        ),
        LayerSpec(P[0], _f32, "world-space position x of the pixel-centre hit (0 on background)"),
        LayerSpec(P[1], _f32, "world-space position y"),
        LayerSpec(P[2], _f32, "world-space position z"),
        LayerSpec(N[0], _f32, "world-space shading normal x (0 on background)"),
        LayerSpec(N[1], _f32, "world-space shading normal y"),
        LayerSpec(N[2], _f32, "world-space shading normal z"),
        LayerSpec(OBJECT_ID, _u32, "object id: 0 = background, 1..N = the object table's shapes"),
        LayerSpec(PRIM_ID, _u32, "primitive (triangle) index within its shape; 0 on background"),
        LayerSpec(LINES, _f32, "gray-level line image in [0, 1] (depth contours and edges)"),
        LayerSpec(RAW_RGB[0], _f32, "beauty red before lines or overlays were composited"),
        LayerSpec(RAW_RGB[1], _f32, "beauty green before lines or overlays were composited"),
        LayerSpec(RAW_RGB[2], _f32, "beauty blue before lines or overlays were composited"),
        LayerSpec(CONTOUR, _u32, "object id on apparent-contour pixels, 0 elsewhere"),
        LayerSpec(EDGES_REAL, _f32, "1 where the primary hit object differs (real contour)"),
        LayerSpec(EDGES_REFLECTION, _f32, "1 where trees first differ in a reflection subtree"),
        LayerSpec(EDGES_REFRACTION, _f32, "1 where trees first differ in a refraction subtree"),
        LayerSpec(EDGES_SHADOW, _f32, "1 where the same object sees different lights (shadow)"),
        LayerSpec(RAYTREE_HI, _u32, "upper 32 bits of the 64-bit ray-tree signature hash"),
        LayerSpec(RAYTREE_LO, _u32, "lower 32 bits of the 64-bit ray-tree signature hash"),
        LayerSpec(LEAF_ID, _u32, "leaf primitive: 1 + leaf index over all leaf meshes; 0 = none"),
    )
}


def spec(name: str) -> LayerSpec | None:
    """The spec of a known layer, or ``None`` for a user-defined one."""
    return SPECS.get(name)
