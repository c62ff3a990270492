"""Anti-aliased lines keep full ink: an axis-aligned line at any sub-pixel position has a
pixel of full ink across it, and the same ink across as a crease (closed form).

The camera: 90 degree horizontal fov, 32 x 24 film, at the origin looking down +z; a point
``(X, Y, 5)`` projects to ``px = 16 - 16 X / 5`` (Mitsuba's camera +x is the image's left). A
``w``-px line drawn with ``n x n`` rays per pixel is a band of ``max(w n, 2 n - 1)``
sub-pixels (:mod:`mi_npr.antialias`): ``2n - 1`` consecutive sub-pixels always hold one film
pixel whole, so the darkest pixel across an axis-aligned line is 1 and the ink across it is
``(2n - 1) / n`` px wherever it lies; a band of ``n`` sub-pixels at a third of a pixel would
give 0.67 + 0.33.
"""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr

from .helpers import scene_xml

W, H = 32, 24
ROWS = slice(4, 20)  # rows far from the top and bottom of the objects
COLS = slice(6, 15)  # the columns around the line at px ~ 10


def _x(px: float) -> float:
    return (16.0 - px) * 5.0 / 16.0


def _silhouette(px: float) -> str:
    """A slab whose front face (z = 5) covers the image right of px (a vertical edge there),
    its side face hidden from the camera; the background left of it."""
    x = _x(px)
    return (
        '<shape type="cube"><transform name="to_world">'
        f'<scale x="{(10 + x) / 2}" y="10" z="1"/><translate x="{(x - 10) / 2}" z="6"/>'
        "</transform></shape>"
    )


def _crease(px: float) -> str:
    """A wide prism whose front edge (z = 5) is a 120-degree crease at px: two faces seen at 30
    degrees from their normals, its other edges far outside the image."""
    x, a = _x(px), 20.0
    return (
        '<shape type="cube"><transform name="to_world">'
        f'<scale x="{a}" y="10" z="{a}"/><rotate y="1" angle="45"/><scale x="{3**0.5}"/>'
        f'<translate x="{x}" z="{5 + a * 2**0.5}"/></transform></shape>'
    )


def _ink(tmp_path, body: str, n: int) -> np.ndarray:
    path = tmp_path / "scene.xml"
    path.write_text(scene_xml(body, width=W, height=H, fov=90.0))
    gb = mi_npr.render_layers(path, ["lines"], {"line_aa": n}).gbuffer
    return np.asarray(gb["lines.V"])[ROWS, COLS]


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("px", [10.0, 10.3, 10.33, 10.6, 10.67])
def test01_silhouette_against_the_background_has_full_ink(tmp_path, px, n):
    ink = _ink(tmp_path, _silhouette(px), n)
    assert ink.max(axis=1).min() >= 0.99  # every row: one pixel of full ink
    np.testing.assert_allclose(ink.sum(axis=1), (2 * n - 1) / n, atol=2e-3)


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("px", [10.3, 10.6])
def test02_crease_has_full_ink_and_the_silhouettes_ink(tmp_path, px, n):
    """A crease is found on the supersampled G-buffer one sub-pixel left or right from row to
    row along a straight edge (a property of crease detection, not of the band): where it
    steps, the widened band's soft corners add up to a quarter pixel of ink. So the ink across
    agrees with the silhouette's on average within that, and is never less."""
    crease = _ink(tmp_path, _crease(px), n)
    silhouette = _ink(tmp_path, _silhouette(px), n)
    assert crease.max(axis=1).min() >= 0.99
    assert abs(crease.sum(axis=1).mean() - silhouette.sum(axis=1).mean()) <= 0.25
    assert crease.sum(axis=1).min() >= (2 * n - 1) / n - 2e-3  # never lighter than the band


def test03_one_ray_per_pixel_is_unchanged(tmp_path):
    """n = 1: the 1-px line of the pixel-centre chain, one full pixel per row."""
    ink = _ink(tmp_path, _silhouette(10.33), 1)
    np.testing.assert_array_equal(ink.sum(axis=1), 1.0)
    assert ink.max() == 1.0


def test04_a_thin_line_is_the_full_band_lightened(tmp_path):
    """Below 1 px the line is the 1-px band times its width, as at n = 1."""
    path = tmp_path / "scene.xml"
    path.write_text(scene_xml(_silhouette(10.33), width=W, height=H, fov=90.0))
    thin = mi_npr.render_layers(path, ["lines"], {"line_aa": 3, "line_width": 0.5}).gbuffer
    full = mi_npr.render_layers(path, ["lines"], {"line_aa": 3}).gbuffer
    np.testing.assert_allclose(np.asarray(thin["lines.V"]), 0.5 * np.asarray(full["lines.V"]))
