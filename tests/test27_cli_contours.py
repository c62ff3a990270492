"""mi-npr contours: PNG with red contours, SVG, EXR with the contour layer; errors."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import cli
from mi_npr import layers as L
from mi_npr.io import read_exr

from .helpers import SCENES, run_cli, scene_xml

BALLS = (
    '<shape type="sphere" id="ball"><point name="center" x="0.5" y="0" z="4"/></shape>'
    '<shape type="sphere" id="back"><point name="center" x="-0.6" y="0.2" z="6"/></shape>'
    '<emitter type="constant"/>'
)
SVG = "{http://www.w3.org/2000/svg}"


@pytest.fixture
def balls(tmp_path) -> Path:
    p = tmp_path / "balls.xml"
    nested = '<integrator type="npr_gbuffer"><integrator type="direct"/></integrator>'
    p.write_text(scene_xml(BALLS, integrator=nested, spp=2))
    return p


def test01_writes_png_svg_exr(balls, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["contours", str(balls), "-o", str(out), "--spp", "3", "--no-progress"]) == 0
    assert sorted(os.listdir(out)) == [
        "balls_contours.exr",
        "balls_contours.png",
        "balls_contours.svg",
    ]
    gb = read_exr(out / "balls_contours.exr")
    assert {L.CONTOUR, *L.GBUFFER, *L.RAW_RGB} <= set(gb.names)
    assert gb.numpy(L.CONTOUR).dtype == np.uint32 and gb.metadata["mi_npr/spp"] == "3"
    on = gb.numpy(L.CONTOUR) != 0
    assert set(np.unique(gb.numpy(L.CONTOUR)[on])) == {1, 2}
    png = np.asarray(Image.open(out / "balls_contours.png"))
    assert png.shape == (24, 32, 3) and np.all(png[on] == [255, 0, 0])
    root = ET.parse(out / "balls_contours.svg").getroot()
    assert [g.get("id") for g in root.findall(f"{SVG}g/{SVG}g")] == ["back", "ball"]
    assert root.find(f".//{SVG}image") is not None
    assert "balls_contours.svg" in capsys.readouterr().out


def test02_options(balls, tmp_path):
    out = tmp_path / "out"
    args = ["contours", str(balls), "-o", str(out), "--no-beauty-in-svg", "--no-progress"]
    args += ["--method", "code_direction", "--id-mode", "primitive", "-D", "unused=1"]
    assert cli.main(args) == 1  # Mitsuba rejects unused defines: one line, not a traceback
    assert cli.main(args[:-2]) == 0
    gb = read_exr(out / "balls_contours.exr")
    assert gb.metadata["mi_npr/contour_method"] == "code_direction"
    assert gb.metadata["mi_npr/contour_id_mode"] == "primitive"
    assert ET.parse(out / "balls_contours.svg").getroot().find(f".//{SVG}image") is None


def test03_xml_settings_are_the_defaults(tmp_path):
    p = tmp_path / "c.xml"
    xml = '<integrator type="npr_contours"><string name="id_mode" value="component"/></integrator>'
    p.write_text(scene_xml(BALLS, integrator=xml))
    out = tmp_path / "out"
    assert cli.main(["contours", str(p), "-o", str(out)]) == 0
    assert read_exr(out / "c_contours.exr").metadata["mi_npr/contour_id_mode"] == "component"
    assert cli.main(["contours", str(p), "-o", str(out), "--id-mode", "shape"]) == 0
    assert read_exr(out / "c_contours.exr").metadata["mi_npr/contour_id_mode"] == "shape"


def test04_errors(balls, tmp_path):
    broken = tmp_path / "broken.xml"
    broken.write_text("<scene version='3.0.0'><shape type='sphere'>")
    r = run_cli("contours", str(balls), str(broken), "-o", str(tmp_path / "o"), "--no-progress")
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert str(broken) in r.stderr and "1 of 2 inputs failed" in r.stderr
    assert (tmp_path / "o" / "balls_contours.png").exists()
    r = run_cli("contours", str(balls), "-o", str(tmp_path / "o"), "--method", "moore")
    assert r.returncode == 2 and "'method' = 'moore': expected one of border" in r.stderr


def test05_cli_flags_are_the_plugins_parameters():
    """The flags are generated from npr_contours' PARAMS (same names)."""
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices["contours"]
    flags = {o for a in sub._actions for o in a.option_strings}
    from mi_npr.drawings import DRAWINGS

    for p in DRAWINGS["contours"].params:
        assert "--" + p.name.replace("_", "-") in flags
    assert set(mi_npr.contours.ID_MODES) >= {"material", "silhouette"}
    assert {a.dest: tuple(a.choices) for a in sub._actions if a.choices} == {
        "svg_image": mi_npr.io.svg.SVG_IMAGE
    }


def test06_paper_scene(tmp_path):
    out = tmp_path / "out"
    args = ["contours", str(SCENES / "scene1.xml"), "-o", str(out), "-D", "width=64"]
    assert cli.main([*args, "-D", "height=48", "--spp", "1"]) == 0
    gb = read_exr(out / "scene1_contours.exr")
    assert gb.shape == (48, 64) and (gb.numpy(L.CONTOUR) != 0).sum() > 100
