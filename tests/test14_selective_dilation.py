"""Eqs. 5.3-5.4 (selective dilation) against a brute-force reference written from the definition."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from mi_npr.kernels import selective_dilation

RNG = np.random.default_rng(14)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]


def clean_depth(d, top=1.0):
    return top if math.isnan(d) else min(max(float(d), 0.0), top)


def ref_selective_dilation(D, n=3, iterations=1, top=1.0):
    """On R = 1 - D with an n x n window S (clamped at the border): m = mean over S, Na = number
    of the n*n - 1 neighbours with R > m; R <- max_S R where Na > (n*n - 1) / 2. Returns 1 - R.

    In exact rational arithmetic on the float32 depths (``R_i > m`` is ``d_i < mean(d)``), so
    ties are ties. ``top``: NaN reads as it and depth is clamped to [0, top].
    """
    d = np.vectorize(lambda v: clean_depth(v, top))(np.asarray(D, dtype=np.float64))
    d = d.astype(np.float32)
    h, w = d.shape
    r = n // 2
    for _ in range(iterations):
        new = d.copy()
        for y in range(h):
            for x in range(w):
                vals = [
                    d[min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)]
                    for dy in range(-r, r + 1)
                    for dx in range(-r, r + 1)
                ]
                mean = sum(Fraction(float(v)) for v in vals) / len(vals)
                centre = vals.pop(len(vals) // 2)
                n_above = sum(Fraction(float(v)) < mean for v in vals)
                if n_above > len(vals) / 2:
                    new[y, x] = min(*vals, centre)
        d = new
    return d.astype(np.float64)


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize(("size", "iterations"), [(3, 1), (3, 2), (5, 1), (3, 0)])
def test01_random_depth_matches_reference(shape, size, iterations):
    D = RNG.random(shape).astype(np.float32)
    got = np.asarray(selective_dilation(D, size, iterations))
    np.testing.assert_allclose(got, ref_selective_dilation(D, size, iterations), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test02_piecewise_constant_depth(shape):
    D = RNG.choice([0.1, 0.4, 1.0], size=shape, p=[0.5, 0.3, 0.2]).astype(np.float32)
    got = np.asarray(selective_dilation(D, 3, 2))
    np.testing.assert_allclose(got, ref_selective_dilation(D, 3, 2), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test03_flat_depth_is_unchanged(shape):
    for value in (0.0, 0.37, 1.0):
        D = np.full(shape, value, np.float32)
        np.testing.assert_array_equal(np.asarray(selective_dilation(D, 3, 3)), D)


def test04_one_pixel_hole_filled_straight_boundary_stays():
    D = np.ones((9, 12), np.float32)
    D[:, :6] = 0.25  # a near surface on the left, far background on the right
    D[4, 2] = 1.0  # a 1-pixel hole in the near surface
    got = np.asarray(selective_dilation(D, 3))
    assert got[4, 2] == np.float32(0.25)  # filled with the surrounding depth
    expected = D.copy()
    expected[4, 2] = 0.25
    np.testing.assert_array_equal(got, expected)  # the boundary did not move, bit for bit
    # A diagonal boundary stays too; an isolated far pixel on it is filled.
    yy, xx = np.mgrid[0:9, 0:12]
    diag = np.where(xx > yy + 1, 1.0, 0.25).astype(np.float32)
    np.testing.assert_array_equal(np.asarray(selective_dilation(diag, 3)), diag)


def test05_plain_dilation_would_grow_the_object():
    """What the selective test prevents: the 3x3 maximum of R moves the boundary by one pixel."""
    D = np.ones((5, 8), np.float32)
    D[:, :4] = 0.25
    R = 1.0 - D
    grown = np.max([np.roll(R, s, axis=1) for s in (-1, 0, 1)], axis=0)
    assert (grown > R).any()
    np.testing.assert_array_equal(np.asarray(selective_dilation(D)), D)


def test06_larger_window_fills_larger_holes():
    D = np.full((11, 11), 0.25, np.float32)
    D[4:6, 4:6] = 1.0  # a 2x2 hole: the 3x3 window sees too much of it at its corners
    five = np.asarray(selective_dilation(D, 5))
    assert np.all(five == np.float32(0.25))
    np.testing.assert_allclose(
        np.asarray(selective_dilation(D, 3, 2)), ref_selective_dilation(D, 3, 2), atol=1e-6
    )


def test07_nan_and_inf_never_spread():
    D = RNG.random((64, 48)).astype(np.float32)
    D[7, 7], D[0, 1], D[63, 0] = np.nan, np.inf, -np.inf
    got = np.asarray(selective_dilation(D, 3, 2))
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref_selective_dilation(D, 3, 2), atol=1e-6)


def test08_exact_ties_are_not_float32_rounding():
    """Seven neighbours at x, one at x - 1/8, the centre at x + 1/8. The mean is x
    exactly, so only one neighbour is nearer than the mean and the centre keeps its depth; a
    float32 mean (rounded below x in R) counted all seven as above and dilated the pixel."""
    x = np.float32(0.7276081442832947)
    D = np.full((3, 3), x, np.float32)
    D[1, 1], D[0, 0] = x + np.float32(0.125), x - np.float32(0.125)
    assert float(np.asarray(selective_dilation(D))[1, 1]) == float(D[1, 1])
    np.testing.assert_array_equal(np.asarray(selective_dilation(D)), ref_selective_dilation(D))
