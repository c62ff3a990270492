"""Readable ray-tree signatures in the notation of the paper's Fig. 5 (``4A2BL1C``).

The figure itself is missing from the extracted text; its caption gives trees *a* and *b* the
strings ``4A2BL1C`` and ``7A3BL1``. We read them as: nodes listed children first (post-order), each
as its *position* (heap numbering: root 1, reflection child of ``p`` = ``2p``, refraction child =
``2p + 1``), its *object* letter and the *lights* it sees, the root's position 1 left out. Tree
*a* is then a primary hit on object C (position 1), whose mirror reflection hits B (position 2),
which sees light 1 and whose own reflection hits A (position 4). Tree *b* is the same chain along
refraction rays (positions 3 and 7); its root letter is not in the extracted caption, which we
take for an extraction loss.

Grammar (every tree has exactly one string and every string one tree)::

    signature := node* root | ""            ("" = the ray hits nothing)
    node      := POSITION object light*     (POSITION >= 2, decimal)
    root      := object light*
    object    := "A".."Z" for ids 1..26,  "{id}" for ids > 26
    light     := "L1".."L9" for lights 1..9,  "L{k}" for lights k > 9

Order: a node's reflection subtree, then its refraction subtree, then the node; lights in
increasing number. Object ids are the stable ids of :func:`mi_npr.object_table` (``object_id``
layer); light numbers those of :func:`mi_npr.raytree.light_table`. A ray that hits nothing adds
no node (a mirror reflecting the empty background has no child), and the tree of a ray that
hits nothing is the empty string.

>>> format_signature({1: (3, (0,)), 2: (2, (1,)), 4: (1, (0,))})
'4A2BL1C'
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..raycast import film_grid, film_size, pixel_rays
from ..session import RENDER_LOCK, SceneSession
from .lights import light_table
from .render import scene_max_depth, scene_shadow_lights
from .tracer import Nodes, trace_trees

Tree = Mapping[int, tuple[int, Sequence[int]]]


def object_letters(obj: int) -> str:
    """``1 -> "A"`` ... ``26 -> "Z"``, larger ids in braces (``27 -> "{27}"``)."""
    if obj < 1:
        raise ParameterError(f"object id {obj} has no letter (0 is the background)")
    return chr(ord("A") + obj - 1) if obj <= 26 else f"{{{obj}}}"


def light_marks(words: Sequence[int]) -> str:
    """The lights of a mask, ``L1`` ... ``L9``, ``L{10}`` ... (bit ``k - 1`` = light ``k``)."""
    out = []
    for w_i, w in enumerate(words):
        for b in range(32):
            if (int(w) >> b) & 1:
                k = 32 * w_i + b + 1
                out.append(f"L{k}" if k <= 9 else f"L{{{k}}}")
    return "".join(out)


def format_signature(tree: Tree) -> str:
    """The string of a tree given as ``{position: (object id, light-mask words)}``."""
    if not tree:
        return ""
    if 1 not in tree:
        raise ParameterError("a ray tree needs a root (position 1)")

    def walk(p: int) -> str:
        if p not in tree:
            return ""
        obj, words = tree[p]
        me = object_letters(obj) + light_marks(words)
        return walk(2 * p) + walk(2 * p + 1) + (str(p) if p > 1 else "") + me

    return walk(1)


def signatures_of(nodes: Nodes, n: int) -> list[str]:
    """The strings of rays ``0 .. n - 1`` from recorded :class:`Nodes`."""
    trees: list[dict[int, tuple[int, tuple[int, ...]]]] = [{} for _ in range(n)]
    for r, p, o, w in zip(nodes.ray, nodes.pos, nodes.obj, nodes.lights, strict=True):
        trees[int(r)][int(p)] = (int(o), tuple(int(v) for v in w))
    return [format_signature(t) for t in trees]


def _trace_pixels(
    session: SceneSession, x: Any, y: Any, max_depth: int | None, shadow_lights: str | None
) -> list[str]:
    scene = session.scene
    depth = scene_max_depth(scene) if max_depth is None else max_depth
    chosen = scene_shadow_lights(scene) if shadow_lights is None else shadow_lights
    with RENDER_LOCK:
        objects = session.objects
        lights = light_table(scene, objects, chosen)
        rays = pixel_rays(session.sensor, mi.Float(x), mi.Float(y))
        trees = trace_trees(scene, rays, objects, lights, depth, record=True)
    assert trees.nodes is not None
    return signatures_of(trees.nodes, dr.width(rays.o))


def signature(
    scene: str | os.PathLike[str] | mi.Scene,
    x: int,
    y: int,
    *,
    max_depth: int | None = None,
    sensor: int = 0,
    shadow_lights: str | None = None,
) -> str:
    """The signature of pixel ``(x, y)``'s tree (ray through the pixel centre, like the
    ``raytree.hi``/``raytree.lo`` layers), for debugging and tests.

    ``max_depth`` and ``shadow_lights`` (the lights in the trees,
    :mod:`mi_npr.raytree.lights`) default to the scene's ``npr_raytree`` integrator's, else 3
    and ``"hard"``, as in the ray-tree layers.

    >>> mi_npr.raytree.signature("scenes_xml/scene1.xml", 350, 260)
    '2BL1DL1'

    (the middle sphere D, lit by light 1, whose mirror reflection hits the floor B, lit by
    light 1).
    """
    session = SceneSession.open(scene, sensor=sensor)
    w, h = film_size(session.sensor)
    for name, v, hi in (("x", x, w), ("y", y, h)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v < hi:
            raise ParameterError(f"{name} = {v!r}: must be an integer pixel index in 0..{hi - 1}")
    return _trace_pixels(session, [x + 0.5], [y + 0.5], max_depth, shadow_lights)[0]


def signatures(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    max_depth: int | None = None,
    sensor: int = 0,
    corners: bool = False,
    shadow_lights: str | None = None,
) -> np.ndarray:
    """The signatures of every pixel centre, an (H, W) array of ``str``; with ``corners``, of
    every pixel corner, (H + 1, W + 1) (the rays the edge layers compare)."""
    session = SceneSession.open(scene, sensor=sensor)
    w, h = film_size(session.sensor)
    cw, ch = (w + 1, h + 1) if corners else (w, h)
    out = _trace_pixels(session, *film_grid(w, h, corners), max_depth, shadow_lights)
    return np.array(out, dtype=object).reshape(ch, cw)
