"""Every layer (EXR channel) name mi-npr reads or writes, defined once.

Names are what Nuke and Blender read as layers (Blender's multilayer reader,
``imb_exr_split_channel_name`` in ``openexr_api.cpp``): the *last* dot-separated token is the
channel and must be ONE letter (R G B A X Y Z W U V; longer tokens are dropped or, in older
versions, collapsed onto their last letter), the token before it is the pass, anything before
that the layer. So every layer is ``pass.channel`` with a one-letter channel: ``P.X``, ``N.Z``,
``beauty.R``; a single-valued layer is ``<name>.V`` (value): ``object_id.V``, ``lines.V``;
the ray-tree classes are one pass each (``edges_real.V``, ...), since ``edges.real`` and
``edges.reflection`` would be one pass with unreadable channels. ``R G B`` (Blender's
"Combined", Nuke's ``rgba``) and ``Z`` (the OpenEXR standard depth channel: Blender's "Depth"
pass, Nuke's ``depth.Z``) stay bare. Cryptomatte layers follow their own specification
(:mod:`mi_npr.cryptomatte`).

Integer layers are ``uint32`` in the :class:`~mi_npr.gbuffer.GBuffer`. In EXR files ids are
stored as ``FLOAT`` holding whole numbers (exact below 2**24; a larger id is an error), because
OpenImageIO-based tools read ``UINT`` channels as normalised [0, 1] values; only the 64-bit
ray-tree hash halves, which are no ids and use all 32 bits, stay ``UINT``. In the tensor that
``mi.render`` returns every layer is float32.
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
    #: Pixel type in EXR files: ``"FLOAT"`` (ids too, exact below 2**24) or ``"UINT"``.
    exr_type: str = "FLOAT"


R, G, B = "R", "G", "B"
RGB = (R, G, B)
#: The beauty before lines or overlays were composited onto R G B (kept for compositing apps).
RAW_RGB = ("beauty.R", "beauty.G", "beauty.B")
Z = "Z"
P = ("P.X", "P.Y", "P.Z")
N = ("N.X", "N.Y", "N.Z")
OBJECT_ID = "object_id.V"
PRIM_ID = "prim_id.V"

LINES = "lines.V"
#: Coverage of the styled vector strokes (mi_npr.strokes).
STROKES = "strokes.V"
CONTOUR = "contour.V"
#: Ink in [0, 1] of the soft (differentiable) contours, ``contour_model = "soft"``.
CONTOUR_INK = "contour_ink.V"
EDGES_REAL = "edges_real.V"
EDGES_REFLECTION = "edges_reflection.V"
EDGES_REFRACTION = "edges_refraction.V"
EDGES_SHADOW = "edges_shadow.V"
EDGES = (EDGES_REAL, EDGES_REFLECTION, EDGES_REFRACTION, EDGES_SHADOW)
RAYTREE_HI = "raytree_hi.V"
RAYTREE_LO = "raytree_lo.V"
#: Cryptomatte 1.2 (mi_npr.cryptomatte): ``CryptoObject00.R`` ... as the specification names them.
CRYPTO_OBJECT = "CryptoObject"
CRYPTO_MATERIAL = "CryptoMaterial"
#: Foliage: which leaf primitive a pixel sees.
LEAF_ID = "leaf_id.V"

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
        LayerSpec(STROKES, _f32, "coverage in [0, 1] of the styled vector strokes"),
        LayerSpec(RAW_RGB[0], _f32, "beauty red before lines or overlays were composited"),
        LayerSpec(RAW_RGB[1], _f32, "beauty green before lines or overlays were composited"),
        LayerSpec(RAW_RGB[2], _f32, "beauty blue before lines or overlays were composited"),
        LayerSpec(CONTOUR, _u32, "object id on apparent-contour pixels, 0 elsewhere"),
        LayerSpec(CONTOUR_INK, _f32, "ink in [0, 1] of the soft, differentiable object outlines"),
        LayerSpec(EDGES_REAL, _f32, "1 where the primary hit object differs (real contour)"),
        LayerSpec(EDGES_REFLECTION, _f32, "1 where trees first differ in a reflection subtree"),
        LayerSpec(EDGES_REFRACTION, _f32, "1 where trees first differ in a refraction subtree"),
        LayerSpec(EDGES_SHADOW, _f32, "1 where the same object sees different lights (shadow)"),
        LayerSpec(
            RAYTREE_HI, _u32, "upper 32 bits of the 64-bit ray-tree signature hash", 0.0, "UINT"
        ),
        LayerSpec(
            RAYTREE_LO, _u32, "lower 32 bits of the 64-bit ray-tree signature hash", 0.0, "UINT"
        ),
        LayerSpec(LEAF_ID, _u32, "leaf primitive: 1 + leaf index over all leaf meshes; 0 = none"),
    )
}


def spec(name: str) -> LayerSpec | None:
    """The spec of a known layer, or ``None`` for a user-defined one."""
    return SPECS.get(name)


#: Names layers had before 0.2 (read from old files under their new names).
LEGACY: dict[str, str] = {
    "object_id": OBJECT_ID,
    "prim_id": PRIM_ID,
    "lines": LINES,
    "contour": CONTOUR,
    "edges.real": EDGES_REAL,
    "edges.reflection": EDGES_REFLECTION,
    "edges.refraction": EDGES_REFRACTION,
    "edges.shadow": EDGES_SHADOW,
    "raytree.hi": RAYTREE_HI,
    "raytree.lo": RAYTREE_LO,
    "leaf_id": LEAF_ID,
}

#: The largest integer float32 holds exactly (every integer up to it is exact).
FLOAT_EXACT = 2**24


def exr_type(name: str) -> str:
    """Pixel type of a layer in EXR files: ``"UINT"`` only for the layers whose spec says so."""
    known = spec(name)
    if known is not None:
        return known.exr_type
    return "FLOAT"


def meaning(name: str) -> str:
    """What a layer holds, in words (``""`` for a layer mi-npr does not know)."""
    known = spec(name)
    if known is not None:
        return known.description
    for crypto in (CRYPTO_OBJECT, CRYPTO_MATERIAL):
        rank = name.removeprefix(crypto)
        if rank != name and len(rank) == 4 and rank[:2].isdigit() and rank[2] == ".":
            k = 2 * int(rank[:2]) + (rank[3] in "BA")
            what = "id (name hash as float)" if rank[3] in "RB" else "coverage"
            return f"Cryptomatte {crypto}: {what} of rank {k}"
    return ""
