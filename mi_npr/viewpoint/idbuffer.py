"""ID buffers for many viewpoints in one Dr.Jit launch, counted into per-polygon areas.

**Polygons.** A polygon is a (shape, primitive) pair. The scene's polygons are numbered
``1..n`` (0 is the background), object by object in the order of mi-npr's stable object ids
(:func:`mi_npr.object_table`), triangle by triangle within a mesh. Non-mesh shapes (``sphere``,
``cylinder``, ``disk``, curves, ...) count as one polygon per shape. An ``instance`` owns the
polygons of every shape in its ``shapegroup`` (each instance separately, as it is a separate
object on screen): ``n`` counts them once per instance. ``n`` (eq. 1) is the total of all that.
Mitsuba's Python API links an instance to its group only through the instance's description
(``ShapeGroup[name = "..."]``) and the group to its shapes only through the scene's parameter
hierarchy (``mi.traverse(scene).hierarchy``): both are used. An instance whose group cannot be
found that way still works: it counts ``effective_primitive_count()`` polygons, indexed by
primitive, and adds no curvature to eq. 2.

**Cameras.** Every viewpoint is a pinhole camera at ``origin`` looking at ``target``, with the
horizontal field of view ``fov`` (degrees) and a ``width x height`` image, oriented like
Mitsuba's ``lookat`` with the ``up`` vector of :func:`mi_npr.camera.view_frame`. The ray of
pixel ``(x, y)`` goes through its exact centre ``(x + 0.5, y + 0.5)``, like the G-buffer pass
(:mod:`mi_npr.render`), so the ID buffer of a viewpoint equals the ``object_id`` / ``prim_id``
layers of a Mitsuba ``perspective`` sensor at that pose (checked in the tests), except for back
faces (below). The rays of V viewpoints (``V x width x height`` lanes) are built and cast by
:mod:`mi_npr.raycast` (:func:`~mi_npr.raycast.pinhole_rays`, :func:`~mi_npr.raycast.cast`) in one
kernel launch per batch, no Python loop over views.

**Back faces.** A hit whose geometric normal faces away from the ray, or lies across it
(``dot(n, d) >= 0``: a face seen exactly edge-on shows no area), on a shape whose BSDF has no
back side (``mi.BSDFFlags.BackSide`` unset: ``diffuse``, ``conductor``, ``plastic``...;
``twosided``, ``dielectric``, ``principled`` have one) counts as background: the
outside of a one-sided room's walls is what Mitsuba renders black, so it adds nothing to eqs.
1-3. It still hides what lies behind it (the ray stops there, as in a render).

**Counting.** Each lane's (view, polygon) pair is counted on the CPU with ``np.unique``: the
result is *sparse* (:class:`~mi_npr.viewpoint.measures.SparseAreas`, at most one cell per pixel),
so memory grows with the number of rays, never with ``V x n`` (a 1.5 M triangle scene has 6 MB
per viewpoint in a dense table). :func:`areas` densifies it for callers that want the table.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..camera import view_frame
from ..errors import ParameterError, SceneError, one_line
from ..raycast import cast, pinhole_rays
from ..raycast import require_jit as _require_jit
from ..scene import ObjectTable, object_table
from .measures import SparseAreas, Topology, vertex_curvature

#: Lanes per launch (V x width x height): a bound on the memory one batch takes (its rays, hits
#: and the (view, polygon) pairs counted on the CPU: ~25 bytes a lane, ~50 MB at most).
MAX_RAYS = 1 << 21

_ALL_ONES = 0xFFFFFFFF
_GROUP_NAME = re.compile(r'shapegroup\s*=\s*ShapeGroup\[\s*name\s*=\s*"([^"]*)"')


def _registry_index(shape: Any) -> int:
    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


@dataclass
class _Part:
    """A shape whose triangles are polygons: a top-level shape, or one shape of an instance's
    group (then ``to_world`` is the instance's transform, ``None`` otherwise)."""

    object_id: int
    shape: Any
    to_world: np.ndarray | None
    offset: int  # its first polygon is offset + 1
    count: int


@dataclass
class Polygons:
    """The scene's polygon numbering (module docstring) and the lookup tables that apply it."""

    n: int
    parts: list[_Part]
    base: np.ndarray  # (objects + 1,) first polygon - 1 of each object id
    span: np.ndarray  # (objects + 1,) polygons of each object id
    table: ObjectTable = field(repr=False)
    _base: Any = field(repr=False)
    _span: Any = field(repr=False)
    _local: Any = field(repr=False)  # registry index of si.shape -> offset within its object
    _last: Any = field(repr=False)  # registry index of si.shape -> its polygons - 1
    _one_sided: Any = field(repr=False)  # registry index of si.shape -> 1 if its BSDF has no back
    _topology: Topology | None = field(default=None, repr=False)

    def index(self, si: mi.SurfaceInteraction3f, oid: Any, d: Any = None, back: int = 0) -> Any:
        """Polygon index (``UInt32``, 0 = background) of each interaction with object ``oid``;
        with the ray directions ``d``, a one-sided shape seen from its back is background, or
        ``back`` where given (module docstring)."""
        reg = dr.reinterpret_array(mi.UInt32, si.shape)
        size = dr.width(self._local)
        known = (oid > 0) & (reg < size)
        r = dr.minimum(reg, size - 1)
        local = dr.gather(mi.UInt32, self._local, r, known)
        last = dr.select(known, dr.gather(mi.UInt32, self._last, r, known), _ALL_ONES)
        within = dr.minimum(local + dr.minimum(si.prim_index, last), self._gather(self._span, oid))
        index = dr.select(oid > 0, self._gather(self._base, oid) + within + 1, 0)
        if d is not None:
            one_sided = dr.gather(mi.UInt32, self._one_sided, r, known) > 0
            index = dr.select((oid > 0) & one_sided & (dr.dot(si.n, d) >= 0), back, index)
        return index

    @staticmethod
    def _gather(table: Any, oid: Any) -> Any:
        return dr.gather(mi.UInt32, table, oid)

    def topology(self) -> Topology:
        """Welded vertices and angle defects of every mesh polygon (for eq. 2), computed once."""
        if self._topology is None:
            self._topology = _topology(self)
        return self._topology


def _count(shape: Any) -> int:
    return int(shape.face_count()) if shape.is_mesh() else 1


def _group_children(scene: mi.Scene) -> dict[str, list[Any]]:
    """Shapes of every ``shapegroup`` by the group's id (Mitsuba exposes them through the
    scene's parameter hierarchy only)."""
    groups: dict[str, list[Any]] = {}
    for node, (parent, _) in mi.traverse(scene).hierarchy.items():
        if parent is not None and parent.class_name() == "ShapeGroupPlugin":
            if isinstance(node, mi.Shape):
                groups.setdefault(parent.id(), []).append(node)
    return groups


def one_sided(shape: Any) -> bool:
    """Whether ``shape`` is seen as background from its back: its BSDF has no back side
    (``mi.BSDFFlags.BackSide``; ``twosided`` adds one). A shape without a BSDF is two-sided."""
    bsdf = shape.bsdf()
    return bsdf is not None and not mi.has_flag(bsdf.flags(), mi.BSDFFlags.BackSide)


def require_jit() -> None:
    """The batched ID buffers are Dr.Jit kernels: scalar variants cannot run them."""
    _require_jit("viewpoint quality")


def polygons(scene: mi.Scene) -> Polygons:
    """Number the polygons of ``scene`` (see the module docstring)."""
    require_jit()
    table = object_table(scene)
    groups: dict[str, list[Any]] | None = None
    parts: list[_Part] = []
    n_obj = len(table.names)
    base = np.zeros(n_obj + 1, np.int64)
    span = np.zeros(n_obj + 1, np.int64)
    local: dict[int, tuple[int, int]] = {}  # registry index -> (offset within object, count - 1)
    sided: dict[int, bool] = {}  # registry index -> one-sided
    n = 0
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        base[oid] = n
        if shape.class_name() == "Instance":
            if groups is None:
                groups = _group_children(scene)
            m = _GROUP_NAME.search(str(shape))
            children = groups.get(m.group(1), []) if m else []
            to_world = np.asarray(mi.traverse(shape)["to_world"].matrix.numpy(), np.float64)
            to_world = to_world.reshape(4, 4, -1)[..., 0]
            if not children:  # cannot resolve the group: its primitives, without topology
                span[oid] = max(int(shape.effective_primitive_count()), 1)
            for child in children:
                c = _count(child)
                parts.append(_Part(oid, child, to_world, n + int(span[oid]), c))
                local[_registry_index(child)] = (int(span[oid]), c - 1)
                sided[_registry_index(child)] = one_sided(child)
                span[oid] += c
        else:
            c = _count(shape)
            parts.append(_Part(oid, shape, None, n, c))
            local[_registry_index(shape)] = (0, c - 1)
            sided[_registry_index(shape)] = one_sided(shape)
            span[oid] = c
        n += int(span[oid])
    if n >= 2**32 - 1:
        raise SceneError(f"the scene has {n} polygons: too many to number in 32 bits")
    size = max(local) + 1 if local else 1
    lut_local = np.zeros(size, np.uint32)
    lut_last = np.full(size, 0xFFFFFFFF, np.uint32)  # unknown shapes: clamped by the object
    lut_sided = np.zeros(size, np.uint32)
    for reg, (off, last) in local.items():
        lut_local[reg], lut_last[reg] = off, last
        lut_sided[reg] = sided.get(reg, False)
    span_minus1 = np.maximum(span - 1, 0)
    return Polygons(
        n=n,
        parts=parts,
        base=base,
        span=span,
        table=table,
        _base=mi.UInt32(base.astype(np.uint32)),
        _span=mi.UInt32(span_minus1.astype(np.uint32)),
        _local=mi.UInt32(lut_local),
        _last=mi.UInt32(lut_last),
        _one_sided=mi.UInt32(lut_sided),
    )


def _topology(polys: Polygons) -> Topology:
    pv = np.full((polys.n + 1, 3), -1, np.int64)
    terms = []
    nv = 0
    for part in polys.parts:
        if not part.shape.is_mesh():
            continue
        V = np.asarray(part.shape.vertex_positions_buffer().numpy(), np.float64).reshape(-1, 3)
        F = np.asarray(part.shape.faces_buffer().numpy(), np.int64).reshape(-1, 3)
        if part.to_world is not None:  # angles change under non-uniform scaling: use world space
            V = V @ part.to_world[:3, :3].T + part.to_world[:3, 3]
        defect, weld = vertex_curvature(V, F)
        pv[part.offset + 1 : part.offset + 1 + len(F)] = weld[F] + nv
        terms.append(np.abs(defect))
        nv += len(defect)
    term = np.concatenate(terms) if terms else np.zeros(0)
    return Topology(pv, term)


# -- cameras ----------------------------------------------------------------------------------


def image_size(res: int, aspect: float) -> tuple[int, int]:
    """``(width, height)`` with ``res`` pixels along the longer side and the given w/h aspect."""
    if not isinstance(res, (int, np.integer)) or res < 1:
        raise ParameterError(f"res = {res!r}: must be a positive integer")
    if aspect >= 1.0:
        return int(res), max(1, round(res / aspect))
    return max(1, round(res * aspect)), int(res)


def _count_batch(
    scene: mi.Scene,
    polys: Polygons,
    origin: np.ndarray,
    frame: tuple[np.ndarray, np.ndarray, np.ndarray],
    fov: float,
    size: tuple[int, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(view, polygon, pixels)`` of every (view, polygon) pair seen in this batch; polygon
    ``n + 1`` counts the back faces that are background (module docstring)."""
    rays, view = pinhole_rays(origin, frame, fov, size)
    hits = cast(scene, rays, polys.table, detail="minimal")
    poly = polys.index(hits.si, hits.object_id, rays.d, back=polys.n + 1)
    dr.eval(poly)
    key = view.numpy().astype(np.int64) * (polys.n + 2) + poly.numpy()
    cells, counts = np.unique(key, return_counts=True)
    return cells // (polys.n + 2), cells % (polys.n + 2), counts


def sparse_areas(
    scene: mi.Scene,
    origins: Sequence[Sequence[float]] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    fov: float,
    size: tuple[int, int],
    up: Sequence[float] | np.ndarray | None = None,
    polys: Polygons | None = None,
) -> SparseAreas:
    """:func:`areas` as a :class:`~mi_npr.viewpoint.measures.SparseAreas` (the cells that are
    not 0): what the measures read, in memory that grows with the rays, not the polygons."""
    require_jit()
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(o)):
        raise ParameterError("origins must be finite")
    if not 0.0 < fov < 180.0:
        raise ParameterError(f"fov = {fov!r}: must be in (0, 180) degrees")
    polys = polys if polys is not None else polygons(scene)
    frame = view_frame(o, np.asarray(target, np.float64), up)
    w, h = size
    per = max(1, MAX_RAYS // (w * h))
    parts = []
    try:
        for s in range(0, len(o), per):
            sl = slice(s, s + per)
            v, p, c = _count_batch(scene, polys, o[sl], tuple(a[sl] for a in frame), fov, size)
            parts.append((v + s, p, c))
    except RuntimeError as e:
        raise SceneError(f"viewpoint ID buffers failed: {one_line(e)}") from None
    if not parts:
        return SparseAreas.from_dense(np.zeros((0, polys.n + 1), np.uint32))
    rows, cols, vals = (np.concatenate(x) for x in zip(*parts, strict=True))
    is_back = cols == polys.n + 1
    back = np.bincount(rows[is_back], weights=vals[is_back], minlength=len(o)).astype(np.int64)
    if np.any(is_back):  # into the background, with the misses of the same view
        bg = np.zeros(len(o), np.int64)
        np.add.at(bg, rows[cols == 0], vals[cols == 0])
        keep = (cols > 0) & ~is_back
        rows = np.concatenate([np.flatnonzero(bg + back), rows[keep]])
        cols = np.concatenate([np.zeros(np.count_nonzero(bg + back), np.int64), cols[keep]])
        vals = np.concatenate([(bg + back)[bg + back > 0], vals[keep]])
    return SparseAreas(rows, cols, vals, (len(o), polys.n + 1), back)


def areas(
    scene: mi.Scene,
    origins: Sequence[Sequence[float]] | np.ndarray,
    target: Sequence[float] | np.ndarray,
    fov: float,
    size: tuple[int, int],
    up: Sequence[float] | np.ndarray | None = None,
    polys: Polygons | None = None,
) -> np.ndarray:
    """Projected visible area (pixel count) of every polygon from every viewpoint.

    Returns uint32 ``(V, n + 1)``: row ``v`` is viewpoint ``origins[v]``, column 0 the
    background (with one-sided polygons seen from their back), column ``i`` polygon ``i``
    (module docstring); each row sums to ``width x height``. Batches of viewpoints run as single
    Dr.Jit launches. The table is ``V x (n + 1)`` cells: :func:`sparse_areas` for large scenes.
    """
    return sparse_areas(scene, origins, target, fov, size, up, polys).dense().astype(np.uint32)
