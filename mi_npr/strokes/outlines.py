"""Image-space outlines of the shapes that are not meshes (Mitsuba's ``sphere``, ``cylinder``,
``disk``, instances...), exact to a fraction of a pixel.

**Which shapes.** Meshes get their silhouettes in object space (:mod:`mi_npr.strokes.edges`);
every other shape gets its outline here, so no outline is drawn twice: in the id image that is
traced, every mesh reads as background.

**Two id images.** The first sees through glass: each pixel-centre ray
(:func:`mi_npr.raycast.pixel_rays`) keeps the first surface that is neither glass nor ``null``
(:func:`mi_npr.strokes.visibility.first_opaque_hit`), so a sphere behind a glass pane keeps its
outline, marked ``through_glass``; in it only the opaque shapes that are not meshes have ids.
The second stops at glass (only ``null`` surfaces are passed) and gives ids to the glass shapes
that are not meshes alone: their own outlines, seen where nothing opaque is in front of them.

**Vertices** come from :func:`mi_npr.contours.vectorize` (crack cycles of the id image, one
vertex per crack bisected along the crack with ``ITERATIONS`` extra rays: within
``2**-14`` px of the outline), with no simplification there. Each vertex is then *probed*: two
rays at ``PROBE`` px on either side of the outline, across its local tangent. The side that sees
the object ``k`` is the inside; its hit gives the vertex's 3-D position, depth and primitive.
A vertex is on ``k``'s own outline (and kept) when the outside sees nothing or a surface
farther than the inside one (by more than 0.1 %); it is a **silhouette** where the inside
surface is seen edge-on, ``|n . d| < GRAZING`` (``n`` its normal, ``d`` the ray; a sphere's
limb: at ``PROBE`` px inside the limb of a sphere of radius ``R`` px, ``|n . d|`` is about
``sqrt(2 PROBE / R)``, 0.014 for ``R = 20``), else a **border** (the rim of a disk, of an
open cylinder). Being seen edge-on is not enough to keep a vertex: where an outline meets a
nearer object's, the vertices within a pixel of the meeting point lie near the limb but on
the nearer object's outline.

Otherwise the object is cut by something in front (its outline there is the other object's) or
meets another object at equal depth (an intersection, not drawn for these shapes yet). Runs of
kept vertices of one kind and one glass state are the strokes (a whole kept cycle: a closed
stroke), simplified by Douglas-Peucker at ``TOLERANCE`` px (kept vertices stay on the outline).
These strokes are visible by construction: ``qi = 0``; the hidden part of such an outline is
not drawn.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..contours.vector import VectorPath, douglas_peucker, vectorize
from ..gbuffer import Projection
from ..raycast import film_grid, pixel_rays
from ..scene import ObjectTable
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
    ray = pixel_rays(
        sensor,
        jit_array(mi.Float, xy[:, 0].astype(np.float32)),
        jit_array(mi.Float, xy[:, 1].astype(np.float32)),
    )
    si, oid, hit, glass = first_opaque_hit(scene, table, ray, stop_at_glass=stop_at_glass)
    cos = dr.abs(dr.dot(si.n, ray.d))
    hit_np = np.asarray(hit.numpy(), bool)
    p = np.stack([np.asarray(c.numpy(), np.float64) for c in (si.p.x, si.p.y, si.p.z)], -1)
    depth = np.where(hit_np, (p - camera.origin) @ camera.forward, np.inf)
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
    ray = pixel_rays(
        sensor,
        jit_array(mi.Float, xy[:, 0].astype(np.float32)),
        jit_array(mi.Float, xy[:, 1].astype(np.float32)),
    )
    _, oid, _, _ = first_opaque_hit(scene, table, ray, mi.RayFlags.Minimal, stop_at_glass)
    return np.asarray(oid.numpy(), np.uint32)


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
) -> list[Stroke]:
    """The outline strokes of every shape that is not a mesh (module docstring)."""
    out = _outlines(scene, sensor, table, camera, False)
    return out + _outlines(scene, sensor, table, camera, True)


def _outlines(
    scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, camera: Projection, glass: bool
) -> list[Stroke]:
    """The outline strokes of the glass (``glass``) or the opaque shapes that are not meshes."""
    lut = analytic_ids(table, glass)
    if not lut.any():
        return []
    w, h = (int(v) for v in sensor.film().crop_size())
    gx, gy = film_grid(w, h)
    centres = np.stack([np.asarray(gx.numpy(), np.float64), np.asarray(gy.numpy(), np.float64)], 1)
    ids = lut[object_ids(scene, sensor, table, centres, glass)].reshape(h, w)
    if not ids.any():
        return []

    def ids_at(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return lut[object_ids(scene, sensor, table, np.stack([x, y], 1), glass)]

    paths = vectorize(ids, objects=table.names, ids_at=ids_at, tolerance=0.0, iterations=ITERATIONS)
    paths = [p for p in paths if len(p) >= 2]
    if not paths:
        return []
    pts = np.concatenate([p.points for p in paths])
    nrm = np.concatenate([normals_2d(p.points, p.closed) for p in paths])
    a = probe(scene, sensor, table, pts + PROBE * nrm, camera, glass)
    b = probe(scene, sensor, table, pts - PROBE * nrm, camera, glass)
    out: list[Stroke] = []
    start = 0
    for path in paths:
        n = len(path)
        sl = slice(start, start + n)
        start += n
        out += _path_strokes(
            path, {k: v[sl] for k, v in a.items()}, {k: v[sl] for k, v in b.items()}
        )
    return out


def _path_strokes(path: VectorPath, a: dict, b: dict) -> list[Stroke]:
    k = np.uint32(path.object_id)
    in_a = a["hit"] & (a["object_id"] == k)
    in_b = b["hit"] & (b["object_id"] == k)
    ok = in_a ^ in_b
    inside = {key: np.where(_col(in_a, a[key]), a[key], b[key]) for key in a}
    outside = {key: np.where(_col(in_a, a[key]), b[key], a[key]) for key in a}
    grazing = inside["cos"] < GRAZING
    farther = ~outside["hit"] | (outside["depth"] > inside["depth"] * (1.0 + 1e-3))
    keep = ok & farther
    # state of each vertex: -1 dropped, else kind (0 silhouette, 1 border) + 2 * glass
    state = np.where(keep, np.where(grazing, 0, 1) + 2 * inside["glass"].astype(int), -1)
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
                kind="silhouette" if st % 2 == 0 else "border",
                points=pts[keep_idx],
                position=inside["position"][keep_idx],
                depth=inside["depth"][keep_idx],
                object_id=np.full(len(keep_idx), k, np.uint32),
                prim=inside["prim"][keep_idx],
                qi=0,
                through_glass=st >= 2,
                closed=closed,
            )
        )
    return out


def _col(mask: np.ndarray, like: np.ndarray) -> np.ndarray:
    """``mask`` shaped to broadcast against ``like`` ((N,) or (N, 3))."""
    return mask if like.ndim == 1 else mask[:, None]
