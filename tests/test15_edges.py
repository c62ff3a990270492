"""Object-ID and normal (crease) edges against brute-force references from the definitions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mi_npr.kernels import id_edges, normal_edges

RNG = np.random.default_rng(15)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]
CROSS = ((-1, 0), (0, -1), (0, 1), (1, 0))


def _neighbours(h, w, y, x):
    """The 4-neighbours, clamped: outside the image repeats the border pixel."""
    for dy, dx in CROSS:
        yield min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)


def ref_id_edges(ids):
    h, w = ids.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            out[y, x] = any(ids[q] != ids[y, x] for q in _neighbours(h, w, y, x))
    return out


def _angle(a, b):
    """Angle between two vectors in degrees, None if either is zero or not finite."""
    la, lb = math.sqrt(sum(v * v for v in a)), math.sqrt(sum(v * v for v in b))
    if not (math.isfinite(la) and math.isfinite(lb)) or la == 0 or lb == 0:
        return None
    if np.array_equal(a, b):
        return 0.0  # acos of a rounded 1 would not be exactly 0
    cos = sum(u * v for u, v in zip(a, b, strict=True)) / (la * lb)
    return math.degrees(math.acos(min(max(cos, -1.0), 1.0)))


def ref_normal_edges(N, ids, angle_deg):
    h, w = ids.shape
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            if ids[y, x] == 0:
                continue
            for q in _neighbours(h, w, y, x):
                a = _angle(N[y, x].astype(np.float64), N[q].astype(np.float64))
                if ids[q] == ids[y, x] and a is not None and a > angle_deg:
                    out[y, x] = 1.0
    return out


@pytest.mark.parametrize("shape", SIZES)
def test01_id_edges_match_reference(shape):
    ids = RNG.integers(0, 3, shape).astype(np.uint32)
    np.testing.assert_array_equal(np.asarray(id_edges(ids)), ref_id_edges(ids))


@pytest.mark.parametrize("shape", SIZES)
def test02_one_object_no_edges(shape):
    for value in (0, 7):
        assert not np.asarray(id_edges(np.full(shape, value, np.uint32))).any()
    n = np.zeros((*shape, 3), np.float32)
    n[..., 2] = 1.0
    assert not np.asarray(normal_edges(n, np.ones(shape, np.uint32), 1.0)).any()


def test03_id_edge_is_two_pixels_thick_and_the_border_is_no_edge():
    ids = np.ones((6, 8), np.uint32)
    ids[:, 5:] = 2
    e = np.asarray(id_edges(ids))
    assert np.all(e[:, 4:6] == 1.0) and e.sum() == 12


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("angle", [0.0, 20.0, 60.0, 135.0])
def test04_normal_edges_match_reference(shape, angle):
    # Smoothly varying normals with a few creases, unnormalised, on three objects.
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    n = np.stack([np.sin(xx * 0.3), np.cos(yy * 0.2), np.ones((h, w))], axis=-1)
    n += RNG.normal(scale=0.05, size=n.shape)
    n[RNG.random((h, w)) < 0.1] *= -1.0  # creases
    n *= RNG.uniform(0.5, 2.0, (h, w, 1))
    ids = RNG.integers(0, 3, shape).astype(np.uint32)
    got = np.asarray(normal_edges(n.astype(np.float32), ids, angle))
    np.testing.assert_array_equal(got, ref_normal_edges(n.astype(np.float32), ids, angle))


def test05_crease_of_a_box():
    n = np.zeros((5, 8, 3), np.float32)
    n[:, :4] = (0, 0, -1)  # front face
    n[:, 4:] = (1, 0, 0)  # side face, 90 degrees away
    ids = np.ones((5, 8), np.uint32)
    e = np.asarray(normal_edges(n, ids, 30.0))
    assert np.all(e[:, 3:5] == 1.0) and e.sum() == 10
    assert not np.asarray(normal_edges(n, ids, 95.0)).any()  # 90 is not above 95
    ids[:, 4:] = 2  # another object: an ID edge, not a crease
    assert not np.asarray(normal_edges(n, ids, 30.0)).any()
    ids[:] = 0  # background has no creases
    assert not np.asarray(normal_edges(n, ids, 30.0)).any()


def test06_nan_inf_and_zero_normals_make_no_edges():
    n = np.zeros((4, 5, 3), np.float32)
    n[..., 2] = 1.0
    n[1, 1] = np.nan
    n[2, 3] = (np.inf, 0, 0)
    n[0, 4] = 0.0
    ids = np.ones((4, 5), np.uint32)
    got = np.asarray(normal_edges(n, ids, 10.0))
    assert not got.any()
    np.testing.assert_array_equal(got, ref_normal_edges(n, ids, 10.0))


def test07_exactly_the_threshold_angle_is_no_edge():
    # "More than angle_deg": a right angle is no crease at 90 degrees, one at 89.9.
    N = np.zeros((1, 2, 3), np.float32)
    N[0, 0], N[0, 1] = (0, 0, 1), (1, 0, 0)
    ids = np.ones((1, 2), np.uint32)
    np.testing.assert_array_equal(np.asarray(normal_edges(N, ids, 90.0)), [[0, 0]])
    np.testing.assert_array_equal(np.asarray(normal_edges(N, ids, 89.9)), [[1, 1]])
    N[0, 1] = (0.5, 0, math.sqrt(3) / 2)  # 30 degrees, exact in the reference
    assert not np.asarray(normal_edges(N, ids, 30.0)).any()
