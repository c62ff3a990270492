"""Intersection lines: where the triangles of two different meshes cut each other.

**Pairs of triangles.** For every pair of meshes whose bounding boxes overlap, the triangles of
each that reach into the overlap are hashed into a uniform grid over it (cell side: the median
triangle size there, at most ``GRID`` cells per axis); triangles sharing a cell, with
overlapping bounding boxes, are tested. The cost is about ``O(F + P)`` for ``F`` triangles in
the overlaps and ``P`` candidate pairs (``O(F_a F_b)`` at worst, when all triangles crowd into
one cell). Self-intersections of one mesh are not looked for.

**One pair** (the plane-clipping form of Moller's test): each triangle's vertices are put on
either side of the other's plane (a vertex on a plane counts as on its positive side, so a
triangle that only touches a plane does not cut it); a triangle that straddles the other's
plane crosses it along a segment between two of its edges; the two segments lie on the line
of the planes' intersection, and their overlap is the intersection. Coplanar and parallel
triangles give none.

Segments of neighbouring pairs meet where the line crosses a triangle edge; their ends are
welded (as mesh vertices are, :data:`mi_npr.strokes.edges.WELD`) so chaining joins them.
"""

from __future__ import annotations

import numpy as np

#: Most grid cells per axis over the overlap of two meshes.
GRID = 64
#: Candidate pairs tested at once (memory bound).
CHUNK = 1 << 18


def _boxes(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return t.min(1), t.max(1)


def _candidates(ta: np.ndarray, tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of triangles ``ta[i]``, ``tb[j]`` whose bounding boxes overlap, found
    through a uniform grid (module docstring)."""
    alo, ahi = _boxes(ta)
    blo, bhi = _boxes(tb)
    lo = np.maximum(alo.min(0), blo.min(0))
    hi = np.minimum(ahi.max(0), bhi.max(0))
    if np.any(lo > hi):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ia = np.flatnonzero(np.all((alo <= hi) & (ahi >= lo), axis=1))
    ib = np.flatnonzero(np.all((blo <= hi) & (bhi >= lo), axis=1))
    if not len(ia) or not len(ib):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    extent = float(np.max(hi - lo))
    sizes = np.concatenate([(ahi - alo)[ia].max(1), (bhi - blo)[ib].max(1)])
    h = max(float(np.median(sizes)), extent / GRID, 1e-30)
    cells = np.maximum(1, np.ceil((hi - lo) / h).astype(np.int64))

    def expand(idx: np.ndarray, tlo: np.ndarray, thi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c0 = np.clip(np.floor((tlo[idx] - lo) / h).astype(np.int64), 0, cells - 1)
        c1 = np.clip(np.floor((thi[idx] - lo) / h).astype(np.int64), 0, cells - 1)
        span = c1 - c0 + 1
        count = span.prod(1)
        owner = np.repeat(np.arange(len(idx)), count)
        k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
        sx, sy = span[owner, 0], span[owner, 1]
        cx = c0[owner, 0] + k % sx
        cy = c0[owner, 1] + (k // sx) % sy
        cz = c0[owner, 2] + k // (sx * sy)
        key = (cz * cells[1] + cy) * cells[0] + cx
        return idx[owner], key

    a_tri, a_key = expand(ia, alo, ahi)
    b_tri, b_key = expand(ib, blo, bhi)
    order = np.argsort(b_key, kind="stable")
    b_tri, b_key = b_tri[order], b_key[order]
    start = np.searchsorted(b_key, a_key, "left")
    stop = np.searchsorted(b_key, a_key, "right")
    n = stop - start
    pa = np.repeat(a_tri, n)
    pb = b_tri[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    pair = np.unique(pa * len(tb) + pb)
    pa, pb = pair // len(tb), pair % len(tb)
    ok = np.all((alo[pa] <= bhi[pb]) & (ahi[pa] >= blo[pb]), axis=1)
    return pa[ok], pb[ok]


def _crossing(t: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two points where triangles ``t`` (N, 3, 3) cross a plane, given their vertices'
    signed distances ``s`` (N, 3) to it (each triangle straddles it)."""
    pos = s >= 0
    pts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        with np.errstate(invalid="ignore", divide="ignore"):
            w = s[:, a] / (s[:, a] - s[:, b])  # nan where the edge does not cross: unused
            p = t[:, a] + w[:, None] * (t[:, b] - t[:, a])
        pts.append((pos[:, a] != pos[:, b], p))
    cross = np.stack([c for c, _ in pts], 1)
    p = np.stack([q for _, q in pts], 1)
    first = np.argmax(cross, 1)
    second = 2 - np.argmax(cross[:, ::-1], 1)
    rows = np.arange(len(t))
    return p[rows, first], p[rows, second]


def segments(t1: np.ndarray, t2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The intersection of each pair of triangles ``t1[i]``, ``t2[i]`` (N, 3, 3): ``(ok, p,
    q)``, the segment ``p -> q`` (N, 3) where ``ok`` (module docstring)."""
    n1 = np.cross(t1[:, 1] - t1[:, 0], t1[:, 2] - t1[:, 0])
    n2 = np.cross(t2[:, 1] - t2[:, 0], t2[:, 2] - t2[:, 0])
    s2 = np.einsum("nij,nj->ni", t2 - t1[:, :1], n1)  # t2's vertices against t1's plane
    s1 = np.einsum("nij,nj->ni", t1 - t2[:, :1], n2)
    straddle = lambda s: np.any(s >= 0, 1) & np.any(s < 0, 1)  # noqa: E731
    line = np.cross(n1, n2)
    ok = straddle(s1) & straddle(s2) & (np.linalg.norm(line, axis=1) > 0)
    p = np.zeros((len(t1), 3))
    q = np.zeros((len(t1), 3))
    if not ok.any():
        return ok, p, q
    i = np.flatnonzero(ok)
    a0, a1 = _crossing(t1[i], s1[i])
    b0, b1 = _crossing(t2[i], s2[i])
    L = line[i]
    ta0, ta1 = np.einsum("ij,ij->i", a0, L), np.einsum("ij,ij->i", a1, L)
    tb0, tb1 = np.einsum("ij,ij->i", b0, L), np.einsum("ij,ij->i", b1, L)
    swap_a, swap_b = ta1 < ta0, tb1 < tb0
    alo = np.where(swap_a[:, None], a1, a0)
    ahi = np.where(swap_a[:, None], a0, a1)
    blo = np.where(swap_b[:, None], b1, b0)
    bhi = np.where(swap_b[:, None], b0, b1)
    ta_lo, ta_hi = np.minimum(ta0, ta1), np.maximum(ta0, ta1)
    tb_lo, tb_hi = np.minimum(tb0, tb1), np.maximum(tb0, tb1)
    lo = np.where((ta_lo >= tb_lo)[:, None], alo, blo)
    hi = np.where((ta_hi <= tb_hi)[:, None], ahi, bhi)
    good = np.minimum(ta_hi, tb_hi) > np.maximum(ta_lo, tb_lo)
    ok[i] = good
    p[i], q[i] = lo, hi
    return ok, p, q


def intersections(
    v: np.ndarray, f: np.ndarray, face_oid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every intersection segment between triangles of different objects: ends ``p``, ``q``
    (S, 3) and the two faces ``fa``, ``fb`` (S,) (indices into ``f``) it lies on."""
    tris = v[f]
    objects = np.unique(face_oid)
    lo_of = {o: tris[face_oid == o].reshape(-1, 3).min(0) for o in objects}
    hi_of = {o: tris[face_oid == o].reshape(-1, 3).max(0) for o in objects}
    ps, qs, fas, fbs = [], [], [], []
    for k, oa in enumerate(objects):
        for ob in objects[k + 1 :]:
            if np.any(lo_of[oa] > hi_of[ob]) or np.any(lo_of[ob] > hi_of[oa]):
                continue
            ia, ib = np.flatnonzero(face_oid == oa), np.flatnonzero(face_oid == ob)
            pa, pb = _candidates(tris[ia], tris[ib])
            for c in range(0, len(pa), CHUNK):
                fa, fb = ia[pa[c : c + CHUNK]], ib[pb[c : c + CHUNK]]
                ok, p, q = segments(tris[fa], tris[fb])
                ps.append(p[ok])
                qs.append(q[ok])
                fas.append(fa[ok])
                fbs.append(fb[ok])
    if not ps:
        z = np.zeros(0, np.int64)
        return np.zeros((0, 3)), np.zeros((0, 3)), z, z
    return np.concatenate(ps), np.concatenate(qs), np.concatenate(fas), np.concatenate(fbs)
