"""Fitting to a line drawing: the camera from a sketch (:func:`fit_camera`).

Given a scene and a line drawing of it seen from an unknown camera, find the camera whose
:func:`~mi_npr.ad.soft_lines` match the drawing: minimise the multi-scale blurred L2
(:func:`~mi_npr.ad.blurred_l2`) between the rendered lines and the drawing's ink with
``mi.ad.Adam``, coarse to fine.

**Parameters.** ``origin`` and ``target`` (world units), ``up`` (re-orthonormalised against the
view direction at every use, so only its roll matters) and ``fov`` (degrees), each optimised
or held (``params``). The learning rates are relative: ``lr`` times the start's distance
``|target - origin|`` for the points, ``lr`` for ``up``, ``lr`` times 50 degrees for ``fov``.

**Schedule.** ``iterations`` Adam steps; the blur scales of the loss go from wide to narrow
(:data:`SCHEDULE`: the first third of the steps with ``scales[0:]``, the next with
``scales[1:]``, the last with ``scales[2:]`` of ``scales``), so the far field pulls first and
the narrow scales place the lines; the learning rate decays by 10 over the run.

Ambiguity resolved: ``target`` is a point only up to its position along the view line (the
image does not depend on it); the fit moves it only across. A start taken from the scene's
sensor (which keeps no target) gets its target across from the centre of the scene's objects.

A drawing of another size than the render, a variant without AD, and a name in ``params`` that
is not a camera parameter are :class:`~mi_npr.errors.ParameterError` s naming the value.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from .. import io
from ..camera import Camera, across_from, bounding_sphere, view_frame
from ..camera.sensor import camera_of, resolve, sensor_xml
from ..errors import ParameterError
from ..params import Param, check_arg, entry, integer_range, real_range
from ..raycast import film_size, require_jit
from ..scene import load_scene, merge_defines
from .losses import blurred_l2, read_drawing
from .visibility import Pinhole, soft_lines

#: The camera parameters :func:`fit_camera` can optimise.
CAMERA_PARAMS = ("origin", "target", "up", "fov")

#: Blur scales (pixels) of the loss, widest first; the schedule drops the widest as it goes.
SCALES = (8.0, 4.0, 2.0, 1.0)
#: Options of :func:`~mi_npr.ad.soft_lines` while fitting: cheaper than its defaults.
LINE_OPTIONS: dict[str, Any] = {"n": 2, "sigma": 0.7}


def require_ad(what: str) -> None:
    """Fitting needs a differentiable variant: a one-line error naming the active one."""
    require_jit(what)
    if not dr.is_diff_v(mi.Float):
        variant = str(mi.variant())
        hint = variant.replace("_", "_ad_", 1) if "_ad_" not in variant else "llvm_ad_rgb"
        raise ParameterError(
            f"{what} needs an AD variant, and {variant!r} has none: use {hint!r} "
            f"(mi_npr.set_variant({hint!r}) or --variant {hint})"
        )


def names_rule(allowed: Sequence[str], what: str) -> Callable[[Any], str | None]:
    """The rule of a parameter list (names joined by commas), each one of ``allowed``."""

    def check(v: Any) -> str | None:
        names = [n.strip() for n in str(v).split(",") if n.strip()]
        bad = [n for n in names if n not in allowed]
        if bad:
            return f"{bad[0]!r} is not a differentiable {what} parameter ({', '.join(allowed)})"
        return None if names else f"give at least one of {', '.join(allowed)}"

    return check


#: :func:`fit_camera`'s settings (the command line's flags are built from this table).
FIT_PARAMS: tuple[Param, ...] = (
    Param("iterations", int, 120, "Adam steps", integer_range(1, 100_000)),
    Param("lr", float, 0.03, "learning rate (relative to the camera's distance for points)",
          real_range(0.0, 1.0, open_lo=True)),
    Param("fit", str, "origin,target,up",
          "the camera parameters to fit, comma-separated: origin, target, up, fov",
          names_rule(CAMERA_PARAMS, "camera")),
    Param("samples", int, 2, "samples per pixel along each axis of the differentiable lines",
          integer_range(1, 16)),
)  # fmt: skip


def _names(who: str, table: Sequence[Param], value: Sequence[str] | str) -> tuple[str, ...]:
    """A parameter list (a sequence of names, or names joined by commas) checked by the
    table's ``fit`` rule."""
    text = value if isinstance(value, str) else ",".join(str(v) for v in value)
    text = check_arg(who, entry(table, "fit"), text)
    return tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))


def drawing_ink(drawing: Any, size: tuple[int, int]) -> np.ndarray:
    """The drawing (a path to a PNG or SVG, or an (H, W) ink array) checked against the
    render's ``size = (W, H)``; another size is an error naming both."""
    name = "the drawing"
    if isinstance(drawing, (str, os.PathLike)):
        name = os.fspath(drawing)
        drawing = read_drawing(drawing)
    ink = np.asarray(drawing, np.float32)
    if ink.ndim != 2:
        raise ParameterError(f"{name}: expected an (H, W) drawing, got shape {ink.shape}")
    if ink.shape != (size[1], size[0]):
        raise ParameterError(
            f"{name} is {ink.shape[1]}x{ink.shape[0]} pixels, the scene's film "
            f"{size[0]}x{size[1]}: they must be the same size"
        )
    return ink


@dataclass
class CameraFit:
    """What :func:`fit_camera` found: the ``camera``, the ``start``, the ``loss`` after each
    step and the wall ``seconds`` the fit took."""

    camera: Camera
    start: Camera
    loss: list[float] = field(default_factory=list)
    seconds: float = 0.0


def _frame(o: Any, t: Any, up: Any, fov: Any) -> Pinhole:
    return Pinhole.look_at(o, t, up, fov)


def _camera(opt: Any, values: dict[str, Any], params: Sequence[str]) -> Camera:
    """The optimiser's camera as a :class:`Camera` (``up`` made orthogonal to the view)."""
    v = {k: np.asarray(opt[k] if k in params else values[k], np.float64).ravel() for k in values}
    o, t = v["origin"], v["target"]
    f = (t - o) / np.linalg.norm(t - o)
    up = v["up"] - f * float(v["up"] @ f)
    return Camera(tuple(o), tuple(t), tuple(up / np.linalg.norm(up)), float(v["fov"][0]))


def _sensor_start(scene: mi.Scene, sensor: mi.Sensor) -> Camera:
    """The sensor's camera with its target on the view line across from the centre of the
    scene's objects (a sensor keeps no target, and the distance to it scales the steps)."""
    c = camera_of(sensor)
    centre, radius, _ = bounding_sphere(scene)
    return Camera(c.origin, tuple(across_from(c, centre, radius)), c.up, c.fov)


def fit_camera(
    scene: mi.Scene | str | os.PathLike[str],
    drawing: Any,
    *,
    start: Camera | None = None,
    params: Sequence[str] | str = ("origin", "target", "up"),
    iterations: int = 120,
    lr: float = 0.03,
    samples: int = 2,
    scales: Sequence[float] = SCALES,
    line_options: dict[str, Any] | None = None,
    on_step: Callable[[int, float, Camera], None] | None = None,
) -> CameraFit:
    """The camera that sees ``scene``'s lines as ``drawing`` (module docstring).

    ``scene``: a loaded scene or an XML path; ``drawing``: a PNG or SVG path
    (:func:`~mi_npr.ad.read_drawing`) or an (H, W) ink array, the size of the scene's film;
    ``start``: the first guess (the scene's sensor by default; a missing ``up``/``fov`` from
    it); ``params``: which of :data:`CAMERA_PARAMS` to optimise (a list, or names joined by
    commas); ``samples``: the lines' samples per pixel along each axis; ``line_options``:
    other :func:`~mi_npr.ad.soft_lines` options (:data:`LINE_OPTIONS`);
    ``on_step(i, loss, camera)`` is called after every step with the camera so far.
    """
    require_ad("fit_camera")
    params = _names("fit_camera", FIT_PARAMS, params)
    iterations = check_arg("fit_camera", entry(FIT_PARAMS, "iterations"), iterations)
    lr = check_arg("fit_camera", entry(FIT_PARAMS, "lr"), lr)
    samples = check_arg("fit_camera", entry(FIT_PARAMS, "samples"), samples)
    if not isinstance(scene, mi.Scene):
        scene = load_scene(scene)
    scales = tuple(float(s) for s in scales)
    if not scales:
        raise ParameterError("scales: give at least one")
    sensor = scene.sensors()[0] if scene.sensors() else None
    if sensor is None:
        raise ParameterError("fit_camera: the scene has no sensor (its film gives the size)")
    size = film_size(sensor)
    ink = drawing_ink(drawing, size)
    begin = resolve(start, sensor) if start is not None else _sensor_start(scene, sensor)
    opts = {**LINE_OPTIONS, "n": samples, **(line_options or {})}
    bb = scene.bbox()
    opts.setdefault("depth_scale", float(dr.norm(bb.max - bb.min)) if bb.valid() else 1.0)

    dist = float(np.linalg.norm(np.subtract(begin.target, begin.origin)))
    values = {
        "origin": mi.Point3f(begin.origin),
        "target": mi.Point3f(begin.target),
        "up": mi.Vector3f(begin.up),
        "fov": mi.Float(begin.fov),
    }
    rates = {"origin": lr * dist, "target": lr * dist, "up": lr, "fov": lr * 50.0}
    opt = mi.ad.Adam(lr=lr)
    for k in params:
        opt[k] = values[k]
    total = float(ink.sum())
    t0 = time.perf_counter()
    result = CameraFit(camera=begin, start=begin)
    stages = [scales[min(i, len(scales) - 1) :] for i in range(3)]
    for i in range(iterations):
        stage = stages[min(2, 3 * i // iterations)]
        decay = 0.1 ** (i / iterations)
        opt.set_learning_rate({k: rates[k] * decay for k in params})
        cur = {k: opt[k] if k in params else values[k] for k in CAMERA_PARAMS}
        cam = _frame(cur["origin"], cur["target"], cur["up"], cur["fov"])
        lines = soft_lines(scene, cam, size, **opts)
        # The same amount of ink as the drawing: a drawing's line width is not the render's,
        # and without this, shrinking the lines (moving away) lowers the loss by itself.
        lines = lines * (total / dr.maximum(dr.sum(lines.array), 1e-6))
        loss = blurred_l2(lines, ink, stage)
        dr.backward(loss)
        opt.step()
        if "up" in params:  # only the roll matters: keep it a unit vector
            opt["up"] = dr.normalize(opt["up"])
        value = float(loss[0])
        result.loss.append(value)
        if on_step is not None:
            on_step(i, value, _camera(opt, values, params))
    result.camera = _camera(opt, values, params)
    result.seconds = time.perf_counter() - t0
    return result


def camera_error(camera: Camera, reference: Camera) -> tuple[float, float]:
    """``(degrees, distance)`` between two cameras: the angle of the rotation between their
    frames (view direction and roll together), and the distance between their origins
    relative to ``reference``'s distance to its target."""
    a = np.array(view_frame(camera.origin, camera.target, camera.up))
    b = np.array(view_frame(reference.origin, reference.target, reference.up))
    cos = np.clip((np.trace(a @ b.T) - 1.0) / 2.0, -1.0, 1.0)
    scale = np.linalg.norm(np.subtract(reference.target, reference.origin))
    moved = np.linalg.norm(np.subtract(camera.origin, reference.origin))
    return float(np.degrees(np.arccos(cos))), float(moved / scale)


def ink_picture(ink: Any) -> np.ndarray:
    """Line ink ((H, W) in [0, 1]) as a picture: dark lines on white paper, as
    :func:`~mi_npr.ad.read_drawing` reads it back (``1 - luminance``)."""
    return np.clip(1.0 - np.asarray(ink, np.float32), 0.0, 1.0)


def write_fit_camera(
    scene_path: str | os.PathLike[str],
    drawing: str | os.PathLike[str],
    outdir: str | os.PathLike[str],
    *,
    stem: str | None = None,
    defines: dict[str, Any] | None = None,
    **options: Any,
) -> tuple[CameraFit, dict[str, Path]]:
    """:func:`fit_camera` on an XML scene and a drawing file, written to ``outdir``:
    ``<stem>_fit_camera.xml`` (the camera as a ``<sensor>``, the film and sampler of the
    scene's, :func:`~mi_npr.camera.sensor.sensor_xml`) and ``<stem>_fit_camera.png`` (the fitted
    camera's lines, dark on white). ``options`` go to :func:`fit_camera`. Returns the fit and
    the written paths by kind (``sensor``, ``lines``)."""
    require_ad("fit_camera")
    scene = load_scene(scene_path, merge_defines(defines, {}))
    fit = fit_camera(scene, drawing, **options)
    d = io.check_writable_dir(outdir, create=True)
    stem = stem or Path(scene_path).stem
    sensor = scene.sensors()[0]
    c = fit.camera
    lines = soft_lines(scene, Pinhole.look_at(c.origin, c.target, c.up, c.fov), film_size(sensor))
    out: dict[str, Path] = {}
    with io.output_set():  # the XML and its picture together, or neither
        note = f"Fitted to {Path(drawing).name} by mi-npr fit-camera"
        out["sensor"] = io.write_text(
            d / f"{stem}_fit_camera.xml", sensor_xml(c, sensor, comment=note)
        )
        out["lines"] = io.write_png(d / f"{stem}_fit_camera.png", ink_picture(lines), linear=False)
    return fit, out


# -- fitting a shape ------------------------------------------------------------------------

#: The pose parameters of an object :func:`fit_shape` can optimise.
SHAPE_PARAMS = ("translation", "rotation", "scale")

#: :func:`fit_shape`'s settings (the command line's flags are built from this table).
SHAPE_FIT_PARAMS: tuple[Param, ...] = (
    entry(FIT_PARAMS, "iterations"),
    entry(FIT_PARAMS, "lr"),
    Param(
        "fit",
        str,
        "translation,rotation,scale",
        "the object's pose parameters to fit, comma-separated: translation, rotation, scale",
        names_rule(SHAPE_PARAMS, "shape"),
    ),
    entry(FIT_PARAMS, "samples"),
)


@dataclass
class ShapeFit:
    """What :func:`fit_shape` found for ``object``: the pose change about ``centre`` (the
    object's bounding-box centre as loaded), ``p -> centre + translation + R (scale (p -
    centre))`` with ``R = Rz Ry Rx`` of ``rotation`` (degrees about x, then y, then z); the
    ``loss`` after each step and the fit's wall ``seconds``."""

    object: str
    centre: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray
    scale: float
    loss: list[float] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def matrix(self) -> np.ndarray:
        """The pose change as a 4x4 world-space matrix (column vectors)."""
        R = np.asarray(_rotation(*np.radians(self.rotation)), np.float64).reshape(3, 3)
        m = np.eye(4)
        m[:3, :3] = R * self.scale
        m[:3, 3] = self.centre + self.translation - m[:3, :3] @ self.centre
        return m

    def to_dict(self) -> dict[str, Any]:
        return {
            "object": self.object,
            "centre": self.centre.tolist(),
            "translation": self.translation.tolist(),
            "rotation_degrees_xyz": self.rotation.tolist(),
            "scale": self.scale,
            "matrix": self.matrix.tolist(),
        }


def _rotation(ax: Any, ay: Any, az: Any) -> list[Any]:
    """The 3x3 matrix ``Rz(az) Ry(ay) Rx(ax)`` (row-major, nine entries): well defined, with
    gradients, at 0, unlike an axis-angle vector."""
    cx, sx, cy, sy, cz, sz = (f(a) for a in (ax, ay, az) for f in (np.cos, np.sin))
    if not isinstance(ax, (float, np.floating)):
        cx, sx, cy, sy, cz, sz = (f(a) for a in (ax, ay, az) for f in (dr.cos, dr.sin))
    return [
        cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx,
        sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx,
        -sy, cy * sx, cy * cx,
    ]  # fmt: skip


def _shape_key(scene: mi.Scene, name: str) -> tuple[str, mi.Shape]:
    """The scene's ``mi.traverse`` key that moves the object ``name`` (its ``vertex_positions``
    for a mesh, else its ``to_world``), and the shape."""
    from ..scene import object_table  # here: only the shape fit needs the object table

    table = object_table(scene)
    found = [oid for oid, n in table.names.items() if n == name]
    if not found:
        names = ", ".join(sorted(table.names.values())) or "none"
        raise ParameterError(f"object {name!r}: the scene has no such object (it has {names})")
    shape = table.shapes[found[0]]
    key = f"{shape.id()}.{'vertex_positions' if shape.is_mesh() else 'to_world'}"
    if not shape.id() or key not in mi.traverse(scene):
        raise ParameterError(
            f"object {name!r}: a {shape.class_name()} without a differentiable "
            f"{key.rsplit('.', 1)[-1]} in the scene's parameters; its pose cannot be fitted"
        )
    return key, shape


def fit_shape(
    scene: mi.Scene | str | os.PathLike[str],
    drawing: Any,
    object: str,
    *,
    params: Sequence[str] | str = SHAPE_PARAMS,
    iterations: int = 120,
    lr: float = 0.03,
    samples: int = 2,
    scales: Sequence[float] = SCALES,
    line_options: dict[str, Any] | None = None,
    on_step: Callable[[int, float], None] | None = None,
) -> ShapeFit:
    """The pose of ``object`` (its name in the scene's object table) that makes the scene's
    lines, seen by its sensor, match ``drawing`` (as :func:`fit_camera`, the camera held and
    the object moved): ``params`` among :data:`SHAPE_PARAMS`; learning rates ``lr`` times the
    object's bounding radius for the translation, ``lr`` radians for the rotation and ``lr``
    for the log of the scale. The object is left at the fitted pose."""
    require_ad("fit_shape")
    params = _names("fit_shape", SHAPE_FIT_PARAMS, params)
    iterations = check_arg("fit_shape", entry(SHAPE_FIT_PARAMS, "iterations"), iterations)
    lr = check_arg("fit_shape", entry(SHAPE_FIT_PARAMS, "lr"), lr)
    samples = check_arg("fit_shape", entry(SHAPE_FIT_PARAMS, "samples"), samples)
    scales = tuple(float(s) for s in scales)
    if not scales:
        raise ParameterError("scales: give at least one")
    if not isinstance(scene, mi.Scene):
        scene = load_scene(scene)
    if not scene.sensors():
        raise ParameterError("fit_shape: the scene has no sensor (it sees the drawing)")
    sensor = scene.sensors()[0]
    size = film_size(sensor)
    ink = drawing_ink(drawing, size)
    key, shape = _shape_key(scene, object)
    sp = mi.traverse(scene)  # the scene's: updating it rebuilds the acceleration structure
    bb = shape.bbox()
    centre = np.array((bb.min + bb.max) * 0.5, np.float64).ravel()
    radius = max(float(dr.norm(bb.max - bb.min)) * 0.5, 1e-6)
    mesh = key.endswith(".vertex_positions")
    original = mi.Float(sp[key]) if mesh else mi.Transform4f(sp[key])
    cam = Pinhole.of_sensor(sensor)
    opts = {**LINE_OPTIONS, "n": samples, **(line_options or {})}
    sb = scene.bbox()
    opts.setdefault("depth_scale", float(dr.norm(sb.max - sb.min)) if sb.valid() else 1.0)
    values = {"translation": mi.Vector3f(0.0), "rotation": mi.Vector3f(0.0), "scale": mi.Float(0.0)}
    rates = {"translation": lr * radius, "rotation": lr, "scale": lr}
    opt = mi.ad.Adam(lr=lr)
    for k in params:
        opt[k] = values[k]
    c = mi.Point3f(centre)
    total = float(ink.sum())

    def pose(cur: dict[str, Any]) -> None:
        r = cur["rotation"]
        R = _rotation(r.x, r.y, r.z)
        s = dr.exp(cur["scale"])
        if mesh:
            q = dr.unravel(mi.Point3f, original) - c
            rq = mi.Vector3f(
                *(R[3 * i] * q.x + R[3 * i + 1] * q.y + R[3 * i + 2] * q.z for i in range(3))
            )
            sp[key] = dr.ravel(c + cur["translation"] + s * rq)
        else:
            t = c + cur["translation"]
            M = mi.Matrix4f(
                s * R[0], s * R[1], s * R[2], 0.0,
                s * R[3], s * R[4], s * R[5], 0.0,
                s * R[6], s * R[7], s * R[8], 0.0,
                0.0, 0.0, 0.0, 1.0,
            )  # fmt: skip
            T = mi.Transform4f().translate(t) @ mi.Transform4f(M) @ mi.Transform4f().translate(-c)
            sp[key] = T @ original
        sp.update()

    t0 = time.perf_counter()
    fit = ShapeFit(object, centre, np.zeros(3), np.zeros(3), 1.0)
    stages = [scales[min(i, len(scales) - 1) :] for i in range(3)]
    for i in range(iterations):
        decay = 0.1 ** (i / iterations)
        opt.set_learning_rate({k: rates[k] * decay for k in params})
        pose({k: opt[k] if k in params else values[k] for k in SHAPE_PARAMS})
        lines = soft_lines(scene, cam, size, **opts)
        lines = lines * (total / dr.maximum(dr.sum(lines.array), 1e-6))
        loss = blurred_l2(lines, ink, stages[min(2, 3 * i // iterations)])
        dr.backward(loss)
        opt.step()
        fit.loss.append(float(loss[0]))
        if on_step is not None:
            on_step(i, fit.loss[-1])
    final = {k: opt[k] if k in params else values[k] for k in SHAPE_PARAMS}
    pose({k: dr.detach(v) for k, v in final.items()})
    fit.translation = np.asarray(final["translation"], np.float64).ravel()
    fit.rotation = np.degrees(np.asarray(final["rotation"], np.float64).ravel())
    fit.scale = float(np.exp(np.asarray(final["scale"]).ravel()[0]))
    fit.seconds = time.perf_counter() - t0
    return fit


def write_fit_shape(
    scene_path: str | os.PathLike[str],
    drawing: str | os.PathLike[str],
    object: str,
    outdir: str | os.PathLike[str],
    *,
    stem: str | None = None,
    defines: dict[str, Any] | None = None,
    **options: Any,
) -> tuple[ShapeFit, dict[str, Path]]:
    """:func:`fit_shape` on an XML scene and a drawing file, written to ``outdir``:
    ``<stem>_fit_shape.json`` (:meth:`ShapeFit.to_dict`: the pose change and its 4x4 matrix,
    to apply before the object's ``to_world``) and ``<stem>_fit_shape.png`` (the scene's lines
    with the object at the fitted pose, dark on white). ``options`` go to :func:`fit_shape`."""
    import json  # only this writer needs it

    require_ad("fit_shape")
    scene = load_scene(scene_path, merge_defines(defines, {}))
    fit = fit_shape(scene, drawing, object, **options)
    d = io.check_writable_dir(outdir, create=True)
    stem = stem or Path(scene_path).stem
    lines = soft_lines(scene)
    info = {**fit.to_dict(), "loss": fit.loss[-1], "iterations": len(fit.loss)}
    out: dict[str, Path] = {}
    with io.output_set():
        out["pose"] = io.write_text(d / f"{stem}_fit_shape.json", json.dumps(info, indent=2))
        out["lines"] = io.write_png(d / f"{stem}_fit_shape.png", ink_picture(lines), linear=False)
    return fit, out
