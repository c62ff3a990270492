"""Connected components of many meshes at once, cached per mesh: the ``"component"`` ids and the
boxes of ray-cast mode's small-object guard.

:func:`mesh_parts` returns, for each mesh, the component of every face (numbered ``0..`` by the
lowest face they hold, vertices welded by position) and each component's world bounding box, from
:func:`mi_npr.meshes.components` (all the meshes asked for in one scipy call, so there is no
per-mesh Python work beyond reading the buffers).

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

import mitsuba as mi
import numpy as np

from ..meshes import Parts, components, weld_keys  # noqa: F401  (weld_keys: public here too)

#: How many meshes' parts are kept (least recently used are dropped first).
CACHE_SIZE = 4096


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
