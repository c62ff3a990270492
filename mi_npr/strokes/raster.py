"""Styled strokes rasterised with anti-aliasing: the ``strokes.V`` layer and its colours.

A stroke is a chain of *capsules*: around each segment ``a -> b`` the points within the
radius ``r(s) = w(s) / 2`` of the segment, ``w`` and the opacity ``o`` interpolated linearly
between the segment's vertices (:mod:`mi_npr.strokes.style`), ``s`` the parameter of the
nearest point of the segment. A pixel centre at distance ``d`` from the segment is covered by

    ``a = clip(r + 1/2 - d, 0, min(1, 2 r)) * o``,

the area of a 1-px box filter over a straight edge (exact for a line along the pixel grid;
a line thinner than 1 px covers at most its width). Within one stroke the coverage is the
*maximum* over its segments (joints are not darker than the line), and strokes are laid
over each other in order with ``A <- A (1 - a) + a`` and premultiplied colour
``C <- C (1 - a) + color a``. Dashes (hidden lines) cut the stroke by arc length into its
"on" pieces first. Only the strokes the style draws (:meth:`Style.drawn`) are rasterised.
"""

from __future__ import annotations

import itertools
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from .model import Stroke, Strokes, sizes
from .order import lexsort_ints, stable_argsort
from .style import Style, arc_lengths
from .visibility import jit_array


def dash_pieces(
    points: np.ndarray, values: np.ndarray, pattern: tuple[float, ...], closed: bool = False
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The "on" pieces of a polyline under a dash ``pattern`` (on, off, on... px; ``()``:
    the whole polyline): each piece's points (K, 2) and its per-vertex ``values`` (K, C)
    interpolated along it."""
    p = np.asarray(points, np.float64)
    v = np.asarray(values, np.float64).reshape(len(p), -1)
    if closed and len(p) > 1:
        p, v = np.concatenate([p, p[:1]]), np.concatenate([v, v[:1]])
    if not pattern or len(p) < 2 or sum(pattern) <= 0:
        return [(p, v)]
    q, w, size, _ = _dashed(p, v, np.array([len(p)]), pattern)
    cut = np.cumsum(size)[:-1]
    return list(zip(np.split(q, cut), np.split(w, cut), strict=True))


def _dashed(
    p: np.ndarray, v: np.ndarray, size: np.ndarray, pattern: tuple[float, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The "on" pieces of many polylines at once (:func:`dash_pieces`): ``p`` (M, 2) and
    ``v`` (M, C) their vertices one polyline after the other, ``size`` (S,) each one's count
    (>= 2). Returns the pieces' points and values, each piece's size and the polyline it
    comes from. The pattern restarts at every polyline; an odd-length pattern alternates on
    and off through two repeats (``4`` is 4 on, 4 off)."""
    pat = np.asarray(pattern, np.float64)
    if len(pat) % 2:
        pat = np.concatenate([pat, pat])
    period = float(pat.sum())
    offset = np.concatenate([[0.0], np.cumsum(pat)[:-1]])
    on, on_at = pat[0::2], offset[0::2]
    arc, total = arc_lengths(p, size)
    first = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
    # each "on" interval [a, b) of each polyline: period q, entry j
    periods = np.ceil(total / period).astype(np.int64)
    k = np.repeat(np.arange(len(size)), periods * len(on))
    i = np.arange(len(k)) - np.repeat(
        np.cumsum(periods * len(on)) - periods * len(on), periods * len(on)
    )
    a = (i // len(on)) * period + on_at[i % len(on)]
    length = on[i % len(on)]
    keep = (a < total[k]) & (length > 0)
    k, a, length = k[keep], a[keep], length[keep]
    b = np.minimum(a + length, total[k])
    # one increasing coordinate over all polylines: a searchsorted finds any arc length
    base = np.concatenate([[0.0], np.cumsum(total + 1.0)[:-1]])
    g = arc + np.repeat(base, size)
    ga, gb = a + base[k], b + base[k]
    inner_lo = np.searchsorted(g, ga, "right")
    inner_hi = np.maximum(np.searchsorted(g, gb, "left"), inner_lo)
    n_inner = inner_hi - inner_lo
    piece_size = n_inner + 2
    starts = np.concatenate([[0], np.cumsum(piece_size)[:-1]])
    m = int(piece_size.sum())
    src = np.empty(m, np.int64)  # a vertex of the polyline, or -1: an interpolated end
    src[:] = -1
    owner = np.repeat(np.arange(len(k)), n_inner)
    rank = np.arange(len(owner)) - np.repeat(np.cumsum(n_inner) - n_inner, n_inner)
    src[starts[owner] + 1 + rank] = inner_lo[owner] + rank
    out_p = np.empty((m, p.shape[1]))
    out_v = np.empty((m, v.shape[1]))
    inner = src >= 0
    out_p[inner], out_v[inner] = p[src[inner]], v[src[inner]]
    lo_seg = first[k]
    hi_seg = first[k] + size[k] - 2
    for at, gt in ((starts, ga), (starts + piece_size - 1, gb)):
        j = np.clip(np.searchsorted(g, gt, "right") - 1, lo_seg, hi_seg)
        span = g[j + 1] - g[j]
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(span > 0, (gt - g[j]) / span, 0.0)
        f = np.clip(f, 0.0, 1.0)[:, None]
        out_p[at] = p[j] + f * (p[j + 1] - p[j])
        out_v[at] = v[j] + f * (v[j + 1] - v[j])
    return out_p, out_v, piece_size, k


def _capsules(
    p: np.ndarray,
    r: np.ndarray,
    o: np.ndarray,
    size: np.ndarray,
    width: int,
    height: int,
    owner: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels covered by polylines ``p`` (M, 2) given one after the other (``size`` (S,)
    vertices each) with per-vertex radius ``r`` and opacity ``o`` (module docstring): each
    covered (owner, pixel) once, with its largest coverage (over the owner's segments), in
    order of owner then pixel; ``owner`` (S,): whose each polyline is (the pieces of one dashed
    stroke share theirs); a polyline of one vertex is a dot."""
    one = size == 1
    if one.any():  # a dot: the segment from the vertex to itself
        rep = np.where(np.repeat(one, size), 2, 1)
        p, r, o = np.repeat(p, rep, 0), np.repeat(r, rep), np.repeat(o, rep)
        size = np.where(one, 2, size)
    last = np.cumsum(size) - 1
    seg = np.ones(len(p), bool)
    seg[last] = False
    i = np.flatnonzero(seg)
    who = np.repeat(np.arange(len(size)), size)[i]
    a, b = p[i], p[i + 1]
    ra, rb, oa, ob = r[i], r[i + 1], o[i], o[i + 1]
    rmax = np.maximum(ra, rb)
    x0 = np.maximum(np.floor(np.minimum(a[:, 0], b[:, 0]) - rmax - 1).astype(np.int64), 0)
    x1 = np.minimum(np.ceil(np.maximum(a[:, 0], b[:, 0]) + rmax + 1).astype(np.int64), width)
    y0 = np.maximum(np.floor(np.minimum(a[:, 1], b[:, 1]) - rmax - 1).astype(np.int64), 0)
    y1 = np.minimum(np.ceil(np.maximum(a[:, 1], b[:, 1]) + rmax + 1).astype(np.int64), height)
    nx, ny = np.maximum(x1 - x0, 0), np.maximum(y1 - y0, 0)
    count = nx * ny
    idx, cov, own = [], [], []
    bounds = np.searchsorted(np.cumsum(count), np.arange(0, count.sum(), CHUNK), "right")
    for c0, c1 in itertools.pairwise([*np.unique(bounds).tolist(), len(count)]):
        sl = slice(c0, c1)
        seg = (x0[sl], y0[sl], nx[sl], a[sl], b[sl], ra[sl], rb[sl], oa[sl], ob[sl])
        s, pixel, c = _pixel_tests(count[sl], seg, width)
        idx.append(pixel)
        cov.append(c)
        own.append(who[c0 + s])
    if not idx:
        z = np.zeros(0, np.int64)
        return z, z, np.zeros(0)
    idx, cov, own = np.concatenate(idx), np.concatenate(cov), np.concatenate(own)
    if not len(idx):
        return own.astype(np.int64), idx.astype(np.int64), cov
    own = np.asarray(owner, np.int64)[own]
    # per owner and pixel, the largest coverage: one sort of one key, a maximum per run
    key = own * (width * height) + idx
    order = stable_argsort(key)
    key = key[order]
    head = np.flatnonzero(np.append(True, key[1:] != key[:-1]))
    cov = np.maximum.reduceat(cov[order], head)
    key = key[head]
    return key // (width * height), key % (width * height), cov


def _pixel_tests(
    count: np.ndarray, seg: tuple[np.ndarray, ...], width: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixel tests of :func:`_capsules` for segments ``seg`` (their boxes' corners ``x0``,
    ``y0`` and widths ``nx``, ends ``a``, ``b``, radii and opacities at the ends; ``count``
    pixels each, row by row over the box), in one Dr.Jit kernel (double precision): each
    covered pixel's segment (an index into ``seg``), flat index and coverage."""
    x0, y0, nx, a, b, ra, rb, oa, ob = seg
    n = int(count.sum())
    if n == 0:
        return np.zeros(0, np.uint32), np.zeros(0, np.uint32), np.zeros(0)
    start = np.cumsum(count) - count
    # each test's segment: the last one starting at or before it (the segments' starts
    # marked, summed along the tests; a segment of no test starts where the next one does)
    mark = dr.zeros(mi.UInt32, n)
    marked = jit_array(mi.UInt32, start[start < n].astype(np.uint32))
    # atomics (a reduction into a small array by copies per thread would bake its size into
    # the kernel: a kernel per size)
    dr.scatter_reduce(dr.ReduceOp.Add, mark, 1, marked, mode=dr.ReduceMode.Direct)
    s = dr.cumsum(mark) - 1
    j = dr.arange(mi.UInt32, n)

    def at(values: np.ndarray, kind: type = mi.Float64) -> Any:
        return dr.gather(kind, jit_array(kind, values), s)

    k = mi.Int32(j - at(start.astype(np.uint32), mi.UInt32))
    w = dr.maximum(at(nx.astype(np.int32), mi.Int32), 1)  # a kernel's idle lanes read 0
    xs, ys = at(x0.astype(np.int32), mi.Int32) + k % w, at(y0.astype(np.int32), mi.Int32) + k // w
    cx, cy = mi.Float64(xs) + 0.5, mi.Float64(ys) + 0.5
    ax, ay, bx, by = at(a[:, 0]), at(a[:, 1]), at(b[:, 0]), at(b[:, 1])
    abx, aby = bx - ax, by - ay
    ll = abx * abx + aby * aby
    t = dr.select(ll == 0, 0.0, ((cx - ax) * abx + (cy - ay) * aby) / ll)
    t = dr.clip(t, 0.0, 1.0)
    dx, dy = cx - (ax + t * abx), cy - (ay + t * aby)
    d = dr.sqrt(dx * dx + dy * dy)
    r0, o0 = at(ra), at(oa)
    rr = r0 + t * (at(rb) - r0)
    oo = o0 + t * (at(ob) - o0)
    c = dr.clip(rr + 0.5 - d, 0.0, dr.minimum(1.0, 2.0 * rr)) * oo
    hit = dr.compress(c > 0)
    pixel = dr.gather(mi.UInt32, mi.UInt32(ys * width + xs), hit)
    out = (dr.gather(mi.UInt32, s, hit), pixel, dr.gather(mi.Float64, c, hit))
    dr.eval(*out)
    return tuple(np.asarray(x.numpy()) for x in out)  # type: ignore[return-value]


#: Pixel tests per batch of :func:`_capsules` (one kernel; memory: 4 bytes each, and 16 per
#: covered pixel).
CHUNK = 1 << 19
#: Strokes rasterised at once by :func:`rasterize` (memory bound: their covered pixels).
BLOCK = 1 << 10


def _coverage(
    strokes: list[Stroke], style: Style, depth_range: tuple[float, float], width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels each of ``strokes`` covers: ``(stroke, pixel, coverage)``, each pair once,
    coverage in (0, 1] (module docstring)."""
    z = np.zeros(0, np.int64)
    if not strokes:
        return z, z, np.zeros(0)
    size = sizes(strokes)
    w = style.vertex_widths(strokes, depth_range, size)
    o = style.vertex_opacity(strokes, depth_range, size)
    closed = (size > 1) & np.fromiter((s.closed for s in strokes), bool, len(strokes))
    pts = np.concatenate([s.points for s in strokes])
    vals = np.stack([w, o], -1)
    if closed.any():  # a closed stroke ends where it starts
        first = np.concatenate([[0], np.cumsum(size)[:-1]])
        again = np.zeros(len(pts), np.int64)
        again[first[closed] + size[closed] - 1] = 1
        take = np.repeat(np.arange(len(pts)), again + 1)
        extra = np.zeros(len(take), bool)
        extra[np.cumsum(again + 1)[again == 1] - 1] = True
        take[extra] = np.repeat(first, size)[again == 1]
        pts, vals = pts[take], vals[take]
        size = size + closed
    dashed = np.array([bool(style.dashes(s)) for s in strokes]) & (size >= 2)
    dashed &= sum(style.dash) > 0  # refused by the style's rule; never dash by zeros
    owner = np.arange(len(strokes))
    parts = []
    if (~dashed).any():
        keep = np.repeat(~dashed, size)
        parts.append((pts[keep], vals[keep], size[~dashed], owner[~dashed]))
    if dashed.any():
        keep = np.repeat(dashed, size)
        q, v, n, k = _dashed(pts[keep], vals[keep], size[dashed], tuple(style.dash))
        parts.append((q, v, n, owner[dashed][k]))
    p = np.concatenate([x[0] for x in parts])
    v = np.concatenate([x[1] for x in parts])
    n = np.concatenate([x[2] for x in parts])
    k = np.concatenate([x[3] for x in parts])
    # the pieces of one stroke (its dashes) cover a pixel once, with their largest coverage
    stroke, idx, cov = _capsules(p, v[:, 0] / 2.0, v[:, 1], n, width, height, k)
    if not len(idx):
        return z, z, np.zeros(0)
    return stroke, idx, np.minimum(cov, 1.0)


def stroke_coverage(
    stroke: Stroke, style: Style, depth_range: tuple[float, float], width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """The pixels one stroke covers: unique flat indices and their coverage in (0, 1]."""
    _, idx, cov = _coverage([stroke], style, depth_range, width, height)
    order = np.argsort(idx)
    return idx[order], cov[order]


def rasterize(strokes: Strokes, style: Style) -> tuple[np.ndarray, np.ndarray]:
    """The drawn strokes as coverage (H, W) float32 in [0, 1] and premultiplied linear RGB
    ink (H, W, 3) float32 (module docstring)."""
    h, w = strokes.height, strokes.width
    # single precision throughout (what is returned): a pixel's strokes are laid in order,
    # each step's rounding ~1e-7 of [0, 1]
    alpha = np.zeros(h * w, np.float32)
    ink = np.zeros((h * w, 3), np.float32)
    drawn = [s for s in strokes if style.drawn(s)]
    # a block of strokes at a time, in order (memory: the block's covered pixels): each
    # pixel gets the same strokes in the same order as from all at once
    for b in range(0, len(drawn), BLOCK):
        block = drawn[b : b + BLOCK]
        stroke, idx, a = _coverage(block, style, strokes.depth_range, w, h)
        if not len(idx):
            continue
        col = np.asarray([style.kind_color(s) for s in block], np.float32).reshape(-1, 3)
        # strokes laid in order: per pixel, its strokes one level at a time (the k-th stroke
        # over each pixel at level k), every pixel of a level at once
        order = lexsort_ints((stroke, idx))
        stroke, idx, a = stroke[order], idx[order], a[order]
        head = np.flatnonzero(np.append(True, idx[1:] != idx[:-1]))
        level = np.arange(len(idx)) - np.repeat(head, np.diff(np.append(head, len(idx))))
        by_level = stable_argsort(level)
        cut = np.searchsorted(level[by_level], np.arange(1, int(level.max()) + 1))
        for sel in np.split(by_level, cut):
            i, c = idx[sel], a[sel].astype(np.float32)
            alpha[i] = alpha[i] * (1.0 - c) + c
            ink[i] = ink[i] * (1.0 - c)[:, None] + col[stroke[sel]] * c[:, None]
    # the pixel tests' buffers, which Dr.Jit would keep for reuse, handed back: the next
    # drawing's rays and raster ask for other sizes
    dr.flush_malloc_cache()
    return alpha.reshape(h, w), ink.reshape(h, w, 3)


def on_background(alpha: np.ndarray, ink: np.ndarray, background: np.ndarray) -> np.ndarray:
    """The strokes laid over ``background`` ((H, W, 3) linear RGB, or an RGB triple: paper):
    ``background (1 - A) + C``."""
    bg = np.broadcast_to(np.asarray(background, np.float32), ink.shape)
    return (bg * (1.0 - alpha[..., None]) + ink).astype(np.float32)
