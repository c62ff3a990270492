"""The scenes in scenes_xml/: they load, render small, and keep the promises of their comments."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.scene import declared_defaults

from .helpers import SCENES

ALL = sorted(p.name for p in SCENES.glob("*.xml"))


def test01_the_paper_scenes_exist():
    assert {
        "scene1.xml",
        "scene2.xml",
        "scene3.xml",
        "scene4.xml",
        "fig9_sphere_cube.xml",
        "cornell_box.xml",
    } <= set(ALL)


@pytest.mark.parametrize("name", ALL)
def test02_every_scene_declares_defaults_and_renders(name):
    path = SCENES / name
    assert {"width", "height", "spp", "integrator"} <= declared_defaults(path)
    gb = mi_npr.render(path, width=24, height=18, spp=2)
    assert gb.shape == (18, 24)
    assert len(gb.objects) >= 2
    assert set(np.unique(gb.numpy("object_id.V"))) <= {0, *gb.objects}
    assert np.isfinite(gb.beauty).all() and gb.beauty.max() > 0


def test03_scene1_and_scene2_differ_only_in_materials():
    one = mi_npr.render(SCENES / "scene1.xml", width=40, height=30, spp=2)
    two = mi_npr.render(SCENES / "scene2.xml", width=40, height=30, spp=2)
    assert one.objects == two.objects
    for name in mi_npr.layers.GBUFFER_AOVS:
        np.testing.assert_array_equal(one.numpy(name), two.numpy(name), err_msg=name)
    assert not np.array_equal(one.beauty, two.beauty)


def test04_scene3_hides_one_object_and_shows_one_through_a_gap():
    gb = mi_npr.render(SCENES / "scene3.xml", width=80, height=60, spp=1)
    ids = gb.numpy("object_id.V")
    assert not np.any(ids == gb.find_object("sphere_hidden"))
    gap = ids == gb.find_object("cube_in_gap")
    assert gap.any()
    # Every cube pixel has a front box pixel on its row to the left and to the right.
    fronts = {gb.find_object("box_front_left"), gb.find_object("box_front_right")}
    for y in np.unique(np.nonzero(gap)[0]):
        xs = np.nonzero(gap[y])[0]
        row = ids[y]
        assert np.isin(row[: xs.min()], list(fronts)).any()
        assert np.isin(row[xs.max() + 1 :], list(fronts)).any()


def test05_fig9_is_one_shape_with_two_components():
    scene = mi_npr.load_scene(SCENES / "fig9_sphere_cube.xml", width=16, height=12, spp=1)
    meshes = [s for s in scene.shapes() if s.id() == "sphere_mesh"]
    assert len(meshes) == 1 and meshes[0].face_count() == 2088 + 12


def test06_cornell_box_keeps_every_wall_separate():
    gb = mi_npr.render(SCENES / "cornell_box.xml", width=32, height=32, spp=1)
    assert set(gb.objects.values()) == {
        "back",
        "ceiling",
        "floor",
        "green-wall",
        "large-box",
        "light",
        "red-wall",
        "small-box",
    }


def test07_any_scene_is_sized_from_python(tmp_path):
    """``width``, ``height`` and ``spp`` size a scene whatever its ``<default>``\\ s are named, in
    ``mi_npr.load_scene`` and ``mi_npr.render`` as on the command line: a film of 32 x 24 whose
    default is called ``res``; one side alone keeps the aspect; a declared default still takes
    the value itself."""
    from .public_style import room

    path = room(tmp_path)  # <default name="res" .../>: no width or height default
    scene = mi_npr.load_scene(path, width=32, height=24, spp=2)
    (sensor,) = scene.sensors()
    assert tuple(sensor.film().size()) == (32, 24) and sensor.sampler().sample_count() == 2
    gb = mi_npr.render(path, width=20, height=10)
    assert gb.shape == (10, 20)
    assert tuple(mi_npr.load_scene(path, width=30).sensors()[0].film().size()) == (30, 30)
    with pytest.raises(mi_npr.ParameterError, match="width = 'wide'"):
        mi_npr.load_scene(path, width="wide")
    # scene1 declares width/height: the defaults take them (its `res`-free film is 64 x 48)
    gb = mi_npr.render(SCENES / "scene1.xml", width=64, height=48, spp=1)
    assert gb.shape == (48, 64)
