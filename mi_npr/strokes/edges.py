"""Object-space feature edges of a scene's meshes, and the camera's projection of them.

**Topology.** Every mesh (``shape.is_mesh()``: Mitsuba's ``obj``, ``ply``, ``cube``,
``rectangle``...) gives its vertex positions (world space: Mitsuba stores them transformed)
and faces. Vertices of *all* meshes closer than ``1e-6`` of the scene's size
are welded into one (a mesh split at UV seams, or two objects that share an edge, such as a
room's floor and wall); an edge is a pair of welded vertices, its faces the triangles that use
it. Building it costs ``O(F log F)`` for ``F`` triangles.

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
from dataclasses import dataclass

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
    faces (F, 3) int64 into them, and each face's object id and primitive index (F,)."""
    vs, fs, oids, prims = [], [], [], []
    base = 0
    for oid in sorted(table.shapes):
        shape = table.shapes[oid]
        if not shape.is_mesh():
            continue
        # the mesh interface, not mi.traverse: a ``rectangle`` is a mesh without the
        # ``vertex_positions`` parameter
        nv, nf = int(shape.vertex_count()), int(shape.face_count())
        pos = shape.vertex_position(dr.arange(mi.UInt32, nv))
        idx = shape.face_indices(dr.arange(mi.UInt32, nf))
        v = np.stack([np.asarray(c.numpy(), np.float64) for c in (pos.x, pos.y, pos.z)], -1)
        f = np.stack([np.asarray(c.numpy(), np.int64) for c in (idx.x, idx.y, idx.z)], -1)
        if len(f) == 0:
            continue
        vs.append(v)
        fs.append(f + base)
        oids.append(np.full(len(f), oid, np.int64))
        prims.append(np.arange(len(f), dtype=np.int64))
        base += len(v)
    if not fs:
        z = np.zeros(0, np.int64)
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), z, z
    return np.concatenate(vs), np.concatenate(fs), np.concatenate(oids), np.concatenate(prims)


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


def feature_edges(
    table: ObjectTable, origin: np.ndarray, crease_angle: float = 134.0, intersect: bool = True
) -> FeatureEdges:
    """The feature edges of every mesh in ``table`` seen from ``origin`` (module docstring),
    with the ``intersection`` lines between different meshes when ``intersect``."""
    v, f, face_oid, face_prim = mesh_arrays(table)
    if len(f) == 0:
        return FeatureEdges.empty()
    size = float(np.linalg.norm(v.max(0) - v.min(0))) or 1.0
    wid = weld(v, WELD * size)
    fw = wid[f]  # welded corners (F, 3)
    # half-edges: (F * 3) of (from, to), face index
    hu = fw.reshape(-1)
    hv = fw[:, [1, 2, 0]].reshape(-1)
    hface = np.repeat(np.arange(len(f)), 3)
    ok = hu != hv  # a face collapsed by welding has no edge there
    hu, hv, hface = hu[ok], hv[ok], hface[ok]
    lo, hi = np.minimum(hu, hv), np.maximum(hu, hv)
    forward = hu < hv
    keys, inverse, counts = np.unique(
        np.stack([lo, hi], 1), axis=0, return_inverse=True, return_counts=True
    )
    inverse = inverse.reshape(-1)
    order = np.argsort(inverse, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    h0 = order[starts]
    h1 = order[np.minimum(starts + 1, len(order) - 1)]
    two = counts >= 2
    f0, f1 = hface[h0], hface[h1]
    # face normals (unnormalised), from the faces' own (unwelded) corners
    p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    nrm = np.cross(p1 - p0, p2 - p0)
    n0 = nrm[f0]
    n1 = np.where((forward[h0] == forward[h1])[:, None], -nrm[f1], nrm[f1])
    # the edge's ends: one representative position per welded vertex (its first occurrence)
    rep = np.zeros(int(wid.max()) + 1, np.int64)
    rep[wid[::-1]] = np.arange(len(wid))[::-1]
    a = v[rep[keys[:, 0]]]
    b = v[rep[keys[:, 1]]]
    view = a - np.asarray(origin, np.float64).reshape(1, 3)
    vlen = np.linalg.norm(view, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        s0 = np.einsum("ij,ij->i", n0, view) / (np.linalg.norm(n0, axis=1) * vlen[:, 0])
        s1 = np.einsum("ij,ij->i", n1, view) / (np.linalg.norm(n1, axis=1) * vlen[:, 0])
        cos_n = np.einsum("ij,ij->i", n0, n1) / (
            np.linalg.norm(n0, axis=1) * np.linalg.norm(n1, axis=1)
        )
    s0, s1 = np.nan_to_num(s0, nan=0.0), np.nan_to_num(s1, nan=0.0)
    front0, front1 = s0 < 0, s1 < 0
    # dihedral < crease_angle  <=>  angle(n0, n1) > 180 - crease_angle
    crease_cos = math.cos(math.radians(180.0 - crease_angle))
    crease = (crease_angle > 0) & (np.nan_to_num(cos_n, nan=1.0) < crease_cos)
    o0, o1 = face_oid[f0], face_oid[f1]
    kind = np.full(len(keys), -1, np.int64)
    is_two = two & (counts == 2)
    kind[counts >= 3] = _CREASE
    kind[is_two & crease] = _CREASE
    kind[is_two & (o0 != o1)] = _MATERIAL
    kind[counts == 1] = _BORDER
    kind[is_two & (front0 != front1)] = _SIL
    keep = kind >= 0
    # the face drawn: the one facing the camera more
    second = two & (s1 < s0)
    face = np.where(second, f1, f0)
    faces = np.zeros((len(keys), 2, 2), np.int64)
    faces[:, 0, 0], faces[:, 0, 1] = o0, face_prim[f0]
    faces[:, 1, 0] = np.where(two, o1, 0)
    faces[:, 1, 1] = np.where(two, face_prim[f1], 0)
    mesh = FeatureEdges(
        a=a[keep],
        b=b[keep],
        va=keys[keep, 0],
        vb=keys[keep, 1],
        kind=kind[keep],
        object_id=face_oid[face[keep]].astype(np.uint32),
        prim=face_prim[face[keep]].astype(np.uint32),
        faces=faces[keep],
    )
    if not intersect:
        return mesh
    return _concat(mesh, _intersection_edges(v, f, face_oid, face_prim, nrm, origin, size, wid))


def _intersection_edges(
    v: np.ndarray,
    f: np.ndarray,
    face_oid: np.ndarray,
    face_prim: np.ndarray,
    nrm: np.ndarray,
    origin: np.ndarray,
    size: float,
    wid: np.ndarray,
) -> FeatureEdges:
    """The ``intersection`` edges (:mod:`mi_npr.strokes.intersect`), their ends welded into
    nodes numbered after the mesh vertices'."""
    p, q, fa, fb = intersections(v, f, face_oid)
    if not len(p):
        return FeatureEdges.empty()
    node = weld(np.concatenate([p, q]), WELD * size) + int(wid.max()) + 1
    va, vb = node[: len(p)], node[len(p) :]
    keep = va != vb
    p, q, fa, fb, va, vb = p[keep], q[keep], fa[keep], fb[keep], va[keep], vb[keep]
    view = p - np.asarray(origin, np.float64).reshape(1, 3)
    with np.errstate(invalid="ignore", divide="ignore"):
        facing = [
            np.nan_to_num(
                np.einsum("ij,ij->i", nrm[g], view) / np.linalg.norm(nrm[g], axis=1), nan=0.0
            )
            for g in (fa, fb)
        ]
    face = np.where(facing[1] < facing[0], fb, fa)
    faces = np.stack(
        [np.stack([face_oid[fa], face_prim[fa]], 1), np.stack([face_oid[fb], face_prim[fb]], 1)], 1
    )
    return FeatureEdges(
        a=p,
        b=q,
        va=va,
        vb=vb,
        kind=np.full(len(p), KINDS.index("intersection"), np.int64),
        object_id=face_oid[face].astype(np.uint32),
        prim=face_prim[face].astype(np.uint32),
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
                f"strokes: a {cam.kind} camera is not supported (a perspective camera is)"
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
        h = p @ self.matrix[:3, :3].T + self.matrix[:3, 3]
        w = p @ self.matrix[3, :3] + self.matrix[3, 3]
        return np.concatenate([h[..., :2], h[..., 2:3], w[..., None]], axis=-1)

    def film(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Film positions (..., 2) and depths (...) of world points ``p`` (..., 3)."""
        h = self.clip(p)
        w = h[..., 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = np.stack([h[..., 0] / w * self.width, h[..., 1] / w * self.height], -1)
        return xy, w

    def clip_segments(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The parameter interval ``[lo, hi]`` of each segment ``a + s (b - a)`` (E, 3) inside
        the view frustum (in front of the near plane, inside the image frame); ``lo > hi`` where
        none of it is."""
        ha, hb = self.clip(a), self.clip(b)
        lo = np.zeros(len(a))
        hi = np.ones(len(a))
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
