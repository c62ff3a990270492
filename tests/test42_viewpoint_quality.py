"""mi_npr.viewpoint.quality: eqs. 1-3 of one viewpoint, from its ID buffer."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr.meshes import merge, write_ply
from mi_npr.viewpoint import qualities, quality

MEASURES = ("pb", "curvature", "entropy")


@pytest.fixture
def hand_made(write_scene, tmp_path):
    """A square of 2 triangles facing the camera, a triangle hidden behind it (one mesh), and an
    analytic sphere hidden behind both: n = 4 polygons. Square camera, fov 90 (tan = 1)."""
    square = (
        np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32),
        np.array([[0, 2, 1], [0, 3, 2]]),  # wound to face -z, the camera (one-sided BSDF)
    )
    hidden = (np.array([[-0.2, -0.2, 1], [0.2, -0.2, 1], [0, 0.2, 1]], np.float32), [[0, 1, 2]])
    ply = write_ply(tmp_path / "hand.ply", *merge(square, hidden))
    body = (
        f'<shape type="ply" id="hand"><string name="filename" value="{ply}"/></shape>'
        '<shape type="sphere" id="behind"><point name="center" x="0" y="0" z="2"/>'
        '<float name="radius" value="0.3"/></shape>'
    )
    return write_scene(body, width=32, height=32, fov=90.0, origin="0, 0, -2", target="0, 0, 0")


def test01_eq1_on_a_hand_made_mesh(hand_made):
    # The square spans [-1, 1]^2 at distance 2: NDC [-0.5, 0.5], so the pixel centres
    # x + 0.5 with |1 - 2 (x + 0.5) / 32| < 0.5 are covered: x = 8..23, 16 x 16 pixels.
    # Visible: the 2 square triangles of n = 4 polygons.
    expected = 2 / 4 + 16 * 16 / (32 * 32)
    got = quality(hand_made, [0, 0, -2], [0, 0, 0], measure="pb", res=32)
    assert got == pytest.approx(expected, abs=1e-12)
    # At res 64 the square covers 32 x 32 of 64 x 64 pixels: the same value.
    assert quality(hand_made, [0, 0, -2], [0, 0, 0], "pb", 64) == pytest.approx(expected)


def test02_entropy_and_curvature_by_hand(hand_made):
    from mi_npr.viewpoint import areas, polygons

    scene = mi_npr.load_scene(hand_made)
    a = areas(scene, [[0, 0, -2]], [0, 0, 0], 90.0, (32, 32))[0].astype(float)
    # Objects by name: "behind" (the sphere) is polygon 1, "hand" polygons 2-4.
    assert a[0] == 1024 - 256 and a[1] == 0 and a[2] + a[3] == 256 and a[4] == 0
    p = a[a > 0] / 1024
    assert quality(scene, [0, 0, -2], [0, 0, 0], "entropy", 32) == pytest.approx(
        -(p * np.log2(p)).sum()
    )
    # Visible vertices: the square's 4 corners, all on the mesh boundary, each with angles
    # summing to pi / 2 (one right angle, or two halves of one at the diagonal): pi - pi / 2.
    assert polygons(scene).n == 4
    expected = 4 * (math.pi / 2) * (256 / 1024)
    assert quality(scene, [0, 0, -2], [0, 0, 0], "curvature", 32) == pytest.approx(expected)


@pytest.mark.parametrize("measure", MEASURES)
def test03_a_viewpoint_that_sees_nothing(hand_made, measure):
    # Looking away from the scene.
    assert quality(hand_made, [0, 0, -2], [0, 0, -5], measure=measure, res=16) == 0.0
    # An empty scene.
    empty = mi_npr.mi.load_dict({"type": "scene"})
    assert quality(empty, [0, 0, -2], measure=measure, res=8) == 0.0


def test04_batch_equals_single_and_default_target(hand_made):
    scene = mi_npr.load_scene(hand_made)
    rng = np.random.default_rng(1)
    origins = 3 * rng.normal(size=(5, 3))
    for m in MEASURES:
        batch = qualities(scene, origins, measure=m, res=24)
        single = [quality(scene, o, measure=m, res=24) for o in origins]
        np.testing.assert_allclose(batch, single)
    # Default target: the bounding sphere's centre.
    c = np.asarray(scene.bbox().bounding_sphere().center).ravel()
    assert quality(scene, origins[0], res=24) == quality(scene, origins[0], c, res=24)
    # A path works like a loaded scene.
    assert quality(hand_made, origins[0], res=24) == quality(scene, origins[0], res=24)


def test05_bad_parameters(hand_made):
    with pytest.raises(mi_npr.ParameterError, match="measure"):
        quality(hand_made, [0, 0, -2], measure="beauty")
    with pytest.raises(mi_npr.ParameterError, match="res"):
        quality(hand_made, [0, 0, -2], res=0)
    with pytest.raises(mi_npr.ParameterError, match="target"):
        quality(hand_made, [0, 0, -2], target=[0, 1])
    with pytest.raises(mi_npr.SceneError, match="no such file"):
        quality("does/not/exist.xml", [0, 0, -2])
