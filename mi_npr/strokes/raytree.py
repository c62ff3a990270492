"""Strokes of the ray trees: reflection, refraction and shadow lines.

The ray-tree edge classes (:func:`mi_npr.raytree.render.raytree_layers`: Nehab-Gattass
signatures compared at the four corners of each pixel) mark the pixels where what a
reflection, a refraction or a shadow shows changes. Such a line has no object-space source (it
is where a secondary ray's first hit changes), so it is found in image space, on the exact ray
trees, and traced: each class's mask becomes polylines through pixel centres
(:func:`mi_npr.contours.vector.trace_strokes`: chained, ending at ends and junctions, passing
straight through crossings), typed ``reflection``, ``refraction`` or ``shadow``.

**Attributes.** Every vertex gets those of the surface its pixel-centre ray sees first, through
glass (:func:`mi_npr.strokes.outlines.probe`): the surface on which the reflection, refraction
or shadow is seen, its world position, depth, object and primitive. A stroke is split where
that surface is seen through glass on one side and directly on the other.

**Ambiguities resolved.** The vertices are pixel centres: the class changes between two
corners of the marked pixel, so a vertex lies within ``sqrt(2) / 2`` px of the change (the
object-space strokes are exact; these are not). These strokes are visible (``qi = 0``): their
pixels are the ones seen. A pixel that two classes mark belongs to the first of refraction,
reflection, shadow, as in :func:`mi_npr.raytree.edges.classify_edges`.
"""

from __future__ import annotations

import itertools

import mitsuba as mi
import numpy as np

from .. import layers as L
from ..contours.vector import trace_strokes
from ..gbuffer import Projection
from ..raytree.lights import HARD
from ..raytree.render import raytree_layers
from ..scene import ObjectTable
from .model import Stroke
from .outlines import probe

#: The stroke kind of each ray-tree edge layer.
CLASSES = {
    L.EDGES_REFRACTION: "refraction",
    L.EDGES_REFLECTION: "reflection",
    L.EDGES_SHADOW: "shadow",
}


def raytree_strokes(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    camera: Projection,
    max_depth: int = 3,
    shadow_lights: str = HARD,
) -> list[Stroke]:
    """The reflection, refraction and shadow strokes of ``sensor``'s image (module docstring),
    from ray trees of ``max_depth`` levels and the lights ``shadow_lights`` picks."""
    layers = raytree_layers(scene, sensor, max_depth, shadow_lights=shadow_lights)
    out: list[Stroke] = []
    for name, kind in CLASSES.items():
        mask = np.asarray(layers[name].numpy()) > 0.5
        lines = [p for p in trace_strokes(mask) if len(p) >= 2]
        if not lines:
            continue
        pts = np.concatenate(lines)
        seen = probe(scene, sensor, table, pts, camera)
        start = 0
        for line in lines:
            sl = slice(start, start + len(line))
            start += len(line)
            out += _strokes(kind, line, {k: v[sl] for k, v in seen.items()})
    return out


def _strokes(kind: str, line: np.ndarray, seen: dict[str, np.ndarray]) -> list[Stroke]:
    """``line`` (its first vertex repeated last when closed) as strokes of one glass state."""
    closed = len(line) > 2 and np.array_equal(line[0], line[-1])
    glass = seen["glass"]
    if closed and np.all(glass == glass[0]):
        runs, closed_run = [np.arange(len(line) - 1)], True
    else:
        cut = np.flatnonzero(np.diff(glass.astype(np.int8))) + 1
        # neighbouring runs share their meeting vertex so that the line has no gap
        bounds = itertools.pairwise([0, *cut.tolist(), len(line)])
        runs = [np.arange(a, b + 1 if b < len(line) else b) for a, b in bounds]
        closed_run = False
    return [
        Stroke(
            kind=kind,
            points=line[idx],
            position=seen["position"][idx],
            depth=seen["depth"][idx],
            object_id=seen["object_id"][idx],
            prim=seen["prim"][idx],
            qi=0,
            through_glass=bool(glass[idx[0]]),
            closed=closed_run,
        )
        for idx in runs
        if len(idx) >= 2
    ]
