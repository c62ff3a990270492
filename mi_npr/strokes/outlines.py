"""Image-space outlines of the shapes that are not meshes (Mitsuba's ``sphere``, ``cylinder``,
``disk``, ``sdfgrid``, curves, instances...), exact to a fraction of a pixel.

**Which shapes.** Meshes get their silhouettes in object space (:mod:`mi_npr.strokes.edges`);
every other shape gets its outline here, so no outline is drawn twice: in the id image that is
traced, every mesh reads as background.

**Which outlines.** An object ``k``'s outline lies in front of something else (another object,
the background: the *id outline*, where the id image changes) or in front of ``k`` itself (the
*self-occlusion outline*, the same id on both sides: the rim of an open cylinder before its
inner wall, the inner limb of a torus before its far side, a curve crossing itself, one shape
of a shape group before another), where the depth steps within ``k``.

**Two id images.** The first sees through glass: each pixel-centre ray
(:func:`mi_npr.raycast.pixel_rays`) keeps the first surface that is neither glass nor ``null``
(:func:`mi_npr.strokes.visibility.first_opaque_hit`), so a sphere behind a glass pane keeps its
outline, marked ``through_glass``; in it only the opaque shapes that are not meshes have ids.
The second stops at glass (only ``null`` surfaces are passed) and gives ids to the glass shapes
that are not meshes alone: their own outlines, seen where nothing opaque is in front of them.
The depth of each image is that of its hits (along the view axis, the ``Z`` layer's).

**Id outlines.** Their vertices come from :func:`mi_npr.contours.vectorize` (crack cycles of
the id image, one vertex per crack bisected along the crack with ``ITERATIONS`` extra rays:
within ``2**-14`` px of the outline), with no simplification there.

**Self-occlusion outlines** (:func:`depth_step_paths`), one vertex per crack of the pixel grid
that they cross:

- *Seeds*: the depth steps of the ``lines`` drawing (:func:`step_cracks`): 4-neighbours of one
  id whose normalised depths (:func:`mi_npr.kernels.chain.depth_field`: eq. 5.1's, the
  background at 2) differ by more than eq. 5.1's ``t / c``
  (:func:`~mi_npr.kernels.chain.depth_step`, the drawing's defaults: 2.5 % of the frame's
  depth range), the near pixel being the one that owns the step
  (:func:`mi_npr.kernels.edges.owns`). Not on a lone sphere or disk
  (:func:`can_self_occlude`): convex or flat, it never hides a part of itself, and a step
  next to its limb is a steep slope, which the confirmation below would refuse.
- *Location*: ``ITERATIONS`` halvings of the segment between the two pixel centres, each
  keeping the half whose ends differ more in depth (a point that does not see ``k`` lies
  beyond the near side); then the step is *confirmed*: towards the near pixel ``k`` is seen,
  towards the far one a surface farther by ``RISE`` (or nothing) at ``STEP_PROBE`` px, and the
  depths differ by at least three quarters of that at ``STEP_PROBE / 4`` px (a step's
  difference stays, a smooth surface's shrinks with the distance, near a limb as its square
  root: to a half). A steep slope of one surface is no outline. ``STEP_PROBE`` (0.02 px) lies
  beyond the rounding of the intersections at a rim seen at a grazing angle, which flip
  between its two sides within about 0.002 px of it: the vertex lies in that band.
- *Following*: from the ends of the confirmed steps, every crack within ``GROW`` px (of one
  id, the nearer pixel first) is located and confirmed the same way, in rounds, until a round
  confirms nothing new (at most ``GROW_ROUNDS``). So an outline that is a depth line somewhere
  is drawn on where its step is fainter (towards the point where a tube's rim meets its side,
  the step fades to nothing); one that never is, is not drawn.
- *Chaining*: two confirmed cracks that meet at a pixel corner are joined; of three, the two
  opposite ones, and the third to the nearer of them (a T); of four, each to its opposite (a
  crossing). Where an outline runs through pixel centres, a pixel on it reads either side and
  two of its cracks may share no corner: the ends of two chains of one object within
  ``BRIDGE`` px are joined too, the nearest first.
  :func:`mi_npr.strokes.chain.chain_order` (at any turn) makes the paths.

Where a self-occlusion outline runs between the pixel centres and an id outline, within a
pixel of it, no crack crosses it, and it is not drawn: a tube's rim ends a few pixels before
the point where it touches the side outline (tangentially), within a pixel of that outline.

**Kinds.** Each vertex is then *probed*: two rays at ``PROBE`` px (``STEP_PROBE`` px for a
self-occlusion outline) on either side of the outline, across its local tangent; where both
rays of an id outline's vertex see its object, or neither does (rays grazing a limb flip
between hit and miss within a band that widens, in pixels, with the resolution: an open
cylinder's side at 1280 x 960), the two are cast again at each of ``WIDER`` px in turn until
one side sees it and the other does not. The *inside*
is the side that sees ``k`` (of an id outline), or the nearer side (of a self-occlusion
outline: it must see ``k``); its hit gives the vertex's 3-D position, depth and primitive. A
vertex is on ``k``'s own outline (and kept) when the outside sees nothing or a surface
farther than the inside one (by more than ``RISE``); it is a **silhouette** where the
inside surface is seen edge-on, ``|n . d| < GRAZING`` (``n`` its normal, ``d`` the ray: the
surface turns away; a sphere's limb: at ``PROBE`` px inside the limb of a sphere of radius
``R`` px, ``|n . d|`` is about ``sqrt(2 PROBE / R)``, 0.014 for ``R = 20``; 0.045 at
``STEP_PROBE``), else a **border** (an open edge: the rim of a disk, of an
open cylinder, in front of the background or of its own inner wall). Near the point where a
rim meets a silhouette, the surface inside the rim grazes too: those last pixels of the rim
are silhouettes. Being seen edge-on is not enough to keep a vertex: where an outline meets a
nearer object's, the vertices within a pixel of the meeting point lie near the limb but on the
nearer object's outline.

A vertex whose outside probe sees another object at the inside's depth (within ``RISE``) is
on an **intersection**: the object meets that one there (a sphere sunk into a floor, two
spheres through each other). It is drawn from the outline of the smaller object id when both
have outlines here (both are not meshes), so once; mesh-mesh intersections come from
:mod:`~mi_npr.strokes.intersect`. Otherwise the object is cut by something in front (its
outline there is the other object's) and the vertex is dropped. Runs of kept vertices of one
kind and one glass state are the strokes (a whole kept cycle: a closed stroke), simplified by
Douglas-Peucker at ``TOLERANCE`` px (kept vertices stay on the outline). These strokes are
visible by construction: ``qi = 0``; the hidden part of such an outline is not drawn.
"""

from __future__ import annotations

from collections.abc import Callable

import drjit as dr
import mitsuba as mi
import numpy as np

from ..contours.vector import VectorPath, douglas_peucker, vectorize
from ..gbuffer import Projection
from ..kernels.chain import depth_field, depth_step
from ..kernels.edges import owns
from ..raycast import film_grid, pixel_rays
from ..scene import ObjectTable
from .chain import chain_order
from .model import Stroke
from .visibility import first_opaque_hit, jit_array

#: Bisection halvings per crack (2**-14 px).
ITERATIONS = 14
#: Distance of the side probes from an outline vertex, in pixels.
PROBE = 2e-3
#: Below this ``|n . d|`` the inside surface is seen edge-on: a silhouette.
GRAZING = 0.25
#: Douglas-Peucker tolerance of the outline strokes, in pixels.
TOLERANCE = 0.02
#: The far side of an outline lies farther than its near side by more than this share.
RISE = 1e-3
#: Distance of the side probes of a self-occlusion outline's vertex, in pixels: beyond the
#: rounding of the intersections at a rim seen at a grazing angle (their hits flip between
#: the two sides within about 2e-3 px of an open cylinder's rim at 960 x 720).
STEP_PROBE = 0.02
#: Wider side probes of an id outline's vertex whose probes at ``PROBE`` px both see its
#: object or neither do (rays grazing a limb flip between hit and miss there), tried in turn.
WIDER = (0.02, 0.2)
#: Self-occlusion outlines are followed on from their ends this far (px) a round...
GROW = 8
#: ...for at most this many rounds.
GROW_ROUNDS = 64
#: Ends of self-occlusion outlines this close (px) are joined.
BRIDGE = 1.5


def film_rays(sensor: mi.Sensor, xy: np.ndarray) -> mi.Ray3f:
    """The pixel rays of ``sensor`` through film positions ``xy`` (N, 2) (pixels)."""
    x, y = (jit_array(mi.Float, xy[:, k].astype(np.float32)) for k in range(2))
    return pixel_rays(sensor, x, y)


def _hit_depths(
    si: mi.SurfaceInteraction3f, hit: mi.Bool, camera: Projection
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``hit`` (N,) bool, the hit points (N, 3) and their depths along ``camera``'s view axis
    (+inf on a miss)."""
    hit_np = np.asarray(hit.numpy(), bool)
    p = np.stack([np.asarray(c.numpy(), np.float64) for c in (si.p.x, si.p.y, si.p.z)], -1)
    return hit_np, p, np.where(hit_np, (p - camera.origin) @ camera.forward, np.inf)


def probe(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    xy: np.ndarray,
    camera: Projection,
    stop_at_glass: bool = False,
) -> dict[str, np.ndarray]:
    """What the pixel ray through each film position ``xy`` (N, 2) sees first, through glass
    (unless ``stop_at_glass``): ``hit``, ``object_id``, ``prim``, ``position`` (N, 3), ``depth``
    (along ``camera``'s view axis from its origin: the ``Z`` layer's; +inf on a miss), ``cos``
    (``|n . d|``) and ``glass``."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(xy) == 0:
        z = np.zeros(0)
        return {
            "hit": z.astype(bool),
            "object_id": z.astype(np.uint32),
            "prim": z.astype(np.uint32),
            "position": np.zeros((0, 3)),
            "depth": z,
            "cos": z,
            "glass": z.astype(bool),
        }
    ray = film_rays(sensor, xy)
    si, oid, hit, glass = first_opaque_hit(scene, table, ray, stop_at_glass=stop_at_glass)
    cos = dr.abs(dr.dot(si.n, ray.d))
    hit_np, p, depth = _hit_depths(si, hit, camera)
    return {
        "hit": hit_np,
        "object_id": np.asarray(oid.numpy(), np.uint32),
        "prim": np.where(hit_np, np.asarray(si.prim_index.numpy(), np.uint32), 0),
        "position": np.where(hit_np[:, None], p, 0.0),
        "depth": depth,
        "cos": np.where(hit_np, np.asarray(cos.numpy(), np.float64), 1.0),
        "glass": np.broadcast_to(np.asarray(glass.numpy(), bool), hit_np.shape).copy(),
    }


def object_ids(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    xy: np.ndarray,
    stop_at_glass: bool = False,
) -> np.ndarray:
    """:func:`probe`'s ``object_id`` alone (N,) uint32, from hits that compute nothing else
    (``mi.RayFlags.Minimal``): the id image and the bisections of its cracks cast most of
    this module's rays."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return np.zeros(0, np.uint32)
    ray = film_rays(sensor, xy)
    _, oid, _, _ = first_opaque_hit(scene, table, ray, mi.RayFlags.Minimal, stop_at_glass)
    return np.asarray(oid.numpy(), np.uint32)


def ids_and_depths(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    xy: np.ndarray,
    camera: Projection,
    stop_at_glass: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`probe`'s ``object_id`` and ``depth`` alone, from hits that compute the position
    and nothing else (``mi.RayFlags.Minimal``): the pixel-centre image and the bisections of
    its depth steps."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return np.zeros(0, np.uint32), np.zeros(0)
    ray = film_rays(sensor, xy)
    si, oid, hit, _ = first_opaque_hit(scene, table, ray, mi.RayFlags.Minimal, stop_at_glass)
    dr.eval(si.p, oid, hit)
    return np.asarray(oid.numpy(), np.uint32), _hit_depths(si, hit, camera)[2]


def normals_2d(points: np.ndarray, closed: bool) -> np.ndarray:
    """Unit normals (N, 2) of a polyline at its vertices (the tangent from the neighbours,
    turned by 90 degrees; ``(0, 0)`` where the polyline has no length)."""
    p = np.asarray(points, np.float64)
    n = len(p)
    if n < 2:
        return np.zeros((n, 2))
    if closed:
        t = np.roll(p, -1, 0) - np.roll(p, 1, 0)
    else:
        t = np.empty_like(p)
        t[1:-1] = p[2:] - p[:-2]
        t[0], t[-1] = p[1] - p[0], p[-1] - p[-2]
    length = np.hypot(t[:, 0], t[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(length[:, None] > 0, t / length[:, None], 0.0)
    return np.stack([-u[:, 1], u[:, 0]], -1)


def analytic_ids(table: ObjectTable, glass: bool = False) -> np.ndarray:
    """Object id -> outline id (N + 1,) uint32: the shapes that are not meshes and are glass
    (``glass``) or not keep their id, every other object reads as background (0)."""
    lut = np.zeros(len(table) + 1, np.uint32)
    for oid, shape in table.shapes.items():
        bsdf = None if shape.class_name() == "Instance" else shape.bsdf()
        is_glass = bsdf is not None and mi.has_flag(bsdf.flags(), mi.BSDFFlags.DeltaTransmission)
        if not shape.is_mesh() and is_glass == glass:
            lut[oid] = oid
    return lut


#: Shapes (Mitsuba class names) that never hide a part of themselves: a sphere is convex, a
#: disk flat; the depth seen across one of them is continuous.
NEVER_SELF_OCCLUDING = frozenset({"Sphere", "Disk"})


def can_self_occlude(table: ObjectTable) -> np.ndarray:
    """Object id -> whether the object can lie in front of itself (N + 1,) bool: every object
    but a lone shape of :data:`NEVER_SELF_OCCLUDING` (an instance may group several shapes)."""
    out = np.ones(len(table) + 1, bool)
    out[0] = False
    for oid, shape in table.shapes.items():
        if shape.class_name() in NEVER_SELF_OCCLUDING:
            out[oid] = False
    return out


def _simplified(idx: np.ndarray, points: np.ndarray, closed: bool) -> np.ndarray:
    """The indices (into ``points``) of the vertices Douglas-Peucker keeps of ``points[idx]``."""
    sub = points[idx]
    kept = douglas_peucker(sub, TOLERANCE, closed=closed)
    out = []
    j = 0
    n = len(sub)
    if closed and len(kept):  # a closed path is kept from its own starting vertex
        j = int(np.flatnonzero(np.all(sub == kept[0], axis=1))[0])
    for q in kept:
        for _ in range(n):
            if np.array_equal(sub[j % n], q):
                break
            j += 1
        out.append(idx[j % n])
    return np.asarray(out, np.int64)


def outline_strokes(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    camera: Projection,
    depth_range: tuple[float, float] | None = None,
) -> list[Stroke]:
    """The outline strokes of every shape that is not a mesh (module docstring): their id
    outlines and their self-occlusion outlines. ``depth_range``: the frame's nearest and
    farthest finite depth, which the depth steps are measured against (default: those of the
    pixel-centre hits)."""
    out = _outlines(scene, sensor, table, camera, False, depth_range)
    return out + _outlines(scene, sensor, table, camera, True, depth_range)


def _outlines(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    camera: Projection,
    glass: bool,
    depth_range: tuple[float, float] | None,
) -> list[Stroke]:
    """The outline strokes of the glass (``glass``) or the opaque shapes that are not meshes."""
    lut = analytic_ids(table, glass)
    if not lut.any():
        return []
    w, h = (int(v) for v in sensor.film().crop_size())
    gx, gy = film_grid(w, h)
    centres = np.stack([np.asarray(gx.numpy(), np.float64), np.asarray(gy.numpy(), np.float64)], 1)
    # the depths only where a self-occlusion outline can be (module docstring)
    folds = can_self_occlude(table) & (lut > 0)
    if folds.any():
        oid, z = ids_and_depths(scene, sensor, table, centres, camera, glass)
    else:
        oid, z = object_ids(scene, sensor, table, centres, glass), None
    ids = lut[oid].reshape(h, w)
    if not ids.any():
        return []

    def ids_at(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return lut[object_ids(scene, sensor, table, np.stack([x, y], 1), glass)]

    def seen_at(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        o, d = ids_and_depths(scene, sensor, table, xy, camera, glass)
        return lut[o], d

    paths = vectorize(ids, objects=table.names, ids_at=ids_at, tolerance=0.0, iterations=ITERATIONS)
    paths = [p for p in paths if len(p) >= 2]
    # only shapes that can be in front of themselves have self-occlusion outlines: seeds on a
    # sphere's limb or a disk's tilt would be located only to be refused
    folded = np.where(folds[ids], ids, 0)
    steps = []
    if z is not None and folded.any():
        steps = depth_step_paths(folded, z.reshape(h, w), seen_at, depth_range)
    if not paths and not steps:
        return []
    every = paths + steps
    pts = np.concatenate([p.points for p in every])
    nrm = np.concatenate([normals_2d(p.points, p.closed) for p in every])
    nrm *= np.repeat([PROBE] * len(paths) + [STEP_PROBE] * len(steps), [len(p) for p in every])[
        :, None
    ]
    a = probe(scene, sensor, table, pts + nrm, camera, glass)
    b = probe(scene, sensor, table, pts - nrm, camera, glass)
    # an id outline's vertex whose two probes do not tell its object from the rest lies in
    # the band where grazing rays flip: probed again farther out (module docstring)
    k = np.repeat([p.object_id for p in every], [len(p) for p in every]).astype(np.uint32)
    n_id = sum(len(p) for p in paths)
    for wider in WIDER:
        again = np.flatnonzero(_sees(a, k)[:n_id] == _sees(b, k)[:n_id])
        if not len(again):
            break
        step = nrm[again] * (wider / PROBE)
        a2 = probe(scene, sensor, table, pts[again] + step, camera, glass)
        b2 = probe(scene, sensor, table, pts[again] - step, camera, glass)
        told = _sees(a2, k[again]) != _sees(b2, k[again])
        for x, x2 in ((a, a2), (b, b2)):
            for key in x:
                x[key][again[told]] = x2[key][told]
    out: list[Stroke] = []
    start = 0
    for i, path in enumerate(every):
        n = len(path)
        sl = slice(start, start + n)
        start += n
        sides = {k: v[sl] for k, v in a.items()}, {k: v[sl] for k, v in b.items()}
        if i < len(paths):
            state, inside = _id_outline_state(path.object_id, *sides, lut)
        else:
            state, inside = _depth_step_state(path.object_id, *sides)
        out += _path_strokes(path, state, inside)
    return out


# ----------------------------------------------------------------- self-occlusion outlines

#: Pixel offsets of a crack's two pixels: a crack of axis 0 lies between ``(x, y)`` and
#: ``(x + 1, y)``, one of axis 1 between ``(x, y)`` and ``(x, y + 1)``.
_AXIS = np.array([[1, 0], [0, 1]])

#: Film positions (N, 2) -> the outline id and the depth seen through each.
SeenAt = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def same_id_cracks(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pair of 4-neighbours of ``ids`` (H, W) with the same id, not 0: the pixels
    ``a`` and ``b`` (M, 2) int64 ``(x, y)``, ``b`` to the right of or below ``a``."""
    h, w = ids.shape
    pa = []
    for dx, dy in _AXIS:
        same = (ids[: h - dy, : w - dx] == ids[dy:, dx:]) & (ids[dy:, dx:] > 0)
        ys, xs = np.nonzero(same)
        pa.append(np.stack([xs, ys], 1))
    axis = np.repeat([0, 1], [len(pa[0]), len(pa[1])])
    a = np.concatenate(pa).astype(np.int64)
    return a, a + _AXIS[axis]


def step_cracks(
    ids: np.ndarray, z: np.ndarray, depth_range: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The depth steps within one outline id (module docstring): ``near`` and ``far`` (M, 2)
    int64, the ``(x, y)`` pixels on either side of each step, 4-neighbours with the same id
    (not 0) of ``ids`` (H, W) whose depths ``z`` (H, W, +inf: background) step as the
    ``lines`` drawing's do (:func:`mi_npr.kernels.chain.depth_field` and ``depth_step``; the
    near pixel is the one :func:`mi_npr.kernels.edges.owns` gives the step to)."""
    h, w = ids.shape
    a, b = same_id_cracks(ids)
    if not len(a):
        return a, b
    zf = jit_array(mi.Float, np.asarray(z, np.float32).ravel())
    frame = None
    if depth_range is not None:
        frame = tuple(jit_array(mi.Float, np.array([v], np.float32)) for v in depth_range)
    D = np.asarray(depth_field(zf, frame=frame)(zf).numpy()).reshape(h, w)
    da = jit_array(mi.Float, D[a[:, 1], a[:, 0]])
    db = jit_array(mi.Float, D[b[:, 1], b[:, 0]])
    step = depth_step()
    a_near = np.asarray(owns(da, db, step, mi.Bool(False)).numpy(), bool)
    b_near = np.asarray(owns(db, da, step, mi.Bool(False)).numpy(), bool)
    return np.concatenate([a[a_near], b[b_near]]), np.concatenate([b[a_near], a[b_near]])


def _located(
    seen_at: SeenAt, near: np.ndarray, far: np.ndarray, k: np.ndarray, z: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the segment from the centre of pixel ``near`` to that of ``far`` (M, 2) crosses
    a depth step of object ``k``, and whether it does (module docstring). ``z`` (H, W): the
    depths at the pixel centres."""
    start = near + 0.5
    step = (far - near).astype(np.float64)
    lo, hi = np.zeros(len(near)), np.ones(len(near))
    z_lo, z_hi = z[near[:, 1], near[:, 0]], z[far[:, 1], far[:, 0]]
    for _ in range(ITERATIONS):
        mid = 0.5 * (lo + hi)
        oid, z_mid = seen_at(start + mid[:, None] * step)
        # the step lies in the half whose ends differ more in depth; a point that does not
        # see k is beyond the step (the near side ends before it)
        on = oid == k
        upper = on & (z_mid - z_lo < z_hi - z_mid)
        lo, z_lo = np.where(upper, mid, lo), np.where(upper, z_mid, z_lo)
        hi, z_hi = np.where(upper, hi, mid), np.where(upper | ~on, z_hi, z_mid)
    xy = start + (0.5 * (lo + hi))[:, None] * step
    # a step, not a steep slope: the depths on either side differ nearly as much at a
    # quarter of the distance (a smooth surface's difference shrinks with it, near a limb as
    # its square root: to a half)
    at = [xy + e * step for e in (-STEP_PROBE, STEP_PROBE, -STEP_PROBE / 4, STEP_PROBE / 4)]
    oid, depth = seen_at(np.concatenate(at))
    near_id, (d0, d1, d2, d3) = oid[: len(xy)], depth.reshape(4, -1)
    with np.errstate(invalid="ignore"):  # inf - inf: the background on the far side
        jump = np.isinf(d3) | (d3 - d2 > 0.75 * (d1 - d0))
    ok = (near_id == k) & (d1 > d0 * (1.0 + RISE)) & jump
    return xy, ok


def _crack_corners(near: np.ndarray, far: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two ends of each crack between pixels ``near`` and ``far`` (M, 2), as pixel corners
    ``(x, y)`` (2M, 2) (first ends, then second ends), and the crack's slot at each (2M,): 0
    up, 1 right, 2 down, 3 left of the corner, the order around it. A crack between ``(x,
    y)`` and ``(x + 1, y)`` runs from corner ``(x + 1, y)`` down to ``(x + 1, y + 1)``, one
    between ``(x, y)`` and ``(x, y + 1)`` from ``(x, y + 1)`` right to ``(x + 1, y + 1)``."""
    lo = np.minimum(near, far)
    axis = (far - near)[:, 1] != 0
    c0 = lo + np.where(axis[:, None], [0, 1], [1, 0])
    slots = np.concatenate([np.where(axis, 1, 2), np.where(axis, 3, 0)])
    return np.concatenate([c0, lo + 1]), slots


def _ends(near: np.ndarray, far: np.ndarray) -> np.ndarray:
    """The pixel corners (E, 2) where exactly one of the cracks ``near``/``far`` ends."""
    corners, _ = _crack_corners(near, far)
    key, count = np.unique(corners, axis=0, return_counts=True)
    return key[count == 1]


def _corner_pieces(near: np.ndarray, far: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The pieces (P, 2) between the cracks of ``near``/``far`` (M cracks) that meet at a
    pixel corner (module docstring): two cracks at a corner are joined; of three, the two
    opposite ones, and the third to the nearer of them (``xy``: the cracks' vertices); of four,
    each to its opposite."""
    corners, slots = _crack_corners(near, far)
    crack = np.concatenate([np.arange(len(near))] * 2)
    key, inv = np.unique(corners, axis=0, return_inverse=True)
    table = np.full((len(key), 4), -1, np.int64)
    table[inv.ravel(), slots] = crack
    have = table >= 0
    count = have.sum(1)
    pieces = []
    two = table[count == 2]
    pieces.append(two[two >= 0].reshape(-1, 2))
    four = table[count == 4]
    pieces += [four[:, [0, 2]], four[:, [1, 3]]]
    three = table[count == 3]
    if len(three):
        m = np.argmin(three >= 0, axis=1)  # the missing slot
        r = np.arange(len(three))
        bar_a, bar_b = three[r, (m + 1) % 4], three[r, (m + 3) % 4]
        stem = three[r, (m + 2) % 4]
        da = np.hypot(*(xy[bar_a] - xy[stem]).T)
        db = np.hypot(*(xy[bar_b] - xy[stem]).T)
        pieces += [
            np.stack([bar_a, bar_b], 1),
            np.stack([stem, np.where(da <= db, bar_a, bar_b)], 1),
        ]
    return np.concatenate(pieces).astype(np.int64)


def _bridged(pieces: np.ndarray, xy: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``pieces`` (P, 2) between cracks of one object (``k``), and one more between each two
    ends (cracks with one piece or none) of two chains of that object whose vertices ``xy``
    lie within ``BRIDGE`` px, the nearest first, each end once: where an outline passes through
    pixel centres, a pixel on it may read either side, and two cracks of it share no corner."""
    # imported here: scipy.sparse and scipy.spatial slow the start of every command
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    degree = np.bincount(pieces.ravel(), minlength=len(xy))
    ends = np.flatnonzero(degree <= 1)
    if len(ends) < 2:
        return pieces
    pairs = cKDTree(xy[ends]).query_pairs(BRIDGE, output_type="ndarray")
    a, b = ends[pairs[:, 0]], ends[pairs[:, 1]]
    a, b = a[k[a] == k[b]], b[k[a] == k[b]]
    if not len(a):
        return pieces
    graph = coo_matrix((np.ones(len(pieces)), pieces.T), shape=(len(xy),) * 2)
    _, chain = connected_components(graph, directed=False)
    extra = []
    for n in np.argsort(np.hypot(*(xy[a] - xy[b]).T), kind="stable"):
        p, q = int(a[n]), int(b[n])
        if degree[p] < 2 and degree[q] < 2 and chain[p] != chain[q]:
            extra.append((p, q))
            degree[p] += 1
            degree[q] += 1
            chain[chain == chain[q]] = chain[p]
    return np.concatenate([pieces, np.array(extra, np.int64).reshape(-1, 2)])


def _key(near: np.ndarray, far: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index of each crack in an (H + 1, W + 1, 2) array: its second corner, its axis."""
    c = np.maximum(near, far)
    return c[:, 1], c[:, 0], ((far - near)[:, 1] != 0).astype(np.int64)


def depth_step_paths(
    ids: np.ndarray,
    z: np.ndarray,
    seen_at: SeenAt,
    depth_range: tuple[float, float] | None = None,
) -> list[VectorPath]:
    """The self-occlusion outlines of ``ids`` (H, W) as paths (module docstring): the depth
    steps of :func:`step_cracks`, each located by bisection along its crack (``seen_at(xy)``:
    the outline id and depth seen through film positions ``xy`` (N, 2)) and followed on to
    where they vanish, chained at the pixel corners where they meet; every vertex of a path is
    a step's."""
    near, far = step_cracks(ids, z, depth_range)
    if not len(near):
        return []
    h, w = ids.shape
    tried = np.zeros((h + 1, w + 1, 2), bool)  # by a crack's second corner and its axis
    tried[_key(near, far)] = True
    xy, ok = _located(seen_at, near, far, ids[near[:, 1], near[:, 0]], z)
    near, far, xy = near[ok], far[ok], xy[ok]
    if not len(near):
        return []
    # every crack within one object, its nearer pixel first: where fainter steps are looked for
    a, b = same_id_cracks(ids)
    swap = (z[b[:, 1], b[:, 0]] < z[a[:, 1], a[:, 0]])[:, None]
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    corners_ab, _ = _crack_corners(a, b)
    from scipy.ndimage import maximum_filter  # lazy: keeps scipy's import out of start-up

    for _ in range(GROW_ROUNDS):
        ends = _ends(near, far)
        if not len(ends):
            break
        region = np.zeros((h + 1, w + 1), bool)
        region[ends[:, 1], ends[:, 0]] = True
        region = maximum_filter(region, 2 * GROW + 1)
        c0, c1 = corners_ab[: len(a)], corners_ab[len(a) :]
        inside = region[c0[:, 1], c0[:, 0]] | region[c1[:, 1], c1[:, 0]]
        cand = np.flatnonzero(inside & ~tried[_key(a, b)])
        if not len(cand):
            break
        tried[_key(a[cand], b[cand])] = True
        kc = ids[a[cand, 1], a[cand, 0]]
        gxy, gok = _located(seen_at, a[cand], b[cand], kc, z)
        if not gok.any():
            break
        near = np.concatenate([near, a[cand][gok]])
        far = np.concatenate([far, b[cand][gok]])
        xy = np.concatenate([xy, gxy[gok]])
    k = ids[near[:, 1], near[:, 0]]
    pieces = _corner_pieces(near, far, xy)
    pieces = _bridged(pieces[k[pieces[:, 0]] == k[pieces[:, 1]]], xy, k)
    d = xy[pieces[:, 1]] - xy[pieces[:, 0]]
    order, rev, start, closed = chain_order(
        pieces[:, 0], pieces[:, 1], k[pieces[:, 0]], d, -d, 180.0
    )
    out = []
    for c, is_closed in enumerate(closed.tolist()):
        steps = order[start[c] : start[c + 1]]
        walk = np.where(
            rev[start[c] : start[c + 1]][:, None], pieces[steps][:, ::-1], pieces[steps]
        )
        seq = walk[:, 0] if is_closed else np.append(walk[:, 0], walk[-1, 1])
        oid = int(k[seq[0]])
        out.append(VectorPath(oid, f"object_{oid}", xy[seq], bool(is_closed)))
    return out


# ------------------------------------------------------------------------ kinds and runs


def _sees(probed: dict, k: np.ndarray | np.uint32) -> np.ndarray:
    """Where the rays of a :func:`probe` hit object ``k`` (one id, or one a ray)."""
    return probed["hit"] & (probed["object_id"] == k)


def _sides(
    in_a: np.ndarray, a: dict, b: dict
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The probes of the inside (where ``in_a``: ``a``, else ``b``) and of the outside."""
    inside = {key: np.where(_col(in_a, a[key]), a[key], b[key]) for key in a}
    outside = {key: np.where(_col(in_a, a[key]), b[key], a[key]) for key in a}
    return inside, outside


def _id_outline_state(
    k: int, a: dict, b: dict, lut: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Per vertex of an id outline of object ``k``: its state (-1 dropped, else kind (0
    silhouette, 1 border, 2 intersection) + 3 * glass) and the inside probe (module
    docstring). ``lut``: :func:`analytic_ids`, which tells the objects whose own outlines are
    traced (an intersection with one of them is drawn from the smaller id's outline)."""
    k = np.uint32(k)
    in_a, in_b = _sees(a, k), _sees(b, k)
    inside, outside = _sides(in_a, a, b)
    farther = ~outside["hit"] | (outside["depth"] > inside["depth"] * (1.0 + RISE))
    state = _state(in_a ^ in_b, farther, inside)
    other = outside["object_id"]
    level = outside["hit"] & (np.abs(outside["depth"] - inside["depth"]) <= inside["depth"] * RISE)
    mine = (lut[np.minimum(other, len(lut) - 1)] == 0) | (k < other)
    meet = (in_a ^ in_b) & level & (other != k) & mine
    return np.where(meet, 2 + 3 * inside["glass"].astype(int), state), inside


def _depth_step_state(k: int, a: dict, b: dict) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """:func:`_id_outline_state` of a self-occlusion outline: the inside is the nearer probe,
    which sees ``k``."""
    inside, outside = _sides(a["depth"] <= b["depth"], a, b)
    ok = _sees(inside, np.uint32(k))
    farther = outside["depth"] > inside["depth"] * (1.0 + RISE)
    return _state(ok, farther, inside), inside


def _state(ok: np.ndarray, farther: np.ndarray, inside: dict) -> np.ndarray:
    grazing = inside["cos"] < GRAZING
    kind = np.where(grazing, 0, 1) + 3 * inside["glass"].astype(int)
    return np.where(ok & farther, kind, -1)


def _path_strokes(path: VectorPath, state: np.ndarray, inside: dict) -> list[Stroke]:
    """The strokes of ``path``: its runs of vertices of one ``state`` (not -1), the whole
    path where every vertex of a closed one has the same."""
    k = np.uint32(path.object_id)
    n = len(state)
    pts = path.points
    runs: list[tuple[np.ndarray, bool]] = []
    if path.closed and np.all(state == state[0]):
        if state[0] >= 0:
            runs.append((np.arange(n), True))
    else:
        change = np.flatnonzero(state != np.roll(state, 1)) if path.closed else None
        if path.closed:
            first = int(change[0])
            order = (first + np.arange(n)) % n
        else:
            order = np.arange(n)
        segs = np.split(order, np.flatnonzero(np.diff(state[order])) + 1)
        for i, seg in enumerate(segs):
            nxt = segs[(i + 1) % len(segs)] if path.closed or i + 1 < len(segs) else None
            if state[seg[0]] < 0:
                continue
            if nxt is not None and state[nxt[0]] >= 0:  # two kept runs meet: no gap between
                seg = np.append(seg, nxt[0])
            if len(seg) >= 2:
                runs.append((seg, False))
    out = []
    for idx, closed in runs:
        keep_idx = _simplified(idx, pts, closed)
        st = int(state[idx[0]])
        out.append(
            Stroke(
                kind=_KINDS[st % 3],
                points=pts[keep_idx],
                position=inside["position"][keep_idx],
                depth=inside["depth"][keep_idx],
                object_id=np.full(len(keep_idx), k, np.uint32),
                prim=inside["prim"][keep_idx],
                qi=0,
                through_glass=st >= 3,
                closed=closed,
            )
        )
    return out


#: The stroke kind of each outline state modulo 3 (:func:`_id_outline_state`).
_KINDS = ("silhouette", "border", "intersection")


def _col(mask: np.ndarray, like: np.ndarray) -> np.ndarray:
    """``mask`` shaped to broadcast against ``like`` ((N,) or (N, 3))."""
    return mask if like.ndim == 1 else mask[:, None]
