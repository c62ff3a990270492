"""``-D integrator=npr_lines`` on a scene whose own integrator has settings npr_lines does not
take (``max_depth``, ``rr_depth``, ``hide_emitters``): the scene's integrator, with those
settings, stays the beauty and the lines are drawn on it."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import cli

from .helpers import scene_xml

BODY = """
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="sphere"><point name="center" x="0" y="0" z="4"/><float name="radius" value="1"/>
        <bsdf type="diffuse"/></shape>"""
# max_depth 1: camera rays see only emitters; hide_emitters hides those too: a black beauty
# that no other integrator (npr_lines' headlight, a default path) would give.
OWN = """<integrator type="$integrator">
        <integer name="max_depth" value="1"/>
        <integer name="rr_depth" value="5"/>
        <boolean name="hide_emitters" value="true"/>
    </integrator>"""


def _scene(tmp_path, integrator=OWN, default='<default name="integrator" value="path"/>'):
    text = scene_xml(BODY, width=32, height=24, integrator=integrator)
    path = tmp_path / "ball.xml"
    path.write_text(text.replace('<scene version="3.0.0">', f'<scene version="3.0.0">{default}'))
    return path


def test01_the_scene_alone_renders_with_its_path_integrator(tmp_path):
    scene = mi_npr.load_scene(_scene(tmp_path))
    assert scene.integrator().class_name() == "PathIntegrator"
    assert float(np.max(np.asarray(mi_npr.mi.render(scene)))) == 0.0  # black, as argued above


def test02_cli_define_keeps_the_scene_integrator_as_beauty(tmp_path):
    out = tmp_path / "o"
    args = ["render", str(_scene(tmp_path)), "-D", "integrator=npr_lines", "-o", str(out)]
    assert cli.main([*args, "--no-progress"]) == 0
    gb = mi_npr.io.read_exr(out / "ball.exr")
    beauty = np.stack([np.asarray(gb[f"beauty.{c}"]) for c in "RGB"])
    assert float(beauty.max()) == 0.0  # the scene's path integrator, max_depth 1, hidden sky
    ink = np.asarray(gb["lines.V"])
    assert ink.max() > 0.5  # the sphere's outline is drawn
    ids = np.asarray(gb["object_id.V"])
    assert (ids > 0).sum() > 20


def test03_load_scene_hands_the_settings_to_the_nested_beauty(tmp_path):
    scene = mi_npr.load_scene(_scene(tmp_path), integrator="npr_lines")
    integ = scene.integrator()
    assert integ.PLUGIN == "npr_lines"
    assert integ.beauty.class_name() == "PathIntegrator"
    assert "max_depth = 1" in str(integ.beauty) and "rr_depth = 5" in str(integ.beauty)


def test04_npr_lines_written_in_the_file_still_refuses_unknown_settings(tmp_path):
    written = OWN.replace("$integrator", "npr_lines")
    with pytest.raises(
        mi_npr.SceneError, match=r"unknown parameter .(max_depth|rr_depth|hide_emitters)"
    ):
        mi_npr.load_scene(_scene(tmp_path, integrator=written, default=""))


def test05_a_misspelt_npr_setting_is_still_an_error(tmp_path):
    """The beauty takes only what the scene's integrator accepts: a name neither knows fails."""
    bad = OWN.replace('name="rr_depth"', 'name="line_widht"')
    with pytest.raises(mi_npr.SceneError, match="line_widht"):
        mi_npr.load_scene(_scene(tmp_path, integrator=bad), integrator="npr_lines")
