"""The npr_raytree plugin as Mitsuba sees it: XML parameters, mi.render's tensor, the overlay on
the nested beauty, mi_npr.raytree.render on any scene, errors."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.raytree import COLORS, LAYERS, raytree_layers

SCENE = (
    '<shape type="sphere" id="glass"><point name="center" x="0.5" y="0" z="5"/>'
    '<float name="radius" value="0.9"/><bsdf type="dielectric"/></shape>'
    '<shape type="sphere" id="mirror_ball"><point name="center" x="-1.2" y="0.2" z="6"/>'
    '<float name="radius" value="0.8"/><bsdf type="conductor"/></shape>'
    '<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>'
    '<scale value="8"/><translate y="-1"/></transform><bsdf type="diffuse"/></shape>'
    '<emitter type="point" id="key"><point name="position" x="-2" y="4" z="2"/></emitter>'
)


def _numpy(layers):
    """The ray-tree layers (Dr.Jit tensors) as numpy arrays, for the references."""
    return {k: np.asarray(v) for k, v in layers.items()}


def raytree_integrator(depth=None, nested='<integrator type="direct"/>'):
    d = "" if depth is None else f'<integer name="max_depth" value="{depth}"/>'
    return f'<integrator type="npr_raytree">{d}{nested}</integrator>'


def test01_mi_render_returns_beauty_then_aovs(write_scene):
    scene = mi_npr.load_scene(write_scene(SCENE, integrator=raytree_integrator(), spp=2))
    integ = scene.integrator()
    names = integ.aov_names()
    assert names == [*LAYERS, *L.GBUFFER_AOVS, *L.RAW_RGB]
    img = np.asarray(mi_npr.mi.render(scene, seed=2).numpy())
    assert img.shape == (24, 32, 3 + len(names))
    gb = mi_npr.render(scene, seed=2)
    for i, name in enumerate([*L.RGB, *names]):
        # integer layers become float32 in the tensor (the 32-bit hash halves are rounded)
        np.testing.assert_array_equal(img[..., i], gb.numpy(name).astype(np.float32), err_msg=name)
    assert gb.metadata["mi_npr/integrator"] == "npr_raytree"
    assert gb.metadata["mi_npr/raytree_max_depth"] == "3"
    assert gb.numpy(L.RAYTREE_HI).dtype == np.uint32 and gb.numpy(L.EDGES_REAL).dtype == np.float32


def test02_overlay_colours_over_the_raw_beauty(write_scene):
    scene = mi_npr.load_scene(write_scene(SCENE, integrator=raytree_integrator(), spp=2))
    gb = mi_npr.render(scene, seed=1)
    ref = mi_npr.mi.load_dict({"type": "direct"}).render(scene, scene.sensors()[0], seed=1, spp=2)
    raw = gb.stack(L.RAW_RGB)
    np.testing.assert_array_equal(raw, np.asarray(ref.numpy())[..., :3])
    drawn = np.zeros(gb.shape, bool)
    for name, color in COLORS.items():
        m = gb.numpy(name) > 0
        assert m.any(), name  # the scene shows every class
        np.testing.assert_array_equal(gb.beauty[m], np.broadcast_to(color, (m.sum(), 3)))
        drawn |= m
    np.testing.assert_array_equal(gb.beauty[~drawn], raw[~drawn])


def test03_max_depth_parameter(write_scene):
    one_xml = write_scene(SCENE, integrator=raytree_integrator(1), name="one.xml")
    one = mi_npr.render(one_xml)
    three = mi_npr.render(write_scene(SCENE, integrator=raytree_integrator(), name="three.xml"))
    assert one.metadata["mi_npr/raytree_max_depth"] == "1"
    assert not one.numpy(L.EDGES_REFLECTION).any() and not one.numpy(L.EDGES_REFRACTION).any()
    assert three.numpy(L.EDGES_REFLECTION).any() and three.numpy(L.EDGES_REFRACTION).any()
    np.testing.assert_array_equal(one.numpy(L.EDGES_REAL), three.numpy(L.EDGES_REAL))
    # mi_npr.raytree.render reads the scene's max_depth, or takes its own
    assert mi_npr.render_raytree(one_xml) == one
    deeper = mi_npr.render_raytree(one_xml, max_depth=3)
    np.testing.assert_array_equal(deeper.numpy(L.EDGES_REFRACTION), three.numpy(L.EDGES_REFRACTION))


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ('<integer name="max_depth" value="0"/>', "'max_depth' = 0: must be in 1..31"),
        ('<integer name="max_depth" value="40"/>', "must be in 1..31"),
        ('<float name="max_depth" value="2.5"/>', "expected an integer"),
        ('<string name="max_depth" value="x"/>', "expected an integer"),
        ('<integer name="depth" value="3"/>', "unknown parameter 'depth'"),
    ],
)
def test04_bad_parameters_are_clear_errors(write_scene, param, message):
    path = write_scene(SCENE, integrator=f'<integrator type="npr_raytree">{param}</integrator>')
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    assert message in str(e.value) and "npr_raytree" in str(e.value)
    assert "\n" not in str(e.value)


def test05_raytree_render_on_any_scene(write_scene):
    plain = write_scene(SCENE, integrator='<integrator type="path"/>', name="plain.xml")
    gb = mi_npr.render_raytree(plain, spp=2)
    assert gb.metadata["mi_npr/beauty"] == "PathIntegrator"
    scene = mi_npr.load_scene(plain)
    lay = _numpy(raytree_layers(scene, 0, 3))
    for name in LAYERS:
        np.testing.assert_array_equal(gb.numpy(name), lay[name], err_msg=name)
    headlight = mi_npr.render_raytree(write_scene(SCENE, name="gbuf.xml"))  # npr_gbuffer, no beauty
    assert headlight.metadata["mi_npr/beauty"] == "headlight"
    with pytest.raises(mi_npr.ParameterError, match="max_depth"):
        mi_npr.render_raytree(plain, max_depth=0)
    with pytest.raises(mi_npr.SceneError, match="no such file"):
        mi_npr.render_raytree("no/such/scene.xml")


def test06_scalar_variants_get_a_clear_error(write_scene):
    path = write_scene(SCENE, integrator=raytree_integrator(), width=4, height=3)
    mi_npr.set_variant("scalar_rgb")
    with pytest.raises(mi_npr.ParameterError, match="JIT variant"):
        mi_npr.render(path)


def test07_sample_fallback_and_to_string(write_scene):
    mi = mi_npr.mi
    scene = mi_npr.load_scene(write_scene(SCENE, integrator=raytree_integrator(2)))
    integ = scene.integrator()
    assert "NprRayTreeIntegrator[beauty=DirectIntegrator, max_depth=2, " in str(integ)
    assert "cryptomatte=False" in str(integ)
    ray, _ = scene.sensors()[0].sample_ray(0.0, 0.5, mi.Point2f([0.5], [0.5]), mi.Point2f(0.5))
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(0, 1)
    _color, _valid, aovs = integ.sample(scene, sampler, mi.RayDifferential3f(ray))
    assert len(aovs) == len(integ.aov_names())


def test08_with_overlays_equals_chained_with_overlay():
    from mi_npr.compose import with_overlay, with_overlays

    rng = np.random.default_rng(8)
    h, w = 7, 5
    gb = mi_npr.GBuffer({c: rng.random((h, w), dtype=np.float32) for c in L.RGB})
    binary = (rng.random((h, w)) < 0.3).astype(np.float32)
    soft = rng.random((h, w)).astype(np.float32)
    soft[0, 0] = np.nan  # counts as 0
    layers = [(binary, (1, 0, 0)), (soft, (0, 0.5, 1)), (1 - binary, (0.2, 0.2, 0.2))]
    chained = gb
    for alpha, color in layers:
        chained = with_overlay(chained, alpha, color)
    once = with_overlays(gb, layers)
    for name in (*L.RGB, *L.RAW_RGB):
        np.testing.assert_allclose(once[name], chained[name], rtol=1e-6, err_msg=name)
    np.testing.assert_array_equal(once.stack(L.RAW_RGB), gb.beauty)
