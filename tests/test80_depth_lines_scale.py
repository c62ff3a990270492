"""The lines chain draws a lone sphere's whole silhouette at camera distances from 2
to 500 radii and scene scales from 1e-3 to 1e3, with ``far`` given or not; and nothing off the
sphere's outline at the distances where its own relief is small."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K

RES = 64


def _scene(radius: float, dist: float, fov: float) -> str:
    near, far = radius * dist * 0.01, radius * dist * 100.0
    return f"""<scene version="3.0.0">
    <integrator type="npr_gbuffer"/>
    <sensor type="perspective">
        <float name="fov" value="{fov}"/>
        <float name="near_clip" value="{near}"/><float name="far_clip" value="{far}"/>
        <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{RES}"/>
            <integer name="height" value="{RES}"/><rfilter type="box"/></film>
    </sensor>
    <shape type="sphere" id="ball"><float name="radius" value="{radius}"/>
        <point name="center" x="0" y="0" z="{dist * radius}"/></shape>
</scene>"""


def analytic_mask(dist: float, fov: float) -> np.ndarray:
    """Pixels whose centre ray hits a unit sphere at (0, 0, dist): the ray's angle to the view
    axis is below asin(1 / dist). Mitsuba's x fov, square film; +x is to the left."""
    half = math.tan(math.radians(fov) / 2)
    c = (np.arange(RES) + 0.5) / RES * 2 - 1
    x, y = np.meshgrid(c * half, c * half)
    return np.arctan(np.hypot(x, y)) < math.asin(1 / dist)


def _rim(mask: np.ndarray, diagonal: bool = False) -> np.ndarray:
    """Pixels of ``mask`` with a 4-neighbour (8-neighbour with ``diagonal``) outside it."""
    pad = np.pad(mask, 1, mode="edge")
    out = np.zeros_like(mask)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if abs(dy) + abs(dx) == 1 or (diagonal and dy and dx):
                out |= ~pad[1 + dy : 1 + dy + RES, 1 + dx : 1 + dx + RES]
    return mask & out


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
@pytest.mark.parametrize("dist", [2.0, 5.0, 50.0, 500.0])
def test01_whole_silhouette_at_any_scale(tmp_path, scale, dist):
    fov = 2 * math.degrees(math.asin(1 / dist)) * 1.3
    path = tmp_path / "ball.xml"
    path.write_text(_scene(scale, dist, fov))
    gb = mi_npr.render(path)
    ball = np.isfinite(np.asarray(gb.numpy("Z")))
    analytic = analytic_mask(dist, fov)
    assert (ball != analytic).sum() <= 4  # the render is the analytic sphere (rounding at rims)
    rim, rim8 = _rim(ball), _rim(ball, diagonal=True)
    assert rim.sum() > 100
    for far in (None, 10 * dist * scale, 1e4 * dist * scale):
        ink = np.asarray(K.lines(gb, far=far)) > 0
        assert ink[rim].all(), f"far={far}: {int((rim & ~ink).sum())} silhouette pixels missing"
        assert not (ink & ~ball).any()  # on the sphere's side of the step
        if dist >= 50:  # a relief of at most 2 % of the depth: nothing inside the outline
            assert not (ink & ~rim8).any()
