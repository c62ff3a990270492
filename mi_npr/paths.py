"""Camera paths as data: orbits, splines through keyframes, and the paper's exploration.

A path is a list of :class:`~mi_npr.camera.Camera` (``origin``, ``target``, ``up``, ``fov`` in
degrees, horizontal like Mitsuba's ``x_fov``, and ``time``, the frame's time in [0, 1]), written
and read as a camera file (:func:`mi_npr.camera.to_json`, :func:`mi_npr.camera.read_cameras`),
the format of the batch's ``--views FILE.json``.

- :func:`mi_npr.camera.orbit`: a turn around the scene's up axis through the centre of its
  bounding sphere, starting from the scene's own camera (the batch's ``orbit:N`` too);
- :func:`through`: a smooth path through keyframes. Positions (``origin`` and ``target``) follow
  a centripetal Catmull-Rom spline, which passes through every keyframe and never overshoots
  into cusps or self-intersections, with the frames between two keyframes spread evenly by
  the origin's arc length (a constant speed from key to key); keyframe ``k`` of ``K`` is
  frame ``round(k (N - 1) / (K - 1))`` exactly. Orientation has no flips: ``up`` is the
  keyframes' ``up`` blended linearly and made orthogonal to the view direction; where that
  is degenerate (looking along ``up``), the previous frame's ``up`` is parallel-transported
  (rotated by the smallest rotation taking the previous view direction to the new one), so
  ``up`` never jumps. A keyframe without ``up`` or ``fov`` takes the scene sensor's
  (:func:`mi_npr.camera.resolve`, done by :func:`make_path`);
- :func:`explore`: the exploration of the paper (section 2.1, last paragraph: "a camera that
  chooses good viewpoints along a path avoiding brusque changes of direction"), see its
  docstring;
- :func:`render_frames`: every camera rendered with :func:`mi_npr.pipeline.render_layers` (the
  scene loaded once, one sensor per camera from :func:`mi_npr.camera.sensor_for`), written as
  ``frame_0000.exr`` ... with the drawings' PNGs, ``path.json``, ``coherence.json``
  (:mod:`mi_npr.coherence`) and the videos; or every frame a batch job, the cameras handed to
  :func:`mi_npr.batch.run` in memory.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mitsuba as mi
import numpy as np
from PIL import Image
from tqdm import tqdm

from . import layers as L
from .batch import run
from .camera import Camera, orbit, read_cameras, resolve, rotate, sensor_for, to_json
from .camera.model import vector
from .coherence import line_variants, popping
from .errors import NprWarning, ParameterError, SceneError, as_path, shown
from .gbuffer import GBuffer
from .io import read_exr, write_layered_outputs, write_text
from .io.frames import check_format, write_coherence, write_video
from .memory import check_path
from .params import MAX_FRAMES, Param, integer_range, names, real_range
from .pipeline import render_layers
from .scene import load_scene, sensor_of
from .session import SceneSession
from .viewpoint.measures import check_measure
from .viewpoint.search import sample_sphere, viewing

SceneLike = str | os.PathLike[str] | mi.Scene

#: The settings of a path (``mi-npr path``; :func:`render_path`'s keyword arguments).
PATH_PARAMS: tuple[Param, ...] = (
    Param("frames", int, None, "frames of the path", integer_range(1, MAX_FRAMES)),
    Param("fps", int, 24, "video frames per second", integer_range(1, 240)),
    Param("degrees", float, 360.0, "orbit angle", real_range(0.0, 3600.0, open_lo=True)),
    Param(
        "max_speed",
        float,
        4.0,
        "--explore: most degrees the camera moves per frame",
        real_range(0.0, 180.0, open_lo=True),
    ),
    Param(
        "max_turn",
        float,
        12.0,
        "--explore: most degrees its direction of motion turns per frame",
        real_range(0.0, 180.0, open_lo=True),
    ),
)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _times(n: int) -> np.ndarray:
    return np.linspace(0.0, 1.0, n) if n > 1 else np.zeros(1)


def check_frames(frames: Any) -> int:
    """``frames`` as an int in [1, :data:`MAX_FRAMES`], else a :class:`ParameterError`."""
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)):
        raise ParameterError(f"frames = {shown(frames)}: must be an integer")
    if not 1 <= frames <= MAX_FRAMES:
        raise ParameterError(f"frames = {frames}: must be in [1, {MAX_FRAMES}]")
    return int(frames)


# ------------------------------------------------------------------------------ interpolation


def _catmull_rom(p: np.ndarray, seg: int, s: float) -> np.ndarray:
    """Centripetal Catmull-Rom (alpha = 1/2) between ``p[seg]`` and ``p[seg + 1]`` at ``s`` in
    [0, 1]; the end segments mirror their neighbour as the missing control point."""
    n = len(p)
    p1, p2 = p[seg], p[seg + 1]
    p0 = p[seg - 1] if seg > 0 else 2 * p1 - p2
    p3 = p[seg + 2] if seg + 2 < n else 2 * p2 - p1
    if np.allclose(p1, p2):
        return p1.copy()

    def knot(t: float, a: np.ndarray, b: np.ndarray) -> float:
        return t + max(float(np.linalg.norm(b - a)), 1e-12) ** 0.5

    t0 = 0.0
    t1 = knot(t0, p0, p1)
    t2 = knot(t1, p1, p2)
    t3 = knot(t2, p2, p3)
    t = t1 + s * (t2 - t1)
    a1 = (t1 - t) / (t1 - t0) * p0 + (t - t0) / (t1 - t0) * p1
    a2 = (t2 - t) / (t2 - t1) * p1 + (t - t1) / (t2 - t1) * p2
    a3 = (t3 - t) / (t3 - t2) * p2 + (t - t2) / (t3 - t2) * p3
    b1 = (t2 - t) / (t2 - t0) * a1 + (t - t0) / (t2 - t0) * a2
    b2 = (t3 - t) / (t3 - t1) * a2 + (t - t1) / (t3 - t1) * a3
    return (t2 - t) / (t2 - t1) * b1 + (t - t1) / (t2 - t1) * b2


#: Spline parameters at which a segment's arc length is tabulated.
_ARC_S = np.linspace(0.0, 1.0, 129)


def _arc_length(p: np.ndarray, seg: int) -> np.ndarray:
    """Cumulative length of segment ``seg`` at :data:`_ARC_S`: frames are spread evenly by
    length, so the camera moves at a constant speed between two keyframes."""
    pts = np.array([_catmull_rom(p, seg, s) for s in _ARC_S])
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def _transport(up: np.ndarray, d0: np.ndarray, d1: np.ndarray) -> np.ndarray:
    """``up`` rotated by the smallest rotation taking direction ``d0`` to ``d1``."""
    axis = np.cross(d0, d1)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return up
    return rotate(up, axis / s, math.atan2(s, float(np.dot(d0, d1))))


def key_frames(keys: int, frames: int) -> list[int]:
    """The frame of each of ``keys`` keyframes in a path of ``frames`` frames."""
    frames = check_frames(frames)
    if isinstance(keys, bool) or not isinstance(keys, (int, np.integer)) or not 1 <= keys <= frames:
        raise ParameterError(f"keys = {shown(keys)}: must be an integer in [1, frames = {frames}]")
    if keys == 1:
        return [0]
    return [round(k * (frames - 1) / (keys - 1)) for k in range(keys)]


def through(cameras: Sequence[Camera], frames: int) -> list[Camera]:
    """``frames`` cameras through the keyframes ``cameras`` (module docstring): keyframe ``k``
    is frame ``round(k (frames - 1) / (K - 1))``, ``fov`` and ``time`` are blended linearly.
    Every keyframe needs its ``up`` and ``fov`` (:func:`mi_npr.camera.resolve`)."""
    frames = check_frames(frames)
    keys = list(cameras)
    if not keys:
        raise ParameterError("through: no keyframes")
    if not all(isinstance(c, Camera) for c in keys):
        raise ParameterError("through: keyframes must be mi_npr.camera.Camera objects")
    for k, c in enumerate(keys):
        if not c.resolved:
            raise ParameterError(
                f"through: keyframe {k} has no {'up' if c.up is None else 'fov'} "
                "(mi_npr.camera.resolve gives it the scene sensor's)"
            )
    if len(keys) == 1:
        return [keys[0]] * frames
    if frames < len(keys):
        raise ParameterError(f"frames = {frames}: fewer than the {len(keys)} keyframes")
    origins = np.array([c.origin for c in keys])
    T = np.array([c.target for c in keys])
    U = np.array([c.up for c in keys])
    at = key_frames(len(keys), frames)
    out: list[Camera] = []
    prev_up = prev_d = None
    for seg in range(len(keys) - 1):
        a, b = keys[seg], keys[seg + 1]
        last = seg == len(keys) - 2
        arc = _arc_length(origins, seg)
        for f in range(at[seg], at[seg + 1] + (1 if last else 0)):
            u = (f - at[seg]) / max(at[seg + 1] - at[seg], 1)
            s = float(np.interp(u * arc[-1], arc, _ARC_S)) if arc[-1] > 0 else u
            o = _catmull_rom(origins, seg, s)
            t = _catmull_rom(T, seg, s)
            d = _unit(t - o)
            up = (1 - s) * U[seg] + s * U[seg + 1]
            up = up - np.dot(up, d) * d
            if np.linalg.norm(up) < 1e-3 and prev_up is not None:
                up = _transport(prev_up, prev_d, d)
                up = up - np.dot(up, d) * d
            up = _unit(up)
            if prev_up is not None and np.dot(up, prev_up) < 0:  # never a flip
                up = _unit(_transport(prev_up, prev_d, d))
            fov = (1 - s) * a.fov + s * b.fov  # type: ignore[operator]
            time = min(max((1 - s) * a.time + s * b.time, 0.0), 1.0)  # no rounding past 1
            out.append(Camera(o, t, up, fov, time))
            prev_up, prev_d = up, d
    return out


def angular_steps(cameras: Sequence[Camera], centre: Sequence[float] | None = None) -> dict:
    """Per-frame changes of a path, in degrees: ``view`` (angle between consecutive view
    directions), ``speed`` (angle the camera moves by as seen from ``centre``, default each
    frame's target) and ``turn`` (change of the direction of motion on the sphere about
    ``centre``)."""
    D = np.array([c.forward for c in cameras])
    view = np.degrees(np.arccos(np.clip(np.sum(D[1:] * D[:-1], axis=1), -1, 1)))
    C = (
        np.array([c.target for c in cameras])
        if centre is None
        else np.broadcast_to(vector("centre", centre), (len(cameras), 3))
    )
    R = _unit(np.array([c.origin for c in cameras]) - C)
    speed = np.degrees(np.arccos(np.clip(np.sum(R[1:] * R[:-1], axis=1), -1, 1)))
    turn = []
    for i in range(1, len(R) - 1):
        h0 = _heading(R[i - 1], R[i])
        h1 = _heading(R[i], R[i + 1])
        if h0 is None or h1 is None:
            turn.append(0.0)
            continue
        h0 = _unit(_transport(h0, R[i - 1], R[i]))
        turn.append(math.degrees(math.acos(float(np.clip(np.dot(h0, h1), -1, 1)))))
    return {"view": view, "speed": speed, "turn": np.array(turn)}


def _heading(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The unit tangent at ``a`` of the great circle from ``a`` towards ``b``."""
    h = b - np.dot(a, b) * a
    n = np.linalg.norm(h)
    return h / n if n > 1e-12 else None


# -------------------------------------------------------------------------------- exploration


@dataclass(frozen=True)
class Exploration:
    """What :func:`explore` found: the path, the quality of every frame's view (the measure of
    ``measure`` at the viewing sphere's ID-buffer resolution) and the candidate views."""

    cameras: list[Camera]
    qualities: np.ndarray
    candidates: np.ndarray
    candidate_qualities: np.ndarray
    goals: list[int]
    measure: str


def explore(
    scene: SceneLike,
    frames: int,
    measure: str = "entropy",
    *,
    max_speed: float = 4.0,
    max_turn: float = 12.0,
    samples: int = 96,
    res: int = 48,
    max_elevation: float = 75.0,
    visit_radius: float = 25.0,
    sensor: int = 0,
    ignore: Sequence[str] = (),
    result: bool = False,
    frame: Sequence[str] = (),
) -> list[Camera] | Exploration:
    """The paper's automatic exploration (section 2.1, last paragraph): a camera path on the
    viewing sphere through good viewpoints, without brusque changes.

    **How the path is chosen.** The viewing sphere is that of best view
    (:func:`mi_npr.viewpoint.viewing`: centred on the scene's bounding sphere, radius framing
    the whole scene at the sensor's ``fov``, viewpoints on the allowed side of the up axis).
    ``samples`` Fibonacci directions on it, up to ``max_elevation`` degrees above the horizon
    (a camera looking straight down its ``up`` has no defined roll), are rated by ``measure``
    (eq. 1 ``pb``, eq. 2 ``curvature`` or eq. 3 ``entropy``) in batched ID-buffer launches
    (:meth:`~mi_npr.viewpoint.search.Viewing.rate`, ``res`` pixels). The camera starts at the
    best candidate. It then steers, one frame at a time, towards a *goal*: the unvisited
    candidate maximising ``q / q_max - angle / 180`` (quality against the arc still to fly,
    both in [0, 1]). Candidates within ``visit_radius`` degrees of the camera count as visited
    when it passes them, so the path moves on from a good region to the next one instead of
    circling; the goal is reached when the camera is within one step of it, and a new one is
    picked (when all are visited, the visits are forgotten).

    **No brusque change**, bounded per frame and checked by :func:`angular_steps`:

    - *angular speed*: the camera moves along the sphere by at most ``max_speed`` degrees per
      frame (as seen from the sphere's centre; it always looks at the centre, so the view
      direction turns by the same angle), slowing down to land on the goal;
    - *turning*: the direction of motion on the sphere (the great-circle heading) changes by
      at most ``max_turn`` degrees per frame, so a new goal behind the camera gives a smooth
      U-turn, never a reversal.

    Returns the cameras, or with ``result=True`` an :class:`Exploration` with the qualities of
    every frame's view (rated like the candidates).
    """

    frames = check_frames(frames)
    check_measure(measure)
    for name, v, hi in (
        ("max_speed", max_speed, 180.0),
        ("max_turn", max_turn, 180.0),
        ("max_elevation", max_elevation, 90.0),
        ("visit_radius", visit_radius, 180.0),
    ):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= hi:
            raise ParameterError(f"{name} = {v!r}: must be in (0, {hi:g}] degrees")
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 4096:
        raise ParameterError(f"samples = {samples!r}: must be in [1, 4096]")
    s = load_scene(scene)
    view = viewing(s, res=res, sensor=sensor, ignore=ignore, frame=frame)
    up = np.asarray(view.up, np.float64)
    dirs, q = sample_sphere(s, view, measure, max(samples * 2, 8))
    elev = np.degrees(np.arcsin(np.clip(dirs @ up, -1, 1)))
    keep = view.allowed(dirs) & (elev <= max_elevation)
    if not keep.any():
        raise ParameterError("explore: no allowed viewpoint (max_elevation too low?)")
    dirs, q = dirs[keep], np.nan_to_num(q[keep])
    qmax = float(q.max()) if q.max() > 0 else 1.0

    speed, turn = math.radians(max_speed), math.radians(max_turn)
    radius_v = math.radians(visit_radius)
    pos = dirs[int(np.argmax(q))].copy()
    visited = np.zeros(len(dirs), dtype=bool)
    heading: np.ndarray | None = None
    goal = None
    goals: list[int] = []
    path = [pos.copy()]

    def arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.arccos(np.clip(b @ a, -1.0, 1.0))

    def pick() -> int:
        if visited.all():
            visited[:] = False
        score = q / qmax - arc(pos, dirs) / math.pi
        score[visited] = -np.inf
        return int(np.argmax(score))

    while len(path) < frames:
        visited |= arc(pos, dirs) <= radius_v
        if goal is None or arc(pos, dirs[goal][None])[0] <= 1e-6:
            goal = pick()
            goals.append(goal)
        want = _heading(pos, dirs[goal])
        if want is None:  # on the goal already
            goal = None
            path.append(pos.copy())
            continue
        if heading is None:
            heading = want
        else:  # turn towards the goal by at most max_turn
            cosang = float(np.clip(np.dot(heading, want), -1.0, 1.0))
            ang = math.acos(cosang)
            if ang > turn:
                axis = pos  # rotate the heading about the position (the sphere's normal)
                side = 1.0 if np.dot(np.cross(heading, want), axis) >= 0 else -1.0
                heading = _unit(rotate(heading, axis, side * turn))
            else:
                heading = want
        step = min(speed, float(arc(pos, dirs[goal][None])[0]))
        new = math.cos(step) * pos + math.sin(step) * heading
        h = up * max(0.0, -float(np.dot(new, up)))  # stay on the allowed side
        new = _unit(new + h) if not view.allow_below else _unit(new)
        heading = _heading(new, new + (new - pos)) if step > 0 else heading
        pos = new
        path.append(pos.copy())

    P = np.array(path)
    origins = view.origins(P)
    times = _times(frames)
    cams = [Camera(o, view.target, up, view.fov, times[i]) for i, o in enumerate(origins)]
    if not result:
        return cams
    qual = view.qualities(s, origins, measure)
    return Exploration(cams, qual, dirs, q, goals, measure)


def make_path(
    scene: SceneLike,
    frames: int,
    *,
    explore_measure: str | None = None,
    keys: str | os.PathLike[str] | Sequence[Camera] | None = None,
    degrees: float = 360.0,
    max_speed: float = 4.0,
    max_turn: float = 12.0,
    explore_ignore: Sequence[str] = (),
    frame: Sequence[str] = (),
    orbit_target: str = "objects",
) -> list[Camera]:
    """The path of ``mi-npr path``: :func:`explore` with ``explore_measure`` (objects named in
    ``explore_ignore`` count as background), :func:`through` the keyframes ``keys`` (cameras or
    a camera file; a missing ``up`` or ``fov`` is the scene sensor's), else an
    :func:`~mi_npr.camera.orbit` of ``degrees``; the exploration and the orbit frame the
    objects named in ``frame`` (default: the objects that matter); ``orbit_target``:
    ``objects`` (their centre) or ``camera`` (the scene camera's own target,
    :func:`~mi_npr.camera.orbit`)."""
    if explore_measure is not None and keys is not None:
        raise ParameterError("explore and keys: give one of them")
    if explore_measure is not None:
        return explore(
            scene,
            frames,
            explore_measure,
            max_speed=max_speed,
            max_turn=max_turn,
            ignore=explore_ignore,
            frame=frame,
        )
    frames = check_frames(frames)
    if keys is not None:
        if isinstance(keys, (str, os.PathLike)):
            source, cams = os.fspath(keys), read_cameras(keys)
        else:
            source, cams = "keys", list(keys)
        s = load_scene(scene)
        like = sensor_of(s) if s.sensors() else None
        cams = [resolve(c, like, f"{source}: camera {k}") for k, c in enumerate(cams)]
        return through(cams, frames)
    if orbit_target not in ("objects", "camera"):
        raise ParameterError(f"orbit_target = {orbit_target!r}: expected 'objects' or 'camera'")
    target = "camera" if orbit_target == "camera" else None
    return orbit(scene, frames, degrees, target=target, frame=frame)


def path_qualities(
    scene: SceneLike, cameras: Sequence[Camera], measure: str = "entropy", res: int = 48
) -> np.ndarray:
    """The quality (eq. 1, 2 or 3) of every camera's view at the viewing sphere's distance
    (:func:`mi_npr.viewpoint.viewing`): for comparing paths of different radii."""

    check_measure(measure)
    s = load_scene(scene)
    view = viewing(s, res=res)
    d = np.array([np.subtract(c.origin, view.target) for c in cameras])
    return view.qualities(s, view.origins(d), measure)


# ---------------------------------------------------------------------------------- rendering


class FrameFiles(Sequence):
    """The frames of a path as written in a folder, read back one at a time: item ``i`` is
    ``frame_%04d.exr``'s layers of the coherence measure (``Z``, ``P``, the line layers) with
    its camera. The measure and the videos go through the frames in order, so they hold one or
    two frames in memory however long the path."""

    def __init__(self, outdir: str | os.PathLike[str], frames: int) -> None:
        self.outdir, self.frames = as_path(outdir, "output directory"), check_frames(frames)

    def __len__(self) -> int:
        return self.frames

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(self.frames))]
        if not -self.frames <= i < self.frames:
            raise IndexError(f"frame {i} of {self.frames}")
        gb = read_exr(self.outdir / f"frame_{i % self.frames:04d}.exr")
        return GBuffer({n: gb[n] for n in _KEPT if n in gb}, camera=gb.camera)

    def pictures(self, suffix: str = "") -> Iterator[np.ndarray]:
        """The sRGB frames ``frame_%04d<suffix>.png`` in order (``_contours``: the contour
        overlay), as the videos take them; a frame without one ends the sequence."""
        for i in range(self.frames):
            png = self.outdir / f"frame_{i:04d}{suffix}.png"
            if not png.is_file():
                return
            with Image.open(png) as im:
                yield np.asarray(im.convert("RGB"))


@dataclass
class Frames:
    """What :func:`render_frames` wrote and measured."""

    files: list[Path]
    #: the frames for :func:`mi_npr.coherence.popping` (``P``, ``Z``, the line layers), read
    #: from the written files as they are used (:class:`FrameFiles`)
    gbuffers: Sequence
    coherence: dict | None = None
    videos: list[Path] | None = None


#: Layers of a frame the coherence measure reads.
_KEPT = (L.Z, *L.P, L.LINES, L.CONTOUR)


def render_frames(
    scene: SceneLike,
    cameras: Sequence[Camera],
    out: str | os.PathLike[str],
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    *,
    resolution: tuple[int | None, int | None] | None = None,
    spp: int | str | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
    video: str | None = None,
    fps: int = 24,
    variants: bool = False,
    progress: bool = False,
    on_frame: Callable[[int, Any], None] | None = None,
    cluster: Mapping[str, Any] | None = None,
) -> Frames:
    """Render every camera of a path into ``out`` (the one place frames are rendered).

    The scene is loaded once (:class:`~mi_npr.session.SceneSession`: ``resolution``, ``spp``,
    ``defines``); frame ``i`` is :func:`mi_npr.pipeline.render_layers` of that scene seen by
    :func:`mi_npr.camera.sensor_for` of camera ``i``, written by
    :func:`mi_npr.io.write_layered_outputs` as ``frame_%04d.exr``, ``frame_%04d.png`` and each
    drawing's PNG/SVG. Then ``path.json`` (the cameras), ``coherence.json``
    (:func:`mi_npr.coherence.popping` of the ``lines`` layer, or the ``contour`` layer without
    lines) and, with ``video`` (``"mp4"`` or ``"gif"``), the
    videos ``beauty.<fmt>`` (the beauty with the lines) and ``contours.<fmt>`` (the contour
    overlay, with ``contours`` on) through :func:`mi_npr.io.frames.write_video`. With
    ``variants``, ``coherence.json`` also holds the popping of the four line variants of the
    thesis's claim (:func:`mi_npr.coherence.line_variants`) and the plot draws them.

    Memory does not grow with the path: each frame goes to disk as it is rendered, and the
    coherence measure and an mp4 read the frames back one at a time (:class:`FrameFiles`); a
    gif holds its frames, so the memory it needs is checked before the first frame renders
    (:func:`mi_npr.memory.check_path`).

    ``cluster`` (``workers``, ``threads_per_worker``, ``scheduler``, ``client``, ``resume``,
    ``retries``, ``job_timeout``: :func:`mi_npr.batch.run`'s) makes every frame a batch job on
    Dask instead: ``scene`` must then be an XML path; the cameras go to the batch in memory
    (camera ``i`` is the view ``frame_%04d``); the frames are the same files (plus the batch's
    ``manifest.jsonl``, so ``resume`` skips finished frames), read back for the coherence
    measure and the videos.
    """

    cams = list(cameras)
    if not cams:
        raise ParameterError("render_frames: no cameras")
    if video is not None:
        check_format(video)
    drawings = names("drawings", drawings)
    outdir = as_path(out, "output directory")
    outdir.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    session = None
    if cluster is None:
        session = SceneSession.open(scene, spp=spp, defines=defines, resolution=resolution)
        w, h = (int(v) for v in session.sensor.film().crop_size())
    else:
        w, h = resolution if resolution is not None else (None, None)
    if w is not None and h is not None:
        gifs = (1 + ("contours" in drawings)) if video == "gif" else 0
        check_path(w, h, len(cams), gifs)
    if cluster is not None:
        files += _frames_as_jobs(
            scene, cams, outdir, drawings, params, resolution, spp, seed, defines, cluster, progress
        )
    else:
        assert session is not None
        bar = tqdm(total=len(cams), desc="frames", unit="frame", leave=False) if progress else None
        for i, cam in enumerate(cams):
            sensor = sensor_for(cam, session.sensor)
            r = render_layers(
                session.scene, drawings, params, sensor=sensor, spp=session.spp, seed=seed
            )
            files += write_layered_outputs(r, outdir, f"frame_{i:04d}")
            if on_frame is not None:
                on_frame(i, r)
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
    frames = FrameFiles(outdir, len(cams))
    files.append(write_text(outdir / "path.json", to_json(cams)))
    if cluster is None:  # the batch names the files of its earlier jobs itself
        _warn_other_frames(outdir, len(cams))
    first = frames[0]
    layer = L.LINES if L.LINES in first else L.CONTOUR if L.CONTOUR in first else None
    del first
    coherence = None
    curves = line_variants(frames) if variants else None
    if layer is not None:
        coherence = popping(frames, layer=layer)
    elif curves:
        coherence = {"layer": None, "overall": None}
    if coherence is not None:
        files += write_coherence(coherence, outdir, curves)
        coherence = {**coherence, "variants": curves} if curves else coherence
    videos = []
    if video is not None:
        written = {p.name for p in files}
        for name, suffix in (("beauty", ""), ("contours", "_contours")):
            if f"frame_0000{suffix}.png" in written:
                videos.append(
                    write_video(outdir / f"{name}.{video}", frames.pictures(suffix), fps=fps)
                )
    files += videos
    return Frames(files, frames, coherence, videos)


_FRAME = re.compile(r"^frame_(\d{4,})[._]")


def _warn_other_frames(outdir: Path, frames: int) -> None:
    """A warning naming the frame files of an earlier, longer path left in ``outdir`` (they
    are not part of this path: ``path.json``, the coherence and the videos leave them out)."""
    left = sorted(
        e.name for e in os.scandir(outdir) if (m := _FRAME.match(e.name)) and int(m[1]) >= frames
    )
    if left:
        shown = ", ".join(left[:4]) + (", ..." if len(left) > 4 else "")
        warnings.warn(
            f"{outdir}: frame files of an earlier, longer path are left beside this path's "
            f"{frames} frames: {shown}",
            NprWarning,
            stacklevel=3,
        )


def _frames_as_jobs(
    scene: SceneLike,
    cams: Sequence[Camera],
    outdir: Path,
    drawings: Sequence[str],
    params: Mapping[str, Any] | None,
    resolution: tuple[int | None, int | None] | None,
    spp: int | str | None,
    seed: int,
    defines: Mapping[str, Any] | None,
    cluster: Mapping[str, Any],
    progress: bool,
) -> list[Path]:
    """Every frame a job of :func:`mi_npr.batch.run` (the cameras, named ``frame_%04d``, given
    in memory; written flat into ``outdir``); the files written, or one
    :class:`~mi_npr.errors.SceneError` line naming the first frame that failed."""

    if not isinstance(scene, (str, os.PathLike)):
        raise ParameterError("frames as batch jobs: give the scene as an XML path")
    views = [replace(c, id=f"frame_{i:04d}") for i, c in enumerate(cams)]
    w, h = resolution if resolution is not None else (None, None)
    allowed = {
        "workers",
        "threads_per_worker",
        "scheduler",
        "client",
        "resume",
        "retries",
        "job_timeout",
        "dashboard",
        "on_dashboard",
    }
    unknown = sorted(set(cluster) - allowed)
    if unknown:
        raise ParameterError(
            f"cluster: unknown option {unknown[0]!r} ({', '.join(sorted(allowed))})"
        )
    rows = run(
        [scene],
        views,
        out=outdir,
        drawings=drawings,
        params=params,
        width=w,
        height=h,
        spp=None if spp is None else int(spp),
        seed=seed,
        defines=defines,
        progress=progress,
        flat=True,
        **cluster,
    )
    failed = [r for r in rows if r.get("status") != "done"]
    if failed:
        raise SceneError(f"{len(failed)} of {len(rows)} frames failed: {failed[0].get('error')}")
    return [outdir / p for r in rows for p in r["outputs"]]


def render_path(
    scene: SceneLike,
    out: str | os.PathLike[str],
    frames: int,
    drawings: Sequence[str] = (),
    params: Mapping[str, Any] | None = None,
    *,
    explore_measure: str | None = None,
    keys: str | os.PathLike[str] | Sequence[Camera] | None = None,
    degrees: float = 360.0,
    max_speed: float = 4.0,
    max_turn: float = 12.0,
    explore_ignore: Sequence[str] = (),
    frame: Sequence[str] = (),
    orbit_target: str = "objects",
    resolution: tuple[int | None, int | None] | None = None,
    spp: int | str | None = None,
    defines: Mapping[str, Any] | None = None,
    **options: Any,
) -> Frames:
    """``mi-npr path``: load ``scene`` once (``resolution``, ``spp``, ``defines``), build its
    path (:func:`make_path`) and render it (:func:`render_frames`, ``options``)."""

    session = SceneSession.open(scene, spp=spp, defines=defines, resolution=resolution)
    cams = make_path(
        session.scene,
        frames,
        explore_measure=explore_measure,
        keys=keys,
        degrees=degrees,
        max_speed=max_speed,
        max_turn=max_turn,
        explore_ignore=explore_ignore,
        frame=frame,
        orbit_target=orbit_target,
    )
    if options.get("cluster") is not None:  # frames as batch jobs: the workers load the file
        return render_frames(
            scene, cams, out, drawings, params, resolution=resolution, spp=spp, defines=defines,
            **options,
        )  # fmt: skip
    return render_frames(session.scene, cams, out, drawings, params, spp=session.spp, **options)
