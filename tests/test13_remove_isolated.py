"""Eq. 5.2 (isolated-pixel removal) against a brute-force reference written from its definition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mi_npr.kernels import remove_isolated

RNG = np.random.default_rng(13)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]


def clean_line(p):
    """The documented policy: NaN is no line (0), values are clamped to [0, 1]."""
    return 0.0 if math.isnan(p) else min(max(float(p), 0.0), 1.0)


def ref_remove_isolated(P, t0=0.5):
    """p0 <- p0 * sat(sum_i ceil(sat(p_i - t0)) - 2) over the 3x3 block including the centre;
    pixels outside the image count 0."""
    P = np.asarray(P, dtype=np.float64)
    h, w = P.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            total = 0
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    if 0 <= y + dy < h and 0 <= x + dx < w:
                        pi = clean_line(P[y + dy, x + dx])
                        total += math.ceil(min(max(pi - t0, 0.0), 1.0))
            out[y, x] = clean_line(P[y, x]) * min(max(total - 2, 0), 1)
    return out


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("t0", [0.0, 0.3, 0.5, 1.0])
def test01_random_lines_match_reference(shape, t0):
    P = RNG.random(shape).astype(np.float32)
    P[RNG.random(shape) < 0.5] = 0.0  # sparse, as line images are
    got = np.asarray(remove_isolated(P, t0))
    np.testing.assert_allclose(got, ref_remove_isolated(P, t0), atol=1e-6)


@pytest.mark.parametrize("shape", SIZES)
def test02_no_lines_stay_none(shape):
    assert not np.asarray(remove_isolated(np.zeros(shape))).any()


def test03_isolated_contour_pixel_is_removed():
    P = np.zeros((9, 12), np.float32)
    P[4, 2] = 1.0  # isolated
    P[1, 6:11] = 0.9  # a horizontal line
    P[5:8, 8] = 0.8  # a short vertical one
    P[0, 0] = P[8, 11] = 1.0  # isolated in corners (outside counts as nothing)
    got = np.asarray(remove_isolated(P))
    assert got[4, 2] == 0.0 and got[0, 0] == 0.0 and got[8, 11] == 0.0
    np.testing.assert_array_equal(
        got[1, 7:10], np.float32(0.9)
    )  # inner pixels keep their gray level
    assert got[1, 6] == 0.0 and got[1, 10] == 0.0  # ends have one neighbour only
    np.testing.assert_array_equal(got[6, 8], np.float32(0.8))
    np.testing.assert_array_equal(got, ref_remove_isolated(P))


def test04_pixel_at_or_below_t0_needs_three_neighbours():
    P = np.zeros((3, 3), np.float32)
    P[1, 1] = 0.4  # below t0: counts for nobody, itself included
    P[0, 0] = P[0, 2] = 0.9
    assert np.asarray(remove_isolated(P))[1, 1] == 0.0
    P[2, 0] = 0.9
    assert np.asarray(remove_isolated(P))[1, 1] == np.float32(0.4)


def test05_nan_and_inf_never_spread():
    P = RNG.random((64, 48)).astype(np.float32)
    P[3, 3], P[10, 0], P[0, 20] = np.nan, np.inf, -np.inf
    got = np.asarray(remove_isolated(P, 0.5))
    assert np.all(np.isfinite(got)) and got.max() <= 1.0
    np.testing.assert_allclose(got, ref_remove_isolated(P, 0.5), atol=1e-6)
