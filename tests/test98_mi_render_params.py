"""Every npr integrator under Mitsuba's differentiable render call,
``mi.render(scene, params=params, spp=..., seed=...)``, forward and backward, as Mitsuba's own
optimisation loops write it (``dr.enable_grad``, ``params.update()``, ``dr.backward``).

References: the headlight beauty is linear in the BSDF's reflectance, so a central finite
difference is exact up to float rounding; the depth of a plane facing the camera moves one for
one with the plane (no pixel changes visibility), so d(sum Z)/dz is the number of pixels."""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

W, H = 24, 16
PLUGINS = ("npr_gbuffer", "npr_lines", "npr_contours", "npr_raytree", "npr_strokes")


def _scene(plugin: str) -> mi.Scene:
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": plugin},
            "sensor": {
                "type": "perspective",
                "fov": 40,
                "film": {"type": "hdrfilm", "width": W, "height": H},
                "sampler": {"type": "independent", "sample_count": 1},
            },
            "ball": {
                "type": "sphere",
                "center": [0.0, 0.0, 5.0],
                "radius": 1.0,
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}},
            },
            "wall": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f().translate([0.0, 0.0, 9.0]).scale(20.0),
            },
        }
    )


def _loss(image: mi.TensorXf) -> mi.TensorXf:
    return dr.mean(image[:, :, 0])  # the beauty's red channel, lines and overlays included


def _f(x) -> float:
    return float(np.asarray(x).ravel()[0])


@pytest.mark.parametrize("plugin", PLUGINS)
def test01_forward_and_backward_match_finite_differences(plugin):
    scene = _scene(plugin)
    params = mi.traverse(scene)
    key = "ball.bsdf.reflectance.value"
    base = mi.Color3f(params[key])
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params=params, spp=1, seed=3)
    assert image.shape[:2] == (H, W)
    loss = _loss(image)
    dr.backward(loss)
    grad = _f(dr.sum(dr.grad(params[key])))

    def at(v: float) -> float:
        params[key] = mi.Color3f(v)
        params.update()
        return _f(_loss(mi.render(scene, spp=1, seed=3)))

    fd = (at(_f(base[0]) + 0.05) - at(_f(base[0]) - 0.05)) / 0.1
    params[key] = base
    params.update()
    assert fd > 1e-3  # the ball is seen and lit
    assert grad == pytest.approx(fd, rel=1e-3)


def test02_depth_follows_a_translated_mesh():
    """An optimisation step on a mesh's vertices (``params.update(opt)``) through npr_gbuffer's
    ``Z`` channel: d(sum Z)/dz = W * H for a wall that fills the film."""
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "npr_gbuffer"},
            "sensor": {
                "type": "perspective",
                "fov": 30,
                "film": {"type": "hdrfilm", "width": W, "height": H},
            },
            "wall": {  # a mesh: its front face at z = 4 (its diagonal off every pixel centre)
                "type": "cube",
                "to_world": mi.ScalarTransform4f().translate([0.37, 0.21, 5.0]).scale([10, 10, 1]),
            },
        }
    )
    params = mi.traverse(scene)
    key = "wall.vertex_positions"
    opt = mi.ad.Adam(lr=0.1)
    opt["dz"] = mi.Float(0.0)
    v0 = dr.unravel(mi.Point3f, params[key])

    def apply() -> None:
        params[key] = dr.ravel(v0 + mi.Vector3f(0, 0, opt["dz"]))
        params.update()

    apply()
    image = mi.render(scene, params=params, spp=1)
    z = image[:, :, 3]  # R G B, then the G-buffer's Z
    assert np.allclose(np.asarray(z), 4.0, atol=1e-4)
    dr.backward(dr.sum(z))
    assert _f(dr.grad(opt["dz"])) == pytest.approx(W * H, rel=1e-4)
    opt.step()
    apply()
    assert _f(dr.mean(mi.render(scene, params=params, spp=1)[:, :, 3])) < 4.0
