"""The ray-tree pass of an image: ``raytree.hi``/``raytree.lo`` at pixel centres, the four edge
layers from the corner grid, and the overlay of the edge classes on the beauty.

One wavefront traces both ray sets: the W x H pixel-centre rays (the G-buffer's rays) and the
(W + 1) x (H + 1) corner rays (at integer film positions ``(x, y)``, ``0 <= x <= W``,
``0 <= y <= H``), both from :func:`mi_npr.raycast.film_grid` and
:func:`~mi_npr.raycast.pixel_rays`.
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from .. import layers as L
from ..compose import with_overlays
from ..gbuffer import GBuffer
from ..kernels import widen_lines
from ..raycast import film_grid, film_size, pixel_rays, require_jit
from ..scene import object_table, sensor_of
from ..session import SceneSession
from .edges import any_corner, as_image, classify_edges
from .lights import HARD, light_table
from .tracer import Trees, check_max_depth, trace_trees

#: Overlay colours (linear RGB) of the edge classes.
COLORS: dict[str, tuple[float, float, float]] = {
    L.EDGES_REAL: (1.0, 0.0, 0.0),
    L.EDGES_REFLECTION: (0.0, 0.0, 1.0),
    L.EDGES_REFRACTION: (0.0, 1.0, 0.0),
    L.EDGES_SHADOW: (0.5, 0.5, 0.5),
}
#: The layers this pass adds, in EXR / ``aov_names`` order.
LAYERS = (L.RAYTREE_HI, L.RAYTREE_LO, *L.EDGES)


def scene_max_depth(scene: mi.Scene) -> int:
    """The ``max_depth`` of the scene's ``npr_raytree`` integrator, else the default 3."""
    integ = scene.integrator()
    if getattr(integ, "PLUGIN", None) == "npr_raytree":
        return int(integ.params["max_depth"])
    return 3


def scene_shadow_lights(scene: mi.Scene) -> str:
    """The ``shadow_lights`` of the scene's ``npr_raytree`` integrator, else ``"hard"``."""
    integ = scene.integrator()
    if getattr(integ, "PLUGIN", None) == "npr_raytree":
        return str(integ.params["shadow_lights"])
    return HARD


def _slice(trees: Trees, start: int, count: int) -> Trees:
    idx = dr.arange(mi.UInt32, count) + start

    def g(tp: type, a: Any) -> Any:
        return dr.gather(tp, a, idx)

    return Trees(
        g(mi.UInt64, trees.hash),
        g(mi.UInt32, trees.root_obj),
        tuple(g(mi.UInt32, w) for w in trees.root_lights),
        tuple((g(mi.UInt64, a), g(mi.UInt64, b)) for a, b in trees.levels),
    )


def _selected_trees(corners: Trees, ids: Any) -> tuple[Trees, Any]:
    """The corner trees with their primary objects in the ids of ``ids`` (an object-level
    :class:`~mi_npr.contours.idmode.IdMap`: unselected objects are background), and whether
    each corner sees a selected object."""
    lut = mi.UInt32(ids.object_lut())
    root = dr.gather(mi.UInt32, lut, corners.root_obj)
    return Trees(corners.hash, root, corners.root_lights, corners.levels), root != 0


def raytree_layers(
    scene: mi.Scene,
    sensor: int | mi.Sensor = 0,
    max_depth: int = 3,
    ids: Any = None,
    shadow_lights: str = HARD,
) -> dict[str, Any]:
    """``raytree.hi``, ``raytree.lo`` (uint32) and the four ``edges.*`` layers (float32 0/1)
    of ``sensor``'s image, each an (H, W) Dr.Jit tensor.

    ``ids`` (an :class:`~mi_npr.contours.idmode.IdMap` of a mode in
    :data:`~mi_npr.contours.idmode.OBJECT_MODES`) chooses what one object is for
    ``edges.real`` and which objects are drawn: an edge pixel of any class is kept only when
    one of its four corner rays sees a selected object first. ``shadow_lights`` picks the
    lights of the trees (:mod:`mi_npr.raytree.lights`; hard-shadow lights by default)."""
    max_depth = check_max_depth(max_depth)
    require_jit("ray trees")
    s = sensor_of(scene, sensor)
    w, h = film_size(s)
    objects = object_table(scene)
    lights = light_table(scene, objects, shadow_lights)
    n_px, n_c = w * h, (w + 1) * (h + 1)
    (cx, cy), (kx, ky) = film_grid(w, h), film_grid(w, h, corners=True)
    x, y = dr.concat([cx, kx]), dr.concat([cy, ky])
    trees = trace_trees(scene, pixel_rays(s, x, y), objects, lights, max_depth)
    dr.eval(trees.hash, trees.root_obj, trees.root_lights, trees.levels)
    hi, lo = _slice(trees, 0, n_px).hi_lo()
    corners = _slice(trees, n_px, n_c)
    if ids is not None and not ids.identity:
        corners, seen = _selected_trees(corners, ids)
        keep = mi.Float(any_corner(seen, w, h))
        edges = {k: v * keep for k, v in classify_edges(corners, w, h).items()}
    else:
        edges = classify_edges(corners, w, h)
    dr.eval(hi, lo, *edges.values())
    out = {L.RAYTREE_HI: as_image(hi, w, h), L.RAYTREE_LO: as_image(lo, w, h)}
    out.update({name: as_image(v, w, h) for name, v in edges.items()})
    return out


def overlay(gb: GBuffer, line_width: float = 1.0) -> GBuffer:
    """``gb`` with each edge class drawn over the beauty in its colour (:data:`COLORS`),
    ``line_width`` pixels wide; the untouched beauty stays in ``beauty.R/G/B``."""
    if line_width == 1.0:
        return with_overlays(gb, [(gb[name], color) for name, color in COLORS.items()])

    wide = [(np.asarray(widen_lines(gb[n], float(line_width))), c) for n, c in COLORS.items()]
    return with_overlays(gb, wide)


def add_raytree(
    scene: mi.Scene | SceneSession,
    sensor: int | mi.Sensor,
    gb: GBuffer,
    max_depth: int = 3,
    *,
    ids: Any = None,
    shadow_lights: str = HARD,
    line_width: float = 1.0,
) -> GBuffer:
    """``gb`` plus the ray-tree layers (:func:`raytree_layers`), with the edge classes
    composited onto ``R G B``."""
    session = scene if isinstance(scene, SceneSession) else None
    if session is None:
        src = gb.metadata.get("mi_npr/scene")
        session = SceneSession(scene, sensor_of(scene, sensor), src)
    with session.step("ray-tree pass"):
        new = raytree_layers(session.scene, session.sensor, max_depth, ids, shadow_lights)
    out = overlay(gb.with_layers(new), line_width)
    meta = {"mi_npr/raytree_max_depth": max_depth, "mi_npr/raytree_shadow_lights": shadow_lights}
    return out.with_metadata(**meta)
