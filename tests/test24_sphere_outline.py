"""A sphere's apparent contour against its analytic outline (closed form, no rendering oracle)."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.contours import trace, trace_scene

from .test04_sphere_closed_form import CASES, _sphere_scene, analytic_sphere


@pytest.mark.parametrize("case", CASES[:2])
def test01_contour_within_one_pixel_of_the_outline(write_scene, case):
    path = _sphere_scene(write_scene, case)
    mask, _, _, _, outline = analytic_sphere(**case)
    buffer = trace(mi_npr.render(path))
    rays, _ = trace_scene(path, macro=4)
    assert len(buffer) == len(rays) and all(a == b for a, b in zip(buffer, rays, strict=True))
    (c,) = buffer
    assert c.name == "ball" and c.closed and not c.is_hole
    # Every contour pixel's centre ray passes within 1 px of the silhouette (except where the
    # image border cuts the sphere: that is contour too, by definition)...
    h, w = mask.shape
    inner = (c.xs > 0) & (c.xs < w - 1) & (c.ys > 0) & (c.ys < h - 1)
    assert outline[c.ys[inner], c.xs[inner]].max() <= 1.0
    assert np.all(mask[c.ys, c.xs] | (outline[c.ys, c.xs] < 1e-3))
    # ... and every analytic boundary pixel inside the image is on the contour.
    pts = set(map(tuple, c.points.tolist()))
    for y, x in np.argwhere(mask):
        edge = x in (0, w - 1) or y in (0, h - 1)
        edge = edge or not (mask[y, x - 1] and mask[y, x + 1] and mask[y - 1, x] and mask[y + 1, x])
        if edge and outline[y, x] > 1e-3:  # pixels grazing the outline may flip either way
            assert (x, y) in pts


def test02_sphere_at_full_resolution(write_scene):
    case = dict(CASES[0], width=320, height=240)
    path = _sphere_scene(write_scene, case)
    _, _, _, _, outline = analytic_sphere(**case)
    (c,), stats = trace_scene(path)
    inner = (c.xs > 0) & (c.xs < 319) & (c.ys > 0) & (c.ys < 239)
    assert inner.sum() > 400 and outline[c.ys[inner], c.xs[inner]].max() <= 1.0
    assert stats.ray_fraction < 0.1
