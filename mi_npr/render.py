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

**Seams.** A ray that meets a mesh exactly on the edge shared by two of its triangles can slip
between them (Embree's and OptiX's intersection tests are not watertight there): it misses, or
hits whatever lies behind, and a whole grid of rays through pixel centres meets such edges
wherever a mesh's diagonal runs through them, so the lines, contours and ids got 1-px specks. The
rule (:func:`grid_channels`, for the pixel-centre pass and the anti-aliased lines' sub-pixel
grid alike): a ray whose 4-neighbours in the grid (those inside it, at least two) all hit one
object ``k`` while it hits another object, or nothing, or ``k`` farther than all of them, is
cast again :data:`~mi_npr.raycast.SEAM_OFFSET` of a grid cell away along the four diagonals;
the first of those rays that hits ``k`` within the neighbours' depth range (widened by their
own spread) replaces it. A real one-cell feature (a hole, a dimple, a thin object) is seen by
the offset rays too and stays as it is.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from . import layers as L
from ._version import __version__
from .camera import projection_of
from .errors import ParameterError
from .gbuffer import GBuffer
from .memory import check_render, render_passes
from .raycast import (
    SEAM_OFFSET,
    Hits,
    cast,
    film_grid,
    film_size,
    pixel_rays,
    posed_rays,
    require_jit,
    transform_frame,
    transforms,
)
from .scene import ObjectTable, merge_defines, sensor_of
from .session import SceneSession, check_spp

__all__ = ["pixel_rays", "render", "render_gbuffer", "render_views"]


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
    frame: tuple[Any, Any] | None = None,
) -> dict[str, Any]:
    """G-buffer channels for ``ray`` (any width): ``{layer name: Float/UInt32}``; ``frame``:
    each lane's camera origin and axis for ``Z`` where the rays are of many views."""
    hits = cast(scene, ray, table, detail="full")
    valid, si = hits.valid, hits.si
    out: dict[str, Any] = {L.Z: hits.depth(sensor, frame)}
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


def grid_channels(
    scene: mi.Scene,
    sensor: mi.Sensor,
    table: ObjectTable,
    shade: bool,
    n: int = 1,
    rows: tuple[int, int] | None = None,
) -> dict[str, Any]:
    """The channels of the rays through the cell centres of an ``n W x n H`` grid over the
    film (``n = 1``: the pixel centres; cell ``j`` is at ``(j + 0.5) / n`` film pixels), row
    major, evaluated, with the seams closed (module docstring). ``rows = (r0, r1)``: the grid's
    rows ``r0 .. r1 - 1`` only (a strip; every cell as in the whole grid, except that the seams
    of the strip's first and last rows are closed against the strip's cells alone)."""
    w, h = film_size(sensor)
    W, H = w * n, h * n
    r0, r1 = (0, H) if rows is None else rows
    x, y = film_grid(W, r1 - r0)
    if r0:
        y = y + float(r0)  # whole numbers plus 0.5: exact in float32, as in the whole grid
    out = channels(scene, sensor, pixel_rays(sensor, x / n, y / n), table, shade)
    dr.eval(*out.values())

    def again(x: Any, y: Any, view: Any) -> dict[str, Any]:
        return channels(scene, sensor, pixel_rays(sensor, x, y), table, shade)

    return _close_seams(again, out, W, r1 - r0, n, row0=r0)


#: ``(x, y, view) -> channels``: the G-buffer channels of the rays through film positions
#: ``(x, y)`` (pixels) of the views ``view`` (lanes of ``UInt32``); how seams are cast again.
Recast = Callable[[Any, Any, Any], dict[str, Any]]


def _close_seams(
    recast: Recast,
    out: dict[str, Any],
    W: int,
    H: int,
    n: int,
    views: int = 1,
    row0: int = 0,
) -> dict[str, Any]:
    """The seam rule (module docstring) on ``views`` grids of ``W x H`` stacked lane-wise
    (view ``v``'s cell ``(x, y)`` is lane ``v W H + y W + x``); a cell's neighbours are those of
    its own view. ``row0``: the grid's first row is row ``row0`` of a larger grid (a strip), so
    cells are cast again at their rows there."""
    ids, z = out[L.OBJECT_ID], out[L.Z]
    i = dr.arange(mi.UInt32, views * W * H)
    view = i // (W * H) if views > 1 else mi.UInt32(0)
    local = i - view * (W * H) if views > 1 else i
    px, py = mi.Int32(local % W), mi.Int32(local // W)
    inside, nid, nz = [], [], []
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        qx, qy = px + dx, py + dy
        ok = (qx >= 0) & (qx < W) & (qy >= 0) & (qy < H)
        q = mi.UInt32(dr.clip(qy, 0, H - 1) * W + dr.clip(qx, 0, W - 1))
        if views > 1:
            q += view * (W * H)
        inside.append(ok)
        nid.append(dr.gather(mi.UInt32, ids, q))
        nz.append(dr.gather(mi.Float, z, q))
    ref = dr.select(inside[0], nid[0], nid[1])  # one neighbour inside the grid (W >= 2)
    ref = dr.select(inside[0] | inside[1], ref, dr.select(inside[2], nid[2], nid[3]))
    agree, count = mi.Bool(True), mi.UInt32(0)
    zmin, zmax = mi.Float(dr.inf), mi.Float(-dr.inf)
    for ok, k, d in zip(inside, nid, nz, strict=True):
        agree &= ~ok | (k == ref)
        count += dr.select(ok, 1, 0)
        zmin = dr.select(ok, dr.minimum(zmin, d), zmin)
        zmax = dr.select(ok, dr.maximum(zmax, d), zmax)
    spread = zmax - zmin + 1e-4 * zmax
    suspect = agree & (count >= 2) & (ref != 0) & ((ids != ref) | (z > zmax + spread))
    m = int(dr.count(suspect)[0])
    if m == 0:
        return out
    idx = dr.compress(suspect)
    sx, sy = mi.Float(dr.gather(mi.Int32, px, idx)), mi.Float(dr.gather(mi.Int32, py, idx))
    if row0:
        sy = sy + float(row0)  # whole numbers: exact in float32
    want = dr.gather(mi.UInt32, ref, idx)
    lo = dr.gather(mi.Float, zmin - spread, idx)
    hi = dr.gather(mi.Float, zmax + spread, idx)
    e = SEAM_OFFSET
    offsets = ((e, e), (-e, e), (e, -e), (-e, -e))
    cx = dr.concat([sx + 0.5 + ox for ox, _ in offsets])
    cy = dr.concat([sy + 0.5 + oy for _, oy in offsets])
    sv = dr.gather(mi.UInt32, view, idx) if views > 1 else mi.UInt32(0)
    again = recast(cx / n, cy / n, dr.concat([sv] * len(offsets)) if views > 1 else sv)
    chosen, found = mi.UInt32(0), mi.Bool(False)
    for k in range(len(offsets)):
        j = dr.arange(mi.UInt32, m) + k * m
        cid = dr.gather(mi.UInt32, again[L.OBJECT_ID], j)
        cz = dr.gather(mi.Float, again[L.Z], j)
        ok = ~found & (cid == want) & (cz >= lo) & (cz <= hi)
        chosen = dr.select(ok, j, chosen)
        found |= ok
    fixed = dict(out)
    for name, v in out.items():
        t = type(v)
        new = t(v)  # a copy: the scatter must not change the caller's arrays
        dr.scatter(new, dr.gather(t, again[name], chosen, found), idx, found)
        fixed[name] = new
    dr.eval(*fixed.values())
    return fixed


def gbuffer_layers(scene: mi.Scene, sensor: mi.Sensor, table: ObjectTable, shade: bool) -> dict:
    """Run the pixel-centre pass: ``{name: (H, W) tensor}`` (Dr.Jit, evaluated, gradients kept
    on AD variants), seams closed (module docstring)."""
    w, h = film_size(sensor)
    out = grid_channels(scene, sensor, table, shade)
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
    before_beauty: Callable[[dict[str, Any]], None] | None = None,
) -> GBuffer:
    """The G-buffer of a loaded scene; ``beauty`` is the integrator for ``R G B`` (or none);
    ``progress``: a progress bar for a long beauty (:func:`beauty_layers`);
    ``before_beauty``: called with the pixel-centre layers (``{name: (H, W) tensor}``) once
    they are rendered, before the beauty (to start work that needs them alone, which runs
    beside the beauty on a thread of its own).

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
        if before_beauty is not None:
            before_beauty(layers)
        if beauty is not None:
            layers.update(
                beauty_layers(session.scene, sensor, beauty, spp or 0, seed, passes, progress)
            )
    return _gbuffer(layers, session, sensor, beauty, spp)


def _gbuffer(
    layers: dict[str, Any],
    session: SceneSession,
    sensor: mi.Sensor,
    beauty: mi.Integrator | None,
    spp: int | None,
) -> GBuffer:
    """The layers of one view in the G-buffer's order, with its camera and metadata."""
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
    return GBuffer(ordered, session.objects.names, projection_of(sensor), meta)


#: Rays per launch that :func:`views_per_launch` allows: a bound on the memory of one launch
#: of :func:`render_views` (its channels, ~50 bytes a ray, and the hits while they are found).
LAUNCH_RAYS = 1 << 19


def views_per_launch(width: int, height: int) -> int:
    """How many views of ``width x height`` pixels one launch of :func:`render_views` takes
    within :data:`LAUNCH_RAYS` rays (at least one)."""
    return max(1, LAUNCH_RAYS // max(1, width * height))


def _pose(sensor: mi.Sensor) -> tuple:
    """What a sensor's rays depend on besides its ``to_world``."""
    p = projection_of(sensor)
    params = mi.traverse(sensor)
    shift = tuple(
        float(np.asarray(params[k]).ravel()[0]) for k in sorted(params.keys()) if "principal" in k
    )
    film = sensor.film()
    crop = (tuple(film.crop_size()), tuple(film.crop_offset()), tuple(film.size()))
    time = (float(sensor.shutter_open()), float(sensor.shutter_open_time()))
    return (p.kind, p.fov, p.near_clip, p.far_clip, p.resolution, shift, crop, time)


def _reference(sensors: Sequence[mi.Sensor]) -> mi.Sensor:
    """The ``perspective`` sensor of ``sensors``' film, fov and clip planes at the identity pose
    (:func:`mi_npr.raycast.posed_rays`); a :class:`ParameterError` unless every sensor is such
    a ``perspective`` sensor, uncropped, without a principal point shift."""
    poses = {_pose(s) for s in sensors}
    kind, fov, near, far, (w, h), shift, (crop, offset, size), time = next(iter(poses))
    if len(poses) > 1 or kind != "perspective" or any(shift) or offset != (0, 0) or crop != size:
        raise ParameterError(
            "render_views: the sensors must be perspective sensors of one film size, field of "
            "view and clip planes, without a crop window or a principal point shift"
        )
    return mi.load_dict(
        {
            "type": "perspective",
            "fov": fov,
            "fov_axis": "x",
            "near_clip": near,
            "far_clip": far,
            "shutter_open": time[0],
            "shutter_close": time[0] + time[1],
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
        }
    )


def render_views(
    scene: mi.Scene | SceneSession,
    sensors: Sequence[mi.Sensor],
    beauty: mi.Integrator | None = None,
    spp: int | None = None,
    seed: int = 0,
) -> list[GBuffer]:
    """The G-buffers of many views of one scene, their channels in one launch: the pixel-centre
    rays of every view (``V x W x H`` lanes, view ``v``'s pixel ``(x, y)`` in lane
    ``v W H + y W + x``) cast together, their seams closed together (each pixel among its own
    view's neighbours), then cut into one :class:`GBuffer` per view.

    ``sensors``: ``perspective`` sensors that differ by their ``to_world`` only (a batch's
    cameras, :func:`mi_npr.camera.sensor_for`); view ``k`` equals
    ``render_gbuffer(scene, sensors[k], beauty, spp, seed)`` layer for layer, bit for bit (the
    rays are the sensor's own, :func:`mi_npr.raycast.posed_rays`). ``beauty`` (an integrator)
    renders each view's ``R G B`` on its own (Mitsuba's film adds a pixel's samples in the order
    its threads take them, so two beauty renders agree to their last bits only); without it,
    the headlight shading of the G-buffer pass, in the same launch. Memory grows with
    ``V x W x H``: callers split long lists (:func:`views_per_launch`).

    >>> s = mi_npr.session.SceneSession.open("scenes_xml/scene1.xml", resolution=(32, 24))
    >>> cams = mi_npr.views.cameras(mi_npr.views.parse_views("orbit:3"), s.scene, s.sensor)
    >>> gbs = render_views(s, [mi_npr.camera.sensor_for(c, s.sensor) for _, c in cams])
    >>> [gb["Z"].shape for gb in gbs]
    [(24, 32), (24, 32), (24, 32)]
    """
    spp = check_spp(spp)
    sensors = list(sensors)
    if not sensors:
        return []
    session = scene if isinstance(scene, SceneSession) else None
    if session is None:
        require_jit()
        session = SceneSession(scene, sensors[0], None, spp)
    passes = check_render(sensors[0], beauty, spp, seed)
    table, shade = session.objects, beauty is None
    if len(sensors) == 1:  # any sensor: the pass of one view
        with session.step("rendering"):
            layers = gbuffer_layers(session.scene, sensors[0], table, shade)
            if beauty is not None:
                layers.update(
                    beauty_layers(session.scene, sensors[0], beauty, spp or 0, seed, passes)
                )
        return [_gbuffer(layers, session, sensors[0], beauty, spp)]
    reference = _reference(sensors)
    w, h = film_size(reference)
    npix, V = w * h, len(sensors)
    M = np.stack(
        [np.asarray(s.world_transform().matrix, np.float32).reshape(4, 4) for s in sensors]
    )
    origin, forward = transform_frame(transforms(M))
    dr.eval(origin, forward)

    def recast(x: Any, y: Any, view: Any) -> dict[str, Any]:
        rays = posed_rays(reference, transforms(M, view), x, y)
        frame = (dr.gather(mi.Point3f, origin, view), dr.gather(mi.Vector3f, forward, view))
        return channels(session.scene, reference, rays, table, shade, frame)

    with session.step("rendering"):
        i = dr.arange(mi.UInt32, V * npix)
        view = i // npix
        pix = i - view * npix
        out = recast(mi.Float(pix % w) + 0.5, mi.Float(pix // w) + 0.5, view)
        dr.eval(*out.values())
        out = _close_seams(recast, out, w, h, 1, V)
        j = dr.arange(mi.UInt32, npix)
        TF, TU = mi.TensorXf, mi.TensorXu
        cut = [
            {
                k: (TU if isinstance(v, mi.UInt32) else TF)(
                    dr.gather(type(v), v, j + k_view * npix), shape=(h, w)
                )
                for k, v in out.items()
            }
            for k_view in range(V)
        ]
        dr.eval(cut)  # one kernel cuts every view
        del out
        for layers, sensor in zip(cut, sensors, strict=True):
            if beauty is not None:
                layers.update(beauty_layers(session.scene, sensor, beauty, spp or 0, seed, passes))
    return [_gbuffer(c, session, s, beauty, spp) for c, s in zip(cut, sensors, strict=True)]


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
