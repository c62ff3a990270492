"""The G-buffer pass: one ray through the exact centre of every pixel, never filtered.

Mitsuba's film averages every AOV through its reconstruction filter (mitsuba3 #396, #575), which
blends integer ids across edges. So the G-buffer bypasses the film: rays are generated here with
``sensor.sample_ray`` at pixel centres ``((x + 0.5) / W, (y + 0.5) / H)`` of the crop window, at
the centre of the lens (aperture sample 0.5) and of the shutter interval, intersected once, and
each channel is evaluated as its own planar array. The beauty image is the nested integrator's own
``render`` at the film's filter and spp, so the two never mix.

Per pixel (see :mod:`mi_npr.layers`): ``Z`` camera-space depth along the view axis (+inf on a
miss), ``P`` world position, ``N`` shading normal, ``object_id``, ``prim_id``, and ``R G B``.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Mapping
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from . import layers as L
from ._version import __version__
from .errors import ParameterError, SceneError, one_line
from .gbuffer import GBuffer, to_numpy
from .memory import check_render, render_passes
from .scene import (
    ObjectTable,
    camera_of,
    declared_defaults,
    load_scene,
    merge_defines,
    object_table,
    sensor_of,
)

# Mitsuba scenes must not be rendered from two threads at once.
_LOCK = threading.RLock()


def _camera_frame(sensor: mi.Sensor) -> tuple[Any, Any]:
    """Camera origin and unit view axis (+z of the camera frame) in world space."""
    T = sensor.world_transform()
    o = T @ mi.Point3f(0.0, 0.0, 0.0)
    f = dr.normalize(T @ mi.Vector3f(0.0, 0.0, 1.0))
    return o, f


def pixel_rays(sensor: mi.Sensor, x: Any, y: Any) -> mi.Ray3f:
    """Rays through pixel positions ``(x, y)`` of the crop window (centres are ``i + 0.5``)."""
    w, h = sensor.film().crop_size()
    time = sensor.shutter_open() + 0.5 * sensor.shutter_open_time()
    pos = mi.Point2f(x / float(w), y / float(h))
    ray, _ = sensor.sample_ray(time, 0.5, pos, mi.Point2f(0.5, 0.5))
    return ray


def _headlight(si: mi.SurfaceInteraction3f, ray: mi.Ray3f, valid: Any) -> Any:
    """Cheap preview shading when no beauty integrator is nested: albedo x headlight cosine."""
    if not dr.is_jit_v(mi.Float) and not valid:
        return mi.Color3f(0.0)  # scalar variants: a miss has no BSDF to ask
    bsdf = si.bsdf(ray)
    albedo = mi.Color3f(0.6)
    if mi.is_rgb:
        refl = bsdf.eval_diffuse_reflectance(si, valid)
        albedo = dr.select(dr.max(refl) > 0.0, mi.Color3f(refl), albedo)
    cos = dr.abs(dr.dot(si.sh_frame.n, ray.d))
    return dr.select(valid, albedo * (0.2 + 0.8 * cos), mi.Color3f(0.0))


def _bsdf_normals(
    si: mi.SurfaceInteraction3f, valid: Any, table: ObjectTable, ids: Any, n: Any
) -> Any:
    """Shading normals that BSDFs define themselves: a BSDF with a method
    ``npr_shading_normal(si, active) -> world-space unit normal`` (such as ``npr_foliage``'s mixed
    leaf/HLP normal) replaces ``n`` on the pixels of the shapes that use it, so the ``N`` layer
    holds the normal the BSDF shades with. One masked call per such shape (few in a scene)."""
    for oid, shape in table.shapes.items():
        fn = getattr(shape.bsdf(), "npr_shading_normal", None)
        if fn is not None:
            mask = valid & (ids == oid)
            n = dr.select(mask, fn(si, mask), n)
    return n


def trace(
    scene: mi.Scene,
    sensor: mi.Sensor,
    ray: mi.Ray3f,
    table: ObjectTable,
    shade: bool,
) -> dict[str, Any]:
    """G-buffer channels for ``ray`` (any width): ``{layer name: Float/UInt32}``."""
    si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True)
    valid = si.is_valid()
    o, f = _camera_frame(sensor)
    out: dict[str, Any] = {}
    out[L.Z] = dr.select(valid, dr.dot(si.p - o, f), dr.inf)
    for i, name in enumerate(L.P):
        out[name] = dr.select(valid, si.p[i], 0.0)
    ids = table.lookup(si)
    n = _bsdf_normals(si, valid, table, ids, si.sh_frame.n)
    for i, name in enumerate(L.N):
        out[name] = dr.select(valid, n[i], 0.0)
    out[L.OBJECT_ID] = ids
    out[L.PRIM_ID] = dr.select(valid, si.prim_index, 0)
    if shade:
        rgb = _headlight(si, ray, valid)
        for i, name in enumerate(L.RGB):
            out[name] = rgb[i]
    return out


def _pass_jit(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, shade: bool) -> dict:
    w, h = (int(v) for v in sensor.film().crop_size())
    idx = dr.arange(mi.UInt32, w * h)
    x = mi.Float(idx % w) + 0.5
    y = mi.Float(idx // w) + 0.5
    out = trace(scene, sensor, pixel_rays(sensor, x, y), table, shade)
    dr.eval(*out.values())
    return {k: to_numpy(v).reshape(h, w) for k, v in out.items()}


def _pass_scalar(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, shade: bool) -> dict:
    w, h = (int(v) for v in sensor.film().crop_size())
    names = [*L.GBUFFER_AOVS, *(L.RGB if shade else ())]
    arrays = {
        k: np.zeros((h, w), dtype=np.uint32 if k in (L.OBJECT_ID, L.PRIM_ID) else np.float32)
        for k in names
    }
    for yy in range(h):
        for xx in range(w):
            vals = trace(scene, sensor, pixel_rays(sensor, xx + 0.5, yy + 0.5), table, shade)
            for k in names:
                arrays[k][yy, xx] = vals[k]
    return arrays


def gbuffer_layers(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, shade: bool) -> dict:
    """Run the pixel-centre pass: ``{name: (H, W) numpy array}`` (views of Dr.Jit memory)."""
    if dr.is_jit_v(mi.Float):
        return _pass_jit(scene, sensor, table, shade)
    return _pass_scalar(scene, sensor, table, shade)


def beauty_layers(
    scene: mi.Scene,
    sensor: mi.Sensor,
    integrator: mi.Integrator,
    spp: int,
    seed: int,
    passes: int = 1,
) -> dict[str, np.ndarray]:
    """The nested integrator's image (film filter, ``spp`` or the sampler's count): R, G, B
    (in ``passes`` renders when memory asks for it, :mod:`mi_npr.memory`)."""
    img = render_passes(integrator, scene, sensor, spp, seed, passes)
    a = to_numpy(img)
    if a.ndim != 3 or a.shape[-1] < 3:
        # Mono variants or odd films: replicate the first channel.
        a = a.reshape(a.shape[0], a.shape[1], -1)
        a = np.repeat(a[..., :1], 3, axis=-1)
    return {name: a[..., i] for i, name in enumerate(L.RGB)}


def render_gbuffer(
    scene: mi.Scene,
    sensor: int | mi.Sensor = 0,
    beauty: mi.Integrator | None = None,
    spp: int | None = None,
    seed: int = 0,
    source: str | None = None,
) -> GBuffer:
    """The G-buffer of a loaded scene; ``beauty`` is the integrator for ``R G B`` (or none).

    ``spp`` overrides the sensor's sample count for the beauty image (``None`` keeps it). The
    G-buffer channels are always one exact sample per pixel.
    """
    if spp is not None and (not isinstance(spp, int) or spp < 1):
        raise ParameterError(f"spp = {spp!r}: must be a positive integer")
    sensor = sensor_of(scene, sensor)
    passes = check_render(sensor, beauty, spp, seed)  # table checks, memory (issue 18)
    with _LOCK:
        table = object_table(scene)
        try:
            layers = gbuffer_layers(scene, sensor, table, shade=beauty is None)
            if beauty is not None:
                layers.update(beauty_layers(scene, sensor, beauty, spp or 0, seed, passes))
        except (ParameterError, SceneError):
            raise
        except RuntimeError as e:
            raise SceneError(f"{source or 'scene'}: rendering failed: {one_line(e)}") from None
    ordered = {k: layers[k] for k in L.GBUFFER}
    spp_used = spp if spp is not None else sensor.sampler().sample_count()
    meta = {
        "mi_npr/version": __version__,
        "mi_npr/variant": str(mi.variant()),
        "mi_npr/spp": str(spp_used if beauty is not None else 1),
        "mi_npr/beauty": beauty.class_name() if beauty is not None else "headlight",
    }
    if source:
        meta["mi_npr/scene"] = source
    return GBuffer(ordered, table.names, camera_of(sensor), meta)


def prepare(
    scene: str | os.PathLike[str] | mi.Scene, spp: int | str | None, defines: dict[str, Any]
) -> tuple[mi.Scene, int | None, str | None]:
    """What :func:`render` does before rendering: ``(loaded scene, spp, source path)``.

    ``spp`` may be a string (command line, define); it also fills the XML's ``spp`` default
    when the file declares one.
    """
    source = os.fspath(scene) if isinstance(scene, (str, os.PathLike)) else None
    if isinstance(spp, str):  # from a command line or a define
        try:
            spp = int(spp)
        except ValueError:
            raise ParameterError(f"spp = {spp!r}: must be a positive integer") from None
    if spp is not None and source is not None and "spp" in declared_defaults(source):
        defines["spp"] = spp
    return load_scene(scene, defines), spp, source


def render(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int = 0,
    spp: int | None = None,
    seed: int = 0,
    defines: Mapping[str, Any] | None = None,
    **more: Any,
) -> GBuffer:
    """Render a scene (a loaded ``mi.Scene`` or an XML path) into a :class:`GBuffer`.

    Keyword arguments fill the XML's ``<default>``s, like ``mi.load_file`` (``width=64,
    height=48``); ``defines={"seed": 3}`` reaches the names this function takes itself.
    ``spp`` always sets the beauty's samples per pixel; when the XML declares a ``spp`` default,
    it fills it too (so ``render("scene.xml", spp=4)`` means 4 spp either way).
    When the scene's integrator is one of mi-npr's (``npr_gbuffer``, ``npr_lines``, ...), its
    nested integrator makes the beauty image and its own layers are added; any other integrator
    (``path``, ``direct``, ...) is used as the beauty integrator as it is.

    >>> gb = mi_npr.render("scenes_xml/scene1.xml", width=64, height=48, spp=4)  # doctest: +SKIP
    >>> gb["Z"].shape, gb.objects                                                # doctest: +SKIP
    """
    loaded, spp, source = prepare(scene, spp, merge_defines(defines, more))
    integrator = loaded.integrator()
    if hasattr(integrator, "npr_gbuffer"):
        return integrator.npr_gbuffer(loaded, sensor=sensor, spp=spp, seed=seed, source=source)
    return render_gbuffer(loaded, sensor, integrator, spp, seed, source)
