"""Where cameras go around a scene: its bounding sphere, the orbit, the sphere of views.

**Framing.** A scene is framed by the bounding sphere (centre ``c``, radius ``R``) of the objects
that matter (:func:`objects_that_matter`, or the shapes given, e.g. all but a floor): not the
shapes of emitters (an area light), not flat shapes (floors, backdrops, walls: the box's smallest
extent below :data:`FLAT` of its largest), not a stage (a ground, a curved backdrop, a dome: a
box diagonal above :data:`HUGE` times the median of the others' and a box that holds all their
centres; a house beside a mailbox is no stage), unless that leaves nothing; where the one
solid shape left is the stage of the flat ones (a disk before a curved backdrop), the flat
ones are the objects. A
pinhole camera with horizontal field of view ``fov`` and an image of ``W x H`` pixels sees the
whole sphere from the distance ``R / sin(phi / 2)`` (:func:`fit_distance`), ``phi`` the smaller
of its horizontal and vertical fields of view, ``tan(phi_y / 2) = tan(fov / 2) H / W``.

**Orbit** (:func:`orbit`). ``n`` cameras on the circle about the scene's up axis ``a``
(:func:`~mi_npr.camera.up_axis`) through the target ``c`` (default: the bounding sphere's
centre), starting at the scene camera's origin ``o`` and keeping its distance and height:
camera ``i`` is at ``c + R_a(i s) (o - c)``, ``R_a`` Rodrigues' rotation about ``a``, with
``s = degrees / n`` for a full turn (``|degrees| >= 360``: the first view is not repeated)
and ``s = degrees / (n - 1)`` otherwise (the last view at ``degrees``). Each looks at ``c``
with the sensor's ``fov`` (``None``: the sensor's) and up ``a`` made orthogonal to its view,
so nothing rolls however high the orbit is; ``time`` goes evenly from 0 to 1. A scene camera
*on* the axis (``|a x (o - c)| <= 1e-9 |o - c|``, e.g. straight above the centre) has no
circle to go round: a :class:`~mi_npr.errors.ParameterError`, never ``n`` identical views.

**Sphere of views** (:func:`sphere_directions`, :func:`on_sphere`). The Fibonacci lattice of
``m`` points, ``z_i = 1 - (2 i + 1) / m`` along the pole and the golden angle
``pi (3 - sqrt 5)`` between neighbours, with its pole (+y) turned onto the up axis. The upper
half of ``n`` views is the ``n`` points of the lattice of ``2 n`` above the equator (the lattice
is symmetric). Cameras on it look at the centre with the up of
:func:`~mi_npr.camera.view_frame`.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Sequence
from typing import Any

import mitsuba as mi
import numpy as np

from ..errors import ParameterError, shown
from ..params import MAX_VIEWS, name_list
from ..scene import load_scene, object_table, sensor_of, shape_bbox
from .model import Camera, angle_of, nearest_axis, orthogonal_up, rotate, vectors, view_frame
from .sensor import camera_of

SceneLike = str | os.PathLike[str] | mi.Scene


#: A shape is flat (a floor, a backdrop, a wall) when its box's smallest extent is below this
#: share of its largest.
FLAT = 1e-3
#: A shape is a ground, a backdrop or a dome when its box's diagonal exceeds this many times
#: the median of the others' and its box holds all their centres.
HUGE = 4.0


def objects_that_matter(
    scene: mi.Scene, shapes: Sequence[mi.Shape] | None = None
) -> list[mi.Shape]:
    """The shapes a view is framed on (module docstring): all but emitters' shapes, flat
    shapes and stages; a flat object on a stage (a disk before a backdrop) where nothing else
    is left; all of them when that leaves none. Chosen among ``shapes`` when given (the
    scene's shapes but those a user ignores): the one rule for every camera placed around a
    scene (orbit, sphere, best view, exploration paths)."""
    shapes = list(scene.shapes()) if shapes is None else list(shapes)
    boxes = {id(s): shape_bbox(s) for s in shapes}
    lit = [s for s in shapes if not s.is_emitter() and np.all(np.isfinite(boxes[id(s)]))]
    ext = {k: np.asarray(b[1] - b[0], np.float64) for k, b in boxes.items()}
    is_flat = {id(s): not ext[id(s)].min() > FLAT * max(ext[id(s)].max(), 0) for s in lit}
    flat = [s for s in lit if is_flat[id(s)]]
    keep = [s for s in lit if not is_flat[id(s)]]

    # each shape's box diagonal and centre once (the stage test compares every pair)
    diag = {id(s): float(np.linalg.norm(ext[id(s)])) for s in lit}
    centre = {id(s): 0.5 * (boxes[id(s)][0] + boxes[id(s)][1]) for s in lit}

    def stage(s: mi.Shape, among: list[mi.Shape]) -> bool:
        """Far larger than the others of ``among`` and holding their centres."""
        others = [id(t) for t in among if t is not s]
        lo, hi = boxes[id(s)]
        return diag[id(s)] > HUGE * float(np.median([diag[k] for k in others])) and all(
            np.all((centre[k] >= lo) & (centre[k] <= hi)) for k in others
        )

    if len(keep) > 1:
        keep = [s for s in keep if not stage(s, keep)] or keep
    elif len(keep) == 1 and flat and stage(keep[0], keep + flat):
        keep = flat  # the one solid shape is the stage of the flat ones: they are the objects
    return keep or shapes


def framed_shapes(
    scene: mi.Scene, frame: Sequence[str] = (), ignore: Sequence[str] = ()
) -> list[mi.Shape]:
    """The shapes a view of ``scene`` frames: those named in ``frame`` (object names as
    ``mi-npr info`` lists them: ``--frame``), else :func:`objects_that_matter` among the shapes
    not named in ``ignore``. A name the scene does not have is a
    :class:`~mi_npr.errors.ParameterError` naming the closest ones."""
    frame = name_list("frame", () if frame is None else frame)
    ignore = name_list("ignore", () if ignore is None else ignore)
    if not frame and not ignore:
        return objects_that_matter(scene)
    table = object_table(scene)
    by_name = {name: table.shapes[oid] for oid, name in table.names.items()}
    for what, asked in (("frame", frame), ("ignore", ignore)):
        for n in asked:
            if n not in by_name:
                close = difflib.get_close_matches(str(n), list(by_name), 3, 0.5)
                hint = f"closest: {', '.join(close)}" if close else f"objects: {', '.join(by_name)}"
                raise ParameterError(f"{what} {n!r}: no such object ({hint})")
    if frame:
        return [by_name[n] for n in dict.fromkeys(frame)]
    dropped = {id(by_name[n]) for n in ignore}
    return objects_that_matter(scene, [s for s in scene.shapes() if id(s) not in dropped])


def bounding_sphere(
    scene: mi.Scene, shapes: Sequence[mi.Shape] | None = None
) -> tuple[np.ndarray, float, float]:
    """``(centre, R, inner)``: the bounding sphere of the objects that matter in ``scene``
    (:func:`objects_that_matter`; or of ``shapes``), and the radius of a sphere of viewpoints
    inside their box (a quarter of its smallest extent; 0 for a flat scene, which has no
    inside). A scene without shapes: ``(0, 0, 0)``; an unbounded one: a non-finite centre or
    radius."""
    if not scene.shapes():
        return np.zeros(3), 0.0, 0.0
    bb = scene.bbox()
    shapes = shapes or objects_that_matter(scene)
    if shapes:
        boxes = np.stack([shape_bbox(s) for s in shapes])
        bb = mi.ScalarBoundingBox3f(boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0))
    bs = bb.bounding_sphere()
    c = np.asarray(bs.center, np.float64).ravel()[:3]
    r = float(np.asarray(bs.radius).ravel()[0])
    extent = np.asarray(bb.max, np.float64).ravel()[:3] - np.asarray(bb.min, np.float64).ravel()[:3]
    inner = 0.25 * float(extent.min())
    # A quad rotated by 90 degrees is 1e-16 thick from rounding, and a camera on its plane
    # would see it edge-on (or, on OptiX, hit it at t = 0).
    return c, r, inner if inner > 1e-4 * r else 0.0


def fit_distance(radius: float, fov: float, size: tuple[int, int]) -> float:
    """The distance from which a ``fov`` degree, ``size = (W, H)`` camera sees a sphere of
    ``radius`` whole (module docstring); 1 for a sphere of radius 0."""
    radius, fov = angle_of("radius", radius), angle_of("fov", fov)
    if radius < 0:
        raise ParameterError(f"radius = {radius!r}: must be >= 0")
    if not 0 < fov < 180:
        raise ParameterError(f"fov = {fov!r}: must be in (0, 180) degrees")
    try:
        w, h = (angle_of("size", x) for x in size)
    except (TypeError, ValueError):
        raise ParameterError(f"size = {shown(size)}: expected (width, height)") from None
    if not (w >= 1 and h >= 1):
        raise ParameterError(f"size = {shown(size)}: width and height must be >= 1")
    size = (w, h)
    tx = math.tan(math.radians(fov) / 2.0)
    half = min(math.atan(tx), math.atan(tx * size[1] / size[0]))
    return radius / math.sin(half) if radius > 0 else 1.0


def _count(who: str, n: Any) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= MAX_VIEWS:
        raise ParameterError(f"{who}: n = {n!r}: must be an integer in [1, {MAX_VIEWS}]")
    return int(n)


def across_from(camera: Camera, centre: Any, radius: float) -> np.ndarray:
    """The point of ``camera``'s view line nearest ``centre`` (its depth ``(centre - origin) .
    forward``), or ``max(radius, 1)`` along it where ``centre`` is not in front: the target of a
    sensor, which keeps none, across from the objects it looks at."""
    c = vectors("centre", centre).reshape(-1)
    if c.shape != (3,):
        raise ParameterError(f"centre = {shown(centre)}: expected 3 finite numbers")
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating)):
        raise ParameterError(f"radius = {shown(radius)}: expected a number")
    f = np.asarray(camera.forward, np.float64)
    origin = np.asarray(camera.origin, np.float64)
    depth = float(np.dot(c - origin, f))
    if not math.isfinite(depth) or depth <= 0.0:
        depth = max(float(radius), 1.0)
    return origin + depth * f


def orbit(
    scene: SceneLike,
    n: int,
    degrees: float = 360.0,
    *,
    sensor: int | mi.Sensor = 0,
    target: Sequence[float] | str | None = None,
    frame: Sequence[str] = (),
) -> list[Camera]:
    """``n`` cameras turning ``degrees`` about the scene's up axis through ``target`` (default:
    the centre ``c`` of the bounding sphere of the objects named in ``frame``, else of the
    objects that matter; ``"camera"``: the scene camera's own target, the point of its view
    line nearest ``c``, so that the first view is the sensor's own), from the scene's
    ``sensor`` (module docstring).

    >>> cams = orbit("scenes_xml/scene3.xml", 12)
    >>> len(cams), cams[0].fov == cams[6].fov, round(cams[3].time, 4)
    (12, True, 0.2727)
    """
    n = _count("orbit", n)
    if isinstance(degrees, bool) or not isinstance(degrees, (int, float)):
        raise ParameterError(f"degrees = {degrees!r}: must be a number")
    if not math.isfinite(degrees):
        raise ParameterError(f"degrees = {degrees!r}: must be finite")
    s = load_scene(scene)
    start = camera_of(sensor_of(s, sensor))
    up = nearest_axis(start.up)
    if target is None or (isinstance(target, str) and target == "camera"):
        c, r, _ = bounding_sphere(s, framed_shapes(s, frame))
        c = c if np.all(np.isfinite(c)) else np.zeros(3)  # an unbounded scene: the origin
        if target == "camera":  # the sensor keeps no target: its view line across from c
            c = across_from(start, c, r)
    elif isinstance(target, str):
        raise ParameterError(f"target = {target!r}: expected 3 numbers or 'camera'")
    else:
        c = vectors("target", target).reshape(-1)
        if c.shape != (3,):
            raise ParameterError(f"target = {shown(target)}: expected 3 finite numbers")
    arm = np.asarray(start.origin) - c
    if np.linalg.norm(np.cross(arm, up)) <= 1e-9 * np.linalg.norm(arm):
        raise ParameterError(
            f"orbit: the scene's camera at {list(start.origin)} lies on the orbit's axis (the "
            f"up axis {up.tolist()} through {c.tolist()}): there is no circle to orbit on"
        )
    step = math.radians(degrees) / (n if abs(degrees) >= 360 else max(n - 1, 1))
    times = np.linspace(0.0, 1.0, n) if n > 1 else np.zeros(1)
    out = []
    for i in range(n):
        o = c + rotate(arm, up, i * step)
        u = orthogonal_up((c - o) / np.linalg.norm(c - o), up)
        out.append(Camera(o, c, u, start.fov, float(times[i])))
    return out


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly evenly spread unit vectors (the Fibonacci lattice of the module docstring,
    its pole +y), float64 (n, 3).

    >>> d = fibonacci_sphere(4)
    >>> d[:, 1].tolist()
    [0.75, 0.25, -0.25, -0.75]
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"samples = {n!r}: must be a positive integer")
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    return np.stack([r * np.cos(phi), z, r * np.sin(phi)], axis=-1)  # y is the pole axis


def rotation_y_to(up: Any) -> np.ndarray:
    """The 3x3 rotation taking +y onto the direction ``up`` (the smallest; a half turn about
    +x for -y)."""
    y = np.array([0.0, 1.0, 0.0])
    u = vectors("up", up, nonzero=True)
    if u.shape != (3,):
        raise ParameterError(f"up = {shown(up)}: expected one vector of 3 numbers")
    u = u / np.linalg.norm(u)
    v = np.cross(y, u)
    c = float(y @ u)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def sphere_directions(n: int, up: Any = (0.0, 1.0, 0.0), upper: bool = True) -> np.ndarray:
    """``n`` Fibonacci-lattice unit vectors with the pole on ``up``, only above its equator
    with ``upper`` (module docstring), float64 (n, 3)."""
    n = _count("sphere", n)
    if not isinstance(upper, (bool, np.bool_)):
        raise ParameterError(f"upper = {shown(upper)}: expected True or False")
    if upper:  # the lattice of 2n points is symmetric: its n points with y > 0 are a half
        d = fibonacci_sphere(2 * n)
        d = d[d[:, 1] > 0][:n]
    else:
        d = fibonacci_sphere(n)
    return d @ rotation_y_to(up).T


def on_sphere(
    directions: np.ndarray, centre: Any, radius: float, up: Any, fov: float | None
) -> list[Camera]:
    """Cameras at ``centre + radius * directions`` (unit, (n, 3)) looking at ``centre``, up
    from :func:`~mi_npr.camera.view_frame` with ``up`` preferred."""
    c = vectors("centre", centre).reshape(-1)
    if c.shape != (3,):
        raise ParameterError(f"centre = {shown(centre)}: expected 3 finite numbers")
    d = vectors("directions", directions, nonzero=True).reshape(-1, 3)
    radius = angle_of("radius", radius)
    if radius <= 0:
        raise ParameterError(f"radius = {radius!r}: must be > 0")
    origins = c + radius * (d / np.linalg.norm(d, axis=-1, keepdims=True))
    _, _, ups = view_frame(origins, c, up)
    return [Camera(o, c, u, fov) for o, u in zip(origins, ups, strict=True)]
