"""Object-ID edges and normal (crease) edges from the G-buffer's exact per-pixel layers.

The thesis (section 5.1) draws plants from depth alone and finds ID contours "visually
misleading" there; for the man-made scenes of the paper they add what depth cannot see:
boundaries between touching or intersecting objects at the same depth (ID edges) and creases
inside one object, such as a cube's edges (normal edges).

Definitions, both over the 4-neighbourhood (up, left, right, down), where pixels outside
the image repeat the border pixel, so the image border itself is never an edge:

- *ID edge*: a pixel whose ``object_id`` differs from some 4-neighbour's. The test is symmetric,
  so the edge is 2 px thick (one pixel on each side of the boundary); the background (id 0) is an
  object like any other.
- *Normal edge*: a pixel of an object (id != 0) whose shading normal makes an angle larger than
  ``angle_deg`` with the normal of some 4-neighbour on the *same* object (also 2 px thick).
  Normals need not be unit length; a zero, NaN or inf normal never makes an edge.

- *Leaf edge*: a pixel whose ``leaf_id`` differs from some 4-neighbour's, where at
  least one of the two is a leaf (id != 0). Leaves overlap at nearly equal depth, so depth
  contours miss part of their outlines; the per-leaf id finds all of them. ``width=2`` marks both
  sides (2 px, like ID edges); ``width=1`` marks only the *nearer* pixel of each pair (smaller
  ``Z``; on equal depth the larger id), so every outline is 1 px thick and belongs to the leaf in
  front, as eq. 5.1 puts depth lines on the near side. NaN depth reads as +inf (background).

- *Crease edge*: a pixel of an object whose normal makes a *dihedral angle* smaller
  than ``crease_angle`` degrees with the normal of a 4-neighbour on the same object, the
  dihedral angle being ``180 - angle(n0, n1)`` (two coplanar faces: 180, a cube's edge: 90), as
  Blender Freestyle's crease angle (default 134) defines it. Always 1 px thick.

**Which side is drawn** (1-px ID and crease edges). Every edge separates a pair of
4-neighbours ``p, q``; exactly one of them is inked, by one rule shared by all kinds:

1. a *depth step*: where ``q`` is farther than ``p`` by more than ``step`` (in the units of the
   depth given), ``p`` is inked, not ``q``: the near side, where eq. 5.1 puts the pixel of the
   same step. The chain passes its normalised, pre-filtered depth and ``step = t / c``, eq. 5.1's
   own threshold, so an ID or crease edge at a silhouette lands on eq. 5.1's pixels and never
   widens the line;
2. no depth step (touching objects, a crease on one surface): depth cannot choose a side, as the
   surfaces' own slopes make "nearer" flip from pixel to pixel along the edge (2-px patches on
   diagonal edges). A per-surface key chooses instead, constant along the edge, so the ink is
   the boundary row of one surface only: for ID edges the *larger object id* (as
   :func:`leaf_edges`); for creases the surface that *faces the camera more* (larger
   ``-n . view / |n|``, ``view`` the camera's viewing axis), equal facing resolved by the larger
   normal in lexicographic (x, y, z) order.

All return a ``TensorXf`` (on the inputs' backend) of 0 and 1, shape (H, W).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

import drjit as dr

from ..errors import ParameterError
from ._stencil import (
    CROSS,
    Array,
    Field,
    Grid,
    Tensor,
    exact,
    float_image,
    id_image,
    require,
    same_shape,
    tensor,
    vector_image,
)


def id_edge(ids: Field) -> Array:
    """Pixels with a 4-neighbour of another id (lazy)."""
    centre = ids.at()
    edge = None
    for dy, dx in CROSS:
        differs = ids.at(dy, dx) != centre
        edge = differs if edge is None else edge | differs
    return edge


def owns(z0: Any, z1: Any, step: Any, key_wins: Array) -> Array:
    """Whether pixel ``p`` (depth ``z0``) inks the edge it shares with ``q`` (depth ``z1``): the
    side rule of the module docstring. ``key_wins`` is the per-surface key's verdict."""
    dz = z1 - z0
    return (dz > step) | ((dr.abs(dz) <= step) & key_wins)


def id_edge_sided(ids: Field, depth: Field, step: Any) -> Array:
    """1-px ID edges (lazy): pixels with a 4-neighbour of another id that they own (see
    :func:`owns`; ties go to the larger id)."""
    centre, z0 = ids.at(), depth.at()
    edge = None
    for dy, dx in CROSS:
        other = ids.at(dy, dx)
        mine = (other != centre) & owns(z0, depth.at(dy, dx), step, centre > other)
        edge = mine if edge is None else edge | mine
    return edge


def _step(step: Any) -> str | None:
    ok = isinstance(step, numbers.Real) and not isinstance(step, bool) and step >= 0
    return None if ok and not math.isnan(step) else "must be a number >= 0 (inf allowed)"


def _depth_field(depth: Any, shape: tuple[int, int], grid: Grid, name: str) -> Field:
    """``depth`` (or all zeros when ``None``) as a field, NaN read as +inf (background)."""
    if depth is None:
        return Field(grid.zeros(), grid)
    z, shape_z = float_image(depth, name, grid.B)
    same_shape({"object_id": shape, name: shape_z})
    return Field(z, grid, _inf_for_nan)


@exact
def id_edges(object_id: Any, width: int = 2, Z: Any = None, step: float = 0.0) -> Tensor:
    """1 where a 4-neighbour has another ``object_id`` (ID edges), else 0.

    ``object_id`` is an (H, W) array of integers >= 0 (uint32 from the G-buffer, or floats
    holding integers, as in ``mi.render``'s tensor). ``width=2`` marks both sides of every
    boundary; ``width=1`` only one: the nearer pixel where the depth ``Z`` (optional, (H, W),
    NaN = background) steps by more than ``step``, else the larger id (module docstring).

    >>> import numpy as np
    >>> ids = np.array([[1, 1, 2, 2]], np.uint32)
    >>> np.asarray(id_edges(ids)), np.asarray(id_edges(ids, 1))
    (array([[0., 1., 1., 0.]], dtype=float32), array([[0., 0., 1., 0.]], dtype=float32))
    """
    require("width", width, edge_width)
    require("step", step, _step)
    ids, shape = id_image(object_id, "object_id")
    grid = Grid(shape, ids)
    if width == 2:
        return tensor(dr.select(id_edge(Field(ids, grid)), 1.0, 0.0), shape)
    depth = _depth_field(Z, shape, grid, "Z")
    edge = id_edge_sided(Field(ids, grid), depth, grid.opaque(step))
    return tensor(dr.select(edge, 1.0, 0.0), shape)


def angle(v: Any) -> str | None:
    """The rule for ``angle_deg``: degrees in [0, 180)."""
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 <= v < 180
    return None if ok else "must lie in [0, 180) degrees"


def _length(n: list[Any]) -> Any:
    return dr.sqrt(dr.fma(n[0], n[0], dr.fma(n[1], n[1], n[2] * n[2])))


def _bent(n0: list[Any], n1: list[Any], id0: Any, id1: Any, cos_a: Any) -> Array:
    """Two 4-neighbours on one object whose normals turn by more than ``acos(cos_a)``: tested
    as ``dot(n0, n1) < cos_a |n0| |n1|`` (false for zero or non-finite normals). Equal normals
    never bend, whatever rounding does to the dot product and the lengths (an angle of 0, and the
    border pixel compared with itself)."""
    dot = dr.fma(n0[0], n1[0], dr.fma(n0[1], n1[1], n0[2] * n1[2]))
    differ = (n1[0] != n0[0]) | (n1[1] != n0[1]) | (n1[2] != n0[2])
    return (id1 == id0) & differ & (dot < cos_a * _length(n0) * _length(n1))


def normal_edge(N: list[Field], ids: Field, angle_deg: float) -> Array:
    """Pixels whose normal turns by more than ``angle_deg`` towards a 4-neighbour on the same
    object (lazy). ``angle > a`` is tested as ``dot(n0, n1) < cos(a) |n0| |n1|``, false for
    zero or non-finite normals."""
    # cos(radians(90)) is 6e-17, not 0: rounded, a right angle is not "more than 90 degrees".
    cos_a = ids.grid.opaque(round(math.cos(math.radians(angle_deg)), 12))
    n0, id0 = [f.at() for f in N], ids.at()
    edge = None
    for dy, dx in CROSS:
        bent = _bent(n0, [f.at(dy, dx) for f in N], id0, ids.at(dy, dx), cos_a)
        edge = bent if edge is None else edge | bent
    return edge & (id0 != 0)


@exact
def normal_edges(N: Any, object_id: Any, angle_deg: float) -> Tensor:
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
    ids, shape_i = id_image(object_id, "object_id", planes[0])
    shape = same_shape({"N": shape_n, "object_id": shape_i})
    grid = Grid(shape, ids)
    edge = normal_edge([Field(p, grid) for p in planes], Field(ids, grid), angle_deg)
    return tensor(dr.select(edge, 1.0, 0.0), shape)


def dihedral(v: Any) -> str | None:
    """The rule for ``crease_angle``: degrees in [0, 180] (0 = no creases)."""
    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 <= v <= 180
    return None if ok else "must lie in [0, 180] degrees (dihedral angle; 0 = off)"


def _unit(n: list[Any]) -> list[Any]:
    length = _length(n)
    return [c / length for c in n]


def crease_edge(
    N: list[Field],
    ids: Field,
    crease_angle: float,
    depth: Field,
    step: Any,
    view: tuple[float, float, float],
) -> Array:
    """1-px crease edges (lazy): pixels whose dihedral angle to a 4-neighbour on the same object
    is below ``crease_angle`` (normals turning by more than ``180 - crease_angle``) and that own
    the edge (:func:`owns`; ties to the surface facing ``view``'s camera more)."""
    cos_a = ids.grid.opaque(round(math.cos(math.radians(180.0 - crease_angle)), 12))
    # Opaque, not literals: a kernel of its own for every camera axis would fill Dr.Jit's
    # kernel cache over the views of a long batch.
    view = tuple(ids.grid.opaque(c) for c in view)  # type: ignore[assignment]
    n0 = [f.at() for f in N]
    u0 = _unit(n0)
    facing0 = -(u0[0] * view[0] + u0[1] * view[1] + u0[2] * view[2])
    id0, z0 = ids.at(), depth.at()
    edge = None
    for dy, dx in CROSS:
        n1 = [f.at(dy, dx) for f in N]
        bent = _bent(n0, n1, id0, ids.at(dy, dx), cos_a)
        u1 = _unit(n1)
        facing1 = -(u1[0] * view[0] + u1[1] * view[1] + u1[2] * view[2])
        lexi = (u0[0] > u1[0]) | (
            (u0[0] == u1[0]) & ((u0[1] > u1[1]) | ((u0[1] == u1[1]) & (u0[2] > u1[2])))
        )
        key = (facing0 > facing1) | ((facing0 == facing1) & lexi)
        mine = bent & owns(z0, depth.at(dy, dx), step, key)
        edge = mine if edge is None else edge | mine
    return edge & (id0 != 0)


def _view(v: Any) -> tuple[float, float, float]:
    try:
        a = [float(c) for c in v]
    except (TypeError, ValueError):
        a = []
    norm = math.sqrt(sum(c * c for c in a)) if len(a) == 3 else 0.0
    if not (math.isfinite(norm) and norm > 0):
        raise ParameterError(f"view = {v!r}: must be a non-zero, finite 3-vector")
    return (a[0] / norm, a[1] / norm, a[2] / norm)


@exact
def crease_edges(
    N: Any,
    object_id: Any,
    crease_angle: float = 134.0,
    Z: Any = None,
    step: float = 0.0,
    view: tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> Tensor:
    """1 on creases (dihedral angle below ``crease_angle`` degrees between 4-neighbours on one
    object), 1 px thick, else 0; background (id 0) has none. ``crease_angle = 0`` draws none.

    ``N`` is an (H, W, 3) array of world-space normals (any length), ``object_id`` (H, W) ids,
    ``Z`` optional (H, W) depth with ``step`` (see the module docstring's side rule) and ``view``
    the camera's viewing axis in world space (Mitsuba's camera looks along its +z).

    >>> import numpy as np   # a cube's edge seen head-on from the front face's side
    >>> N = np.zeros((1, 4, 3), np.float32); N[0, :2, 2] = -1; N[0, 2:, 0] = 1
    >>> np.asarray(crease_edges(N, np.ones((1, 4), np.uint32)))   # 90 < 134: the front face
    array([[0., 1., 0., 0.]], dtype=float32)
    """
    require("crease_angle", crease_angle, dihedral)
    require("step", step, _step)
    view = _view(view)
    planes, shape_n = vector_image(N, "N")
    ids, shape = id_image(object_id, "object_id", planes[0])
    same_shape({"object_id": shape, "N": shape_n})
    grid = Grid(shape, ids)
    if crease_angle == 0:
        return tensor(grid.zeros(), shape)
    depth = _depth_field(Z, shape, grid, "Z")
    edge = crease_edge(
        [Field(p, grid) for p in planes],
        Field(ids, grid),
        crease_angle,
        depth,
        grid.opaque(step),
        view,
    )
    return tensor(dr.select(edge, 1.0, 0.0), shape)


def leaf_edge(ids: Field, depth: Field, width: int) -> Array:
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


@exact
def leaf_edges(leaf_id: Any, Z: Any, width: int = 1) -> Tensor:
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
    z, shape_z = float_image(Z, "Z", ids)
    shape = same_shape({"leaf_id": shape_i, "Z": shape_z})
    grid = Grid(shape, ids)
    edge = leaf_edge(Field(ids, grid), Field(z, grid, _inf_for_nan), width)
    return tensor(dr.select(edge, 1.0, 0.0), shape)
