"""The deterministic ray-tree tracer and the 64-bit tree hash (paper, section 2.2.3; Nehab and
Gattass's ray-path categories).

The tree of a ray (Fig. 5 of the paper): its root is the object the ray hits, with the lights
visible from the hit point (:mod:`mi_npr.raytree.lights`). A surface whose BSDF has a delta
reflection lobe (mirror, smooth conductor, smooth plastic's coating, glass) has a *reflection*
child; one with a delta transmission lobe (glass) or a ``Null`` one (the straight-through
transmission of thin glass, ``thindielectric``, and of the ``null`` BSDF) has a *refraction*
child; each child is the tree of the specular ray it spawns. Rough and diffuse surfaces end the
branch. A child's direction comes from ``bsdf.sample`` with a :class:`mitsuba.BSDFContext` that
enables only that lobe (``DeltaReflection``, or ``DeltaTransmission | Null``), so nothing is
chosen at random; a lobe whose weight is zero there (total internal reflection, a one-sided
mirror seen from behind) gives no child. A ray that hits nothing adds no node.

Node positions (what the paper's "numbering of the node positions" is taken to mean, consistent
with its strings ``4A2BL1C`` and ``7A3BL1``): heap numbering, the root is 1, the reflection child
of node ``p`` is ``2p`` and its refraction child ``2p + 1``. A node's depth is
``floor(log2(p))``; ``max_depth`` counts levels like Mitsuba's ``max_depth`` counts path segments
(``max_depth = 1``: the primary hit only; 3: root, children and grandchildren).

Tracing is a wavefront over all rays at once: level ``d`` holds the (ray, position) items alive at
depth ``d``, compacted with ``dr.compress`` so deeper levels only cost what is specular.

Hash (``raytree.hi``/``raytree.lo``). Each node gets a 64-bit key
``mix(mix(p << 32 | object) ^ (w_0 + c_0)) ...`` over its light-mask words ``w_i`` (``mix`` =
MurmurHash3's 64-bit finaliser, a bijection); the tree hash is ``mix`` of the sum (mod 2**64)
of its nodes' keys. So the hash is a function of the node set alone (the same set the signature
string is written from), the empty tree (nothing hit) hashes to 0, and different trees collide
with probability about 2**-64 per pair (a sum of strong keys is a set hash; every key includes
the node's position, so permuting nodes changes it). Sums per level and per child kind are kept
too: the edge classifier compares them to find the shallowest differing node.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError
from ..params import MAX_RAYTREE_DEPTH
from ..raycast import cast, require_jit
from ..scene import ObjectTable
from .lights import LightTable, visible_lights

#: Largest accepted ``max_depth``: positions must fit the 32 bits they are stored in.
MAX_DEPTH = MAX_RAYTREE_DEPTH

_M1 = 0xFF51AFD7ED558CCD
_M2 = 0xC4CEB9FE1A85EC53
_GOLDEN = 0x9E3779B97F4A7C15


#: BSDF lobes followed by reflection children (``2p``) and refraction children (``2p + 1``).
#: ``Null`` is the straight-through transmission of thin glass (``thindielectric``).
REFLECTION_LOBES = int(mi.BSDFFlags.DeltaReflection)
REFRACTION_LOBES = int(mi.BSDFFlags.DeltaTransmission) | int(mi.BSDFFlags.Null)


def mix64(h: Any) -> Any:
    """MurmurHash3's ``fmix64`` on a Dr.Jit ``UInt64`` array (a bijection of 64-bit words)."""
    h = h ^ (h >> 33)
    h = h * _M1
    h = h ^ (h >> 33)
    h = h * _M2
    return h ^ (h >> 33)


def node_key(pos: Any, obj: Any, words: list[Any]) -> Any:
    """The 64-bit key of tree nodes: position, object id and light-mask words (see above)."""
    h = mix64((mi.UInt64(pos) << 32) | mi.UInt64(obj))
    for i, w in enumerate(words):
        h = mix64(h ^ (mi.UInt64(w) + ((i + 1) * _GOLDEN) % 2**64))
    return h


def check_max_depth(max_depth: Any) -> int:
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, np.integer)):
        raise ParameterError(f"max_depth = {max_depth!r}: expected an integer")
    if not 1 <= int(max_depth) <= MAX_DEPTH:
        raise ParameterError(f"max_depth = {max_depth!r}: must be in 1..{MAX_DEPTH}")
    return int(max_depth)


@dataclass
class Nodes:
    """Every node of every traced tree, as flat numpy arrays (one entry per node).

    ``ray`` is the index of the tree's ray, ``pos`` the node position, ``obj`` the object id,
    ``lights`` the light mask, shape (nodes, words). Only filled when tracing with ``record``.
    """

    ray: np.ndarray
    pos: np.ndarray
    obj: np.ndarray
    lights: np.ndarray

    def of_ray(self, i: int) -> dict[int, tuple[int, tuple[int, ...]]]:
        """The tree of ray ``i``: ``{position: (object id, light-mask words)}``."""
        sel = np.flatnonzero(self.ray == i)
        return {
            int(self.pos[j]): (int(self.obj[j]), tuple(int(w) for w in self.lights[j])) for j in sel
        }


@dataclass
class Trees:
    """The ray trees of ``n`` rays, summarised for hashing and edge classification.

    - ``hash``: the 64-bit tree hash (``UInt64``, 0 for an empty tree),
    - ``root_obj``: the primary hit's object id (``UInt32``, 0 on a miss),
    - ``root_lights``: its light mask (tuple of ``UInt32`` words),
    - ``levels[d - 1] = (reflection, refraction)``: for depths ``d = 1 .. max_depth - 1``, the sums
      (mod 2**64) of the keys of the nodes at depth ``d`` in even (reflection) and odd (refraction)
      positions (``UInt64``).
    """

    hash: Any
    root_obj: Any
    root_lights: tuple[Any, ...]
    levels: tuple[tuple[Any, Any], ...]
    nodes: Nodes | None = field(default=None, repr=False)

    @property
    def width(self) -> int:
        return dr.width(self.root_obj)

    def hi_lo(self) -> tuple[Any, Any]:
        """The hash split into its upper and lower 32 bits (``UInt32`` each)."""
        return mi.UInt32(self.hash >> 32), mi.UInt32(self.hash & 0xFFFFFFFF)


def specular_lobes(objects: ObjectTable) -> list[int]:
    """Per object id (0 = nothing hit), the flags of its BSDF's lobes that spawn children.

    An instance's id covers shapes with BSDFs of their own: it gets every lobe, and the BSDF
    call decides per hit."""
    out = [0] * (len(objects) + 1)
    for k, shape in objects.shapes.items():
        bsdf = None if shape.class_name() == "Instance" else shape.bsdf()
        flags = int(bsdf.flags()) if bsdf is not None else -1
        out[k] = flags & (REFLECTION_LOBES | REFRACTION_LOBES)
    return out


def _level(
    scene: mi.Scene,
    ray: mi.Ray3f,
    pos: Any,
    objects: ObjectTable,
    lights: LightTable,
    lobes: Any,
    coherent: bool,
) -> tuple[Any, ...]:
    """One wavefront level: hits, node keys, and the children's rays (unless ``lobes`` is
    ``None``: the last level)."""
    hits = cast(scene, ray, objects, detail="full", coherent=coherent)
    si, valid, obj = hits.si, hits.valid, hits.object_id
    words = visible_lights(scene, si, ray.d, obj, lights, objects, valid)
    key = dr.select(valid, node_key(pos, obj, words), mi.UInt64(0))
    if lobes is None:
        return valid, obj, words, key, None
    has = dr.gather(mi.UInt32, lobes, obj, valid)
    bsdf = si.bsdf(mi.RayDifferential3f(ray))
    kids = []
    for lobe in (REFLECTION_LOBES, REFRACTION_LOBES):
        ctx = mi.BSDFContext()
        ctx.type_mask = lobe
        active = valid & ((has & lobe) != 0)  # only specular hits pay for the BSDF call
        bs, w = bsdf.sample(ctx, si, 0.5, mi.Point2f(0.5, 0.5), active)
        ok = active & (bs.pdf > 0) & (dr.max(mi.unpolarized_spectrum(w)) > 0)
        ok &= (bs.sampled_type & lobe) != 0
        kids.append((ok, si.spawn_ray(si.to_world(bs.wo))))
    return valid, obj, words, key, kids


def _gather_child(ray_r: mi.Ray3f, ray_t: mi.Ray3f, parent: Any, is_t: Any) -> mi.Ray3f:
    """Child rays: the refraction ray of ``parent`` where ``is_t``, else its reflection ray."""

    def pick(tp: Any, a: Any, b: Any) -> Any:
        return dr.select(is_t, dr.gather(tp, b, parent), dr.gather(tp, a, parent))

    return mi.Ray3f(
        pick(mi.Point3f, ray_r.o, ray_t.o),
        pick(mi.Vector3f, ray_r.d, ray_t.d),
        pick(mi.Float, ray_r.maxt, ray_t.maxt),
        pick(mi.Float, ray_r.time, ray_t.time),
        ray_r.wavelengths,
    )


def trace_trees(
    scene: mi.Scene,
    rays: mi.Ray3f,
    objects: ObjectTable,
    lights: LightTable,
    max_depth: int = 3,
    record: bool = False,
) -> Trees:
    """The ray trees of ``rays`` (any width) down to ``max_depth`` levels.

    With ``record``, every node is also returned (:class:`Nodes`) for signatures and tests.
    """
    require_jit("ray trees")
    max_depth = check_max_depth(max_depth)
    n = dr.width(rays.o)
    idx = dr.arange(mi.UInt32, n)  # the tree (ray) each wavefront item belongs to
    pos = dr.full(mi.UInt32, 1, n)
    ray = rays
    total = dr.zeros(mi.UInt64, n)
    levels: list[tuple[Any, Any]] = []
    root_obj: Any = None
    root_lights: tuple[Any, ...] = ()
    rec: list[tuple[Any, ...]] = []
    lut = specular_lobes(objects)
    levels_traced = max_depth if any(lut) else 1  # else nothing in the scene spawns children
    lobes = mi.UInt32(lut)
    for depth in range(levels_traced):
        last = depth == levels_traced - 1
        valid, obj, words, key, kids = _level(
            scene, ray, pos, objects, lights, None if last else lobes, coherent=depth == 0
        )
        # One kernel per level: the scatters and compress() below would otherwise each re-run
        # the intersections and shadow rays.
        dr.eval(valid, obj, words, key, kids)
        if depth == 0:
            root_obj, root_lights = obj, tuple(words)
            total = key
        else:
            refl, refr = dr.zeros(mi.UInt64, n), dr.zeros(mi.UInt64, n)
            odd = (pos & 1) == 1
            # Few items hit few trees: plain atomics beat Dr.Jit's per-thread copies here.
            direct = dr.ReduceMode.Direct
            dr.scatter_reduce(dr.ReduceOp.Add, refl, key, idx, valid & ~odd, mode=direct)
            dr.scatter_reduce(dr.ReduceOp.Add, refr, key, idx, valid & odd, mode=direct)
            total = total + refl + refr
            levels.append((refl, refr))
        if record:
            rec.append((idx, pos, valid, obj, words))
        if last:
            break
        (ok_r, ray_r), (ok_t, ray_t) = kids
        m = dr.width(ok_r)
        j = dr.arange(mi.UInt32, 2 * m)  # item j: parent j // 2, child kind j % 2
        parent = j >> 1
        is_t = (j & 1) == 1
        want = dr.select(is_t, dr.gather(mi.Bool, ok_t, parent), dr.gather(mi.Bool, ok_r, parent))
        sel = dr.compress(want)
        if dr.width(sel) == 0:
            break
        parent, is_t = sel >> 1, (sel & 1) == 1
        ray = _gather_child(ray_r, ray_t, parent, is_t)
        pos = 2 * dr.gather(mi.UInt32, pos, parent) + mi.UInt32(is_t)
        idx = dr.gather(mi.UInt32, idx, parent)
    while len(levels) < max_depth - 1:
        levels.append((dr.zeros(mi.UInt64, n), dr.zeros(mi.UInt64, n)))
    trees = Trees(mix64(total), root_obj, root_lights, tuple(levels))
    if record:
        trees.nodes = _collect(rec, lights.words)
    return trees


def _collect(rec: list[tuple[Any, ...]], nwords: int) -> Nodes:
    parts: dict[str, list[np.ndarray]] = {"ray": [], "pos": [], "obj": [], "lights": []}
    for idx, pos, valid, obj, words in rec:
        v = np.asarray(valid.numpy(), dtype=bool)
        parts["ray"].append(np.asarray(idx.numpy())[v])
        parts["pos"].append(np.asarray(pos.numpy())[v])
        parts["obj"].append(np.asarray(obj.numpy())[v])
        w = np.stack([np.asarray(x.numpy()) for x in words], axis=-1).reshape(-1, nwords)
        parts["lights"].append(w[v])
    return Nodes(
        *(np.concatenate(parts[k]).astype(np.uint32) for k in ("ray", "pos", "obj")),
        np.concatenate(parts["lights"]).astype(np.uint32).reshape(-1, nwords),
    )
