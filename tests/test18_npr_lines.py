"""The npr_lines plugin as Mitsuba sees it: mi.render's layout, compositing, XML parameters."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr import layers as L
from mi_npr.antialias import antialiased_lines
from mi_npr.compose import over

mi = mi_npr.mi

BALL = (
    '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/>'
    '<bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.6, 0.1"/></bsdf></shape>'
    '<shape type="rectangle" id="wall"><transform name="to_world">'
    '<scale value="30"/><translate z="20"/></transform></shape>'
    '<emitter type="constant"/>'
)


def lines_integrator(*params: str, nested: str = '<integrator type="direct"/>') -> str:
    return f'<integrator type="npr_lines">{"".join(params)}{nested}</integrator>'


def test01_all_background_closed_form(write_scene):
    gb = mi_npr.render(write_scene("", integrator=lines_integrator()))
    assert not gb.numpy(L.LINES).any() and gb.numpy(L.LINES).dtype == np.float32
    np.testing.assert_array_equal(gb.beauty, gb.stack(L.RAW_RGB))  # nothing drawn


def test02_mi_render_returns_composited_beauty_lines_then_gbuffer(write_scene):
    scene = mi_npr.load_scene(write_scene(BALL, integrator=lines_integrator(), spp=2))
    integ = scene.integrator()
    assert integ.aov_names() == [L.LINES, *L.GBUFFER_AOVS, *L.RAW_RGB]
    img = mi.render(scene, seed=2)
    names = [*L.RGB, L.LINES, *L.GBUFFER_AOVS, *L.RAW_RGB]
    assert tuple(img.shape) == (24, 32, len(names))
    gb = mi_npr.render(scene, seed=2)
    a = np.asarray(img)
    for i, name in enumerate(names):
        np.testing.assert_array_equal(a[..., i], gb.numpy(name).astype(np.float32), err_msg=name)
    ink = gb.numpy(L.LINES)
    # Anti-aliased by default: gray levels, within a pixel of the ball's outline.
    ball = gb.object_id == 1
    near_ball = ball | np.roll(ball, 1, 0) | np.roll(ball, -1, 0)
    near_ball |= np.roll(near_ball, 1, 1) | np.roll(near_ball, -1, 1)
    assert ink.max() == 1.0 and np.all(near_ball[ink > 0]) and 0 < ink[ink > 0].min() < 0.5
    expected = antialiased_lines(scene, scene.sensors()[0], gb, 3)  # the library's chain
    np.testing.assert_array_equal(ink, expected)
    # Black lines over the raw beauty, which stays in beauty.R/G/B.
    np.testing.assert_allclose(gb.beauty, over(gb.stack(L.RAW_RGB), ink, (0, 0, 0)), atol=1e-6)
    assert np.all(gb.beauty[ink == 1.0] == 0.0)
    assert "mi_npr/lines" in gb.metadata and gb.metadata["mi_npr/integrator"] == "npr_lines"


def test03_parameters_reach_the_chain(write_scene):
    params = (
        '<float name="c" value="10"/>',
        '<float name="t" value="0.25"/>',
        '<float name="t0" value="0.3"/>',
        '<integer name="dilation_size" value="5"/>',
        '<integer name="dilation_iterations" value="2"/>',
        '<boolean name="remove_isolated" value="false"/>',
        '<boolean name="id_edges" value="true"/>',
        '<float name="crease_angle" value="155"/>',
        '<rgb name="line_color" value="1, 0, 0"/>',
        '<integer name="line_aa" value="1"/>',
        '<float name="near" value="1"/>',
        '<float name="far" value="30"/>',
    )
    scene = mi_npr.load_scene(write_scene(BALL, integrator=lines_integrator(*params)))
    gb = mi_npr.render(scene)
    expected = K.lines(
        gb,
        c=10.0,
        t=0.25,
        t0=0.3,
        dilation_size=5,
        dilation_iterations=2,
        remove_isolated=False,
        id_edges=True,
        crease_angle=155.0,
        near=1.0,
        far=30.0,
    )
    np.testing.assert_array_equal(gb.numpy(L.LINES), np.asarray(expected))
    drawn = gb.numpy(L.LINES) == 1.0
    assert np.all(gb.numpy("R")[drawn] == 1.0) and np.all(gb.numpy("G")[drawn] == 0.0)  # red lines
    assert "line_color=(1.0, 0.0, 0.0)" in str(scene.integrator())


def test04_defaults_are_the_chains_defaults():
    integ = mi.load_dict({"type": "npr_lines"})
    chain = [p.name for p in K.LINES_PARAMS]  # ... line_width, bright_fade, near, far
    own = ["line_color", "line_aa"]
    sel = ["id_mode", "only", "ignore"]  # object selection
    model = ["line_model"]  # what draws the lines, first
    assert [p.name for p in integ.PARAMS] == [*model, *chain[:-2], *own, *chain[-2:], *sel]
    defaults = {p.name: p.default for p in K.LINES_PARAMS}
    own = [*model, "line_color", "line_aa", "cryptomatte"]  # the plugin's own and every one's
    assert {k: v for k, v in integ.params.items() if k not in own + sel} == defaults
    assert integ.params["line_aa"] == 3  # chosen by measurement
    assert integ.params["line_model"] == "thesis"
    assert integ.params["line_color"] == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ('<float name="c" value="-1"/>', "parameter 'c' = -1.0: must be a finite number >= 0"),
        ('<float name="t" value="-0.1"/>', "parameter 't' = -0.1"),
        ('<integer name="dilation_size" value="4"/>', "parameter 'dilation_size' = 4: must be"),
        ('<integer name="dilation_size" value="1"/>', "parameter 'dilation_size' = 1: must be"),
        ('<integer name="dilation_iterations" value="-1"/>', "'dilation_iterations' = -1"),
        ('<float name="t0" value="1.5"/>', "parameter 't0' = 1.5: must lie in [0, 1]"),
        ('<float name="t0" value="-0.5"/>', "parameter 't0' = -0.5"),
        ('<float name="crease_angle" value="181"/>', "parameter 'crease_angle' = 181.0"),
        ('<string name="line_color" value="blue"/>', "parameter 'line_color' = 'blue'"),
        ('<rgb name="line_color" value="-1, 0, 0"/>', "'line_color' = [-1, 0, 0]: must be finite"),
        ('<string name="remove_isolated" value="maybe"/>', "parameter 'remove_isolated'"),
        ('<float name="tt" value="1"/>', "npr_lines: unknown parameter 'tt'"),
        ('<integer name="line_aa" value="0"/>', "parameter 'line_aa' = 0: must be an integer"),
        ('<float name="line_width" value="6"/>', "line_width = 6 with line_aa = 3: 18 sub-"),
    ],
)
def test05_bad_xml_parameters_are_one_line_errors(write_scene, param, message):
    path = write_scene(BALL, integrator=lines_integrator(param))
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    text = str(e.value)
    assert message in text and "npr_lines" in text and str(path) in text
    assert "\n" not in text and "Traceback" not in text


def test06_near_not_below_far_is_an_error_when_loading(write_scene):
    params = ('<float name="near" value="5"/>', '<float name="far" value="2"/>')
    path = write_scene(BALL, integrator=lines_integrator(*params))
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    assert "npr_lines: near = 5.0, far = 2.0: near must be less than far" in str(e.value)


@pytest.mark.parametrize("name", ["scene1", "scene2", "scene3", "scene4"])
def test07_paper_scenes_take_npr_lines(scenes, name):
    gb = mi_npr.render(scenes / f"{name}.xml", width=64, height=48, spp=1, integrator="npr_lines")
    assert gb.metadata["mi_npr/integrator"] == "npr_lines"
    ink = gb.numpy(L.LINES)
    assert ink.any() and 0.0 <= ink.min() and ink.max() <= 1.0
    assert L.RAW_RGB[0] in gb and gb.metadata["mi_npr/beauty"] == "PathIntegrator"


def test08_scalar_variant(write_scene):
    """JIT variants only: the plugin refuses a scalar variant in one line naming itself."""
    path = write_scene(BALL, width=8, height=6, integrator=lines_integrator(nested=""))
    mi_npr.set_variant("scalar_rgb")
    with pytest.raises(mi_npr.SceneError, match="npr_lines needs a JIT variant") as e:
        mi_npr.load_scene(path)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("pixel_format", ["rgb", "rgba"])
def test20_film_holds_what_mi_render_returns(write_scene, tmp_path, pixel_format):
    # Mitsuba's own tools read the film (film.bitmap(), film.write()): it must hold the
    # composited beauty and every layer, unfiltered, like the returned tensor.
    path = write_scene(BALL, integrator=lines_integrator(), spp=4, rfilter="gaussian")
    text = path.read_text().replace(
        '<film type="hdrfilm">',
        f'<film type="hdrfilm"><string name="pixel_format" value="{pixel_format}"/>',
    )
    path.write_text(text)
    scene = mi_npr.load_scene(path)
    img = np.asarray(mi.render(scene))
    film = scene.sensors()[0].film()
    names = [*L.RGB, *(["A"] if pixel_format == "rgba" else []), *scene.integrator().aov_names()]
    assert img.shape[-1] == len(names)
    bitmap = film.bitmap()
    assert [f.name for f in bitmap.struct_()] == names
    np.testing.assert_array_equal(np.asarray(bitmap), img)
    gb = mi_npr.render(path)
    lines = img[..., names.index(L.LINES)]
    np.testing.assert_array_equal(lines, gb.numpy(L.LINES))
    assert lines.max() > 0.5  # the ball's outline is there
    np.testing.assert_array_equal(img[..., names.index(L.OBJECT_ID)], gb.object_id)
    if pixel_format == "rgba":
        np.testing.assert_array_equal(img[..., 3], (gb.object_id > 0).astype(np.float32))
    film.write(str(tmp_path / "film.exr"))  # hdrfilm writes half floats by default
    written = mi_npr.io.read_exr(tmp_path / "film.exr")
    np.testing.assert_allclose(written.numpy(L.LINES), gb.numpy(L.LINES), rtol=1e-3, atol=1e-4)
