"""Vector contours for illustration programs: paths on the objects' true outlines, simplified.

Image coordinates: ``x`` to the right, ``y`` down, pixel ``(i, j)`` spans ``[i, i+1] x [j, j+1]``
(its centre is ``(i + 0.5, j + 0.5)``), as in SVG with one user unit per pixel.

**Outline points.** Every contour of :mod:`mi_npr.contours.trace` is a cycle of *cracks*: pairs of
4-adjacent pixels ``p`` (object ``k``) and ``q`` (not ``k``). The true outline crosses the segment
between their centres, so each crack gets one vertex there, found by bisection with extra rays
(:func:`mi_npr.raycast.pixel_rays`, the G-buffer's own camera rays): ``iterations`` halvings put it
within ``2**-iterations`` px of the point where the id changes (12: 0.00024 px). Consecutive
cracks' vertices, in the follower's order, are the path: marching squares whose vertices lie on
the outline instead of at the crack midpoints. Without a scene (an id buffer alone) the vertices
are the crack midpoints.

**The image frame is never a contour.** A crack whose ``q`` lies outside the image is where the
object meets the frame: it adds no vertex and cuts the cycle, so an object that touches the border
becomes open paths ending one half-pixel inside the frame at most.

**Simplification.** Douglas-Peucker with ``tolerance`` (default 0.25 px): the kept vertices are
outline points, and every dropped one lies within ``tolerance`` of the simplified path. A closed
path is split at its two mutually farthest vertices first.

**Strokes** (:func:`trace_strokes`) turn line masks without an object-space source (the
ray-tree edge classes, the lines a scene's strokes do not explain) into polylines through the
pixel centres, all in array operations:

1. *The pixel graph*: an edge between 8-neighbours, except a diagonal that a pixel 4-adjacent to
   both bridges (an L-shaped corner is one corner, not a triangle).
2. *Pruning*: a line two pixels wide makes every pixel a junction (its two rows and the rungs
   between them). In rounds, an edge between two pixels of degree 3 or more is removed when it
   comes first at both of its pixels in the order (ends where an edge continues it straight,
   edge index): rungs go before the rows they join. Every pixel keeps two edges or more, so
   every pixel stays on a path, and no edge joining two such pixels is left.
3. *Chains*: a path goes on through a pixel of degree 2 and straight through a *crossing* (4
   edges in two straight pairs: a thin line crossing another stays one path); it ends at an end
   (degree 1) or a junction (3, or 4 that is no crossing: a T is three paths ending at its
   junction). A cycle that meets no end or junction is a closed path: its first vertex repeated
   last. A lone pixel is a path of one vertex. Found by pointer jumping on the half-edges
   (each half-edge's successor on its walk), ``log2`` of the longest path steps.
4. *Douglas-Peucker* on every chain at once: a segment is split at its farthest vertex while
   that lies more than ``tolerance`` from the segment; so every pixel centre of the mask lies
   within ``tolerance`` of a path, and every vertex is a pixel centre.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mitsuba as mi
import numpy as np

from .. import layers as L
from ..errors import ParameterError
from ..gbuffer import GBuffer
from ..raycast import cast, pixel_rays, require_jit
from ..raytree.render import COLORS
from ..scene import object_table, sensor_of
from .idmode import check_id_mode
from .idmode import id_map as make_id_map
from .overlay import mode_ids
from .trace import Grid, check_ids, crack_cycles

#: Pixel offsets of the crack sides d = 0..3 (+x, +y, -x, -y).
_SIDE = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.float64)

IdsAt = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class VectorPath:
    """One piece of an object's outline: ``points`` (N, 2) float64 ``(x, y)`` image positions."""

    object_id: int
    name: str
    points: np.ndarray
    closed: bool
    is_hole: bool = False

    def __len__(self) -> int:
        return len(self.points)


class RayIds:
    """Object ids at film positions, by one camera ray each (``pixel_rays``: the same rays as
    the G-buffer's pixel centres), in the ids of ``id_mode`` (:mod:`mi_npr.contours.idmode`)."""

    def __init__(
        self, scene: Any, sensor: Any = 0, id_mode: str = "shape", id_map: Any = None
    ) -> None:

        require_jit("vector contours")
        self.scene = scene
        self.sensor = sensor_of(scene, sensor)
        self.table = object_table(scene)
        if id_map is not None:  # an IdMap: an id mode and an object selection
            self.table, self.map = id_map.table, id_map
        elif id_mode != "shape":
            self.map = make_id_map(scene, check_id_mode(id_mode), self.table)
        else:
            self.map = None

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:

        if len(x) == 0:
            return np.zeros(0, np.uint32)
        ray = pixel_rays(
            self.sensor, mi.Float(x.astype(np.float32)), mi.Float(y.astype(np.float32))
        )
        hits = cast(self.scene, ray, self.table, coherent=False)
        ids = hits.object_id if self.map is None else hits.ids(self.map)
        return np.asarray(ids.numpy(), np.uint32)


def _bisect(
    ids_at: IdsAt, start: np.ndarray, step: np.ndarray, k: np.ndarray, iterations: int
) -> np.ndarray:
    """Parameter t in (0, 1) along ``start + t * step`` where the id stops being ``k``."""
    lo = np.zeros(len(start))
    hi = np.ones(len(start))
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        p = start + mid[:, None] * step
        inside = ids_at(p[:, 0], p[:, 1]) == k
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return 0.5 * (lo + hi)


def douglas_peucker(points: np.ndarray, tolerance: float, closed: bool = False) -> np.ndarray:
    """The vertices of ``points`` that Douglas-Peucker keeps at ``tolerance`` (first and last
    always; a closed path is split at its two mutually farthest vertices)."""
    p = np.asarray(points, np.float64)
    n = len(p)
    if n <= 2:
        return p.copy()
    if closed:
        a = 0
        b = int(np.argmax(np.sum((p - p[0]) ** 2, axis=1)))
        a = int(np.argmax(np.sum((p - p[b]) ** 2, axis=1)))
        a, b = min(a, b), max(a, b)
        if a == b:
            return p[:1].copy()
        first = _dp_open(p[a : b + 1], tolerance)
        second = _dp_open(np.concatenate([p[b:], p[: a + 1]]), tolerance)
        return np.concatenate([first[:-1], second[:-1]])
    return _dp_open(p, tolerance)


def _dp_open(p: np.ndarray, tolerance: float) -> np.ndarray:
    keep = np.zeros(len(p), dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(p) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        seg = p[j] - p[i]
        rel = p[i + 1 : j] - p[i]
        length = float(np.hypot(*seg))
        if length > 0:
            d = np.abs(seg[0] * rel[:, 1] - seg[1] * rel[:, 0]) / length
        else:
            d = np.hypot(rel[:, 0], rel[:, 1])
        m = int(np.argmax(d))
        if d[m] > tolerance:
            keep[i + 1 + m] = True
            stack += [(i, i + 1 + m), (i + 1 + m, j)]
    return p[keep]


def _runs(valid: np.ndarray) -> list[tuple[int, int]] | None:
    """Cyclic runs of ``True`` as (start, length); ``None`` when all are ``True``."""
    n = len(valid)
    if valid.all():
        return None
    if not valid.any():
        return []
    s = int(np.flatnonzero(~valid)[0])  # rotate so the sequence starts on a frame crack
    rolled = np.roll(valid, -s)
    out: list[tuple[int, int]] = []
    i = 0
    while i < n:
        if rolled[i]:
            j = i
            while j < n and rolled[j]:
                j += 1
            out.append(((i + s) % n, j - i))
            i = j
        else:
            i += 1
    return out


def vectorize(
    source: GBuffer | np.ndarray,
    scene: Any = None,
    *,
    sensor: Any = 0,
    id_mode: str = "shape",
    objects: Mapping[int, str] | None = None,
    tolerance: float = 0.25,
    iterations: int = 12,
    ids_at: IdsAt | None = None,
) -> list[VectorPath]:
    """Every contour of ``source`` (a GBuffer, its ``object_id`` or the ids of ``id_mode``; or
    an (H, W) id buffer) as :class:`VectorPath` pieces on the true outline (module docstring).

    ``scene`` (with ``sensor``) casts the bisection rays; ``ids_at(x, y)`` may replace it (any
    function from film positions to ids); with neither, vertices sit at crack midpoints.
    ``tolerance`` is Douglas-Peucker's, in pixels (0 keeps every vertex).
    """
    if not (isinstance(tolerance, (int, float)) and np.isfinite(tolerance) and tolerance >= 0):
        raise ParameterError(f"tolerance = {tolerance!r}: must be a number >= 0 (pixels)")
    if not isinstance(iterations, int) or not 0 <= iterations <= 40:
        raise ParameterError(f"iterations = {iterations!r}: must be an integer in 0..40")
    if isinstance(source, GBuffer):
        if id_mode != "shape":
            ids, names = mode_ids(source, scene, id_mode)
        else:
            ids, names = source.object_id, dict(source.objects)
        objects = objects if objects is not None else names
    else:
        ids = source
    grid = Grid.from_ids(check_ids(ids))
    cc = crack_cycles(grid)
    if ids_at is None and scene is not None:
        ids_at = RayIds(scene, sensor, id_mode)
    xy = grid.xy(cc.pix).astype(np.float64)
    nb = cc.pix + grid.offsets4()[cc.side]
    inside_image = grid.ids[nb] != np.uint32(0xFFFFFFFF)
    start = xy + 0.5
    step = _SIDE[cc.side]
    k = grid.ids[cc.pix]
    t = np.full(len(cc.pix), 0.5)
    if ids_at is not None and inside_image.any():
        sel = np.flatnonzero(inside_image)
        t[sel] = _bisect(ids_at, start[sel], step[sel], k[sel], iterations)
    points = start + t[:, None] * step
    out: list[VectorPath] = []
    for c in range(len(cc.object_id)):
        a, b = int(cc.offsets[c]), int(cc.offsets[c + 1])
        oid = int(cc.object_id[c])
        name = (objects or {}).get(oid, f"object_{oid}")
        pts, valid = points[a:b], inside_image[a:b]
        runs = _runs(valid)
        if runs is None:
            simple = douglas_peucker(pts, tolerance, closed=True)
            out.append(VectorPath(oid, name, simple, True, bool(cc.is_hole[c])))
            continue
        for s, n in runs:
            idx = (s + np.arange(n)) % len(pts)
            simple = douglas_peucker(pts[idx], tolerance)
            out.append(VectorPath(oid, name, simple, False, bool(cc.is_hole[c])))
    return out


# --------------------------------------------------------------------------------- strokes


def _pixel_graph(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stroke graph of mask ``m`` (module docstring): pixel coordinates ``(x, y)`` in
    row-major order, the undirected edges ``(i, j)`` between them, pruned, and the (H, W) map of
    pixel indices (-1 off the mask)."""
    h, w = m.shape
    ys, xs = np.nonzero(m)
    idx = np.full(m.shape, -1, np.int64)
    idx[ys, xs] = np.arange(len(xs))
    pairs = []
    right = m[:, :-1] & m[:, 1:]
    pairs.append((idx[:, :-1][right], idx[:, 1:][right]))
    down = m[:-1, :] & m[1:, :]
    pairs.append((idx[:-1, :][down], idx[1:, :][down]))
    if h > 1 and w > 1:
        a, b, c, d = m[:-1, :-1], m[:-1, 1:], m[1:, :-1], m[1:, 1:]
        dr_ = a & d & ~b & ~c  # (x, y) -> (x + 1, y + 1)
        pairs.append((idx[:-1, :-1][dr_], idx[1:, 1:][dr_]))
        dl = b & c & ~a & ~d  # (x + 1, y) -> (x, y + 1)
        pairs.append((idx[:-1, 1:][dl], idx[1:, :-1][dl]))
    i = np.concatenate([p[0] for p in pairs])
    j = np.concatenate([p[1] for p in pairs])
    xy = np.stack([xs, ys], 1)
    keep = _pruned(xy, idx, i, j)
    return xy, i[keep], j[keep], idx


def _straight(
    xy: np.ndarray,
    idx: np.ndarray,
    edges: tuple[np.ndarray, np.ndarray, np.ndarray],
    u: np.ndarray,
    v: np.ndarray,
) -> np.ndarray:
    """Per step ``u -> v`` (pixel indices): the index of the edge among ``edges`` (``i``, ``j``,
    live mask) that continues it straight beyond ``v`` (the same step again), or -1."""
    i, j, live = edges
    n = len(xy)
    key = np.concatenate([i * n + j, j * n + i])
    eid = np.concatenate([np.arange(len(i))] * 2)
    order = np.argsort(key)
    key, eid = key[order], eid[order]
    h, w = idx.shape
    nxt = 2 * xy[v] - xy[u]
    inside = (nxt[:, 0] >= 0) & (nxt[:, 0] < w) & (nxt[:, 1] >= 0) & (nxt[:, 1] < h)
    k = np.full(len(u), -1, np.int64)
    k[inside] = idx[nxt[inside, 1], nxt[inside, 0]]
    if not len(key):
        return np.full(len(u), -1, np.int64)
    want = v * n + k
    at = np.minimum(np.searchsorted(key, want), len(key) - 1)
    hit = (k >= 0) & (key[at] == want) & live[eid[at]]
    return np.where(hit, eid[at], -1)


def _pruned(xy: np.ndarray, idx: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The edges kept (mask) after pruning (module docstring): in rounds, an edge between two
    pixels of degree 3 or more goes when it is the first such edge at both of its pixels, in
    the order (number of its ends where a live edge continues it straight, edge index)."""
    n, e = len(xy), len(i)
    live = np.ones(e, bool)
    while True:
        deg = np.bincount(np.concatenate([i[live], j[live]]), minlength=n)
        cand = live & (deg[i] >= 3) & (deg[j] >= 3)
        if not cand.any():
            return live
        c = np.flatnonzero(cand)
        ahead = _straight(xy, idx, (i, j, live), i[c], j[c]) >= 0
        behind = _straight(xy, idx, (i, j, live), j[c], i[c]) >= 0
        rank = (ahead.astype(np.int64) + behind) * e + c
        best = np.full(n, np.iinfo(np.int64).max)
        np.minimum.at(best, i[c], rank)
        np.minimum.at(best, j[c], rank)
        live[c[(best[i[c]] == rank) & (best[j[c]] == rank)]] = False


def _jump(succ: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pointer jumping along ``succ`` (a terminal points to itself): per element its terminal,
    its number of steps to it and the smallest index met (over the whole cycle for elements on
    a cycle, which never reach a fixed point)."""
    n = len(succ)
    ptr = succ.copy()
    dist = (ptr != np.arange(n)).astype(np.int64)
    low = np.minimum(np.arange(n), ptr)
    for _ in range(int(n).bit_length()):
        low = np.minimum(low, low[ptr])
        dist = dist + dist[ptr]
        ptr = ptr[ptr]
    return ptr, dist, low


def _chains(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The chains of mask ``m`` (module docstring): the pixels ``(x, y)`` of every chain, one
    after the other, and the offsets of each chain in them (``xy[off[c]:off[c + 1]]``), chains
    in the row-major order of their first pixel."""
    xy, i, j, idx = _pixel_graph(m)
    n, e = len(xy), len(i)
    deg = np.bincount(np.concatenate([i, j]), minlength=n)
    # half-edges: h < e runs i -> j, h + e is its reverse
    tail, head = np.concatenate([i, j]), np.concatenate([j, i])
    rev = np.concatenate([np.arange(e, 2 * e), np.arange(e)])
    hid = np.arange(2 * e)
    two = deg == 2
    # a walk arriving at a pixel of degree 2 leaves by its other half-edge, one arriving at a
    # crossing goes straight on; elsewhere it ends
    by_tail = np.argsort(tail, kind="stable")
    first = np.searchsorted(tail[by_tail], np.arange(n))
    mid = two[head]
    out_a = by_tail[np.minimum(first[head[mid]], 2 * e - 1)]
    out_b = by_tail[np.minimum(first[head[mid]] + 1, 2 * e - 1)]
    succ = hid.copy()
    succ[mid] = np.where(out_a == rev[mid], out_b, out_a)
    on = _straight(xy, idx, (i, j, np.ones(e, bool)), tail, head)
    on_half = np.where(on < 0, -1, np.where(i[np.maximum(on, 0)] == head, on, on + e))
    straight = np.bincount(head[on >= 0], minlength=n)
    crossing = (deg == 4) & (straight == 4)
    cross = crossing[head]
    succ[cross] = on_half[cross]
    two = two | crossing
    ptr, _, low = _jump(succ)
    # a cycle of degree-2 pixels is walked both ways: keep the orientation holding the smaller
    # half-edge and cut it just before that one
    ring = succ[ptr] != ptr
    keep_ring = ring & (low < low[rev])
    cut = keep_ring & (succ == low)
    succ[cut] = hid[cut]
    ptr, dist, _ = _jump(succ)
    # a path between ends or junctions is walked from both: keep the orientation whose first
    # half-edge is smaller than the other's
    start = (~two[tail] & (hid < rev[ptr])) | (keep_ring & (hid == low))
    s = np.flatnonzero(start)
    chain = np.full(2 * e, -1)
    chain[ptr[s]] = np.arange(len(s))
    member = (~ring | keep_ring) & (chain[ptr] >= 0)
    hs = np.flatnonzero(member)
    c = chain[ptr[hs]]
    # every chain: its first pixel, then the head of each half-edge in walking order; a lone
    # pixel is a chain of one
    singles = np.flatnonzero(deg == 0)
    first_px = np.concatenate([tail[s], singles])
    length = np.concatenate([dist[s] + 2, np.ones(len(singles), np.int64)])
    order = np.argsort(first_px, kind="stable")
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    off = np.concatenate([[0], np.cumsum(length[order])])
    seq = np.empty(int(off[-1]), np.int64)
    seq[off[rank]] = first_px
    seq[off[rank[c]] + 1 + dist[s[c]] - dist[hs]] = head[hs]
    return xy[seq].astype(np.float64), off


def _dp_chains(p: np.ndarray, off: np.ndarray, tolerance: float) -> np.ndarray:
    """Douglas-Peucker on every chain ``p[off[c]:off[c + 1]]`` at once: the mask of kept
    vertices. A chain's ends are kept; a segment is split at its farthest vertex while that lies
    more than ``tolerance`` from the segment (the segment, not its line: a chain that turns back
    keeps its turn). A closed chain (last vertex = first) has a segment of length 0 to begin
    with, which its farthest vertex splits."""
    n = len(p)
    keep = np.zeros(n, bool)
    keep[off[:-1][np.diff(off) > 0]] = True
    keep[off[1:][np.diff(off) > 0] - 1] = True
    live = np.flatnonzero(~keep)
    ids = np.arange(n)
    # the segment of every live vertex: the kept vertices before and after it
    prev = np.maximum.accumulate(np.where(keep, ids, 0))[live]
    nxt = np.minimum.accumulate(np.where(keep, ids, n)[::-1])[::-1][live]
    while len(live):
        a, b, q = p[prev], p[nxt], p[live]
        ab = b - a
        t = np.clip(np.sum((q - a) * ab, 1) / np.maximum(np.sum(ab * ab, 1), 1e-300), 0.0, 1.0)
        d = np.hypot(*(q - a - t[:, None] * ab).T)
        # live vertices of one segment are contiguous: one group per segment
        bounds = np.flatnonzero(np.diff(prev, prepend=-1))
        far = np.maximum.reduceat(d, bounds)
        group = np.repeat(np.arange(len(bounds)), np.diff(np.append(bounds, len(live))))
        split = far > tolerance
        at_far = np.flatnonzero((d == far[group]) & split[group])
        chosen = at_far[np.unique(group[at_far], return_index=True)[1]]
        keep[live[chosen]] = True
        cut = np.full(len(bounds), -1)
        cut[group[chosen]] = live[chosen]
        c = cut[group]
        nxt = np.where(live < c, c, nxt)
        prev = np.where(live > c, c, prev)
        stay = split[group] & (live != c)
        live, prev, nxt = live[stay], prev[stay], nxt[stay]
    return keep


def trace_strokes(mask: Any, tolerance: float = 0.25) -> list[np.ndarray]:
    """Polylines (each (N, 2) float64 through pixel centres) covering an (H, W) line mask (module
    docstring): one per chain between ends and junctions, a closed one with its first vertex
    repeated last, a lone pixel as one vertex; every pixel centre of the mask within
    ``tolerance`` px of one, in the row-major order of their first pixel.

    >>> m = np.zeros((5, 9), bool)
    >>> m[2, 1:8] = True
    >>> [p.tolist() for p in trace_strokes(m)]
    [[[1.5, 2.5], [7.5, 2.5]]]
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim != 2:
        raise ParameterError(f"stroke mask: expected an (H, W) array, got shape {m.shape}")
    if not (isinstance(tolerance, (int, float)) and np.isfinite(tolerance) and tolerance >= 0):
        raise ParameterError(f"tolerance = {tolerance!r}: must be a number >= 0 (pixels)")
    # the chains of the mask's bounding box: the same chains, moved by whole pixels (every
    # pixel beyond it is off the mask), for a fraction of the image's work when it is sparse
    rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
    if not len(rows):
        return []
    y0, x0 = int(rows[0]), int(cols[0])
    p, off = _chains(m[y0 : int(rows[-1]) + 1, x0 : int(cols[-1]) + 1])
    p += (x0 + 0.5, y0 + 0.5)  # whole numbers plus 0.5: exact, as through the whole image
    keep = _dp_chains(p, off, float(tolerance))
    counts = np.add.reduceat(keep, off[:-1]) if len(p) else np.zeros(0, np.int64)
    return np.split(p[keep], np.cumsum(counts)[:-1]) if len(counts) else []


#: Segments sampled at once by :func:`near_polylines`.
NEAR_BLOCK = 1 << 14


def near_polylines(
    shape: tuple[int, int], polylines: Sequence[np.ndarray], radius: float
) -> np.ndarray:
    """(H, W) bool: the pixels whose centre lies within ``radius`` px of a pixel that one of
    ``polylines`` ((N, 2) film positions, pixels) passes through. Each polyline is sampled every
    0.25 px, so the distance measured is within 0.85 px of the true distance to the polyline.
    Distances between pixels are ``sqrt(dx^2 + dy^2)`` of whole ``dx, dy``, as the Euclidean
    distance transform measures them (:func:`_dilate_disk`)."""
    h, w = shape
    lines = [np.asarray(line, np.float64).reshape(-1, 2) for line in polylines]
    lines = [q for q in lines if len(q)]
    on = np.zeros(shape, bool)
    if not lines:
        return on
    # every polyline's segments sampled in a few calls (the segments within one polyline only),
    # NEAR_BLOCK segments at a time: the samples' temporaries stay small
    q = np.concatenate(lines)
    last = np.cumsum([len(v) for v in lines]) - 1
    inner = np.ones(len(q) - 1, bool)
    inner[last[:-1]] = False
    start = q[:-1][inner]
    seg = np.diff(q, axis=0)[inner]

    def mark(p: np.ndarray) -> None:
        p = np.floor(p).astype(np.int64)
        p = p[(p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)]
        on[p[:, 1], p[:, 0]] = True

    for b in range(0, len(seg), NEAR_BLOCK):
        a, d = start[b : b + NEAR_BLOCK], seg[b : b + NEAR_BLOCK]
        k = np.maximum(1, np.ceil(np.hypot(*d.T) / 0.25).astype(np.int64))
        t = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)
        mark(a.repeat(k, 0) + d.repeat(k, 0) * (t / k.repeat(k))[:, None])
    mark(q[last])
    if not on.any():
        return on
    return _dilate_disk(on, radius)


#: The radius from which :func:`_dilate_disk` thresholds the distance transform (its own work
#: grows with the radius).
_DISK_RADIUS = 32


def _dilate_disk(on: np.ndarray, radius: float) -> np.ndarray:
    """The pixels within ``radius`` of a pixel of ``on`` (H, W): ``edt(~on) <= radius`` of
    scipy's exact Euclidean distance transform, the square root of a whole ``dx^2 + dy^2``. For
    a small radius the same set costs a few array operations: per row offset ``dy``, the
    offsets ``|dx|`` up to the largest one whose distance passes (``on`` shifted along its rows
    and OR-ed), OR-ed into the rows ``dy`` away."""
    if not radius >= 0:
        return np.zeros(on.shape, bool)  # no distance passes (a NaN radius neither)
    if radius >= _DISK_RADIUS:
        from scipy.ndimage import distance_transform_edt  # lazy: scipy's import is slow

        return distance_transform_edt(~on) <= radius
    h, w = on.shape
    d = np.arange(int(radius) + 1, dtype=np.float64)
    # each row's half width: the offsets pass from 0 up (the distance grows with |dx|)
    half = np.count_nonzero(np.sqrt(d[:, None] ** 2 + d[None, :] ** 2) <= radius, axis=1) - 1
    near = np.zeros(on.shape, bool)
    r = on.copy()  # on dilated along its rows by [-k, k], k growing
    for k in range(int(half[0]) + 1):
        if 0 < k < w:
            r[:, k:] |= on[:, :-k]
            r[:, :-k] |= on[:, k:]
        for dy in np.flatnonzero(half == k).tolist():  # the row offsets of half width k
            if dy >= h:
                continue
            near[: h - dy] |= r[dy:]
            if dy:
                near[dy:] |= r[: h - dy]
    return near


def stroke_layers(
    gb: GBuffer, tolerance: float = 0.25, lines: bool = True
) -> dict[str, tuple[list[np.ndarray], tuple[float, float, float]]]:
    """The GBuffer's line drawings as SVG stroke layers: ``lines`` (the ``lines.V`` layer above
    0.5, black; left out with ``lines=False``) and each ray-tree edge class present
    (``edges_real``, ... in the overlay's colours), each as polylines (:func:`trace_strokes`)."""

    out: dict[str, tuple[list[np.ndarray], tuple[float, float, float]]] = {}
    if lines and L.LINES in gb:
        out[L.LINES.split(".")[0]] = (
            trace_strokes(gb.numpy(L.LINES) > 0.5, tolerance),
            (0.0, 0.0, 0.0),
        )
    for name, rgb in COLORS.items():
        if name in gb:
            out[name.split(".")[0]] = (trace_strokes(gb.numpy(name) > 0.5, tolerance), tuple(rgb))
    return out


__all__ = [
    "RayIds",
    "VectorPath",
    "douglas_peucker",
    "near_polylines",
    "stroke_layers",
    "trace_strokes",
    "vectorize",
]
