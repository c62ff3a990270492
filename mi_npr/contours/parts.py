"""Connected components of many meshes at once, cached per mesh: the ``"component"`` ids and the
boxes of ray-cast mode's small-object guard.

:func:`mesh_parts` returns, for each mesh, the component of every face (numbered ``0..`` by the
lowest face they hold, as :func:`mi_npr.meshes.face_components` numbers them, vertices welded by
position) and each component's world bounding box. All the meshes asked for are done together
with whole-array numpy and one scipy ``connected_components`` call (one graph whose vertices are
the welded positions of every mesh, a position of one mesh never welded to one of another), so
there is no per-mesh Python work beyond reading the buffers.

**Cache.** A scene's meshes do not change between calls unless the user edits them, so the
result is kept per mesh (the ``mi.Shape`` object itself, held so its ``id`` stays its own) for
the last :data:`CACHE_SIZE` meshes, and checked on every use against the mesh's bounding box,
face count and vertex count: a mesh edited through ``mi.traverse`` that keeps all three (vertices
moved inside the same box) would keep stale parts, which only the guard's boxes and the
``"component"`` numbering could notice; :func:`clear_cache` forgets everything.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import mitsuba as mi
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

#: How many meshes' parts are kept (least recently used are dropped first).
CACHE_SIZE = 4096


@dataclass(frozen=True)
class Parts:
    """The connected components of one mesh."""

    labels: np.ndarray  # int64 per face: component, numbered by lowest face
    boxes: np.ndarray  # (C, 2, 3) float64: [min, max] of each component's vertices

    @property
    def count(self) -> int:
        return len(self.boxes)


_CACHE: OrderedDict[int, tuple[mi.Shape, tuple, Parts]] = OrderedDict()
_LOCK = threading.Lock()


def clear_cache() -> None:
    """Forget every mesh's parts (they are recomputed on next use)."""
    with _LOCK:
        _CACHE.clear()


def _key(shape: mi.Shape) -> tuple:
    bb = shape.bbox()
    box = tuple(float(v) for v in (*bb.min, *bb.max))
    return box, int(shape.primitive_count()), int(shape.vertex_count())


def mesh_arrays(shape: mi.Shape) -> tuple[np.ndarray, np.ndarray]:
    """Faces (m, 3) int64 and vertex positions (n, 3) float32 of a mesh."""
    F = np.asarray(shape.faces_buffer().numpy(), np.int64).reshape(-1, 3)
    V = np.asarray(shape.vertex_positions_buffer().numpy(), np.float32).reshape(-1, 3)
    return F, V


def mesh_parts(shapes: Sequence[mi.Shape]) -> list[Parts]:
    """The :class:`Parts` of each mesh in ``shapes`` (from the cache where it holds them)."""
    out: list[Parts | None] = [None] * len(shapes)
    todo: list[int] = []
    keys: list[tuple] = []
    with _LOCK:
        for i, shape in enumerate(shapes):
            key = _key(shape)
            hit = _CACHE.get(id(shape))
            if hit is not None and hit[0] is shape and hit[1] == key:
                _CACHE.move_to_end(id(shape))
                out[i] = hit[2]
            else:
                todo.append(i)
                keys.append(key)
    if todo:
        fresh = components([mesh_arrays(shapes[i]) for i in todo])
        with _LOCK:
            for i, key, parts in zip(todo, keys, fresh, strict=True):
                out[i] = parts
                _CACHE[id(shapes[i])] = (shapes[i], key, parts)
                _CACHE.move_to_end(id(shapes[i]))
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
    return out  # type: ignore[return-value]


def weld_keys(V: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Index of each vertex among the distinct ``(group, position)`` pairs ((n,) int64).

    Positions compare by value like ``np.unique(V, axis=0)`` (``-0.0`` equals ``0.0``, a NaN
    equals nothing): the float bits, with ``-0.0`` made ``+0.0``, are sorted as two 64-bit keys.
    """
    n = len(V)
    if n == 0:
        return np.zeros(0, np.int64)
    bits = (np.asarray(V, np.float32) + np.float32(0.0)).view(np.uint32).astype(np.uint64)
    k1 = (np.asarray(group, np.uint64) << np.uint64(32)) | bits[:, 0]
    k2 = (bits[:, 1] << np.uint64(32)) | bits[:, 2]
    nan = np.isnan(V).any(axis=1)
    if nan.any():  # each NaN vertex stays on its own
        k1[nan] |= np.uint64(1) << np.uint64(63)
        k2[nan] = np.flatnonzero(nan).astype(np.uint64)
    order = np.lexsort((k2, k1))
    s1, s2 = k1[order], k2[order]
    new = np.empty(n, dtype=bool)
    new[0] = True
    new[1:] = (s1[1:] != s1[:-1]) | (s2[1:] != s2[:-1])
    inverse = np.empty(n, np.int64)
    inverse[order] = np.cumsum(new) - 1
    return inverse


def components(meshes: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[Parts]:
    """:class:`Parts` of meshes given as ``(F, V)`` arrays, all in one graph (module docstring)."""
    m = len(meshes)
    if m == 0:
        return []
    nv = np.array([len(V) for _, V in meshes], np.int64)
    nf = np.array([len(F) for F, _ in meshes], np.int64)
    voff = np.concatenate([[0], np.cumsum(nv)[:-1]])
    V = np.concatenate([np.asarray(V, np.float32).reshape(-1, 3) for _, V in meshes])
    F = np.concatenate(
        [np.asarray(F, np.int64).reshape(-1, 3) + o for (F, _), o in zip(meshes, voff, strict=True)]
    )
    mesh_of_face = np.repeat(np.arange(m), nf)
    if len(F) == 0:
        return [Parts(np.zeros(0, np.int64), np.zeros((0, 2, 3))) for _ in meshes]
    W = weld_keys(V, np.repeat(np.arange(m), nv))[F]
    n = int(W.max()) + 1
    edges = np.concatenate([W[:, [0, 1]], W[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges), np.int8), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, vertex_label = connected_components(graph, directed=False)
    label = vertex_label[W[:, 0]]  # per face; no component spans two meshes
    order = np.argsort(label, kind="stable")  # faces of one component, lowest first
    sl = label[order]
    start = np.flatnonzero(np.r_[True, sl[1:] != sl[:-1]])
    first = order[start]  # lowest face of each component
    group = np.empty(len(F), np.int64)
    group[order] = np.cumsum(np.r_[True, sl[1:] != sl[:-1]]) - 1
    # Number the components of each mesh by their lowest face (faces are in mesh order).
    by_first = np.argsort(first, kind="stable")
    comp_mesh = mesh_of_face[first[by_first]]
    count = np.bincount(comp_mesh, minlength=m)
    cstart = np.concatenate([[0], np.cumsum(count)[:-1]])
    rank = np.empty(len(first), np.int64)
    rank[by_first] = np.arange(len(first)) - cstart[comp_mesh]
    # Component boxes: each face's box, then the min / max over the component's faces.
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    lo = np.minimum.reduceat(np.minimum(np.minimum(a, b), c)[order], start)
    hi = np.maximum.reduceat(np.maximum(np.maximum(a, b), c)[order], start)
    boxes = np.stack([lo, hi], axis=1).astype(np.float64)[by_first]
    face_rank = rank[group]
    fstart = np.concatenate([[0], np.cumsum(nf)])
    return [
        Parts(
            face_rank[fstart[i] : fstart[i + 1]],
            boxes[cstart[i] : cstart[i] + count[i]],
        )
        for i in range(m)
    ]
