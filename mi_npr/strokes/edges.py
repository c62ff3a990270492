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
   sign). Normals follow the winding; where two faces wind the shared edge the same way (an
   inconsistently oriented mesh) the second face's normal is flipped for this edge.
2. ``border``: one face (the edge of an open surface).
3. ``material``: two faces of different objects (the objects meet along the edge; an object
   boundary, whether or not their BSDFs differ).
4. ``crease``: two faces whose dihedral angle ``180 - angle(n0, n1)`` is below
   ``crease_angle`` degrees (Freestyle's definition, the ``lines`` drawing's: coplanar faces
   180, a cube's edges 90; 0 turns creases off); also every edge of three or more faces (a
   non-manifold fold that no dihedral angle describes).

5. ``intersection``: where triangles of two different meshes cut each other
   (:mod:`mi_npr.strokes.intersect`); these edges are not mesh edges: their ends are nodes of
   their own, welded among themselves.

Other edges (smooth, coplanar) are not drawn. Each edge is drawn with one face, the one that
*faces the camera more* (the smaller ``n . (a - o) / (|n| |a - o|)``; for a silhouette, the
front face; for a border, its face): that face's object and primitive index are the edge's.

**Projection** (:class:`Projector`): Mitsuba's perspective camera (:mod:`mi_npr.projection`'s
matrices) in homogeneous coordinates. A 3-D segment is clipped to the view frustum (the near
plane and the image frame) in homogeneous coordinates, where every bound is linear in the
segment's parameter, so the clipped ends lie exactly on the frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import drjit as dr
import mitsuba as mi
import numpy as np

from ..camera import projection_of
from ..errors import ParameterError
from ..projection import world_to_ndc
from ..scene import ObjectTable
from .intersect import intersections
from .model import KINDS

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


def mesh_arrays(table: ObjectTable) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every mesh of the object table as one triangle soup: vertex positions (V, 3) float64,
    faces (F, 3) into them (int32; int64 past 2**31 vertices), and each face's object id and
    primitive index (F,) int32, the faces of one object contiguous, objects in increasing
    id."""
    vs, fs, oids, prims = [], [], [], []
    base = 0
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if not shape.is_mesh():
            continue
        # the mesh's own buffers (world space, flat): no kernel per shape
        v = np.asarray(shape.vertex_positions_buffer().numpy(), np.float64).reshape(-1, 3)
        f = np.asarray(shape.faces_buffer().numpy(), np.int64).reshape(-1, 3)
        if len(f) == 0:
            continue
        vs.append(v)
        fs.append(f + base)
        oids.append(np.full(len(f), oid, np.int32))
        prims.append(np.arange(len(f), dtype=np.int32))
        base += len(v)
    if not fs:
        z = np.zeros(0, np.int32)
        return np.zeros((0, 3)), np.zeros((0, 3), np.int32), z, z
    faces = np.concatenate(fs)
    if base < 2**31:  # half the memory of the largest array
        faces = faces.astype(np.int32)
    return np.concatenate(vs), faces, np.concatenate(oids), np.concatenate(prims)


def weld(v: np.ndarray, tolerance: float) -> np.ndarray:
    """A welded vertex id for each row of ``v`` (V, 3): vertices closer than ``tolerance``
    (transitively) share one id, numbered 0..K-1."""
    if len(v) == 0:
        return np.zeros(0, np.int64)
    # scipy's spatial and sparse modules take ~0.2 s to import: only scenes with meshes pay it
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(v).query_pairs(tolerance, output_type="ndarray")
    n = len(v)
    if len(pairs) == 0:
        return np.arange(n, dtype=np.int64)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(g, directed=False)
    return labels.astype(np.int64)


@dataclass(eq=False)
class Topology:
    """What of the feature edges does not depend on the camera: the triangle soup
    (:func:`mesh_arrays`), its unit face normals ``unit`` (0 for a degenerate face) and the
    planes' offsets ``offset = unit . p0``, the welded vertices (their first
    occurrence's position ``welded``), and per welded edge ``E``: its ends ``keys`` (E, 2), its
    face count ``counts``, its first two faces ``f0``, ``f1`` (``f1 = f0`` with one face),
    ``flip`` (the two faces wind the edge the same way: ``f1``'s normal is turned for it) and
    ``cos_n``, the cosine between the two (turned) normals (1 where undefined). The
    intersection segments (:func:`~mi_npr.strokes.intersect.intersections`) are found on first
    use."""

    v: np.ndarray
    f: np.ndarray
    face_oid: np.ndarray
    face_prim: np.ndarray
    unit: np.ndarray
    offset: np.ndarray
    size: float
    welded: np.ndarray
    keys: np.ndarray
    counts: np.ndarray
    f0: np.ndarray
    f1: np.ndarray
    flip: np.ndarray
    cos_n: np.ndarray
    crossings: tuple[np.ndarray, ...] | None = None
    _two: np.ndarray | None = None
    _kinds: dict = field(default_factory=dict)

    @classmethod
    def of(cls, v: np.ndarray, f: np.ndarray, face_oid: np.ndarray, face_prim: np.ndarray):
        """The topology of a triangle soup (class docstring)."""
        if len(f) == 0:
            z, z3 = np.zeros(0, np.int64), np.zeros((0, 3))
            zi = z.astype(np.int32)
            return cls(
                v,
                f,
                z,
                z,
                z3,
                z[:0] * 0.0,
                1.0,
                z3,
                np.zeros((0, 2), np.int32),
                zi,
                zi,
                zi,
                z.astype(bool),
                z * 0.0,
            )
        size = float(np.linalg.norm(v.max(0) - v.min(0))) or 1.0
        wid = weld(v, WELD * size)
        n_welded = int(wid.max()) + 1
        # half-edges (from, to) and their face, in 32 bits (memory: 3 per face); one sort of
        # a 64-bit key groups each edge's
        fw = wid.astype(np.int32)[f]  # welded corners (F, 3)
        hu = fw.reshape(-1)
        hv = fw[:, [1, 2, 0]].reshape(-1)
        hface = np.repeat(np.arange(len(f), dtype=np.int32), 3)
        del fw
        ok = hu != hv  # a face collapsed by welding has no edge there
        if not ok.all():
            hu, hv, hface = hu[ok], hv[ok], hface[ok]
        del ok
        forward = hu < hv
        lo, hi = np.minimum(hu, hv), np.maximum(hu, hv)
        del hu, hv
        key = lo.astype(np.int64) * n_welded + hi
        order = np.argsort(key, kind="stable")
        key = key[order]
        head = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
        del key
        counts = np.diff(np.append(head, len(order))).astype(np.int32)
        h0 = order[head]
        h1 = np.where(counts >= 2, order[np.minimum(head + 1, len(order) - 1)], h0)
        del order, head
        f0, f1 = hface[h0], hface[h1]
        flip = forward[h0] == forward[h1]
        keys = np.stack([lo[h0], hi[h0]], 1)
        del hface, forward, lo, hi, h0, h1
        # unit normals and plane offsets, a block of faces at a time (bounded temporaries)
        unit = np.empty((len(f), 3))
        offset = np.empty(len(f))
        for c in range(0, len(f), 1 << 20):
            fc = f[c : c + (1 << 20)]
            p0 = v[fc[:, 0]]
            n = np.cross(v[fc[:, 1]] - p0, v[fc[:, 2]] - p0)
            length = np.linalg.norm(n, axis=1)
            unit[c : c + len(fc)] = n / np.where(length > 0, length, np.inf)[:, None]
            offset[c : c + len(fc)] = np.einsum("ij,ij->i", unit[c : c + len(fc)], p0)
        # cos of the (turned) normals, a column at a time; a degenerate face: 1 (no crease)
        cos_n = np.zeros(len(f0))
        for k in range(3):
            col = unit[:, k]
            cos_n += col[f0] * col[f1]
        cos_n = np.where(flip, -cos_n, cos_n)
        degenerate = ~np.any(unit != 0, axis=1)
        cos_n[degenerate[f0] | degenerate[f1]] = 1.0
        rep = np.zeros(n_welded, np.int64)
        rep[wid[::-1]] = np.arange(len(wid))[::-1]
        return cls(
            v,
            f,
            face_oid,
            face_prim,
            unit,
            offset,
            size,
            v[rep],
            keys,
            counts,
            f0,
            f1,
            flip,
            cos_n,
        )

    @property
    def two(self) -> np.ndarray:
        """The edges of exactly two faces (E,) bool."""
        if self._two is None:
            self._two = self.counts == 2
        return self._two

    def static_kinds(self, crease_angle: float) -> np.ndarray:
        """Each edge's kind (E,) int8 as far as it does not depend on the camera: crease,
        material or border (module docstring), -1 for none (a silhouette overrides them)."""
        if crease_angle not in self._kinds:
            # dihedral < crease_angle  <=>  angle(n0, n1) > 180 - crease_angle
            crease_cos = math.cos(math.radians(180.0 - crease_angle))
            crease = (crease_angle > 0) & (self.cos_n < crease_cos)
            kind = np.full(len(self.counts), -1, np.int8)
            kind[self.counts >= 3] = _CREASE
            kind[self.two & crease] = _CREASE
            kind[self.two & (self.face_oid[self.f0] != self.face_oid[self.f1])] = _MATERIAL
            kind[self.counts == 1] = _BORDER
            self._kinds = {crease_angle: kind}  # one angle kept: the memory of one array
        return self._kinds[crease_angle]

    def facing(self, origin: np.ndarray) -> np.ndarray:
        """``unit . (p - origin)`` per face (F,), ``p`` any point of its plane: negative where
        the face is front-facing, its magnitude how squarely."""
        return self.offset - self.unit @ np.asarray(origin, np.float64).reshape(3)


#: The last scene's topology: one ``(key, buffers, topology)`` entry, replaced as a whole (a
#: thread reads one entry, never a mix of two) (:func:`topology`).
_LAST: list = [None]


def topology(table: ObjectTable) -> Topology:
    """The :class:`Topology` of every mesh in ``table``, kept for the next call while the
    meshes' vertex and face buffers are the same Dr.Jit arrays: a mesh whose positions are
    updated (``mi.traverse``) gets a new buffer, hence a new topology. The cached entry holds
    the buffers it was built from so that their Dr.Jit indices are not reused meanwhile."""
    buffers, key = [], []
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if shape.is_mesh():
            vp, fb = shape.vertex_positions_buffer(), shape.faces_buffer()
            buffers += [vp, fb]
            key.append((oid, vp.index, fb.index, dr.width(vp), dr.width(fb)))
    key_t = tuple(key)
    entry = _LAST[0]
    if entry is not None and entry[0] == key_t:
        return entry[2]
    entry = _LAST[0] = None  # the old one's memory first
    topo = Topology.of(*mesh_arrays(table))
    _LAST[0] = (key_t, buffers, topo)
    return topo


def feature_edges(
    table: ObjectTable, origin: np.ndarray, crease_angle: float = 134.0, intersect: bool = True
) -> FeatureEdges:
    """The feature edges of every mesh in ``table`` seen from ``origin`` (module docstring),
    with the ``intersection`` lines between different meshes when ``intersect``."""
    topo = topology(table)
    if len(topo.f) == 0:
        return FeatureEdges.empty()
    d = topo.facing(origin)
    # front-facing tests as byte gathers over every edge; the values only for the drawn ones
    neg, pos = d < 0, d > 0
    front0 = neg[topo.f0]
    front1 = np.where(topo.flip, pos[topo.f1], neg[topo.f1])  # the turned normal's sign
    kind = topo.static_kinds(crease_angle).copy()
    kind[topo.two & (front0 != front1)] = _SIL
    e = np.flatnonzero(kind >= 0)
    f0, f1, two = topo.f0[e], topo.f1[e], topo.two[e]
    # the face drawn: the one facing the camera more
    d0, d1 = d[f0], np.where(topo.flip[e], -d[f1], d[f1])
    face = np.where(two & (d1 < d0), f1, f0)
    o0, o1 = topo.face_oid[f0], topo.face_oid[f1]
    faces = np.zeros((len(e), 2, 2), np.int64)
    faces[:, 0, 0], faces[:, 0, 1] = o0, topo.face_prim[f0]
    faces[:, 1, 0] = np.where(two, o1, 0)
    faces[:, 1, 1] = np.where(two, topo.face_prim[f1], 0)
    keys = topo.keys[e]
    mesh = FeatureEdges(
        a=topo.welded[keys[:, 0]],
        b=topo.welded[keys[:, 1]],
        va=keys[:, 0],
        vb=keys[:, 1],
        kind=kind[e],
        object_id=topo.face_oid[face].astype(np.uint32),
        prim=topo.face_prim[face].astype(np.uint32),
        faces=faces,
    )
    if not intersect:
        return mesh
    return _concat(mesh, _intersection_edges(topo, d))


def _intersection_edges(topo: Topology, d: np.ndarray) -> FeatureEdges:
    """The ``intersection`` edges (:mod:`mi_npr.strokes.intersect`), their ends welded into
    nodes numbered after the mesh vertices'; ``d``: :meth:`Topology.facing`."""
    if topo.crossings is None:
        p, q, fa, fb = intersections(topo.v, topo.f, topo.face_oid)
        node = weld(np.concatenate([p, q]), WELD * topo.size) + len(topo.welded)
        va, vb = node[: len(p)], node[len(p) :]
        keep = va != vb
        topo.crossings = (p[keep], q[keep], fa[keep], fb[keep], va[keep], vb[keep])
    p, q, fa, fb, va, vb = topo.crossings
    if not len(p):
        return FeatureEdges.empty()
    # each end lies on both planes: the plane's facing value there is the face's
    face = np.where(d[fb] < d[fa], fb, fa)
    oid, prim = topo.face_oid, topo.face_prim
    faces = np.stack([np.stack([oid[fa], prim[fa]], 1), np.stack([oid[fb], prim[fb]], 1)], 1)
    return FeatureEdges(
        a=p,
        b=q,
        va=va,
        vb=vb,
        kind=np.full(len(p), KINDS.index("intersection"), np.int64),
        object_id=oid[face].astype(np.uint32),
        prim=prim[face].astype(np.uint32),
        faces=faces.astype(np.int64),
    )


def _concat(x: FeatureEdges, y: FeatureEdges) -> FeatureEdges:
    return FeatureEdges(
        *(np.concatenate([getattr(x, k), getattr(y, k)]) for k in x.__dataclass_fields__)
    )


class Projector:
    """World -> film for a perspective sensor: ``clip(P)`` homogeneous coordinates, where the
    film position is ``(X / W * width, Y / W * height)`` and ``W`` the depth along the view
    axis (the ``Z`` layer's)."""

    def __init__(self, sensor: mi.Sensor) -> None:
        cam = projection_of(sensor)
        ndc = world_to_ndc(cam)
        if ndc is None:
            raise ParameterError(
                f"strokes: the {cam.kind} camera is not supported (a perspective camera is)"
            )
        self.camera = cam
        self.width, self.height = cam.resolution
        self.near = float(cam.near_clip)
        self.matrix = ndc
        self.origin = cam.origin

    def clip(self, p: np.ndarray) -> np.ndarray:
        """Homogeneous coordinates (..., 4) of world points ``p`` (..., 3): ``X, Y`` scaled so
        that ``X / W`` is the film's ``x / width``, and ``W`` the depth."""
        p = np.asarray(p, np.float64)
        m = self.matrix
        out = np.empty((*p.shape[:-1], 4))
        # one row at a time: numpy's matmul of (N, 3) by (3, 3) was several times slower
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        for r in range(4):
            out[..., r] = x * m[r, 0] + y * m[r, 1] + z * m[r, 2] + m[r, 3]
        return out

    def film(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions (..., 2) and depths (...) of world points ``p`` (..., 3)."""
        return self.film_of(self.clip(p))

    def film_of(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions (..., 2) and depths (...) of homogeneous points ``h`` (..., 4)."""
        w = h[..., 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = np.stack([h[..., 0] / w * self.width, h[..., 1] / w * self.height], -1)
        return xy, w

    def clip_segments(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The parameter interval ``[lo, hi]`` of each segment ``a + s (b - a)`` (E, 3) inside
        the view frustum (in front of the near plane, inside the image frame); ``lo > hi`` where
        none of it is."""
        return self.clip_homogeneous(self.clip(a), self.clip(b))

    def clip_homogeneous(self, ha: np.ndarray, hb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`clip_segments` of segments given by their ends' homogeneous coordinates
        ``ha``, ``hb`` (E, 4) (:meth:`clip`; the map is linear, so the point of parameter ``s``
        is ``ha + s (hb - ha)``)."""
        lo = np.zeros(len(ha))
        hi = np.ones(len(ha))
        x0, y0, w0 = ha[:, 0], ha[:, 1], ha[:, 3]
        x1, y1, w1 = hb[:, 0], hb[:, 1], hb[:, 3]
        for f0, f1 in (
            (w0 - self.near, w1 - self.near),
            (x0, x1),
            (w0 - x0, w1 - x1),
            (y0, y1),
            (w0 - y0, w1 - y1),
        ):
            d = f1 - f0
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -f0 / d
            lo = np.where(d > 0, np.maximum(lo, t), lo)
            hi = np.where(d < 0, np.minimum(hi, t), hi)
            out = (d == 0) & (f0 < 0)
            lo = np.where(out, 2.0, lo)
        return lo, hi
