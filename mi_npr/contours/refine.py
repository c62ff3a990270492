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
   and other sensors without ``sample_direction``, are not guarded. A mesh's component boxes
   are projected only where its own box does not already cover them (a guarded box, or one
   off the image, holds theirs); the components of all meshes are found in one vectorised
   pass and kept per mesh (:mod:`mi_npr.contours.parts`), so a scene's later calls reuse them.
3. **Following** (section 3.2). Every pair of 4-adjacent known pixels with different ids is a crack
   of a contour (see :mod:`mi_npr.contours.trace`); the follower needs, for each crack, the two
   pixels ahead of it (and, to grow in both directions at once, the two behind it). Those are cast
   in one batch per round, for all contours together; new cracks among them ask for their own, and
   so on until nothing is missing. Each crack's whole contour is then known, so the crack cycles
   of the partial ID map are *exactly* the buffer-mode contours they belong to, and the same
   tracer (:func:`mi_npr.contours.trace.cycles`) orders them, once the seams of the G-buffer
   pass are closed on the ids cast (:func:`close_seams`). A contour is found entirely or not
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

**Batches in Dr.Jit.** The cache is two Dr.Jit arrays over the padded grid of
:class:`~mi_npr.contours.trace.Grid` (``ids``, and ``known``: the outside ring is known), and
every batch is built, deduplicated and cast without leaving Dr.Jit (:meth:`Caster.cast_jit`):
the candidate pixels of a batch are a ``UInt32`` array with repeats; those not known yet scatter
their lane number into a per-pixel slot and the lane whose number stays is the one that casts
(one lane per pixel), ``dr.compress`` lists them, :func:`~mi_npr.raycast.cast` intersects
their rays, and two scatters fill the cache. A refinement level is the blocks of the level as
``UInt32`` arrays: each block gives four child lanes, and the children that exist (the block's
corners differ, and it is longer than one pixel step along that axis) are compressed; their
corners are the next batch. A following round takes the pixels cast last, 8 lanes each (the
cracks on its four sides and on its neighbours' sides facing it; 4 in the first round, when
every known pixel is in it), compresses the cracks that exist and asks for their 4 pixels each.
Host synchronisations are the ``dr.compress`` calls (two per level and per round); the cost
follows the number of pixels a batch looks at, not the image size. The cracks
of the final partial map are found in Dr.Jit too, and the cache is read back once for the
contour tracer (:func:`~mi_npr.contours.trace.contours_from_grid`, numpy and scipy); the paper's
walk (``method="code_direction"``) may still ask for more pixels, cast the same way.
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

from ..camera import projection_of
from ..errors import ParameterError
from ..raycast import SEAM_OFFSET, cast, film_size, pixel_centres, pixel_rays
from ..scene import merge_defines
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
    """Computes pixel ids on demand, each pixel at most once. The cache is two Dr.Jit arrays of
    the padded grid's layout (:class:`~mi_npr.contours.trace.Grid`): ``ids`` and ``known``;
    :attr:`grid` reads them back for the contour tracer. Subclasses say how ids are computed:
    :class:`RayCaster` casts pixel-centre rays, :class:`BufferCaster` reads an ID buffer (tests,
    what-if studies)."""

    def __init__(self, height: int, width: int):
        self.height, self.width, self.stride = height, width, width + 2
        empty = Grid.empty(height, width)
        assert empty.known is not None
        self.ids = mi.UInt32(empty.ids)  # padded ids; the ring is OUTSIDE
        self.known = mi.Bool(empty.known)  # the ring is known
        # one lane per pixel (cast_jit); all ones between batches
        self._claim = dr.full(mi.UInt32, 0xFFFFFFFF, len(empty.ids))
        s = self.stride
        self.offsets = mi.UInt32(np.array([1, s, -1, -s], np.int64).astype(np.uint32))
        self._grid: Grid | None = None
        self._cast: list[mi.UInt32] = []  # the pixels computed, one array per batch
        self.stats = TraceStats(width, height)

    def compute_jit(self, pix: mi.UInt32) -> mi.UInt32:
        """Ids of the pixels at flat padded indices ``pix`` (all distinct and inside)."""
        raise NotImplementedError

    def guard_boxes(self, macro: int = MACRO) -> np.ndarray | None:
        """(K, 4) film-space boxes ``x0, y0, x1, y1`` of objects that may hide between corner rays
        (step 2), or ``None`` when unknown."""
        return None

    def seam_ids(self, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
        """(4, K) ids of the rays a hair from the centres of pixels ``(x, y)`` along the four
        diagonals (:func:`close_seams`), or ``None`` when this caster cannot cast them."""
        return None

    def set_ids(self, x: np.ndarray, y: np.ndarray, ids: np.ndarray) -> None:
        """Replace the ids of known pixels ``(x, y)``."""
        pix = self.index(x, y)
        dr.scatter(self.ids, mi.UInt32(np.ascontiguousarray(ids, np.uint32)), pix)
        dr.eval(self.ids)
        self._grid = None

    def index(self, x: Any, y: Any) -> mi.UInt32:
        """Flat padded index of pixels ``(x, y)`` (numpy or Dr.Jit integers)."""
        if isinstance(x, np.ndarray):
            x = mi.UInt32(np.ascontiguousarray(x, np.uint32).reshape(-1))
            y = mi.UInt32(np.ascontiguousarray(y, np.uint32).reshape(-1))
        if dr.width(x) == 0:
            return mi.UInt32()
        return (y + 1) * self.stride + x + 1

    def cast_jit(self, pix: mi.UInt32, active: mi.Bool | bool = True) -> mi.UInt32:
        """Compute the unknown pixels among flat padded indices ``pix`` (active lanes; repeats
        allowed) in one batch; returns the distinct pixels computed."""
        if dr.width(pix) == 0:
            return mi.UInt32()
        dr.eval(pix)  # what follows is then the same kernels for every caller (compiled once)
        new = self._unknown(pix, mi.Bool(active))
        n = dr.width(new)
        if n == 0:
            return new
        # Nothing else refers to ids / known now: the scatters write in place (no copy).
        dr.scatter(self.ids, self.compute_jit(new), new)
        dr.scatter(self.known, True, new)
        dr.scatter(self._claim, 0xFFFFFFFF, new)  # every slot this batch claimed, reset
        dr.eval(self.ids, self.known, self._claim)
        self._grid = None
        self._cast.append(new)
        self.stats.rays_cast += n
        self.stats.launches += 1
        return new

    def _unknown(self, pix: mi.UInt32, active: mi.Bool) -> mi.UInt32:
        """The distinct unknown pixels among the active ``pix``, in the order of their first
        lane: the smallest lane number of each pixel is kept in one slot per pixel (an atomic
        minimum into slots that are all ones between batches, not a racing plain scatter, so
        the batch, and the order its rays are traced in, is the same on every run whatever the
        threads do)."""
        need = active & ~dr.gather(mi.Bool, self.known, pix, active)
        lane = dr.arange(mi.UInt32, dr.width(pix))
        dr.scatter_reduce(dr.ReduceOp.Min, self._claim, lane, pix, need, mode=dr.ReduceMode.Direct)
        win = need & (dr.gather(mi.UInt32, self._claim, pix, need) == lane)
        return dr.gather(mi.UInt32, pix, dr.compress(win))  # evaluated with the cast

    def cast_so_far(self) -> mi.UInt32:
        """Every pixel computed so far (flat padded indices, each once)."""
        if not self._cast:
            return mi.UInt32()
        if len(self._cast) > 1:
            self._cast = [dr.concat(self._cast)]
        return self._cast[0]

    def cracks(self) -> tuple[np.ndarray, np.ndarray]:
        """The cracks among the pixels computed so far (:func:`~mi_npr.contours.trace.cycles`'s
        partial-grid rule: an object pixel and a known 4-neighbour of another id), as numpy
        ``(pixel, side)`` sorted by ``pixel * 4 + side``; found in Dr.Jit, sorted in numpy."""
        U = mi.UInt32
        done = self.cast_so_far()
        if dr.width(done) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        lane = dr.arange(U, 4 * dr.width(done))
        p = dr.gather(U, done, lane >> 2)
        q = p + dr.gather(U, self.offsets, lane & 3)
        k = dr.gather(U, self.ids, p)
        crack = (k != 0) & dr.gather(mi.Bool, self.known, q) & (dr.gather(U, self.ids, q) != k)
        sel = dr.compress(crack)
        if dr.width(sel) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        key = dr.gather(U, done, sel >> 2) * 4 + (sel & 3)
        key = np.sort(np.asarray(key.numpy(), np.int64))
        return key >> 2, key & 3

    @property
    def grid(self) -> Grid:
        """The cache read back as a numpy :class:`~mi_npr.contours.trace.Grid` (ids, known)."""
        if self._grid is None:
            ids = np.array(self.ids.numpy(), np.uint32)
            known = np.array(self.known.numpy(), bool)
            self._grid = Grid(self.height, self.width, ids, known)
        return self._grid

    def cast(self, idx: np.ndarray) -> np.ndarray:
        """Compute the unknown pixels among flat padded indices ``idx`` (numpy); returns those
        computed, sorted. The numpy :attr:`grid` is updated in place (the contour tracer's
        ``fetch``)."""
        g = self.grid
        new = self.cast_jit(mi.UInt32(np.asarray(idx, np.int64).reshape(-1).astype(np.uint32)))
        done = np.asarray(new.numpy(), np.int64)
        if len(done):
            assert g.known is not None
            g.ids[done] = np.asarray(dr.gather(mi.UInt32, self.ids, new).numpy())
            g.known[done] = True
        self._grid = g
        return np.sort(done)


class BufferCaster(Caster):
    """Reads ids from an (H, W) buffer: ray-cast mode's logic without a scene."""

    def __init__(self, ids: np.ndarray):
        super().__init__(*ids.shape)
        self.buffer = mi.UInt32(np.ascontiguousarray(ids, np.uint32).reshape(-1))

    def compute_jit(self, pix: mi.UInt32) -> mi.UInt32:
        x, y = pix % self.stride - 1, pix // self.stride - 1
        return dr.gather(mi.UInt32, self.buffer, y * self.width + x)


class RayCaster(Caster):
    """Casts the G-buffer pass's pixel-centre rays (same intersection, same id lookup)."""

    def __init__(self, scene: mi.Scene, sensor: mi.Sensor, ids: IdMap):
        w, h = film_size(sensor)
        super().__init__(h, w)
        self.scene, self.sensor, self.id_map = scene, sensor, ids

    def compute_jit(self, pix: mi.UInt32) -> mi.UInt32:
        ray = pixel_rays(self.sensor, *pixel_centres(pix % self.stride - 1, pix // self.stride - 1))
        return cast(self.scene, ray, self.id_map.table).ids(self.id_map)

    def seam_ids(self, x: np.ndarray, y: np.ndarray) -> np.ndarray | None:
        e = SEAM_OFFSET
        offsets = ((e, e), (-e, e), (e, -e), (-e, -e))
        fx = np.concatenate([x + 0.5 + ox for ox, _ in offsets]).astype(np.float32)
        fy = np.concatenate([y + 0.5 + oy for _, oy in offsets]).astype(np.float32)
        ray = pixel_rays(self.sensor, mi.Float(fx), mi.Float(fy))
        ids = cast(self.scene, ray, self.id_map.table).ids(self.id_map)
        return np.asarray(ids.numpy(), np.uint32).reshape(4, -1)

    def guard_boxes(self, macro: int = MACRO) -> np.ndarray | None:
        """Pixel boxes of the shapes, and of the components of the meshes whose own box does
        not already cover them: a mesh whose box is guarded whole, or lies off the image, needs
        no component boxes (theirs lie inside its box, and project inside its projection)."""
        uv, front = self._project(self.id_map.shape_boxes())
        if uv is None:
            return None
        _, _, small, off = pixel_rects(uv, self.grid.width, self.grid.height, macro)
        covered = front & (small | off)
        parts, _ = self.id_map.part_boxes(np.flatnonzero(~covered) + 1)
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
        cam = projection_of(self.sensor)
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


def refine(caster: Caster, macro: int = MACRO) -> None:
    """Step 1: macro-pixel corners, then the split blocks' new corners, one batch per level.
    The blocks of a level are Dr.Jit arrays: each block gives four child lanes, the ones that
    exist (the block splits, along an axis longer than one pixel step) are compressed."""
    w, h = caster.width, caster.height
    xs, ys = _grid_points(w, macro), _grid_points(h, macro)
    gx, gy = np.meshgrid(xs, ys)
    caster.cast_jit(caster.index(gx, gy))
    x0, x1 = (xs[:-1], xs[1:]) if len(xs) > 1 else (xs, xs)
    y0, y1 = (ys[:-1], ys[1:]) if len(ys) > 1 else (ys, ys)
    bx0, by0 = (mi.UInt32(a.ravel().astype(np.uint32)) for a in np.meshgrid(x0, y0))
    bx1, by1 = (mi.UInt32(a.ravel().astype(np.uint32)) for a in np.meshgrid(x1, y1))
    while dr.width(bx0):
        bx0, bx1, by0, by1 = _split(caster, bx0, bx1, by0, by1)
        if dr.width(bx0) == 0:
            break
        corner = dr.arange(mi.UInt32, 4 * dr.width(bx0))
        blk = corner >> 2
        px = dr.select(
            (corner & 1) != 0, dr.gather(mi.UInt32, bx1, blk), dr.gather(mi.UInt32, bx0, blk)
        )
        py = dr.select(
            (corner & 2) != 0, dr.gather(mi.UInt32, by1, blk), dr.gather(mi.UInt32, by0, blk)
        )
        caster.cast_jit(caster.index(px, py))


def _split(caster: Caster, bx0: Any, bx1: Any, by0: Any, by1: Any) -> tuple[Any, Any, Any, Any]:
    """The child blocks of one refinement level (evaluated): a block whose four corners differ
    splits in two along each axis longer than one pixel step. Four lanes per block, one per
    possible child; the ones that exist are compressed."""
    U = mi.UInt32
    lane = dr.arange(U, 4 * dr.width(bx0))
    b, kx, ky = lane >> 2, (lane & 1) != 0, (lane & 2) != 0
    X0, X1, Y0, Y1 = (dr.gather(U, a, b) for a in (bx0, bx1, by0, by1))
    c = [
        dr.gather(U, caster.ids, caster.index(x, y))
        for x, y in ((X0, Y0), (X1, Y0), (X0, Y1), (X1, Y1))
    ]
    sx, sy = (X1 - X0) > 1, (Y1 - Y0) > 1
    keep = ((c[0] != c[1]) | (c[0] != c[2]) | (c[0] != c[3])) & (sx | sy)
    sel = dr.compress(keep & (~kx | sx) & (~ky | sy))
    if dr.width(sel) == 0:
        return U(), U(), U(), U()
    b, kx, ky = sel >> 2, (sel & 1) != 0, (sel & 2) != 0
    X0, X1, Y0, Y1 = (dr.gather(U, a, b) for a in (bx0, bx1, by0, by1))
    mx, my = (X0 + X1) >> 1, (Y0 + Y1) >> 1
    out = (
        dr.select(kx, mx, X0),
        dr.select(((X1 - X0) > 1) & ~kx, mx, X1),
        dr.select(ky, my, Y0),
        dr.select(((Y1 - Y0) > 1) & ~ky, my, Y1),
    )
    dr.eval(out)
    return out


def guard_pixels(caster: Caster, macro: int = MACRO) -> None:
    """Step 2: cast every pixel of the boxes of objects that can hide between corner rays."""
    boxes = caster.guard_boxes(macro)
    if boxes is None or len(boxes) == 0:
        return
    lo, hi, small, _ = pixel_rects(boxes, caster.width, caster.height, macro)
    caster.cast_jit(caster.index(*rect_pixels(lo[small], hi[small])))


def rect_pixels(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel ``(x, y)`` of the inclusive rectangles ``lo``..``hi`` ((K, 2) each)."""
    lo, hi = np.asarray(lo, np.int64).reshape(-1, 2), np.asarray(hi, np.int64).reshape(-1, 2)
    bw, bh = (hi - lo + 1).T
    n = bw * bh
    box = np.repeat(np.arange(len(n)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    return lo[box, 0] + k % bw[box], lo[box, 1] + k // bw[box]


def follow(caster: Caster) -> None:
    """Step 3: cast the pixels ahead of and behind every known crack until none is missing.
    Each round looks at the pixels cast last (first: every pixel known), in Dr.Jit: 8 lanes per
    pixel (4 sides, the crack on this pixel's side or on the neighbour's), the cracks that exist
    are compressed, and each asks for its 4 pixels in one batch."""
    new = caster.cast_so_far()
    first = True
    while dr.width(new):
        # First round: every known pixel is in ``new``, so a neighbour's crack is its own.
        need = _crack_needs(caster, new, both=not first)
        first = False
        new = caster.cast_jit(need) if need is not None else mi.UInt32()
        caster.stats.rounds += 1


def _crack_needs(caster: Caster, new: mi.UInt32, both: bool = True) -> mi.UInt32 | None:
    """The pixels ahead of and behind the cracks of pixels ``new`` (repeats, known ones
    included); ``None`` when they have no crack. ``both``: also the cracks of their neighbours
    on the sides facing them (else only the cracks on the pixels' own sides)."""
    U = mi.UInt32
    out = int(OUTSIDE)
    offs = caster.offsets
    shift = 3 if both else 2  # lanes per pixel: 4 sides (x 2 with the neighbours' cracks)
    lane = dr.arange(U, dr.width(new) << shift)
    p = dr.gather(U, new, lane >> shift)
    d = (lane >> (shift - 2)) & 3
    q = p + dr.gather(U, offs, d)
    idp, idq = dr.gather(U, caster.ids, p), dr.gather(U, caster.ids, q)
    ok = dr.gather(mi.Bool, caster.known, q) & (idq != idp)
    theirs = ((lane & 1) != 0) if both else mi.Bool(False)  # q's crack, on its side d + 2
    sel = dr.compress(ok & dr.select(theirs, (idq != 0) & (idq != out), idp != 0))
    if dr.width(sel) == 0:
        return None
    k = dr.arange(U, 4 * dr.width(sel))  # 4 lanes per crack: ahead, ahead + side, behind, ...
    c = dr.gather(U, sel, k >> 2)
    theirs = ((c & 1) != 0) if both else mi.Bool(False)
    d = (c >> (shift - 2)) & 3
    p = dr.gather(U, new, c >> shift)
    crack = dr.select(theirs, p + dr.gather(U, offs, d), p)
    side = dr.select(theirs, (d + 2) & 3, d)
    t = dr.gather(U, offs, (side + 1) & 3)
    base = dr.select((k & 2) == 0, crack + t, crack - t)  # ahead, behind
    return dr.select((k & 1) != 0, base + dr.gather(U, offs, side), base)


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

    >>> contours, stats = trace_scene("scenes_xml/scene2.xml", width=64, height=48)
    >>> [c.name for c in contours]
    ['back_wall', 'floor', 'sphere_left', 'sphere_middle', 'sphere_right']
    >>> stats.rays_cast < stats.width * stats.height  # fewer rays than pixels
    True
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


def close_seams(caster: Caster) -> int:
    """The seam rule of :mod:`mi_npr.render` on the ids cast so far: a known pixel whose known
    4-neighbours inside the image (at least two) all have one non-background id it does not
    have takes that id when a ray a hair from its centre sees it. Ray-cast contours then equal
    buffer mode's, whose G-buffer closes the same seams (this mode has no depths, so the
    neighbours' depth range is not checked, and in the ``primitive`` mode the two triangles of
    a seam never agree). Returns the number of pixels changed."""
    g = caster.grid
    if g.known is None:
        return 0
    s, h, w = g.stride, g.height, g.width
    ids = g.ids.reshape(h + 2, s)
    known = g.known.reshape(h + 2, s)
    centre, ck = ids[1:-1, 1:-1], known[1:-1, 1:-1]
    sides = [(ids[1:-1, 2:], known[1:-1, 2:]), (ids[1:-1, :-2], known[1:-1, :-2])]
    sides += [(ids[2:, 1:-1], known[2:, 1:-1]), (ids[:-2, 1:-1], known[:-2, 1:-1])]
    # a pixel the rule changes differs from a known neighbour inside the image (the one its
    # id would come from): the rule is evaluated at those pixels alone
    differs = np.zeros((h, w), bool)
    for v, k in sides:
        differs |= k & (v != centre) & (v != OUTSIDE)
    ys, xs = np.nonzero(ck & differs)
    vals = [(v[ys, xs], k[ys, xs]) for v, k in sides]
    inside = [k & (v != OUTSIDE) for v, k in vals]
    ref = np.full(len(xs), OUTSIDE, np.uint32)
    for (v, _), ok in zip(vals, inside, strict=True):
        ref = np.where((ref == OUTSIDE) & ok, v, ref)
    agree = np.ones(len(xs), bool)
    count = np.zeros(len(xs), np.int64)
    for (v, k), ok in zip(vals, inside, strict=True):
        agree &= ~(v != OUTSIDE) | (k & (v == ref))  # an unknown neighbour: no verdict
        count += ok
    cand = agree & (count >= 2) & (ref != 0) & (ref != OUTSIDE) & (centre[ys, xs] != ref)
    ys, xs, want = ys[cand], xs[cand], ref[cand]
    if len(xs) == 0:
        return 0
    again = caster.seam_ids(xs, ys)
    if again is None:
        return 0
    hit = np.any(again == want[None, :], axis=0)
    if hit.any():
        caster.set_ids(xs[hit], ys[hit], want[hit])
    return int(hit.sum())


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
    refine(caster, macro)
    t1 = time.perf_counter()
    stats.times["refine"] = t1 - t0
    if guard:
        before = stats.rays_cast
        guard_pixels(caster, macro)
        stats.guarded_pixels = stats.rays_cast - before
    t2 = time.perf_counter()
    stats.times["guard"] = t2 - t1
    follow(caster)
    close_seams(caster)
    t3 = time.perf_counter()
    stats.times["follow"] = t3 - t2
    g = caster.grid  # the one read-back of the cache
    contours = contours_from_grid(
        g, names, method, fetch=lambda need: caster.cast(np.asarray(need)), cracks=caster.cracks()
    )
    stats.times["trace"] = time.perf_counter() - t3
    stats.contours = len(contours)
    assert g.known is not None
    stats.cast = g.known.reshape(g.height + 2, g.stride)[1:-1, 1:-1].copy()
    return contours, stats
