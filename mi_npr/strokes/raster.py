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

import numpy as np

from .model import Stroke, Strokes
from .style import Style


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
    if not pattern or len(p) < 2:
        return [(p, v)]
    seg = np.hypot(*np.diff(p, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if sum(pattern) <= 0:  # refused by the style's rule; never loop forever on it
        return [(p, v)]
    marks = []  # (start, end) of every "on" interval along the stroke
    t = 0.0
    i = 0
    while t < total:
        length = pattern[i % len(pattern)]
        if i % 2 == 0 and length > 0:
            marks.append((t, min(t + length, total)))
        t += length
        i += 1
    out = []
    for a, b in marks:
        inner = (s > a) & (s < b)
        ts = np.concatenate([[a], s[inner], [b]])
        out.append((_at(p, s, ts), _at(v, s, ts)))
    return out


def _at(values: np.ndarray, s: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """``values`` (N, C) given at arc lengths ``s`` (N,), interpolated at ``ts``."""
    return np.stack([np.interp(ts, s, values[:, k]) for k in range(values.shape[1])], -1)


def _capsules(
    p: np.ndarray, r: np.ndarray, o: np.ndarray, width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel indices and coverage of a polyline ``p`` (K, 2) with per-vertex radius ``r``
    and opacity ``o`` (module docstring); the same pixel may appear more than once."""
    idx, cov = [], []
    if len(p) == 1:
        p, r, o = np.concatenate([p, p]), np.concatenate([r, r]), np.concatenate([o, o])
    for k in range(len(p) - 1):
        a, b = p[k], p[k + 1]
        rmax = max(r[k], r[k + 1])
        x0 = max(int(np.floor(min(a[0], b[0]) - rmax - 1)), 0)
        x1 = min(int(np.ceil(max(a[0], b[0]) + rmax + 1)), width)
        y0 = max(int(np.floor(min(a[1], b[1]) - rmax - 1)), 0)
        y1 = min(int(np.ceil(max(a[1], b[1]) + rmax + 1)), height)
        if x0 >= x1 or y0 >= y1:
            continue
        ys, xs = np.mgrid[y0:y1, x0:x1]
        cx, cy = xs.ravel() + 0.5, ys.ravel() + 0.5
        ab = b - a
        ll = float(ab @ ab)
        t = np.zeros_like(cx) if ll == 0 else ((cx - a[0]) * ab[0] + (cy - a[1]) * ab[1]) / ll
        t = np.clip(t, 0.0, 1.0)
        d = np.hypot(cx - (a[0] + t * ab[0]), cy - (a[1] + t * ab[1]))
        rr = r[k] + t * (r[k + 1] - r[k])
        oo = o[k] + t * (o[k + 1] - o[k])
        c = np.clip(rr + 0.5 - d, 0.0, np.minimum(1.0, 2.0 * rr)) * oo
        hit = c > 0
        idx.append((ys.ravel() * width + xs.ravel())[hit])
        cov.append(c[hit])
    if not idx:
        return np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(idx), np.concatenate(cov)


def stroke_coverage(
    stroke: Stroke, style: Style, depth_range: tuple[float, float], width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """The pixels one stroke covers: unique flat indices and their coverage in (0, 1]."""
    w = style.widths(stroke, depth_range)
    o = style.opacity(stroke, depth_range)
    idx, cov = [], []
    for pts, vals in dash_pieces(
        stroke.points, np.stack([w, o], -1), style.dashes(stroke), stroke.closed
    ):
        i, c = _capsules(pts, vals[:, 0] / 2.0, vals[:, 1], width, height)
        idx.append(i)
        cov.append(c)
    i = np.concatenate(idx) if idx else np.zeros(0, np.int64)
    c = np.concatenate(cov) if cov else np.zeros(0)
    if not len(i):
        return i, c
    order = np.lexsort((-c, i))  # per pixel, the largest coverage first
    i, c = i[order], c[order]
    first = np.append(True, i[1:] != i[:-1])
    return i[first], np.minimum(c[first], 1.0)


def rasterize(strokes: Strokes, style: Style) -> tuple[np.ndarray, np.ndarray]:
    """The drawn strokes as coverage (H, W) float32 in [0, 1] and premultiplied linear RGB
    ink (H, W, 3) float32 (module docstring)."""
    h, w = strokes.height, strokes.width
    alpha = np.zeros(h * w)
    ink = np.zeros((h * w, 3))
    for s in strokes:
        if not style.drawn(s):
            continue
        i, a = stroke_coverage(s, style, strokes.depth_range, w, h)
        if not len(i):
            continue
        col = np.asarray(style.kind_color(s), np.float64)
        alpha[i] = alpha[i] * (1.0 - a) + a
        ink[i] = ink[i] * (1.0 - a)[:, None] + col[None, :] * a[:, None]
    return alpha.reshape(h, w).astype(np.float32), ink.reshape(h, w, 3).astype(np.float32)


def on_background(alpha: np.ndarray, ink: np.ndarray, background: np.ndarray) -> np.ndarray:
    """The strokes laid over ``background`` ((H, W, 3) linear RGB, or an RGB triple: paper):
    ``background (1 - A) + C``."""
    bg = np.broadcast_to(np.asarray(background, np.float32), ink.shape)
    return (bg * (1.0 - alpha[..., None]) + ink).astype(np.float32)
