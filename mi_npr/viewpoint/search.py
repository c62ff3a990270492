"""Best-view search on the viewing sphere (section 2.1 of the paper, Figs. 1-2).

The scene's bounding sphere sits at the centre of a viewing sphere of radius ``radius`` whose
surface holds every candidate viewpoint; cameras look at the centre. The sphere is cut into 8
spherical triangles whose vertices are the 6 points on the +-x, +-y, +-z axes (Fig. 1).

**Allowed viewpoints.** Those on the side of the scene's up axis ``up`` (below), the horizon
included: 4 of the 8 triangles, 5 of the 6 axis points. ``allow_below`` allows the whole sphere.

**The paper's search** (``beam=1``): the axis points are rated (one batched evaluation), the
triangle whose vertices have the highest *summed* quality is kept; then, ``depth`` times (Fig. 2),
it is split into 4 by its edge midpoints pushed back onto the sphere, the 3 new midpoints are rated
(one batch) and the child with the highest vertex sum is kept: ``6 + 3 depth`` evaluations on the
whole sphere. One triangle chosen on 6 samples often holds the wrong peak (97.8% of the best of a
dense sampling on a tilted cube, much less for eq. 2 in clutter).

**The beam search** (``beam=k > 1``, the default 3): the first level splits every allowed
triangle (the sphere sampled every 45 degrees); each later level splits the ``k`` triangles whose
*best* vertex rates highest (vertex sum on ties: a narrow peak next to two poor vertices is kept),
rating their new midpoints in one batch. What is left of ``max_evaluations`` (40) then goes on a
ring of viewpoints around the best one, half a final triangle edge away: eqs. 1-3 jump where a
polygon appears, so their peaks are narrow. Never more than ``max_evaluations`` viewpoints are
rated (a level splits only the triangles whose midpoints still fit). Above the ground at
``depth=3``: 5 + 8 + 9 + 9 midpoints and a ring of 9, 40 in all.

**A closed room.** When no viewpoint of the beam search's first level sees more than 5% of its
image covered (:data:`INSIDE_BELOW`) and one sees more than a tenth of it filled with the backs
of one-sided faces (:data:`CLOSED_ABOVE`): a room closed by one-sided walls shows only their backs
to the outside, and what leaks through its seams, the viewpoints move inside the scene, onto
the sphere of radius ``inner`` (half the smallest half-extent of the box of every shape not
ignored) around that box's centre, and the search starts again there with what is left of the
budget. Its result is returned if it beats the outside (a thin object, all back faces inside,
stays seen from outside); its ``evaluations`` then leave out the 13 or 18 rated outside. Only
with the default ``target`` and ``radius``.

Either way the result is the best viewpoint evaluated. Ties go to the first candidate in the
order above (+x, -x, +y, -y, +z, -z; octants in the order of :data:`OCTANTS`).

Defaults, where the paper leaves them open:

- ``target``: the centre of the bounding sphere of the objects that matter
  (:func:`mi_npr.camera.objects_that_matter`, :func:`mi_npr.camera.bounding_sphere`): the
  framing of orbits and spheres of views, so a floor, a backdrop or a light never sets it.
- ``fov``: the horizontal field of view of the scene's sensor (``sensor``-th,
  :data:`mi_npr.camera.DEFAULT_FOV` = 45 degrees if it has none, e.g. an orthographic one); the
  ID buffers have the sensor film's aspect ratio and ``res`` pixels along its longer side, so
  the quality of the written camera is the one rated. A scene without any sensor (built with
  ``mi.load_dict``) gets square 45 degree views.
- ``radius``: ``R / sin(phi / 2)`` with ``R`` the bounding-sphere radius and ``phi`` the smaller
  of the horizontal and vertical fields of view of the ID buffers
  (:func:`mi_npr.camera.fit_distance`): the distance at which the whole bounding sphere just
  fits in the image (2.61 R for a square 45 degree view). With a ``target`` away from the
  sphere's centre, ``R`` grows by that distance, so the scene still fits.
- ``ignore``: names of objects (a floor, a backdrop) whose pixels count as background: they
  still hide what is behind them, but add nothing to any measure, their polygons leave ``n``
  (eq. 1), and the objects that matter are chosen among the others only. Large flat
  polygons otherwise decide most searches (a floor seen from straight above or below fills the
  image with one or two faces).
- ``up``: the scene's up axis (:func:`mi_npr.camera.up_axis`: the world axis closest to the
  +y of the sensor's ``to_world``: +y for a camera placed with ``lookat up="0, 1, 0"``, however
  it is tilted, +z for ``up="0, 0, 1"``), +y for a scene without a sensor. It is the side
  viewpoints stay on, and the preferred up of every viewpoint's camera (the world axis least
  aligned with the view direction where that is too close to it,
  :func:`mi_npr.camera.view_frame`).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import mitsuba as mi
import numpy as np

from ..camera import (
    DEFAULT_FOV,
    bounding_sphere,
    camera_of,
    fibonacci_sphere,
    fit_distance,
    framed_shapes,
    nearest_axis,
    view_frame,
)
from ..errors import ParameterError, SceneError
from ..memory import check_images
from ..params import (
    MAX_RES,
    MAX_VIEW_DEPTH,
    Param,
    check_arg,
    entry,
    integer_range,
    name_list,
    names,
)
from ..scene import load_scene, sensor_of
from . import idbuffer
from .measures import MEASURES, SparseAreas, Topology, check_measure

#: The search's settings (``mi-npr best-view --depth --res``).
SEARCH_PARAMS: tuple[Param, ...] = (
    Param(
        "depth",
        int,
        3,
        "levels of subdivision of the viewing sphere's triangles",
        integer_range(0, MAX_VIEW_DEPTH),
    ),
    Param("res", int, 128, "ID buffer size, long side", integer_range(1, MAX_RES)),
)

AXES = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64
)
#: The 8 spherical triangles of Fig. 1 as indices into :data:`AXES` (one per octant, wound
#: counter-clockwise seen from outside the sphere).
OCTANTS = np.array(
    [[0, 2, 4], [0, 5, 2], [0, 4, 3], [0, 3, 5], [1, 4, 2], [1, 2, 5], [1, 3, 4], [1, 5, 3]]
)

SceneLike = str | os.PathLike[str] | mi.Scene


@dataclass(frozen=True)
class Viewing:
    """How viewpoints are rendered for one scene: the sphere, the camera, the polygons."""

    target: np.ndarray
    radius: float
    fov: float
    size: tuple[int, int]
    up: np.ndarray
    polygons: idbuffer.Polygons = field(repr=False)
    #: columns of the area table kept (column 0, the background, always): ignored objects' not
    keep: np.ndarray | None = field(default=None, repr=False)
    #: viewpoints below the plane through the target normal to ``up`` are allowed too
    allow_below: bool = False
    #: radius of the sphere of viewpoints inside the scene, tried when nothing can be seen from
    #: outside (0: never; module docstring)
    inner: float = 0.0
    #: centre of that inside sphere: the middle of every shape not ignored (a room's), not the
    #: target framed on the objects that matter (``None``: the target)
    inner_target: np.ndarray | None = field(default=None, repr=False)

    def origins(self, directions: np.ndarray) -> np.ndarray:
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return self.target + self.radius * d

    def sparse_areas(self, scene: mi.Scene, origins: np.ndarray) -> SparseAreas:
        return idbuffer.sparse_areas(
            scene, origins, self.target, self.fov, self.size, self.up, self.polygons
        )

    def areas(self, scene: mi.Scene, origins: np.ndarray) -> np.ndarray:
        """The dense ``(V, n + 1)`` table (:func:`~mi_npr.viewpoint.idbuffer.areas`)."""
        return self.sparse_areas(scene, origins).dense().astype(np.uint32)

    def qualities(self, scene: mi.Scene, origins: np.ndarray, measure: str) -> np.ndarray:
        return self.rate(scene, origins, measure)[0]

    def rate(
        self, scene: mi.Scene, origins: np.ndarray, measure: str
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The quality of each viewpoint, and the fractions of its image that are background
        and one-sided faces seen from behind (a part of the background)."""
        a = self.sparse_areas(scene, origins)
        topo = self.polygons.topology() if measure == "curvature" else None
        if self.keep is not None:  # ignored objects' pixels become background
            a = a.merge(self.keep)
            if topo is not None:
                topo = Topology(topo.polygon_vertices[self.keep], topo.vertex_term)
        q = np.asarray(MEASURES[measure](a, topo), np.float64).reshape(-1)
        total = np.bincount(a.rows, weights=a.values, minlength=a.shape[0])
        empty = np.bincount(a.rows[a.cols == 0], weights=a.values[a.cols == 0], minlength=len(q))
        back = a.back if a.back is not None else np.zeros(len(q))
        return q, empty / np.maximum(total, 1), back / np.maximum(total, 1)

    def allowed(self, directions: np.ndarray) -> np.ndarray:
        """Which unit ``directions`` (from the target) are allowed viewpoints: those on the
        side of :attr:`up` (its plane included), or all with ``allow_below``."""
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        if self.allow_below:
            return np.ones(len(d), dtype=bool)
        return d @ self.up >= -1e-12


def _kept_columns(polys: idbuffer.Polygons, ignore: Sequence[str]) -> np.ndarray | None:
    """The area-table columns that stay when the objects named ``ignore`` are ignored."""
    if not names("ignore", ignore):
        return None
    by_name = {v: k for k, v in polys.table.names.items()}
    unknown = [n for n in ignore if n not in by_name]
    if unknown:
        raise ParameterError(
            f"ignore = {unknown[0]!r}: no such object (objects: {', '.join(by_name)})"
        )
    keep = np.ones(polys.n + 1, dtype=bool)
    for name in ignore:
        oid = by_name[name]
        start = int(polys.base[oid]) + 1
        keep[start : start + int(polys.span[oid])] = False
    return keep


def _bounding_sphere(
    scene: mi.Scene, polys: idbuffer.Polygons, ignore: Sequence[str] = (), frame: Sequence[str] = ()
) -> tuple[np.ndarray, float, np.ndarray, float]:
    """``(centre, R, whole, inner)``: the bounding sphere of the objects named in ``frame``, else
    of the objects that matter among those not in ``ignore``
    (:func:`mi_npr.camera.framed_shapes`: a floor, a backdrop or a light does not set the
    distance, as for orbits and spheres of views; an ignored object neither), and the centre
    and the inner radius of the box of every shape not ignored (a closed room's walls make its
    inside; :func:`mi_npr.camera.bounding_sphere`)."""
    c, r, _ = bounding_sphere(scene, framed_shapes(scene, frame, ignore))
    kept = [s for k, s in polys.table.shapes.items() if polys.table.names[k] not in ignore]
    whole, _, inner = bounding_sphere(scene, kept or list(scene.shapes()))
    if not (np.all(np.isfinite(c)) and math.isfinite(r)):
        raise SceneError("the scene's bounding box is not finite: give target and radius")
    return c, r, whole, inner


def viewing(
    scene: mi.Scene,
    target: Sequence[float] | np.ndarray | None = None,
    radius: float | None = None,
    res: int = 128,
    fov: float | None = None,
    sensor: int | mi.Sensor = 0,
    ignore: Sequence[str] = (),
    *,
    allow_below: bool = False,
    frame: Sequence[str] = (),
) -> Viewing:
    """The viewing setup of ``scene`` with the defaults of the module docstring filled in;
    ``frame``: the objects whose bounding sphere sets the default target and radius (default:
    the objects that matter)."""
    if scene.sensors() or isinstance(sensor, mi.Sensor):
        s = sensor_of(scene, sensor)
        cam = camera_of(s)
        # The whole film's aspect (its fov is the whole film's), not a crop window's.
        fw, fh = (int(v) for v in s.film().size())
        aspect, up = fw / fh, nearest_axis(cam.up)
        fov = float(cam.fov) if fov is None and cam.fov is not None else fov
    else:  # a scene built in Python may have no sensor: a square view, +y up
        aspect, up = 1.0, np.array([0.0, 1.0, 0.0])
    fov = DEFAULT_FOV if fov is None else float(fov)
    if not 0.0 < fov < 180.0:
        raise ParameterError(f"fov = {fov!r}: must be in (0, 180) degrees")
    size = idbuffer.image_size(res, aspect)
    check_images(size[0], size[1], 12, "ID buffers")  # the largest batch: 12 first-level midpoints
    polys = idbuffer.polygons(scene)
    ignore = name_list("ignore", ignore)
    keep = _kept_columns(polys, ignore)  # checks the names first
    frame = name_list("frame", frame)
    centre, R, whole, inner = _bounding_sphere(scene, polys, ignore, frame)
    if target is not None or radius is not None:
        inner = 0.0  # the user's sphere: no other
    if target is None:
        tgt = centre
    else:
        tgt = np.asarray(target, np.float64).reshape(-1)
        if tgt.shape != (3,) or not np.all(np.isfinite(tgt)):
            raise ParameterError(f"target = {target!r}: expected 3 finite numbers")
    if radius is None:
        R += float(np.linalg.norm(tgt - centre))  # a target off-centre: still see everything
        radius = fit_distance(R, fov, size)
    elif (
        isinstance(radius, bool)
        or not isinstance(radius, numbers.Real)
        or not (math.isfinite(radius) and radius > 0)
    ):
        raise ParameterError(f"radius = {radius!r}: must be a positive number")
    return Viewing(tgt, float(radius), fov, size, up, polys, keep, bool(allow_below), inner, whole)


def qualities(
    scene: SceneLike,
    origins: Sequence[Sequence[float]] | np.ndarray,
    target: Sequence[float] | np.ndarray | None = None,
    measure: str = "entropy",
    res: int = 128,
    *,
    fov: float | None = None,
    sensor: int = 0,
    ignore: Sequence[str] = (),
) -> np.ndarray:
    """:func:`quality` of many viewpoints at once (batched Dr.Jit launches): float64 (V,)."""
    check_measure(measure)
    scene = load_scene(scene)
    view = viewing(scene, target, 1.0, res, fov, sensor, ignore)
    return view.qualities(scene, np.asarray(origins, np.float64).reshape(-1, 3), measure)


def quality(
    scene: SceneLike,
    origin: Sequence[float] | np.ndarray,
    target: Sequence[float] | np.ndarray | None = None,
    measure: str = "entropy",
    res: int = 128,
    *,
    fov: float | None = None,
    sensor: int = 0,
    ignore: Sequence[str] = (),
) -> float:
    """Quality of the viewpoint at ``origin`` looking at ``target`` (eq. 1, 2 or 3).

    ``measure``: ``"pb"`` (eq. 1), ``"curvature"`` (eq. 2) or ``"entropy"`` (eq. 3), computed
    from the areas of an ``res``-pixel ID buffer (see :mod:`mi_npr.viewpoint.measures` for the
    exact definitions). ``target`` defaults to the centre of the bounding sphere of the objects
    that matter (module docstring); ``fov`` and the image's aspect ratio come from the scene's
    sensor. A viewpoint that sees nothing has quality 0. Objects named in ``ignore`` count as
    background (module docstring).

    >>> from mi_npr.viewpoint import quality
    >>> round(quality("scenes_xml/scene3.xml", [4, 3, -4], measure="pb", res=32), 2)
    1.18
    """
    q = qualities(scene, [origin], target, measure, res, fov=fov, sensor=sensor, ignore=ignore)
    return float(q[0])


@dataclass(frozen=True)
class BestView:
    """The result of :func:`best_view`: a camera pose, its quality and the whole search.

    ``origin``/``target``/``up`` is a ``lookat`` (``up`` orthogonal to the view direction);
    ``viewpoints`` (E, 3) and ``qualities`` (E,) list every evaluated viewpoint in evaluation
    order (``evaluations == E``); ``triangle`` (3, 3) holds the unit directions of the final
    spherical triangle; ``size`` is the ID buffer's (width, height); ``world_up`` the preferred
    up direction every viewpoint's frame was built from.
    """

    origin: np.ndarray
    target: np.ndarray
    up: np.ndarray
    quality: float
    evaluations: int
    viewpoints: np.ndarray
    qualities: np.ndarray
    measure: str
    radius: float
    fov: float
    size: tuple[int, int]
    depth: int
    triangle: np.ndarray
    world_up: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    @property
    def direction(self) -> np.ndarray:
        """Unit vector from the target to the viewpoint."""
        d = self.origin - self.target
        return d / np.linalg.norm(d)

    def view(self, i: int) -> BestView:
        """The ``i``-th evaluated viewpoint as a camera (same search record, another pose)."""
        o = self.viewpoints[i]
        _, _, up = view_frame(o, self.target, self.world_up)
        return replace(self, origin=o.copy(), up=up, quality=float(self.qualities[i]))

    @property
    def worst(self) -> BestView:
        """The worst evaluated viewpoint as a camera (the first one on ties): ``sensor_xml``
        writes it like the best."""
        return self.view(int(np.argmin(self.qualities)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (what ``mi-npr best-view --json`` prints)."""
        return {
            "measure": self.measure,
            "quality": self.quality,
            "origin": self.origin.tolist(),
            "target": self.target.tolist(),
            "up": self.up.tolist(),
            "fov": self.fov,
            "radius": self.radius,
            "depth": self.depth,
            "res": list(self.size),
            "evaluations": self.evaluations,
            "viewpoints": [
                {"origin": o.tolist(), "quality": float(q)}
                for o, q in zip(self.viewpoints, self.qualities, strict=True)
            ],
        }


def _midpoint(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    m = a + b
    return m / np.linalg.norm(m)


def _edge(u: int, v: int) -> tuple[int, int]:
    return (u, v) if u < v else (v, u)


#: The search moves inside the scene when no viewpoint of its first level sees more than this
#: fraction of its image covered (module docstring).
INSIDE_BELOW = 0.05
#: ... and some viewpoint sees more than this fraction of its image filled with the backs of
#: one-sided faces (a sparse scene, mostly empty space, stays seen from outside).
CLOSED_ABOVE = 0.1

#: Default width of the search (triangles kept at each level) and its cap on evaluations.
BEAM = 3
MAX_EVALUATIONS = 40


def best_view(
    scene: SceneLike,
    measure: str = "entropy",
    depth: int = 3,
    res: int = 128,
    radius: float | None = None,
    *,
    target: Sequence[float] | np.ndarray | None = None,
    fov: float | None = None,
    sensor: int = 0,
    ignore: Sequence[str] = (),
    allow_below: bool = False,
    beam: int = BEAM,
    max_evaluations: int = MAX_EVALUATIONS,
    frame: Sequence[str] = (),
) -> BestView:
    """Search the viewing sphere for the best viewpoint under ``measure`` (module docstring).

    ``depth`` levels of subdivision follow the 8 (4 above the ground) spherical triangles of
    Fig. 1: the first splits them all, each next one the ``beam`` triangles with the best
    vertex, and a ring around the best viewpoint takes what is left of ``max_evaluations``
    (never exceeded but by the 5 or 6 axis points). ``allow_below`` lets viewpoints below the
    scene's ground (the side opposite its up axis) compete. ``beam=1, allow_below=True`` is the
    paper's search: one triangle by vertex sum per level, ``6 + 3 depth`` evaluations, no cap.
    ``frame``: the objects whose bounding sphere the viewing sphere is about (default: the
    objects that matter, :func:`mi_npr.camera.framed_shapes`).

    >>> from mi_npr.viewpoint import best_view
    >>> bv = best_view("scenes_xml/scene4.xml", "entropy", depth=1, res=32)
    >>> bv.evaluations, bv.size, bool(bv.quality == bv.qualities.max())
    (40, (32, 24), True)
    """
    check_measure(measure)
    depth = check_arg("best_view", entry(SEARCH_PARAMS, "depth"), depth)
    res = check_arg("best_view", entry(SEARCH_PARAMS, "res"), res)
    for name, v in (("beam", beam), ("max_evaluations", max_evaluations)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ParameterError(f"{name} = {v!r}: must be a positive integer")
    scene = load_scene(scene)
    check_shapes(scene)
    view = viewing(
        scene, target, radius, res, fov, sensor, ignore, allow_below=allow_below, frame=frame
    )
    return search(scene, view, measure, int(depth), int(beam), int(max_evaluations))


def check_shapes(scene: mi.Scene) -> None:
    """A search needs something to look at."""
    if not scene.shapes():
        raise SceneError("the scene has no shapes: there is nothing to look at")


def _ring(centre: np.ndarray, angle: float, count: int) -> np.ndarray:
    """``count`` unit vectors evenly spaced on a circle ``angle`` radians around ``centre``."""
    u = np.cross(centre, [1.0, 0.0, 0.0] if abs(centre[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(centre, u)
    phi = 2.0 * math.pi * (np.arange(count) + 0.5) / count
    side = np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w
    return math.cos(angle) * centre + math.sin(angle) * side


def search(
    scene: mi.Scene,
    view: Viewing,
    measure: str,
    depth: int,
    beam: int = BEAM,
    max_evaluations: int = MAX_EVALUATIONS,
    frame: Sequence[str] = (),
) -> BestView:
    """The search of :func:`best_view` for a prepared :class:`Viewing` (module docstring)."""
    octants = [t for t in OCTANTS if np.all(view.allowed(AXES[t]))]
    used = sorted({int(i) for t in octants for i in t})
    dirs: list[np.ndarray] = [AXES[i] for i in used]
    tris = [[used.index(int(i)) for i in t] for t in octants]
    q0, empty, back = view.rate(scene, view.origins(np.asarray(dirs)), measure)
    q: list[float] = list(q0)
    seen = float(1.0 - empty.min())  # the most any viewpoint rated so far sees of the scene
    backs = float(back.max())  # ... and of the backs of one-sided faces
    paper = beam == 1

    def score(t: list[int]) -> float:
        """The paper ranks triangles by their vertex sum; the beam by their best vertex (a peak
        between two poor vertices is not lost), the sum breaking ties."""
        s = sum(q[i] for i in t)
        return s if paper else max(q[i] for i in t) + 1e-6 * s

    mids: dict[tuple[int, int], int] = {}  # edge -> index of its midpoint in dirs
    for level in range(depth):
        # The first level splits every octant (beam search); then the `beam` best triangles
        # (stable: first on ties) are split, as far as their new midpoints fit in the budget.
        order = sorted(range(len(tris)), key=lambda k: -score(tris[k]))
        kept, new = [], []
        for k in order[: beam if paper or level > 0 else len(order)]:
            a, b, c = tris[k]
            edges = [_edge(u, v) for u, v in ((a, b), (b, c), (c, a))]
            edges = [e for e in edges if e not in mids and e not in new]
            if not paper and len(dirs) + len(new) + len(edges) > max_evaluations:
                break
            kept.append(tris[k])
            new.extend(edges)
        if not kept:
            break
        for e in new:
            mids[e] = len(dirs)
            dirs.append(_midpoint(dirs[e[0]], dirs[e[1]]))
        qm, empty, back = view.rate(scene, view.origins(np.asarray(dirs[-len(new) :])), measure)
        q.extend(qm)
        seen, backs = max(seen, float(1.0 - empty.min())), max(backs, float(back.max()))
        tris = []
        for a, b, c in kept:
            ab, bc, ca = (mids[_edge(u, v)] for u, v in ((a, b), (b, c), (c, a)))
            tris.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]])
        left = max_evaluations - len(dirs)
        closed = seen < INSIDE_BELOW and backs > CLOSED_ABOVE
        if level == 0 and not paper and view.inner > 0 and closed and left >= len(q):
            # Only backs seen from outside (a closed room of one-sided walls, and what leaks
            # through its seams): look from inside.
            centre = view.target if view.inner_target is None else view.inner_target
            inside = replace(view, target=centre, radius=view.inner, inner=0.0)
            bv = search(scene, inside, measure, depth, beam, left)
            if bv.quality > max(q):  # not a thin object that is all back faces inside
                return bv
    left = max_evaluations - len(dirs)
    if not paper and left >= 3:
        # Polish: the rest of the budget on a ring around the best viewpoint, half a final
        # triangle edge away (a measure jumps where a polygon appears: its peaks are narrow).
        t = tris[0]
        edge = math.acos(float(np.clip(np.dot(dirs[t[0]], dirs[t[1]]), -1.0, 1.0)))
        ring = _ring(dirs[int(np.argmax(q))], 0.5 * edge, left)
        ring = ring[view.allowed(ring)]
        if len(ring):
            dirs.extend(ring)
            q.extend(view.qualities(scene, view.origins(ring), measure))
    qs = np.asarray(q, np.float64)
    best = int(np.argmax(qs))
    final = max(tris, key=score)  # first on ties
    origins = view.origins(np.asarray(dirs))
    _, _, up = view_frame(origins[best], view.target, view.up)
    return BestView(
        origin=origins[best],
        target=view.target.copy(),
        up=up,
        quality=float(qs[best]),
        evaluations=len(qs),
        viewpoints=origins,
        qualities=qs,
        measure=measure,
        radius=view.radius,
        fov=view.fov,
        size=view.size,
        depth=depth,
        triangle=np.asarray([dirs[i] for i in final]),
        world_up=np.asarray(view.up, np.float64),
    )


def quality_map(
    scene: SceneLike,
    measure: str = "entropy",
    samples: int = 256,
    res: int = 64,
    radius: float | None = None,
    *,
    target: Sequence[float] | np.ndarray | None = None,
    fov: float | None = None,
    sensor: int = 0,
    ignore: Sequence[str] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """The quality over the whole viewing sphere: ``(directions (S, 3), qualities (S,))`` at
    ``samples`` Fibonacci-lattice directions, rated in batched launches (for the sphere picture
    and plots; same setup as :func:`best_view`)."""
    check_measure(measure)
    scene = load_scene(scene)
    view = viewing(scene, target, radius, res, fov, sensor, ignore)
    return sample_sphere(scene, view, measure, samples)


def sample_sphere(
    scene: mi.Scene, view: Viewing, measure: str, samples: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`quality_map` for a prepared :class:`Viewing`."""
    d = fibonacci_sphere(int(samples))
    return d, view.qualities(scene, view.origins(d), measure)
