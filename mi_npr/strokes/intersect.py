"""Intersection lines: where the triangles of two different meshes cut each other.

**Pairs of triangles.** For every pair of meshes whose bounding boxes overlap (of those asked
for: a view's visible lines need only the pairs whose pixels touch, :func:`touching_pairs`), the
triangles of each that reach into the overlap are hashed into a uniform grid over it (cell side:
the median triangle size there, at most ``GRID`` cells per axis); triangles sharing a cell, with
overlapping bounding boxes, are tested. The cost is about ``O(F + P)`` for ``F`` triangles in
the overlaps and ``P`` candidate pairs (``O(F_a F_b)`` at worst, when all triangles crowd into
one cell). Self-intersections of one mesh are not looked for. The candidates are found on the
calling thread and tested in blocks of :data:`CHUNK` pairs meanwhile, on as many threads as
Dr.Jit has (a batch worker's ``--threads``, as OpenEXR's pool in :mod:`mi_npr.io.exr`); the
segments come in the same order as from one thread.

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

from concurrent.futures import ThreadPoolExecutor

import drjit as dr
import numpy as np

from .order import stable_argsort

#: Most grid cells per axis over the overlap of two meshes.
GRID = 64
#: Candidate pairs tested at once (memory bound).
CHUNK = 1 << 14


def touching_pairs(ids: np.ndarray) -> np.ndarray:
    """The pairs of different nonzero ids that touch in an id image ``ids`` (H, W) (two pixels
    side by side or corner to corner): (K, 2), the lower id first, sorted. A visible
    intersection line of two objects runs between their pixels, so these are the pairs whose
    lines a view can show (one shorter than a pixel may fall between pixel centres)."""
    ids = np.asarray(ids).astype(np.int64)
    found = [np.zeros((0, 2), np.int64)]
    h, w = ids.shape
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = ids[: h - dy, max(0, -dx) : w - max(0, dx)]
        b = ids[dy:, max(0, dx) : w - max(0, -dx)]
        m = (a != b) & (a > 0) & (b > 0)
        found.append(np.stack([np.minimum(a[m], b[m]), np.maximum(a[m], b[m])], 1))
    pairs = np.concatenate(found)
    return np.unique(pairs, axis=0) if len(pairs) else pairs


def _inside(tlo: np.ndarray, thi: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The indices of the boxes (``tlo``, ``thi``: (3, N), an axis a row) that overlap the box
    (``lo``, ``hi``)."""
    m = tlo[0] <= hi[0]
    for k in range(3):
        if k:
            m &= tlo[k] <= hi[k]
        m &= thi[k] >= lo[k]
    return np.flatnonzero(m)


def _candidates(
    alo: np.ndarray,
    ahi: np.ndarray,
    blo: np.ndarray,
    bhi: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of triangles of two meshes whose bounding boxes (``alo[:, i]``,
    ``ahi[:, i]``) and (``blo[:, j]``, ``bhi[:, j]``) overlap ((3, N) arrays, an axis a row),
    found through a uniform grid over the overlap (``lo``, ``hi``) of the two meshes' boxes
    (module docstring). A pair is reported by the one cell that holds the larger of its two
    boxes' lower corners (no pair twice, no sort to remove duplicates); pairs come in the order
    of ``i``'s cells."""
    none = np.zeros(0, np.int64), np.zeros(0, np.int64)
    if np.any(lo > hi):
        return none
    ia, ib = _inside(alo, ahi, lo, hi), _inside(blo, bhi, lo, hi)
    if not len(ia) or not len(ib):
        return none
    alo, ahi, blo, bhi = alo[:, ia], ahi[:, ia], blo[:, ib], bhi[:, ib]  # those in the overlap
    extent = float(np.max(hi - lo))
    sizes = np.concatenate([(ahi - alo).max(0), (bhi - blo).max(0)])
    h = max(float(np.median(sizes)), extent / GRID, 1e-30)
    cells = np.maximum(1, np.ceil((hi - lo) / h).astype(np.int64))
    lo_c, top = lo[:, None], (cells - 1)[:, None]

    def cell(x: np.ndarray) -> np.ndarray:  # (3, n) points -> their cells (3, n)
        return np.clip(np.floor((x - lo_c) / h).astype(np.int64), 0, top)

    def flat(c: np.ndarray) -> np.ndarray:  # cells (3, n) -> their flat index
        return (c[2] * cells[1] + c[1]) * cells[0] + c[0]

    def expand(tlo: np.ndarray, thi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each box's lower corner's cell (3, n), and (box, cell) for every cell it covers."""
        c0 = cell(tlo)
        span = cell(thi) - c0 + 1
        count = span[0] * span[1] * span[2]
        owner = np.repeat(np.arange(len(count)), count)
        k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
        sx, sy = span[0][owner], span[1][owner]
        cx = c0[0][owner] + k % sx
        cy = c0[1][owner] + (k // sx) % sy
        cz = c0[2][owner] + k // (sx * sy)
        return c0, owner, (cz * cells[1] + cy) * cells[0] + cx

    ca, a_box, a_key = expand(alo, ahi)
    cb, b_box, b_key = expand(blo, bhi)
    order = stable_argsort(b_key)
    b_box, b_key = b_box[order], b_key[order]
    start = np.searchsorted(b_key, a_key, "left")
    stop = np.searchsorted(b_key, a_key, "right")
    n = stop - start
    pa = np.repeat(a_box, n)
    at = np.repeat(a_key, n)
    pb = b_box[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    for k in range(3):  # the boxes overlap: an axis at a time, on the pairs left
        ok = alo[k][pa] <= bhi[k][pb]
        ok &= ahi[k][pa] >= blo[k][pb]
        pa, pb, at = pa[ok], pb[ok], at[ok]
    # the one cell that reports a pair: that of the larger lower corner, whose cell is the
    # larger of the two corners' cells axis by axis (the cell is monotone in each coordinate)
    keep = flat(np.maximum(ca[:, pa], cb[:, pb])) == at
    return ia[pa[keep]], ib[pb[keep]]


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


def _straddles(s: np.ndarray) -> np.ndarray:
    """Rows of signed distances ``s`` (N, 3) with a vertex on each side (on the plane: the
    positive side)."""
    pos, neg = s >= 0, s < 0
    return (pos[:, 0] | pos[:, 1] | pos[:, 2]) & (neg[:, 0] | neg[:, 1] | neg[:, 2])


def _normals(t: np.ndarray) -> np.ndarray:
    return np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])


def segments(t1: np.ndarray, t2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The intersection of each pair of triangles ``t1[i]``, ``t2[i]`` (N, 3, 3): ``(ok, p,
    q)``, the segment ``p -> q`` (N, 3) where ``ok`` (module docstring). The tests run in
    turn on the pairs the earlier ones left (``t2`` across ``t1``'s plane, then ``t1`` across
    ``t2``'s), each with the same arithmetic as on all pairs."""
    n = len(t1)
    ok = np.zeros(n, bool)
    p = np.zeros((n, 3))
    q = np.zeros((n, 3))
    n1 = _normals(t1)
    s2 = np.einsum("nij,nj->ni", t2 - t1[:, :1], n1)  # t2's vertices against t1's plane
    i = np.flatnonzero(_straddles(s2))
    t1, t2, n1, s2 = t1[i], t2[i], n1[i], s2[i]
    n2 = _normals(t2)
    s1 = np.einsum("nij,nj->ni", t1 - t2[:, :1], n2)
    line = np.cross(n1, n2)
    keep = _straddles(s1) & (np.linalg.norm(line, axis=1) > 0)
    i, t1, t2, s1, s2, line = i[keep], t1[keep], t2[keep], s1[keep], s2[keep], line[keep]
    if not len(i):
        return ok, p, q
    a0, a1 = _crossing(t1, s1)
    b0, b1 = _crossing(t2, s2)
    L = line
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
    ok[i] = np.minimum(ta_hi, tb_hi) > np.maximum(ta_lo, tb_lo)
    p[i], q[i] = lo, hi
    return ok, p, q


def _boxes(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's bounding box (3, F), an axis a row, in single precision, rounded
    outwards (so it holds the double-precision box), a block of faces at a time (bounded
    temporaries)."""
    lo = np.empty((3, len(f)), np.float32)
    hi = np.empty((3, len(f)), np.float32)
    down, up = np.float32(-np.inf), np.float32(np.inf)
    for k in range(3):
        x = np.ascontiguousarray(v[:, k])
        for c in range(0, len(f), 4 * CHUNK):
            fc = f[c : c + 4 * CHUNK]
            a, b, d = x[fc[:, 0]], x[fc[:, 1]], x[fc[:, 2]]
            m = np.minimum(np.minimum(a, b), d)
            lo[k, c : c + len(fc)] = np.nextafter(m.astype(np.float32), down)
            np.maximum(np.maximum(a, b), d, out=m)
            hi[k, c : c + len(fc)] = np.nextafter(m.astype(np.float32), up)
    return lo, hi


def intersections(
    v: np.ndarray, f: np.ndarray, face_oid: np.ndarray, pairs: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every intersection segment between triangles of different objects: ends ``p``, ``q``
    (S, 3) and the two faces ``fa``, ``fb`` (S,) (indices into ``f``) it lies on, ``fa``'s
    object the lower id; the segments of one pair of objects together, the pairs in increasing
    ids. The faces of one object are contiguous in ``f``, objects in increasing id (as
    :func:`mi_npr.strokes.edges.mesh_arrays` gives them). ``pairs``: (K, 2) object ids, the
    pairs of objects searched (either order; default every pair)."""
    z = np.zeros(0, np.int64)
    empty = np.zeros((0, 3)), np.zeros((0, 3)), z, z
    if len(f) == 0:
        return empty
    tlo, thi = _boxes(v, f)
    head = np.flatnonzero(np.append(True, face_oid[1:] != face_oid[:-1]))
    stop = np.append(head[1:], len(f))
    olo = np.minimum.reduceat(tlo, head, axis=1).T
    ohi = np.maximum.reduceat(thi, head, axis=1).T
    # every pair of objects whose boxes overlap, the first of the pair earlier in ``f``
    found_pairs = []
    for r in range(0, len(head), 1024):  # rows of the object-by-object test, memory bound
        lo, hi = olo[r : r + 1024, None], ohi[r : r + 1024, None]
        meet = np.all((lo <= ohi[None]) & (hi >= olo[None]), axis=2)
        i, j = np.nonzero(meet)
        found_pairs.append(np.stack([i + r, j], 1)[i + r < j])
    ka, kb = np.concatenate(found_pairs).T
    if pairs is not None:  # only the pairs asked for (objects in increasing id: ka's lower)
        oid = face_oid[head].astype(np.int64)
        asked = np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1)
        m = int(max(oid.max(), asked.max(initial=0))) + 1
        keep = np.isin(oid[ka] * m + oid[kb], asked[:, 0] * m + asked[:, 1])
        ka, kb = ka[keep], kb[keep]

    def blocks():  # the candidate pairs, gathered into blocks of about CHUNK pairs
        held, count = [], 0
        for oa, ob in zip(ka.tolist(), kb.tolist(), strict=True):
            sa, sb = slice(head[oa], stop[oa]), slice(head[ob], stop[ob])
            lo, hi = np.maximum(olo[oa], olo[ob]), np.minimum(ohi[oa], ohi[ob])
            pa, pb = _candidates(tlo[:, sa], thi[:, sa], tlo[:, sb], thi[:, sb], lo, hi)
            held.append((pa + head[oa], pb + head[ob]))
            count += len(pa)
            if count >= CHUNK:
                yield np.concatenate([a for a, _ in held]), np.concatenate([b for _, b in held])
                held, count = [], 0
        if count:
            yield np.concatenate([a for a, _ in held]), np.concatenate([b for _, b in held])

    def test(fa: np.ndarray, fb: np.ndarray) -> tuple[np.ndarray, ...]:
        ok, p, q = segments(v[f[fa]].astype(np.float64), v[f[fb]].astype(np.float64))
        return p[ok], q[ok], fa[ok], fb[ok]

    # this thread finds the candidates (many small numpy calls, which hold the GIL) while the
    # pool tests them in large blocks (long numpy loops, which let go of it); results in order
    found, jobs = [], []
    workers = max(1, int(dr.thread_count()))  # as many as Dr.Jit has (a batch worker's)
    with ThreadPoolExecutor(workers) as pool:
        for b in blocks():
            jobs.append(pool.submit(test, *b))
            while len(jobs) > 2 * workers:  # a few blocks waiting at most (memory)
                found.append(jobs.pop(0).result())
        found += [job.result() for job in jobs]
    found = [r for r in found if len(r[0])]
    if not found:
        return empty
    return tuple(np.concatenate(x) for x in zip(*found, strict=True))  # type: ignore[return-value]
