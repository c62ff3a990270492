"""Foliage abstraction (thesis section 4.3): leaf primitives, higher-level primitives (HLPs) with
implicit-surface normals, and the thesis's four drawing styles.

- :mod:`~mi_npr.foliage.plant` -- :class:`Plant` (a plant's leaves), :func:`read_plant` (PLY/OBJ
  mesh or point set);
- :mod:`~mi_npr.foliage.procedural` -- :func:`procedural_tree`, a seeded tree/bush generator;
- :mod:`~mi_npr.foliage.hlp` -- :class:`HLPSet` (ellipsoid blobs, their summed field, its
  closed-form gradient, JSON I/O) and :func:`build_hlps` (k-means clustering);
- :mod:`~mi_npr.foliage.leaves` -- :func:`make_leaves` (leaf primitives: size, shape, placement,
  orientation; one mesh) and :func:`leaf_id_layer` (the ``leaf_id`` layer);
- :mod:`~mi_npr.foliage.styles` -- the four styles as presets and as scenes.

The Mitsuba side is two plugins: the ``npr_leaves`` shape (builds the leaf mesh when the scene
loads, so ``leaf_size`` can be an XML ``<default>``) and the ``npr_foliage`` BSDF (shades with
the mixed normal ``normalize((1 - a) n_leaf + a n_hlp)`` and puts it in the G-buffer's ``N``).
"""

from __future__ import annotations

from . import styles
from .hlp import ISO, HLPSet, build_hlps
from .leaves import (
    ORIENTATIONS,
    PLACEMENTS,
    SHAPES,
    LeafTemplate,
    Leaves,
    leaf_id_layer,
    leaf_template,
    make_leaves,
)
from .plant import Plant, read_plant
from .procedural import procedural_tree
from .styles import STYLES, make_scene

__all__ = [
    "ISO",
    "ORIENTATIONS",
    "PLACEMENTS",
    "SHAPES",
    "STYLES",
    "HLPSet",
    "LeafTemplate",
    "Leaves",
    "Plant",
    "build_hlps",
    "leaf_id_layer",
    "leaf_template",
    "make_leaves",
    "make_scene",
    "procedural_tree",
    "read_plant",
    "styles",
]
