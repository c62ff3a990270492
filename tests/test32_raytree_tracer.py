"""The wavefront ray-tree tracer against a one-ray-at-a-time recursive reference (scalar_rgb
variant, written here from the rules of mi_npr.raytree.tracer/lights), hand-checked signatures in
the paper's notation, and the 64-bit hash: equal exactly when the strings are equal."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.raycast import pixel_rays
from mi_npr.raytree import light_table, raytree_layers, signature, signatures, trace_trees
from mi_npr.raytree.signature import format_signature

from .test30_raytree_signature import tree_hash_ref

# Every kind of light, a mirror, a glass sphere (TIR inside it), diffuse objects, an area light
# on a sphere (its centre is inside it) and one on a rectangle, a one-sided mirror's back, and an
# instanced mirror ball (its object's BSDF is the instanced shape's).
MIXED = """
<shape type="sphere" id="glass"><point name="center" x="0.9" y="0" z="5"/>
    <float name="radius" value="0.9"/><bsdf type="dielectric"/></shape>
<shape type="sphere" id="ball"><point name="center" x="-1.1" y="-0.3" z="4.5"/>
    <float name="radius" value="0.7"/><bsdf type="diffuse"/></shape>
<shape type="rectangle" id="mirror"><transform name="to_world"><rotate y="1" angle="200"/>
    <scale value="2.5"/><translate z="8"/></transform><bsdf type="conductor"/></shape>
<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>
    <scale value="8"/><translate y="-1"/></transform><bsdf type="diffuse"/></shape>
<shape type="rectangle" id="tilted"><transform name="to_world"><rotate x="1" angle="50"/>
    <translate x="-2" y="1.2" z="6"/></transform><bsdf type="conductor"/></shape>
<shape type="sphere" id="bulb"><point name="center" x="2" y="1.6" z="6"/>
    <float name="radius" value="0.25"/><emitter type="area"/></shape>
<shape type="rectangle" id="panel"><transform name="to_world"><rotate x="1" angle="90"/>
    <scale value="0.5"/><translate x="-1" y="2.5" z="3"/></transform><emitter type="area"/></shape>
<shape type="shapegroup" id="group"><shape type="sphere"><float name="radius" value="0.4"/>
    <bsdf type="conductor"/></shape></shape>
<shape type="instance" id="instanced_mirror_ball"><ref id="group"/>
    <transform name="to_world"><translate x="-0.3" y="0.4" z="3.5"/></transform></shape>
<emitter type="point" id="key"><point name="position" x="-3" y="4" z="1"/></emitter>
<emitter type="spot" id="spot"><transform name="to_world"><lookat origin="1,3,2" target="1,-1,6"/>
    </transform><float name="cutoff_angle" value="15"/></emitter>
<emitter type="directional" id="sun"><vector name="direction" x="1" y="-1" z="0.5"/></emitter>
<emitter type="constant" id="sky"/>
"""
PATH = '<integrator type="path"/>'


def _numpy(layers):
    """The ray-tree layers (Dr.Jit tensors) as numpy arrays, for the references."""
    return {k: np.asarray(v) for k, v in layers.items()}


# ----------------------------------------------------------------------------- reference
def _visible_ref(mi, scene, si, ray_d, obj, lt, table) -> list[int]:
    import drjit as dr

    words = [0] * lt.words
    n = si.n
    eye = dr.dot(n, -ray_d)
    for k, e in lt.emitters.items():
        kind = lt.kinds[k]
        if kind in ("environment", "direction"):
            if kind == "environment":  # the zenith of the sky: +y of the emitter's frame
                up = e.world_transform() @ mi.Vector3f(0, 1, 0)
                d = up / dr.norm(up)
            else:
                d = e.sample_direction(si, mi.Point2f(0.5, 0.5))[0].d
            ok = dr.dot(n, d) * eye > 0 and not scene.ray_test(si.spawn_ray(d))
        elif kind == "area":
            bb = e.get_shape().bbox()
            c = (bb.min + bb.max) * 0.5
            if obj == lt.shape_ids[k]:
                ok = True
            elif dr.dot(n, c - si.p) * eye > 0:
                pi = scene.ray_intersect_preliminary(si.spawn_ray_to(c))
                ok = (not pi.is_valid()) or table.lookup(pi) == lt.shape_ids[k]
            else:
                ok = False
        else:
            ds, w = e.sample_direction(si, mi.Point2f(0.5, 0.5))
            ok = (
                dr.max(w) > 0
                and dr.dot(n, ds.d) * eye > 0
                and not scene.ray_test(si.spawn_ray_to(ds.p))
            )
        if ok:
            words[(k - 1) // 32] |= 1 << ((k - 1) % 32)
    return words


class _NamedTable:
    """The reference's own object numbering in scalar_rgb (mi-npr's ObjectTable is JIT-only):
    every shape by its XML id, numbered like the given id -> name table."""

    def __init__(self, scene, names):
        by_name = {v: k for k, v in names.items()}
        self.names = dict(names)
        self.shapes = {by_name[s.id()]: s for s in scene.shapes()}
        self._ptr = {s.ptr: k for k, s in self.shapes.items()}

    def lookup(self, si):
        if not si.is_valid():
            return 0
        obj = si.instance if si.instance is not None else si.shape
        return self._ptr.get(obj.ptr, 0)


def reference_trees(path, xs, ys, max_depth) -> list[dict]:
    """Trees of the rays through film positions (xs, ys), one ray at a time, recursively."""
    names = mi_npr.object_table(mi_npr.load_scene(path)).names  # ids to compare with
    mi_npr.set_variant("scalar_rgb")
    mi = mi_npr.mi
    scene = mi_npr.load_scene(path)
    table = _NamedTable(scene, names)
    lt = light_table(scene, table)
    sensor = scene.sensors()[0]

    def grow(ray, pos, depth, tree):
        si = scene.ray_intersect(ray)
        if not si.is_valid():
            return
        obj = int(table.lookup(si))
        tree[pos] = (obj, tuple(_visible_ref(mi, scene, si, ray.d, obj, lt, table)))
        if depth + 1 >= max_depth:
            return
        bsdf = si.bsdf()
        F = mi.BSDFFlags
        refr = int(F.DeltaTransmission) | int(F.Null)  # Null: thin glass goes straight through
        for lobe, child in ((int(F.DeltaReflection), 2 * pos), (refr, 2 * pos + 1)):
            ctx = mi.BSDFContext()
            ctx.type_mask = lobe
            bs, w = bsdf.sample(ctx, si, 0.5, mi.Point2f(0.5, 0.5))
            if bs.pdf > 0 and max(w) > 0 and int(bs.sampled_type) & lobe:
                grow(si.spawn_ray(si.to_world(bs.wo)), child, depth + 1, tree)

    out = []
    for x, y in zip(xs, ys, strict=True):
        tree: dict = {}
        grow(pixel_rays(sensor, float(x), float(y)), 1, 0, tree)
        out.append(tree)
    mi_npr.set_variant("llvm_ad_rgb")
    return out


def vector_trees(path, xs, ys, max_depth) -> list[dict]:
    mi = mi_npr.mi
    scene = mi_npr.load_scene(path)
    table = mi_npr.object_table(scene)
    rays = pixel_rays(scene.sensors()[0], mi.Float(xs), mi.Float(ys))
    trees = trace_trees(scene, rays, table, light_table(scene, table), max_depth, record=True)
    return [trees.nodes.of_ray(i) for i in range(len(xs))]


@pytest.mark.parametrize("max_depth", [1, 3, 5])
def test01_wavefront_equals_recursive_reference(write_scene, max_depth):
    w, h = 28, 20
    path = write_scene(MIXED, width=w, height=h, fov=60, origin="0, 0.3, 0", integrator=PATH)
    ys, xs = np.mgrid[0:h, 0:w]
    xs, ys = (xs.ravel() + 0.5).astype(np.float32), (ys.ravel() + 0.5).astype(np.float32)
    ref = reference_trees(path, xs, ys, max_depth)
    got = vector_trees(path, xs, ys, max_depth)
    bad = [i for i in range(len(xs)) if got[i] != ref[i]]
    assert not bad, [(i, got[i], ref[i]) for i in bad[:3]]
    depths = {int(np.log2(p)) for t in got for p in t}
    assert depths == set(range(max_depth))  # every level is exercised
    lights = {k for t in got for _, w_ in t.values() for k in range(32) if w_[0] >> k & 1}
    assert lights == set(range(6))  # each of the six lights is seen somewhere


# ----------------------------------------------------------------------------- hand checks
# Fig. 5, tree a: the camera sees mirror "c_first" (C), which reflects to mirror "b_second" (B),
# which sees the light and reflects to the diffuse "a_third" (A), behind which the light is.
FIG5A = """
<shape type="rectangle" id="c_first"><transform name="to_world"><rotate y="1" angle="-135"/>
    <translate z="5"/></transform><bsdf type="conductor"/></shape>
<shape type="rectangle" id="b_second"><transform name="to_world"><rotate y="1" angle="135"/>
    <translate x="-5" z="5"/></transform><bsdf type="conductor"/></shape>
<shape type="rectangle" id="a_third"><transform name="to_world"><scale value="2"/>
    <translate x="-5"/></transform><bsdf type="diffuse"/></shape>
<emitter type="point" id="light"><point name="position" x="8" y="0" z="-1"/></emitter>
"""
# Tree b: two thin glass panes C and B in a row and a diffuse A behind them; the light sits
# between the panes, in front of B only; B is turned so its reflection leaves the scene.
FIG5B = """
<shape type="rectangle" id="c_first"><transform name="to_world"><rotate y="1" angle="180"/>
    <scale value="3"/><translate z="3"/></transform><bsdf type="thindielectric"/></shape>
<shape type="rectangle" id="b_second"><transform name="to_world"><rotate y="1" angle="150"/>
    <scale value="3"/><translate z="6"/></transform><bsdf type="thindielectric"/></shape>
<shape type="rectangle" id="a_third"><transform name="to_world"><rotate y="1" angle="180"/>
    <scale value="6"/><translate z="9"/></transform><bsdf type="diffuse"/></shape>
<emitter type="point" id="light"><point name="position" x="0" y="2" z="4.5"/></emitter>
"""


def test02_the_papers_trees_a_and_b(write_scene):
    a = write_scene(FIG5A, width=9, height=9, fov=10, name="a.xml")
    assert signature(a, 4, 4) == "4A2BL1C"
    b = write_scene(FIG5B, width=9, height=9, fov=10, name="b.xml")
    assert signature(b, 4, 4) == "7A3BL1C"
    assert signature(b, 4, 4, max_depth=2) == "3BL1C"
    assert signature(b, 4, 4, max_depth=1) == "C"


def test03_simple_pixels_and_arguments(write_scene):
    body = (
        '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="5"/></shape>'
        '<emitter type="point" id="lamp"><point name="position" x="0" y="0" z="0"/></emitter>'
    )
    path = write_scene(body, width=16, height=12, fov=30)
    assert signature(path, 8, 6) == "AL1"  # lit by the light at the eye
    assert signature(path, 0, 0) == ""  # nothing hit
    for x, y in ((16, 0), (-1, 0), (0, 12), (1.5, 2)):
        with pytest.raises(mi_npr.ParameterError):
            signature(path, x, y)
    with pytest.raises(mi_npr.ParameterError, match="max_depth"):
        signature(path, 1, 1, max_depth=0)
    s = signatures(path)
    assert s.shape == (12, 16) and s[6, 8] == "AL1" and s[0, 0] == ""
    c = signatures(path, corners=True)
    assert c.shape == (13, 17) and c[0, 0] == ""


# ----------------------------------------------------------------------------- the hash
def _hash_layers(path):
    scene = mi_npr.load_scene(path)
    lay = _numpy(raytree_layers(scene, 0, 3, shadow_lights="all"))
    return (lay[L.RAYTREE_HI].astype(np.uint64) << np.uint64(32)) | lay[L.RAYTREE_LO]


def test04_hash_equal_iff_strings_equal_on_every_pixel(write_scene):
    path = write_scene(MIXED, width=40, height=30, fov=60, origin="0, 0.3, 0", target="0, 0, 1")
    h = _hash_layers(path).ravel()
    s = signatures(path, max_depth=3, shadow_lights="all").ravel()
    groups_s = {}
    groups_h = {}
    for i, (hv, sv) in enumerate(zip(h.tolist(), s.tolist(), strict=True)):
        groups_s.setdefault(sv, set()).add(i)
        groups_h.setdefault(hv, set()).add(i)
    assert sorted(map(sorted, groups_s.values())) == sorted(map(sorted, groups_h.values()))
    assert len(groups_s) > 30  # a scene with many different trees
    # and the hash is the documented function of the nodes (numpy reference)
    mi = mi_npr.mi
    scene = mi_npr.load_scene(path)
    table = mi_npr.object_table(scene)
    ys, xs = np.mgrid[0:30, 0:40]
    rays = pixel_rays(scene.sensors()[0], mi.Float(xs.ravel() + 0.5), mi.Float(ys.ravel() + 0.5))
    nodes = trace_trees(scene, rays, table, light_table(scene, table), 3, record=True).nodes
    for i in range(0, 1200, 7):
        tree = nodes.of_ray(i)
        assert tree_hash_ref(tree) == int(h[i])
        assert format_signature(tree) == s[i]
    assert int(h[s == ""][0]) == 0  # the background's empty tree hashes to 0
