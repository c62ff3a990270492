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
CHUNK = 1 << 16


def _candidates(
    alo: np.ndarray, ahi: np.ndarray, blo: np.ndarray, bhi: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of triangles of two meshes whose bounding boxes (``alo[i]``,
    ``ahi[i]``) and (``blo[j]``, ``bhi[j]``) overlap, found through a uniform grid (module
    docstring). A pair is reported by the one cell that holds the larger of its two boxes'
    lower corners (no pair twice, no sort to remove duplicates)."""
    lo = np.maximum(alo.min(0), blo.min(0))
    hi = np.minimum(ahi.max(0), bhi.max(0))
    none = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if np.any(lo > hi):
        return none
    ia = np.flatnonzero(np.all((alo <= hi) & (ahi >= lo), axis=1))
    ib = np.flatnonzero(np.all((blo <= hi) & (bhi >= lo), axis=1))
    if not len(ia) or not len(ib):
        return none
    extent = float(np.max(hi - lo))
    sizes = np.concatenate([(ahi[ia] - alo[ia]).max(1), (bhi[ib] - blo[ib]).max(1)])
    h = max(float(np.median(sizes)), extent / GRID, 1e-30)
    cells = np.maximum(1, np.ceil((hi - lo) / h).astype(np.int64))

    def cell(x: np.ndarray) -> np.ndarray:
        return np.clip(np.floor((x - lo) / h).astype(np.int64), 0, cells - 1)

    def flat(c: np.ndarray) -> np.ndarray:
        return (c[..., 2] * cells[1] + c[..., 1]) * cells[0] + c[..., 0]

    def expand(idx: np.ndarray, tlo: np.ndarray, thi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c0, c1 = cell(tlo[idx]), cell(thi[idx])
        span = c1 - c0 + 1
        count = span.prod(1)
        owner = np.repeat(np.arange(len(idx)), count)
        k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
        sx, sy = span[owner, 0], span[owner, 1]
        c = np.stack([k % sx, (k // sx) % sy, k // (sx * sy)], 1) + c0[owner]
        return idx[owner], flat(c)

    a_tri, a_key = expand(ia, alo, ahi)
    b_tri, b_key = expand(ib, blo, bhi)
    order = np.argsort(b_key, kind="stable")
    b_tri, b_key = b_tri[order], b_key[order]
    start = np.searchsorted(b_key, a_key, "left")
    stop = np.searchsorted(b_key, a_key, "right")
    n = stop - start
    pa = np.repeat(a_tri, n)
    at = np.repeat(a_key, n)
    pb = b_tri[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    ok = np.all((alo[pa] <= bhi[pb]) & (ahi[pa] >= blo[pb]), axis=1)
    pa, pb, at = pa[ok], pb[ok], at[ok]
    home = flat(cell(np.maximum(alo[pa], blo[pb])))
    keep = home == at
    return pa[keep], pb[keep]


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


def _boxes(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's bounding box (F, 3) in single precision, rounded outwards (so it holds
    the double-precision box), a block of faces at a time (bounded temporaries)."""
    lo = np.empty((len(f), 3), np.float32)
    hi = np.empty((len(f), 3), np.float32)
    for c in range(0, len(f), CHUNK):
        t = v[f[c : c + CHUNK]]  # (n, 3 corners, 3)
        lo[c : c + CHUNK] = np.nextafter(t.min(1).astype(np.float32), np.float32(-np.inf))
        hi[c : c + CHUNK] = np.nextafter(t.max(1).astype(np.float32), np.float32(np.inf))
    return lo, hi


def intersections(
    v: np.ndarray, f: np.ndarray, face_oid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every intersection segment between triangles of different objects: ends ``p``, ``q``
    (S, 3) and the two faces ``fa``, ``fb`` (S,) (indices into ``f``) it lies on. The faces of
    one object are contiguous in ``f`` (as :func:`mi_npr.strokes.edges.mesh_arrays` gives
    them)."""
    z = np.zeros(0, np.int64)
    empty = np.zeros((0, 3)), np.zeros((0, 3)), z, z
    if len(f) == 0:
        return empty
    tlo, thi = _boxes(v, f)
    head = np.flatnonzero(np.append(True, face_oid[1:] != face_oid[:-1]))
    stop = np.append(head[1:], len(f))
    olo = np.minimum.reduceat(tlo, head)
    ohi = np.maximum.reduceat(thi, head)
    # every pair of objects whose boxes overlap, the first of the pair earlier in ``f``
    pairs = []
    for r in range(0, len(head), 1024):  # rows of the object-by-object test, memory bound
        lo, hi = olo[r : r + 1024, None], ohi[r : r + 1024, None]
        meet = np.all((lo <= ohi[None]) & (hi >= olo[None]), axis=2)
        i, j = np.nonzero(meet)
        pairs.append(np.stack([i + r, j], 1)[i + r < j])
    ka, kb = np.concatenate(pairs).T
    ps, qs, fas, fbs = [], [], [], []
    for oa, ob in zip(ka.tolist(), kb.tolist(), strict=True):
        sa, sb = slice(head[oa], stop[oa]), slice(head[ob], stop[ob])
        pa, pb = _candidates(tlo[sa], thi[sa], tlo[sb], thi[sb])
        for c in range(0, len(pa), CHUNK):
            fa, fb = pa[c : c + CHUNK] + head[oa], pb[c : c + CHUNK] + head[ob]
            ok, p, q = segments(v[f[fa]], v[f[fb]])
            ps.append(p[ok])
            qs.append(q[ok])
            fas.append(fa[ok])
            fbs.append(fb[ok])
    if not ps:
        return empty
    return np.concatenate(ps), np.concatenate(qs), np.concatenate(fas), np.concatenate(fbs)
