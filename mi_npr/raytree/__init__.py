"""Ray-tree signatures and classified ray-tree edges (paper, section 2.2.3: Nehab and Gattass).

Each pixel's ray tree (the object hit, the lights visible from it, and the trees of its mirror
reflection and glass refraction rays) is traced deterministically, hashed to 64 bits
(``raytree.hi``/``raytree.lo``) and written as a string in the paper's Fig. 5 notation
(:func:`signature`). Trees at pixel corners are compared to find edge pixels, each classified as
a real contour, a shadow, a reflection or a refraction edge (``edges.*`` layers).

Modules: :mod:`.lights` (light numbers, shadow rays), :mod:`.tracer` (the wavefront tracer and the
hash), :mod:`.signature` (strings), :mod:`.edges` (classification), :mod:`.render` (the image pass,
the overlay). Rendering a scene with its ray-tree edges in one call is the pipeline's
(:func:`mi_npr.render_raytree`, the ``raytree`` drawing).
"""

from __future__ import annotations

from .edges import classify_edges
from .lights import LightTable, light_table
from .render import COLORS, LAYERS, add_raytree, overlay, raytree_layers
from .signature import format_signature, object_letters, signature, signatures
from .tracer import MAX_DEPTH, Nodes, Trees, trace_trees

__all__ = [
    "COLORS",
    "LAYERS",
    "MAX_DEPTH",
    "LightTable",
    "Nodes",
    "Trees",
    "add_raytree",
    "classify_edges",
    "format_signature",
    "light_table",
    "object_letters",
    "overlay",
    "raytree_layers",
    "signature",
    "signatures",
    "trace_trees",
]
