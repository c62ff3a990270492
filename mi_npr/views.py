"""Viewpoints of a batch (``mi-npr batch --views SPEC``): which cameras each scene is seen from.

A view spec names a list of views; each view has an id (the stem of its output files) and, once
the scene is loaded, a :class:`~mi_npr.camera.Camera` that :func:`mi_npr.camera.sensor_for`
turns into a Mitsuba sensor with the film, sampler and reconstruction filter of the scene's own
sensor.

==================  ===========================================================================
``scene``           the scene's own sensor (view id ``scene``), rendered as it is
``orbit:N``         N views on a circle around the scene's up axis through the centre of its
                    bounding sphere, at the sensor's distance and elevation; view 0 is at the
                    sensor's azimuth (``orbit_000`` ... ``orbit_N-1``, counter-clockwise seen
                    from above): :func:`mi_npr.camera.orbit`, the camera paths' orbit;
                    ``orbit:N:camera`` about the scene camera's own target (its view line
                    across from that centre: view 0 is the sensor's own view)
``sphere:N``        N Fibonacci-lattice directions on the upper half of the viewing sphere
                    (best view's sphere: its up axis, centre and radius); ``sphere:N:all`` the
                    whole sphere (``sphere_000`` ...)
``random:N``        N directions drawn uniformly on the whole viewing sphere (the sphere's
                    centre, radius and up) by a generator seeded with 0, ``random:N:SEED``
                    with SEED: the same spec gives the same views (``random_000`` ...)
``best:K``          the K best-rated viewpoints of best view's search (``best:K:MEASURE`` with
                    MEASURE ``entropy``, the default, ``pb`` or ``curvature``), best first
                    (``best_0`` ...)
``FILE.json``       a camera file (:mod:`mi_npr.camera.files`: a missing ``up`` is the scene's
                    up axis, a missing ``fov`` the sensor's); a camera's ``id`` names its view,
                    else ``cam_000`` ...
==================  ===========================================================================

:meth:`ViewSpec.of_cameras` makes a spec of cameras given in memory (a camera path's frames).
Ambiguities resolved: the sphere's views have the up of best view's cameras
(:func:`mi_npr.camera.view_frame`); a file's camera keeps its missing ``up``/``fov`` as ``None``
(the manifest records the camera as given) until it meets the scene's sensor.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np

from .camera import (
    Camera,
    bounding_sphere,
    fit_distance,
    framed_shapes,
    on_sphere,
    orbit,
    read_cameras,
    sphere_directions,
    to_json,
)
from .errors import ParameterError
from .params import MAX_BEST, MAX_VIEWS, SEED_MAX, Param, check_arg, integer_range, seed_rule
from .scene import load_scene
from .viewpoint.measures import check_measure
from .viewpoint.search import check_shapes, search, viewing

#: The counts inside ``mi-npr batch --views SPEC`` (``orbit:N``, ``sphere:N``, ``best:K``, the
#: cameras of a JSON file): checked like every parameter.
VIEW_PARAMS: tuple[Param, ...] = (
    Param("orbit", int, 8, "views on the orbit", integer_range(1, MAX_VIEWS)),
    Param("sphere", int, 8, "views on the viewing sphere", integer_range(1, MAX_VIEWS)),
    Param("best", int, 1, "best-rated views", integer_range(1, MAX_BEST)),
    Param("random", int, 8, "views in random directions", integer_range(1, MAX_VIEWS)),
    Param("file", int, 1, "cameras in a JSON file", integer_range(1, MAX_VIEWS)),
)

_MEASURES = ("entropy", "pb", "curvature")
#: Sphere views stand this much farther than the distance at which what they frame just fits.
FRAME_MARGIN = 1.1


@dataclass(frozen=True)
class ViewSpec:
    """A parsed ``--views`` value: ``kind`` (``scene``, ``orbit``, ``sphere``, ``random``,
    ``best``, ``file``, ``cameras``), a count ``n``, an option (``all`` for ``sphere``, the
    measure for ``best``, the seed for ``random``) and, for a file or cameras given in memory,
    the cameras (their ids set)."""

    text: str
    kind: str
    n: int = 1
    option: str = ""
    cameras: tuple[Camera, ...] = ()

    def ids(self) -> list[str]:
        """The view ids, known without loading the scene (the batch's job list)."""
        if self.kind == "scene":
            return ["scene"]
        if self.kind in ("file", "cameras"):
            return [str(c.id) for c in self.cameras]
        if self.kind == "best":
            return [f"best_{k}" for k in range(self.n)]
        width = max(3, len(str(self.n - 1)))
        return [f"{self.kind}_{k:0{width}d}" for k in range(self.n)]

    @cached_property
    def _index(self) -> dict[str, int]:
        return {str(c.id): k for k, c in enumerate(self.cameras)}

    def camera(self, view: str) -> Camera | None:
        """The camera of ``view`` for a file or cameras given in memory, else ``None`` (the
        cameras of the other kinds are placed once the scene is loaded)."""
        k = self._index.get(view)
        return None if k is None else self.cameras[k]

    def where(self, view: str) -> str:
        """How errors name the camera of ``view``: its file and index for a camera file."""
        if self.kind != "file":
            return f"camera {view}"
        return f"{self.text}: camera {self._index.get(view, view)}"

    @classmethod
    def of_cameras(cls, cameras: Sequence[Camera], source: str = "cameras") -> ViewSpec:
        """The views of ``cameras`` given in memory, named by their ids (``cam_000`` ... where
        unset); ``text`` (what ``resume`` compares) holds a digest of the cameras, so a changed
        camera is rendered again."""
        cams = _named(list(cameras), source)
        digest = hashlib.sha256(to_json(cams).encode()).hexdigest()[:16]
        return cls(f"{len(cams)} cameras {digest}", "cameras", len(cams), cameras=cams)


def _named(cameras: list[Any], source: str) -> tuple[Camera, ...]:
    """``cameras`` with ids (``cam_%03d`` where unset), checked unique and not ``scene``."""
    if not cameras or not all(isinstance(c, Camera) for c in cameras):
        raise ParameterError(f"{source}: expected a non-empty list of mi_npr.camera.Camera")
    out, seen = [], set()
    for k, c in enumerate(cameras):
        vid = c.id if c.id is not None else f"cam_{k:03d}"
        if vid == "scene":
            raise ParameterError(f"{source}: camera {k}: id 'scene' names the scene's own view")
        if vid in seen:
            raise ParameterError(f"{source}: camera {k}: id {vid!r} is used twice")
        seen.add(vid)
        out.append(c if c.id == vid else replace(c, id=vid))
    return tuple(out)


def _view_param(kind: str) -> Any:
    return next(p for p in VIEW_PARAMS if p.name == kind)


def _random_seed(text: str, option: str) -> int:
    """The seed of ``random:N:SEED`` (0 when not given), checked like ``--seed``."""
    if not option:
        return 0
    try:
        seed = int(option)
    except ValueError:
        raise ParameterError(f"views = {text!r}: seed {option!r} is not an integer") from None
    if not 0 <= seed <= SEED_MAX:
        raise ParameterError(f"views = {text!r}: seed {seed} is not in [0, {SEED_MAX}]")
    return seed


def _whole(who: str, name: str, value: Any, rule: Any) -> int:
    """``value`` as an int that ``rule`` accepts, or :class:`ParameterError`."""
    if value is None:
        raise ParameterError(f"{who}: parameter {name!r} = None: expected an integer")
    return check_arg(who, Param(name, int, 0, name, rule), value)


def random_directions(n: int, seed: int = 0) -> np.ndarray:
    """``n`` unit vectors drawn uniformly on the sphere (normalised 3D standard normals) by
    numpy's PCG64 generator seeded with ``seed``, float64 (n, 3): the same ``(n, seed)`` gives
    the same directions, and the first ``m`` of ``n`` are those of ``m``.

    >>> d = random_directions(3, seed=1)
    >>> d.shape, bool(np.allclose(np.linalg.norm(d, axis=1), 1.0))
    ((3, 3), True)
    >>> bool(np.array_equal(d[:2], random_directions(2, seed=1)))
    True
    """
    n = _whole("random_directions", "n", n, integer_range(1, MAX_VIEWS))
    seed = _whole("random_directions", "seed", seed, seed_rule)
    rng = np.random.Generator(np.random.PCG64(seed))
    out = np.empty((n, 3))
    for k in range(n):  # one draw per view: a longer list keeps the views of a shorter one
        v = rng.standard_normal(3)
        while np.linalg.norm(v) < 1e-9:  # a direction needs a length
            v = rng.standard_normal(3)
        out[k] = v / np.linalg.norm(v)
    return out


def parse_views(text: str) -> ViewSpec:
    """Parse a ``--views`` value (module docstring); :class:`ParameterError` naming it."""
    if not isinstance(text, str) or not text:
        raise ParameterError(
            f"views = {text!r}: expected scene, orbit:N, sphere:N, random:N, best:K or FILE.json"
        )
    if text == "scene":
        return ViewSpec(text, "scene")
    kind, sep, rest = text.partition(":")
    if sep and kind in ("orbit", "sphere", "random", "best"):
        count, _, option = rest.partition(":")
        try:
            n = int(count)
        except ValueError:
            raise ParameterError(f"views = {text!r}: {count!r} is not an integer") from None
        n = check_arg(f"views {kind}", _view_param(kind), n)
        if kind == "orbit" and option not in ("", "camera"):
            raise ParameterError(
                f"views = {text!r}: orbit's option is 'camera' (about the scene camera's target)"
            )
        if kind == "sphere" and option not in ("", "all", "upper"):
            raise ParameterError(f"views = {text!r}: sphere's option is 'all' or 'upper'")
        if kind == "random":
            option = str(_random_seed(text, option))
        if kind == "best":
            option = option or "entropy"
            if option not in _MEASURES:
                raise ParameterError(
                    f"views = {text!r}: measure {option!r}: expected {', '.join(_MEASURES)}"
                )
        return ViewSpec(text, kind, n, option)
    if text.lower().endswith(".json") or os.path.isfile(text):
        cams = _named(read_cameras(text), text)
        check_arg(text, _view_param("file"), len(cams))
        return ViewSpec(text, "file", len(cams), cameras=cams)
    raise ParameterError(
        f"views = {text!r}: expected scene, orbit:N, sphere:N, random:N, best:K or FILE.json"
    )


# -- cameras of a loaded scene ----------------------------------------------------------------


def sphere(
    scene: Any,
    sensor: Any,
    n: int,
    upper: bool = True,
    seed: int | None = None,
    frame: Sequence[str] = (),
) -> list[Camera]:
    """``n`` cameras at Fibonacci-lattice directions on a sphere about the objects that matter
    (:func:`mi_npr.camera.objects_that_matter`: not a floor, a backdrop or a light), at the
    distance from which their bounding sphere fits the film with a 10% margin, best view's up
    axis and fov (only the upper half with ``upper``), looking at its centre
    (:func:`mi_npr.camera.sphere_directions`, :func:`mi_npr.camera.on_sphere`). With ``seed``
    the directions are :func:`random_directions` instead (the whole sphere; ``upper`` is
    ignored). ``frame``: the objects framed instead (:func:`mi_npr.camera.framed_shapes`)."""

    scene = load_scene(scene)
    below = seed is not None or not upper
    view = viewing(scene, res=32, sensor=sensor, allow_below=below, frame=frame)
    c, r, _ = bounding_sphere(scene, framed_shapes(scene, frame))
    if np.all(np.isfinite(c)) and math.isfinite(r) and r > 0:
        distance = FRAME_MARGIN * fit_distance(r, view.fov, view.size)
        view = viewing(scene, c, distance, 32, sensor=sensor, allow_below=below)
    if seed is None:
        d = sphere_directions(n, view.up, upper)
    else:
        d = random_directions(n, seed)
    return on_sphere(d, view.target, view.radius, view.up, view.fov)


def best(
    scene: Any, sensor: Any, k: int, measure: str = "entropy", frame: Sequence[str] = ()
) -> list[Camera]:
    """The ``k`` best-rated viewpoints of best view's search (best first, ties in evaluation
    order); ``frame``: the objects framed (default: the objects that matter)."""

    scene = load_scene(scene)
    k = _whole("views best", "k", k, integer_range(1, MAX_BEST))
    check_measure(measure)
    check_shapes(scene)
    view = viewing(scene, sensor=sensor, frame=frame)
    bv = search(scene, view, measure, 3)
    if k > bv.evaluations:
        raise ParameterError(f"views best:{k}: the search rated only {bv.evaluations} viewpoints")
    order = np.argsort(-bv.qualities, kind="stable")[:k]
    out = []
    for i in order:
        v = bv.view(int(i))
        out.append(Camera(v.origin, v.target, v.up, float(bv.fov)))
    return out


def cameras(
    spec: ViewSpec, scene: Any, sensor: Any, frame: Sequence[str] = ()
) -> list[tuple[str, Camera | None]]:
    """The views of ``spec`` for a loaded scene seen by ``sensor``: ``(view id, camera)``;
    the camera is ``None`` for the ``scene`` view (the sensor itself is rendered). ``frame``:
    the objects that orbits, spheres and best views frame (``--frame``; default: the objects
    that matter, :func:`mi_npr.camera.framed_shapes`)."""
    ids = spec.ids()
    if spec.kind == "scene":
        return [("scene", None)]
    if spec.kind in ("file", "cameras"):
        return [(str(c.id), c) for c in spec.cameras]
    if spec.kind == "orbit":
        target = "camera" if spec.option == "camera" else None
        cams = orbit(scene, spec.n, sensor=sensor, target=target, frame=frame)
    elif spec.kind == "sphere":
        cams = sphere(scene, sensor, spec.n, upper=spec.option != "all", frame=frame)
    elif spec.kind == "random":
        cams = sphere(scene, sensor, spec.n, seed=int(spec.option or 0), frame=frame)
    else:
        cams = best(scene, sensor, spec.n, spec.option, frame=frame)
    return list(zip(ids, cams, strict=True))
