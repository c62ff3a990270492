"""Ray-cast mode: selective refinement + following equals buffer mode, casting each pixel once."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.contours import trace, trace_scene
from mi_npr.contours.refine import BufferCaster, refine, run

from .helpers import SCENES


def buffer_contours(scene, id_mode="shape", method="border"):
    gb = mi_npr.render(scene)
    ids, names = mi_npr.contours.mode_ids(gb, scene, id_mode)
    return trace(ids, objects=names, method=method)


def assert_same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x == y, (x, y)


# ----------------------------------------------------------------------------- without a scene
def test01_refinement_corners_and_split_blocks():
    ids = np.zeros((17, 17), np.uint32)
    c = BufferCaster(ids)
    refine(c, 8)
    # Nothing differs: only the shared corners of the 8x8 macro pixels are cast.
    assert c.stats.rays_cast == 9 and c.stats.launches == 1
    np.testing.assert_array_equal(np.argwhere(c.grid.known.reshape(19, 19)[1:-1, 1:-1]) % 8, 0)
    ids[5, 5] = 1  # inside macro pixel (0, 0), on no corner: not found by refinement alone
    c = BufferCaster(ids)
    refine(c, 8)
    assert c.stats.rays_cast == 9
    ids[0, 0] = 2  # a corner differs: its macro pixels split down to 2x2 blocks
    c = BufferCaster(ids)
    refine(c, 8)
    known = c.grid.known.reshape(19, 19)[1:-1, 1:-1]
    assert known[0:2, 0:2].all() and c.stats.launches == 4  # one batch per level


def test02_odd_sizes_and_tiny_images():
    for h, w in [(1, 1), (1, 9), (9, 1), (2, 3), (10, 11), (33, 17)]:
        rng = np.random.default_rng(h * 100 + w)
        ids = rng.integers(0, 3, (h, w)).astype(np.uint32)
        contours, stats = run(BufferCaster(ids), None)
        assert_same(contours, trace(ids))
        assert stats.rays_cast == stats.cast.sum() <= h * w


@pytest.mark.parametrize("seed", range(6))
def test03_found_contours_are_exact(seed):
    """Every contour found on a partial map is the buffer-mode contour, whole; big blobs are
    always found; what is missed is small and never touches a found contour."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(20, 70, 2))
    yy, xx = np.mgrid[0:h, 0:w]
    ids = np.zeros((h, w), np.uint32)
    for k in range(1, 7):
        cy, cx, r = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(0.5, 14)
        ids[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = k
    ref = trace(ids)
    got, stats = run(BufferCaster(ids), None)
    for c in got:
        assert any(c == r for r in ref)
    found = {(c.object_id, tuple(c.points[0])) for c in got}
    cast = np.pad(stats.cast, 1, constant_values=True)  # the outside is always known
    padded = np.pad(ids, 1, constant_values=np.uint32(0xFFFFFFFF))
    for r in ref:
        if (r.object_id, tuple(r.points[0])) in found:
            continue
        # Missed only if none of its cracks has both pixels computed (then it would be followed).
        for x, y in r.points.tolist():
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                if padded[y + 1 + dy, x + 1 + dx] != r.object_id:
                    assert not (cast[y + 1, x + 1] and cast[y + 1 + dy, x + 1 + dx])
    for method in ("border", "code_direction"):
        again, _ = run(BufferCaster(ids), None, method=method)
        assert len(again) == len(got)


# ----------------------------------------------------------------------------- scenes
SCENE_NAMES = sorted(p.name for p in SCENES.glob("*.xml"))


@pytest.mark.parametrize("name", SCENE_NAMES)
def test04_every_scene_equals_buffer_mode(name):
    scene = mi_npr.load_scene(SCENES / name, width=80, height=60, spp=1)
    ref = buffer_contours(scene)
    got, stats = trace_scene(scene)
    assert_same(got, ref)
    assert 0 < stats.ray_fraction < 1 and stats.rays_cast == stats.cast.sum()
    assert set(stats.times) == {"setup", "refine", "guard", "follow", "trace"}
    assert stats.contours == len(ref)


@pytest.mark.parametrize("id_mode", ["shape", "primitive", "component"])
@pytest.mark.parametrize("name", ["scene4.xml", "fig9_sphere_cube.xml"])
def test05_id_modes_equal_buffer_mode(name, id_mode):
    scene = mi_npr.load_scene(SCENES / name, width=64, height=48, spp=1)
    got, _ = trace_scene(scene, id_mode=id_mode)
    assert_same(got, buffer_contours(scene, id_mode))


@pytest.mark.parametrize("name", ["scene1.xml", "scene3.xml"])
def test06_code_direction_equals_buffer_mode(name):
    scene = mi_npr.load_scene(SCENES / name, width=80, height=60, spp=1)
    got, _ = trace_scene(scene, method="code_direction")
    assert_same(got, buffer_contours(scene, method="code_direction"))


def test07_full_resolution_casts_few_rays():
    """At the paper's 640x480, a fraction of a full ID buffer's rays (target <= 20%)."""
    got, stats = trace_scene(SCENES / "scene1.xml", width=640, height=480, spp=1)
    assert stats.ray_fraction < 0.2
    assert [c.name for c in got if not c.is_hole][:5] == [
        "back_wall",
        "floor",
        "sphere_left",
        "sphere_middle",
        "sphere_right",
    ]


def _spheres(rng, n, w, h, camera="perspective"):
    mi = mi_npr.mi
    to_world = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])
    sensor = {"type": camera, "film": {"type": "hdrfilm", "width": w, "height": h}}
    if camera == "perspective":
        sensor |= {"fov": 40, "to_world": to_world}
    else:  # orthographic: a 5 x 5 window, about what the perspective camera sees at z = 6
        sensor |= {"to_world": to_world @ mi.ScalarTransform4f().scale([2.5, 2.5, 1])}
    d = {"type": "scene", "sensor": sensor}
    for i in range(n):
        small = rng.random() < 0.5
        d[f"s{i:02d}"] = {
            "type": "sphere",
            "center": [
                float(rng.uniform(-2, 2)),
                float(rng.uniform(-1.5, 1.5)),
                float(rng.uniform(4, 8)),
            ],
            "radius": float(rng.uniform(0.01, 0.08) if small else rng.uniform(0.05, 0.6)),
        }
    return mi.load_dict(d, optimize=False)


@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
def test08_small_objects_are_guarded(camera):
    """Random scenes of small and large spheres: with the guard nothing is missed; without it,
    spheres between the macro-pixel corners are (the paper's limitation). An orthographic
    camera has no sample_direction: its boxes are projected along its parallel rays."""
    rng = np.random.default_rng(7)
    missed_without = 0
    for _ in range(6):
        scene = _spheres(rng, 12, 96, 72, camera)
        ref = buffer_contours(scene)
        got, _ = trace_scene(scene)
        assert_same(got, ref)
        bare, _ = trace_scene(scene, guard=False)
        assert all(any(c == r for r in ref) for c in bare)
        missed_without += len(ref) - len(bare)
    assert missed_without > 0


def test09_scene1_and_scene2_same_contours():
    a, _ = trace_scene(SCENES / "scene1.xml", width=96, height=72, spp=1)
    b, _ = trace_scene(SCENES / "scene2.xml", width=96, height=72, spp=1)
    assert_same(a, b)


def test10_errors_and_scalar_variant(write_scene):
    with pytest.raises(mi_npr.SceneError, match="no such file"):
        trace_scene("nope.xml")
    with pytest.raises(mi_npr.ParameterError, match="macro"):
        trace_scene(SCENES / "scene2.xml", width=8, height=6, macro=0)
    with pytest.raises(mi_npr.ParameterError, match="id_mode"):
        trace_scene(SCENES / "scene2.xml", width=8, height=6, id_mode="x")
    path = write_scene(
        '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>',
        width=12,
        height=9,
    )
    _, stats = trace_scene(path, macro=4)
    assert stats.rays_cast <= 12 * 9 and stats.guarded_pixels > 0
    mi_npr.set_variant("scalar_rgb")
    with pytest.raises(mi_npr.ParameterError, match="JIT variant"):
        trace_scene(path, macro=4)
