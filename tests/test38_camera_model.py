"""One camera model (:mod:`mi_npr.camera`): the batch's views, camera paths and best view read,
place and render cameras through the same type and functions, so they agree on every input:
a camera file without ``up``/``fov`` (the scene sensor's), unknown keys (one error), the orbit
of a camera on the orbit's axis (one error, never identical views), and a path's frames handed
to the batch in memory."""

from __future__ import annotations

import ast
import json
import math
from pathlib import Path

import numpy as np
import pytest

import mi_npr
from mi_npr import ParameterError
from mi_npr import camera as C
from mi_npr import paths as P
from mi_npr import views as V
from mi_npr.cli import main
from mi_npr.io import read_exr
from mi_npr.session import SceneSession

from .helpers import SCENES, scene_xml

SPHERE = """<shape type="sphere"><point name="center" x="0" y="0" z="0"/>
<float name="radius" value="1"/></shape>"""
SMALL = ["--width", "32", "--height", "24", "--spp", "1", "--no-progress"]


def _unit(v) -> np.ndarray:
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _image_up(origin, target, up) -> np.ndarray:
    """The image's up of ``lookat(origin, target, up)``: ``up`` minus its part along the view
    (the test's own Gram-Schmidt)."""
    f = _unit(np.subtract(target, origin))
    u = np.asarray(up, np.float64)
    return _unit(u - (u @ f) * f)


@pytest.fixture
def zup_scene(tmp_path) -> Path:
    """A unit sphere seen by a 50 degree sensor whose lookat has ``up="0, 0, 1"``: its up axis
    is +z, unlike the +y a camera file used to default to."""
    xml = scene_xml(SPHERE, origin="0, -4, 1", target="0, 0, 0", fov=50.0)
    p = tmp_path / "zup.xml"
    p.write_text(xml.replace('up="0, 1, 0"', 'up="0, 0, 1"'))
    return p


# -- the type and its file --------------------------------------------------------------------


def test01_camera_is_checked_once_with_one_set_of_messages():
    cam = C.Camera([1, 2, 3], (0, 0, 0), None, None, 0.5, "front")
    assert (cam.origin, cam.up, cam.fov, cam.time) == ((1.0, 2.0, 3.0), None, None, 0.5)
    assert cam.id == "front"
    np.testing.assert_allclose(cam.forward, -np.array([1, 2, 3]) / math.sqrt(14))
    for kwargs, words in (
        ({"origin": (0, 0, 0), "target": (0, 0, 0)}, "same point"),
        ({"origin": (0, 0, 0), "target": (0, 2, 0), "up": (0, -3, 0)}, "parallel"),
        ({"origin": "123", "target": (0, 0, 1)}, "origin"),
        ({"origin": (0, 0, 0), "target": (0, 0, 1), "fov": 180}, "fov"),
        ({"origin": (0, 0, 0), "target": (0, 0, 1), "time": 1.5}, "time"),
        ({"origin": (0, 0, 0), "target": (0, 0, 1), "time": float("nan")}, "time"),
        ({"origin": (0, 0, 0), "target": (0, 0, 1), "id": "a/b"}, "id"),
    ):
        with pytest.raises(ParameterError, match=words) as e:
            C.Camera(**kwargs)
        assert str(e.value).startswith("camera: ") and "\n" not in str(e.value)


def test02_camera_file_list_or_object_round_trip(tmp_path):
    cams = [
        C.Camera((4, 3, -4), (0, 0.5, 0), (0, 1, 0), 40, 0.0, "a"),
        C.Camera((-4, 3, -4), (0, 0.5, 0), None, None, 1.0),
    ]
    text = C.to_json(cams)
    assert C.from_json(text) == cams
    assert "id" not in json.loads(text)[1]  # written only where set
    p = tmp_path / "wrapped.json"
    p.write_text(json.dumps({"cameras": json.loads(text)}))
    assert C.read_cameras(p) == cams
    p.write_text(json.dumps({"cameras": json.loads(text), "fov": 30}))
    with pytest.raises(ParameterError, match="unknown key 'fov'"):
        C.read_cameras(p)
    # time absent: camera k of K at k / (K - 1)
    p.write_text(json.dumps([{"origin": [0, 0, k + 1], "target": [0, 0, 0]} for k in range(5)]))
    assert [c.time for c in C.read_cameras(p)] == [0.0, 0.25, 0.5, 0.75, 1.0]


# -- 1 and 3: a missing up or fov is the scene sensor's, in the batch and in a path ----------


def test03_missing_up_and_fov_are_the_scene_sensors_in_batch_and_path(tmp_path, zup_scene):
    o, t = (3.0, -3.0, 2.0), (0.0, 0.0, 0.0)
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps([{"id": "k0", "origin": list(o), "target": list(t)},
                                {"origin": [-3, -3, 2], "target": [0, 0, 0]}]))  # fmt: skip
    up = _image_up(o, t, (0, 0, 1))  # the scene's up axis is +z
    # batch --views FILE.json
    out = tmp_path / "batch"
    argv = ["batch", str(zup_scene), "--views", str(keys), "-o", str(out), "--workers", "0"]
    assert main([*argv, *SMALL]) == 0
    batch_cam = read_exr(out / "zup" / "k0.exr").camera
    np.testing.assert_allclose(batch_cam.origin, o, atol=1e-5)
    np.testing.assert_allclose(batch_cam.up, up, atol=1e-5)
    assert batch_cam.fov == pytest.approx(50.0, abs=1e-4)
    # path --keys FILE.json: the same file, the same camera at its first frame
    out = tmp_path / "path"
    argv = ["path", str(zup_scene), "--keys", str(keys), "--frames", "3", "-o", str(out)]
    assert main([*argv, *SMALL]) == 0
    first = C.from_json((out / "path.json").read_text())[0]
    np.testing.assert_allclose(first.up, up, atol=1e-9)
    assert first.fov == pytest.approx(50.0)
    path_cam = read_exr(out / "frame_0000.exr").camera
    np.testing.assert_allclose(path_cam.to_world, batch_cam.to_world, atol=1e-6)


def test04_a_key_without_fov_takes_the_scene_fov(zup_scene):
    keys = [
        C.Camera((3, -3, 2), (0, 0, 0), (0, 0, 1), 30.0),
        C.Camera((-3, -3, 2), (0, 0, 0), (0, 0, 1)),  # fov: the sensor's 50
    ]
    path = P.make_path(str(zup_scene), 5, keys=keys)
    assert [c.fov for c in path] == pytest.approx([30.0, 35.0, 40.0, 45.0, 50.0], abs=1e-6)
    with pytest.raises(ParameterError, match="keyframe 1 has no fov"):
        P.through(keys, 5)  # unresolved keys: through alone cannot guess


def test05_up_axis_along_the_view_names_the_file_and_camera(tmp_path, zup_scene):
    keys = tmp_path / "down.json"
    keys.write_text(json.dumps([{"origin": [0, 0, 5], "target": [0, 0, 0]}]))  # down the z axis
    with pytest.raises(ParameterError) as e:
        P.make_path(str(zup_scene), 2, keys=keys)
    msg = str(e.value)
    assert msg.startswith(f"{keys}: camera 0: ") and "up axis [0.0, 0.0, 1.0]" in msg
    rows = mi_npr.batch.run([zup_scene], str(keys), out=tmp_path / "o", workers=0, progress=False)
    assert rows[0]["status"] == "failed" and f"{keys}: camera 0: " in rows[0]["error"]


# -- 2: unknown keys, one reader, one rule, one error ------------------------------------------


def test06_unknown_key_is_one_error_in_both_commands(tmp_path, capsys):
    p = tmp_path / "cams.json"
    good = {"origin": [0, 1, -4], "target": [0, 0, 0]}
    p.write_text(json.dumps([good, {**good, "zoom": 2}]))
    want = f"{p}: camera 1: unknown key 'zoom'"
    with pytest.raises(ParameterError) as views_error:
        V.parse_views(str(p))
    with pytest.raises(ParameterError) as path_error:
        P.make_path(str(SCENES / "scene3.xml"), 3, keys=p)
    assert str(views_error.value) == str(path_error.value)
    assert str(views_error.value).startswith(want) and "\n" not in str(views_error.value)
    scene3 = str(SCENES / "scene3.xml")
    for cmd in (["batch", scene3, "--views"], ["path", scene3, "--frames", "2", "--keys"]):
        assert main([*cmd, str(p), "-o", str(tmp_path / "o"), *SMALL]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0]


# -- 4: one orbit; a camera on the orbit's axis is one error everywhere -----------------------


def test07_orbit_is_one_function_for_batch_and_path(tmp_path, write_scene):
    scene = write_scene(SPHERE, origin="1, 2, -4", target="0, 0, 0")
    rows = mi_npr.batch.run([scene], "orbit:4", out=tmp_path / "b", workers=0, progress=False)
    path = P.make_path(str(scene), 4)
    assert [r["camera"] for r in rows] == [c.to_dict() for c in path]
    # closed form: (1, 2, -4) turned about +y by 90 degrees: (x, z) -> (z, -x)
    np.testing.assert_allclose(path[1].origin, (-4, 2, -1), atol=1e-12)


def test08_orbit_up_never_rolls_even_high_above(write_scene):
    # 87 degrees above the sphere's centre, looking 18 degrees down: the up axis is +y
    scene = write_scene(SPHERE, origin="0.3, 6, 0", target="6, 4, 0")
    s = SceneSession.open(scene)
    axis = C.up_axis(s.sensor)
    np.testing.assert_array_equal(axis, [0, 1, 0])
    cams = C.orbit(s.scene, 12, sensor=s.sensor)
    for c in cams:
        f = c.forward
        left = np.cross(c.up, f)
        assert abs(left @ axis) < 1e-9  # the image's horizontal stays horizontal: no roll
        assert np.dot(c.up, f) == pytest.approx(0, abs=1e-12) and np.dot(c.up, axis) > 0


def test09_camera_on_the_orbit_axis_is_one_error_not_identical_views(tmp_path, write_scene, capsys):
    # Straight above the sphere's centre, looking 40 degrees down: the up axis is +y, and the
    # camera lies on it: an orbit about it has no circle to go round.
    scene = write_scene(SPHERE, origin="0, 5, 0", target="6, 0, 0")
    s = SceneSession.open(scene)
    with pytest.raises(ParameterError, match="lies on the orbit's axis") as in_views:
        V.cameras(V.parse_views("orbit:4"), s.scene, s.sensor)
    with pytest.raises(ParameterError) as in_paths:
        P.make_path(str(scene), 4)
    assert str(in_views.value) == str(in_paths.value) and "\n" not in str(in_views.value)
    rows = mi_npr.batch.run([scene], "orbit:4", out=tmp_path / "b", workers=0, progress=False)
    assert [r["status"] for r in rows] == ["failed"] * 4
    assert all(str(in_views.value) in r["error"] for r in rows)
    assert main(["path", str(scene), "--frames", "4", "-o", str(tmp_path / "p"), *SMALL]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(in_views.value) in err[0]


# -- 5: a path's frames go to the batch in memory ------------------------------------------------


def test10_batch_takes_cameras_in_memory(tmp_path, write_scene):
    scene = write_scene(SPHERE, origin="0, 1, -4", target="0, 0, 0")
    cams = [C.Camera((0, 1, -4), (0, 0, 0), id="front"), C.Camera((4, 1, 0), (0, 0, 0))]
    rows = mi_npr.batch.run([scene], cams, out=tmp_path / "m", workers=0, progress=False)
    assert [r["view"] for r in rows] == ["front", "cam_001"]
    f = tmp_path / "cams.json"
    f.write_text(C.to_json(cams))
    mi_npr.batch.run([scene], str(f), out=tmp_path / "f", workers=0, progress=False)
    for view in ("front", "cam_001"):
        a = read_exr(tmp_path / "m" / "scene" / f"{view}.exr")
        b = read_exr(tmp_path / "f" / "scene" / f"{view}.exr")
        np.testing.assert_array_equal(a.numpy("Z"), b.numpy("Z"))
    # resume: the same cameras redo nothing, a moved camera is rendered again
    n = len((tmp_path / "m" / "manifest.jsonl").read_text().splitlines())
    again = dict(out=tmp_path / "m", workers=0, progress=False, resume=True)
    mi_npr.batch.run([scene], cams, **again)
    assert len((tmp_path / "m" / "manifest.jsonl").read_text().splitlines()) == n
    mi_npr.batch.run([scene], [cams[0], C.Camera((4, 2, 0), (0, 0, 0))], **again)
    assert len((tmp_path / "m" / "manifest.jsonl").read_text().splitlines()) > n
    with pytest.raises(ParameterError, match="twice"):
        mi_npr.batch.run([scene], [cams[0], cams[0]], out=tmp_path / "x", workers=0)


def test11_path_frames_as_jobs_write_no_camera_file(tmp_path):
    scene = str(SCENES / "scene3.xml")
    cams = C.orbit(scene, 2, 10.0)
    size = {"resolution": (32, 24), "spp": 1}
    fr = P.render_frames(scene, cams, tmp_path, [], cluster={"workers": 0}, **size)
    assert not (tmp_path / "frames.json").exists()
    assert C.from_json((tmp_path / "path.json").read_text()) == cams
    assert {p.name for p in fr.files} >= {"frame_0000.exr", "frame_0001.exr", "path.json"}
    for i, c in enumerate(cams):
        frame = read_exr(tmp_path / f"frame_{i:04d}.exr")
        np.testing.assert_allclose(frame.camera.origin, c.origin, atol=1e-4)


# -- sensors -------------------------------------------------------------------------------------


def test12_camera_of_and_sensor_for_agree_with_the_xml(zup_scene):
    s = SceneSession.open(zup_scene)
    cam = C.camera_of(s.sensor)
    np.testing.assert_allclose(cam.origin, (0, -4, 1), atol=1e-6)
    np.testing.assert_allclose(cam.forward, _unit((0, 4, -1)), atol=1e-6)
    np.testing.assert_allclose(cam.up, _image_up((0, -4, 1), (0, 0, 0), (0, 0, 1)), atol=1e-6)
    assert cam.fov == pytest.approx(50.0)
    again = C.sensor_for(cam, s.sensor)
    m = np.asarray(again.world_transform().matrix)
    np.testing.assert_allclose(m, np.asarray(s.sensor.world_transform().matrix), atol=1e-6)
    p = C.projection_of(again)
    assert p.resolution == (32, 24) and p.fov == pytest.approx(50.0)


def test13_sensor_file_loads_as_the_camera(tmp_path, zup_scene):
    s = SceneSession.open(zup_scene)
    cam = C.Camera((2, -3, 2), (0, 0, 0.5), None, 35.0)
    text = C.sensor_xml(cam, s.sensor, name="shot")
    f = tmp_path / "shot.xml"
    f.write_text(text)
    (sensor,) = mi_npr.mi.load_file(str(f)).sensors()
    back = C.camera_of(sensor)
    np.testing.assert_allclose(back.origin, cam.origin, atol=1e-5)
    np.testing.assert_allclose(back.forward, cam.forward, atol=1e-5)
    np.testing.assert_allclose(back.up, _image_up(cam.origin, cam.target, (0, 0, 1)), atol=1e-5)
    assert back.fov == pytest.approx(35.0) and C.projection_of(sensor).resolution == (32, 24)


def test14_camera_package_imports_nothing_above_it():
    """scene -> camera -> G-buffer -> drawings -> writers: the camera package may read scenes,
    parameters and errors (and the G-buffer's record type), never a renderer, batch or CLI."""
    allowed = {"errors", "params", "scene", "gbuffer"}
    pkg = Path(mi_npr.camera.__file__).parent
    for f in pkg.glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 2:
                top = (node.module or "").split(".")[0]
                assert top in allowed, f"{f.name} imports mi_npr.{node.module}"
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                assert not node.module.startswith("mi_npr"), f"{f.name}: {node.module}"


FLOOR_AND_BACKDROP = """<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="3, 2, 6" target="3, 0.25, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="32"/>
        </film>
    </sensor>
    <shape type="cube" id="crate"><transform name="to_world"><scale value="0.25"/>
        <translate x="3" y="0.25"/></transform></shape>
    <shape type="rectangle" id="floor"><transform name="to_world"><scale value="20"/>
        <rotate x="1" angle="-90"/></transform></shape>
    <shape type="rectangle" id="backdrop"><transform name="to_world"><scale value="20"/>
        <translate y="10" z="-10"/></transform></shape>
    <shape type="sphere" id="lamp"><point name="center" x="-6" y="8" z="0"/>
        <float name="radius" value="0.2"/><emitter type="area"/></shape>
</scene>"""


@pytest.mark.parametrize("spec", ["orbit:4", "sphere:4"])
def test17_views_frame_the_objects_not_the_floor(tmp_path, spec):
    """A crate off-centre on a 40 m floor before a backdrop, lit by an area light: the framing
    is the crate's (floors, backdrops and lights are not what a view is about), so every view
    sees it, and sphere views see it whole and large."""
    from mi_npr import views
    from mi_npr.camera import objects_that_matter, sensor_for
    from mi_npr.session import SceneSession

    path = tmp_path / "stage.xml"
    path.write_text(FLOOR_AND_BACKDROP)
    s = SceneSession.open(path)
    assert [sh.id() for sh in objects_that_matter(s.scene)] == ["crate"]
    crate = s.objects.id_of("crate")
    for vid, cam in views.cameras(views.parse_views(spec), s.scene, s.sensor):
        gb = mi_npr.render(s.scene, sensor=sensor_for(cam, s.sensor), spp=1)
        seen = gb.object_id == crate
        assert seen.sum() > 30, (vid, int(seen.sum()))
        if spec.startswith("sphere"):  # whole: the crate touches no border of the image
            assert not (seen[0].any() or seen[-1].any() or seen[:, 0].any() or seen[:, -1].any())


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"origin": [0, 0, -1e39]}, "origin = .*: expected 3 finite numbers"),  # inf in float32
        ({"origin": [True, 0, 0]}, "origin = .*: expected 3 finite numbers"),
        ({"target": ["1", "2", "3"]}, "target = .*: expected 3 finite numbers"),
        ({"origin": [0, 0, 3e38], "target": [0, 0, -3e38]}, "too far apart \\(float32\\)"),
        ({"origin": [1, 1, 1], "target": [1, 1, 1 + 1e-10]}, "the same point"),  # in float32
    ],
)
def test15_cameras_are_checked_as_mitsuba_sees_them(fields, message):
    """Mitsuba computes in float32: an origin of -1e39 would be infinite, the camera NaN."""
    values = {"origin": [0, 0, -4], "target": [0, 0, 0], **fields}
    with pytest.raises(ParameterError, match=message):
        C.Camera.checked("keys.json: camera 0", **values)


def test16_a_camera_file_nested_too_deeply_is_one_error(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(ParameterError, match=r"deep.json: not a JSON file of cameras \(nested"):
        C.read_cameras(deep)


def test18_a_stage_is_not_framed_but_a_big_neighbour_is():
    """A shape far larger than the rest whose box holds their centres (a curved backdrop, a
    dome) is a stage; one as large beside them (a house by a mailbox) is an object."""
    import mitsuba as mi

    from mi_npr.camera import objects_that_matter

    def scene(big_at):
        return mi.load_dict(
            {
                "type": "scene",
                "ball": {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5},
                "big": {
                    "type": "cube",
                    "to_world": mi.ScalarTransform4f().translate(big_at).scale([8, 4, 8]),
                },
            }
        )

    assert [s.id() for s in objects_that_matter(scene([0, 3, 0]))] == ["ball"]
    assert sorted(s.id() for s in objects_that_matter(scene([20, 3, 0]))) == ["ball", "big"]


def test19_a_flat_object_on_a_stage_is_framed(tmp_path):
    """mitsuba-data's disk and rectangle scenes: the one object is flat and the only solid
    shape is the backdrop, a stage holding it. The object is what matters (not the stage, which
    alone was left once flat shapes were set aside), and every orbit view sees it; a flat shape
    beside a large object (a floor under a crate) still does not matter."""
    import mitsuba as mi

    from mi_npr import views
    from mi_npr.camera import objects_that_matter, sensor_for
    from mi_npr.session import SceneSession

    def scene(stage_at):
        return {
            "type": "scene",
            "disk": {"type": "disk", "to_world": mi.ScalarTransform4f().translate([0, 0, 1])},
            "stage": {
                "type": "cube",
                "to_world": mi.ScalarTransform4f().translate(stage_at).scale([8, 8, 4]),
            },
        }

    assert [s.id() for s in objects_that_matter(mi.load_dict(scene([0, 0, 3])))] == ["disk"]
    # the same box beside the disk, not around it: an object; the flat disk then does not count
    assert [s.id() for s in objects_that_matter(mi.load_dict(scene([30, 0, 3])))] == ["stage"]
    path = tmp_path / "disk.xml"
    path.write_text(
        '<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="40"/>'
        '<transform name="to_world"><lookat origin="3, -3, 4" target="0, 0, 1" up="0, 0, 1"/>'
        '</transform><film type="hdrfilm"><integer name="width" value="32"/>'
        '<integer name="height" value="24"/></film></sensor>'
        '<shape type="disk" id="disk"><transform name="to_world"><translate z="1"/></transform>'
        '<bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>'
        '<shape type="cube" id="stage"><transform name="to_world"><scale x="8" y="8" z="4"/>'
        '<translate z="3"/></transform></shape></scene>'
    )
    s = SceneSession.open(path)
    disk = s.objects.id_of("disk")
    for vid, cam in views.cameras(views.parse_views("orbit:4"), s.scene, s.sensor):
        np.testing.assert_allclose(cam.target, [0, 0, 1], atol=1e-6)
        gb = mi_npr.render(s.scene, sensor=sensor_for(cam, s.sensor), spp=1)
        assert (gb.object_id == disk).sum() > 20, vid
