"""Viewpoints of a batch (``mi-npr batch --views SPEC``): which cameras each scene is seen from.

A view spec names a list of views; each view has an id (the stem of its output files) and, once
the scene is loaded, a :class:`CameraSpec` (``origin``, ``target``, ``up``, horizontal ``fov``)
that :func:`sensor_for` turns into a Mitsuba sensor with the film, sampler and reconstruction
filter of the scene's own sensor.

==================  ===========================================================================
``scene``           the scene's own sensor (view id ``scene``), rendered as it is
``orbit:N``         N views on a circle around the scene's up axis through the centre of its
                    bounding sphere, at the sensor's distance and elevation; view 0 is at the
                    sensor's azimuth (``orbit_000`` ... ``orbit_N-1``, counter-clockwise seen
                    from above)
``sphere:N``        N Fibonacci-lattice directions on the upper half of the viewing sphere
                    (best view's sphere: its up axis, centre and radius); ``sphere:N:all`` the
                    whole sphere (``sphere_000`` ...)
``best:K``          the K best-rated viewpoints of best view's search (``best:K:MEASURE`` with
                    MEASURE ``entropy``, the default, ``pb`` or ``curvature``), best first
                    (``best_0`` ...)
``FILE.json``       a list of cameras ``{"origin": [x, y, z], "target": [...], "up": [...],
                    "fov": degrees}`` (``up`` defaults to +y, ``fov`` to the sensor's; an
                    ``"id"`` names the view, else ``cam_000`` ...)
==================  ===========================================================================

Ambiguities resolved: the orbit's centre is the bounding sphere's centre (a sensor's ``lookat``
target is not kept by Mitsuba), its up axis the world axis nearest the sensor's up (as best view
does, :func:`mi_npr.viewpoint.search.viewing`); a view's up is the one best view gives its
cameras (:func:`mi_npr.viewpoint.view_frame`).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ParameterError
from .params import VIEW_PARAMS, check_arg, check_lookat

#: A view id is a file stem: letters, digits, ``_``, ``-`` and ``.`` (not first).
_VIEW_ID = re.compile(r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}$")
_MEASURES = ("entropy", "pb", "curvature")


@dataclass(frozen=True)
class CameraSpec:
    """A pinhole camera: ``lookat(origin, target, up)`` and a horizontal ``fov`` (degrees,
    ``None``: the scene sensor's)."""

    origin: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "origin": list(self.origin),
            "target": list(self.target),
            "up": list(self.up),
            "fov": self.fov,
        }


@dataclass(frozen=True)
class ViewSpec:
    """A parsed ``--views`` value: ``kind`` (``scene``, ``orbit``, ``sphere``, ``best``,
    ``file``), a count ``n``, an option (``all`` for ``sphere``, the measure for ``best``) and,
    for a file, its cameras by view id."""

    text: str
    kind: str
    n: int = 1
    option: str = ""
    cameras: tuple[tuple[str, CameraSpec], ...] = ()

    def ids(self) -> list[str]:
        """The view ids, known without loading the scene (the batch's job list)."""
        if self.kind == "scene":
            return ["scene"]
        if self.kind == "file":
            return [i for i, _ in self.cameras]
        if self.kind == "best":
            return [f"best_{k}" for k in range(self.n)]
        width = max(3, len(str(self.n - 1)))
        return [f"{self.kind}_{k:0{width}d}" for k in range(self.n)]


def _camera(where: str, item: Any) -> CameraSpec:
    if not isinstance(item, dict):
        raise ParameterError(f"{where}: expected an object with origin, target, up, fov")
    # "time": a camera path's (mi-npr path writes path.json in this format), not used here
    unknown = sorted(set(item) - {"id", "origin", "target", "up", "fov", "time"})
    if unknown:
        raise ParameterError(
            f"{where}: unknown key {unknown[0]!r} (keys: id, origin, target, up, fov, time)"
        )
    for key in ("origin", "target"):
        if key not in item:
            raise ParameterError(f"{where}: missing {key!r}")
    origin, target, up, fov = check_lookat(
        where, item["origin"], item["target"], item.get("up", (0.0, 1.0, 0.0)), item.get("fov")
    )
    return CameraSpec(origin, target, up, fov)


def read_cameras(path: str | os.PathLike[str]) -> tuple[tuple[str, CameraSpec], ...]:
    """The cameras of a JSON file (a list, or ``{"cameras": [...]}``), checked, by view id."""
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as f:
            data = json.load(f)
    except OSError as e:
        raise ParameterError(f"{name}: cannot read the cameras ({e.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ParameterError(f"{name}: not a JSON file of cameras ({e})") from None
    if isinstance(data, dict) and "cameras" in data:
        data = data["cameras"]
    if not isinstance(data, list) or not data:
        raise ParameterError(f"{name}: expected a non-empty list of cameras")
    check_arg(name, _view_param("file"), len(data))
    out: list[tuple[str, CameraSpec]] = []
    seen: set[str] = set()
    for k, item in enumerate(data):
        where = f"{name}: camera {k}"
        vid = item.get("id", f"cam_{k:03d}") if isinstance(item, dict) else ""
        if not isinstance(vid, str) or not _VIEW_ID.match(vid) or vid in ("scene",):
            raise ParameterError(f"{where}: id {vid!r} is not a valid file stem")
        if vid in seen:
            raise ParameterError(f"{where}: id {vid!r} is used twice")
        seen.add(vid)
        out.append((vid, _camera(where, item)))
    return tuple(out)


def _view_param(kind: str) -> Any:
    return next(p for p in VIEW_PARAMS if p.name == kind)


def parse_views(text: str) -> ViewSpec:
    """Parse a ``--views`` value (module docstring); :class:`ParameterError` naming it."""
    if not isinstance(text, str) or not text:
        raise ParameterError(
            f"views = {text!r}: expected scene, orbit:N, sphere:N, best:K or FILE.json"
        )
    if text == "scene":
        return ViewSpec(text, "scene")
    kind, sep, rest = text.partition(":")
    if sep and kind in ("orbit", "sphere", "best"):
        count, _, option = rest.partition(":")
        try:
            n = int(count)
        except ValueError:
            raise ParameterError(f"views = {text!r}: {count!r} is not an integer") from None
        n = check_arg(f"views {kind}", _view_param(kind), n)
        if kind == "orbit" and option:
            raise ParameterError(f"views = {text!r}: orbit takes no option")
        if kind == "sphere" and option not in ("", "all", "upper"):
            raise ParameterError(f"views = {text!r}: sphere's option is 'all' or 'upper'")
        if kind == "best":
            option = option or "entropy"
            if option not in _MEASURES:
                raise ParameterError(
                    f"views = {text!r}: measure {option!r}: expected {', '.join(_MEASURES)}"
                )
        return ViewSpec(text, kind, n, option)
    if text.lower().endswith(".json") or os.path.isfile(text):
        return ViewSpec(text, "file", cameras=read_cameras(text))
    raise ParameterError(
        f"views = {text!r}: expected scene, orbit:N, sphere:N, best:K or FILE.json"
    )


# -- cameras of a loaded scene ----------------------------------------------------------------


def _pose(sensor: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, float | None]:
    """A sensor's origin, view direction, up vector and horizontal fov."""
    from .scene import camera_of

    cam = camera_of(sensor)
    m = np.asarray(cam.to_world, np.float64)
    return m[:3, 3].copy(), m[:3, 2].copy(), m[:3, 1].copy(), cam.fov


def sensor_camera(sensor: Any, target: Sequence[float] | None = None) -> CameraSpec:
    """The :class:`CameraSpec` of a sensor (its target one unit ahead unless given)."""
    o, d, up, fov = _pose(sensor)
    t = o + d if target is None else np.asarray(target, np.float64)
    return CameraSpec(_t3(o), _t3(t), _t3(up), fov)


def _t3(v: Any) -> tuple[float, float, float]:
    a = np.asarray(v, np.float64).reshape(3)
    return (float(a[0]) + 0.0, float(a[1]) + 0.0, float(a[2]) + 0.0)


def orbit(scene: Any, sensor: Any, n: int) -> list[CameraSpec]:
    """``n`` cameras on the circle around the up axis through the bounding sphere's centre,
    at the sensor's distance and elevation, the first one at the sensor's azimuth."""
    from .viewpoint.search import nearest_axis

    o, _, up_s, fov = _pose(sensor)
    bs = scene.bbox().bounding_sphere()
    c = np.asarray(bs.center, np.float64).reshape(-1)[:3]
    if not np.all(np.isfinite(c)):
        c = np.zeros(3)
    up = nearest_axis(up_s)  # the world axis nearest the sensor's up (best view's)
    rel = o - c
    h = float(rel @ up)  # height above the centre
    flat = rel - h * up
    r = float(np.linalg.norm(flat))
    if r < 1e-9:  # looking straight down the up axis: any azimuth, at the same distance
        flat = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 0.0, 1.0])
        r, flat = 1e-6, flat / np.linalg.norm(flat) * 1e-6
    e1 = flat / r
    e2 = np.cross(up, e1)
    out = []
    for k in range(n):
        a = 2.0 * math.pi * k / n
        origin = c + h * up + r * (math.cos(a) * e1 + math.sin(a) * e2)
        out.append(_look(origin, c, up, fov))
    return out


def _look(origin: np.ndarray, target: np.ndarray, world_up: np.ndarray, fov: float | None):
    from .viewpoint import view_frame

    _, _, up = view_frame(origin, target, world_up)
    return CameraSpec(_t3(origin), _t3(target), _t3(up), fov)


def sphere(scene: Any, sensor: Any, n: int, upper: bool = True) -> list[CameraSpec]:
    """``n`` cameras at Fibonacci-lattice directions on best view's viewing sphere (its centre,
    radius and up axis; only the upper half with ``upper``), looking at its centre."""
    from .viewpoint import fibonacci_sphere
    from .viewpoint.search import viewing

    view = viewing(scene, res=32, sensor=sensor, allow_below=not upper)
    if upper:  # the lattice of 2n points is symmetric: its n points with y > 0 are a half
        d = fibonacci_sphere(2 * n)
        d = d[d[:, 1] > 0][:n]
    else:
        d = fibonacci_sphere(n)
    # The lattice's pole is +y: turn it onto the up axis.
    d = d @ _rotation_y_to(view.up).T
    return [_look(o, view.target, view.up, view.fov) for o in view.origins(d)]


def _rotation_y_to(up: np.ndarray) -> np.ndarray:
    """The rotation taking +y onto the unit vector ``up`` (an axis, or any direction)."""
    y = np.array([0.0, 1.0, 0.0])
    u = np.asarray(up, np.float64) / np.linalg.norm(up)
    v = np.cross(y, u)
    c = float(y @ u)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def best(scene: Any, sensor: Any, k: int, measure: str = "entropy") -> list[CameraSpec]:
    """The ``k`` best-rated viewpoints of best view's search (best first, ties in evaluation
    order)."""
    from .viewpoint.search import check_shapes, search, viewing

    check_shapes(scene)
    view = viewing(scene, sensor=sensor)
    bv = search(scene, view, measure, 3)
    if k > bv.evaluations:
        raise ParameterError(f"views best:{k}: the search rated only {bv.evaluations} viewpoints")
    order = np.argsort(-bv.qualities, kind="stable")[:k]
    out = []
    for i in order:
        v = bv.view(int(i))
        out.append(CameraSpec(_t3(v.origin), _t3(v.target), _t3(v.up), float(bv.fov)))
    return out


def cameras(spec: ViewSpec, scene: Any, sensor: Any) -> list[tuple[str, CameraSpec | None]]:
    """The views of ``spec`` for a loaded scene seen by ``sensor``: ``(view id, camera)``;
    the camera is ``None`` for the ``scene`` view (the sensor itself is rendered)."""
    ids = spec.ids()
    if spec.kind == "scene":
        return [("scene", None)]
    if spec.kind == "file":
        return list(spec.cameras)
    if spec.kind == "orbit":
        cams = orbit(scene, sensor, spec.n)
    elif spec.kind == "sphere":
        cams = sphere(scene, sensor, spec.n, upper=spec.option != "all")
    else:
        cams = best(scene, sensor, spec.n, spec.option)
    return list(zip(ids, cams, strict=True))


def sensor_for(camera: CameraSpec, like: Any) -> Any:
    """A ``perspective`` sensor at ``camera`` with the film size, reconstruction filter,
    sampler, clip planes (and fov, when the camera has none) of the sensor ``like``
    (:func:`mi_npr.scene.sensor_at`)."""
    from .scene import sensor_at

    return sensor_at(like, camera.origin, camera.target, camera.up, camera.fov)
