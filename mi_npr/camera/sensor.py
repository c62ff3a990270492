"""Cameras and Mitsuba sensors: the pose of a sensor, and a sensor (or a sensor file) at a camera.

- :func:`camera_of`: the :class:`~mi_npr.camera.Camera` of a sensor: ``origin`` the translation
  of its ``to_world``, ``target`` one unit along its +z, ``up`` its unit +y, ``fov`` its
  ``x_fov`` (``None`` without one, e.g. orthographic). Mitsuba keeps no ``lookat`` target, so
  the target is a direction, not a point of the scene.
- :func:`projection_of`: the whole record of a sensor as rendered (transform, lens, film, clip
  planes), the G-buffer's :class:`~mi_npr.gbuffer.Projection`.
- :func:`up_axis`: the scene's up axis, the world axis nearest the sensor's +y
  (:func:`~mi_npr.camera.nearest_axis`): +y for a sensor placed with ``lookat up="0, 1, 0"``
  however it is pitched, +z for ``up="0, 0, 1"``; +y for a scene without a sensor.
- :func:`resolve`: a camera's missing ``up`` becomes :func:`up_axis`, its missing ``fov`` the
  sensor's ``x_fov`` (:data:`DEFAULT_FOV` for a sensor without one, or no sensor). Resolved
  ambiguity: a missing ``up`` is the scene's *axis*, not the sensor's own +y, which a pitched
  scene camera tilts: given to a camera looking another way it would roll the image.
- :func:`sensor_for`: a ``perspective`` sensor at a resolved camera with the film size (the
  whole film, not a crop window), reconstruction filter, sampler (a clone: type, sample count
  and seed) and clip planes of the sensor it is like: the one way a camera becomes a sensor
  (batch views, camera paths).
- :func:`sensor_xml`: the same sensor as a Mitsuba scene file (the best view's file).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import mitsuba as mi
import numpy as np

from ..errors import ParameterError, shown
from ..gbuffer import Projection
from ..scene import check_resolution
from .model import CAMERA_ID, Camera, nearest_axis, parallel

#: Horizontal field of view (degrees) of a camera where neither it nor its sensor has one.
DEFAULT_FOV = 45.0
#: Film and sampler written by :func:`sensor_xml` for a camera that has no sensor to be like.
DEFAULT_WIDTH = 512
DEFAULT_SPP = 16


def _scalar(x: Any) -> float:
    return float(np.asarray(x).ravel()[0]) if not isinstance(x, (int, float)) else float(x)


def projection_of(sensor: mi.Sensor) -> Projection:
    """The :class:`~mi_npr.gbuffer.Projection` of ``sensor``: its ``to_world``, crop
    resolution, horizontal fov, kind and clip planes (Mitsuba's defaults where it has none)."""
    m = np.asarray(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    params = mi.traverse(sensor)
    fov = _scalar(params["x_fov"]) if "x_fov" in params else None
    kind = sensor.class_name().replace("Camera", "").lower() or "camera"
    near = _scalar(params["near_clip"]) if "near_clip" in params else 1e-2
    far = _scalar(params["far_clip"]) if "far_clip" in params else 1e4
    w, h = sensor.film().crop_size()
    return Projection(m, (int(w), int(h)), fov, kind, near, far)


def _camera(p: Projection) -> Camera:
    o = p.origin
    return Camera(o, o + p.forward, p.up, p.fov)


def camera_of(sensor: mi.Sensor) -> Camera:
    """The :class:`~mi_npr.camera.Camera` of ``sensor`` (module docstring)."""
    return _camera(projection_of(sensor))


def up_axis(sensor: mi.Sensor | None) -> np.ndarray:
    """The scene's up axis seen from ``sensor`` (module docstring); +y for ``None``."""
    if sensor is None:
        return np.array([0.0, 1.0, 0.0])
    return nearest_axis(projection_of(sensor).up)


def resolve(camera: Camera, like: mi.Sensor | None, where: str = "camera") -> Camera:
    """``camera`` with its missing ``up`` and ``fov`` taken from the sensor ``like`` (module
    docstring); a scene's up axis along the camera's view is a
    :class:`~mi_npr.errors.ParameterError` starting with ``where``."""
    if camera.resolved:
        return camera
    p = projection_of(like) if like is not None else None
    up = camera.up
    if up is None:
        axis = nearest_axis(p.up) if p is not None else np.array([0.0, 1.0, 0.0])
        if parallel(camera.forward, axis):
            raise ParameterError(
                f"{where}: no up given, and the scene's up axis {axis.tolist()} lies along "
                "the view direction: give the camera an up"
            )
        up = tuple(float(v) for v in axis)
    fov = camera.fov
    if fov is None:
        fov = p.fov if p is not None and p.fov is not None else DEFAULT_FOV
    return replace(camera, up=up, fov=fov)


def sensor_for(camera: Camera, like: mi.Sensor) -> mi.Sensor:
    """A ``perspective`` sensor at ``camera`` (resolved against ``like``) with the film size,
    reconstruction filter, sampler and clip planes of the sensor ``like`` (module docstring)."""
    where = "camera" if camera.id is None else f"camera {camera.id}"
    c = resolve(camera, like, where)
    p = projection_of(like)
    w, h = (int(v) for v in like.film().size())
    d: dict[str, Any] = {
        "type": "perspective",
        "fov": float(c.fov),  # type: ignore[arg-type]
        "fov_axis": "x",
        "to_world": mi.ScalarTransform4f().look_at(
            origin=list(c.origin),
            target=list(c.target),
            up=list(c.up),  # type: ignore[arg-type]
        ),
        "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": like.film().rfilter()},
        "sampler": like.sampler().clone(),
        "near_clip": p.near_clip,
        "far_clip": p.far_clip,
    }
    return mi.load_dict(d)


# -- a camera as a sensor file -------------------------------------------------------------

_FILTERS = {
    "BoxFilter": "box",
    "TentFilter": "tent",
    "GaussianFilter": "gaussian",
    "LanczosSincFilter": "lanczos",
    "MitchellNetravaliFilter": "mitchell",
    "CatmullRomFilter": "catmullrom",
}
_SAMPLERS = {
    "IndependentSampler": "independent",
    "StratifiedSampler": "stratified",
    "MultijitterSampler": "multijitter",
    "OrthogonalSampler": "orthogonal",
    "LowDiscrepancySampler": "ldsampler",
}


def _vec(v: Any) -> str:
    return ", ".join(f"{float(x) + 0.0:.9g}" for x in v)  # + 0.0: no "-0"


def _rfilter_xml(film: mi.Film) -> str:
    rf = film.rfilter()
    kind = _FILTERS.get(rf.class_name())
    if kind is None:  # an unknown filter: hdrfilm's default (gaussian) rather than a bad guess
        return ""
    r = float(rf.radius())
    if kind == "gaussian":  # Mitsuba's gaussian has radius = 4 stddev
        return f'<rfilter type="gaussian"><float name="stddev" value="{r / 4:.9g}"/></rfilter>'
    if kind == "tent":
        return f'<rfilter type="tent"><float name="radius" value="{r:.9g}"/></rfilter>'
    if kind == "lanczos":
        return f'<rfilter type="lanczos"><integer name="lobes" value="{round(r)}"/></rfilter>'
    return f'<rfilter type="{kind}"/>'


def sensor_xml(
    camera: Camera,
    like: mi.Sensor | None = None,
    *,
    size: tuple[int, int] | None = None,
    name: str = "camera",
    comment: str = "",
) -> str:
    """The text of a Mitsuba scene file holding ``camera`` as a ``perspective`` sensor with
    the ``id`` ``name``.

    Copied from the sensor ``like``: near/far clip, sampler type and sample count, film
    width/height (not its crop window), reconstruction filter (type and size; a ``mitchell``
    filter's B and C fall back to their defaults). Written: the resolved camera's ``lookat``
    and ``fov``, with ``fov_axis="x"``. Without ``like``: a film of ``size`` (default
    ``DEFAULT_WIDTH`` square), ``DEFAULT_SPP`` independent samples, hdrfilm's filter.

    The ``<sensor>`` element is wrapped in a ``<scene version="3.0.0">`` root, because Mitsuba
    loads or includes only files with a versioned root and rejects a ``version`` attribute on
    a nested ``<sensor>``: so the file loads on its own (``mi.load_file`` gives a scene with
    that one sensor), ``<include filename="..."/>`` adds its sensor to a scene, and the
    ``<sensor>`` element can be pasted into a scene in place of its own.
    """
    if not isinstance(name, str) or not CAMERA_ID.match(name):
        raise ParameterError(f"sensor id {shown(name)}: expected a file stem")
    if not isinstance(comment, str) or "--" in comment:
        raise ParameterError(f"comment = {shown(comment)}: expected text without '--'")
    if size is not None:
        size = check_resolution(size)
        if size is None or None in size:
            raise ParameterError("size: expected (width, height), both given")
    c = resolve(camera, like)
    if like is None:
        w, h = size if size is not None else (DEFAULT_WIDTH, DEFAULT_WIDTH)
        near, far, rfilter, sampler, spp = 1e-2, 1e4, "", "independent", DEFAULT_SPP
    else:
        p = projection_of(like)
        film = like.film()
        w, h = size if size is not None else tuple(int(v) for v in film.size())
        near, far, rfilter = p.near_clip, p.far_clip, _rfilter_xml(film)
        sampler = _SAMPLERS.get(like.sampler().class_name(), "independent")
        spp = int(like.sampler().sample_count())
    rfilter = f"\n            {rfilter}" if rfilter else ""
    note = f"{comment}.\n     " if comment else ""
    return f"""<?xml version="1.0" encoding="utf-8"?>
<!-- {note}Load this file on its own, <include> it in a scene, or paste the <sensor> element. -->
<scene version="3.0.0">
    <sensor type="perspective" id="{name}">
        <float name="fov" value="{c.fov:.9g}"/>
        <string name="fov_axis" value="x"/>
        <float name="near_clip" value="{near:.9g}"/>
        <float name="far_clip" value="{far:.9g}"/>
        <transform name="to_world">
            <lookat origin="{_vec(c.origin)}"
                    target="{_vec(c.target)}"
                    up="{_vec(c.up)}"/>
        </transform>
        <sampler type="{sampler}">
            <integer name="sample_count" value="{spp}"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="{w}"/>
            <integer name="height" value="{h}"/>{rfilter}
        </film>
    </sensor>
</scene>
"""
