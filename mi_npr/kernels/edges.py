"""Object-ID edges and normal (crease) edges from the G-buffer's exact per-pixel layers.

The thesis (section 5.1) draws plants from depth alone and finds ID contours "visually
misleading" there; for the man-made scenes of the paper they add what depth cannot see:
boundaries between touching or intersecting objects at the same depth (ID edges) and creases
inside one object, such as a cube's edges (normal edges).

Definitions (issue 4), both over the 4-neighbourhood (up, left, right, down), where pixels outside
the image repeat the border pixel, so the image border itself is never an edge:

- *ID edge*: a pixel whose ``object_id`` differs from some 4-neighbour's. The test is symmetric,
  so the edge is 2 px thick (one pixel on each side of the boundary); the background (id 0) is an
  object like any other.
- *Normal edge*: a pixel of an object (id != 0) whose shading normal makes an angle larger than
  ``angle_deg`` with the normal of some 4-neighbour on the *same* object (also 2 px thick).
  Normals need not be unit length; a zero, NaN or inf normal never makes an edge.

- *Leaf edge* (issue 8): a pixel whose ``leaf_id`` differs from some 4-neighbour's, where at
  least one of the two is a leaf (id != 0). Leaves overlap at nearly equal depth, so depth
  contours miss part of their outlines; the per-leaf id finds all of them. ``width=2`` marks both
  sides (2 px, like ID edges); ``width=1`` marks only the *nearer* pixel of each pair (smaller
  ``Z``; on equal depth the larger id), so every outline is 1 px thick and belongs to the leaf in
  front, as eq. 5.1 puts depth lines on the near side. NaN depth reads as +inf (background).

All return a ``drjit.llvm.ad.TensorXf`` of 0 and 1, shape (H, W).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import drjit as dr
from drjit.llvm.ad import Bool, TensorXf

from ._stencil import (
    CROSS,
    Field,
    Grid,
    float_image,
    id_image,
    opaque,
    require,
    same_shape,
    tensor,
    vector_image,
)


def id_edge(ids: Field) -> Bool:
    """Pixels with a 4-neighbour of another id (lazy)."""
    centre = ids.at()
    edge = None
    for dy, dx in CROSS:
        differs = ids.at(dy, dx) != centre
        edge = differs if edge is None else edge | differs
    return edge


def id_edges(object_id: Any) -> TensorXf:
    """1 where a 4-neighbour has another ``object_id`` (ID edges, 2 px thick), else 0.

    ``object_id`` is an (H, W) array of integers >= 0 (uint32 from the G-buffer, or floats
    holding integers, as in ``mi.render``'s tensor).

    >>> import numpy as np
    >>> ids = np.array([[1, 1, 2, 2]], np.uint32)
    >>> np.asarray(id_edges(ids))
    array([[0., 1., 1., 0.]], dtype=float32)
    """
    ids, shape = id_image(object_id, "object_id")
    return tensor(dr.select(id_edge(Field(ids, Grid(shape))), 1.0, 0.0), shape)


def angle(v: Any) -> str | None:
    """The rule for ``angle_deg``: degrees in [0, 180)."""
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 <= v < 180
    return None if ok else "must lie in [0, 180) degrees"


def normal_edge(N: list[Field], ids: Field, angle_deg: float) -> Bool:
    """Pixels whose normal turns by more than ``angle_deg`` towards a 4-neighbour on the same
    object (lazy). ``angle > a`` is tested as ``dot(n0, n1) < cos(a) |n0| |n1|``, false for
    zero or non-finite normals."""
    # cos(radians(90)) is 6e-17, not 0: rounded, a right angle is not "more than 90 degrees".
    cos_a = opaque(round(math.cos(math.radians(angle_deg)), 12))
    n0 = [f.at() for f in N]
    len0 = dr.sqrt(dr.fma(n0[0], n0[0], dr.fma(n0[1], n0[1], n0[2] * n0[2])))
    id0 = ids.at()
    edge = None
    for dy, dx in CROSS:
        n1 = [f.at(dy, dx) for f in N]
        len1 = dr.sqrt(dr.fma(n1[0], n1[0], dr.fma(n1[1], n1[1], n1[2] * n1[2])))
        dot = dr.fma(n0[0], n1[0], dr.fma(n0[1], n1[1], n0[2] * n1[2]))
        # Equal normals never bend, whatever rounding does to dot and lengths (angle_deg = 0,
        # and the border pixel compared with itself).
        differ = (n1[0] != n0[0]) | (n1[1] != n0[1]) | (n1[2] != n0[2])
        bent = (ids.at(dy, dx) == id0) & differ & (dot < cos_a * len0 * len1)
        edge = bent if edge is None else edge | bent
    return edge & (id0 != 0)


def normal_edges(N: Any, object_id: Any, angle_deg: float) -> TensorXf:
    """1 where the normal turns by more than ``angle_deg`` degrees to a 4-neighbour on the same
    object (crease edges, 2 px thick), else 0; background (id 0) has none.

    ``N`` is an (H, W, 3) array of normals (any length; ``GBuffer.normals``), ``object_id`` an
    (H, W) id image, ``angle_deg`` in [0, 180).

    >>> import numpy as np
    >>> N = np.zeros((1, 4, 3), np.float32); N[0, :2, 2] = 1; N[0, 2:, 0] = 1   # a 90 deg crease
    >>> np.asarray(normal_edges(N, np.ones((1, 4), np.uint32), 30.0))
    array([[0., 1., 1., 0.]], dtype=float32)
    """
    require("angle_deg", angle_deg, angle)
    planes, shape_n = vector_image(N, "N")
    ids, shape_i = id_image(object_id, "object_id")
    shape = same_shape({"N": shape_n, "object_id": shape_i})
    grid = Grid(shape)
    edge = normal_edge([Field(p, grid) for p in planes], Field(ids, grid), angle_deg)
    return tensor(dr.select(edge, 1.0, 0.0), shape)


def leaf_edge(ids: Field, depth: Field, width: int) -> Bool:
    """Pixels on a leaf outline (lazy): a 4-neighbour has another leaf id (one of the two != 0);
    with ``width == 1`` only where this pixel is the nearer one of the pair."""
    centre, z0 = ids.at(), depth.at()
    edge = None
    for dy, dx in CROSS:
        other = ids.at(dy, dx)
        differs = other != centre
        if width == 1:
            z1 = depth.at(dy, dx)
            differs &= (z1 > z0) | ((z1 == z0) & (centre > other))
        edge = differs if edge is None else edge | differs
    return edge


def edge_width(v: Any) -> str | None:
    """The rule for a leaf-edge width: 1 or 2 pixels."""
    return None if v in (1, 2) and not isinstance(v, bool) else "must be 1 or 2 (pixels)"


def _inf_for_nan(z: Any) -> Any:
    return dr.select(dr.isnan(z), dr.inf, z)


def leaf_edges(leaf_id: Any, Z: Any, width: int = 1) -> TensorXf:
    """1 on the outline of every leaf (the ``leaf_id`` layer), else 0; see the module docstring.

    ``leaf_id`` is an (H, W) integer image (0 = not a leaf), ``Z`` the (H, W) depth (``+inf`` or
    NaN on the background), ``width`` 1 (the nearer side only) or 2 (both sides).

    >>> import numpy as np
    >>> ids = np.array([[1, 1, 2, 2]], np.uint32); Z = np.array([[1, 1, 2, 2]], np.float32)
    >>> np.asarray(leaf_edges(ids, Z, 1)), np.asarray(leaf_edges(ids, Z, 2))
    (array([[0., 1., 0., 0.]], dtype=float32), array([[0., 1., 1., 0.]], dtype=float32))
    """
    require("width", width, edge_width)
    ids, shape_i = id_image(leaf_id, "leaf_id")
    z, shape_z = float_image(Z, "Z")
    shape = same_shape({"leaf_id": shape_i, "Z": shape_z})
    grid = Grid(shape)
    edge = leaf_edge(Field(ids, grid), Field(z, grid, _inf_for_nan), width)
    return tensor(dr.select(edge, 1.0, 0.0), shape)
