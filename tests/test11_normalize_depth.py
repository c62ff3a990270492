"""normalize_depth against a brute-force reference (the issue's definition, written as loops)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mi_npr.kernels import normalize_depth

RNG = np.random.default_rng(11)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]


def ref_normalize(Z, near=None, far=None):
    """D = clamp((Z - near) / (far - near), 0, 1); non-finite Z -> 1; near/far default to the
    frame's finite range, a given bound is never crossed by the other; far == near is a step."""
    Z = np.asarray(Z, dtype=np.float64)
    finite = [float(z) for z in Z.flat if math.isfinite(z)]
    lo = min(finite) if finite else math.inf
    hi = max(finite) if finite else -math.inf
    n = lo if near is None else near
    f = hi if far is None else far
    if near is not None and far is None:
        f = max(f, n)
    if far is not None and near is None:
        n = min(n, f)
    out = np.ones(Z.shape)
    for idx, z in np.ndenumerate(Z):
        if not math.isfinite(z):
            continue
        if f > n:
            out[idx] = min(max((z - n) / (f - n), 0.0), 1.0)
        else:
            out[idx] = 0.0 if z <= n else 1.0
    return out


def _depths(shape):
    Z = RNG.uniform(2.0, 9.0, shape)
    if Z.size > 3:
        Z.flat[RNG.choice(Z.size, Z.size // 4, replace=False)] = np.inf  # background
    return Z


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize(("near", "far"), [(None, None), (1.0, 12.0), (3.0, 6.0), (4.0, None)])
def test01_matches_reference(shape, near, far):
    Z = _depths(shape)
    got = np.asarray(normalize_depth(Z.astype(np.float32), near=near, far=far))
    np.testing.assert_allclose(got, ref_normalize(Z.astype(np.float32), near, far), atol=1e-6)


@pytest.mark.parametrize("shape", [(7, 5), (64, 48), (65, 67)])  # 65x67: a partial reduction block
def test02_frame_range_maps_to_exactly_0_and_1(shape):
    Z = _depths(shape)
    D = np.asarray(normalize_depth(Z))
    finite = np.isfinite(Z)
    assert D[finite].min() == 0.0 and D[finite].max() == 1.0
    assert np.all(D[~finite] == 1.0)
    assert np.all(np.diff(D[finite][np.argsort(Z[finite])]) >= 0)  # order is kept


def test03_only_one_bound_given():
    Z = np.array([[2.0, 4.0, 6.0, np.inf]])
    np.testing.assert_allclose(np.asarray(normalize_depth(Z, far=10.0)), [[0, 0.25, 0.5, 1]])
    np.testing.assert_allclose(np.asarray(normalize_depth(Z, near=0.0)), [[1 / 3, 2 / 3, 1, 1]])
    # A bound beyond the frame: the other one follows it instead of crossing it.
    np.testing.assert_array_equal(np.asarray(normalize_depth(Z, near=8.0)), [[0, 0, 0, 1]])
    np.testing.assert_array_equal(np.asarray(normalize_depth(Z, far=1.0)), [[1, 1, 1, 1]])


@pytest.mark.parametrize(
    ("Z", "expected"),
    [
        (np.full((3, 4), np.inf), np.ones((3, 4))),  # nothing hit
        (np.full((3, 4), 5.0), np.zeros((3, 4))),  # one depth: all nearest
        (np.array([[5.0]]), np.zeros((1, 1))),
        (np.array([[np.inf]]), np.ones((1, 1))),
        (np.array([[np.nan, 1.0, -np.inf, 3.0, np.inf]]), np.array([[1, 0, 1, 1, 1]])),
    ],
)
def test04_degenerate_frames_and_non_finite_values(Z, expected):
    got = np.asarray(normalize_depth(Z))
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(got, ref_normalize(Z))


def test05_nan_and_inf_never_spread():
    Z = _depths((64, 48))
    Z[10, 10], Z[20, 30], Z[0, 0] = np.nan, -np.inf, np.nan
    D = np.asarray(normalize_depth(Z))
    assert np.all(np.isfinite(D))
    np.testing.assert_allclose(D, ref_normalize(Z), atol=1e-6)
    assert D[10, 10] == 1.0 and D[20, 30] == 1.0
