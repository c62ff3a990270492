"""The corner-grid edge classifier (mi_npr.raytree.classify_edges) against a brute-force numpy
loop written from the rules in the module docstring, on random and hand-made corner trees."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.raytree import Trees, classify_edges


def make_trees(obj, lights, levels) -> Trees:
    """Corner trees from numpy arrays: obj (H+1, W+1); lights (H+1, W+1, words);
    levels (H+1, W+1, depth-1, 2) uint64."""
    mi = mi_npr.mi
    n = obj.size
    lv = levels.reshape(n, -1, 2)
    return Trees(
        mi.UInt64(np.zeros(n, np.uint64)),
        mi.UInt32(obj.ravel().astype(np.uint32)),
        tuple(
            mi.UInt32(lights.reshape(n, -1)[:, i].astype(np.uint32))
            for i in range(lights.shape[-1])
        ),
        tuple(
            (mi.UInt64(lv[:, d, 0].copy()), mi.UInt64(lv[:, d, 1].copy()))
            for d in range(lv.shape[1])
        ),
    )


def classify_ref(obj, lights, levels):
    """One pixel at a time: the shallowest depth where the four corners disagree decides."""
    h, w = obj.shape[0] - 1, obj.shape[1] - 1
    out = {name: np.zeros((h, w), np.float32) for name in L.EDGES}
    for y in range(h):
        for x in range(w):
            cs = [(y, x), (y, x + 1), (y + 1, x), (y + 1, x + 1)]

            def differ(get, cs=cs):
                return len({get(c) for c in cs}) > 1

            if differ(lambda c: obj[c]):
                out[L.EDGES_REAL][y, x] = 1
                continue
            if differ(lambda c: tuple(lights[c])):
                out[L.EDGES_SHADOW][y, x] = 1
                continue
            for d in range(levels.shape[2]):
                refr = differ(lambda c, d=d: levels[c][d, 1])
                refl = differ(lambda c, d=d: levels[c][d, 0])
                if refr:  # a tie goes to refraction
                    out[L.EDGES_REFRACTION][y, x] = 1
                    break
                if refl:
                    out[L.EDGES_REFLECTION][y, x] = 1
                    break
    return out


def run(obj, lights, levels):
    h, w = obj.shape[0] - 1, obj.shape[1] - 1
    got = classify_edges(make_trees(obj, lights, levels), w, h)
    return {k: np.asarray(v.numpy()).reshape(h, w) for k, v in got.items()}


def random_corners(rng, h, w, words=1, depth=3, p=0.15):
    """Mostly-equal corner data, so that differences at every depth occur."""

    def sparse(shape, hi):
        return np.where(rng.random(shape) < p, rng.integers(1, hi, shape), 0)

    obj = sparse((h + 1, w + 1), 3).astype(np.uint32)
    lights = sparse((h + 1, w + 1, words), 3).astype(np.uint32)
    levels = sparse((h + 1, w + 1, depth - 1, 2), 2**62).astype(np.uint64)
    return obj, lights, levels


@pytest.mark.parametrize(
    ("h", "w", "words", "depth"),
    [(1, 1, 1, 3), (1, 7, 1, 2), (5, 1, 2, 4), (9, 13, 1, 3), (16, 11, 2, 5), (4, 4, 1, 1)],
)
def test01_random_corners_match_the_reference(h, w, words, depth):
    rng = np.random.default_rng(h * 100 + w)
    for _ in range(3):
        obj, lights, levels = random_corners(rng, h, w, words, depth)
        got, ref = run(obj, lights, levels), classify_ref(obj, lights, levels)
        for k in L.EDGES:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=k)
        total = sum(got.values())
        assert total.max() <= 1  # exactly one class per edge pixel


def test02_no_edges_anywhere():
    obj = np.full((6, 8), 3, np.uint32)
    lights = np.full((6, 8, 1), 5, np.uint32)
    levels = np.full((6, 8, 2, 2), 77, np.uint64)
    got = run(obj, lights, levels)
    assert all(not v.any() for v in got.values())
    assert all(v.dtype == np.float32 and v.shape == (5, 7) for v in got.values())


def test03_hand_made_classes_and_tie():
    obj = np.ones((2, 2), np.uint32)
    lights = np.zeros((2, 2, 1), np.uint32)
    levels = np.zeros((2, 2, 2, 2), np.uint64)
    assert run(obj, lights, levels)[L.EDGES_REAL].sum() == 0
    o = obj.copy()
    o[1, 1] = 2
    assert run(o, lights, levels)[L.EDGES_REAL][0, 0] == 1
    li = lights.copy()
    li[0, 1, 0] = 1
    assert run(obj, li, levels)[L.EDGES_SHADOW][0, 0] == 1
    lv = levels.copy()
    lv[1, 0, 1, 1] = 9  # a depth-2 refraction difference ...
    assert run(obj, lights, lv)[L.EDGES_REFRACTION][0, 0] == 1
    lv[0, 0, 0, 0] = 4  # ... loses against a shallower reflection difference
    assert run(obj, lights, lv)[L.EDGES_REFLECTION][0, 0] == 1
    lv[0, 1, 0, 1] = 4  # same depth, both kinds differ: refraction wins the tie
    assert run(obj, lights, lv)[L.EDGES_REFRACTION][0, 0] == 1
    lv2 = levels.copy()
    lv2[:, :, 0, :] = 5  # all equal, however large: no edge
    assert sum(v.sum() for v in run(obj, lights, lv2).values()) == 0


def test04_a_vertical_object_boundary_marks_one_pixel_column():
    obj = np.zeros((5, 7), np.uint32)
    obj[:, 3:] = 1  # corner columns 0..2 see nothing, 3..6 the object
    got = run(obj, np.zeros((5, 7, 1), np.uint32), np.zeros((5, 7, 2, 2), np.uint64))
    expected = np.zeros((4, 6), np.float32)
    expected[:, 2] = 1  # the pixels whose corners straddle the boundary
    np.testing.assert_array_equal(got[L.EDGES_REAL], expected)


def test05_size_mismatch_is_an_error():
    obj, lights, levels = random_corners(np.random.default_rng(0), 3, 4)
    trees = make_trees(obj, lights, levels)
    with pytest.raises(mi_npr.ParameterError, match="corner trees"):
        classify_edges(trees, 4, 4)
    with pytest.raises(mi_npr.ParameterError, match="at least"):
        classify_edges(trees, 0, 3)
