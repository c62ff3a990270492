"""mi-npr best-view: the written sensor loads in Mitsuba and reproduces the rated view."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import cli
from mi_npr.viewpoint import entropy, pb, polygons

from .helpers import run_cli
from .test41_viewpoint_idbuffer import gbuffer_areas

BODY = (
    '<shape type="cube" id="box"><transform name="to_world"><scale x="0.8" y="0.5" z="0.6"/>'
    '<rotate y="1" angle="20"/></transform></shape>'
    '<shape type="sphere" id="ball"><point name="center" x="1.2" y="0.3" z="0.4"/>'
    '<float name="radius" value="0.4"/></shape>'
    '<emitter type="constant"/>'
)
NESTED = '<integrator type="npr_gbuffer"><integrator type="direct"/></integrator>'


@pytest.fixture
def scene_path(write_scene):
    return write_scene(
        BODY,
        name="toy.xml",
        width=40,
        height=30,
        fov=50.0,
        spp=2,
        rfilter="gaussian",
        integrator=NESTED,
        origin="2, 3, -5",
        target="0, 0, 0",
    )


def _run(capsys, *args):
    code = cli.main(["best-view", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("measure", ["entropy", "pb"])
def test01_writes_a_sensor_that_reproduces_the_view(scene_path, tmp_path, capsys, measure):
    out = tmp_path / "out"
    code, stdout, err = _run(
        capsys, scene_path, "--measure", measure, "--depth", "2", "--res", "40", "-o", out, "--json"
    )
    assert code == 0, err
    info = json.loads(stdout)
    assert sorted(p.name for p in out.iterdir()) == [
        "toy_best_view.png",
        "toy_best_view.xml",
        "toy_quality_sphere.png",
    ]
    assert 12 < info["evaluations"] <= 40 and info["measure"] == measure
    assert info["res"] == [40, 30]
    assert set(info["outputs"]) == {"sensor", "render", "sphere"}
    # The file loads in Mitsuba on its own: one perspective sensor at the best view.
    mi = mi_npr.mi
    cam_scene = mi.load_file(str(out / "toy_best_view.xml"))
    (sensor,) = cam_scene.sensors()
    cam = mi_npr.projection_of(sensor)
    np.testing.assert_allclose(cam.origin, info["origin"], atol=1e-5)
    np.testing.assert_allclose(cam.up, info["up"], atol=1e-5)
    assert cam.fov == pytest.approx(50.0) and cam.resolution == (40, 30)
    assert sensor.sampler().sample_count() == 2
    assert sensor.film().rfilter().class_name() == "GaussianFilter"
    # Rendered from it, the scene's ID buffer gives the quality the search reported.
    scene = mi_npr.load_scene(scene_path)
    gb = mi_npr.render_gbuffer(scene, sensor)
    a = gbuffer_areas(scene, gb)
    assert len(a) == polygons(scene).n + 1
    q = {"entropy": entropy, "pb": pb}[measure](a)
    assert q == pytest.approx(info["quality"], rel=1e-9)
    # The PNGs: the render at the film's size, the sphere picture in colour.
    assert np.asarray(Image.open(out / "toy_best_view.png")).shape == (30, 40, 3)
    sphere = np.asarray(Image.open(out / "toy_quality_sphere.png"))
    assert sphere.ndim == 3 and len(np.unique(sphere.reshape(-1, 3), axis=0)) > 50


def test02_include_and_paste(scene_path, tmp_path, capsys):
    out = tmp_path / "o"
    code, stdout, _ = _run(capsys, scene_path, "--measure", "curvature", "--depth", "1", "-o", out)
    assert code == 0 and "quality" in stdout and "toy_best_view.xml" in stdout
    text = (out / "toy_best_view.xml").read_text()
    assert 'id="best_view"' in text and "<lookat" in text
    mi = mi_npr.mi
    src = Path(scene_path).read_text()
    # <include> adds the sensor to the scene (as its second sensor here).
    included = src.replace("</scene>", f'<include filename="{out / "toy_best_view.xml"}"/></scene>')
    (tmp_path / "inc.xml").write_text(included)
    assert len(mi.load_file(str(tmp_path / "inc.xml")).sensors()) == 2
    # Pasting the <sensor> element in place of the scene's own works too.
    element = re.search(r"<sensor .*?</sensor>", text, re.S).group(0)
    pasted = re.sub(r"<sensor .*?</sensor>", element, src, flags=re.S)
    (tmp_path / "paste.xml").write_text(pasted)
    s = mi.load_file(str(tmp_path / "paste.xml"))
    assert s.sensors()[0].id() == "best_view"
    ET.fromstring(text.split("?>", 1)[1])  # well-formed


def test03_defines_and_a_user_run(tmp_path, scenes):
    out = tmp_path / "o"
    res = run_cli(
        "best-view",
        str(scenes / "scene4.xml"),
        "--measure",
        "entropy",
        "--depth",
        "1",
        "--res",
        "24",
        "-D",
        "width=32",
        "-D",
        "height=24",
        "-D",
        "spp=1",
        "-o",
        str(out),
        "--json",
    )
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout)
    assert info["res"] == [24, 18] and info["quality"] > 0
    assert np.asarray(Image.open(out / "scene4_best_view.png")).shape == (24, 32, 3)


def test04_usage_and_input_errors(scene_path, tmp_path, capsys):
    out = tmp_path / "o"
    for bad in (
        [scene_path, "-o", out],  # --measure is required
        [scene_path, "--measure", "beauty", "-o", out],
        [scene_path, "--measure", "pb", "--depth", "-1", "-o", out],
        [scene_path, "--measure", "pb", "--res", "0", "-o", out],
    ):
        with pytest.raises(SystemExit) as e:
            cli.main(["best-view", *map(str, bad)])
        assert e.value.code == 2
    capsys.readouterr()
    code, _, err = _run(capsys, tmp_path / "missing.xml", "--measure", "pb", "-o", out)
    assert code == 1 and "missing.xml" in err and "Traceback" not in err
    empty = tmp_path / "empty.xml"
    empty.write_text('<scene version="3.0.0"><emitter type="constant"/></scene>')
    code, _, err = _run(capsys, empty, "--measure", "pb", "-o", out)
    assert code == 1 and "nothing to look at" in err
    assert not out.exists() or not any(out.iterdir())


def test05_a_scene_without_sensor(tmp_path, capsys):
    """Nothing to copy: a square 45 degree view, a 512-pixel film, 16 spp."""
    bare = tmp_path / "bare.xml"
    bare.write_text('<scene version="3.0.0"><shape type="cube"/></scene>')
    out = tmp_path / "o"
    code, stdout, err = _run(capsys, bare, "--measure", "entropy", "--depth", "1", "--res", "16",
                             "-o", out, "--json")  # fmt: skip
    assert code == 0, err
    info = json.loads(stdout)
    assert info["fov"] == 45.0 and info["res"] == [16, 16]
    (sensor,) = mi_npr.mi.load_file(str(out / "bare_best_view.xml")).sensors()
    assert mi_npr.projection_of(sensor).resolution == (512, 512)
    assert sensor.sampler().sample_count() == 16


def test06_a_crop_window_does_not_change_the_rated_view(scene_path, tmp_path, capsys):
    # The view is rated over the whole film (its fov is the whole film's): the written sensor
    # has the whole film, no crop, and reproduces the quality the search reported.
    text = scene_path.read_text().replace(
        '<integer name="height" value="30"/>',
        '<integer name="height" value="30"/><integer name="crop_width" value="20"/>'
        '<integer name="crop_height" value="10"/>',
    )
    cropped = tmp_path / "cropped.xml"
    cropped.write_text(text)
    out = tmp_path / "out"
    code, stdout, err = _run(
        capsys, cropped, "--measure", "pb", "--depth", "1", "--res", "40", "-o", out, "--json"
    )
    assert code == 0, err
    info = json.loads(stdout)
    assert info["res"] == [40, 30]
    (sensor,) = mi_npr.mi.load_file(str(out / "cropped_best_view.xml")).sensors()
    assert tuple(sensor.film().crop_size()) == (40, 30)
    scene = mi_npr.load_scene(cropped)
    a = gbuffer_areas(scene, mi_npr.render_gbuffer(scene, sensor))
    assert pb(a) == pytest.approx(info["quality"], rel=1e-9) and info["quality"] > 0


def test07_spp_read_before_an_include_declares_it(tmp_path, capsys):
    """mitsuba-data's ``sensor_thinlens.xml``: the sensor reads ``$spp`` before the include that
    declares its default, so the scene loads only with ``spp`` defined up front; ``--spp``
    defines it as ``render``'s does, and the written sensor takes it."""
    (tmp_path / "inc.xml").write_text(
        '<scene version="3.0.0"><default name="spp" value="8"/>' + BODY + "</scene>"
    )
    scene = tmp_path / "early.xml"
    scene.write_text(
        '<scene version="3.0.0"><sensor type="perspective">'
        '<transform name="to_world"><lookat origin="2, 3, -5" target="0, 0, 0" up="0, 1, 0"/>'
        '</transform><sampler type="independent"><integer name="sample_count" value="$spp"/>'
        '</sampler><film type="hdrfilm"><integer name="width" value="40"/>'
        '<integer name="height" value="30"/></film></sensor>'
        '<include filename="inc.xml"/></scene>'
    )
    with pytest.raises(RuntimeError, match="spp"):  # Mitsuba's own loader, no define
        mi_npr.mi.load_file(str(scene))
    out = tmp_path / "o"
    code, _, err = _run(capsys, scene, "--measure", "entropy", "--depth", "1", "--res", "16",
                        "--spp", "3", "--width", "20", "-o", out)  # fmt: skip
    assert code == 0, err
    (sensor,) = mi_npr.mi.load_file(str(out / "early_best_view.xml")).sensors()
    assert sensor.sampler().sample_count() == 3
    assert mi_npr.projection_of(sensor).resolution == (20, 15)
