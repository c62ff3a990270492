"""Object ids: exact per pixel, stable under shape reordering, never blended by the film."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr

SHAPES = [
    '<shape type="sphere" id="ball"><point name="center" x="0.5" y="0" z="4"/>'
    '<float name="radius" value="0.8"/></shape>',
    '<shape type="cube" id="box"><transform name="to_world"><scale value="0.6"/>'
    '<translate x="-0.7" y="0.2" z="5"/></transform></shape>',
    '<shape type="rectangle"><transform name="to_world"><scale value="4"/>'
    '<translate z="7"/></transform></shape>',  # no id: gets a deterministic name
    '<shape type="rectangle"><transform name="to_world"><scale value="0.3"/>'
    '<translate x="1.5" y="1" z="6"/></transform></shape>',
]


def brute_force_ids(path, names):
    """Per pixel centre, intersect each shape in a scene of its own and keep the nearest: an
    oracle that uses neither the full scene's shape order nor mi-npr's lookup table. It loads its
    own copy of the scene: ``load_dict`` renames the shapes it is given (their id becomes
    "only"), so the caller's scene must not be touched."""
    mi = mi_npr.mi
    scene = mi_npr.load_scene(path)
    copy = mi_npr.object_table(scene)  # names only: the lookup table is not used
    assert copy.names == names
    sensor = scene.sensors()[0]
    w, h = sensor.film().crop_size()
    ys, xs = np.mgrid[0:h, 0:w]
    pos = mi.Point2f(mi.Float((xs.ravel() + 0.5) / w), mi.Float((ys.ravel() + 0.5) / h))
    ray, _ = sensor.sample_ray(0.5, 0.5, pos, mi.Point2f(0.5))
    best_t = np.full(w * h, np.inf)
    best = np.zeros(w * h, np.uint32)
    for oid, shape in copy.shapes.items():
        alone = mi.load_dict({"type": "scene", "only": shape})
        pi = alone.ray_intersect_preliminary(ray)
        t = np.where(pi.is_valid().numpy(), pi.t.numpy(), np.inf)
        closer = t < best_t
        best_t[closer], best[closer] = t[closer], oid
    return best.reshape(h, w)


@pytest.mark.parametrize(("spp", "rfilter"), [(1, "box"), (16, "gaussian")])
def test01_ids_equal_brute_force_whatever_the_film(write_scene, spp, rfilter):
    path = write_scene(
        "".join(SHAPES),
        width=48,
        height=36,
        spp=spp,
        rfilter=rfilter,
        integrator='<integrator type="npr_gbuffer"><integrator type="path"/></integrator>',
    )
    scene = mi_npr.load_scene(path)
    gb = mi_npr.render(scene)
    np.testing.assert_array_equal(gb.numpy("object_id.V"), brute_force_ids(path, gb.objects))
    assert set(np.unique(gb.numpy("object_id.V"))) <= {0, *gb.objects}
    # The tensor Mitsuba's own mi.render returns holds the same exact integers.
    img = np.asarray(mi_npr.mi.render(scene).numpy())
    names = ["R", "G", "B", *scene.integrator().aov_names()]
    ids = img[..., names.index("object_id.V")]
    np.testing.assert_array_equal(ids, gb.numpy("object_id.V").astype(np.float32))


def test02_same_ids_when_the_xml_order_changes(write_scene):
    a = mi_npr.render(write_scene("".join(SHAPES), name="a.xml"))
    b = mi_npr.render(write_scene("".join(reversed(SHAPES)), name="b.xml"))
    c = mi_npr.render(write_scene("".join(SHAPES[2:] + SHAPES[:2]), name="c.xml"))
    assert a.objects == b.objects == c.objects
    assert list(a.objects.values()) == sorted(a.objects.values())
    assert {"ball", "box"} <= set(a.objects.values())
    unnamed = [n for n in a.objects.values() if n.startswith("rectangle_")]
    assert len(unnamed) == 2
    np.testing.assert_array_equal(a["object_id.V"], b["object_id.V"])
    np.testing.assert_array_equal(a["object_id.V"], c["object_id.V"])


def test03_identical_unnamed_shapes_get_distinct_names(write_scene):
    twin = '<shape type="sphere"><point name="center" x="0" y="0" z="4"/></shape>'
    gb = mi_npr.render(write_scene(twin + twin))
    names = list(gb.objects.values())
    assert len(names) == 2 and len(set(names)) == 2


def test04_prim_id_is_the_triangle_index(write_scene):
    mi = mi_npr.mi
    body = (
        '<shape type="ply" id="mesh"><string name="filename" value="{}"/>'
        '<transform name="to_world"><translate z="4"/></transform></shape>'
    )
    from mi_npr.meshes import uv_sphere, write_ply

    ply = write_ply(write_scene("", name="unused.xml").parent / "s.ply", *uv_sphere(12, 8))
    scene = mi_npr.load_scene(write_scene(body.format(ply), width=40, height=30))
    gb = mi_npr.render(scene)
    hit = gb.numpy("object_id.V") > 0
    prims = np.unique(gb.numpy("prim_id.V")[hit])
    assert len(prims) > 20 and prims.max() < 2 * 12 * 7
    # The hit triangle really contains the hit point (barycentric test on the mesh data).
    mesh = scene.shapes()[0]
    V = mi.traverse(mesh)["vertex_positions"].numpy().reshape(-1, 3)
    F = mi.traverse(mesh)["faces"].numpy().reshape(-1, 3)
    P = gb.positions[hit]
    tri = V[F[gb.numpy("prim_id.V")[hit]]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    dist = np.abs(np.einsum("ij,ij->i", P - tri[:, 0], n)) / np.linalg.norm(n, axis=1)
    assert dist.max() < 1e-4
