"""Leaf edges (the outline of every leaf from the leaf_id layer) and bright_fade in the line
chain, against brute-force numpy references."""

from __future__ import annotations

import numpy as np
import pytest

from mi_npr import kernels as K
from mi_npr import layers as L
from mi_npr.errors import ParameterError
from mi_npr.gbuffer import GBuffer

RNG = np.random.default_rng(53)
CROSS = ((-1, 0), (0, -1), (0, 1), (1, 0))


def leaf_edges_ref(ids: np.ndarray, Z: np.ndarray, width: int) -> np.ndarray:
    """Loops: a 4-neighbour (border pixels repeat) with another id; width 1 = the nearer pixel
    only (ties: the larger id); NaN depth is +inf."""
    h, w = ids.shape
    Z = np.where(np.isnan(Z), np.inf, Z)
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            for dy, dx in CROSS:
                yy, xx = min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)
                a, b = ids[y, x], ids[yy, xx]
                if a == b:
                    continue
                z0, z1 = Z[y, x], Z[yy, xx]
                if width == 2 or z1 > z0 or (z1 == z0 and a > b):
                    out[y, x] = 1.0
    return out


def random_leaf_image(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping rectangles ("leaves") at random depths over a background of id 0 and +inf."""
    ids = np.zeros((h, w), np.uint32)
    Z = np.full((h, w), np.inf, np.float32)
    for leaf in range(1, 12):
        y0, x0 = RNG.integers(0, h), RNG.integers(0, w)
        y1, x1 = y0 + RNG.integers(1, 6), x0 + RNG.integers(1, 8)
        z = np.float32(RNG.choice([1.0, 1.5, 2.0]))  # equal depths happen: ties
        sl = np.s_[y0:y1, x0:x1]
        nearer = z < Z[sl]
        ids[sl] = np.where(nearer, leaf, ids[sl])
        Z[sl] = np.where(nearer, z, Z[sl])
    return ids, Z


@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (7, 1), (13, 17), (32, 24)])
@pytest.mark.parametrize("width", [1, 2])
def test01_leaf_edges_match_brute_force(shape, width):
    ids, Z = random_leaf_image(*shape)
    Z[RNG.random(shape) < 0.05] = np.nan
    got = np.asarray(K.leaf_edges(ids, Z, width))
    np.testing.assert_array_equal(got, leaf_edges_ref(ids, Z, width))


def test02_closed_forms():
    # No leaves, or one leaf filling the image: no edges.
    assert not np.asarray(K.leaf_edges(np.zeros((5, 6), np.uint32), np.ones((5, 6)))).any()
    assert not np.asarray(K.leaf_edges(np.full((5, 6), 3, np.uint32), np.ones((5, 6)))).any()
    # A leaf in front of another: width 1 marks the front leaf's border only; every boundary
    # pair gets exactly one marked pixel.
    ids = np.array([[1, 1, 2, 2, 2]], np.uint32)
    Z = np.array([[2, 2, 1, 1, 1]], np.float32)
    assert np.asarray(K.leaf_edges(ids, Z, 1)).tolist() == [[0, 0, 1, 0, 0]]
    assert np.asarray(K.leaf_edges(ids, Z, 2)).tolist() == [[0, 1, 1, 0, 0]]
    ids, Z = random_leaf_image(40, 40)
    one = np.asarray(K.leaf_edges(ids, Z, 1)) > 0
    for dy, dx in ((0, 1), (1, 0)):
        a, b = ids[: 40 - dy, : 40 - dx], ids[dy:, dx:]
        ea, eb = one[: 40 - dy, : 40 - dx], one[dy:, dx:]
        assert np.all((ea | eb)[a != b])  # every boundary is drawn
    for bad in (0, 3, True):
        with pytest.raises(ParameterError, match="width"):
            K.leaf_edges(ids, Z, bad)
    with pytest.raises(ParameterError):
        K.leaf_edges(ids, Z[:, :-1], 1)


def test03_chain_adds_leaf_edges_and_bright_fade():
    h, w = 24, 32
    ids, Z = random_leaf_image(h, w)
    rgb = RNG.uniform(0, 1, (h, w, 3)).astype(np.float32)
    base = {
        L.Z: Z,
        L.OBJECT_ID: (ids > 0).astype(np.uint32),
        L.LEAF_ID: ids,
        **{c: rgb[..., i] for i, c in enumerate(L.RGB)},
    }
    gb = GBuffer(base)
    plain = np.asarray(K.lines(gb))
    for width in (1, 2):
        got = np.asarray(K.lines(gb, leaf_edges=width))
        np.testing.assert_array_equal(got, np.maximum(plain, leaf_edges_ref(ids, Z, width)))
    Y = rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    faded = np.asarray(K.lines(gb, leaf_edges=1, bright_fade=0.3))
    ref = np.maximum(plain, leaf_edges_ref(ids, Z, 1)) * np.clip(2 - Y / 0.3, 0, 1)
    np.testing.assert_allclose(faded, ref, atol=1e-6)
    # The raw beauty wins over R G B when present (lines composited there must not fade lines).
    raw = gb.with_layers({n: np.zeros((h, w), np.float32) for n in L.RAW_RGB})
    np.testing.assert_array_equal(np.asarray(K.lines(raw, bright_fade=0.3)), plain)
    with pytest.raises(ParameterError, match="leaf_id"):
        K.lines(GBuffer({L.Z: Z}), leaf_edges=1)
    with pytest.raises(ParameterError, match="leaf_edges"):
        K.lines(gb, leaf_edges=3)
    with pytest.raises(ParameterError, match="bright_fade"):
        K.lines(gb, bright_fade=-1.0)
