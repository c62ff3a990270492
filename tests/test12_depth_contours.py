"""Eq. 5.1 (signed depth contours) against a brute-force reference written from its definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mi_npr.kernels import depth_contours

RNG = np.random.default_rng(12)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]


def sat(x):
    return min(max(x, 0.0), 1.0)


def clean_depth(d, top=1.0):
    """The documented policy: NaN is background (1), depth is clamped to [0, 1] (``top``: the
    lines chain's background lies at 2, see test 16)."""
    return top if math.isnan(d) else min(max(float(d), 0.0), top)


def ref_contours(D, c, t, top=1.0):
    """p0 = max_i sat((d_i - d0) c - t) over the 8 neighbours; outside repeats the border."""
    D = np.asarray(D, dtype=np.float64)
    h, w = D.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            d0 = clean_depth(D[y, x], top)
            best = 0.0
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    if (dy, dx) == (0, 0):
                        continue
                    di = D[min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)]
                    di = clean_depth(di, top)
                    best = max(best, sat((di - d0) * c - t))
            out[y, x] = best
    return out


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize(("c", "t"), [(1.0, 0.0), (3.0, 0.2), (8.0, 1.5), (0.0, 0.0)])
def test01_random_depth_matches_reference(shape, c, t):
    D = RNG.random(shape).astype(np.float32)
    got = np.asarray(depth_contours(D, c, t))
    np.testing.assert_allclose(got, ref_contours(D, c, t), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test02_piecewise_constant_depth_large_gain(shape):
    D = RNG.choice([0.0, 0.25, 0.5, 1.0], size=shape).astype(np.float32)
    got = np.asarray(depth_contours(D, 40.0, 1.0))
    np.testing.assert_allclose(got, ref_contours(D, 40.0, 1.0), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test03_no_edges_no_lines(shape):
    for D in (np.zeros(shape), np.ones(shape), np.full(shape, 0.3)):
        assert not np.asarray(depth_contours(D, 40.0, 0.0)).any()
    ramp = np.linspace(0, 1, shape[0] * shape[1]).reshape(shape) * 0.01  # a gentle slope
    assert not np.asarray(depth_contours(ramp, 40.0, 1.0)).any()


def test04_step_lights_the_near_side_only():
    D = np.ones((5, 8), np.float32)
    D[:, :3] = 0.2  # near on the left
    p = np.asarray(depth_contours(D, 10.0, 0.5))
    assert np.all(p[:, 2] == 1.0)  # 1 px, near side
    assert not np.delete(p, 2, axis=1).any()
    # Gray levels are kept: a small step gives a partial value sat(0.07 * 10 - 0.5) = 0.2.
    D[:, 3:] = 0.27
    p = np.asarray(depth_contours(D, 10.0, 0.5))
    np.testing.assert_allclose(p[:, 2], 0.2, atol=1e-6)


def test05_diagonal_neighbours_count():
    D = np.zeros((3, 3), np.float32)
    D[2, 2] = 1.0
    p = np.asarray(depth_contours(D, 1.0, 0.0))
    expected = np.zeros((3, 3))
    expected[1, 1] = 1.0  # its only farther neighbour is diagonal
    expected[1, 2] = expected[2, 1] = 1.0
    np.testing.assert_array_equal(p, expected)


def test06_nan_and_inf_never_spread():
    D = RNG.random((64, 48)).astype(np.float32)
    D[5, 5], D[0, 7], D[30, 0], D[63, 47] = np.nan, np.inf, -np.inf, np.nan
    got = np.asarray(depth_contours(D, 3.0, 0.2))
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref_contours(D, 3.0, 0.2), atol=1e-6)
    flat = np.full((5, 5), 0.5, np.float32)
    flat[2, 2] = np.nan  # reads as background: a ring around it, nothing farther away
    p = np.asarray(depth_contours(flat, 4.0, 0.0))
    assert p[2, 2] == 0.0 and np.all(p[1:4, 1:4][np.arange(9).reshape(3, 3) != 4] == 1.0)
    assert not p[0].any() and not p[:, 0].any()
