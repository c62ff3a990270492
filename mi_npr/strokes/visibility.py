"""Exact visibility of 3-D points by ray casting against the scene itself.

**Quantitative invisibility** (QI, Appel's): the number of surfaces the eye ray from the camera
origin ``o`` to a point ``P`` crosses *strictly in front of* ``P``. A closed solid in front of
``P`` counts twice (its near and its far side), a single sheet once; the back edges of a cube
count 1 (only its front face lies in front of them). The ray continues past each hit until it
reaches ``P`` or ``max_qi`` surfaces were counted (the count is capped there): in a scene of
meshes alone along the eye ray itself, from just beyond the hit (:func:`_qi`), else from
``si.spawn_ray``, which steps off the surface along its normal.

**What does not count.**

- Hits within ``EPSILON`` (relative to ``|P - o|``) in front of ``P``: ``P`` lies on its own
  surfaces, and a surface that contains ``P`` (the floor under a box's bottom edge) does not hide
  it.
- Hits on the faces that own ``P`` (``own``: an edge's adjacent triangles, by object id and
  primitive index): a plane through ``P`` meets the eye ray only at ``P``, so any such hit is
  ``P`` itself, whatever the floating-point error at grazing angles.
- **Glass**: a surface whose BSDF has ``DeltaTransmission`` (Mitsuba's ``dielectric``,
  ``thindielectric``) is seen through: it sets ``through_glass`` instead of counting. Rays are
  not bent: a point behind glass keeps its unrefracted position (exact for a thin pane,
  approximate behind a thick or curved one).
- A surface with the ``null`` BSDF (flags ``Null`` only) is invisible and passes.

At most :data:`MAX_PASSES` glass or null surfaces are passed per ray (more read as opaque).
"""

from __future__ import annotations

from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..scene import ObjectTable

#: Hits this close in front of the point (relative to its distance) are the point itself.
EPSILON = 1e-4
#: Most glass or null surfaces one ray passes through.
MAX_PASSES = 8
#: Rays cast in one launch (the loop's state and inputs are ~40 bytes a ray: memory bound).
RAYS = 1 << 22


def jit_array(kind: type, a: np.ndarray) -> object:
    """A Dr.Jit array of ``kind`` (``mi.Float``, ``mi.UInt32``...) with the values of ``a``,
    from a 64-byte aligned copy. Dr.Jit reads a numpy buffer in place, and compiles a kernel
    that reads an unaligned buffer differently from one that reads an aligned one: a kernel fed
    from numpy arrays of arbitrary alignment missed the kernel cache on most calls (a new
    compilation, tens of ms, each time)."""
    a = np.ascontiguousarray(a)
    buf = np.empty(a.nbytes + 64, np.uint8)
    off = -buf.ctypes.data % 64
    out = buf[off : off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return kind(out)


def _vec(a: np.ndarray, kind: type) -> object:
    a = np.asarray(a, np.float64).reshape(-1, 3).astype(np.float32)
    return kind(*(jit_array(mi.Float, a[:, k]) for k in range(3)))


def own_arrays(own: np.ndarray) -> list:
    """The faces a point lies on, ``own`` (N, 2, 2): ``(object id, prim)`` of up to two faces
    each, as the QI loop takes them: four ``mi.UInt32`` (object id, prim, object id, prim)."""
    own = np.asarray(own)
    return [jit_array(mi.UInt32, own[:, k // 2, k % 2].astype(np.uint32)) for k in range(4)]


def _bounded(o: mi.Point3f, d: mi.Vector3f, maxt: mi.Float) -> mi.Ray3f:
    """The ray ``o + t d``, ``t < maxt`` (``mi.Ray3f(o, d, x)`` would read ``x`` as the time)."""
    ray = mi.Ray3f(o, d)
    ray.maxt = maxt
    return ray


def _surface(flags: mi.UInt32, hit: mi.Bool) -> tuple[mi.Bool, mi.Bool]:
    """``(glass, invisible)`` of each hit, from its BSDF's ``flags``: a delta transmission
    (seen through) or a ``null`` BSDF (not seen at all)."""
    glass = hit & mi.has_flag(flags, mi.BSDFFlags.DeltaTransmission)
    invisible = hit & (flags == mi.UInt32(int(mi.BSDFFlags.Null)))
    return glass, invisible


def quantitative_invisibility(
    scene: mi.Scene,
    table: ObjectTable,
    origin: np.ndarray,
    points: np.ndarray,
    own: np.ndarray | None = None,
    max_qi: int = 8,
) -> tuple[np.ndarray, np.ndarray]:
    """QI (N,) int32 and ``through_glass`` (N,) bool of world ``points`` (N, 3) seen from
    ``origin`` (module docstring). ``own`` (N, 2, 2): ``(object id, prim)`` of up to two faces
    each point lies on (object id 0: none)."""
    n = len(points)
    if n == 0:
        return np.zeros(0, np.int32), np.zeros(0, bool)
    # every input computed in numpy and passed as an evaluated array: the loop's kernel is then
    # the same from call to call (Dr.Jit's cache hits it) instead of fused with its inputs
    p = np.asarray(points, np.float64).reshape(-1, 3)
    o = np.broadcast_to(np.asarray(origin, np.float64).reshape(1, 3), (n, 3))
    d = p - o
    dist = np.linalg.norm(d, axis=1)
    d = d / np.where(dist > 0, dist, 1.0)[:, None]
    if own is None:
        own = np.zeros((n, 2, 2), np.int64)
    qi, glass = _count(
        scene,
        table,
        _vec(o, mi.Point3f),
        _vec(p, mi.Point3f),
        _vec(d, mi.Vector3f),
        jit_array(mi.Float, dist.astype(np.float32)),
        own_arrays(own),
        max_qi,
    )
    return np.asarray(qi.numpy(), np.int32), np.asarray(glass.numpy(), bool)


class SegmentVisibility:
    """QI and ``through_glass`` of points along ``E`` world segments ``a -> b`` (E, 3), seen
    from ``origin``: ``at(i, u)`` is the point of film parameter ``u`` on segment ``i``
    (perspective-correct: 3-D parameter ``s = u w_a / ((1 - u) w_b + u w_a)``, ``w`` the ends'
    homogeneous weights ``wa``, ``wb``: their depths, or 1 for an orthographic camera), lying
    on the faces ``own`` (E, 2, 2) (``quantitative_invisibility``'s). With ``axis`` (an
    orthographic camera's view axis) the ray to a point ``P`` runs along it from the near plane
    (``near`` from ``origin``) instead of from ``origin``.
    The segments are sent to Dr.Jit once; each call sends only ``(i, u)`` and computes its
    points there (in single precision: their error, ~1e-7 of their distance, lies far inside
    the ``EPSILON`` guard)."""

    def __init__(
        self,
        scene: mi.Scene,
        table: ObjectTable,
        origin: np.ndarray,
        a: np.ndarray,
        b: np.ndarray,
        wa: np.ndarray,
        wb: np.ndarray,
        own: np.ndarray,
        max_qi: int,
        axis: np.ndarray | None = None,
        near: float = 0.0,
    ) -> None:
        self._setup(
            scene,
            table,
            origin,
            _vec(a, mi.Point3f),
            _vec(np.asarray(b, np.float64) - np.asarray(a, np.float64), mi.Vector3f),
            jit_array(mi.Float, np.asarray(wa, np.float32)),
            jit_array(mi.Float, np.asarray(wb, np.float32)),
            own_arrays(own),
            max_qi,
            axis,
            near,
        )

    @classmethod
    def of_jit(
        cls,
        scene: mi.Scene,
        table: ObjectTable,
        origin: np.ndarray,
        a: list,
        b: list,
        wa: Any,
        wb: Any,
        own: list,
        max_qi: int,
        axis: np.ndarray | None = None,
        near: float = 0.0,
    ) -> SegmentVisibility:
        """The same from Dr.Jit arrays: ends ``a``, ``b`` (three ``mi.Float64`` each, made
        single precision as the numpy ones are), weights ``wa``, ``wb`` (``mi.Float64``) and
        ``own`` (:func:`own_arrays`')."""
        out = cls.__new__(cls)
        out._setup(
            scene,
            table,
            origin,
            mi.Point3f(*(mi.Float(x) for x in a)),
            mi.Vector3f(*(mi.Float(y - x) for x, y in zip(a, b, strict=True))),
            mi.Float(wa),
            mi.Float(wb),
            list(own),
            max_qi,
            axis,
            near,
        )
        return out

    def _setup(
        self,
        scene: mi.Scene,
        table: ObjectTable,
        origin: np.ndarray,
        a: mi.Point3f,
        ab: mi.Vector3f,
        wa: mi.Float,
        wb: mi.Float,
        own: list,
        max_qi: int,
        axis: np.ndarray | None,
        near: float,
    ) -> None:
        self.scene, self.table, self.max_qi = scene, table, max_qi
        # an evaluated array, not a literal: a literal origin would compile a kernel per view
        self.origin = _vec(np.asarray(origin, np.float64).reshape(1, 3), mi.Point3f)
        # an orthographic camera: parallel rays along ``axis`` from the near plane
        self.axis = None
        if axis is not None:
            self.axis = _vec(np.asarray(axis, np.float64).reshape(1, 3), mi.Vector3f)
            self.near = jit_array(mi.Float, np.array([near], np.float32))
        self.a, self.ab, self.wa, self.wb, self.own = a, ab, wa, wb, own

    def _points(
        self, i: mi.UInt32, u: mi.Float
    ) -> tuple[mi.Point3f, mi.Point3f, mi.Vector3f, mi.Float, list]:
        """Origin, point, unit direction, distance and own faces of parameter ``u`` of each
        segment ``i`` (class docstring)."""
        wa, wb = dr.gather(mi.Float, self.wa, i), dr.gather(mi.Float, self.wb, i)
        s = u * wa / ((1.0 - u) * wb + u * wa)
        p = dr.fma(dr.gather(mi.Vector3f, self.ab, i), s, dr.gather(mi.Point3f, self.a, i))
        zero = dr.zeros(mi.UInt32, dr.width(i))
        o = dr.gather(mi.Point3f, self.origin, zero)
        if self.axis is not None:  # the point of the near plane in front of p
            f = dr.gather(mi.Vector3f, self.axis, zero)
            o = p - (dr.dot(p - o, f) - dr.gather(mi.Float, self.near, zero)) * f
        d = p - o
        dist = dr.norm(d)
        return (
            o,
            p,
            d / dr.select(dist > 0, dist, 1.0),
            dist,
            [dr.gather(mi.UInt32, x, i) for x in self.own],
        )

    def bisect(
        self,
        idx: np.ndarray,
        ulo: np.ndarray,
        uhi: np.ndarray,
        state: np.ndarray,
        iterations: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``iterations`` bisections of each interval ``[ulo, uhi]`` (N,) of segments ``idx``
        (N,) whose state ``2 QI + through_glass`` at ``ulo`` is ``state`` (N,): the midpoint
        replaces the end whose state it has (``ulo`` where it equals ``state``). One kernel
        for all of them (a loop around the QI loop); the parameters in double precision, the
        points in single, as :meth:`at`."""
        if len(idx) == 0:
            return np.asarray(ulo, np.float64), np.asarray(uhi, np.float64)
        if len(idx) > RAYS:
            return _in_launches(self.bisect, (idx, ulo, uhi, state), iterations)
        i = jit_array(mi.UInt32, np.asarray(idx, np.uint32))
        lo = jit_array(mi.Float64, np.asarray(ulo, np.float64))
        hi = jit_array(mi.Float64, np.asarray(uhi, np.float64))
        target = jit_array(mi.UInt32, np.asarray(state, np.uint32))
        step = dr.zeros(mi.UInt32, len(idx))
        dr.make_opaque(step)

        def cond(step, lo, hi):
            return step < iterations

        def body(step, lo, hi):
            mid = 0.5 * (lo + hi)
            o, p, d, dist, own = self._points(i, mi.Float(mid))
            qi, glass = _qi(self.scene, self.table, o, p, d, dist, own, self.max_qi, False)
            same = qi * 2 + dr.select(glass, 1, 0) == target
            return step + 1, dr.select(same, mid, lo), dr.select(same, hi, mid)

        _, lo, hi = dr.while_loop((step, lo, hi), cond, body, labels=("step", "lo", "hi"))
        dr.eval(lo, hi)
        return np.asarray(lo.numpy(), np.float64), np.asarray(hi.numpy(), np.float64)

    def at(self, idx: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """QI (N,) int32 and ``through_glass`` (N,) bool of the points ``u`` (N,) of segments
        ``idx`` (N,) (class docstring)."""
        n = len(idx)
        if n == 0:
            return np.zeros(0, np.int32), np.zeros(0, bool)
        if n > RAYS:
            return _in_launches(self.at, (idx, u))
        i = jit_array(mi.UInt32, np.asarray(idx, np.uint32))
        uu = jit_array(mi.Float, np.asarray(u, np.float32))
        qi, glass = self.states(i, uu)
        return np.asarray(qi.numpy(), np.int32), np.asarray(glass.numpy(), bool)

    def states(self, i: mi.UInt32, u: mi.Float) -> tuple[mi.UInt32, mi.Bool]:
        """:meth:`at` of Dr.Jit arrays (at most :data:`RAYS`), evaluated."""
        o, p, d, dist, own = self._points(i, u)
        return _count(self.scene, self.table, o, p, d, dist, own, self.max_qi)


def _in_launches(f: Any, arrays: tuple[np.ndarray, ...], *rest: Any) -> tuple[np.ndarray, ...]:
    """``f(*arrays, *rest)`` taken :data:`RAYS` rows of ``arrays`` at a time, each of its
    results concatenated."""
    n = len(arrays[0])
    parts = [f(*(a[k : k + RAYS] for a in arrays), *rest) for k in range(0, n, RAYS)]
    return tuple(np.concatenate(x) for x in zip(*parts, strict=True))


def _count(
    scene: mi.Scene,
    table: ObjectTable,
    o: mi.Point3f,
    P: mi.Point3f,
    d: mi.Vector3f,
    dist: mi.Float,
    own: list,
    max_qi: int,
) -> tuple[mi.UInt32, mi.Bool]:
    """The QI loop (module docstring), evaluated, over the rays from ``o`` in direction ``d``
    to the points ``P`` at distance ``dist``; ``own``: the four arrays object id, prim, object
    id, prim of the points' faces."""
    qi, glass = _qi(scene, table, o, P, d, dist, own, max_qi)
    dr.eval(qi, glass)
    return qi, glass


def meshes_only(table: ObjectTable) -> bool:
    """Whether every shape of ``table`` is a mesh (no instance, sphere, curve...): the QI loop
    then needs the preliminary intersections alone (:func:`_qi`)."""
    return all(shape.is_mesh() for shape in table.shapes.values())


def _qi(
    scene: mi.Scene,
    table: ObjectTable,
    o: mi.Point3f,
    P: mi.Point3f,
    d: mi.Vector3f,
    dist: mi.Float,
    own: list,
    max_qi: int,
    opaque: bool = True,
) -> tuple[mi.UInt32, mi.Bool]:
    """:func:`_count`'s loop, traced but not evaluated; ``opaque``: its zeros made evaluated
    arrays (not inside another loop, where nothing can be evaluated).

    Each ray continues past a hit from just beyond it. In a scene of meshes alone the hits
    are preliminary (shape, primitive, distance: no surface interaction, whose virtual call
    over every shape costs as much as the intersection) and the ray goes on from the hit
    along ``d``, ``RayEpsilon (1 + max |p|)`` further (the offset of Mitsuba's
    ``spawn_ray``, along the ray instead of the normal); a hit on the object just passed no
    farther than that offset again is that surface again (a neighbouring triangle of the
    edge or vertex the ray went through) and does not count. Otherwise (spheres, curves,
    instances...) the ray goes on from ``si.spawn_ray``."""
    n = dr.width(P)
    guard = dist * EPSILON
    qi = dr.zeros(mi.UInt32, n)
    glass = dr.zeros(mi.Bool, n)
    active = dist > guard
    steps = dr.zeros(mi.UInt32, n)
    limit = max_qi + MAX_PASSES
    own_o0, own_p0, own_o1, own_p1 = own

    def counted(hit: mi.Bool, oid: mi.UInt32, prim: mi.UInt32, flags: mi.UInt32, skip: mi.Bool):
        mine = ((oid == own_o0) & (prim == own_p0)) | ((oid == own_o1) & (prim == own_p1))
        mine |= skip
        is_glass, invisible = _surface(flags, hit)
        return dr.select(hit & ~is_glass & ~invisible & ~mine, 1, 0), is_glass & ~mine

    if meshes_only(table):
        t0 = dr.zeros(mi.Float, n)
        last = dr.zeros(mi.UInt32, n)  # the object of the previous hit (0: none yet)
        step = dr.zeros(mi.Float, n)  # the offset past the previous hit
        if opaque:
            dr.make_opaque(qi, glass, steps, t0, last, step)

        def cond(t0, step, last, qi, glass, active, steps):
            return active

        def body(t0, step, last, qi, glass, active, steps):
            ray = _bounded(dr.fma(d, t0, o), d, dist - guard - t0)
            pi = scene.ray_intersect_preliminary(ray, coherent=False)
            hit = pi.is_valid()
            oid = table.lookup(pi)
            again = (oid == last) & (pi.t <= step)
            add, through = counted(hit, oid, pi.prim_index, pi.shape.bsdf().flags(), again)
            qi += add
            glass |= through
            steps += 1
            t0 += pi.t
            p = dr.fma(d, t0, o)
            step = mi.math.RayEpsilon * (1.0 + dr.max(dr.abs(p)))
            t0 += step
            last = oid
            active = hit & (qi < max_qi) & (steps < limit) & (dist - guard - t0 > 0)
            return t0, step, last, qi, glass, active, steps

        state = (t0, step, last, qi, glass, active, steps)
        labels = ("t0", "step", "last", "qi", "glass", "active", "steps")
        _, _, _, qi, glass, _, _ = dr.while_loop(state, cond, body, labels=labels)
        return qi, glass

    ray_o = mi.Point3f(o)
    maxt = dist - guard
    if opaque:
        dr.make_opaque(qi, glass, steps)

    def cond_si(ray_o, maxt, qi, glass, active, steps):
        return active

    def body_si(ray_o, maxt, qi, glass, active, steps):
        si = scene.ray_intersect(
            _bounded(ray_o, d, maxt), ray_flags=mi.RayFlags.Minimal, coherent=False
        )
        hit = si.is_valid()
        add, through = counted(hit, table.lookup(si), si.prim_index, si.bsdf().flags(), False)
        qi += add
        glass |= through
        steps += 1
        ray_o = si.spawn_ray(d).o
        maxt = dr.dot(P - ray_o, d) - guard
        active = hit & (qi < max_qi) & (steps < limit) & (maxt > 0)
        return ray_o, maxt, qi, glass, active, steps

    _, _, qi, glass, _, _ = dr.while_loop(
        (ray_o, maxt, qi, glass, active, steps),
        cond_si,
        body_si,
        labels=("o", "maxt", "qi", "glass", "active", "steps"),
    )
    return qi, glass


def first_opaque_hit(
    scene: mi.Scene,
    table: ObjectTable,
    ray: mi.Ray3f,
    flags: mi.RayFlags = mi.RayFlags.All,
    stop_at_glass: bool = False,
) -> tuple[mi.SurfaceInteraction3f, mi.UInt32, mi.Bool, mi.Bool]:
    """The first surface along each ray that is neither glass nor ``null`` (module docstring):
    its surface interaction (``t`` from the ray's origin; the fields ``flags`` asks for:
    ``mi.RayFlags.Minimal`` for the position alone), object id (0: none), whether it was hit
    and whether glass was passed on the way. ``stop_at_glass``: glass is a surface like any
    other (only ``null`` surfaces are passed), which is how a glass shape's own outline is seen."""
    d, o = ray.d, ray.o
    si = scene.ray_intersect(ray, ray_flags=flags, coherent=False)
    glass = dr.zeros(mi.Bool, dr.width(si.t))
    hit = si.is_valid()
    is_glass, invisible = _surface(si.bsdf().flags(), hit)
    passing = invisible if stop_at_glass else is_glass | invisible
    # one kernel: testing ``passing`` alone would trace the rays again for ``si`` afterwards
    dr.eval(si, hit, passing)
    for _ in range(MAX_PASSES):
        if not dr.any(passing):
            break
        glass |= is_glass & passing
        again = scene.ray_intersect(
            si.spawn_ray(d), ray_flags=flags, coherent=False, active=passing
        )
        si = dr.select(passing, again, si)
        hit = dr.select(passing, again.is_valid(), hit)
        is_glass, invisible = _surface(si.bsdf().flags(), hit & passing)
        passing = passing & hit & (invisible if stop_at_glass else is_glass | invisible)
        dr.eval(si, hit, glass, passing)
    si.t = dr.select(hit, dr.dot(si.p - o, d), dr.inf)
    oid = dr.select(hit & ~passing, table.lookup(si), 0)
    return si, oid, hit & ~passing, glass
