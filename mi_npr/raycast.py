"""Camera rays and what they hit: the one ray-casting path of mi-npr (JIT variants only).

Every stage that turns camera rays into ids casts them here: the G-buffer pass
(:mod:`mi_npr.render`), ray-cast contours (:mod:`mi_npr.contours.refine`), the viewpoint ID
buffers (:mod:`mi_npr.viewpoint.idbuffer`) and the ray trees' primary rays
(:mod:`mi_npr.raytree.render`). So an id seen by one of them is the id every other one sees.

**Rays.** Film positions are in pixels of the sensor's crop window: pixel ``(i, j)`` covers
``[i, i + 1) x [j, j + 1)``, its centre is ``(i + 0.5, j + 0.5)`` and its top-left corner
``(i, j)``. :func:`pixel_rays` asks the sensor for the ray through a film position at the centre
of the lens (aperture sample 0.5) and of the shutter interval: one exact ray, no filter, no
jitter. :func:`film_grid` gives every pixel centre, or every pixel corner (``(W + 1) x (H + 1)``
positions), or the centres of a list of pixels. :func:`pinhole_rays` builds the rays of many
pinhole cameras at once (``V x W x H`` lanes), each oriented like Mitsuba's ``lookat`` (camera
+z forward, +y up, +x left), so a view's rays equal those of a ``perspective`` sensor at that
pose. :func:`posed_rays` gives the rays of many poses of one ``perspective`` sensor bit for bit
(its rays in camera space, moved by each lane's ``to_world`` with the sensor's own operations),
so a G-buffer of many views in one launch equals the G-buffers of the views one by one.

**Hits.** :func:`cast` intersects rays once and returns a :class:`Hits`: the object id (stable,
from :class:`mi_npr.scene.ObjectTable`), the primitive index, the material id, the distance ``t``
and, with ``detail="full"``, the full surface interaction for positions and normals. Ids of other
``id_mode``\\ s (components, primitives) come from :meth:`Hits.ids` with a
:class:`~mi_npr.contours.idmode.IdMap`. Everything stays a Dr.Jit array of the active variant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from .errors import ParameterError


def require_jit(what: str = "mi-npr") -> None:
    """mi-npr runs on Mitsuba's JIT variants (``llvm_*``, ``cuda_*``) only, as Mitsuba's own
    Python integrators do: a one-line error naming the variant otherwise."""
    variant = mi.variant()
    if variant is None or not dr.is_jit_v(mi.Float):
        raise ParameterError(
            f"{what} needs a JIT variant (llvm_ad_rgb, cuda_ad_rgb, ...), not {variant!r}: "
            "call mi_npr.set_variant('llvm_ad_rgb')"
        )


#: How far (in grid cells) the rays that re-cast a seam pixel lie from its centre (the seam rule
#: of :mod:`mi_npr.render`): far from float32's resolution of film positions, far below any
#: feature drawn.
SEAM_OFFSET = 1e-3


def film_size(sensor: mi.Sensor) -> tuple[int, int]:
    """``(width, height)`` of the sensor's crop window."""
    w, h = sensor.film().crop_size()
    return int(w), int(h)


def film_grid(width: int, height: int, corners: bool = False) -> tuple[mi.Float, mi.Float]:
    """Film positions of every pixel centre (``W x H``, row-major, row 0 at the top) or, with
    ``corners``, of every pixel corner (``(W + 1) x (H + 1)``, row-major)."""
    cols = width + 1 if corners else width
    rows = height + 1 if corners else height
    idx = dr.arange(mi.UInt32, cols * rows)
    off = 0.0 if corners else 0.5
    return mi.Float(idx % cols) + off, mi.Float(idx // cols) + off


def pixel_centres(x: np.ndarray | Any, y: np.ndarray | Any) -> tuple[mi.Float, mi.Float]:
    """Film positions of the centres of pixels ``(x, y)`` (integer arrays, numpy or Dr.Jit)."""
    if isinstance(x, np.ndarray):
        x = mi.UInt32(np.ascontiguousarray(x, np.uint32))
        y = mi.UInt32(np.ascontiguousarray(y, np.uint32))
    return mi.Float(x) + 0.5, mi.Float(y) + 0.5


def pixel_rays(sensor: mi.Sensor, x: Any, y: Any) -> mi.Ray3f:
    """Rays through film positions ``(x, y)`` (pixels of the crop window; centres are
    ``i + 0.5``), at the centre of the aperture and of the shutter interval."""
    w, h = film_size(sensor)
    time = sensor.shutter_open() + 0.5 * sensor.shutter_open_time()
    pos = mi.Point2f(mi.Float(x) / float(w), mi.Float(y) / float(h))
    ray, _ = sensor.sample_ray(time, 0.5, pos, mi.Point2f(0.5, 0.5))
    return ray


def camera_frame(sensor: mi.Sensor) -> tuple[mi.Point3f, mi.Vector3f]:
    """Camera origin and unit view axis (+z of the camera frame) in world space."""
    return transform_frame(sensor.world_transform())


def transform_frame(to_world: mi.Transform4f) -> tuple[mi.Point3f, mi.Vector3f]:
    """Origin and unit +z axis of a camera-to-world transform (one per lane where ``to_world``
    holds many)."""
    T = to_world
    return T @ mi.Point3f(0.0, 0.0, 0.0), dr.normalize(T @ mi.Vector3f(0.0, 0.0, 1.0))


def transforms(matrices: np.ndarray, index: Any = None) -> mi.Transform4f:
    """``(V, 4, 4)`` camera-to-world matrices as one ``Transform4f`` of V lanes, or of the lanes
    of ``index`` (``UInt32``: lane ``i`` holds matrix ``index[i]``)."""
    m = np.ascontiguousarray(matrices, np.float32).reshape(-1, 4, 4)
    entries = []
    for i in range(4):
        for j in range(4):
            column = mi.Float(np.ascontiguousarray(m[:, i, j]))
            entries.append(column if index is None else dr.gather(mi.Float, column, index))
    return mi.Transform4f(mi.Matrix4f(*entries))


def posed_rays(reference: mi.Sensor, to_world: mi.Transform4f, x: Any, y: Any) -> mi.Ray3f:
    """The rays of :func:`pixel_rays` through film positions ``(x, y)`` of a ``perspective``
    sensor like ``reference`` (whose ``to_world`` is the identity) standing at ``to_world``
    (one transform per lane): Mitsuba's ``perspective`` ``sample_ray`` after its camera-space
    part, ``d = T d_local``, ``o = T.translation() + d near_clip / d_local.z``, bit for bit.

    The two stages are separate kernels: fused into one, LLVM may contract ``o``'s multiply and
    add into a fused multiply-add, one rounding fewer than the sensor's own rays."""
    local = pixel_rays(reference, x, y)
    d = to_world @ local.d
    near_t = reference.near_clip() * dr.rcp(local.d.z)
    shift = to_world.translation()
    dr.eval(d, near_t, shift)
    ray = mi.Ray3f(local)
    ray.o = mi.Point3f(shift + d * near_t)
    ray.d = d
    dr.eval(ray.o)
    return ray


def _vec3(a: np.ndarray) -> mi.Vector3f:
    a = np.ascontiguousarray(a, np.float32)
    return mi.Vector3f(a[:, 0], a[:, 1], a[:, 2])


def pinhole_rays(
    origin: np.ndarray,
    frame: tuple[np.ndarray, np.ndarray, np.ndarray],
    fov: float,
    size: tuple[int, int],
) -> tuple[mi.Ray3f, mi.UInt32]:
    """The pixel-centre rays of ``V`` pinhole cameras in one array of ``V x W x H`` lanes.

    ``origin`` (V, 3); ``frame`` = ``(forward, left, up)`` unit vectors (V, 3) each (see
    :func:`mi_npr.camera.view_frame`); ``fov`` the horizontal field of view in
    degrees; ``size`` = (width, height). Returns the rays and the view index of every lane.
    Pixel ``(x, y)`` looks along ``f + (1 - 2 (x + 0.5) / W) tan(fov / 2) left +
    (1 - 2 (y + 0.5) / H) tan(fov / 2) H / W up``: Mitsuba's ``perspective`` sensor at that pose.
    """
    w, h = size
    tx = math.tan(math.radians(fov) / 2.0)
    ty = tx * h / w
    npix = w * h
    idx = dr.arange(mi.UInt32, len(origin) * npix)
    view = idx // npix
    pix = idx - view * npix
    x = mi.Float(pix % w) + 0.5
    y = mi.Float(pix // w) + 0.5
    f, left, up = (dr.gather(mi.Vector3f, _vec3(a), view) for a in frame)
    o = dr.gather(mi.Point3f, mi.Point3f(_vec3(origin)), view)
    d = dr.normalize(left * ((1.0 - 2.0 * x / w) * tx) + up * ((1.0 - 2.0 * y / h) * ty) + f)
    return mi.Ray3f(o, d), view


@dataclass
class Hits:
    """What :func:`cast` found along each ray (Dr.Jit arrays of the rays' width)."""

    valid: mi.Bool
    object_id: mi.UInt32  # 0 = nothing hit (the object table's ids)
    prim_id: mi.UInt32  # primitive index within the shape; 0 on a miss
    t: mi.Float  # distance along the ray; +inf on a miss
    si: Any  # SurfaceInteraction3f, or PreliminaryIntersection3f with detail="ids"
    table: Any  # the ObjectTable the ids come from

    @property
    def material_id(self) -> mi.UInt32:
        """Material id (0 = nothing hit): the object table's BSDF numbering."""
        return self.table.material_of(self.object_id)

    def ids(self, id_map: Any) -> mi.UInt32:
        """Ids of an ``id_mode`` (:class:`~mi_npr.contours.idmode.IdMap`)."""
        return id_map.lookup(self.si)

    def depth(self, sensor: mi.Sensor, frame: tuple[Any, Any] | None = None) -> mi.Float:
        """Camera-space depth along the sensor's view axis (+inf on a miss); ``frame``: each
        lane's own camera origin and axis instead (rays of many views)."""
        o, f = camera_frame(sensor) if frame is None else frame
        return dr.select(self.valid, dr.dot(self.si.p - o, f), dr.inf)


#: How much :func:`cast` computes per hit: the preliminary intersection only (enough for object
#: ids and primitive indices of plain shapes), a minimal surface interaction (the shape and
#: primitive *inside* an instance, resolved like the full one), or everything (positions,
#: shading frames, BSDFs).
DETAILS = ("ids", "minimal", "full")


def cast(
    scene: mi.Scene,
    rays: mi.Ray3f,
    table: Any,
    *,
    detail: str = "ids",
    coherent: bool = True,
) -> Hits:
    """Intersect ``rays`` with ``scene`` once; object ids through ``table`` (an
    :class:`~mi_npr.scene.ObjectTable`); ``detail`` is one of :data:`DETAILS`."""
    if detail == "ids":
        si = scene.ray_intersect_preliminary(rays, coherent=coherent)
    elif detail in ("minimal", "full"):
        flags = mi.RayFlags.All if detail == "full" else mi.RayFlags.Minimal
        si = scene.ray_intersect(rays, ray_flags=flags, coherent=coherent)
    else:
        raise ParameterError(f"detail = {detail!r}: expected one of {', '.join(DETAILS)}")
    valid = si.is_valid()
    oid = table.lookup(si)
    prim = dr.select(valid, si.prim_index, 0)
    t = dr.select(valid, si.t, dr.inf)
    return Hits(valid, oid, prim, t, si, table)
