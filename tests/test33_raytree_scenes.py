"""Known answers of the edge classes on small scenes: diffuse (real edges only, equal to the ID
edges of the corner grid), a sphere before a mirror (reflection edges only inside the mirror), a
sphere's shadow on a floor (an analytic oracle), a glass sphere before a checkerboard
(refraction edges inside the sphere), and the paper's scenes 1 and 2 (the same real edges)."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.raycast import pixel_rays
from mi_npr.raytree import raytree_layers

LAMP_AT_EYE = '<emitter type="point" id="lamp"><point name="position" x="0" y="0" z="0"/></emitter>'


def _numpy(layers):
    """The ray-tree layers (Dr.Jit tensors) as numpy arrays, for the references."""
    return {k: np.asarray(v) for k, v in layers.items()}


def corner_rays(scene):
    mi = mi_npr.mi
    sensor = scene.sensors()[0]
    w, h = (int(v) for v in sensor.film().crop_size())
    ys, xs = np.mgrid[0 : h + 1, 0 : w + 1]
    f = mi.Float
    return pixel_rays(sensor, f(xs.ravel().astype(np.float32)), f(ys.ravel().astype(np.float32)))


def corner_ids(scene) -> np.ndarray:
    """Object id of every corner ray: each shape intersected in a scene of its own, the nearest
    kept (neither the full scene's BVH nor mi-npr's lookup table). Putting a shape in another
    scene renames it (its id becomes the dict key), so ``scene`` is not to be used afterwards."""
    mi = mi_npr.mi
    table = mi_npr.object_table(scene)
    w, h = (int(v) for v in scene.sensors()[0].film().crop_size())
    ray = corner_rays(scene)
    best_t = np.full((h + 1) * (w + 1), np.inf)
    best = np.zeros((h + 1) * (w + 1), np.uint32)
    for oid, shape in table.shapes.items():
        pi = mi.load_dict({"type": "scene", "only": shape}).ray_intersect_preliminary(ray)
        t = np.where(pi.is_valid().numpy(), pi.t.numpy(), np.inf)
        closer = t < best_t
        best_t[closer], best[closer] = t[closer], oid
    return best.reshape(h + 1, w + 1)


def differs(a: np.ndarray) -> np.ndarray:
    """Pixels whose four corners are not all equal (a: (H + 1, W + 1))."""
    c = a[:-1, :-1]
    return (c != a[:-1, 1:]) | (c != a[1:, :-1]) | (c != a[1:, 1:])


def all_corners_are(ids: np.ndarray, oid: int) -> np.ndarray:
    return (
        (ids[:-1, :-1] == oid)
        & (ids[:-1, 1:] == oid)
        & (ids[1:, :-1] == oid)
        & (ids[1:, 1:] == oid)
    )


def layers_of(write_scene, body, name="scene.xml", **kw):
    scene = mi_npr.load_scene(write_scene(body, name=name, **kw))
    return scene, _numpy(raytree_layers(scene, 0, 3))


# ----------------------------------------------------------------------------- diffuse
DIFFUSE = (
    '<shape type="sphere" id="ball"><point name="center" x="0.6" y="0.1" z="5"/>'
    '<float name="radius" value="0.9"/><bsdf type="diffuse"/></shape>'
    '<shape type="cube" id="box"><transform name="to_world"><rotate y="1" angle="30"/>'
    '<scale value="0.6"/><translate x="-1" y="-0.4" z="6"/></transform><bsdf type="diffuse"/>'
    "</shape>"
    '<shape type="rectangle" id="wall"><transform name="to_world"><scale value="3"/>'
    '<translate z="8"/></transform><bsdf type="diffuse"/></shape>' + LAMP_AT_EYE
)


@pytest.mark.parametrize(("w", "h"), [(40, 30), (1, 1), (17, 9)])
def test01_diffuse_scene_lit_from_the_eye_has_only_real_edges(write_scene, w, h):
    scene, lay = layers_of(write_scene, DIFFUSE, width=w, height=h, fov=50)
    expected = differs(corner_ids(scene)).astype(np.float32)
    np.testing.assert_array_equal(lay[L.EDGES_REAL], expected)
    for name in (L.EDGES_REFLECTION, L.EDGES_REFRACTION, L.EDGES_SHADOW):
        assert not lay[name].any(), name
    if w > 1:
        assert expected.sum() > 20


def test02_empty_scene_and_a_flat_wall_have_no_edges(write_scene):
    _, lay = layers_of(write_scene, LAMP_AT_EYE, width=9, height=7)
    assert all(not lay[k].any() for k in L.EDGES)
    assert not lay[L.RAYTREE_HI].any() and not lay[L.RAYTREE_LO].any()  # empty trees: 0
    wall = '<shape type="rectangle"><transform name="to_world"><scale value="50"/>'
    wall += '<translate z="5"/></transform></shape>'
    _, lay = layers_of(write_scene, wall + LAMP_AT_EYE, name="wall.xml", width=9, height=7)
    assert all(not lay[k].any() for k in L.EDGES)
    hashes = set(zip(lay[L.RAYTREE_HI].ravel(), lay[L.RAYTREE_LO].ravel(), strict=True))
    assert len(hashes) == 1 and hashes != {(0, 0)}  # one tree everywhere


# ----------------------------------------------------------------------------- mirror
MIRROR = (
    '<shape type="sphere" id="ball"><point name="center" x="1.2" y="0" z="6"/>'
    '<float name="radius" value="0.6"/><bsdf type="diffuse"/></shape>'
    '<shape type="rectangle" id="mirror"><transform name="to_world">'
    '<rotate y="1" angle="155"/><scale value="3"/><translate z="8"/></transform>'
    '<bsdf type="{}"/></shape>' + LAMP_AT_EYE
)


def test03_sphere_before_a_mirror_reflects_inside_the_mirror_only(write_scene):
    kw = {"width": 48, "height": 36, "fov": 50}
    scene, mirror = layers_of(write_scene, MIRROR.format("conductor"), "m.xml", **kw)
    _, plane = layers_of(write_scene, MIRROR.format("diffuse"), "p.xml", **kw)
    mirror_id = mi_npr.object_table(scene).id_of("mirror")
    ids = corner_ids(scene)
    refl = mirror[L.EDGES_REFLECTION] > 0
    assert refl.sum() > 10  # the sphere's reflection is outlined ...
    assert np.all(all_corners_are(ids, mirror_id)[refl])  # ... inside the mirror only
    np.testing.assert_array_equal(mirror[L.EDGES_REAL], plane[L.EDGES_REAL])
    np.testing.assert_array_equal(mirror[L.EDGES_REAL], differs(ids).astype(np.float32))
    for lay in (mirror, plane):
        assert not lay[L.EDGES_SHADOW].any() and not lay[L.EDGES_REFRACTION].any()
    assert not plane[L.EDGES_REFLECTION].any()


# ----------------------------------------------------------------------------- shadow
CENTRE, RADIUS, LIGHT = np.array([0.0, 1.0, 2.0]), 1.0, np.array([2.5, 6.0, -1.0])
SHADOW = (
    f'<shape type="sphere" id="ball"><point name="center" x="{CENTRE[0]}" y="{CENTRE[1]}" '
    f'z="{CENTRE[2]}"/><float name="radius" value="{RADIUS}"/><bsdf type="diffuse"/></shape>'
    '<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>'
    '<scale value="10"/></transform><bsdf type="diffuse"/></shape>'
    f'<emitter type="point" id="lamp"><point name="position" x="{LIGHT[0]}" y="{LIGHT[1]}" '
    f'z="{LIGHT[2]}"/></emitter>'
)


def _sphere_t(o, d, c, r):
    oc = o - c
    b = np.sum(oc * d, -1)
    disc = b * b - (np.sum(oc * oc, -1) - r * r)
    sq = np.sqrt(np.maximum(disc, 0.0))
    t = np.where(-b - sq > 1e-6, -b - sq, np.where(-b + sq > 1e-6, -b + sq, np.inf))
    return np.where(disc >= 0, t, np.inf)


def analytic_corners(scene):
    """Object (0 none, 1 ball, 2 floor) and lamp visibility of every corner ray, in float64:
    ray-sphere and ray-plane intersections, the side test and the sphere as the occluder."""
    w, h = (int(v) for v in scene.sensors()[0].film().crop_size())
    ray = corner_rays(scene)
    o = np.stack([np.asarray(ray.o[i].numpy(), np.float64) for i in range(3)], -1)
    d = np.stack([np.asarray(ray.d[i].numpy(), np.float64) for i in range(3)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    ts = _sphere_t(o, d, CENTRE, RADIUS)
    with np.errstate(divide="ignore"):
        tf = np.where(d[:, 1] < 0, -o[:, 1] / d[:, 1], np.inf)
    pf = o + np.where(np.isfinite(tf), tf, 0)[:, None] * d
    tf = np.where((np.abs(pf[:, 0]) <= 10) & (np.abs(pf[:, 2]) <= 10), tf, np.inf)
    obj = np.where(ts < tf, 1, np.where(np.isfinite(tf), 2, 0))
    t = np.minimum(ts, tf)
    p = o + np.where(np.isfinite(t), t, 0)[:, None] * d
    n = np.where((obj == 1)[:, None], (p - CENTRE) / RADIUS, np.array([0.0, 1.0, 0.0]))
    to_light = LIGHT - p
    dist = np.linalg.norm(to_light, axis=-1)
    side = np.sum(n * to_light, -1) * np.sum(-n * d, -1) > 0
    blocked = _sphere_t(p + 1e-4 * n, to_light / dist[:, None], CENTRE, RADIUS) < dist
    lit = side & ~blocked & (obj > 0)
    return obj.reshape(h + 1, w + 1), lit.reshape(h + 1, w + 1)


def test04_sphere_shadow_on_a_floor_is_outlined_and_nothing_else(write_scene):
    kw = {"width": 48, "height": 36, "fov": 50, "origin": "0, 3, -4", "target": "0, 0.5, 2"}
    scene, lay = layers_of(write_scene, SHADOW, **kw)
    obj, lit = analytic_corners(scene)
    real = differs(obj)
    shadow = ~real & differs(lit)
    np.testing.assert_array_equal(lay[L.EDGES_REAL], real.astype(np.float32))
    np.testing.assert_array_equal(lay[L.EDGES_SHADOW], shadow.astype(np.float32))
    on_floor = all_corners_are(obj, 2)
    assert (shadow & on_floor).sum() > 20  # the cast shadow's outline on the floor
    assert not lay[L.EDGES_REFLECTION].any() and not lay[L.EDGES_REFRACTION].any()


# ----------------------------------------------------------------------------- glass
# Squares that touch: no corner ray may pass exactly through a shared border (ties).
SQUARES = "".join(
    f'<shape type="rectangle" id="sq_{i}{j}"><transform name="to_world"><scale value="0.5"/>'
    f'<translate x="{i - 2.37}" y="{j - 2.43}" z="9"/></transform><bsdf type="diffuse"/></shape>'
    for i in range(6)
    for j in range(6)
)
GLASS = (
    '<shape type="sphere" id="glass"><point name="center" x="0" y="0" z="5"/>'
    '<float name="radius" value="1.2"/><bsdf type="dielectric"/></shape>' + SQUARES + LAMP_AT_EYE
)


def test05_glass_sphere_refracts_the_checkerboard_inside_its_outline(write_scene):
    scene, lay = layers_of(write_scene, GLASS, width=48, height=36, fov=50)
    glass = mi_npr.object_table(scene).id_of("glass")
    ids = corner_ids(scene)
    inside = all_corners_are(ids, glass)
    refr = lay[L.EDGES_REFRACTION] > 0
    assert refr.sum() > 30 and np.all(inside[refr])
    assert np.all(inside[lay[L.EDGES_REFLECTION] > 0])
    np.testing.assert_array_equal(lay[L.EDGES_REAL], differs(ids).astype(np.float32))
    assert not lay[L.EDGES_SHADOW].any()
    # the squares' borders outside the sphere are real edges
    assert lay[L.EDGES_REAL][~inside].sum() > 100


# ----------------------------------------------------------------------------- paper scenes
def test06_scene1_and_scene2_have_the_same_real_edges(scenes):
    out = {}
    for name in ("scene1", "scene2"):
        scene = mi_npr.load_scene(scenes / f"{name}.xml", width=64, height=48, spp=1)
        out[name] = _numpy(raytree_layers(scene, 0, 3))
    np.testing.assert_array_equal(out["scene1"][L.EDGES_REAL], out["scene2"][L.EDGES_REAL])
    assert out["scene1"][L.EDGES_REAL].sum() > 50
    # scene 1's glass and mirror make reflection and refraction edges; scene 2 has none
    assert out["scene1"][L.EDGES_REFLECTION].any() and out["scene1"][L.EDGES_REFRACTION].any()
    assert not out["scene2"][L.EDGES_REFLECTION].any()
    assert not out["scene2"][L.EDGES_REFRACTION].any()
    total = sum(out["scene1"][k] for k in L.EDGES)
    assert total.max() == 1  # one class per pixel


def test07_the_mirror_glass_scene_shows_every_class(scenes):
    scene = mi_npr.load_scene(scenes / "raytree_mirror_glass.xml", width=80, height=60, spp=1)
    assert scene.integrator().aov_names()[:2] == [L.RAYTREE_HI, L.RAYTREE_LO]
    lay = _numpy(raytree_layers(scene, 0, 3))
    for name in L.EDGES:
        assert lay[name].sum() > 5, name
