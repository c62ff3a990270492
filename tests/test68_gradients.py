"""On AD variants the G-buffer pass, the line kernels and compositing keep Dr.Jit's gradient
graph: d(sum of the lines layer) / d(scene parameter) from ``dr.backward`` agrees with
central finite differences where the gray levels are not saturated.

The scene: a small tilted rectangle in front of a large tilted wall, seen by a perspective camera,
with a gain ``c`` low enough that the depth step between them gives gray (unsaturated) lines
(eq. 5.1 ramps from ``t / c`` to ``(1 + t) / c``). Moving the camera sideways or the front
rectangle in depth changes the per-pixel depths smoothly; the step ``eps`` is small enough that no
pixel centre crosses an outline, so the finite difference is the derivative of a smooth function.
"""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr

mi, dr = mi_npr.mi, mi_npr.dr

SCENE = """<scene version="3.0.0">
<integrator type="npr_gbuffer"/>
<sensor type="perspective" id="cam"><float name="fov" value="40"/>
 <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
 <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="32"/>
  <rfilter type="box"/></film>
 <sampler type="independent"><integer name="sample_count" value="1"/></sampler></sensor>
<shape type="rectangle" id="back"><transform name="to_world"><scale value="10"/>
 <rotate y="1" angle="20"/><translate z="6"/></transform></shape>
<shape type="rectangle" id="front"><transform name="to_world"><scale value="0.8"/>
 <rotate y="1" angle="-30"/><translate z="4"/></transform></shape>
</scene>"""

#: Gray-level lines (no saturation at the step between the two rectangles), nothing else.
LINES = dict(
    c=4.0,
    t=0.2,
    near=2.0,
    far=10.0,
    dilation_iterations=0,
    remove_isolated=False,
    id_edges=False,
    crease_angle=0.0,
)


def _loss(scene, params, key, T0, move, value, grad):
    v = mi.Float(value)
    if grad:
        dr.enable_grad(v)
    params[key] = mi.Transform4f().translate(move(v)) @ T0
    params.update()
    gb = mi_npr.render_gbuffer(scene)  # the exact pixel-centre pass, headlight beauty
    ink = mi_npr.kernels.lines(gb, **LINES)
    out = mi_npr.compose.with_overlay(gb, ink, (1.0, 0.0, 0.0))  # compositing keeps it too
    loss = dr.sum(ink.array) + 0.5 * dr.sum(out["R"].array)
    if not grad:
        return float(loss[0]), np.asarray(ink)
    dr.backward(loss)
    return float(loss[0]), float(dr.grad(v)[0]), np.asarray(ink)


@pytest.mark.parametrize(
    ("key", "move"),
    [
        ("cam.to_world", lambda v: mi.Vector3f(v, 0.0, 0.0)),  # camera translation
        ("front.to_world", lambda v: mi.Vector3f(0.0, 0.0, v)),  # the object's vertex positions
    ],
    ids=["camera", "object"],
)
def test01_lines_gradient_matches_finite_differences(tmp_path, key, move):
    if not mi.variant().startswith(("llvm_ad", "cuda_ad")):
        pytest.skip("needs an AD variant")
    path = tmp_path / "s.xml"
    path.write_text(SCENE)
    scene = mi_npr.load_scene(path)
    params = mi.traverse(scene)
    T0 = mi.Transform4f(params[key])
    _, grad, ink = _loss(scene, params, key, T0, move, 0.0, True)
    gray = (ink > 0) & (ink < 1)
    assert gray.sum() > 20  # the derivative lives on unsaturated pixels
    eps = 1e-3
    hi, ink_hi = _loss(scene, params, key, T0, move, eps, False)
    lo, ink_lo = _loss(scene, params, key, T0, move, -eps, False)
    # no pixel changed between saturated and not (smooth in [-eps, eps])
    assert np.array_equal(ink_hi > 0, ink > 0) and np.array_equal(ink_lo > 0, ink > 0)
    fd = (hi - lo) / (2 * eps)
    assert abs(grad) > 1.0
    np.testing.assert_allclose(grad, fd, rtol=0.02)
    params[key] = T0  # the scene as loaded
    params.update()
