"""``mi-npr info SCENE.xml``: a scene's defaults, integrator, sensor, objects, materials and
lights, from a scene written here (every expected value is in its XML)."""

from __future__ import annotations

import json
import math

import pytest

from mi_npr import cli
from mi_npr.describe import describe_scene

SCENE = """<scene version="3.0.0">
    <default name="spp" value="3"/>
    <default name="r" value="0.5"/>
    <integrator type="npr_lines"><integrator type="direct"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <transform name="to_world">
            <lookat origin="0, 0, -4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="40"/><integer name="height" value="30"/>
        </film>
    </sensor>
    <bsdf type="diffuse" id="clay"/>
    <shape type="sphere" id="ball"><float name="radius" value="$r"/><ref id="clay"/></shape>
    <shape type="cube" id="box"><ref id="clay"/></shape>
    <shape type="rectangle" id="floor"><bsdf type="conductor"/></shape>
    <emitter type="point" id="key"><point name="position" x="0" y="3" z="0"/></emitter>
    <emitter type="constant"/>
</scene>
"""


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "room.xml"
    p.write_text(SCENE)
    return p


def test01_describe_scene(scene):
    info = describe_scene(scene, {"r": 0.25})
    assert info["defaults"] == {
        "spp": {"file": "3", "used": "3"},
        "r": {"file": "0.5", "used": "0.25"},
    }
    assert info["integrator"]["type"] == "npr_lines" and info["integrator"]["beauty"]
    (s,) = info["sensors"]
    assert s["resolution"] == [40, 30] and s["spp"] == 3 and s["kind"] == "perspective"
    assert math.isclose(s["fov"], 50.0, rel_tol=1e-6)
    assert s["origin"] == pytest.approx([0, 0, -4]) and s["direction"] == pytest.approx([0, 0, 1])
    # object ids are sorted by name (the object table's rule); the cube is a 12-triangle mesh
    objects = {o["name"]: (k, o["material"], o["primitives"]) for k, o in info["objects"].items()}
    assert objects["ball"] == ("1", "clay", 1)
    assert objects["box"] == ("2", "clay", 12)
    assert objects["floor"][:2] == ("3", "floor.bsdf")
    assert sorted(info["materials"].values()) == ["clay", "floor.bsdf"]
    assert [e["name"] for e in info["emitters"]] == ["key", "constantbackgroundemitter_1"]


def test02_the_command_lists_it(scene, capsys):
    assert cli.main(["info", str(scene), "--json", "-D", "spp=5"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["sensors"][0]["spp"] == 5 and info["defaults"]["spp"]["used"] == "5"
    assert cli.main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    for words in ("objects (3; 0 is the background)", "1: ball (Sphere", "key (PointLight)"):
        assert words in out
    assert cli.main(["info", "scene1"]) == 0  # a bundled scene by name
    assert "sphere_left" in capsys.readouterr().out


def test03_a_broken_scene_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='nosuchshape'/></scene>")
    assert cli.main(["info", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mi-npr: error: ") and "bad.xml" in err and "\n" not in err
