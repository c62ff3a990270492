"""Ray-cast mode: the contours from the scene, casting primary rays only where they are needed.

Section 3.1 of the paper (selective refinement) finds start pixels, section 3.2 follows contours
from them; both cast rays on demand instead of rendering an ID buffer. :func:`trace_scene` does:

1. **Macro pixels** (section 3.1). Rays are cast at the corners of 8x8 macro pixels. A macro pixel
   whose four corners see different objects is split into four, down to blocks of 2x2 pixels,
   whose four corners are the four pixels themselves. One batch of rays per level.
   *Ambiguity resolved*: the corners are shared with the neighbouring macro pixels (a grid of
   rays every 8 pixels; the last row and column of the image close the grid). With separate
   corners per macro pixel (pixels 0 and 7, then 8 and 15, ...), a contour running between pixel
   columns 7 and 8 would be seen by neither macro pixel, and 4x more rays would be cast.
2. **Small-object guard** (scene knowledge, not in the paper). Every shape and every connected
   component of a mesh (in every ``id_mode``: the leaves of one foliage mesh, and the gaps
   between them, hide between corner rays like small shapes do) whose projected bounding box is
   at most two macro pixels wide *or* tall can fall between the corner rays; every pixel of that
   box (clipped to the image) is cast, in one batch. Its cost is proportional to the small
   objects' screen area. Boxes are projected with the sensor's ``sample_direction``, or along
   the parallel rays of an orthographic camera; objects whose box crosses the camera plane,
   and other sensors without ``sample_direction``, are not guarded.
3. **Following** (section 3.2). Every pair of 4-adjacent known pixels with different ids is a crack
   of a contour (see :mod:`mi_npr.contours.trace`); the follower needs, for each crack, the two
   pixels ahead of it (and, to grow in both directions at once, the two behind it). Those are cast
   in one batch per round, for all contours together; new cracks among them ask for their own, and
   so on until nothing is missing. Each crack's whole contour is then known, so the crack cycles
   of the partial ID map are *exactly* the buffer-mode contours they belong to, and the same
   tracer (:func:`mi_npr.contours.trace.cycles`) orders them. A contour is found entirely or not
   at all.
4. **One start pixel per contour piece** (the paper keeps one per *object* and loses the other
   pieces): the refinement's 2x2 blocks give many candidate crack pixels per contour; each contour
   keeps its first pixel in raster order, the others are the same contour.

What can be missed: a contour is found when the contours connected to it (through shared crack
edges: an object, what it occludes and what occludes it) include a crack between two cast pixels.
Left out are only pieces that lie, with everything touching them, strictly between the rays of
step 1 and are not guarded by step 2: a thin object crossing the image diagonally, a hole smaller
than a macro pixel in a large object, a sliver of a large object visible through such a hole.
Measured on 40 random scenes of 12 spheres (half of them 1-10 pixels wide) at 160x120: without
the guard, 150 of 410 contours were missed (every one a whole small sphere) with 9.9% of the rays
cast; with it, none, with 12.3%. The tests check the scenes in ``scenes_xml/`` (every ``id_mode``)
and random sphere scenes for equality with buffer mode; the notebook counts the rays.

Every ray is the pixel-centre ray of the G-buffer pass, cast by :func:`mi_npr.raycast.cast`
(same rays, same intersection, same id lookup), so the ids equal the ``object_id`` layer's and
each pixel's id is cast at most once (a cache of known pixels).
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..raycast import cast, film_size, pixel_centres, pixel_rays
from ..scene import camera_of, merge_defines
from ..session import SceneSession
from .contour import Contour
from .idmode import IdMap, check_id_mode, id_map
from .trace import OUTSIDE, Grid, check_method, contours_from_grid, distinct

MACRO = 8


@dataclass
class TraceStats:
    """What :func:`trace_scene` did: rays cast, batches, and seconds per stage."""

    width: int
    height: int
    rays_cast: int = 0
    launches: int = 0  # batches of rays (one Dr.Jit launch each)
    rounds: int = 0  # following rounds (step 3)
    guarded_pixels: int = 0  # rays cast by the small-object guard (step 2)
    contours: int = 0  # = start pixels, one per contour piece
    times: dict[str, float] = field(default_factory=dict)  # stage -> seconds
    cast: np.ndarray | None = field(default=None, repr=False)  # (H, W) bool: pixels cast

    @property
    def ray_fraction(self) -> float:
        """``rays_cast / (width * height)``: 1.0 is what a full ID buffer casts."""
        return self.rays_cast / max(1, self.width * self.height)

    @property
    def total_time(self) -> float:
        return sum(self.times.values())


class Caster:
    """Computes pixel ids on demand into a :class:`~mi_npr.contours.trace.Grid`, each pixel at
    most once (the grid's ``known`` mask is the cache). Subclasses say how: :class:`RayCaster`
    casts pixel-centre rays, :class:`BufferCaster` reads an ID buffer (tests, what-if studies)."""

    def __init__(self, height: int, width: int):
        self.grid = Grid.empty(height, width)
        self.stats = TraceStats(width, height)

    def compute(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Ids (uint32) of pixels ``(x, y)``."""
        raise NotImplementedError

    def guard_boxes(self, macro: int = MACRO) -> np.ndarray | None:
        """(K, 4) film-space boxes ``x0, y0, x1, y1`` of objects that may hide between corner rays
        (step 2), or ``None`` when unknown."""
        return None

    def cast(self, idx: np.ndarray) -> np.ndarray:
        """Compute the unknown pixels among flat padded indices ``idx``; returns those computed."""
        g = self.grid
        assert g.known is not None
        idx = np.asarray(idx, np.int64).reshape(-1)
        idx = distinct(idx[~g.known[idx]])
        if len(idx) == 0:
            return idx
        g.ids[idx] = self.compute(idx % g.stride - 1, idx // g.stride - 1)
        g.known[idx] = True
        self.stats.rays_cast += len(idx)
        self.stats.launches += 1
        return idx


class BufferCaster(Caster):
    """Reads ids from an (H, W) buffer: ray-cast mode's logic without a scene."""

    def __init__(self, ids: np.ndarray):
        super().__init__(*ids.shape)
        self.ids = np.asarray(ids, np.uint32)

    def compute(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return self.ids[y, x]


class RayCaster(Caster):
    """Casts the G-buffer pass's pixel-centre rays (same intersection, same id lookup)."""

    def __init__(self, scene: mi.Scene, sensor: mi.Sensor, ids: IdMap):
        w, h = film_size(sensor)
        super().__init__(h, w)
        self.scene, self.sensor, self.ids = scene, sensor, ids

    def compute(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        ray = pixel_rays(self.sensor, *pixel_centres(x, y))
        hits = cast(self.scene, ray, self.ids.table)
        return np.asarray(hits.ids(self.ids).numpy(), np.uint32).reshape(-1)

    def guard_boxes(self, macro: int = MACRO) -> np.ndarray | None:
        """Pixel boxes of the shapes, and of the components of the meshes whose own box does
        not already cover them: a mesh whose box is guarded whole, or lies off the image, needs
        no component boxes (theirs lie inside its box, and project inside its projection)."""
        uv, front = self._project(self.ids.shape_boxes())
        if uv is None:
            return None
        _, _, small, off = pixel_rects(uv, self.grid.width, self.grid.height, macro)
        covered = front & (small | off)
        parts, _ = self.ids.part_boxes(np.flatnonzero(~covered) + 1)
        puv, pfront = self._project(parts)
        if puv is None:
            return None
        return np.concatenate([uv[front], puv[pfront]])

    def _project(self, boxes: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        """Film-space boxes (K, 4) ``u0, v0, u1, v1`` of world boxes (K, 2, 3), and which of
        them lie wholly in front of the camera (the others cannot be projected)."""
        if len(boxes) == 0:
            return np.zeros((0, 4)), np.zeros(0, dtype=bool)
        sel = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        corners = boxes[:, sel, [0, 1, 2]]  # (K, 8, 3)
        cam = camera_of(self.sensor)
        depth = (corners - cam.origin) @ cam.forward
        flat = corners.reshape(-1, 3).astype(np.float32)
        try:
            it = dr.zeros(mi.Interaction3f)
            it.p = mi.Point3f(*(mi.Float(flat[:, i]) for i in range(3)))
            ds, _ = self.sensor.sample_direction(it, mi.Point2f(0.5, 0.5))
            uv = np.asarray(ds.uv.numpy(), np.float64).T
        except Exception:  # no sample_direction (orthographic): parallel rays are affine
            uv = _affine_projection(self.sensor, corners.reshape(-1, 3))
            if uv is None:
                return None, np.zeros(0, dtype=bool)
        uv = uv.reshape(-1, 8, 2)
        front = (depth > cam.near_clip).all(axis=1) & np.isfinite(uv).all(axis=(1, 2))
        return np.concatenate([uv.min(axis=1), uv.max(axis=1)], axis=1), front


def pixel_rects(
    boxes: np.ndarray, width: int, height: int, macro: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 2's pixel rectangles of film-space boxes (K, 4): ``lo``, ``hi`` (K, 2) inclusive
    pixel corners, one pixel of margin, clipped to the image; ``small`` where at most two macro
    pixels wide or tall (guarded); ``off`` where nothing is left after clipping."""
    lo = np.maximum(np.floor(boxes[:, :2]) - 1, 0)
    hi = np.minimum(np.ceil(boxes[:, 2:]) + 1, [width - 1, height - 1])
    off = (hi < lo).any(axis=1)
    small = ((hi - lo) <= 2 * macro).any(axis=1) & ~off
    return lo, hi, small, off


def _affine_projection(sensor: mi.Sensor, points: np.ndarray) -> np.ndarray | None:
    """Film positions (pixels of the crop window) of world ``points`` for a sensor whose rays
    are parallel (an orthographic camera): the film point ``(u, v)`` casts from ``o + u a + v b``
    along ``d``, so ``p - o = u a + v b + t d`` is a 3x3 solve. ``None`` for any other sensor."""

    def ray(x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
        r = pixel_rays(sensor, mi.Float(x), mi.Float(y))
        o = np.asarray([float(dr.ravel(c)[0]) for c in (r.o.x, r.o.y, r.o.z)])
        d = np.asarray([float(dr.ravel(c)[0]) for c in (r.d.x, r.d.y, r.d.z)])
        return o, d

    (o, d), (ox, dx), (oy, dy) = ray(0.0, 0.0), ray(1.0, 0.0), ray(0.0, 1.0)
    if not (np.allclose(d, dx, atol=1e-6) and np.allclose(d, dy, atol=1e-6)):
        return None  # rays from a point (a camera model without sample_direction): no guard
    M = np.stack([ox - o, oy - o, d], axis=1)
    if abs(np.linalg.det(M)) < 1e-30:
        return None
    uvt = np.linalg.solve(M, (np.asarray(points, np.float64) - o).T).T
    return uvt[:, :2]


def _grid_points(n: int, step: int) -> np.ndarray:
    return distinct(np.r_[np.arange(0, n, step), n - 1])


def refine(caster: Caster, macro: int = MACRO) -> np.ndarray:
    """Step 1: macro-pixel corners, then the split blocks' new corners; every pixel cast."""
    g = caster.grid
    xs, ys = _grid_points(g.width, macro), _grid_points(g.height, macro)
    gx, gy = np.meshgrid(xs, ys)
    cast = [caster.cast(g.index(gx.ravel(), gy.ravel()))]
    x0, x1 = (xs[:-1], xs[1:]) if len(xs) > 1 else (xs, xs)
    y0, y1 = (ys[:-1], ys[1:]) if len(ys) > 1 else (ys, ys)
    bx0, by0 = (a.ravel() for a in np.meshgrid(x0, y0))
    bx1, by1 = (a.ravel() for a in np.meshgrid(x1, y1))
    while len(bx0):
        c = [g.ids[g.index(x, y)] for x, y in ((bx0, by0), (bx1, by0), (bx0, by1), (bx1, by1))]
        differ = (c[0] != c[1]) | (c[0] != c[2]) | (c[0] != c[3])
        sx, sy = (bx1 - bx0) > 1, (by1 - by0) > 1
        keep = differ & (sx | sy)
        bx0, bx1, by0, by1, sx, sy = (a[keep] for a in (bx0, bx1, by0, by1, sx, sy))
        # Split each kept block in two along each axis longer than one pixel step.
        bx0, bx1, by0, by1, sy = _halves(bx0, bx1, sx, by0, by1, sy)
        by0, by1, bx0, bx1 = _halves(by0, by1, sy, bx0, bx1)
        if len(bx0) == 0:
            break
        pts_x = np.concatenate([bx0, bx1, bx0, bx1])
        pts_y = np.concatenate([by0, by0, by1, by1])
        cast.append(caster.cast(g.index(pts_x, pts_y)))
    return np.concatenate(cast)


def _halves(a0: np.ndarray, a1: np.ndarray, split: np.ndarray, *rest: np.ndarray):
    """Intervals [a0, a1] cut at their midpoint where ``split``; ``rest`` arrays follow along."""
    n = 1 + split.astype(np.int64)
    rep = np.repeat(np.arange(len(a0)), n)
    second = np.ones(len(rep), dtype=bool)
    if len(rep):
        second[np.r_[0, np.cumsum(n)[:-1]]] = False
    mid = (a0 + a1) // 2
    lo = np.where(second, mid[rep], a0[rep])
    hi = np.where(split[rep] & ~second, mid[rep], a1[rep])
    return (lo, hi, *(r[rep] for r in rest))


def guard_pixels(caster: Caster, macro: int = MACRO) -> np.ndarray:
    """Step 2: cast every pixel of the boxes of objects that can hide between corner rays."""
    g = caster.grid
    boxes = caster.guard_boxes(macro)
    if boxes is None or len(boxes) == 0:
        return np.zeros(0, np.int64)
    lo, hi, small, _ = pixel_rects(boxes, g.width, g.height, macro)
    return caster.cast(g.index(*rect_pixels(lo[small], hi[small])))


def rect_pixels(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel ``(x, y)`` of the inclusive rectangles ``lo``..``hi`` ((K, 2) each)."""
    lo, hi = np.asarray(lo, np.int64).reshape(-1, 2), np.asarray(hi, np.int64).reshape(-1, 2)
    bw, bh = (hi - lo + 1).T
    n = bw * bh
    box = np.repeat(np.arange(len(n)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    return lo[box, 0] + k % bw[box], lo[box, 1] + k // bw[box]


def follow(caster: Caster, new: np.ndarray) -> None:
    """Step 3: cast the pixels ahead of and behind every known crack until none is missing."""
    g = caster.grid
    assert g.known is not None
    off = g.offsets4()
    while len(new):
        ids_new = g.ids[new]
        pix, side = [], []
        for d in range(4):
            q = new + off[d]
            ok = g.known[q] & (g.ids[q] != ids_new)
            mine = ok & (ids_new != 0)
            pix.append(new[mine])
            side.append(np.full(int(mine.sum()), d))
            idq = g.ids[q]
            theirs = ok & (idq != 0) & (idq != OUTSIDE)
            pix.append(q[theirs])
            side.append(np.full(int(theirs.sum()), (d + 2) & 3))
        p = np.concatenate(pix)
        s = np.concatenate(side).astype(np.int64)
        t = off[(s + 1) & 3]
        ahead, behind = p + t, p - t
        need = np.concatenate([ahead, ahead + off[s], behind, behind + off[s]])
        new = caster.cast(need)
        caster.stats.rounds += 1


def trace_scene(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int | mi.Sensor = 0,
    method: str = "border",
    id_mode: str = "shape",
    macro: int = MACRO,
    guard: bool = True,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> tuple[list[Contour], TraceStats]:
    """The contours of ``scene`` seen by ``sensor``, by ray casting (module docstring).

    ``scene``: a loaded ``mi.Scene`` or an XML path (``defines`` fill its ``<default>``s).
    ``method``: ``"border"`` or ``"code_direction"`` (:mod:`mi_npr.contours.trace`). ``id_mode``:
    ``"shape"``, ``"primitive"`` or ``"component"`` (:mod:`mi_npr.contours.idmode`). ``macro``:
    the macro-pixel size (8 in the paper). ``guard``: cast small objects' boxes (step 2).

    Returns the same contours as :func:`mi_npr.contours.trace` on the scene's G-buffer ids, and a
    :class:`TraceStats` (``rays_cast``, ``ray_fraction``, ``times`` per stage in seconds).

    >>> path = "scenes_xml/scene2.xml"
    >>> contours, stats = trace_scene(path, width=160, height=120)  # doctest: +SKIP
    >>> stats.rays_cast, stats.ray_fraction, stats.times            # doctest: +SKIP
    """
    check_method(method)
    check_id_mode(id_mode)
    check_macro(macro)
    t0 = time.perf_counter()
    session = SceneSession.open(scene, sensor=sensor, defines=merge_defines(defines, more))
    with session.step("ray casting"):
        ids = id_map(session.scene, id_mode, session.objects)
        caster = RayCaster(session.scene, session.sensor, ids)
        setup = time.perf_counter() - t0
        contours, stats = run(caster, ids.names, method=method, macro=macro, guard=guard)
    stats.times = {"setup": setup, **stats.times}
    return contours, stats


def check_macro(macro: int) -> int:
    if not isinstance(macro, int) or isinstance(macro, bool) or macro < 1:
        raise ParameterError(f"macro = {macro!r}: must be a positive integer")
    return macro


def run(
    caster: Caster,
    names: Mapping[int, str] | None,
    *,
    method: str = "border",
    macro: int = MACRO,
    guard: bool = True,
) -> tuple[list[Contour], TraceStats]:
    """Steps 1-4 of the module docstring with any :class:`Caster`; names for the contours."""
    stats = caster.stats
    t0 = time.perf_counter()
    known = [refine(caster, macro)]
    t1 = time.perf_counter()
    stats.times["refine"] = t1 - t0
    if guard:
        before = stats.rays_cast
        known.append(guard_pixels(caster, macro))
        stats.guarded_pixels = stats.rays_cast - before
    t2 = time.perf_counter()
    stats.times["guard"] = t2 - t1
    follow(caster, np.concatenate(known))
    t3 = time.perf_counter()
    stats.times["follow"] = t3 - t2
    contours = contours_from_grid(
        caster.grid, names, method, fetch=lambda need: caster.cast(np.asarray(need))
    )
    stats.times["trace"] = time.perf_counter() - t3
    stats.contours = len(contours)
    g = caster.grid
    assert g.known is not None
    stats.cast = g.known.reshape(g.height + 2, g.stride)[1:-1, 1:-1].copy()
    return contours, stats
