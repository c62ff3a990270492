"""What counts as one object for the contours: a shape, a primitive, a connected component, a
material, or all objects together; and which objects are drawn at all (``only``/``ignore``).

``id_mode="shape"`` (default): the G-buffer's ``object_id`` (one object per top-level shape).
``"primitive"``: one object per primitive (triangle) of a mesh, the behaviour of the paper's Fig. 9
(b, c), where every polygon gets its own contour. ``"component"``: each connected component of a
mesh becomes an object, which fixes the paper's Fig. 9 (a) case of one mesh holding a sphere *and*
a cube (the paper: "we don't know to which polygon belongs each object").
``"material"``: one object per BSDF (the object table's ``materials``, numbered like it), so
the bricks of one colour form one object. ``"silhouette"``: every object is one object named
``silhouette``, so lines run only against the background.

**Selection** (``only``, ``ignore``: shell globs, :func:`fnmatch.fnmatchcase`, on the object
table's *shape* names, whatever the mode): a shape is drawn when it matches one of ``only`` (or
``only`` is empty) and none of ``ignore``. The others count as background (id 0) in every
mode, in the ``contour`` layer, the ``edges.*`` layers and the lines' ID edges alike, so a drawn
object has a contour where it meets an ignored one. A glob that matches no shape is an error
naming it (a typo would otherwise silently draw everything or nothing) and the names it matches
in another case, or else the closest names.

Ids and names, stable like the object table's (:mod:`mi_npr.scene`): shapes are taken in object
table order and numbered 1..M in that order. A shape that is not split (not a mesh, an instance,
or a mesh with a single component in ``"component"`` mode) keeps its name; the parts of a split
shape are named ``<shape>#<c>`` (component ``c``, numbered by the lowest face index it holds) or
``<shape>/<p>`` (primitive ``p``). Components are computed on the mesh's faces with vertices
*welded by position*: PLY and OBJ files duplicate the vertices on UV seams and sharp edges, and
those duplicates must not cut a surface in two. Two faces are in one component when they share a
(welded) vertex.

The mapping is a lookup table applied to ``(object_id, prim_id)``: the same table serves the
G-buffer's numpy layers (:meth:`IdMap.apply`) and rays cast by Dr.Jit (:meth:`IdMap.lookup`), so
buffer mode and ray-cast mode see the same ids.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from difflib import SequenceMatcher
from fnmatch import fnmatchcase
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..scene import ObjectTable, object_table
from .parts import mesh_parts

ID_MODES = ("shape", "primitive", "component", "material", "silhouette")
#: The modes whose ids depend on the object only (not on the primitive): ray trees take these.
OBJECT_MODES = ("shape", "material", "silhouette")
SILHOUETTE = "silhouette"


def check_id_mode(id_mode: str) -> str:
    if id_mode not in ID_MODES:
        raise ParameterError(f"id_mode = {id_mode!r}: expected one of {', '.join(ID_MODES)}")
    return id_mode


def split_globs(value: str | Sequence[str] | None) -> tuple[str, ...]:
    """Globs from a plugin's comma-separated string or a list of strings (blanks dropped)."""
    if value is None:
        return ()
    items = value.split(",") if isinstance(value, str) else list(value)
    for g in items:
        if not isinstance(g, str):
            raise ParameterError(f"object glob {g!r}: expected a string")
    return tuple(g.strip() for g in items if g.strip())


def _hint(glob: str, names: Mapping[int, str]) -> str:
    """What to say about a glob that matches no name: the names it matches in another case
    (globs are case-sensitive, like the XML's ids), else the closest names."""
    values = list(names.values())
    if not values:
        return "the scene has no objects"
    folded = [n for n in values if fnmatchcase(n.lower(), glob.lower())]
    if folded:
        some = ", ".join(folded[:5]) + (", ..." if len(folded) > 5 else "")
        return f"globs are case-sensitive: in another case it matches {some}"
    key = glob.replace("*", "").replace("?", "").lower()
    closest = sorted(values, key=lambda n: -SequenceMatcher(None, key, n.lower()).ratio())[:5]
    return f"closest of the {len(values)} objects: {', '.join(closest)}"


def selected(
    names: Mapping[int, str], only: Sequence[str] = (), ignore: Sequence[str] = ()
) -> set[int]:
    """The ids of ``names`` selected by ``only`` and ``ignore`` (module docstring); a glob that
    matches no name raises :class:`ParameterError`."""
    for flag, globs in (("only", only), ("ignore", ignore)):
        for g in globs:
            if not any(fnmatchcase(n, g) for n in names.values()):
                raise ParameterError(f"{flag} {g!r}: no object matches ({_hint(g, names)})")
    return {
        k
        for k, n in names.items()
        if (not only or any(fnmatchcase(n, g) for g in only))
        and not any(fnmatchcase(n, g) for g in ignore)
    }


def _splittable(shape: mi.Shape) -> bool:
    return bool(shape.is_mesh()) and shape.primitive_count() > 1


@dataclass
class IdMap:
    """Object ids of one ``id_mode`` (see the module docstring) for one scene.

    ``names``: mode id -> name (1..M; 0 is the background). :attr:`boxes`: the world-space
    boxes that ray-cast mode's small-object guard projects (:mod:`mi_npr.contours.refine`).
    """

    mode: str
    names: dict[int, str]
    table: ObjectTable
    base: np.ndarray  # uint32 per shape id 0..N: first slot of the shape in ``lut``
    split: np.ndarray  # uint32 per shape id 0..N: 1 if the shape's primitives have own slots
    lut: np.ndarray  # uint32 per slot: mode id
    _jit: Any = field(default=None, repr=False)
    _boxes: np.ndarray | None = field(default=None, repr=False)
    #: True when ids are the object table's ids unchanged (shape mode, everything selected)
    identity: bool = False

    def object_lut(self) -> np.ndarray:
        """uint32 per shape id 0..N: its id in this mode, for the modes whose ids depend on the
        object only (:data:`OBJECT_MODES`); a :class:`ParameterError` for the others."""
        if np.any(self.split):
            raise ParameterError(
                f"id_mode = {self.mode!r} splits shapes into parts: expected one of "
                f"{', '.join(OBJECT_MODES)} here"
            )
        return np.ascontiguousarray(self.lut[self.base])

    @property
    def boxes(self) -> np.ndarray:
        """(K, 2, 3) bounding boxes ``[min, max]`` of every shape and of every connected
        component of a mesh, *whatever the id_mode*: the parts of one shape (the leaves of a
        foliage mesh) can hide between corner rays as well as small shapes can, and so can the
        holes between them. Each shape's box comes first, then its components' (when it has
        more than one). Computed on first use (only ray-cast mode needs them)."""
        if self._boxes is None:
            sids = np.arange(1, len(self.table) + 1)
            shapes, (parts, owner) = self.shape_boxes(), self.part_boxes(sids)
            where = np.searchsorted(owner, sids, side="right")
            chunks = np.split(parts, where[:-1])
            self._boxes = np.concatenate(
                [np.concatenate([shapes[i : i + 1], chunks[i]]) for i in range(len(sids))]
                or [np.zeros((0, 2, 3))]
            )
        return self._boxes

    def shape_boxes(self) -> np.ndarray:
        """(N, 2, 3) world bounding box of each shape, in object id order (ids 1..N)."""
        boxes = []
        for sid in range(1, len(self.table) + 1):
            bb = self.table.shapes[sid].bbox()  # as shape_bbox, without its numpy round trip
            boxes.append((*bb.min, *bb.max))
        return np.asarray(boxes, np.float64).reshape(-1, 2, 3)

    def part_boxes(self, sids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Boxes (K, 2, 3) of the connected components of shapes ``sids`` (object ids) that are
        meshes with more than one component, and the object id of each box (sorted like
        ``sids``). Cached per mesh (:mod:`mi_npr.contours.parts`)."""
        meshes = [int(s) for s in sids if _splittable(self.table.shapes[int(s)])]
        parts = mesh_parts([self.table.shapes[s] for s in meshes])
        boxes = [p.boxes for p in parts if p.count > 1]
        owner = [np.full(p.count, s) for s, p in zip(meshes, parts, strict=True) if p.count > 1]
        if not boxes:
            return np.zeros((0, 2, 3)), np.zeros(0, np.int64)
        return np.concatenate(boxes), np.concatenate(owner).astype(np.int64)

    def apply(self, object_id: Any, prim_id: Any) -> Any:
        """Mode ids of G-buffer layers ``object_id``/``prim_id`` ((H, W) -> (H, W) uint32):
        numpy arrays give a numpy array, Dr.Jit tensors a tensor (computed in Dr.Jit)."""
        if dr.is_tensor_v(object_id) and dr.is_jit_v(object_id):
            shape = tuple(int(v) for v in object_id.shape)
            s = mi.UInt32(object_id.array)
            if self.identity:
                return mi.TensorXu(s, shape=shape)
            base, split, lut = self._tables()
            slot = dr.gather(mi.UInt32, base, s) + mi.UInt32(prim_id.array) * dr.gather(
                mi.UInt32, split, s
            )
            return mi.TensorXu(dr.gather(mi.UInt32, lut, slot), shape=shape)
        s = np.asarray(object_id, np.int64)
        if self.identity:
            return np.ascontiguousarray(s, dtype=np.uint32)
        slot = self.base[s].astype(np.int64) + np.asarray(prim_id, np.int64) * self.split[s]
        return self.lut[slot]

    def _tables(self) -> tuple[Any, Any, Any]:
        if self._jit is None:
            self._jit = (mi.UInt32(self.base), mi.UInt32(self.split), mi.UInt32(self.lut))
        return self._jit

    def lookup(self, si: Any) -> Any:
        """Mode ids of (preliminary) surface interactions, as ``UInt32`` (0 on a miss)."""
        s = self.table.lookup(si)
        if self.identity:
            return s
        base, split, lut = self._tables()
        prim = dr.select(s != 0, si.prim_index, 0)
        slot = dr.gather(mi.UInt32, base, s) + prim * dr.gather(mi.UInt32, split, s)
        return dr.gather(mi.UInt32, lut, slot)


def id_map(
    scene: mi.Scene,
    id_mode: str = "shape",
    table: ObjectTable | None = None,
    only: Sequence[str] = (),
    ignore: Sequence[str] = (),
) -> IdMap:
    """The :class:`IdMap` of ``scene`` for ``id_mode`` (one of :data:`ID_MODES`), with the
    shapes not selected by ``only``/``ignore`` mapped to the background (module docstring)."""
    check_id_mode(id_mode)
    table = table if table is not None else object_table(scene)
    keep = selected(table.names, split_globs(only), split_globs(ignore))
    n = len(table)
    base = np.zeros(n + 1, np.uint32)
    split = np.zeros(n + 1, np.uint32)
    lut_parts: list[np.ndarray] = [np.zeros(1, np.uint32)]  # slot 0: the background
    names: dict[int, str] = {}
    slot, next_id = 1, 1
    grouped: dict[str, int] = {}  # material / silhouette name -> id
    materials = table.material_ids if id_mode == "material" else None
    comps = {}  # object id -> Parts: every mesh's components in one go (cached per mesh)
    if id_mode == "component":
        sids = [sid for sid in range(1, n + 1) if _splittable(table.shapes[sid])]
        comps = dict(zip(sids, mesh_parts([table.shapes[sid] for sid in sids]), strict=True))
    for sid in range(1, n + 1):
        shape, name = table.shapes[sid], table.names[sid]
        base[sid] = slot
        if sid not in keep:
            lut_parts.append(np.zeros(1, np.uint32))
            slot += 1
            continue
        if id_mode in ("material", SILHOUETTE):
            if id_mode == SILHOUETTE:
                group = SILHOUETTE
            else:  # instances have no BSDF of their own: they stay one object each
                mid = int(materials[sid]) if materials is not None else 0
                group = table.materials.get(mid, name)
            if group not in grouped:
                grouped[group] = len(grouped) + 1
            lut_parts.append(np.array([grouped[group]], np.uint32))
            slot += 1
            continue
        parts = None  # per-primitive part index, when the shape is split
        if id_mode == "primitive" and _splittable(shape):
            parts = np.arange(shape.primitive_count(), dtype=np.int64)
        elif sid in comps and comps[sid].count > 1:
            parts = comps[sid].labels
        if parts is None:
            if id_mode == "shape":  # shape ids stay the object table's, whatever is selected
                next_id = sid
            names[next_id] = name
            lut_parts.append(np.array([next_id], np.uint32))
            slot, next_id = slot + 1, next_id + 1
            continue
        count = int(parts.max()) + 1
        sep = "/" if id_mode == "primitive" else "#"
        for c in range(count):
            names[next_id + c] = f"{name}{sep}{c}"
        split[sid] = 1
        lut_parts.append((next_id + parts).astype(np.uint32))
        slot += len(parts)
        next_id += count
    if grouped:  # ids 1..M in name order, like the object table's
        order = sorted(grouped)
        renum = np.zeros(len(grouped) + 1, np.uint32)
        for k, g in enumerate(order, start=1):
            renum[grouped[g]] = k
            names[k] = g
        lut_parts = [renum[p] for p in lut_parts]
    lut = np.concatenate(lut_parts)
    identity = id_mode == "shape" and len(keep) == n
    return IdMap(id_mode, names, table, base, split, lut, identity=identity)
