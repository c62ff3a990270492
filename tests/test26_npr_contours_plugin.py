"""The npr_contours integrator from XML: mi.render's tensor, mi_npr.render's layers, errors."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.contours import mode_ids, trace

from .helpers import SCENES

BALLS = (
    '<shape type="sphere" id="ball"><point name="center" x="0.5" y="0" z="4"/></shape>'
    '<shape type="sphere" id="back"><point name="center" x="-0.6" y="0.2" z="6"/></shape>'
    '<emitter type="constant"/>'
)


def _xml(params: str = "", nested: str = '<integrator type="direct"/>') -> str:
    return f'<integrator type="npr_contours">{params}{nested}</integrator>'


def test01_mi_render_channels(write_scene):
    scene = mi_npr.load_scene(write_scene(BALLS, integrator=_xml(), spp=2))
    integ = scene.integrator()
    assert integ.aov_names() == [L.CONTOUR, *L.GBUFFER_AOVS, *L.RAW_RGB]
    img = np.asarray(mi_npr.mi.render(scene, seed=1))
    assert img.shape == (24, 32, 3 + len(integ.aov_names()))
    gb = mi_npr.render(scene, seed=1)
    for i, name in enumerate([*L.RGB, *integ.aov_names()]):
        np.testing.assert_array_equal(img[..., i], gb.numpy(name).astype(np.float32), err_msg=name)
    ref = np.zeros(gb.shape, np.uint32)
    for c in trace(gb):
        ref[c.ys, c.xs] = c.object_id
    # the layer keeps the traced pixels on the side that owns each edge (1 px between
    # touching objects; tests/test66 checks the exact rule against a brute-force reference).
    on = gb.numpy(L.CONTOUR) != 0
    assert on.sum() > 0.6 * (ref != 0).sum()
    np.testing.assert_array_equal(gb.numpy(L.CONTOUR)[on], ref[on])
    assert np.all(gb.beauty[on] == [1, 0, 0])
    np.testing.assert_array_equal(gb.stack(L.RAW_RGB)[~on], gb.beauty[~on])
    assert gb.metadata["mi_npr/integrator"] == "npr_contours"


def test02_parameters(write_scene):
    xml = _xml(
        '<string name="method" value="code_direction"/><string name="id_mode" value="component"/>'
        '<rgb name="color" value="0, 0.5, 1"/>'
    )
    scene = mi_npr.load_scene(write_scene(BALLS, integrator=xml))
    gb = mi_npr.render(scene)
    assert gb.metadata["mi_npr/contour_method"] == "code_direction"
    assert gb.metadata["mi_npr/contour_id_mode"] == "component"
    on = gb.numpy(L.CONTOUR) != 0
    np.testing.assert_allclose(gb.beauty[on], np.tile([0, 0.5, 1], (on.sum(), 1)))
    assert "method='code_direction'" in str(scene.integrator())


def test03_without_nested_integrator(write_scene):
    gb = mi_npr.render(write_scene(BALLS, integrator=_xml(nested="")))
    assert gb.metadata["mi_npr/beauty"] == "headlight" and (gb.numpy(L.CONTOUR) != 0).any()


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ('<string name="method" value="moore"/>', "npr_contours: parameter 'method' = 'moore'"),
        ('<string name="id_mode" value="mesh"/>', "npr_contours: parameter 'id_mode' = 'mesh'"),
        ('<float name="width" value="2"/>', "npr_contours: unknown parameter 'width'"),
    ],
)
def test04_bad_parameters(write_scene, params, message):
    path = write_scene(BALLS, integrator=_xml(params))
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    assert message in str(e.value) and "\n" not in str(e.value)


def test05_scene_default_switches_integrator():
    """The paper scenes take the integrator from a <default>: -D integrator=npr_contours."""
    path = SCENES / "fig9_sphere_cube.xml"
    gb = mi_npr.render(path, width=48, height=36, spp=1, integrator="npr_contours")
    scene = mi_npr.load_scene(path, width=48, height=36, spp=1)
    ids, _ = mode_ids(gb, scene, "shape")
    mask, on = mi_npr.contours.contour_mask(ids), gb.numpy(L.CONTOUR) != 0
    assert np.all(mask[on]) and on.sum() > 0  # one side of each edge, not the frame
