"""Apparent contours of real objects (section 3 of the paper): on an ID buffer or by ray casting.

- :func:`trace` follows every contour of an ID buffer (the ``object_id`` layer of a G-buffer).
- :func:`trace_scene` finds the same contours from the scene by casting primary rays only where
  selective refinement and the follower ask for them.
- :class:`Contour` is what both return.
- :func:`vectorize` turns contours into :class:`VectorPath` pieces on the true outline (extra rays,
  Douglas-Peucker), for SVG; :func:`trace_strokes` does lines and edge masks (:mod:`.vector`).
- :func:`overlay` adds the ``contour`` layer to a G-buffer and draws the contours in red over its
  beauty (the paper's Fig. 10); ``id_mode`` chooses what one object is (:mod:`.idmode`).

Rendering a scene and drawing its contours in one call is the pipeline's
(:func:`mi_npr.render_contours`, the ``contours`` drawing).
"""

from __future__ import annotations

from .contour import Contour
from .idmode import ID_MODES, IdMap, id_map
from .overlay import mode_ids, overlay
from .refine import TraceStats, trace_scene
from .trace import METHODS, contour_layer, contour_mask, trace
from .vector import VectorPath, stroke_layers, trace_strokes, vectorize

__all__ = [
    "ID_MODES",
    "METHODS",
    "Contour",
    "IdMap",
    "TraceStats",
    "VectorPath",
    "contour_layer",
    "contour_mask",
    "id_map",
    "mode_ids",
    "overlay",
    "stroke_layers",
    "trace",
    "trace_scene",
    "trace_strokes",
    "vectorize",
]
