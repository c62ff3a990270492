"""Buffer-mode border following against OpenCV's findContours and brute-force references."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import mi_npr
from mi_npr.contours import Contour, contour_layer, contour_mask, trace


# ----------------------------------------------------------------------------- references
def brute_contour_pixels(ids: np.ndarray) -> np.ndarray:
    """The definition, with plain loops: object pixel with a 4-neighbour that is not it."""
    h, w = ids.shape
    out = np.zeros((h, w), dtype=bool)
    for y in range(h):
        for x in range(w):
            k = ids[y, x]
            if k == 0:
                continue
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                xx, yy = x + dx, y + dy
                if not (0 <= xx < w and 0 <= yy < h) or ids[yy, xx] != k:
                    out[y, x] = True
    return out


def cv2_contours(ids: np.ndarray) -> dict[int, list[tuple[tuple, bool]]]:
    """Per object: (pixel set, is_hole) of every contour OpenCV finds on its zero-padded mask."""
    out = {}
    for k in np.unique(ids):
        if k == 0:
            continue
        mask = np.pad((ids == k).astype(np.uint8), 1)
        found, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        out[int(k)] = sorted(
            (_pixel_set(c[:, 0, :] - 1), bool(h[3] != -1))
            for c, h in zip(found, hier[0], strict=True)
        )
    return out


def _pixel_set(points: np.ndarray) -> tuple:
    return tuple(sorted(set(map(tuple, np.asarray(points).tolist()))))


def ours(contours: list[Contour]) -> dict[int, list[tuple[tuple, bool]]]:
    out: dict[int, list] = {}
    for c in contours:
        out.setdefault(c.object_id, []).append((_pixel_set(c.points), c.is_hole))
    return {k: sorted(v) for k, v in out.items()}


def assert_chain(c: Contour) -> None:
    p = c.points
    assert p.dtype == np.int32 and p.ndim == 2 and p.shape[1] == 2 and len(p) >= 1
    if len(p) > 1:
        step = np.abs(np.diff(np.vstack([p, p[:1]]) if c.closed else p, axis=0)).max(axis=1)
        assert np.all(step == 1), f"{c} is not an 8-connected chain"


def check_all(ids: np.ndarray) -> list[Contour]:
    contours = trace(ids)
    for c in contours:
        assert_chain(c)
        assert c.closed
        assert np.all(ids[c.ys, c.xs] == c.object_id)
    ref = brute_contour_pixels(ids)
    np.testing.assert_array_equal(contour_mask(ids), ref)
    np.testing.assert_array_equal(contour_layer(contours, ids.shape) != 0, ref)
    assert ours(contours) == cv2_contours(ids)
    return contours


# ----------------------------------------------------------------------------- random maps
def _blobs(rng, h, w, n):
    ids = np.zeros((h, w), np.uint32)
    yy, xx = np.mgrid[0:h, 0:w]
    for k in range(n):
        cy, cx = rng.uniform(-2, h + 2), rng.uniform(-2, w + 2)
        ry, rx = rng.uniform(0.5, h / 2 + 1), rng.uniform(0.5, w / 2 + 1)
        ids[((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 < 1] = rng.integers(0, 4)
        if rng.random() < 0.3:  # punch a hole
            ids[((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 < 0.2] = 0 if k % 2 else k + 5
    return ids


@pytest.mark.parametrize("seed", range(6))
def test01_random_blobs_match_opencv(seed):
    rng = np.random.default_rng(seed)
    for _ in range(25):
        h, w = (int(v) for v in rng.integers(1, 40, 2))
        check_all(_blobs(rng, h, w, int(rng.integers(1, 6))))


@pytest.mark.parametrize("seed", range(4))
def test02_random_noise_match_opencv(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(40):
        h, w = (int(v) for v in rng.integers(1, 16, 2))
        if rng.random() < 0.5:
            ids = rng.integers(0, int(rng.integers(1, 5)), (h, w)).astype(np.uint32)
        else:  # sparse noise: many 1-pixel objects and diagonal contacts
            ids = (rng.random((h, w)) < rng.random()).astype(np.uint32) * 3
        check_all(ids)


@pytest.mark.parametrize(
    "ids",
    [
        np.zeros((1, 1), np.uint32),
        np.ones((1, 1), np.uint32),
        np.full((3, 5), 2, np.uint32),  # one object fills the image: contour = image border
        np.array([[1, 1, 0, 2, 2, 2, 0]], np.uint32),  # single row
        np.array([[1], [1], [0], [3], [3]], np.uint32),  # single column
        np.array([[1, 0], [0, 1]], np.uint32),  # diagonal contact: one 8-connected piece
        np.array([[0, 1], [1, 0]], np.uint32),
        np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]], np.uint32),  # 1-pixel hole
        np.array([[1, 1, 1], [1, 2, 1], [1, 1, 1]], np.uint32),  # 1-pixel object in a hole
        np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], np.uint32),  # diamond: hole is 4-connected
        np.pad(np.ones((5, 5), np.uint32), 2),
    ],
    ids=lambda a: f"{a.shape[0]}x{a.shape[1]}-{a.ravel()[:6].tolist()}",
)
def test03_hand_made_maps(ids):
    check_all(ids)


def test04_no_objects_no_contours():
    assert trace(np.zeros((7, 9), np.uint32)) == []
    assert not contour_mask(np.zeros((3, 3), np.uint32)).any()


def test05_pieces_holes_and_order():
    ids = np.zeros((12, 16), np.uint32)
    ids[1:11, 1:7] = 4  # a block with a hole
    ids[4:7, 3:5] = 0
    ids[2:5, 9:14] = 4  # a second piece of the same object
    ids[7:12, 9:16] = 2  # touches the bottom and right borders
    contours = check_all(ids)
    kinds = [(c.object_id, c.is_hole) for c in contours]
    assert kinds == [(2, False), (4, False), (4, False), (4, True)]
    first = [tuple(c.points[0]) for c in contours]
    assert first == [(9, 7), (1, 1), (9, 2), (3, 3)]  # by id, then raster-first pixel
    outer = contours[1]
    assert outer.points[1].tolist() == [2, 1]  # outer borders run clockwise on screen


def test06_single_pixel_and_spurs():
    ids = np.zeros((5, 7), np.uint32)
    ids[2, 3] = 1
    (c,) = check_all(ids)
    assert c.points.tolist() == [[3, 2]] and c.closed
    ids = np.zeros((5, 9), np.uint32)
    ids[2, 1:8] = 6  # a 1-pixel-wide line is walked there and back
    (c,) = check_all(ids)
    assert len(c) == 12 and c.points[0].tolist() == [1, 2]


def test07_input_types_and_errors():
    ids = np.zeros((4, 5), np.float32)
    ids[1:3, 1:4] = 3
    a = trace(ids)
    assert trace(ids.astype(np.int64)) == a and trace(ids.astype(np.uint8)) == a
    assert trace(ids[..., None]) == a
    gb = mi_npr.GBuffer({"object_id.V": ids.astype(np.uint32)}, objects={3: "ball"})
    (c,) = trace(gb)
    assert c.name == "ball" and c.object_id == 3
    assert trace(ids, objects={3: "x"})[0].name == "x" and a[0].name == "object_3"
    assert trace(ids, only=[5]) == [] and trace(ids, only=[3]) == a
    bad = ids.copy()
    bad[0, 0] = np.nan
    with pytest.raises(mi_npr.ParameterError, match="finite"):
        trace(bad)
    bad[0, 0] = np.inf
    with pytest.raises(mi_npr.ParameterError, match="finite"):
        trace(bad)
    with pytest.raises(mi_npr.ParameterError, match="non-negative"):
        trace(np.array([[-1, 2]]))
    with pytest.raises(mi_npr.ParameterError, match="2-D"):
        trace(np.zeros((2, 3, 4)))
    with pytest.raises(mi_npr.ParameterError, match="method"):
        trace(ids, method="moore")


def test08_contour_type():
    c = Contour(2, "a", [[1, 2], [2, 2]], closed=False)
    assert c.points.dtype == np.int32 and c.points.shape == (2, 2) and not c.points.flags.writeable
    assert c == Contour(2, "a", np.array([[1, 2], [2, 2]]), closed=False)
    assert c != Contour(2, "a", [[1, 2], [2, 3]], closed=False)
    assert c.xs.tolist() == [1, 2] and c.ys.tolist() == [2, 2] and len(c) == 2
    assert "open" in repr(c) and "'a'" in repr(c)


def test09_rendered_scenes_match_opencv(scenes):
    for name in ("scene1.xml", "scene3.xml", "scene4.xml", "cornell_box.xml"):
        gb = mi_npr.render(scenes / name, width=96, height=72, spp=1)
        contours = check_all(gb.object_id)
        named = trace(gb)
        assert [c.points.tolist() for c in named] == [c.points.tolist() for c in contours]
        assert {c.name for c in named} <= set(gb.objects.values())
