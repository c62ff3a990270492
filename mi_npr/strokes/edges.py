"""Object-space feature edges of a scene's meshes, and the camera's projection of them.

**Topology.** Every mesh (``shape.is_mesh()``: Mitsuba's ``obj``, ``ply``, ``cube``,
``rectangle``...) gives its vertex positions (world space: Mitsuba stores them transformed)
and faces. Vertices of *all* meshes closer than ``1e-6`` of the scene's size
are welded into one (a mesh split at UV seams, or two objects that share an edge, such as a
room's floor and wall); an edge is a pair of welded vertices, its faces the triangles that use
it. Building it costs ``O(F log F)`` for ``F`` triangles; it does not depend on the camera,
so it is built once per scene (:func:`topology`, with the intersection lines) and each view
only classifies the edges (``O(E)`` array operations).

**Kinds** (``mi_npr.strokes.KINDS``), one per edge, the first that applies:

1. ``silhouette``: two faces, one front-facing and one back-facing. A face is front-facing when
   its normal points to the camera: ``n . (a - o) < 0`` with ``o`` the camera origin and ``a``
   any point of the face (exact for a perspective camera: every point of the edge gives the same
   sign); for an orthographic camera, ``n . f < 0`` with ``f`` its view axis. Normals follow
   the winding; where two faces wind the shared edge the same way (an inconsistently oriented
   mesh) the second face's normal is flipped for this edge.
2. ``border``: one face (the edge of an open surface).
3. ``material``: two faces of different objects (the objects meet along the edge; an object
   boundary, whether or not their BSDFs differ).
4. ``crease``: two faces whose dihedral angle ``180 - angle(n0, n1)`` is below
   ``crease_angle`` degrees (Freestyle's definition, the ``lines`` drawing's: coplanar faces
   180, a cube's edges 90; 0 turns creases off); also every edge of three or more faces (a
   non-manifold fold that no dihedral angle describes).

5. ``intersection``: where triangles of two different meshes cut each other
   (:mod:`mi_npr.strokes.intersect`); these edges are not mesh edges: their ends are nodes of
   their own, welded among those of the same pair of objects (a line is chained within its
   pair: where the lines of two pairs meet, each ends). A pair of objects is searched the
   first time a view asks for it (:meth:`Topology.search`; every pair, or those that a view's
   image shows side by side) and kept with the topology.

Other edges (smooth, coplanar) are not drawn. Each edge is drawn with one face, the one that
*faces the camera more* (the smaller ``n . (a - o) / (|n| |a - o|)``; for a silhouette, the
front face; for a border, its face): that face's object and primitive index are the edge's.

**Projection** (:class:`Projector`): Mitsuba's perspective camera (:mod:`mi_npr.projection`'s
matrices; a thin lens through its lens centre) or orthographic camera (an affine map, ``W =
1``) in homogeneous coordinates. A 3-D segment is clipped to the view frustum (the near
plane and the image frame) in homogeneous coordinates, where every bound is linear in the
segment's parameter, so the clipped ends lie exactly on the frame.
"""

from __future__ import annotations

import dataclasses
import math
import threading
from dataclasses import dataclass, field
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..camera import projection_of
from ..errors import ParameterError
from ..gbuffer import Projection
from ..memory import release_freed_memory
from ..projection import world_to_ndc
from ..scene import ObjectTable
from .intersect import intersections
from .model import KINDS
from .order import stable_argsort

#: Welding distance, relative to the diagonal of all meshes' bounding box.
WELD = 1e-6

_SIL, _BORDER, _MATERIAL, _CREASE = (
    KINDS.index(k) for k in ("silhouette", "border", "material", "crease")
)


@dataclass
class FeatureEdges:
    """``E`` feature edges: ends ``a``, ``b`` (E, 3) float64 world points, their welded vertex
    ids ``va``, ``vb`` (E,), ``kind`` (E,) indices into :data:`KINDS`, the drawn face's
    ``object_id`` and ``prim`` (E,), and ``faces`` (E, 2, 2): ``(object id, prim)`` of the
    first two adjacent faces (object id 0 where there is none): rays to the edge never count
    them as occluders."""

    a: np.ndarray
    b: np.ndarray
    va: np.ndarray
    vb: np.ndarray
    kind: np.ndarray
    object_id: np.ndarray
    prim: np.ndarray
    faces: np.ndarray

    def __len__(self) -> int:
        return len(self.a)

    def take(self, rows: slice | np.ndarray) -> FeatureEdges:
        """The edges ``rows`` (a slice or an index array)."""
        return FeatureEdges(*(getattr(self, k)[rows] for k in self.__dataclass_fields__))

    def max_node(self) -> int:
        """The largest node id of the edges' ends (-1 for none)."""
        return int(max(self.va.max(initial=-1), self.vb.max(initial=-1)))

    @classmethod
    def empty(cls) -> FeatureEdges:
        z3 = np.zeros((0, 3))
        zi = np.zeros(0, np.int64)
        return cls(
            z3,
            z3,
            zi,
            zi,
            zi,
            zi.astype(np.uint32),
            zi.astype(np.uint32),
            np.zeros((0, 2, 2), np.int64),
        )


def mesh_arrays(table: ObjectTable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every mesh of the object table as one triangle soup: vertex positions (V, 3) (float32
    where every mesh stores single precision, as a single-precision variant's do: the values
    themselves, in half the memory of float64; else float64), faces (F, 3) into them (int32;
    int64 past 2**31 vertices), and each face's object id (F,) int32, the faces of one object
    contiguous, objects in increasing id (a face's primitive index is its position among its
    object's faces)."""
    meshes = []
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if not shape.is_mesh():
            continue
        # the mesh's own buffers (world space, flat): no kernel per shape
        vp, fb = shape.vertex_positions_buffer(), shape.faces_buffer()
        if dr.width(fb) >= 3:
            meshes.append((oid, vp, fb))
    n_v = sum(dr.width(vp) // 3 for _, vp, _ in meshes)
    n_f = sum(dr.width(fb) // 3 for _, _, fb in meshes)
    # filled in place, one mesh at a time: no second copy of the soup while it is joined
    single = all(dr.type_v(vp) == dr.VarType.Float32 for _, vp, _ in meshes)
    v = np.empty((n_v, 3), np.float32 if single else np.float64)
    faces = np.empty((n_f, 3), np.int32 if n_v < 2**31 else np.int64)
    oids = np.empty(n_f, np.int32)
    base = at = 0
    for oid, vp, fb in meshes:
        mv = np.asarray(vp.numpy()).reshape(-1, 3)
        mf = np.asarray(fb.numpy()).reshape(-1, 3)
        v[base : base + len(mv)] = mv
        faces[at : at + len(mf)] = mf
        faces[at : at + len(mf)] += base
        oids[at : at + len(mf)] = oid
        base, at = base + len(mv), at + len(mf)
    return v, faces, oids


def weld(v: np.ndarray, tolerance: float) -> np.ndarray:
    """A welded vertex id for each row of ``v`` (V, 3): vertices closer than ``tolerance``
    (transitively) share one id, numbered 0..K-1 in the order of each group's first vertex.
    The close pairs come from SciPy's k-d tree; the groups are their connected components,
    found by propagating each group's least index along the pairs (with pointer jumping: a
    few rounds for the small groups of a mesh's seams) rather than through a sparse graph,
    whose copies of the pairs would double their memory."""
    if len(v) == 0:
        return np.zeros(0, np.int64)
    # scipy's spatial module takes ~0.2 s to import: only scenes with meshes pay it
    from scipy.spatial import cKDTree

    # an unbalanced tree without shrunk node boxes: built in a third of the time, the same pairs
    tree = cKDTree(v, balanced_tree=False, compact_nodes=False)
    pairs = tree.query_pairs(tolerance, output_type="ndarray")
    del tree
    n = len(v)
    least = np.arange(n)
    a, b = pairs[:, 0], pairs[:, 1]
    while True:
        m = np.minimum(least[a], least[b])
        if np.array_equal(least[a], m) and np.array_equal(least[b], m):
            break
        np.minimum.at(least, a, m)
        np.minimum.at(least, b, m)
        least = least[least]  # each index's least, then that one's: halves the paths
    first = least == np.arange(n)  # a group's least index: its first vertex
    return (np.cumsum(first) - 1)[least]


#: Half-edges grouped into edges at once while the topology is built (bounds its memory).
HALF_EDGES = 1 << 18
#: Faces whose normals are computed at once, and edges classified at once for a view (bound
#: the memory of the temporaries).
FACES = 1 << 16
EDGE_BLOCK = 1 << 18


def _corner_ends(
    wid: np.ndarray, f: np.ndarray, h: np.ndarray | int
) -> tuple[np.ndarray, np.ndarray]:
    """The welded ends (from, to) of half-edges ``h`` (an index array), or of every half-edge
    from corner ``h`` (an int) of the faces ``f``: half-edge ``h`` runs from corner ``h % 3``
    of face ``h // 3`` to the next corner."""
    if isinstance(h, int):
        return wid[f[:, h]], wid[f[:, (h + 1) % 3]]
    flat = f.reshape(-1)  # half-edge h starts at corner h of the faces' corners in a row
    return wid[flat[h]], wid[flat[h + np.where(h % 3 == 2, -2, 1)]]


def _group_edges(
    wid: np.ndarray, f: np.ndarray, n_welded: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The welded edges of the faces ``f`` (F, 3) whose vertices are welded into ``wid``
    (V,): ``keys`` (E, 2) int32, the face counts (E,) uint8 (3: three or more), the first two
    faces ``f0``, ``f1`` (E,) int32 (``f1 = f0`` with one face) and ``flip`` (E,) bool, in
    increasing ``keys``; an edge's faces are its half-edges' (:func:`_corner_ends`) in the
    order of their indices. The half-edges are sorted about :data:`HALF_EDGES` at a time, in
    ranges of their lower end (the same order as one stable sort of them all); of each
    half-edge only its range is kept meanwhile (one byte or two), its ends found again from
    the faces."""
    f = np.ascontiguousarray(f)  # (its corners in a row: :func:`_corner_ends`)
    # the ranges: runs of lower ends holding about HALF_EDGES half-edges each
    per_end = np.zeros(n_welded, np.int64)
    for k in range(3):  # a corner at a time: no (F, 3) temporaries
        u, w = _corner_ends(wid, f, k)
        per_end += np.bincount(np.minimum(u, w)[u != w], minlength=n_welded)
    cum = np.cumsum(per_end)
    del per_end
    cuts = np.searchsorted(cum, np.arange(HALF_EDGES, int(cum[-1]), HALF_EDGES)) + 1
    cuts = np.unique(np.concatenate([[0], cuts, [n_welded]]))
    n_ranges = len(cuts) - 1
    del cum
    dtype = np.uint8 if n_ranges < 255 else np.uint16 if n_ranges < 65535 else np.uint32
    # the range of each welded vertex as a lower end, and one past the last for none
    of_end = np.append(np.repeat(np.arange(n_ranges, dtype=dtype), np.diff(cuts)), n_ranges)
    of_end = of_end.astype(dtype)
    rank = np.empty(3 * len(f), dtype)
    for k in range(3):
        u, w = _corner_ends(wid, f, k)
        # a face collapsed by welding has no edge there: in no range
        rank[k::3] = of_end[np.where(u != w, np.minimum(u, w), n_welded)]
    del u, w, of_end
    release_freed_memory()
    # the edges written in place, as many rows as half-edges reserved (pages never written
    # take no memory) and the rest handed back at the end: no parts joined, and the ranges'
    # temporaries, all of one size, reuse each other's memory
    cap = int(np.count_nonzero(rank < n_ranges))
    keys = np.empty((cap, 2), np.int32)
    counts = np.empty(cap, np.uint8)
    f0, f1 = np.empty(cap, np.int32), np.empty(cap, np.int32)
    flip = np.empty(cap, bool)
    at = 0
    for r in range(n_ranges):
        sel = np.flatnonzero(rank == r)  # the range's half-edges, in increasing order
        if not len(sel):
            continue
        u, w = _corner_ends(wid, f, sel)
        lo, hi, forward = np.minimum(u, w), np.maximum(u, w), u < w
        del u, w
        key = lo.astype(np.int64) * n_welded + hi
        order = stable_argsort(key)
        key = key[order]
        head = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
        del key
        n = np.diff(np.append(head, len(sel)))
        i0 = order[head]
        i1 = np.where(n >= 2, order[np.minimum(head + 1, len(sel) - 1)], i0)
        del order, head
        rows = slice(at, at + len(i0))
        keys[rows, 0], keys[rows, 1] = lo[i0], hi[i0]
        counts[rows] = np.minimum(n, 3)
        f0[rows], f1[rows] = sel[i0] // 3, sel[i1] // 3
        flip[rows] = forward[i0] == forward[i1]
        at += len(i0)
    del rank
    for x in (keys, counts, f0, f1, flip):
        x.resize((at, *x.shape[1:]), refcheck=False)  # in place: the tail is never copied
    return keys, counts, f0, f1, flip


def _asked_keys(pairs: np.ndarray, n_keys: int) -> np.ndarray:
    """The sorted unique keys (:meth:`Topology.pair_keys`) of the object pairs ``pairs`` (K, 2)
    whose objects are two different meshes' (ids below ``n_keys``)."""
    a = np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1)
    a = a[(a[:, 0] != a[:, 1]) & (a[:, 0] >= 0) & (a[:, 1] < n_keys)]
    return np.unique(a[:, 0] * n_keys + a[:, 1])


def _crossings(
    v: np.ndarray,
    f: np.ndarray,
    face_oid: np.ndarray,
    size: float,
    keys: np.ndarray | None,
    n_keys: int,
) -> tuple[np.ndarray, ...]:
    """The intersection segments of the object pairs ``keys`` (:func:`_asked_keys`; ``None``:
    every pair) of the soup ``v``, ``f``, ``face_oid``, as :attr:`Topology.crossings`: their
    ends welded (``WELD * size``) within each pair of objects into nodes numbered from 0 in
    the order the ends come (``p`` before ``q``); a segment whose ends weld is left out."""
    pairs = None if keys is None else np.stack(np.divmod(keys, n_keys), 1)
    p, q, fa, fb = intersections(v, f, face_oid, pairs)
    zi = np.zeros(0, np.int32)
    if not len(p):
        return p, q, zi, zi, zi, zi
    key = face_oid[fa].astype(np.int64) * n_keys + face_oid[fb]
    block = np.cumsum(np.append(True, key[1:] != key[:-1])) - 1
    # one weld for all pairs, each pair's ends moved along x past every other pair's
    lo = np.minimum(p.min(0), q.min(0))
    span = float(np.max(np.maximum(p.max(0), q.max(0)) - lo)) + 1.0
    ends = np.empty((2 * len(p), 3))
    ends[0::2], ends[1::2] = p - lo, q - lo
    ends[:, 0] += np.repeat(block * (2.0 * span), 2)
    node = weld(ends, WELD * size)
    del ends
    # numbered in the order the ends come: a pair's nodes are then a run starting at its first
    _, first_at, inv = np.unique(node, return_index=True, return_inverse=True)
    rank = np.empty(len(first_at), np.int64)
    rank[np.argsort(first_at, kind="stable")] = np.arange(len(first_at))
    node = rank[inv.ravel()]
    start = np.flatnonzero(np.append(True, block[1:] != block[:-1]))
    node -= np.repeat(node[2 * start], 2 * np.diff(np.append(start, len(p))))
    la, lb = node[0::2].astype(np.int32), node[1::2].astype(np.int32)
    keep = la != lb
    fa, fb = fa[keep].astype(np.int32), fb[keep].astype(np.int32)
    return p[keep], q[keep], fa, fb, la[keep], lb[keep]


def _first_faces(face_oid: np.ndarray) -> np.ndarray:
    """The index of each object id's first face (faces of one object contiguous)."""
    heads = np.flatnonzero(np.append(True, face_oid[1:] != face_oid[:-1]))
    first_face = np.zeros(int(face_oid.max()) + 1, np.int64)
    first_face[face_oid[heads]] = heads
    return first_face


def _early_stage(
    v: np.ndarray, f: np.ndarray, face_oid: np.ndarray, pairs: np.ndarray | None
) -> tuple[float, np.ndarray | None, tuple[np.ndarray, ...], np.ndarray]:
    """What :meth:`Topology.of` takes from the vertex positions themselves (no Dr.Jit call):
    the meshes' size (the diagonal of their box), the keys of the object pairs searched, the
    intersection segments (:func:`_crossings`) and the welded vertex ids (int32), one after
    the other, not side by side (their temporaries would add up)."""
    size = float(np.linalg.norm(v.max(0).astype(np.float64) - v.min(0))) or 1.0
    n_keys = len(_first_faces(face_oid))
    asked = None if pairs is None else _asked_keys(pairs, n_keys)
    crossings = _crossings(v, f, face_oid, size, asked, n_keys)
    release_freed_memory()
    wid = weld(v, WELD * size).astype(np.int32)
    release_freed_memory()
    return size, asked, crossings, wid


@dataclass(eq=False)
class Topology:
    """What of the feature edges does not depend on the camera, kept small (a scene's meshes have
    millions of triangles): per face (F) its object id ``face_oid`` (a face's primitive index
    is its position among its object's faces, from ``first_face``, the index of each object
    id's first face), unit normal ``unit`` (float32; 0 for a degenerate face) and plane offset
    ``offset = unit . p0`` (float64, of the stored normal: the plane of that normal through the
    face's first vertex, so the facing test is exact for it), both of the face with its welded
    vertices (the faces that share an edge share its ends' positions); the welded vertices
    (their first occurrence's position ``welded``, float32 when that holds them exactly, as it
    does for Mitsuba's single-precision meshes); per welded edge (E) its ends ``keys`` (E, 2),
    its face count ``counts`` (3: three or more), its first two faces ``f0``, ``f1`` (``f1 =
    f0`` with one face) and ``flip`` (the two faces wind the edge the same way: ``f1``'s normal
    is turned for it); and the intersection segments ``crossings`` of the pairs of objects
    searched so far (``searched``: their keys :meth:`pair_keys`, sorted; ``None``: every pair)
    (ends ``p``, ``q``, faces ``fa``, ``fb`` (``fa``'s object the lower id), end nodes ``la``,
    ``lb`` numbered within the pair of objects; the segments of a pair together, the pairs in
    increasing keys). The vertex positions and faces themselves are not kept."""

    face_oid: np.ndarray
    first_face: np.ndarray
    unit: np.ndarray
    offset: np.ndarray
    size: float
    welded: np.ndarray
    keys: np.ndarray
    counts: np.ndarray
    f0: np.ndarray
    f1: np.ndarray
    flip: np.ndarray
    crossings: tuple[np.ndarray, ...]
    searched: np.ndarray | None = None
    _kinds: dict = field(default_factory=dict)
    #: Views classified so far (:func:`view_edges`).
    views: int = 0

    @classmethod
    def of(
        cls, table: ObjectTable, pairs: np.ndarray | None = None, early: tuple | None = None
    ) -> Topology:
        """The topology of the meshes of ``table`` (their triangle soup, :func:`mesh_arrays`;
        class docstring), with the intersection lines of the object pairs ``pairs`` ((K, 2)
        object ids; default every pair). Built in the order that keeps the fewest arrays alive
        at once: the intersections first (from the soup alone), the welded vertices, the edges
        (from the faces and their welded vertices alone), then the faces' planes (from the
        welded vertices). ``early``: what :func:`_early_stage` made of this soup already (on
        another thread, :func:`prefetch_topology`): the build goes on from there (``pairs``
        unused)."""
        return cls.from_soup(*mesh_arrays(table), pairs, early)

    @classmethod
    def from_soup(
        cls,
        v: np.ndarray,
        f: np.ndarray,
        face_oid: np.ndarray,
        pairs: np.ndarray | None = None,
        early: tuple | None = None,
    ) -> Topology:
        """:meth:`of` the meshes' triangle soup (:func:`mesh_arrays`: no Dr.Jit call)."""
        z, z3 = np.zeros(0, np.int64), np.zeros((0, 3))
        if len(f) == 0:
            zi = z.astype(np.int32)
            crossings = (z3, z3, zi, zi, zi, zi)
            return cls(
                zi,
                z,
                z3,
                z * 0.0,
                1.0,
                z3,
                np.zeros((0, 2), np.int32),
                z.astype(np.uint8),
                zi,
                zi,
                z.astype(bool),
                crossings,
            )
        first_face = _first_faces(face_oid)
        size, asked, crossings, wid = early or _early_stage(v, f, face_oid, pairs)
        n_welded = int(wid.max()) + 1
        rep = np.zeros(n_welded, np.int64)
        rep[wid[::-1]] = np.arange(len(wid))[::-1]
        welded = v[rep]
        del rep
        if np.array_equal(welded.astype(np.float32), welded):
            welded = welded.astype(np.float32)  # the same values in half the memory
        del v  # the edges need the welded faces alone, the planes the welded vertices
        release_freed_memory()
        keys, counts, f0, f1, flip = _group_edges(wid, f, n_welded)
        release_freed_memory()
        # unit normals and plane offsets of the welded faces, a block of faces at a time
        # (bounded temporaries)
        unit = np.empty((len(f), 3), np.float32)
        offset = np.empty(len(f))
        for c in range(0, len(f), FACES):
            fc = wid[f[c : c + FACES]]
            p0 = welded[fc[:, 0]].astype(np.float64)
            n = np.cross(welded[fc[:, 1]] - p0, welded[fc[:, 2]] - p0)
            length = np.linalg.norm(n, axis=1)
            unit[c : c + len(fc)] = n / np.where(length > 0, length, np.inf)[:, None]
            stored = unit[c : c + len(fc)].astype(np.float64)
            offset[c : c + len(fc)] = np.einsum("ij,ij->i", stored, p0)
        del f, fc, p0, n, length, stored
        return cls(
            face_oid,
            first_face,
            unit,
            offset,
            size,
            welded,
            keys,
            counts,
            f0,
            f1,
            flip,
            crossings,
            asked,
        )

    def pair_keys(self, fa: np.ndarray, fb: np.ndarray) -> np.ndarray:
        """The key of the pair of objects of faces ``fa``, ``fb`` (``fa``'s the lower id):
        ``oid_a * K + oid_b``, ``K`` one past the largest object id of a face."""
        return self.face_oid[fa].astype(np.int64) * len(self.first_face) + self.face_oid[fb]

    def search(self, table: ObjectTable, pairs: np.ndarray | None = None) -> None:
        """Add the intersection lines of the object pairs ``pairs`` ((K, 2) object ids; default
        every pair) not searched yet, from the meshes of ``table`` (the ones this topology was
        built from): their segments go in among the others, in the order of their keys."""
        if self.searched is None:
            return
        n_keys = len(self.first_face)
        asked = None if pairs is None else _asked_keys(pairs, n_keys)
        todo = asked if asked is None else np.setdiff1d(asked, self.searched)
        if todo is not None and len(todo) == 0:
            return
        v, f, face_oid = mesh_arrays(table)
        new = _crossings(v, f, face_oid, self.size, todo, n_keys)
        del v, f, face_oid
        if todo is None:  # every pair: the search holds the ones made before
            self.crossings, self.searched = new, None
            return
        both = tuple(np.concatenate(x) for x in zip(self.crossings, new, strict=True))
        order = np.argsort(self.pair_keys(both[2], both[3]), kind="stable")
        self.crossings = tuple(x[order] for x in both)
        self.searched = np.union1d(self.searched, todo)

    def crossing_rows(
        self, pairs: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rows of ``crossings`` of the object pairs ``pairs`` ((K, 2) object ids; default
        every pair searched) and their ends' node ids, numbered after the welded vertices,
        pair after pair: ``(rows, va, vb)``. The same pairs give the same nodes whatever was
        searched before."""
        _, _, fa, fb, la, lb = self.crossings
        key = self.pair_keys(fa, fb)
        if pairs is None:
            rows = np.arange(len(key))
        else:
            rows = np.flatnonzero(np.isin(key, _asked_keys(pairs, len(self.first_face))))
        if not len(rows):
            z = np.zeros(0, np.int64)
            return z, z, z
        key, la, lb = key[rows], la[rows], lb[rows]
        head = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
        nodes = np.maximum.reduceat(np.maximum(la, lb), head).astype(np.int64) + 1
        first = len(self.welded) + np.cumsum(nodes) - nodes
        base = np.repeat(first, np.diff(np.append(head, len(key))))
        return rows, base + la, base + lb

    def rows_only(self) -> Topology:
        """This topology without what only classifying a view reads (the faces' planes, the
        kinds of the last crease angle): what :meth:`ViewEdges.take` needs, the arrays shared,
        for the last view of a topology no longer kept (its planes freed with it)."""
        z = np.zeros((0, 3), self.unit.dtype)
        return dataclasses.replace(self, unit=z, offset=self.offset[:0].copy(), _kinds={})

    def prim(self, faces: np.ndarray) -> np.ndarray:
        """The primitive index of each face (its position among its object's faces)."""
        return faces - self.first_face[self.face_oid[faces]]

    def static_kinds(self, crease_angle: float) -> np.ndarray:
        """Each edge's kind (E,) int8 as far as it does not depend on the camera: crease,
        material or border (module docstring), -1 for none (a silhouette overrides them).
        Creases compare ``cos_n``, the cosine between the two (turned) normals (1 where
        either face is degenerate), with ``cos(180 - crease_angle)``."""
        if crease_angle not in self._kinds:
            self._kinds = {}  # one angle kept: the memory of one array
            # dihedral < crease_angle  <=>  angle(n0, n1) > 180 - crease_angle
            crease_cos = math.cos(math.radians(180.0 - crease_angle))
            degenerate = ~np.any(self.unit != 0, axis=1)
            kind = np.full(len(self.counts), -1, np.int8)
            for c in range(0, len(kind), EDGE_BLOCK):  # a block of edges at a time (memory)
                f0, f1 = self.f0[c : c + EDGE_BLOCK], self.f1[c : c + EDGE_BLOCK]
                counts = self.counts[c : c + EDGE_BLOCK]
                cos_n = np.zeros(len(f0))
                for k in range(3):
                    col = self.unit[:, k]
                    cos_n += col[f0].astype(np.float64) * col[f1].astype(np.float64)
                cos_n = np.where(self.flip[c : c + EDGE_BLOCK], -cos_n, cos_n)
                cos_n[degenerate[f0] | degenerate[f1]] = 1.0
                two = counts == 2
                crease = (crease_angle > 0) & (cos_n < crease_cos)
                block = kind[c : c + EDGE_BLOCK]
                block[counts >= 3] = _CREASE
                block[two & crease] = _CREASE
                block[two & (self.face_oid[f0] != self.face_oid[f1])] = _MATERIAL
                block[counts == 1] = _BORDER
            self._kinds[crease_angle] = kind
        return self._kinds[crease_angle]

    def facing(self, origin: np.ndarray, direction: np.ndarray | None = None) -> np.ndarray:
        """``unit . (p - origin)`` per face (F,), ``p`` any point of its plane: negative where
        the face is front-facing, its magnitude how squarely; ``unit . direction`` for an
        orthographic camera's view axis ``direction`` (parallel rays)."""
        # in double precision, a block of faces at a time (no (F, 3) double-precision copy)
        at = np.asarray(origin if direction is None else direction, np.float64).reshape(3)
        out = np.empty(len(self.offset))
        for c in range(0, len(out), FACES):
            dot = self.unit[c : c + FACES].astype(np.float64) @ at
            out[c : c + FACES] = dot if direction is not None else self.offset[c : c + FACES] - dot
        return out


#: The last scene's topology: one ``(key, buffers, topology)`` entry, replaced as a whole (a
#: thread reads one entry, never a mix of two) (:func:`topology`).
_LAST: list = [None]


def topology(table: ObjectTable, pairs: np.ndarray | None = None) -> Topology:
    """The :class:`Topology` of every mesh in ``table``, kept for the next call while the
    meshes' vertex and face buffers are the same Dr.Jit arrays: a mesh whose positions are
    updated (``mi.traverse``) gets a new buffer, hence a new topology. The cached entry holds
    the buffers it was built from so that their Dr.Jit indices are not reused meanwhile.
    ``pairs``: the object pairs whose intersection lines a new topology starts with
    (:meth:`Topology.of`; a kept one adds others when asked, :meth:`Topology.search`)."""
    key_t, buffers = _mesh_key(table)
    entry = _LAST[0]
    if entry is not None and entry[0] == key_t:
        return entry[2]
    entry = _LAST[0] = None  # the old one's memory first
    early = _take_early(key_t)
    topo = early if isinstance(early, Topology) else Topology.of(table, pairs, early)
    del early
    release_freed_memory()
    _LAST[0] = (key_t, buffers, topo)
    return topo


#: The first stage of a build (or a whole one) started on another thread
#: (:func:`prefetch_topology`): one ``(key, thread, holder, buffers)``, ``holder["early"]`` its
#: result once done (:func:`_early_stage`'s, or a :class:`Topology`; ``buffers``:
#: the meshes' Dr.Jit buffers, held so that their indices in ``key`` are not reused).
_EARLY: list = [None]


def prefetch_topology(
    table: ObjectTable,
    pairs: np.ndarray | None = None,
    whole: bool = False,
    crease_angle: float | None = None,
) -> bool:
    """Start the part of :func:`topology`'s build for ``table`` that reads only the vertex
    positions (:func:`_early_stage`: the intersection search of ``pairs``, then the weld; with
    ``whole``, the whole build, and the edges' kinds at ``crease_angle`` when given,
    :meth:`Topology.static_kinds`) on a thread of its own, and return at once: whether it started
    (not when the topology is kept already or under way, ``table`` has no mesh, or another one
    is still running; one of other meshes that is done is dropped). That part is numpy and
    SciPy work, which leaves Python's lock to the calling thread most of the time, so a render
    started meanwhile (Dr.Jit waits for its kernels without that lock) runs beside it; its
    result (the segments and the welded ids, a few bytes a vertex; or the whole topology,
    some 60 bytes a face) waits for the next :func:`topology` of the same meshes, which goes
    on from it (or takes it)."""
    key_t, buffers = _mesh_key(table)
    entry, pending = _LAST[0], _EARLY[0]
    if pending is not None and pending[0] != key_t and not pending[1].is_alive():
        pending = _EARLY[0] = None  # a finished one of other meshes, never taken
    if not key_t or pending is not None or (entry is not None and entry[0] == key_t):
        return False
    soup = list(mesh_arrays(table))  # Dr.Jit is read on this thread only
    holder: dict = {}

    def run() -> None:
        # the arrays handed over, not kept here: the build drops each one when it is done
        build = Topology.from_soup if whole else _early_stage
        try:
            holder["early"] = build(soup.pop(0), soup.pop(0), soup.pop(0), pairs)
            if whole and crease_angle is not None:  # the first view's classification
                holder["early"].static_kinds(crease_angle)
        except BaseException:  # the build starts over on the caller's thread
            pass

    thread = threading.Thread(target=run, name="mi-npr topology", daemon=True)
    _EARLY[0] = (key_t, thread, holder, buffers)
    thread.start()
    return True


def wait_for_topology() -> None:
    """Return once no :func:`prefetch_topology` is running (what follows then does not add
    its memory to that work's)."""
    if _EARLY[0] is not None:
        _EARLY[0][1].join()


def _take_early(key: tuple) -> tuple | None:
    """The prefetched first stage of the meshes ``key``, waited for (``None``: there is none,
    or it failed); one of other meshes is waited for and dropped."""
    pending, _EARLY[0] = _EARLY[0], None
    if pending is None:
        return None
    pending[1].join()
    return pending[2].get("early") if pending[0] == key else None


def _mesh_key(table: ObjectTable) -> tuple[tuple, list]:
    """What identifies the meshes of ``table`` for :func:`topology`'s entry (per mesh its
    object id and its vertex and face buffers' Dr.Jit indices and sizes), and the buffers."""
    buffers, key = [], []
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if shape.is_mesh():
            vp, fb = shape.vertex_positions_buffer(), shape.faces_buffer()
            buffers += [vp, fb]
            key.append((oid, vp.index, fb.index, dr.width(vp), dr.width(fb)))
    return tuple(key), buffers


def forget_topology(table: ObjectTable, view: ViewEdges | None = None) -> None:
    """Drop the :class:`Topology` that :func:`topology` keeps, if it is that of ``table``'s
    meshes (a scene that no other view will be drawn from: its memory is handed back); a
    ``view`` of it still to be read keeps only what its rows need
    (:meth:`Topology.rows_only`)."""
    entry = _LAST[0]
    if entry is not None and entry[0] == _mesh_key(table)[0]:
        _LAST[0] = None
        if view is not None and view.topo is entry[2]:
            view.topo = view.topo.rows_only()
        del entry
        release_freed_memory()


class ViewEdges:
    """The feature edges of one view (module docstring), their rows made on demand
    (:meth:`take`): the mesh edges ``edge`` (indices into the :class:`Topology`'s edges) with
    their ``kind`` and drawn ``face``, then the intersection segments ``cross`` (rows of the
    topology's ``crossings``) with their end nodes ``cross_va``, ``cross_vb`` and drawn face
    ``cross_face``. The full rows of a large model's edges would take ~100 bytes each at once;
    these take ~10. ``first``: the first view of its topology (a one-off extraction, whose
    memory peak counts, rather than one of many views of a scene, which reuse each other's
    buffers)."""

    def __init__(
        self,
        topo: Topology,
        edge: np.ndarray,
        kind: np.ndarray,
        face: np.ndarray,
        cross: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
        first: bool = False,
    ) -> None:
        self.topo, self.edge, self.kind, self.face = topo, edge, kind, face
        z = np.zeros(0, np.int64)
        self.cross, self.cross_va, self.cross_vb, self.cross_face = cross or (z, z, z, z)
        self.first = first

    def __len__(self) -> int:
        return len(self.edge) + len(self.cross)

    def max_node(self) -> int:
        """The largest node id of the edges' ends (-1 for none)."""
        t = self.topo
        m = int(t.keys[self.edge].max(initial=-1)) if len(self.edge) else -1
        if len(self.cross):
            m = max(m, int(self.cross_va.max()), int(self.cross_vb.max()))
        return m

    def take(self, rows: slice) -> FeatureEdges:
        """The full rows of the edges ``rows`` (a slice): :class:`FeatureEdges`."""
        start, stop, step = rows.indices(len(self))
        if step != 1:
            raise ValueError("ViewEdges.take: a slice with step 1")
        stop = max(start, stop)
        n_mesh = len(self.edge)
        t = self.topo
        out = []
        if start < n_mesh:
            m = slice(start, min(stop, n_mesh))
            e, face = self.edge[m], self.face[m]
            f0, f1, two = t.f0[e], t.f1[e], t.counts[e] == 2
            faces = np.zeros((len(e), 2, 2), np.int64)
            faces[:, 0, 0], faces[:, 0, 1] = t.face_oid[f0], t.prim(f0)
            faces[:, 1, 0] = np.where(two, t.face_oid[f1], 0)
            faces[:, 1, 1] = np.where(two, t.prim(f1), 0)
            keys = t.keys[e]
            out.append(
                FeatureEdges(
                    a=t.welded[keys[:, 0]].astype(np.float64),
                    b=t.welded[keys[:, 1]].astype(np.float64),
                    va=keys[:, 0].astype(np.int64),
                    vb=keys[:, 1].astype(np.int64),
                    kind=self.kind[m].astype(np.int64),
                    object_id=t.face_oid[face].astype(np.uint32),
                    prim=t.prim(face).astype(np.uint32),
                    faces=faces,
                )
            )
        if stop > n_mesh:
            x = slice(max(start, n_mesh) - n_mesh, stop - n_mesh)
            rows = self.cross[x]
            p, q, fa, fb = (c[rows] for c in t.crossings[:4])
            va, vb, face = self.cross_va[x], self.cross_vb[x], self.cross_face[x]
            oid = t.face_oid
            faces = np.stack(
                [np.stack([oid[fa], t.prim(fa)], 1), np.stack([oid[fb], t.prim(fb)], 1)], 1
            )
            out.append(
                FeatureEdges(
                    a=p,
                    b=q,
                    va=va,
                    vb=vb,
                    kind=np.full(len(p), KINDS.index("intersection"), np.int64),
                    object_id=oid[face].astype(np.uint32),
                    prim=t.prim(face).astype(np.uint32),
                    faces=faces.astype(np.int64),
                )
            )
        if not out:
            return FeatureEdges.empty()
        return out[0] if len(out) == 1 else _concat(out[0], out[1])


def view_edges(
    table: ObjectTable,
    origin: np.ndarray,
    crease_angle: float = 134.0,
    intersect: bool | np.ndarray = True,
    direction: np.ndarray | None = None,
) -> ViewEdges:
    """The feature edges of every mesh in ``table`` seen from ``origin`` (module docstring),
    with the ``intersection`` lines between different meshes when ``intersect`` (``True``:
    every pair of meshes; an array (K, 2) of object ids: those pairs), their rows made on
    demand (:class:`ViewEdges`); ``direction``: the view axis of an orthographic camera, whose
    rays are parallel (a face is front-facing where ``n . direction < 0``)."""
    pairs = None
    if not isinstance(intersect, bool):
        pairs = np.asarray(intersect, np.int64).reshape(-1, 2)
    elif not intersect:
        pairs = np.zeros((0, 2), np.int64)
    topo = topology(table, pairs)
    zi = np.zeros(0, np.int64)
    if len(topo.face_oid) == 0:
        return ViewEdges(topo, zi, zi.astype(np.int8), zi)
    first = topo.views == 0
    topo.views += 1
    d = topo.facing(origin, direction)
    # front-facing tests as byte gathers over every edge (a block of edges at a time: bounded
    # temporaries); the values only for the drawn ones
    neg, pos = d < 0, d > 0
    static = topo.static_kinds(crease_angle)
    parts: dict[str, list[np.ndarray]] = {"e": [], "kind": [], "face": []}
    for c in range(0, len(static), EDGE_BLOCK):
        f0, f1 = topo.f0[c : c + EDGE_BLOCK], topo.f1[c : c + EDGE_BLOCK]
        flip, two = topo.flip[c : c + EDGE_BLOCK], topo.counts[c : c + EDGE_BLOCK] == 2
        front0 = neg[f0]
        front1 = np.where(flip, pos[f1], neg[f1])  # the turned normal's sign
        kind = static[c : c + EDGE_BLOCK].copy()
        kind[two & (front0 != front1)] = _SIL
        e = np.flatnonzero(kind >= 0)
        f0, f1, two = f0[e], f1[e], two[e]
        # the face drawn: the one facing the camera more
        d0, d1 = d[f0], np.where(flip[e], -d[f1], d[f1])
        parts["face"].append(np.where(two & (d1 < d0), f1, f0))
        parts["e"].append(e + c)
        parts["kind"].append(kind[e])
    del neg, pos
    e, kind, face = (np.concatenate(parts[k]) for k in ("e", "kind", "face"))
    cross = None
    if pairs is None or len(pairs):
        topo.search(table, pairs)
        rows, va, vb = topo.crossing_rows(pairs)
        # each end lies on both planes: the plane's facing value there is the face's
        fa, fb = topo.crossings[2][rows], topo.crossings[3][rows]
        cross = (rows, va, vb, np.where(d[fb] < d[fa], fb, fa))
    del d, parts
    if first:
        release_freed_memory()  # the temporaries over every face and edge
    return ViewEdges(topo, e, kind, face, cross, first)


def feature_edges(
    table: ObjectTable,
    origin: np.ndarray,
    crease_angle: float = 134.0,
    intersect: bool | np.ndarray = True,
    direction: np.ndarray | None = None,
) -> FeatureEdges:
    """The feature edges of every mesh in ``table`` seen from ``origin`` (module docstring),
    with the ``intersection`` lines between different meshes when ``intersect``: every row of
    :func:`view_edges` at once."""
    return view_edges(table, origin, crease_angle, intersect, direction).take(slice(None))


def _concat(x: FeatureEdges, y: FeatureEdges) -> FeatureEdges:
    return FeatureEdges(
        *(np.concatenate([getattr(x, k), getattr(y, k)]) for k in x.__dataclass_fields__)
    )


def _orthographic(cam: Projection) -> np.ndarray:
    """World -> (film x / width, film y / height, depth, 1) of Mitsuba's orthographic camera
    (4x4, column vectors): its camera space spans ``x`` in [-1, 1] (+x to the left) and ``y``
    in [-1 / aspect, 1 / aspect] over the film, before ``to_world``'s scale; the depth is the
    distance along the view axis from the camera's origin, as the ``Z`` layer's."""
    inv = np.linalg.inv(cam.to_world)
    w, h = cam.resolution
    unit = np.array([0.0, 0.0, 0.0, 1.0])
    f = cam.forward
    return np.stack(
        [
            0.5 * (unit - inv[0]),
            0.5 * (unit - (w / h) * inv[1]),
            np.append(f, -f @ cam.origin),
            unit,
        ]
    )


def homogeneous(m: Any, x: Any, y: Any, z: Any) -> list:
    """The rows of the 4x4 matrix ``m`` applied to the points ``(x, y, z, 1)``: ``x m[r][0] + y
    m[r][1] + z m[r][2] + m[r][3]`` for each row ``r``, summed in that order, of numpy or Dr.Jit
    arrays alike (so that both give the same bits)."""
    return [x * m[r][0] + y * m[r][1] + z * m[r][2] + m[r][3] for r in range(4)]


class Projector:
    """World -> film for a perspective (or thin-lens: through its lens centre) or an
    orthographic sensor: ``clip(P)`` homogeneous coordinates, where the film position is
    ``(X / W * width, Y / W * height)``; the depth along the view axis (the ``Z`` layer's) is
    ``W`` for a perspective camera and the third coordinate for an orthographic one (whose
    ``W`` is 1). ``ortho``: the camera is orthographic; its rays run along ``forward`` from
    the near plane."""

    def __init__(self, sensor: mi.Sensor) -> None:
        cam = projection_of(sensor)
        ndc = world_to_ndc(cam)
        self.ortho = ndc is None and cam.kind == "orthographic"
        if ndc is None and not self.ortho:
            raise ParameterError(
                f"strokes: the {cam.kind} camera is not supported "
                "(a perspective, thinlens or orthographic one is)"
            )
        self.camera = cam
        self.width, self.height = cam.resolution
        self.near = float(cam.near_clip)
        self.matrix = _orthographic(cam) if self.ortho else ndc
        self.origin = cam.origin
        self.forward = cam.forward
        #: The row of :meth:`clip`'s coordinates that holds the depth.
        self.depth_row = 2 if self.ortho else 3

    def clip(self, p: np.ndarray) -> np.ndarray:
        """Homogeneous coordinates (..., 4) of world points ``p`` (..., 3): ``X, Y`` scaled so
        that ``X / W`` is the film's ``x / width``, and ``W`` the depth."""
        p = np.asarray(p, np.float64)
        # one row at a time: numpy's matmul of (N, 3) by (3, 3) was several times slower
        return np.stack(homogeneous(self.matrix, p[..., 0], p[..., 1], p[..., 2]), -1)

    def film(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions (..., 2) and depths (...) of world points ``p`` (..., 3)."""
        return self.film_of(self.clip(p))

    def film_of(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions (..., 2) and depths (...) of homogeneous points ``h`` (..., 4)."""
        w = h[..., 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = np.stack([h[..., 0] / w * self.width, h[..., 1] / w * self.height], -1)
        return xy, h[..., self.depth_row]
