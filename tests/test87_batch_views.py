"""The viewpoints of ``mi-npr batch --views`` (:mod:`mi_npr.views`): parsing with
one-line errors, the orbit and the sphere against closed forms written here, the best views in
best view's order, and a camera turned into a sensor that renders what the scene's own sensor
renders."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import mi_npr
from mi_npr import views as V
from mi_npr.camera import orbit
from mi_npr.session import SceneSession
from mi_npr.viewpoint.search import viewing

BODY = """<shape type="sphere"><point name="center" x="0" y="0" z="0"/>
<float name="radius" value="1"/></shape>"""


def test01_parse_and_ids():
    assert V.parse_views("scene").ids() == ["scene"]
    assert V.parse_views("orbit:3").ids() == ["orbit_000", "orbit_001", "orbit_002"]
    assert V.parse_views("sphere:2:all").option == "all"
    assert len(V.parse_views("sphere:1500").ids()[-1]) == len("sphere_1499")
    b = V.parse_views("best:2:pb")
    assert (b.ids(), b.option) == (["best_0", "best_1"], "pb")
    assert V.parse_views("best:1").option == "entropy"


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("orbit:0", "orbit"),
        ("orbit:-2", "orbit"),
        ("orbit:x", "'x'"),
        ("orbit:1000001", "orbit"),
        ("sphere:4:lower", "sphere"),
        ("best:41", "best"),
        ("best:2:beauty", "measure"),
        ("orbit:2:all", "orbit"),
        ("spiral:4", "spiral"),
        ("", "views"),
        ("missing.json", "missing.json"),
    ],
)
def test02_bad_specs_are_one_line_errors(spec, words):
    with pytest.raises(mi_npr.ParameterError) as e:
        V.parse_views(spec)
    assert words in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize(
    ("cams", "words"),
    [
        ([], "non-empty"),
        ({"x": 1}, "non-empty"),
        ([{"origin": [0, 0, 0]}], "target"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 0]}], "same point"),
        ([{"origin": [0, 0, 0], "target": [0, 1, 0], "up": [0, 1, 0]}], "parallel"),
        ([{"origin": [0, 0, "a"], "target": [0, 0, 1]}], "origin"),
        ([{"origin": [0, 0, 0], "target": "001"}], "target"),
        ([{"origin": [0, 0, float("nan")], "target": [0, 0, 1]}], "origin"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 1], "fov": 180}], "fov"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 1], "fov": True}], "fov"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 1], "zoom": 2}], "zoom"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 1], "id": "../x"}], "id"),
        ([{"origin": [0, 0, 0], "target": [0, 0, 1], "id": "a"}] * 2, "twice"),
    ],
)
def test03_bad_camera_files(tmp_path, cams, words):
    p = tmp_path / "cams.json"
    p.write_text(json.dumps(cams))
    with pytest.raises(mi_npr.ParameterError) as e:
        V.parse_views(str(p))
    assert words in str(e.value) and str(p) in str(e.value) and "\n" not in str(e.value)
    p.write_text("[{")
    with pytest.raises(mi_npr.ParameterError, match="not a JSON file"):
        V.parse_views(str(p))


def test04_orbit_closed_form(write_scene):
    """Camera at (0, 1, -4) looking at the sphere's centre, +y up: the orbit is that point
    turned about the y axis by 2 pi k / N (x' = x cos a + z sin a, z' = -x sin a + z cos a)."""
    path = write_scene(BODY, origin="0, 1, -4", target="0, 0, 0")
    s = SceneSession.open(path)
    n = 8
    cams = orbit(s.scene, n, sensor=s.sensor)
    for k, cam in enumerate(cams):
        a = 2 * math.pi * k / n
        x, z = 0.0, -4.0
        ref = (x * math.cos(a) + z * math.sin(a), 1.0, -x * math.sin(a) + z * math.cos(a))
        np.testing.assert_allclose(cam.origin, ref, atol=1e-5)
        np.testing.assert_allclose(cam.target, (0, 0, 0), atol=1e-6)
        assert cam.fov == pytest.approx(40.0)
        d = np.subtract(cam.target, cam.origin)
        assert abs(np.dot(cam.up, d)) < 1e-9 and cam.up[1] > 0.9  # orthogonal, upright


def test05_sphere_upper_half_and_whole(write_scene):
    path = write_scene(BODY, origin="0, 1, -4", target="0, 0, 0")
    s = SceneSession.open(path)
    view = viewing(s.scene, res=32, sensor=s.sensor)
    radius = V.FRAME_MARGIN * view.radius  # one object: it alone is framed, with the margin
    for upper, n in ((True, 10), (False, 11)):
        cams = V.sphere(s.scene, s.sensor, n, upper=upper)
        assert len(cams) == n
        o = np.array([c.origin for c in cams]) - view.target
        np.testing.assert_allclose(np.linalg.norm(o, axis=1), radius, rtol=1e-9)
        h = o @ view.up / radius
        if upper:
            assert np.all(h > 0)
        else:
            assert (h > 0).sum() in (n // 2, n // 2 + 1) and np.all(np.abs(h) < 1)
        # Fibonacci lattice: heights evenly spaced (1 - (2i + 1) / M, M = 2n for the half)
        m = 2 * n if upper else n
        ref = 1.0 - (2.0 * np.arange(m) + 1.0) / m
        np.testing.assert_allclose(np.sort(h)[::-1], ref[: len(h)], atol=1e-9)
        assert len({tuple(np.round(c.origin, 9)) for c in cams}) == n


def test06_sphere_turns_the_lattice_onto_a_z_up_scene(write_scene, tmp_path):
    xml = write_scene(BODY).read_text().replace('up="0, 1, 0"', 'up="0, 0, 1"')
    xml = xml.replace('origin="0, 0, 0" target="0, 0, 1"', 'origin="0, -4, 1" target="0, 0, 0"')
    p = tmp_path / "zup.xml"
    p.write_text(xml)
    s = SceneSession.open(p)
    cams = V.sphere(s.scene, s.sensor, 6)
    assert all(c.origin[2] > 0 for c in cams)


def test07_best_views_in_quality_order(scenes):
    s = SceneSession.open(scenes / "scene3.xml")
    cams = V.best(s.scene, s.sensor, 3, "pb")
    bv = mi_npr.viewpoint.best_view(s.scene, "pb")
    np.testing.assert_allclose(cams[0].origin, bv.origin, atol=1e-9)
    q = [mi_npr.viewpoint.quality(s.scene, c.origin, c.target, "pb") for c in cams]
    assert q[0] == pytest.approx(bv.quality) and q[0] >= q[1] >= q[2]
    if bv.evaluations < 40:
        with pytest.raises(mi_npr.ParameterError, match="rated only"):
            V.best(s.scene, s.sensor, 40, "pb")


def test08_a_camera_sensor_renders_like_the_scene_sensor(write_scene, tmp_path):
    """The scene's own lookat given as a JSON camera renders the same G-buffer (the sensor is
    rebuilt with the scene sensor's film, filter and sampler)."""
    path = write_scene(BODY, origin="0.3, 1, -4", target="0, 0.1, 0", width=33, height=21, spp=2)
    cams = tmp_path / "cams.json"
    cams.write_text(json.dumps([{"id": "same", "origin": [0.3, 1, -4], "target": [0, 0.1, 0],
                                 "up": [0, 1, 0]}]))  # fmt: skip
    out = tmp_path / "out"
    a = mi_npr.batch.run([path], "scene", out=out, workers=0, progress=False)
    b = mi_npr.batch.run([path], str(cams), out=out, workers=0, progress=False)
    assert [r["status"] for r in a + b] == ["done", "done"]
    ga = mi_npr.io.read_exr(out / "scene" / "scene.exr")
    gb = mi_npr.io.read_exr(out / "scene" / "same.exr")
    assert (ga.width, ga.height) == (gb.width, gb.height) == (33, 21)
    np.testing.assert_array_equal(ga.numpy("object_id.V"), gb.numpy("object_id.V"))
    np.testing.assert_allclose(ga.numpy("Z"), gb.numpy("Z"), rtol=1e-5)
    assert b[0]["camera"]["fov"] is None and a[0]["camera"]["fov"] == pytest.approx(40.0)
    np.testing.assert_allclose(a[0]["camera"]["origin"], [0.3, 1, -4], atol=1e-5)
