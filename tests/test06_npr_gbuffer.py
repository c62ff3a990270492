"""The npr_gbuffer plugin as Mitsuba sees it: XML, mi.render's tensor, errors, variants."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L

BALL = (
    '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/>'
    '<bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.2, 0.1"/></bsdf></shape>'
    '<emitter type="constant"/>'
)
NESTED = '<integrator type="npr_gbuffer"><integrator type="path"/></integrator>'


def test01_mi_render_returns_beauty_then_aovs(write_scene):
    scene = mi_npr.load_scene(write_scene(BALL, integrator=NESTED, spp=4))
    integ = scene.integrator()
    assert integ.aov_names() == list(L.GBUFFER_AOVS)
    img = mi_npr.mi.render(scene, seed=3)
    assert tuple(img.shape) == (24, 32, 3 + len(L.GBUFFER_AOVS))
    gb = mi_npr.render(scene, seed=3)
    a = img.numpy()
    for i, name in enumerate([*L.RGB, *L.GBUFFER_AOVS]):
        np.testing.assert_array_equal(a[..., i], gb.numpy(name).astype(np.float32), err_msg=name)


def test02_beauty_is_the_nested_integrators_render(write_scene):
    scene = mi_npr.load_scene(write_scene(BALL, integrator=NESTED, spp=4))
    gb = mi_npr.render(scene, seed=1)
    path = mi_npr.mi.load_dict({"type": "path"})
    ref = path.render(scene, scene.sensors()[0], seed=1, spp=4).numpy()
    np.testing.assert_array_equal(gb.beauty, ref[..., :3])
    assert gb.metadata["mi_npr/beauty"] == "PathIntegrator"


def test03_headlight_without_nested_integrator(write_scene):
    gb = mi_npr.render(write_scene(BALL))
    hit = gb.numpy("object_id.V") == 1
    assert np.all(gb.numpy("R")[hit] > gb.numpy("G")[hit])  # the ball's red albedo shows
    assert np.all(gb.beauty[~hit] == 0)
    assert gb.metadata["mi_npr/beauty"] == "headlight"


def test04_spp_override(write_scene):
    scene = mi_npr.load_scene(write_scene(BALL, integrator=NESTED, spp=1))
    one = mi_npr.render(scene)
    many = mi_npr.render(scene, spp=64)
    assert many.metadata["mi_npr/spp"] == "64" and one.metadata["mi_npr/spp"] == "1"
    edge = mi_npr.render(scene)["object_id.V"]
    np.testing.assert_array_equal(edge, many["object_id.V"])  # ids do not depend on spp
    assert not np.array_equal(one.beauty, many.beauty)
    with pytest.raises(mi_npr.ParameterError, match="spp"):
        mi_npr.render(scene, spp=0)


@pytest.mark.parametrize(
    ("integrator", "message"),
    [
        (
            '<integrator type="npr_gbuffer"><float name="tt" value="1"/></integrator>',
            "npr_gbuffer: unknown parameter 'tt'",
        ),
        (
            '<integrator type="npr_gbuffer"><integrator type="path"/><integrator type="direct"/>'
            "</integrator>",
            "at most one nested",
        ),
    ],
)
def test05_bad_parameters_are_clear_errors(write_scene, integrator, message):
    path = write_scene(BALL, integrator=integrator)
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    assert message in str(e.value) and str(path) in str(e.value)
    assert "\n" not in str(e.value) and "Traceback" not in str(e.value)


def test06_plugins_follow_variant_changes(write_scene):
    path = write_scene(BALL, width=6, height=4)
    mi_npr.mi.set_variant("llvm_ad_rgb")
    mi_npr.mi.set_variant("llvm_ad_mono")  # a plain Mitsuba call: the callback registers
    gb = mi_npr.render(path)
    assert gb.metadata["mi_npr/variant"] == "llvm_ad_mono"
    mi_npr.mi.set_variant("llvm_ad_rgb")
    assert isinstance(mi_npr.load_scene(path).integrator(), mi_npr.mi.SamplingIntegrator)
    with pytest.raises(mi_npr.ParameterError, match="not available"):
        mi_npr.set_variant("no_such_variant")


def test07_to_string_and_sample_fallback(write_scene):
    mi = mi_npr.mi
    scene = mi_npr.load_scene(write_scene(BALL, integrator=NESTED))
    integ = scene.integrator()
    assert "NprGBufferIntegrator[beauty=PathIntegrator" in str(integ)
    sensor = scene.sensors()[0]
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f([0.5, 0.01], [0.5, 0.01]), mi.Point2f(0.5))
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(0, 2)
    _color, _valid, aovs = integ.sample(scene, sampler, mi.RayDifferential3f(ray))
    assert len(aovs) == len(integ.aov_names())
    ids = aovs[integ.aov_names().index("object_id.V")].numpy()
    np.testing.assert_array_equal(ids, [1, 0])
