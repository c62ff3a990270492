"""Small triangle meshes in numpy: generators used by the scenes and tests, and PLY I/O.

A mesh is ``(V, F)``: ``V`` float32 (n, 3) vertex positions, ``F`` uint32 (m, 3) triangles with
counter-clockwise winding seen from outside. PLY goes through ``plyfile``: :func:`write_ply` writes
binary little-endian PLY (what Mitsuba's ``ply`` plugin loads fastest); :func:`read_ply` reads
binary and ASCII PLY with triangle or polygon faces (polygons are fanned into triangles) and keeps
the other vertex properties (Mitsuba's own loader drops those a point-set plant needs).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement, PlyElementParseError, PlyListProperty, PlyParseError

from .errors import InputError, check_input_file
from .io._atomic import atomic_output


def uv_sphere(n_lon: int = 36, n_lat: int = 30, radius: float = 1.0) -> tuple[np.ndarray, ...]:
    """A latitude-longitude sphere: ``(n_lat - 1) * n_lon + 2`` vertices, ``2 n_lon (n_lat - 1)``
    triangles (36 x 30 gives 1046 vertices and 2088 faces, the paper's Fig. 9 sphere)."""
    if n_lon < 3 or n_lat < 2:
        raise ValueError("uv_sphere needs n_lon >= 3 and n_lat >= 2")
    theta = np.pi * np.arange(1, n_lat) / n_lat  # polar angles of the rings
    phi = 2 * np.pi * np.arange(n_lon) / n_lon
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring = np.stack(
        [st * np.cos(phi)[None], ct * np.ones_like(phi)[None], st * np.sin(phi)[None]], axis=-1
    ).reshape(-1, 3)
    V = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]]) * radius
    top, bottom = 0, len(V) - 1
    faces = []
    for j in range(n_lon):
        j1 = (j + 1) % n_lon
        faces.append((top, 1 + j1, 1 + j))
        for i in range(n_lat - 2):
            a, b = 1 + i * n_lon + j, 1 + i * n_lon + j1
            c, d = a + n_lon, b + n_lon
            faces.append((a, b, d))
            faces.append((a, d, c))
        last = 1 + (n_lat - 2) * n_lon
        faces.append((last + j, last + j1, bottom))
    return V.astype(np.float32), np.asarray(faces, dtype=np.uint32)


def box(size: float | tuple[float, float, float] = 1.0, center=(0.0, 0.0, 0.0)):
    """An axis-aligned box as 8 vertices and 12 outward-facing triangles."""
    s = np.broadcast_to(np.asarray(size, dtype=np.float64), (3,)) / 2
    c = np.asarray(center, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    V = corners * s + c
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    F = []
    for a, b, cc, d in quads:
        F += [(a, b, cc), (a, cc, d)]
    return V.astype(np.float32), np.asarray(F, dtype=np.uint32)


def merge(*meshes: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Concatenate meshes into one (the parts stay separate connected components)."""
    Vs, Fs, off = [], [], 0
    for V, F in meshes:
        Vs.append(np.asarray(V, np.float32))
        Fs.append(np.asarray(F, np.uint32) + off)
        off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs)


def weld(V: np.ndarray) -> np.ndarray:
    """Index of each vertex among the distinct positions of ``V`` ((n, 3) -> (n,) int64)."""
    if len(V) == 0:
        return np.zeros(0, np.int64)
    _, inverse = np.unique(np.asarray(V), axis=0, return_inverse=True)
    return inverse.reshape(-1).astype(np.int64)


def face_components(F: np.ndarray, V: np.ndarray | None = None) -> np.ndarray:
    """Connected component of each face ((m, 3) -> (m,) int64), numbered 0.. by lowest face.

    Faces sharing a vertex are connected; with ``V`` given, vertices are first welded by position
    (PLY files duplicate seam vertices: a sphere would fall apart into strips without it).
    One mesh of :func:`components`.
    """
    F = np.asarray(F, np.int64).reshape(-1, 3)
    if len(F) == 0:
        return np.zeros(0, np.int64)
    if V is None:  # no welding: every vertex index a position of its own
        n = int(F.max()) + 1
        V = np.repeat(np.arange(n, dtype=np.float64)[:, None], 3, axis=1)
        V[:, 1] = np.arange(n) // (1 << 20)  # positions stay exact in float32 for any n
        V[:, 0] = np.arange(n) % (1 << 20)
    return components([(F, V)])[0].labels


@dataclass(frozen=True)
class Parts:
    """The connected components of one mesh."""

    labels: np.ndarray  # int64 per face: component, numbered by lowest face
    boxes: np.ndarray  # (C, 2, 3) float64: [min, max] of each component's vertices

    @property
    def count(self) -> int:
        return len(self.boxes)


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
    # imported here: scipy.sparse slows the start of every command, most of which never need it
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

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


def write_ply(
    path: str | os.PathLike[str],
    V: np.ndarray,
    F: np.ndarray,
    vertex_attrs: dict[str, np.ndarray] | None = None,
) -> Path:
    """Binary little-endian PLY with float vertices and uint8-counted uint32 triangle lists.

    ``vertex_attrs`` adds float per-vertex properties after ``x y z`` (``{"nx": (n,) array, ...}``;
    :func:`read_ply` returns them in its ``extra`` dict). ``F`` may have no rows (a point set).
    """

    V = np.asarray(V, dtype="<f4")
    F = np.asarray(F, dtype="<u4")
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"write_ply: expected V (n, 3) and F (m, 3), got {V.shape}, {F.shape}")
    if F.size and F.max() >= len(V):
        raise ValueError("write_ply: a face refers to a vertex that does not exist")
    attrs = {k: np.asarray(a, dtype="<f4").reshape(-1) for k, a in (vertex_attrs or {}).items()}
    for k, a in attrs.items():
        if len(a) != len(V) or not k.isidentifier() or k in ("x", "y", "z"):
            raise ValueError(f"write_ply: vertex attribute {k!r} is misnamed or not one per vertex")
    vrec = np.empty(len(V), dtype=[(k, "<f4") for k in ("x", "y", "z", *attrs)])
    vrec["x"], vrec["y"], vrec["z"] = V.T
    for k, a in attrs.items():
        vrec[k] = a
    frec = np.empty(len(F), dtype=[("vertex_indices", "<u4", (3,))])
    frec["vertex_indices"] = F
    ply = PlyData(
        [
            PlyElement.describe(vrec, "vertex"),
            PlyElement.describe(frec, "face", len_types={"vertex_indices": "u1"}),
        ],
        byte_order="<",
        comments=["written by mi-npr"],
    )
    target = Path(path)
    with atomic_output(target) as tmp, open(tmp, "wb") as f:
        ply.write(f)
    return target


def read_ply(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray, dict]:
    """``(V, F, extra)``: positions, triangles and any other per-vertex properties by name
    (``nx ny nz`` normals, ...). Faces are the first list property of the ``face`` element;
    polygons are fanned into triangles."""

    p = Path(path)
    check_input_file(p)
    with open(p, "rb") as f:
        if f.read(3) != b"ply":
            raise InputError(f"{p}: not a PLY file")
    try:
        try:  # triangle lists read as one block when every face is a triangle
            ply = PlyData.read(p, known_list_len={"face": _TRIANGLE_LISTS})
        except PlyElementParseError as e:
            if e.message != "unexpected list length":
                raise
            ply = PlyData.read(p, mmap=False)
        names = [el.name for el in ply.elements]
        if "vertex" not in names:
            raise ValueError("no vertex element")
        vdata = ply["vertex"].data
        V = np.stack([vdata[c] for c in "xyz"], axis=-1).astype(np.float32)
        extra = {
            k: np.array(vdata[k], np.float64)
            for k in vdata.dtype.names
            if k not in "xyz" and vdata.dtype[k].kind != "O"
        }
        F = np.zeros((0, 3), np.uint32)
        if "face" in names:
            lists = [q.name for q in ply["face"].properties if isinstance(q, PlyListProperty)]
            if lists:
                F = _triangulate(ply["face"].data[lists[0]])
    except (PlyParseError, ValueError, KeyError) as e:
        raise InputError(f"{p}: malformed PLY ({e})") from None
    return V, F, extra


#: Names exporters give the face index list (memory-mapped when every face is a triangle).
_TRIANGLE_LISTS = {"vertex_indices": 3, "vertex_index": 3}


def _triangulate(faces: np.ndarray) -> np.ndarray:
    """Triangles of the polygons ``faces`` ((m, 3) array, or (m,) of index arrays), each polygon
    fanned around its first vertex, in face order."""
    if faces.dtype != object:
        return np.array(faces, np.uint32).reshape(-1, 3)
    if not len(faces):
        return np.zeros((0, 3), np.uint32)
    n = np.array([len(f) for f in faces], np.int64)
    flat = np.concatenate(list(faces)).astype(np.int64)
    per = np.maximum(n - 2, 0)  # triangles per polygon
    start = np.cumsum(n) - n
    face = np.repeat(np.arange(len(n)), per)
    j = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per) + 1
    first = start[face]
    return flat[np.stack([first, first + j, first + j + 1], axis=1)].astype(np.uint32)


if __name__ == "__main__":  # pragma: no cover - regenerates the scene meshes
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "scenes_xml/meshes")
    sphere = uv_sphere(36, 30, 1.0)
    cube = box(0.4)
    write_ply(out / "sphere_with_cube.ply", *merge(sphere, cube))
    write_ply(out / "uv_sphere.ply", *sphere)
