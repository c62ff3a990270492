"""``npr_lines`` with ``line_model = 'soft'`` and ``npr_contours`` with ``contour_model =
'soft'`` under ``mi.render(scene, params=params)``: the ``lines.V`` (``contour_ink.V``) channel
is :func:`mi_npr.ad.soft_lines` of the scene's sensor, and ``dr.backward`` through the render
gives its visibility gradients (silhouettes that move), as Mitsuba's own optimisation loops use
them.

References: ``soft_lines`` called directly (its options spelt out from the manuals' rules:
``n = line_aa`` (4 for the contours), ``sigma = line_width / 2``, the scene's bounding-box
diagonal as the depth scale, the contours with the id feature alone); central finite
differences of the rendered channel itself, over a step of many sub-samples (the primal moves
in steps of ``1 / n`` pixel)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr.ad import soft_lines
from mi_npr.errors import ParameterError

mi, dr = mi_npr.mi, mi_npr.dr

W, H = 48, 36
AA, WIDTH = 6, 2.0  # 6 x 6 samples a pixel, sigma = 1 px: smooth to a step of ~0.1 px
LINES, RED = 3, 0  # channels: R G B, then lines.V

pytestmark = pytest.mark.skipif(
    not str(mi.variant()).startswith(("llvm_ad", "cuda_ad")), reason="needs an AD variant"
)


def _scene(shape: dict | None = None, **lines) -> mi.Scene:
    """A sphere of radius 0.5 at the origin (or ``shape``) seen from 5 units away."""
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {
                "type": "npr_lines",
                "line_model": "soft",
                "line_aa": AA,
                "line_width": WIDTH,
                **lines,
            },
            "sensor": {
                "type": "perspective",
                "fov": 40,
                "to_world": mi.ScalarTransform4f().look_at([0, 0, -5], [0, 0, 0], [0, 1, 0]),
                "film": {"type": "hdrfilm", "width": W, "height": H},
                "sampler": {"type": "independent", "sample_count": 1},
            },
            "ball": shape or {"type": "sphere", "radius": 0.5, "bsdf": {"type": "diffuse"}},
        }
    )


def _weights() -> mi.Float:
    """Pixel weights that make a sideways motion change the loss (a plain sum is symmetric)."""
    yy, xx = np.mgrid[0:H, 0:W]
    w = 1.0 + np.sin(xx / 7.0) * np.cos(yy / 5.0) + xx / W
    return mi.Float(w.ravel().astype(np.float32))


def _channel(image: mi.TensorXf, k: int) -> mi.Float:
    """Channel ``k`` of an (H, W, C) image, flat, with its gradients."""
    c = int(image.shape[2])
    return dr.gather(mi.Float, image.array, dr.arange(mi.UInt32, H * W) * c + k)


def test01_the_line_channel_is_soft_lines_of_the_sensor():
    scene = _scene()
    image = mi.render(scene, spp=1)
    assert image.shape == (H, W, 16)
    bb = scene.bbox()
    diagonal = float(np.linalg.norm(np.asarray(bb.max) - np.asarray(bb.min)))
    assert diagonal == pytest.approx(math.sqrt(3.0), rel=1e-5)  # the sphere's box
    ref = soft_lines(scene, n=AA, sigma=WIDTH / 2, depth_scale=diagonal)
    ink = np.asarray(image)[:, :, LINES]
    assert np.allclose(ink, np.asarray(ref), atol=1e-6)
    assert ink.max() > 0.5 and ink[0, 0] == 0.0  # an outline, and paper away from it
    # Black lines composited onto the beauty (kept after the G-buffer channels).
    raw = np.asarray(image)[:, :, 13:16]
    assert np.allclose(np.asarray(image)[:, :, :3], raw * (1.0 - ink[..., None]), atol=1e-6)


def _translate(params, key: str, d: tuple[float, float, float]):
    """``f(v)``: the parameter ``key`` (a ``to_world``) moved by ``v d``, ``params.update()``."""
    T0 = mi.Transform4f(params[key])

    def move(v) -> None:
        params[key] = mi.Transform4f().translate(mi.Vector3f(d) * v) @ T0
        params.update()

    return move


def _gradient_and_difference(scene, key: str, d, channel, eps: float = 0.1) -> tuple[float, float]:
    """``dr.backward``'s gradient of a weighted sum of the rendered ``channel`` along the
    translation ``d`` of ``key``, and the central finite difference of the same (step
    ``eps``)."""
    params = mi.traverse(scene)
    move = _translate(params, key, d)
    weights = _weights()

    def loss(v):
        move(v)
        return dr.sum(_channel(mi.render(scene, params=params, spp=1, seed=1), channel) * weights)

    v = mi.Float(0.0)
    dr.enable_grad(v)
    dr.backward(loss(v))
    grad = float(dr.grad(v)[0])
    fd = (float(loss(mi.Float(eps))[0]) - float(loss(mi.Float(-eps))[0])) / (2 * eps)
    move(mi.Float(0.0))
    return grad, fd


@pytest.mark.parametrize(
    ("key", "d", "channel"),
    [
        ("ball.to_world", (0.0, 0.0, 1.0), LINES),  # the sphere moves away
        ("ball.to_world", (1.0, 0.0, 0.0), LINES),  # the sphere moves sideways
        ("sensor.to_world", (0.5, 0.3, 0.0), LINES),  # the camera moves sideways and up
        ("sensor.to_world", (0.0, 0.0, 1.0), LINES),  # the camera moves forward
        ("ball.to_world", (0.0, 0.0, 1.0), RED),  # the lines composited onto the beauty
    ],
)
def test02_gradients_match_finite_differences_of_the_render(key, d, channel):
    grad, fd = _gradient_and_difference(_scene(), key, d, channel)
    assert abs(fd) > 10.0  # the motion changes the drawing
    assert grad == pytest.approx(fd, rel=0.05)
    if key == "ball.to_world" and d[2] and channel == LINES:
        assert grad < 0.0  # moving away, the outline shrinks: less ink


@pytest.mark.parametrize(
    ("key", "d"),
    [
        ("ball.to_world", (0.0, 0.0, 1.0)),  # the sphere moves away
        ("ball.to_world", (1.0, 0.0, 0.0)),  # the sphere moves sideways
        ("sensor.to_world", (0.5, 0.3, 0.0)),  # the camera moves sideways and up
        ("sensor.to_world", (0.0, 0.0, 1.0)),  # the camera moves forward
    ],
)
def test02b_a_unit_sphere_matches_finite_differences_too(key, d):
    """A sphere of radius 1 (the depth scale, its bounding-box diagonal, over the outline's
    depth is ~0.7, twice test02's), 8 x 8 samples a pixel: the rendered channel's gradient
    against the same central finite difference."""
    ball = {"type": "sphere", "radius": 1.0, "bsdf": {"type": "diffuse"}}
    grad, fd = _gradient_and_difference(_scene(ball, line_aa=8), key, d, LINES)
    assert abs(fd) > 20.0  # the motion changes the drawing
    assert grad == pytest.approx(fd, rel=0.05)
    if key == "ball.to_world" and d[2]:
        assert grad < 0.0  # moving away, the outline shrinks: less ink


def test03_an_adam_loop_fits_a_translation():
    """Mitsuba's tutorial loop (``mi.ad.Adam``, ``params.update(opt)``, ``dr.backward``) on a
    box's vertices, towards the lines of the box moved by (0.15, 0.1, 0)."""
    box = mi.ScalarTransform4f().rotate([0, 1, 0], 30).rotate([1, 0, 0], 20).scale(0.6)
    scene = _scene({"type": "cube", "to_world": box})
    params = mi.traverse(scene)
    key = "ball.vertex_positions"
    v0 = mi.Float(params[key])
    params[key] = dr.ravel(dr.unravel(mi.Point3f, v0) + mi.Vector3f(0.15, 0.1, 0.0))
    params.update()
    target = mi.Float(_channel(mi.render(scene, spp=1), LINES))
    params[key] = v0
    params.update()

    opt = mi.ad.Adam(lr=0.01)
    opt[key] = params[key]
    params.update(opt)
    losses = []
    for it in range(6):
        image = mi.render(scene, params=params, spp=1, seed=it)
        loss = dr.mean(dr.square(_channel(image, LINES) - target))
        dr.backward(loss)
        losses.append(float(loss[0]))
        opt.step()
        params.update(opt)
    assert losses[-1] < 0.7 * losses[0]
    assert all(np.isfinite(losses))


BALL = '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>'


def _refused(path, plugin: str, message: str) -> None:
    """Loading ``path`` fails with one line that names the file, the plugin and ``message``."""
    with pytest.raises(mi_npr.SceneError) as e:
        mi_npr.load_scene(path)
    text = str(e.value)
    assert message in text and plugin in text and str(path) in text
    assert "\n" not in text


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ('<string name="line_model" value="sketchy"/>', "'line_model' = 'sketchy': expected one"),
        ('<float name="t" value="0.5"/>', "'t' belongs to line_model = 'thesis'"),
    ],
)
def test04_bad_parameters_are_one_line_errors(write_scene, params, message):
    soft = '<string name="line_model" value="soft"/>' if "sketchy" not in params else ""
    path = write_scene(BALL, integrator=f'<integrator type="npr_lines">{soft}{params}</integrator>')
    _refused(path, "npr_lines", message)


def test05_a_variant_without_ad_and_a_crop_window_are_refused(write_scene, monkeypatch):
    path = write_scene(BALL, integrator='<integrator type="npr_lines"/>', width=16, height=12)
    scene = mi_npr.load_scene(path)
    params = {"line_model": "soft", "line_aa": 2, "line_width": 1.0}
    ink = mi_npr.render_layers(scene, ["lines"], params, scene_drawings=False).gbuffer.numpy(
        "lines.V"
    )
    assert ink.max() > 0.5  # the outline
    assert np.allclose(ink, np.asarray(soft_lines(scene, n=2)), atol=1e-6)
    sensor = mi.load_dict(
        {
            "type": "perspective",
            "film": {"type": "hdrfilm", "width": 16, "height": 12, "crop_width": 8},
        }
    )
    with pytest.raises(ParameterError, match="crop window 8x12 of 16x12 is not supported"):
        mi_npr.render_layers(scene, ["lines"], params, sensor=sensor, scene_drawings=False)
    monkeypatch.setattr(dr, "is_diff_v", lambda t: False)  # as on a variant without AD
    with pytest.raises(ParameterError, match="line_model = 'soft' needs an AD variant"):
        mi_npr.render_layers(scene, ["lines"], params, scene_drawings=False)


# ------------------------------------------------------------------------ npr_contours, soft

CONTOUR_INK = 3  # channels: R G B, then contour_ink.V


def _contour_scene(**contours) -> mi.Scene:
    """:func:`_scene`'s sphere and camera, drawn by ``npr_contours`` with soft contours."""
    scene = _scene()
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {
                "type": "npr_contours",
                "contour_model": "soft",
                "line_width": WIDTH,
                **contours,
            },
            "sensor": scene.sensors()[0],
            "ball": {"type": "sphere", "radius": 0.5, "bsdf": {"type": "diffuse"}},
        }
    )


def test06_the_contour_channel_is_soft_lines_with_the_id_feature_alone():
    scene = _contour_scene(color=[0.0, 0.0, 1.0])
    image = np.asarray(mi.render(scene, spp=1))
    assert image.shape == (H, W, 16)
    assert scene.integrator().aov_names()[0] == "contour_ink.V"
    ref = soft_lines(scene, n=4, sigma=WIDTH / 2, depth_weight=0.0, normal_weight=0.0)
    ink = image[:, :, CONTOUR_INK]
    assert np.allclose(ink, np.asarray(ref), atol=1e-6)
    assert ink.max() > 0.5 and ink[0, 0] == 0.0 and ink[H // 2, W // 2] < 1e-3  # an outline
    # Not the soft lines' own default features (the depth and normal ones add ink inside).
    full = np.asarray(soft_lines(scene, n=4, sigma=WIDTH / 2))
    assert np.abs(full - ink).max() > 0.05
    # Blue contours composited onto the raw beauty (kept after the G-buffer channels).
    raw = image[:, :, 13:16]
    blue = raw * (1.0 - ink[..., None]) + np.array([0.0, 0.0, 1.0]) * ink[..., None]
    assert np.allclose(image[:, :, :3], blue, atol=1e-6)


@pytest.mark.parametrize(
    ("d", "eps"),
    [
        ((1.0, 0.0, 0.0), 0.1),  # sideways: the outline moves 1.3 px
        # Away: the outline's radius shrinks 0.6 px over the step (0.13 px at 0.1, under the
        # quarter-pixel sub-samples of the 4 x 4 grid); the loss stays near-linear there.
        ((0.0, 0.0, 1.0), 0.5),
    ],
)
def test07_contour_gradients_match_finite_differences_of_the_render(d, eps):
    grad, fd = _gradient_and_difference(_contour_scene(), "ball.to_world", d, CONTOUR_INK, eps)
    assert abs(fd) > 10.0  # the motion changes the drawing
    assert grad == pytest.approx(fd, rel=0.05)
    if d[2]:
        assert grad < 0.0  # moving away, the outline shrinks: less ink


@pytest.mark.parametrize(
    ("params", "message"),
    [
        (
            '<string name="contour_model" value="sketchy"/>',
            "'contour_model' = 'sketchy': expected one",
        ),
        (
            '<string name="contour_model" value="soft"/><string name="method" '
            'value="code_direction"/>',
            "'method' belongs to contour_model = 'exact'; contour_model = 'soft' takes",
        ),
    ],
)
def test08_bad_contour_parameters_are_one_line_errors(write_scene, params, message):
    path = write_scene(BALL, integrator=f'<integrator type="npr_contours">{params}</integrator>')
    _refused(path, "npr_contours", message)


def test09_soft_contours_refuse_a_variant_without_ad_and_a_crop_window(write_scene, monkeypatch):
    path = write_scene(BALL, integrator='<integrator type="npr_contours"/>', width=16, height=12)
    scene = mi_npr.load_scene(path)
    params = {"contour_model": "soft"}
    gb = mi_npr.render_layers(scene, ["contours"], params, scene_drawings=False).gbuffer
    ink = gb.numpy("contour_ink.V")
    assert ink.max() > 0.5  # the outline
    ref = soft_lines(scene, n=4, sigma=0.5, depth_weight=0.0, normal_weight=0.0)
    assert np.allclose(ink, np.asarray(ref), atol=1e-6)
    assert "contour.V" not in gb  # no traced contours
    sensor = mi.load_dict(
        {
            "type": "perspective",
            "film": {"type": "hdrfilm", "width": 16, "height": 12, "crop_width": 8},
        }
    )
    with pytest.raises(
        ParameterError, match="contour_model = 'soft' draws the whole film: its crop window 8x12"
    ):
        mi_npr.render_layers(scene, ["contours"], params, sensor=sensor, scene_drawings=False)
    monkeypatch.setattr(dr, "is_diff_v", lambda t: False)  # as on a variant without AD
    with pytest.raises(ParameterError, match="contour_model = 'soft' needs an AD variant"):
        mi_npr.render_layers(scene, ["contours"], params, scene_drawings=False)


def test10_soft_contours_write_their_picture_and_no_empty_svg(tmp_path):
    """The soft model traces nothing: the command writes the EXR and the PNG, and no SVG that
    would hold no contour (the exact model's SVG is written, with its paths)."""
    from mi_npr.cli import main

    for model, svg in (("soft", False), ("exact", True)):
        out = tmp_path / model
        rc = main(
            ["contours", "scene1", "-o", str(out), "--width", "48", "--height", "36", "--spp", "1",
             "--contour-model", model, "--no-progress"]
        )  # fmt: skip
        assert rc in (0, None)
        names = sorted(p.name for p in out.iterdir())
        assert "scene1_contours.exr" in names and "scene1_contours.png" in names
        assert ("scene1_contours.svg" in names) == svg, names
        if svg:
            assert "<path" in (out / "scene1_contours.svg").read_text()
