"""Line_width in pixels for every kind of line, and max_density (thin creases, then
boundaries, where ink is dense), against numpy references."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr import layers as L

from .test71_line_sides import gbuffer, normals_from_angles

RNG = np.random.default_rng(72)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (31, 24)]


def ref_widen(p, width):
    p = np.clip(np.nan_to_num(np.asarray(p, np.float64), nan=0.0), 0, 1)
    if width <= 1:
        return p * width
    h, w = p.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            for qy in range(h):
                for qx in range(w):
                    d = math.hypot(qy - y, qx - x)
                    out[y, x] = max(out[y, x], p[qy, qx] * min(max((width + 1) / 2 - d, 0), 1))
    return out


def ref_density(p, size):
    """The mean over the window's pixels inside the image."""
    h, w = p.shape
    r = size // 2
    a = np.asarray(p, np.float64)
    return np.array(
        [
            [a[max(y - r, 0) : y + r + 1, max(x - r, 0) : x + r + 1].mean() for x in range(w)]
            for y in range(h)
        ]
    )


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("width", [0.5, 1.0, 1.5, 2.0, 3.0, 4.5])
def test01_widen_matches_reference(shape, width):
    p = (RNG.random(shape) < 0.1) * RNG.uniform(0.2, 1.0, shape)
    p[0, 0] = np.nan
    got = np.asarray(K.widen_lines(p.astype(np.float32), width))
    np.testing.assert_allclose(got, ref_widen(p, width), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test02_density_matches_reference(shape):
    p = RNG.random(shape).astype(np.float32)
    for size in (1, 3, 9):
        got = np.asarray(K.ink_density(p, size))
        np.testing.assert_allclose(got, ref_density(p, size), atol=1e-6)


def _kinds():
    """One vertical line of each kind, alone: a depth step, a boundary, a crease."""
    h, w = 12, 16
    flat = normals_from_angles(0.0, (h, w)).copy()
    one = np.ones((h, w), np.uint32)
    step = np.full((h, w), 5.0, np.float32)
    step[:, 8:] = 9.0
    bent = flat.copy()
    bent[:, 8:] = normals_from_angles(80.0, (h, 8))
    two = one.copy()
    two[:, 8:] = 2
    same = np.full((h, w), 5.0, np.float32)
    return {
        "depth": (gbuffer(step, one, flat), {"id_edges": False, "crease_angle": 0.0}),
        "boundary": (gbuffer(same, two, flat), {"crease_angle": 0.0}),
        "crease": (gbuffer(same, one, bent), {"id_edges": False}),
    }


@pytest.mark.parametrize("kind", ["depth", "boundary", "crease"])
@pytest.mark.parametrize("width", [1.0, 2.0, 3.0, 4.0])
def test03_line_width_holds_for_every_kind(kind, width):
    gb, params = _kinds()[kind]
    ink = np.asarray(K.lines(gb, line_width=width, **params))
    rows = ink[3:-3].sum(axis=1)  # away from the line's ends (eq. 5.2 trims the depth line's)
    np.testing.assert_allclose(rows, width, atol=1e-6)  # ink across the line = its width
    assert ink.max() == 1.0


def test04_max_density_drops_creases_first_and_keeps_contours():
    """Dense creases (a corrugated sheet, normals alternating every 2 px) next to a sparse part,
    and a box with a depth contour on top of the corrugation."""
    h, w = 36, 40
    theta = np.where((np.arange(w) // 2) % 2 == 0, -40.0, 40.0)[None, :].repeat(h, 0)
    theta[:, 20:] = 0.0  # the right half is flat: no creases
    N = normals_from_angles(theta, (h, w)).copy()
    Z = np.full((h, w), 9.0, np.float32)
    ids = np.ones((h, w), np.uint32)
    Z[14:32, 4:38], ids[14:32, 4:38] = 3.0, 2
    N[14:32, 4:38] = normals_from_angles(0.0, (18, 34))
    N[14:32, 30:38] = normals_from_angles(60.0, (18, 8))  # one crease on the box: sparse
    gb = gbuffer(Z, ids, N)
    bound = 0.35
    full = np.asarray(K.lines(gb, far=10.0))
    thin = np.asarray(K.lines(gb, far=10.0, max_density=bound))
    contours = np.asarray(K.lines(gb, far=10.0, id_edges=False, crease_angle=0.0))
    assert np.all(thin >= contours) and np.all(thin <= full)  # depth contours always stay
    dens = np.asarray(K.ink_density(full, 9))
    sparse = dens <= bound
    np.testing.assert_array_equal(thin[sparse], full[sparse])  # untouched where sparse
    inner = (slice(1, 8), slice(2, 14))  # inside the corrugation, away from its edges
    assert dens[inner].min() > bound and full[inner].sum() > 0 and thin[inner].sum() == 0
    assert full[18:28, 29].all() and thin[18:28, 29].all()  # the box's crease stays


def test05_bad_values():
    with pytest.raises(mi_npr.ParameterError, match=r"width = 16"):
        K.widen_lines(np.zeros((2, 2)), 16)
    with pytest.raises(mi_npr.ParameterError, match=r"size = 4"):
        K.ink_density(np.zeros((2, 2)), 4)
    with pytest.raises(mi_npr.ParameterError, match=r"parameter 'max_density' = 0\.0"):
        K.lines({L.Z: np.ones((2, 2))}, max_density=0.0)
