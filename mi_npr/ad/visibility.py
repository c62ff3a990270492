"""Differentiable lines with visibility gradients: silhouettes and occlusion boundaries that move.

The G-buffer pass (:mod:`mi_npr.render`) casts one ray through each pixel centre: its ids and
depths jump where visibility changes, and automatic differentiation sees no motion of a
silhouette at all. :func:`soft_lines` is the line image for optimisation instead: an
anti-aliased (prefiltered, multi-sample) image whose derivatives include the motion of every
discontinuity it sees.

**Samples.** An ``n x n`` grid of rays per pixel (sub-pixel spacing ``h = 1 / n``), over the
image and a margin of ``ceil(3 sigma)`` pixels (so no pixel's filter is cut by the frame). Each
sample ``s`` carries a feature vector ``f_s``: a pseudo-random unit vector in R^4 per object id
(0 for the background, the *id* feature), ``w_d (1/2 + c^2 depth_scale / z)`` (the *depth*
feature; 0 for the background) and ``w_n c^2 n`` (the *normal* feature; 0 for the background),
with ``n`` the shading normal and ``c = n . d`` the cosine of the view angle (``d`` the ray).

Why ``c^2``: the boundary term below takes the nearest sample's feature for the feature's
one-sided limit at a step, and the interior term sums each sample's ``df/dtheta`` over the
grid; both are ``O(h)`` accurate for a feature that is Lipschitz in image position up to the
step. At a smooth contour neither ``n`` nor ``1 / z`` is: the depth grows as the square root
of the distance ``r`` to the outline (``d(1/z)/dtheta`` as ``r^(-1/2)``). With the plain
inverse depth the sample in front of a silhouette is nearer than the contour, so its jump
would be overestimated by ``O(h^(1/2))`` on every link, always in the same direction (about 10%
of d(loss)/d(translation) for a unit sphere 5 units away at ``n = 8``), and the interior sum
would have an error of the same order that depends on where the grid falls on the outline.
``c^2`` vanishes linearly in ``r`` there, so ``c^2 / z`` and ``c^2 n`` are Lipschitz, tend to 0
at the contour, and their ``theta``-derivatives stay bounded. The constant ``1/2`` keeps a step
at silhouettes against the background (where ``c^2 / z`` is 0 on both sides of a smooth
outline); between two surfaces it cancels.

**Prefiltered features.** ``F(x) = sum_s omega(x - p_s) f_s``, ``omega`` a Gaussian of standard
deviation ``sigma`` pixels normalised over the sample grid, and likewise ``F2(x)`` of ``|f_s|^2``.

**Lines.** The local variance ``V = F2 - |F|^2`` is 0 where the features are constant and
``a (1 - a) |f_1 - f_2|^2`` across a step between two features covering ``a`` and ``1 - a`` of
the filter; ink ``= 1 - exp(-V / kappa)``. So silhouettes and ID edges (the id feature),
occlusion boundaries within an object (the depth feature) and creases (the normal feature)
are drawn as bands about ``2 sigma`` wide, each by the same rule. Both geometric features
fade towards grazing: an occlusion boundary's depth step is ``w_d depth_scale |c_f^2 / z_f -
c_b^2 / z_b|`` (front, back), so it is weaker between surfaces seen obliquely, and behind a
smooth contour it is the back surface's ``c^2 / z`` alone.

**Gradients.** Two terms:

- *interior*: each sample's ray is built from the (differentiable) camera and intersected with
  the (differentiable) scene, so ``z`` and ``n`` carry the derivatives of smooth motion;
- *boundary* (Reynolds transport, discretised on the sample grid as in edge sampling): where two
  neighbouring samples ``a``, ``b`` differ by a discontinuity (other ids, a depth-feature step
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
  The jump ``f_front - f_back`` is that of every feature (and of ``|f|^2``), the depth and
  normal features included; with the ``c^2`` weighting the front sample's value is within
  ``O(h)`` of the limit at the step.

Not covered: topology changes (a line born or vanishing at a cusp or a T-junction, a feature
thinner than ``h``), the image-frame boundary beyond the margin, and the discretisation error
of the staircase and of taking the front sample's velocity for the contour's (``O(h)`` in the
tests: 1-2% at ``n = 8``, halving with ``h``). The primal image is exact to the sample grid:
a moving silhouette steps in ``h`` increments, so finite differences need a step of several
``h``.

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

from ..errors import ParameterError, shown
from ..params import MAX_RES
from ..raycast import film_size, require_jit
from ..scene import object_table

Taps = list[tuple[int, float]]

#: Dimension of the per-object id feature.
ID_DIMS = 4
#: The depth feature's constant on every hit (in units of ``depth_weight``): the step a silhouette
#: against the background keeps in it where ``cos^2 / z`` vanishes at a smooth contour.
COVERAGE = 0.5
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

    def spread(self, width: int) -> Pinhole:
        """This camera with every value broadcast to ``width`` lanes (the sample grid), for the
        gradients of the camera's scalars to be summed over the grid in one pass
        (:class:`_Spread`)."""
        parts = [mi.Vector3f(v) for v in (self.origin, self.forward, self.left, self.up)]
        comps = [c for v in parts for c in (v.x, v.y, v.z)] + [mi.Float(self.fov)]
        w = dr.custom(_Spread, comps, width)
        return Pinhole(
            mi.Point3f(*w[0:3]),
            mi.Vector3f(*w[3:6]),
            mi.Vector3f(*w[6:9]),
            mi.Vector3f(*w[9:12]),
            w[12],
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


class _Spread(dr.CustomOp):
    """Values broadcast to ``width`` lanes. Dr.Jit's own broadcast reduces the gradient of each
    edge from a scalar to the grid on its own, evaluating the grid's whole adjoint expression
    once per edge; here the adjoints of all outputs are evaluated together and then summed."""

    def eval(self, values: list[Any], width: int) -> list[Any]:
        self.width = width
        self.narrow = [dr.width(v) == 1 for v in values]
        return [v + dr.zeros(mi.Float, width) for v in values]

    def forward(self) -> None:
        g = self.grad_in("values")
        self.set_grad_out([v + dr.zeros(mi.Float, self.width) for v in g])

    def backward(self) -> None:
        g = self.grad_out()
        dr.eval(g)
        sums = [dr.sum(v) if k else v for v, k in zip(g, self.narrow, strict=True)]
        self.set_grad_in("values", sums)

    def name(self) -> str:
        return "camera spread"


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


def _down(v: Any, rows: int, cols: int, w: int, taps: Taps, n: int, R: int) -> Any:
    """``out[r, i] = sum_k w_k v[r, (i + R) n + k]``: a (rows, cols) array filtered and
    decimated along its rows to (rows, w)."""
    idx = dr.arange(mi.Int32, rows * w)
    r, i = idx // w, idx % w
    acc = mi.Float(0.0)
    for k, wt in taps:
        acc += wt * dr.gather(mi.Float, v, mi.UInt32(r * cols + (i + R) * n + k))
    return acc


def _down_t(g: Any, rows: int, cols: int, w: int, taps: Taps, n: int, R: int) -> Any:
    """The transpose of :func:`_down` (its adjoint, for the backward pass) by gathers:
    ``v[r, c] = sum_i w_(c - R n - i n) g[r, i]`` over the ``2 R + 1`` outputs ``i`` whose
    window holds column ``c`` (taps ``k`` are contiguous from ``-R n``)."""
    idx = dr.arange(mi.Int32, rows * cols)
    r, c = idx // cols, idx % cols
    table = mi.Float([wt for _, wt in taps])  # weight of tap k at k + R n
    last = len(taps) - 1
    acc = mi.Float(0.0)
    for j in range(-(-len(taps) // n)):
        i = c // n - j  # the output reading c through tap k = c % n - R n + j n
        at = c % n + j * n  # that tap's place in the table
        ok = (i >= 0) & (i < w) & (at <= last)
        wt = dr.gather(mi.Float, table, mi.UInt32(dr.minimum(at, last)), ok)
        acc += dr.select(
            ok, wt * dr.gather(mi.Float, g, mi.UInt32(r * w + dr.maximum(i, 0)), ok), 0.0
        )
    return acc


def _transpose(v: Any, rows: int, cols: int) -> Any:
    """A (rows, cols) array stored column by column: (cols, rows)."""
    idx = dr.arange(mi.UInt32, rows * cols)
    return dr.gather(mi.Float, v, (idx % rows) * cols + idx // rows)


class _Separable(dr.CustomOp):
    """:func:`_separable` with a backward pass of gathers: Dr.Jit would otherwise transpose
    each of the filter's gathers into an atomic scatter-add, several times slower."""

    def eval(self, v: Any, rows: int, cols: int, w: int, h: int, taps: Taps, n: int, R: int):
        self.shape = (rows, cols, w, h, taps, n, R)
        return _apply(v, *self.shape)

    def forward(self) -> None:
        self.set_grad_out(_apply(self.grad_in("v"), *self.shape))

    def backward(self) -> None:
        rows, cols, w, h, taps, n, R = self.shape
        g = _transpose(self.grad_out(), h, w)  # (w, h): the y pass's transpose along rows
        g = _down_t(g, w, rows, h, taps, n, R)  # (w, rows)
        g = _transpose(g, w, rows)  # (rows, w)
        self.set_grad_in("v", _down_t(g, rows, cols, w, taps, n, R))

    def name(self) -> str:
        return "separable filter"


def _apply(v: Any, rows: int, cols: int, w: int, h: int, taps: Taps, n: int, R: int) -> Any:
    acc = _down(v, rows, cols, w, taps, n, R)  # (rows, w)
    dr.eval(acc)
    acc = _transpose(acc, rows, w)  # (w, rows)
    return _transpose(_down(acc, w, rows, h, taps, n, R), w, h)  # (h, w)


def _separable(v: Any, rows: int, cols: int, taps: Taps, n: int, R: int, size: tuple[int, int]):
    """``sum_{kx, ky} w_kx w_ky v[(j + R) n + ky, (i + R) n + kx]`` for every pixel ``(i, j)``
    of a ``size = (W, H)`` image, from the (rows, cols) samples ``v``."""
    w, h = size
    return dr.custom(_Separable, v, rows, cols, w, h, taps, n, R)


#: The four links of a sample: to its right, left, lower and upper neighbour.
DIRECTIONS = ((1, 0), (-1, 0), (0, 1), (0, -1))


@dataclass
class _Links:
    """The sample grid's detached data that decides where its links cross a discontinuity."""

    f: list[Any]  # the features, detached
    oid: Any
    valid: Any
    z: Any
    n: Any  # normals
    rows: int
    cols: int
    jump: float  # the depth-feature step that is a discontinuity
    spp: int  # samples per pixel along an axis (1 / h)

    def direction(self, dx: int, dy: int) -> tuple[Any, Any, Any, list[Any]]:
        """For the link from each sample to its neighbour ``(dx, dy)``: the neighbour's index,
        whether this sample is the front one, the weight ``m`` (``h^-1 / 2`` where the link is
        a discontinuity, else 0) and ``f_front - f_back`` per feature."""
        idx = dr.arange(mi.Int32, self.rows * self.cols)
        col, row = idx % self.cols, idx // self.cols
        inside = (col + dx >= 0) & (col + dx < self.cols) & (row + dy >= 0) & (row + dy < self.rows)
        b = mi.UInt32(
            dr.clip(row + dy, 0, self.rows - 1) * self.cols + dr.clip(col + dx, 0, self.cols - 1)
        )
        gb = lambda v, t=mi.Float: dr.gather(t, v, b)  # noqa: E731
        vb = gb(self.valid, mi.Bool)
        step = self.oid != gb(self.oid, mi.UInt32)
        step |= dr.abs(self.f[ID_DIMS] - gb(self.f[ID_DIMS])) > self.jump
        cos = sum(self.n[i] * gb(self.n[i]) for i in range(3))
        step |= self.valid & vb & (cos < CREASE_COS)
        front = self.z <= gb(self.z)
        m = dr.select(inside & step & (self.valid | vb), 0.5 * self.spp, 0.0)
        jumps = [dr.select(front, f - gb(f), gb(f) - f) for f in self.f]
        return b, front, m, jumps


class _Flux(dr.CustomOp):
    """The boundary term (module docstring) of every feature at every sample: linear in the
    samples' image velocities ``(ux, uy)``, with a backward pass of gathers (Dr.Jit's own would
    be a scatter-add per link and feature)."""

    def eval(self, ux: Any, uy: Any, links: _Links) -> list[Any]:
        self.links = links
        return self._apply(ux, uy)

    def _apply(self, ux: Any, uy: Any) -> list[Any]:
        out = [mi.Float(0.0) for _ in self.links.f]
        for dx, dy in DIRECTIONS:
            b, front, m, jumps = self.links.direction(dx, dy)
            ue = (ux if dx else uy) * (dx + dy)  # u . e for e the unit step from here to there
            u = dr.select(front, ue, -dr.gather(mi.Float, ue, b)) * m
            out = [o + j * u for o, j in zip(out, jumps, strict=True)]
        dr.eval(out)
        return out

    def forward(self) -> None:
        self.set_grad_out(self._apply(self.grad_in("ux"), self.grad_in("uy")))

    def backward(self) -> None:
        g = self.grad_out()
        lk = self.links
        # Per direction, the adjoint of the link's velocity: at this sample where it is the
        # front one, else at the neighbour (read there by a gather below). All four in one
        # kernel, which loads this sample's data once.
        own, other = [mi.Float(0.0), mi.Float(0.0)], []
        for dx, dy in DIRECTIONS:
            _, front, m, jumps = lk.direction(dx, dy)
            G = m * (dx + dy) * sum(j * gc for j, gc in zip(jumps, g, strict=True))
            own[0 if dx else 1] += dr.select(front, G, 0.0)
            other.append(dr.select(front, 0.0, -G))
        dr.eval(own, other)
        idx = dr.arange(mi.Int32, lk.rows * lk.cols)
        col, row = idx % lk.cols, idx // lk.cols
        gx, gy = own
        for (dx, dy), o in zip(DIRECTIONS, other, strict=True):
            # the samples whose link in this direction ends here
            sx, sy = col - dx, row - dy
            ok = (sx >= 0) & (sx < lk.cols) & (sy >= 0) & (sy < lk.rows)
            src = mi.UInt32(dr.clip(sy, 0, lk.rows - 1) * lk.cols + dr.clip(sx, 0, lk.cols - 1))
            if dx:
                gx += dr.gather(mi.Float, o, src, ok)
            else:
                gy += dr.gather(mi.Float, o, src, ok)
        self.set_grad_in("ux", gx)
        self.set_grad_in("uy", gy)

    def name(self) -> str:
        return "boundary flux"


def _check(name: str, value: Any, ok: bool, rule: str) -> None:
    if not ok:
        raise ParameterError(f"{name} = {shown(value)}: {rule}")


def _int(v: Any) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def _real(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _size(size: Any) -> tuple[int, int]:
    """``size = (W, H)``, two integers in [1, MAX_RES], or a :class:`ParameterError`."""
    ok = (
        isinstance(size, (tuple, list))
        and len(size) == 2
        and all(_int(v) and 1 <= v <= MAX_RES for v in size)
    )
    _check("size", size, ok, f"expected (W, H), two integers in [1, {MAX_RES}]")
    return int(size[0]), int(size[1])


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
    size = _size(size)
    cam = camera if isinstance(camera, Pinhole) else Pinhole.of_sensor(sensor)
    _check("n", n, _int(n) and 1 <= n <= 16, "expected an integer in [1, 16]")
    for name, v in (("sigma", sigma), ("kappa", kappa)):
        _check(name, v, _real(v) and 0 < v < math.inf, "must be a finite number > 0")
    for name, v in (("depth_weight", depth_weight), ("normal_weight", normal_weight)):
        _check(name, v, _real(v) and 0 <= v < math.inf, "must be a finite number >= 0")
    if depth_scale is not None:
        _check(
            "depth_scale",
            depth_scale,
            _real(depth_scale) and 0 < depth_scale < math.inf,
            "must be a finite number > 0",
        )
    if depth_scale is None:
        bb = scene.bbox()
        depth_scale = float(dr.norm(bb.max - bb.min)) if bb.valid() else 1.0
    w, h = (int(v) for v in size)
    R = max(1, math.ceil(3.0 * sigma))
    cols, rows = (w + 2 * R) * n, (h + 2 * R) * n
    cam = cam.spread(rows * cols)
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
    # Both geometric features weighted by cos^2 of the view angle (module docstring): towards a
    # smooth contour the normal turns and the depth grows as the square root of the distance
    # to the outline, infinitely fast; cos^2 n and cos^2 / z are Lipschitz and vanish there.
    cos = dr.dot(nrm, ray.d)
    c2 = cos * cos
    feats = _id_features(oid)
    inv_z = depth_weight * (COVERAGE + depth_scale * c2 / dr.select(valid, z, 1.0))
    feats.append(dr.select(valid, inv_z, 0.0))
    feats += [dr.select(valid, normal_weight * c2 * nrm[i], 0.0) for i in range(3)]
    feats.append(sum(f * f for f in feats))  # |f|^2, filtered into F2

    # The boundary term: the image velocity of the front sample's material point.
    moving = pi.compute_surface_interaction(
        dr.detach(ray), mi.RayFlags.All | mi.RayFlags.FollowShape, valid
    )
    px, py = cam.project(dr.select(valid, moving.p, cam.origin + cam.forward), (w, h))
    ux, uy = px - dr.detach(px), py - dr.detach(py)  # 0, with the velocity as derivative
    fd = [dr.detach(f) for f in feats]
    # One kernel for everything the links read (smaller kernels compile much faster than one
    # with the filter; a value left out would be recomputed, intersection and all, on its own).
    dr.eval(feats, ux, uy, oid, valid, z, nrm)
    zd, nd = dr.detach(z), dr.detach(nrm)

    links = _Links(fd, oid, valid, zd, nd, rows, cols, 0.05 * depth_weight, n)
    flux = dr.custom(_Flux, ux, uy, links)
    ts = _taps(n, R, sigma)
    F = [_separable(f + q, rows, cols, ts, n, R, (w, h)) for f, q in zip(feats, flux, strict=True)]
    var = dr.maximum(F[-1] - sum(f * f for f in F[:-1]), 0.0)
    return mi.TensorXf(1.0 - dr.exp(-var / kappa), shape=(h, w))
