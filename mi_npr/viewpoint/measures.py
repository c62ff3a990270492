"""Viewpoint quality measures, eqs. 1-3 of the paper (section 2.1), as pure functions of areas.

Layout: ``areas`` is an array of shape ``(..., n + 1)``: column 0 is the *background* (what no
polygon covers), columns ``1..n`` are the scene's ``n`` polygons (see
:mod:`mi_npr.viewpoint.idbuffer` for how a polygon is numbered), each holding its projected
visible area from one viewpoint. Any leading shape is a batch of viewpoints, and every function
returns one value per viewpoint (shape ``areas.shape[:-1]``). mi-npr fills ``areas`` with pixel
counts of an ID buffer, so the row sum is the image area; the measures only use ratios of areas,
so solid angles work as well. The same table may come as a :class:`SparseAreas` (its cells that
are not 0, what :func:`mi_npr.viewpoint.idbuffer.sparse_areas` gives for large scenes); every
measure reads both and gives the same values.

Choices made where the paper (or the text extracted from it) is ambiguous:

- **Eq. 1** (Plemenos-Benayada): ``I(V) = sum_i ceil(P_i / (P_i + 1)) / n + sum_i P_i / r``.
  ``ceil(P/(P+1))`` is 1 for a visible polygon and 0 otherwise, so the first term is the fraction
  of the scene's polygons that are visible. ``n`` is the total number of polygons of the scene,
  visible or not (``areas.shape[-1] - 1``). ``r``, "the total projected area", is read as the
  area of the whole image (background included, the row sum), as in Plemenos and Benayada's
  paper where ``r`` is the resolution of the image: with ``r = sum_i P_i`` the second term would
  be 1 for every viewpoint that sees anything. So ``I`` lies in ``[0, 2]``.
- **Eq. 2** (Sokolov et al.): ``I(p) = sum_{v in V(p)} |2 pi - sum alpha_i(v)| * sum_{f in F(p)}
  P(f)``. A vertex is visible when one of its faces is visible (``V(p)`` = the vertices of the
  faces in ``F(p)``). The angle sums come from the mesh with its duplicate vertices welded by
  position (:func:`vertex_curvature`). ``sum P(f)`` is taken as a fraction of the image area, so
  the value does not depend on the resolution. On the boundary of an open mesh the defect is
  ``pi - sum alpha`` (the turning angle, so that discrete Gauss-Bonnet holds: with ``2 pi``
  there, a floor's 4 corners would count ``6 pi`` and outweigh everything else). Polygons
  without vertices (non-mesh shapes) add their area to ``sum P(f)`` and no curvature.
- **Eq. 3** (viewpoint entropy, Sbert et al.): ``H = -sum_{i=0}^{N_f} (A_i / A_t) log2(A_i / A_t)``
  with the background as face 0, as the sum from ``i = 0`` says, and ``A_t`` the whole image
  (background included). The logarithm is base 2 (bits), as in Sbert et al.; ``0 log 0 = 0``.

A viewpoint that sees nothing has quality 0 under all three measures (and no error).

>>> import numpy as np
>>> a = np.array([60.0, 20.0, 20.0, 0.0])  # background, 3 polygons, one hidden
>>> float(pb(a)), float(entropy(a))
(1.0666666666666667, 1.3709505944546687)
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, shown

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class SparseAreas:
    """A ``(V, n + 1)`` area table stored as its cells that are not 0: ``values[k]`` is the
    area of polygon ``cols[k]`` (0 = background) from viewpoint ``rows[k]``."""

    rows: np.ndarray
    cols: np.ndarray
    values: np.ndarray
    shape: tuple[int, int]
    #: per viewpoint, the part of column 0 that is one-sided faces seen from behind (not empty
    #: space), where the ID buffers counted it
    back: np.ndarray | None = None

    @classmethod
    def from_dense(cls, areas: np.ndarray) -> SparseAreas:
        a = np.asarray(areas)
        a2 = a.reshape(-1, a.shape[-1])
        r, c = np.nonzero(a2)
        return cls(r, c, a2[r, c], (len(a2), a.shape[-1]))

    def dense(self) -> np.ndarray:
        out = np.zeros(self.shape, np.asarray(self.values).dtype)
        out[self.rows, self.cols] = self.values
        return out

    def merge(self, keep: np.ndarray) -> SparseAreas:
        """The table with the columns where ``keep`` is False added to the background (column
        0) and removed: ``(V, keep.sum())`` (``keep[0]`` must be True)."""
        new = np.cumsum(keep) - 1
        cols = np.where(keep[self.cols], new[self.cols], 0)
        width = int(keep.sum())
        cells, inv = np.unique(self.rows * width + cols, return_inverse=True)
        vals = np.bincount(inv.ravel(), weights=self.values, minlength=len(cells))
        return SparseAreas(cells // width, cells % width, vals, (self.shape[0], width), self.back)


def _check(areas: np.ndarray | SparseAreas) -> tuple[SparseAreas, tuple[int, ...]]:
    """The table as sparse float64 cells, and the leading (viewpoint) shape of the result."""
    if isinstance(areas, SparseAreas):
        sp = areas
        lead: tuple[int, ...] = (sp.shape[0],)
    else:
        raw = np.asarray(areas)
        a = raw.astype(np.float64, copy=False)
        if a.ndim < 1 or a.shape[-1] < 1:
            raise ParameterError(f"areas: expected shape (..., n + 1), got {a.shape}")
        if raw.dtype.kind != "u" and (not np.all(np.isfinite(a)) or np.any(a < 0)):
            raise ParameterError("areas: must be finite and non-negative")  # pixel counts are
        sp, lead = SparseAreas.from_dense(a), a.shape[:-1]
    vals = np.asarray(sp.values, np.float64)
    return SparseAreas(sp.rows, sp.cols, vals, sp.shape), lead


def _row_sums(sp: SparseAreas, where: np.ndarray | None = None) -> np.ndarray:
    w = sp.values if where is None else np.where(where, sp.values, 0.0)
    return np.bincount(sp.rows, weights=w, minlength=sp.shape[0]).astype(np.float64)


def _fraction(numerator: np.ndarray, total: np.ndarray) -> np.ndarray:
    """numerator / total, 0 where total is 0 (a view with no area at all sees nothing)."""
    return np.divide(numerator, total, out=np.zeros_like(numerator), where=total > 0)


def pb(areas: np.ndarray | SparseAreas) -> np.ndarray:
    """Eq. 1 (Plemenos-Benayada): fraction of visible polygons + fraction of the image covered."""
    sp, lead = _check(areas)
    n = sp.shape[1] - 1
    poly = (sp.cols > 0) & (sp.values > 0)
    visible = np.bincount(sp.rows[poly], minlength=sp.shape[0]).astype(np.float64)
    first = visible / n if n else np.zeros_like(visible)
    return (first + _fraction(_row_sums(sp, poly), _row_sums(sp))).reshape(lead)


def entropy(areas: np.ndarray | SparseAreas) -> np.ndarray:
    """Eq. 3 (viewpoint entropy) in bits, background included as face 0."""
    sp, lead = _check(areas)
    total = _row_sums(sp)
    ok = sp.values > 0  # only the faces in view: most of a large scene's are not
    r = sp.rows[ok]
    p = sp.values[ok] / total[r]
    h = -np.bincount(r, weights=p * np.log2(p), minlength=sp.shape[0])
    return h.reshape(lead) + 0.0  # + 0.0: no -0.0


@dataclass(frozen=True)
class Topology:
    """What eq. 2 needs to know about the scene's meshes.

    ``polygon_vertices``: int64 ``(n + 1, 3)``, the (welded, scene-wide) vertex indices of each
    polygon; ``-1`` for the background (row 0) and for polygons without vertices (non-mesh
    shapes). ``vertex_term``: float64 ``(n_vertices,)``, ``|2 pi - sum of the angles at the
    vertex|``.
    """

    polygon_vertices: np.ndarray
    vertex_term: np.ndarray

    @property
    def n_polygons(self) -> int:
        return len(self.polygon_vertices) - 1


def vertex_curvature(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angle defect per vertex (the curvature of Fig. 3), with duplicate vertices welded.

    ``V`` float (m, 3) positions, ``F`` int (k, 3) triangles. Vertices at exactly the same
    position are one vertex (meshes often duplicate them to carry per-face normals or uvs, and
    Mitsuba's ``cube`` has 24 vertices for 8 corners). The defect of an interior vertex is
    ``2 pi - sum of adjacent angles`` (eq. 2). A vertex on the mesh's boundary (on an edge that
    only one triangle uses) gets ``pi - sum of adjacent angles``, its turning angle: the discrete
    Gauss-Bonnet theorem then holds for every mesh, the defects summing to ``2 pi chi`` (``4 pi``
    for a closed sphere-like mesh, ``2 pi`` for a disc, 0 for a torus), and a flat open patch
    (a floor) adds its corners' ``pi / 2``, not ``3 pi / 2`` each. A welded vertex that no
    triangle uses gets 0 (it is not on the surface).

    Returns ``(defect, weld)``: ``defect`` (u,) for the u distinct positions, ``weld`` (m,) maps
    each input vertex to its welded index.
    """
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise ParameterError("faces refer to vertices that do not exist")
    if not len(V):
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    _, weld = np.unique(V.astype(np.float32), axis=0, return_inverse=True)
    weld = weld.ravel().astype(np.int64)
    u = int(weld.max()) + 1
    T = V[F]  # (k, 3 corners, 3)
    angles = np.empty((len(F), 3))
    for c in range(3):
        e1 = T[:, (c + 1) % 3] - T[:, c]
        e2 = T[:, (c + 2) % 3] - T[:, c]
        # atan2 of |cross| and dot: exact near 0 and pi, and 0 (not NaN) for degenerate edges.
        angles[:, c] = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=-1), (e1 * e2).sum(-1))
    Fw = weld[F]
    sums = np.bincount(Fw.ravel(), weights=angles.ravel(), minlength=u)
    used = np.bincount(Fw.ravel(), minlength=u) > 0
    edges = np.sort(np.concatenate([Fw[:, [0, 1]], Fw[:, [1, 2]], Fw[:, [2, 0]]]), axis=1)
    edges = edges[edges[:, 0] != edges[:, 1]]  # a collapsed triangle's zero-length edge
    key, count = np.unique(edges[:, 0] * u + edges[:, 1], return_counts=True)
    border = np.zeros(u, dtype=bool)
    border[key[count == 1] // u] = True
    border[key[count == 1] % u] = True
    full = np.where(border, math.pi, TWO_PI)
    return np.where(used, full - sums, 0.0), weld


def curvature(areas: np.ndarray | SparseAreas, topology: Topology) -> np.ndarray:
    """Eq. 2 (Sokolov): sum of ``|2 pi - sum alpha|`` over visible vertices x visible area."""
    sp, lead = _check(areas)
    n = sp.shape[1] - 1
    if topology.n_polygons != n:
        raise ParameterError(
            f"areas has {n} polygons but the topology describes {topology.n_polygons}"
        )
    R = sp.shape[0]
    nv = len(topology.vertex_term)
    poly = (sp.cols > 0) & (sp.values > 0)
    seen = np.zeros(R)
    if nv:
        verts = topology.polygon_vertices[sp.cols[poly]]  # (k, 3)
        rr = np.repeat(sp.rows[poly], 3)
        vv = verts.ravel()
        ok = vv >= 0
        keys = np.unique(rr[ok].astype(np.int64) * nv + vv[ok])  # each (view, vertex) once
        seen = np.bincount(keys // nv, weights=topology.vertex_term[keys % nv], minlength=R)
    covered = _fraction(_row_sums(sp, poly), _row_sums(sp))
    return (seen * covered).reshape(lead)


#: The measures by name, as the CLI and :func:`mi_npr.viewpoint.quality` know them. Each takes
#: ``(areas, topology)``; only ``curvature`` uses the topology.
MEASURES: dict[str, Callable[[np.ndarray, Topology | None], np.ndarray]] = {
    "pb": lambda a, t: pb(a),
    "curvature": lambda a, t: curvature(a, t),  # type: ignore[arg-type]
    "entropy": lambda a, t: entropy(a),
}


def check_measure(measure: str) -> str:
    if not isinstance(measure, str) or measure not in MEASURES:
        raise ParameterError(f"measure = {shown(measure)}: expected one of {', '.join(MEASURES)}")
    return measure
