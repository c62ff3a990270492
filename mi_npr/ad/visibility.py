"""Differentiable lines with visibility gradients: silhouettes and occlusion boundaries that move.

The G-buffer pass (:mod:`mi_npr.render`) casts one ray through each pixel centre: its ids and
depths jump where visibility changes, and automatic differentiation sees no motion of a
silhouette at all. :func:`soft_lines` is the line image for optimisation instead: an
anti-aliased (prefiltered, multi-sample) image whose derivatives include the motion of every
discontinuity it sees.

**Samples.** An ``n x n`` grid of rays per pixel (sub-pixel spacing ``h = 1 / n``), over the
image and a margin of ``ceil(3 sigma)`` pixels (so no pixel's filter is cut by the frame). Each
sample ``s`` carries a feature vector ``f_s``: a pseudo-random unit vector in R^4 per object id
(0 for the background, the *id* feature), ``w_d * depth_scale / z`` (inverse depth; 0 for the
background) and ``w_n * n`` (the shading normal; 0 for the background).

**Prefiltered features.** ``F(x) = sum_s omega(x - p_s) f_s``, ``omega`` a Gaussian of standard
deviation ``sigma`` pixels normalised over the sample grid, and likewise ``F2(x)`` of ``|f_s|^2``.

**Lines.** The local variance ``V = F2 - |F|^2`` is 0 where the features are constant and
``a (1 - a) |f_1 - f_2|^2`` across a step between two features covering ``a`` and ``1 - a`` of
the filter; ink ``= 1 - exp(-V / kappa)``. So silhouettes and ID edges (the id feature),
occlusion boundaries within an object (the depth feature) and creases (the normal feature)
are drawn as bands about ``2 sigma`` wide, each by the same rule.

**Gradients.** Two terms:

- *interior*: each sample's ray is built from the (differentiable) camera and intersected with
  the (differentiable) scene, so ``z`` and ``n`` carry the derivatives of smooth motion;
- *boundary* (Reynolds transport, discretised on the sample grid as in edge sampling): where two
  neighbouring samples ``a``, ``b`` differ by a discontinuity (other ids, an inverse-depth step
  above ``0.05 w_d``, or normals more than 30 degrees apart), the step lies between them and
  moves with the *front* sample's surface (the nearer; at a silhouette the material point on the
  contour moves, to first order, as the outline does along its normal). Its image velocity
  ``u = d pi(P) / d theta`` (``P`` the front hit's material point, Mitsuba's
  ``RayFlags.FollowShape``, ``pi`` the differentiable projection) adds
  ``sum_links omega(m) (f_front - f_back) (u . e) / h`` to ``F`` (``m`` the link's midpoint,
  taken as half at each end, exact to ``O(h^2)``; ``e`` the unit step from front to back); the
  staircase of links measures ``integral (u . n) dl`` exactly for a uniform ``u``. The term is
  zero in the primal pass and differentiates to the flux of the moving boundary, which is what
  Mitsuba's reparameterized primary rays (``prb_reparam``, not in Mitsuba 3.9) give a film.

Not covered: topology changes (a line born or vanishing at a cusp or a T-junction, a feature
thinner than ``h``), the image-frame boundary beyond the margin, and the ``O(h)`` error of the
staircase and of taking the sample's velocity for the contour's. The primal image is exact to
the sample grid: a moving silhouette steps in ``h`` increments, so finite differences need a
step of several ``h``.

Cameras: a :class:`Pinhole` (origin, forward, left, up, horizontal fov; each may hold
gradients), built from a ``lookat`` (:meth:`Pinhole.look_at`) or a perspective sensor's
``to_world`` and ``x_fov`` (:meth:`Pinhole.of_sensor`, gradients of ``params['cam.to_world']``
included).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..raycast import film_size, require_jit
from ..scene import object_table

#: Dimension of the per-object id feature.
ID_DIMS = 4
#: Cosine of the normal angle above which two neighbouring samples are on two sides of a crease.
CREASE_COS = math.cos(math.radians(30.0))


@dataclass
class Pinhole:
    """A perspective camera in Dr.Jit values (gradients allowed): ``origin``; unit ``forward``,
    ``left`` and ``up`` (Mitsuba's camera frame: +z forward, +x left, +y up); ``fov`` the
    horizontal field of view in degrees. Pixel ``(x, y)`` of a ``W x H`` image (``x`` in
    ``[0, W]``) looks along ``forward + (1 - 2 x / W) tan(fov / 2) left + (1 - 2 y / H)
    tan(fov / 2) H / W up``, as :func:`mi_npr.raycast.pinhole_rays` and Mitsuba's
    ``perspective`` sensor."""

    origin: Any
    forward: Any
    left: Any
    up: Any
    fov: Any

    @classmethod
    def look_at(cls, origin: Any, target: Any, up: Any, fov: Any) -> Pinhole:
        """The camera of ``lookat(origin, target, up)`` (Mitsuba's frame construction)."""
        o = mi.Point3f(origin)
        f = dr.normalize(mi.Vector3f(target) - o)
        left = dr.normalize(dr.cross(mi.Vector3f(up), f))
        return cls(o, f, left, dr.cross(f, left), mi.Float(fov))

    @classmethod
    def of_sensor(cls, sensor: mi.Sensor) -> Pinhole:
        """The camera of a ``perspective`` sensor (``fov_axis="x"``), with the gradients its
        ``to_world`` holds after ``params.update()``."""
        if sensor.class_name() != "PerspectiveCamera":
            raise ParameterError(
                f"the sensor is a {sensor.class_name()}: differentiable lines need a "
                "perspective sensor"
            )
        T = sensor.world_transform()
        fov = float(np.asarray(mi.traverse(sensor)["x_fov"]).ravel()[0])
        return cls(
            T @ mi.Point3f(0.0, 0.0, 0.0),
            dr.normalize(T @ mi.Vector3f(0.0, 0.0, 1.0)),
            dr.normalize(T @ mi.Vector3f(1.0, 0.0, 0.0)),
            dr.normalize(T @ mi.Vector3f(0.0, 1.0, 0.0)),
            mi.Float(fov),
        )

    def _tan(self, size: tuple[int, int]) -> tuple[Any, Any]:
        tx = dr.tan(mi.Float(self.fov) * (math.pi / 360.0))
        return tx, tx * (size[1] / size[0])

    def rays(self, x: Any, y: Any, size: tuple[int, int]) -> mi.Ray3f:
        """Rays through image positions ``(x, y)`` (pixels) of a ``size = (W, H)`` image."""
        tx, ty = self._tan(size)
        w, h = size
        d = (
            self.forward
            + self.left * ((1.0 - 2.0 * x / w) * tx)
            + self.up * ((1.0 - 2.0 * y / h) * ty)
        )
        return mi.Ray3f(self.origin, dr.normalize(d))

    def project(self, p: Any, size: tuple[int, int]) -> tuple[Any, Any]:
        """Image positions (pixels) of world points ``p``: the inverse of :meth:`rays`."""
        tx, ty = self._tan(size)
        w, h = size
        q = p - self.origin
        z = dr.dot(q, self.forward)
        x = 0.5 * w * (1.0 - dr.dot(q, self.left) / (z * tx))
        y = 0.5 * h * (1.0 - dr.dot(q, self.up) / (z * ty))
        return x, y


def _id_features(oid: Any) -> list[Any]:
    """A fixed pseudo-random unit vector per object id (a hash of it), 0 for the background."""
    rng = mi.PCG32(initstate=mi.UInt64(oid) * 0x9E3779B97F4A7C15 + 7)
    v = [rng.next_float32() - 0.5 for _ in range(ID_DIMS)]
    norm = dr.sqrt(sum(c * c for c in v))
    return [dr.select(oid > 0, c / norm, 0.0) for c in v]


def _taps(n: int, R: int, sigma: float) -> list[tuple[int, float]]:
    """Offsets ``k`` (sub-samples from a pixel's first one) and the filter's 1-D weights there,
    normalised to sum 1."""
    ks = range(-n * R, n + n * R)
    g = [math.exp(-0.5 * (((k + 0.5) / n - 0.5) / sigma) ** 2) for k in ks]
    return [(k, v / sum(g)) for k, v in zip(ks, g, strict=True)]


def _separable(
    v: Any,
    rows: int,
    cols: int,
    tx: list[tuple[int, float]],
    ty: list[tuple[int, float]],
    n: int,
    R: int,
    size: tuple[int, int],
) -> Any:
    """``sum_{kx, ky} wx wy v[(j + R) n + ky, (i + R) n + kx]`` for every pixel ``(i, j)``."""
    w, h = size
    idx = dr.arange(mi.Int32, rows * w)
    r, i = idx // w, idx % w
    acc = mi.Float(0.0)
    for k, wt in tx:
        acc += wt * dr.gather(mi.Float, v, mi.UInt32(r * cols + (i + R) * n + k))
    dr.eval(acc)
    idx = dr.arange(mi.Int32, h * w)
    j, i = idx // w, idx % w
    out = mi.Float(0.0)
    for k, wt in ty:
        out += wt * dr.gather(mi.Float, acc, mi.UInt32(((j + R) * n + k) * w + i))
    return out


def _check(name: str, value: Any, ok: bool, rule: str) -> None:
    if not ok:
        raise ParameterError(f"{name} = {value!r}: {rule}")


def soft_lines(
    scene: mi.Scene,
    camera: Pinhole | mi.Sensor | None = None,
    size: tuple[int, int] | None = None,
    *,
    n: int = 4,
    sigma: float = 0.5,
    kappa: float = 0.1,
    depth_weight: float = 1.0,
    normal_weight: float = 0.5,
    depth_scale: float | None = None,
) -> mi.TensorXf:
    """The differentiable line image (H, W) of ``scene`` seen by ``camera`` (a :class:`Pinhole`,
    a perspective sensor, or ``None``: the scene's first sensor) at ``size = (W, H)`` (the
    sensor's film by default); module docstring for the definition and the gradient terms.

    ``n`` samples per pixel along each axis, ``sigma`` the filter's standard deviation (pixels),
    ``kappa`` the variance of full ink, ``depth_weight`` / ``normal_weight`` the weights of the
    depth and normal features against the id feature, ``depth_scale`` the length that makes
    depths unitless (the scene's bounding-box diagonal by default; keep it fixed while a
    parameter that moves the box is optimised)."""
    require_jit("soft_lines")
    sensor = scene.sensors()[0] if camera is None and scene.sensors() else None
    if isinstance(camera, mi.Sensor):
        sensor = camera
    if size is None:
        if sensor is None:
            raise ParameterError("soft_lines: give size=(W, H) for a camera without a sensor")
        size = film_size(sensor)
    cam = camera if isinstance(camera, Pinhole) else Pinhole.of_sensor(sensor)
    _check("n", n, isinstance(n, int) and 1 <= n <= 16, "expected an integer in [1, 16]")
    for name, v in (("sigma", sigma), ("kappa", kappa)):
        _check(name, v, isinstance(v, (int, float)) and 0 < v < math.inf, "must be > 0")
    if depth_scale is None:
        bb = scene.bbox()
        depth_scale = float(dr.norm(bb.max - bb.min)) if bb.valid() else 1.0
    w, h = (int(v) for v in size)
    R = max(1, math.ceil(3.0 * sigma))
    cols, rows = (w + 2 * R) * n, (h + 2 * R) * n
    idx = dr.arange(mi.UInt32, rows * cols)
    x = (mi.Float(idx % cols) + 0.5) / n - R
    y = (mi.Float(idx // cols) + 0.5) / n - R
    ray = cam.rays(x, y, (w, h))
    pi = scene.ray_intersect_preliminary(dr.detach(ray), coherent=True)
    valid = pi.is_valid()
    si = pi.compute_surface_interaction(ray, mi.RayFlags.All, valid)  # interior: attached ray
    oid = object_table(scene).lookup(pi)
    # Misses get a finite stand-in point, or their zero gradients would meet infinities.
    p = dr.select(valid, si.p, cam.origin + cam.forward)
    z = dr.select(valid, dr.dot(p - cam.origin, cam.forward), dr.inf)
    nrm = si.sh_frame.n
    # Weighted by cos^2 of the view angle: the normal turns infinitely fast at a smooth
    # silhouette, cos^2 n does not, so the samples' interior derivatives stay bounded there.
    cos = dr.dot(nrm, ray.d)
    nrm_w = nrm * (cos * cos)
    feats = _id_features(oid)
    feats.append(dr.select(valid, depth_weight * depth_scale / dr.select(valid, z, 1.0), 0.0))
    feats += [dr.select(valid, normal_weight * nrm_w[i], 0.0) for i in range(3)]
    feats.append(sum(f * f for f in feats))  # |f|^2, filtered into F2

    # The boundary term: the image velocity of the front sample's material point.
    moving = pi.compute_surface_interaction(
        dr.detach(ray), mi.RayFlags.All | mi.RayFlags.FollowShape, valid
    )
    px, py = cam.project(dr.select(valid, moving.p, cam.origin + cam.forward), (w, h))
    ux, uy = px - dr.detach(px), py - dr.detach(py)  # 0, with the velocity as derivative
    fd = [dr.detach(f) for f in feats]
    dr.eval(feats, ux, uy, oid, valid)  # smaller kernels compile much faster than one
    zd, nd = dr.detach(z), dr.detach(nrm)
    jump_d = 0.05 * depth_weight

    col, row = mi.Int32(idx % cols), mi.Int32(idx // cols)
    flux = [mi.Float(0.0) for _ in fd]
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):  # the link from each sample to a neighbour
        inside = (col + dx >= 0) & (col + dx < cols) & (row + dy >= 0) & (row + dy < rows)
        b = mi.UInt32(dr.clip(row + dy, 0, rows - 1) * cols + dr.clip(col + dx, 0, cols - 1))
        gb = lambda v, t=mi.Float, b=b: dr.gather(t, v, b)  # noqa: E731
        vb = gb(valid, mi.Bool)
        step = oid != gb(oid, mi.UInt32)
        step |= dr.abs(fd[ID_DIMS] - gb(fd[ID_DIMS])) > jump_d
        step |= valid & vb & (sum(nd[i] * gb(nd[i]) for i in range(3)) < CREASE_COS)
        front = zd <= gb(zd)
        ue = (ux if dx else uy) * (dx + dy)  # u . e for e the unit step from here to there
        u = dr.select(front, ue, -gb(ue))
        # Half of the link's flux at each end: the filter at the midpoint, to O(h^2).
        k = dr.select(inside & step & (valid | vb), 0.5 * n * u, 0.0)
        for c, f in enumerate(fd):
            flux[c] += dr.select(front, f - gb(f), gb(f) - f) * k
    dr.eval(flux)
    ts = _taps(n, R, sigma)
    F = [
        _separable(f + q, rows, cols, ts, ts, n, R, (w, h))
        for f, q in zip(feats, flux, strict=True)
    ]
    var = dr.maximum(F[-1] - sum(f * f for f in F[:-1]), 0.0)
    return mi.TensorXf(1.0 - dr.exp(-var / kappa), shape=(h, w))
