"""The G-buffer pass: one ray through the exact centre of every pixel, never filtered.

Mitsuba's film averages every AOV through its reconstruction filter (mitsuba3 #396, #575), which
blends integer ids across edges. So the G-buffer bypasses the film: the pixel-centre rays of
:mod:`mi_npr.raycast` (``((x + 0.5) / W, (y + 0.5) / H)`` of the crop window, centre of the lens
and of the shutter interval) are intersected once and each channel is evaluated as its own planar
array. The beauty image is the nested integrator's own ``render`` at the film's filter and spp,
so the two never mix; a long beauty (a 1-spp probe estimates it) can run in passes under a
progress bar (:func:`beauty_layers`, ``progress=True`` on a terminal).

Per pixel (see :mod:`mi_npr.layers`): ``Z`` camera-space depth along the view axis (+inf on a
miss), ``P`` world position, ``N`` shading normal, ``object_id``, ``prim_id``, and ``R G B``.
JIT variants only (:func:`mi_npr.raycast.require_jit`).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Mapping
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from . import layers as L
from ._version import __version__
from .camera import projection_of
from .gbuffer import GBuffer
from .memory import check_render, render_passes
from .raycast import Hits, cast, film_grid, film_size, pixel_rays, require_jit
from .scene import ObjectTable, merge_defines, sensor_of
from .session import SceneSession, check_spp

__all__ = ["pixel_rays", "render", "render_gbuffer"]


def _headlight(si: mi.SurfaceInteraction3f, ray: mi.Ray3f, valid: Any) -> Any:
    """Cheap preview shading when no beauty integrator is nested: albedo x headlight cosine."""
    bsdf = si.bsdf(ray)
    albedo = mi.Color3f(0.6)
    if mi.is_rgb:
        refl = bsdf.eval_diffuse_reflectance(si, valid)
        albedo = dr.select(dr.max(refl) > 0.0, mi.Color3f(refl), albedo)
    cos = dr.abs(dr.dot(si.sh_frame.n, ray.d))
    return dr.select(valid, albedo * (0.2 + 0.8 * cos), mi.Color3f(0.0))


def _bsdf_normals(hits: Hits, table: ObjectTable, n: Any) -> Any:
    """Shading normals that BSDFs define themselves: a BSDF with a method
    ``npr_shading_normal(si, active) -> world-space unit normal`` (such as ``npr_foliage``'s mixed
    leaf/HLP normal) replaces ``n`` on the pixels of the shapes that use it, so the ``N`` layer
    holds the normal the BSDF shades with. One masked call per such shape (few in a scene)."""
    for oid, shape in table.shapes.items():
        fn = getattr(shape.bsdf(), "npr_shading_normal", None)
        if fn is not None:
            mask = hits.valid & (hits.object_id == oid)
            n = dr.select(mask, fn(hits.si, mask), n)
    return n


def channels(
    scene: mi.Scene,
    sensor: mi.Sensor,
    ray: mi.Ray3f,
    table: ObjectTable,
    shade: bool,
) -> dict[str, Any]:
    """G-buffer channels for ``ray`` (any width): ``{layer name: Float/UInt32}``."""
    hits = cast(scene, ray, table, detail="full")
    valid, si = hits.valid, hits.si
    out: dict[str, Any] = {L.Z: hits.depth(sensor)}
    for i, name in enumerate(L.P):
        out[name] = dr.select(valid, si.p[i], 0.0)
    n = _bsdf_normals(hits, table, si.sh_frame.n)
    for i, name in enumerate(L.N):
        out[name] = dr.select(valid, n[i], 0.0)
    out[L.OBJECT_ID] = hits.object_id
    out[L.PRIM_ID] = hits.prim_id
    if shade:
        rgb = _headlight(si, ray, valid)
        for i, name in enumerate(L.RGB):
            out[name] = rgb[i]
    return out


def gbuffer_layers(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, shade: bool) -> dict:
    """Run the pixel-centre pass: ``{name: (H, W) tensor}`` (Dr.Jit, evaluated, gradients kept
    on AD variants)."""
    w, h = film_size(sensor)
    out = channels(scene, sensor, pixel_rays(sensor, *film_grid(w, h)), table, shade)
    dr.eval(*out.values())
    TF, TU = mi.TensorXf, mi.TensorXu
    return {k: (TU if isinstance(v, mi.UInt32) else TF)(v, shape=(h, w)) for k, v in out.items()}


#: A beauty render estimated longer than this (seconds) is rendered in passes with a progress bar.
PROGRESS_AFTER = 2.0
#: Seconds per pass of a beauty rendered in passes (the bar's update rate).
PASS_SECONDS = 0.5


def _render_in_passes(
    scene: mi.Scene,
    sensor: mi.Sensor,
    integrator: mi.Integrator,
    spp: int,
    seed: int,
    passes: int = 1,
) -> Any:
    """The beauty of ``spp`` samples, with a progress bar on stderr when it is long.

    A 1-spp probe estimates the time of the whole render; under :data:`PROGRESS_AFTER` seconds
    the beauty is rendered as without progress (in the ``passes`` memory asks for). Longer
    renders keep the probe as their first sample and run the other ``spp - 1`` as passes of
    ~:data:`PASS_SECONDS` (at least ``passes``) through :func:`mi_npr.memory.render_passes`:
    each with its own seed, averaged weighted by their spp, the same estimator as one render of
    ``spp`` samples with other random numbers."""

    t0 = time.perf_counter()
    probe = integrator.render(scene, sensor, seed=seed, spp=1, develop=True, evaluate=True)
    dr.eval(probe)
    dr.sync_thread()
    estimate = (time.perf_counter() - t0) * spp
    if estimate < PROGRESS_AFTER:
        return render_passes(integrator, scene, sensor, spp, seed, passes)

    passes = max(passes, min(spp - 1, max(2, int(estimate / PASS_SECONDS))))
    with tqdm(total=spp, desc="beauty", unit="spp", leave=False) as bar:
        bar.update(1)
        return render_passes(
            integrator, scene, sensor, spp, seed, passes, on_pass=bar.update, first=(probe, 1)
        )


def beauty_layers(
    scene: mi.Scene,
    sensor: mi.Sensor,
    integrator: mi.Integrator,
    spp: int,
    seed: int,
    passes: int = 1,
    progress: bool = False,
) -> dict[str, Any]:
    """The nested integrator's image (film filter, ``spp`` or the sampler's count): R, G, B as
    (H, W) tensors, then every channel the integrator writes besides (its ``aov_names()``: the
    ``aov`` integrator's ``nn.X``..., the ``stokes`` integrator's ``S0.R``...) under its own
    name (:func:`scene_channel`). In ``passes`` renders when memory asks for it
    (:mod:`mi_npr.memory`); with ``progress`` (and stderr a terminal), a long render shows a bar
    with its ETA (:func:`_render_in_passes`)."""

    total = spp or sensor.sampler().sample_count()
    if progress and total >= 4 and sys.stderr.isatty():
        img = _render_in_passes(scene, sensor, integrator, total, seed, passes)
    else:
        img = render_passes(integrator, scene, sensor, spp, seed, passes)
    h, w = (int(v) for v in img.shape[:2])
    c = int(img.shape[2]) if img.ndim == 3 else 1
    flat = img.array
    idx = dr.arange(mi.UInt32, h * w) * c
    aovs = list(integrator.aov_names())
    base = c - len(aovs)  # the film's own channels (RGB, RGBA, Y, YA), then the AOVs
    if base not in (1, 2, 3, 4):  # an image of another layout (Mitsuba's aov integrator)
        return _film_channels(sensor.film())
    # Mono variants or odd films (fewer than 3 channels): the first channel three times.
    pick = [min(i, base - 1) if base >= 3 else 0 for i in range(3)]
    out = {
        name: mi.TensorXf(dr.gather(mi.Float, flat, idx + k), shape=(h, w))
        for name, k in zip(L.RGB, pick, strict=True)
    }
    for k, name in enumerate(aovs):
        out[scene_channel(name)] = mi.TensorXf(dr.gather(mi.Float, flat, idx + base + k), (h, w))
    return out


def _film_channels(film: mi.Film) -> dict[str, Any]:
    """R, G, B and every other channel of ``film`` after a render, by the names the film gives
    them: for integrators whose image does not list the film's channels then their AOVs in
    order (the ``aov`` integrator leaves its nested image's ``image.R``... out of it)."""
    bitmap = film.bitmap(raw=False)
    names = [f.name for f in bitmap.struct_()]
    data = np.asarray(bitmap, dtype=np.float32)
    data = data.reshape(*data.shape[:2], -1)
    rgb = [names.index(n) if n in names else 0 for n in L.RGB]
    out = {
        n: mi.TensorXf(np.ascontiguousarray(data[..., k])) for n, k in zip(L.RGB, rgb, strict=True)
    }
    for k, name in enumerate(names):
        if name not in L.RGB and name not in ("A", "W"):
            out[scene_channel(name)] = mi.TensorXf(np.ascontiguousarray(data[..., k]))
    return out


def scene_channel(name: str) -> str:
    """The layer of a channel the scene's own integrator writes: its own name (``nn.X``,
    ``S0.R``), or ``scene.<name>`` where that is a layer of mi-npr's (``Z``, ``N.X``...)."""
    return f"scene.{name}" if L.spec(name) is not None or name in L.RGB else name


def render_gbuffer(
    scene: mi.Scene | SceneSession,
    sensor: int | mi.Sensor = 0,
    beauty: mi.Integrator | None = None,
    spp: int | None = None,
    seed: int = 0,
    source: str | None = None,
    progress: bool = False,
) -> GBuffer:
    """The G-buffer of a loaded scene; ``beauty`` is the integrator for ``R G B`` (or none);
    ``progress``: a progress bar for a long beauty (:func:`beauty_layers`).

    ``spp`` overrides the sensor's sample count for the beauty image (``None`` keeps it). The
    G-buffer channels are always one exact sample per pixel.
    """
    spp = check_spp(spp)
    if isinstance(scene, SceneSession):
        session = scene
    else:
        require_jit()
        session = SceneSession(scene, sensor_of(scene, sensor), source, spp)
    sensor = session.sensor
    passes = check_render(sensor, beauty, spp, seed)  # the seed's table check, then memory
    with session.step("rendering"):
        table = session.objects
        layers = gbuffer_layers(session.scene, sensor, table, shade=beauty is None)
        if beauty is not None:
            layers.update(
                beauty_layers(session.scene, sensor, beauty, spp or 0, seed, passes, progress)
            )
    ordered = {k: layers[k] for k in L.GBUFFER}
    ordered.update({k: v for k, v in layers.items() if k not in ordered})  # the scene's AOVs
    spp_used = spp if spp is not None else sensor.sampler().sample_count()
    meta = {
        "mi_npr/version": __version__,
        "mi_npr/variant": str(mi.variant()),
        "mi_npr/spp": str(spp_used if beauty is not None else 1),
        "mi_npr/beauty": beauty.class_name() if beauty is not None else "headlight",
    }
    if session.source:
        meta["mi_npr/scene"] = session.source
    return GBuffer(ordered, table.names, projection_of(sensor), meta)


def render(
    scene: str | os.PathLike[str] | mi.Scene,
    *,
    sensor: int = 0,
    spp: int | str | None = None,
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

    >>> gb = mi_npr.render("scenes_xml/scene1.xml", width=32, height=24, spp=1)
    >>> gb["Z"].shape, gb.objects  # doctest: +NORMALIZE_WHITESPACE
    ((24, 32), {1: 'back_wall', 2: 'floor', 3: 'sphere_left', 4: 'sphere_middle',
                5: 'sphere_right'})
    """
    session = SceneSession.open(scene, sensor=sensor, spp=spp, defines=merge_defines(defines, more))
    integrator = session.scene.integrator()
    if hasattr(integrator, "npr_gbuffer"):
        return integrator.npr_gbuffer(session, spp=session.spp, seed=seed)
    return render_gbuffer(session, beauty=integrator, spp=session.spp, seed=seed)
