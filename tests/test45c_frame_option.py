"""``--frame OBJECT``: the objects a view frames, named, instead of the objects that matter,
for orbits, spheres of views, best views and exploration paths alike; ``--ignore`` sets more
objects aside; an unknown name is a one-line error naming the closest."""

from __future__ import annotations

import json

import numpy as np
import pytest

import mi_npr
from mi_npr import paths, views
from mi_npr import viewpoint as vp
from mi_npr.camera import framed_shapes, orbit

from .helpers import run_cli, scene_xml

CUBE = np.array([1.0, 0.3, 0.5])
BALL = np.array([-3.0, 0.5, 0.0])
BODY = f"""
    <shape type="rectangle" id="floor"><transform name="to_world">
        <scale value="20"/><rotate x="1" angle="-90"/></transform></shape>
    <shape type="cube" id="cube"><transform name="to_world">
        <scale value="0.3"/><translate x="{CUBE[0]}" y="{CUBE[1]}" z="{CUBE[2]}"/>
    </transform></shape>
    <shape type="sphere" id="ball"><point name="center" x="{BALL[0]}" y="{BALL[1]}" z="{BALL[2]}"/>
        <float name="radius" value="0.5"/></shape>"""


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    p = tmp_path_factory.mktemp("frame") / "two.xml"
    p.write_text(
        scene_xml(BODY, width=32, height=24, fov=40.0, origin="2, 4, 9", target="-1, 0, 0")
    )
    return p


@pytest.fixture(scope="module")
def scene(path):
    return mi_npr.load_scene(path)


def _orbit_targets(path, out, *flags):
    """The targets of ``mi-npr path --orbit`` (2 frames) with ``flags``, from its path.json."""
    res = run_cli("path", str(path), "--orbit", "--frames", "2", *flags,
                  "--width", "16", "--spp", "1", "--no-progress", "-o", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    return [cam["target"] for cam in json.loads((out / "path.json").read_text())]


def _ids(shapes):
    return sorted(s.id() for s in shapes)


def test01_framed_shapes(scene):
    assert _ids(framed_shapes(scene)) == ["ball", "cube"]  # the floor is flat
    assert _ids(framed_shapes(scene, ["ball"])) == ["ball"]
    assert _ids(framed_shapes(scene, ["floor", "ball"])) == ["ball", "floor"]  # as asked
    assert _ids(framed_shapes(scene, ignore=["ball"])) == ["cube"]
    with pytest.raises(mi_npr.ParameterError, match=r"frame 'bal': no such object \(closest: ball"):
        framed_shapes(scene, ["bal"])
    with pytest.raises(mi_npr.ParameterError, match=r"ignore 'cub': no such object"):
        framed_shapes(scene, ignore=["cub"])


def test02_every_camera_placement_frames_the_named_object(scene):
    """Orbit, sphere, random and best views and exploration all look at the ball's centre."""
    for cam in orbit(scene, 3, frame=["ball"]):
        np.testing.assert_allclose(cam.target, BALL, atol=1e-5)
    sensor = scene.sensors()[0]
    for spec in ("orbit:2", "sphere:2", "random:2:4", "best:2"):
        for vid, cam in views.cameras(views.parse_views(spec), scene, sensor, frame=("ball",)):
            np.testing.assert_allclose(cam.target, BALL, atol=1e-5, err_msg=vid)
    for cam in paths.explore(scene, 3, "entropy", samples=8, res=16, frame=["ball"]):
        np.testing.assert_allclose(cam.target, BALL, atol=1e-5)
    bv = vp.best_view(scene, "entropy", depth=1, res=16, frame=["ball"])
    np.testing.assert_allclose(bv.target, BALL, atol=1e-5)
    # the default: both objects' sphere, off both centres
    assert not np.allclose(vp.best_view(scene, depth=1, res=16).target, BALL, atol=1e-3)


def test03_the_three_commands_take_frame(path, tmp_path):
    out = tmp_path / "bv"
    res = run_cli("best-view", str(path), "--measure", "entropy", "--depth", "1", "--res", "16",
                  "--frame", "ball", "-o", str(out), "--json")  # fmt: skip
    assert res.returncode == 0, res.stderr
    np.testing.assert_allclose(json.loads(res.stdout)["target"], BALL, atol=1e-5)
    for target in _orbit_targets(path, tmp_path / "path", "--frame", "ball"):
        np.testing.assert_allclose(target, BALL, atol=1e-5)
    out = tmp_path / "batch"
    res = run_cli("batch", str(path), "--views", "orbit:2", "--frame", "ball", "--workers", "0",
                  "--width", "16", "--spp", "1", "--no-progress", "-o", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    rows = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert [r["status"] for r in rows] == ["done", "done"]
    res = run_cli("path", str(path), "--orbit", "--frames", "2", "--frame", "Ball",
                  "--width", "16", "--no-progress", "-o", str(tmp_path / "bad"))  # fmt: skip
    assert res.returncode != 0
    assert res.stderr.strip().splitlines()[-1] == (
        "mi-npr: error: frame 'Ball': no such object (closest: ball)"
    )


def test04_an_orbit_about_the_scene_cameras_own_target(path, scene, tmp_path):
    """``orbit:N:camera`` and ``path --orbit-target camera``: the centre is the point of the
    sensor's view line nearest the objects' centre, so view 0 looks exactly where the sensor
    does, from where it is; the default centre is the objects'."""
    sensor = mi_npr.camera.camera_of(scene.sensors()[0])
    o, f = np.asarray(sensor.origin), np.asarray(sensor.forward)
    cams = orbit(scene, 4, target="camera")
    c = np.asarray(cams[0].target)
    np.testing.assert_allclose(np.cross(c - o, f), 0, atol=1e-6)  # on the view line
    np.testing.assert_allclose(cams[0].origin, o, atol=1e-5)
    np.testing.assert_allclose(cams[0].forward, f, atol=1e-6)  # the sensor's own view
    for cam in cams:
        np.testing.assert_allclose(cam.target, c, atol=1e-6)
    # across from the centre of the objects (the ball and the cube): the nearest point of the line
    centre = mi_npr.camera.bounding_sphere(scene)[0]
    assert abs(np.dot(centre - c, f)) < 1e-6
    spec = views.parse_views("orbit:3:camera")
    got = [cam for _, cam in views.cameras(spec, scene, scene.sensors()[0])]
    np.testing.assert_allclose(got[0].target, c, atol=1e-6)
    with pytest.raises(mi_npr.ParameterError, match="orbit's option is 'camera'"):
        views.parse_views("orbit:3:cam")
    with pytest.raises(mi_npr.ParameterError, match="expected 3 numbers or 'camera'"):
        orbit(scene, 2, target="sensor")
    for target in _orbit_targets(path, tmp_path / "p", "--orbit-target", "camera"):
        np.testing.assert_allclose(target, c, atol=1e-5)
