"""The paper's scenes (Fig. 9, Fig. 10): what their contours must show."""

from __future__ import annotations

import numpy as np

import mi_npr
from mi_npr.contours import contour_mask, mode_ids, overlay, trace, trace_scene

from .helpers import SCENES

SMALL = dict(width=96, height=72, spp=1)


def test01_scene1_and_scene2_same_contours():
    """Contours come from the scene, not the image: reflections/refractions change nothing."""
    one = mi_npr.render(SCENES / "scene1.xml", integrator="npr_contours", **SMALL)
    two = mi_npr.render(SCENES / "scene2.xml", integrator="npr_contours", **SMALL)
    np.testing.assert_array_equal(one.numpy("contour.V"), two.numpy("contour.V"))
    assert not np.array_equal(one.beauty, two.beauty)
    a, b = trace(one), trace(two)
    assert len(a) == len(b) and all(x == y for x, y in zip(a, b, strict=True))


def test02_fig9_three_id_modes():
    scene = mi_npr.load_scene(SCENES / "fig9_sphere_cube.xml", **SMALL)
    gb = mi_npr.render(scene)
    found = {}
    masks = {}
    for mode in ("shape", "component", "primitive"):
        ids, names = mode_ids(gb, scene, mode)
        found[mode] = trace(ids, objects=names)
        masks[mode] = contour_mask(ids)
        rays, _ = trace_scene(scene, id_mode=mode)
        assert len(rays) == len(found[mode])
        assert all(x == y for x, y in zip(rays, found[mode], strict=True))
    assert {c.name for c in found["shape"]} == {"floor", "sphere_mesh"}
    # From outside, first hits see the sphere only: components name it, the cube has no pixels.
    assert {c.name for c in found["component"]} == {"floor", "sphere_mesh#0"}
    # Per primitive, every visible triangle is outlined (Fig. 9 b/c).
    prim = {c.name for c in found["primitive"]}
    assert len(prim) > 50 and all(n.startswith(("sphere_mesh/", "floor/")) for n in prim)
    # Finer objects only add contour pixels.
    assert not (masks["shape"] & ~masks["component"]).any()
    assert not (masks["component"] & ~masks["primitive"]).any()
    assert masks["primitive"].sum() > 3 * masks["shape"].sum()


def test03_scene3_gap_and_hidden_objects():
    gb = mi_npr.render(SCENES / "scene3.xml", **SMALL)
    names = {c.name for c in trace(gb)}
    assert "cube_in_gap" in names and "sphere_hidden" not in names
    assert {"box_front_left", "box_front_right", "sphere_behind", "cylinder_behind"} <= names


def test04_scene4_intersections_are_contours():
    """Where objects interpenetrate, the crease is a contour, drawn on one side."""
    gb = mi_npr.render(SCENES / "scene4.xml", **SMALL)
    out, contours = overlay(gb)
    ids, layer = gb.object_id, out.numpy("contour.V")
    a, b = gb.find_object("sphere_in_box"), gb.find_object("box_a")
    touching = (ids[:, :-1] == a) & (ids[:, 1:] == b) | (ids[:, :-1] == b) & (ids[:, 1:] == a)
    assert touching.any()
    ys, xs = np.nonzero(touching)
    left, right = layer[ys, xs] == ids[ys, xs], layer[ys, xs + 1] == ids[ys, xs + 1]
    assert np.all(left | right) and not np.all(left & right)
    assert {c.name for c in contours} >= {"slab", "sphere_cut", "cylinder_through_box", "box_b"}
