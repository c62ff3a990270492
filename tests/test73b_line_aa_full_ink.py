"""Anti-aliased lines keep full ink: an axis-aligned line at any sub-pixel position has a
pixel of full ink across it, and exactly the ink of the closed form below.

The camera: 90 degree horizontal fov, 32 x 24 film, at the origin looking down +z; a point
``(X, Y, 5)`` projects to ``px = 16 - 16 X / 5`` (Mitsuba's camera +x is the image's left).

The closed form (:func:`expected_row`), from the definitions of :mod:`mi_npr.antialias` and
:func:`mi_npr.kernels.widen_lines`, not from their code: with ``n x n`` rays per pixel the chain
marks the first sub-pixel on the slab's side of the edge (the nearer side; sub-pixel ``j`` has
its centre at ``(j + 0.5) / n``), and widens it to ``n`` sub-pixels with a soft disc, ink
``clip((n + 1) / 2 - |k|, 0, 1)`` at ``k`` sub-pixels from it. Each film pixel sums its ``n``
sub-pixels of the band (every sub-row alike); the line's best-covered pixel gets full ink and
the others their coverage relative to it. So a 1-px line at 10.33 with ``n = 3`` is 1 + 0, at
10.6 1 + 0.5; a band of ``n`` sub-pixels box-filtered alone would give 0.67 + 0.33 at 10.6.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr

from .helpers import scene_xml

W, H = 32, 24
ROWS = slice(4, 20)  # rows far from the top and bottom of the objects
COLS = slice(6, 15)  # the columns around the line at px ~ 10
POSITIONS = [10.0, 10.3, 10.33, 10.6, 10.67]


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


def expected_row(px: float, n: int) -> np.ndarray:
    """The closed form (module docstring) over the columns ``COLS``."""
    first = math.floor(px * n - 0.5) + 1  # the first sub-pixel centre right of px
    ink = np.zeros(W)
    for k in range(-n, n + 1):
        j = first + k
        ink[j // n] += min(max((n + 1) / 2 - abs(k), 0.0), 1.0)
    return (ink / ink.max())[COLS]


def _ink(tmp_path, body: str, n: int, **params) -> np.ndarray:
    path = tmp_path / "scene.xml"
    path.write_text(scene_xml(body, width=W, height=H, fov=90.0))
    gb = mi_npr.render_layers(path, ["lines"], {"line_aa": n, **params}).gbuffer
    return np.asarray(gb["lines.V"])[ROWS, COLS]


def test00_closed_form_by_hand():
    """The closed form's own cases, counted by hand: n = 3 at 10.6 marks sub-pixel 32 (centre
    10.83), band 31..33: pixel 10 holds two sub-pixels, pixel 11 one -> 1 + 0.5; at 10.33 the
    band is 30..32, pixel 10 whole; n = 2 at 10.0: 0.5, 1, 0.5 on sub-pixels 19..21 -> pixels
    9 and 10 hold 0.5 and 1.5 -> 1/3 + 1."""
    np.testing.assert_allclose(expected_row(10.6, 3)[4:6], [1.0, 0.5])
    np.testing.assert_allclose(expected_row(10.33, 3).sum(), 1.0)
    np.testing.assert_allclose(expected_row(10.0, 2)[3:5], [1 / 3, 1.0])


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("px", POSITIONS)
def test01_silhouette_against_the_background_has_full_ink(tmp_path, px, n):
    ink = _ink(tmp_path, _silhouette(px), n)
    assert ink.max(axis=1).min() >= 0.99  # every row: one pixel of full ink
    np.testing.assert_allclose(ink, np.broadcast_to(expected_row(px, n), ink.shape), atol=2e-3)


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("px", [10.3, 10.6])
def test02_crease_has_full_ink(tmp_path, px, n):
    """A crease is found on the supersampled G-buffer one sub-pixel left or right from row to
    row along a straight edge (which face of a symmetric crease is nearer to facing the camera
    flips with rounding), so a film row may mix two band positions of the closed form. Every
    row still has a pixel of full ink, at least one pixel's ink across, and at most the
    widest position's ink plus the staircase's soft corners (0.1 px)."""
    crease = _ink(tmp_path, _crease(px), n)
    assert crease.max(axis=1).min() >= 0.99
    widest = max(expected_row(q, n).sum() for q in np.arange(10.0, 11.0, 1.0 / (4 * n)))
    assert crease.sum(axis=1).min() >= 1.0 - 2e-3
    assert crease.sum(axis=1).max() <= widest + 0.1


def test03_one_ray_per_pixel_is_unchanged(tmp_path):
    """n = 1: the 1-px line of the pixel-centre chain, one full pixel per row."""
    ink = _ink(tmp_path, _silhouette(10.33), 1)
    np.testing.assert_array_equal(ink.sum(axis=1), 1.0)
    assert ink.max() == 1.0


def test04_a_thin_line_is_the_full_line_lightened(tmp_path):
    """Below 1 px the line is the 1-px line times its width, as at n = 1."""
    for n in (1, 3):
        thin = _ink(tmp_path, _silhouette(10.6), n, line_width=0.5)
        full = _ink(tmp_path, _silhouette(10.6), n)
        np.testing.assert_allclose(thin, 0.5 * full, atol=1e-6)
        assert thin.max(axis=1).min() == pytest.approx(0.5, abs=2e-3)  # not full ink


@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("px", [10.0, 10.33, 10.67])
def test05_gray_lines_keep_their_gray(tmp_path, px, n):
    """A depth step that eq. 5.1 draws gray (the slab's face at z = 5 in front of a wall at
    z = 7.5; normalised depths 3/8 and 11/16 with near = 2, far = 10; c = 2, t = 0.2:
    g = 2 * 5/16 - 0.2 = 0.425) comes out as g times the closed form: darkest pixel g, not 1."""
    wall = (
        '<shape type="rectangle"><transform name="to_world">'
        '<scale value="30"/><translate z="7.5"/></transform></shape>'
    )
    gray = dict(c=2.0, t=0.2, near=2.0, far=10.0, id_edges=False, crease_angle=0.0)
    only_eq51 = dict(remove_isolated=False, dilation_iterations=0)  # eq. 5.2 drops grays < t0
    ink = _ink(tmp_path, _silhouette(px) + wall, n, **gray, **only_eq51)
    g = 2.0 * (7.5 - 5.0) / (10.0 - 2.0) - 0.2
    assert 0.4 < g < 0.5
    np.testing.assert_allclose(ink, np.broadcast_to(g * expected_row(px, n), ink.shape), atol=2e-3)
