"""Strokes: ordered, typed polylines in film coordinates, with exact visibility and styles.

The thesis (chapter 5) pairs image-space contour detection with object-space information for
stylization. Here the pairing goes the other way where the scene allows it: lines come from
object space, exact, and the image is used for what object space lacks.

**Method** (one submodule per step):

1. *Feature edges of meshes* (:mod:`~mi_npr.strokes.edges`): the edges of every mesh, welded
   across meshes, typed ``silhouette`` (front face meets back face, seen from the camera
   origin), ``border`` (one face), ``material`` (faces of two objects meet: an object
   boundary), ``crease`` (dihedral angle below ``crease_angle``, Freestyle's definition, the
   ``lines`` drawing's), and ``intersection`` lines between meshes
   (:mod:`~mi_npr.strokes.intersect`).
2. *Outlines of the other shapes* (spheres, cylinders, disks, curves, instances:
   :mod:`~mi_npr.strokes.outlines`): :func:`mi_npr.contours.vectorize` bisects the id image's
   cracks with rays; a shape's outlines in front of itself (the rim of an open cylinder before
   its inner wall: one id on both sides) start from the ``lines`` drawing's depth steps within
   one id, bisected by depth and followed on while they stay steps; then side probes keep the
   vertices on the shape's own outline, typed ``silhouette`` (surface seen edge-on),
   ``border`` (a rim in front of what lies behind) or ``intersection`` (the object on the other
   side at the same depth: the shape meets a mesh or another such shape there).
   **Nothing is drawn twice**: in that id image every mesh reads as background, so a mesh's
   outline comes from its object-space silhouette and border edges only, and another shape's
   only from its image-space outline; an outline between two shapes belongs to the nearer one,
   and their intersection to the one of smaller object id.
3. *Exact visibility* (:mod:`~mi_npr.strokes.visibility`): quantitative invisibility by rays
   from the camera origin to points sampled every 0.5 px along each edge, which is split where
   it changes (bisection, 1e-4 px). QI counts every surface crossed in front of the point (a
   closed solid counts 2); glass (``DeltaTransmission``) does not hide and marks the points
   behind it ``through_glass``; ``null`` surfaces are invisible. Parts behind more than
   ``max_qi`` surfaces are left out (the ``strokes`` drawing's default, 1, keeps an object's
   own back edges and what lies behind a single sheet: on a large assembly most edges lie
   deeper, and drawn dashed they would cover the picture). Outlines of step 2 are visible
   by construction (their hidden parts are not drawn).
4. *Chaining* (:mod:`~mi_npr.strokes.chain`): pieces of one kind and visibility state joined
   at shared vertices while the stroke turns less than ``chain_angle`` (pieces shorter than a
   pixel on the film never break it by turning); where three or more
   meet, the straightest pair runs on and the others end (the bar of a T continues, its stem
   stops); a visibility change ends a stroke, so a line passing behind an occluder ends on the
   occluder's outline (a T-junction in the image).
5. *Per-vertex attributes* (:class:`Stroke`): film position (sub-pixel), world position,
   depth, object and primitive, and ``depth_behind`` (eq. 5.1's neighbour); per stroke its
   kind, QI, ``through_glass`` and ``closed``. :class:`Strokes` holds one image's strokes.
6. *Styles* (:mod:`~mi_npr.strokes.style`): width by depth, kind, QI and tapered ends; colour
   per kind; dashed hidden lines; presets ``technical``, ``illustration`` and ``thesis``
   (opacity = the gray level of eq. 5.1 evaluated at the stroke).
7. *Raster* (:mod:`~mi_npr.strokes.raster`): anti-aliased coverage (the ``strokes.V`` layer)
   and colours; the files ``<stem>_strokes.svg``, ``.json`` and ``.png`` are written by
   :mod:`mi_npr.io.strokes` (which documents the JSON schema).

**Ambiguities resolved.** The camera is perspective, a thin lens (whose strokes are those of
the pinhole at its lens centre, where the G-buffer's pixel rays pass) or orthographic (parallel
rays from its near plane: silhouettes where ``n . f`` changes sign along its view axis ``f``);
any other sensor is refused with an error. An edge has one kind, the first of silhouette, border,
material, crease. Points behind glass keep their unrefracted position. Strokes are clipped
at the image frame (exactly, in homogeneous coordinates). The frame's depth range (for widths
by depth and eq. 5.1) is that of the G-buffer's ``Z`` layer. Chaining across objects happens
only where two meshes share a vertex.

>>> import mitsuba as mi
>>> scene = mi.load_dict({"type": "scene", "box": {"type": "cube"}, "sensor": {
...     "type": "perspective",
...     "to_world": mi.ScalarTransform4f().look_at([3, 2, 4], [0, 0, 0], [0, 1, 0]),
...     "film": {"type": "hdrfilm", "width": 64, "height": 48}}})
>>> st = extract_strokes(scene, scene.sensors()[0])
>>> sorted({(s.kind, s.qi) for s in st})
[('crease', 0), ('crease', 1), ('silhouette', 0)]
>>> len(st.of_kind("silhouette")), [len(s) for s in st.of_kind("silhouette")]
(3, [3, 3, 3])
"""

from __future__ import annotations

from .extract import extract_strokes, resampled
from .model import KINDS, Stroke, Strokes

__all__ = ["KINDS", "Stroke", "Strokes", "extract_strokes", "resampled"]
