"""Exploration paths and best view frame the objects that matter, as orbits and spheres of
views do: a small object on a huge floor in front of a huge backdrop is in every camera's
image, seen from the distance that fits the object, not the floor."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr import paths, views
from mi_npr import viewpoint as vp

from .helpers import scene_xml

W, H, FOV = 40, 30, 40.0
CENTRE = np.array([1.0, 0.3, 0.5])  # the cube's centre; half-size S
S = 0.3
BODY = f"""
    <shape type="rectangle" id="floor"><transform name="to_world">
        <scale value="20"/><rotate x="1" angle="-90"/></transform></shape>
    <shape type="rectangle" id="backdrop"><transform name="to_world">
        <scale value="20"/><translate z="-8"/></transform></shape>
    <shape type="cube" id="cube"><transform name="to_world">
        <scale value="{S}"/><translate x="{CENTRE[0]}" y="{CENTRE[1]}" z="{CENTRE[2]}"/>
    </transform></shape>"""

# The cube's bounding sphere and the distance from which a W x H, FOV-degree pinhole sees it
# whole: R / sin(phi / 2), phi the smaller of the two fields of view (written out here, not
# taken from mi_npr.camera.fit_distance).
R = S * math.sqrt(3.0)
PHI = min(math.radians(FOV), 2 * math.atan(math.tan(math.radians(FOV) / 2) * H / W))
FIT = R / math.sin(PHI / 2)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("stage") / "stage.xml"
    path.write_text(
        scene_xml(BODY, width=W, height=H, fov=FOV, origin="6, 4, 9", target="1, 0.3, 0.5")
    )
    return mi_npr.load_scene(path)


def _in_image(origin, target, up, fov, point) -> bool:
    """Whether ``point`` projects inside the W x H image of the pinhole camera ``lookat``."""
    f = np.subtract(target, origin)
    f = f / np.linalg.norm(f)
    left = np.cross(up, f)
    left /= np.linalg.norm(left)
    u = np.cross(f, left)
    d = np.subtract(point, origin)
    z = d @ f
    tx = math.tan(math.radians(fov) / 2)
    return z > 0 and abs(d @ left / z) <= tx and abs(d @ u / z) <= tx * H / W


def test01_flat_floor_and_backdrop_are_not_objects_that_matter(scene):
    assert [s.id() for s in mi_npr.camera.objects_that_matter(scene)] == ["cube"]


def test02_exploration_path_sees_the_cube_from_its_fitting_distance(scene):
    cams = paths.explore(scene, 8, "entropy", samples=24, res=24, max_speed=20.0)
    assert len(cams) == 8
    for c in cams:
        np.testing.assert_allclose(c.target, CENTRE, atol=1e-5)
        assert _in_image(c.origin, c.target, c.up, c.fov, CENTRE)
        assert np.linalg.norm(np.subtract(c.origin, CENTRE)) == pytest.approx(FIT, rel=0.03)


def test03_best_view_sees_the_cube_from_its_fitting_distance(scene):
    bv = vp.best_view(scene, "entropy", depth=1, res=24)
    np.testing.assert_allclose(bv.target, CENTRE, atol=1e-5)
    assert bv.radius == pytest.approx(FIT, rel=0.03)
    assert np.linalg.norm(bv.origin - CENTRE) == pytest.approx(FIT, rel=0.03)
    assert _in_image(bv.origin, bv.target, bv.up, FOV, CENTRE)


def test04_views_best_cameras_frame_the_cube(scene):
    for c in views.best(scene, scene.sensors()[0], 2):
        assert _in_image(c.origin, c.target, c.up, c.fov, CENTRE)
        assert np.linalg.norm(np.subtract(c.origin, CENTRE)) == pytest.approx(FIT, rel=0.03)
