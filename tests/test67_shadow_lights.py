"""Ray-tree shadow edges from hard-shadow lights only unless asked (--shadow-lights,
the npr_raytree shadow_lights parameter)."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import cli
from mi_npr import layers as L
from mi_npr.errors import ParameterError
from mi_npr.io import read_exr
from mi_npr.pipeline import render_layers
from mi_npr.raytree import light_table

from .public_style import ground

#: A sky and a small area light beside the point light "sun" of the ground scene.
SOFT = (
    '<emitter type="constant" id="sky"><rgb name="radiance" value="0.2"/></emitter>'
    '<shape type="sphere" id="bulb"><point name="center" x="-1.5" y="1.5" z="1.5"/>'
    '<float name="radius" value="0.2"/><emitter type="area" id="panel">'
    '<rgb name="radiance" value="5"/></emitter></shape>'
)


def test01_light_table_choices(tmp_path):
    scene = mi_npr.load_scene(ground(tmp_path, SOFT))
    objects = mi_npr.object_table(scene)
    assert list(light_table(scene, objects, "hard").names.values()) == ["sun"]
    assert list(light_table(scene, objects, "all").names.values()) == ["panel", "sky", "sun"]
    assert list(light_table(scene, objects, "s*").names.values()) == ["sky", "sun"]
    assert list(light_table(scene, objects, "panel, sun").names.values()) == ["panel", "sun"]
    with pytest.raises(ParameterError, match="no light named 'moon'"):
        light_table(scene, objects, "moon")


def test02_soft_lights_add_shadow_edges_only_when_asked(tmp_path):
    path = ground(tmp_path, SOFT)
    size = {"resolution": (48, 32)}
    hard = render_layers(path, ["raytree"], **size).gbuffer
    sun = render_layers(path, ["raytree"], {"shadow_lights": "sun"}, **size).gbuffer
    every = render_layers(path, ["raytree"], {"shadow_lights": "all"}, **size).gbuffer
    np.testing.assert_array_equal(hard.numpy(L.EDGES_SHADOW), sun.numpy(L.EDGES_SHADOW))
    assert hard.numpy(L.EDGES_SHADOW).any()
    assert every.numpy(L.EDGES_SHADOW).sum() > hard.numpy(L.EDGES_SHADOW).sum()
    assert hard.metadata["mi_npr/raytree_shadow_lights"] == "hard"


def test03_flag_and_plugin_parameter(tmp_path):
    path = ground(tmp_path, SOFT)
    out = tmp_path / "out"
    args = ["raytree", str(path), "-o", str(out), "--no-progress"]
    assert cli.main([*args, "--shadow-lights", "all"]) == 0
    flag = read_exr(out / "ground_raytree.exr")
    xml = path.read_text().replace(
        '<integrator type="path"><integer name="max_depth" value="2"/></integrator>',
        '<integrator type="npr_raytree"><string name="shadow_lights" value="all"/>'
        '<integrator type="path"><integer name="max_depth" value="2"/></integrator>'
        "</integrator>",
    )
    path.write_text(xml)
    gb = mi_npr.render(path)
    np.testing.assert_array_equal(gb.numpy(L.EDGES_SHADOW), flag.numpy(L.EDGES_SHADOW))
    assert gb.metadata["mi_npr/raytree_shadow_lights"] == "all"
