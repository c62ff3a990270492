"""mi_npr.foliage.leaves: leaf templates, the one-mesh layout, leaf count from leaf_size,
placements and the orientation rules (Van Gogh: long axis perpendicular to the HLP direction)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from mi_npr import foliage as fo
from mi_npr.errors import InputError, ParameterError
from mi_npr.foliage.leaves import leaf_count

RNG = np.random.default_rng(52)


@pytest.fixture(scope="module")
def tree():
    plant = fo.procedural_tree(seed=1, n_leaves=400)
    return plant, fo.build_hlps(plant, k=8, seed=1)


def polygon_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test01_templates():
    quad = fo.leaf_template("quad")
    assert quad.triangles == 2 and quad.area == pytest.approx(1.0)
    disc = fo.leaf_template("disc")
    assert disc.triangles == 12 and disc.area == pytest.approx(0.5 * 12 * 0.25 * np.sin(np.pi / 6))
    ell = fo.leaf_template("ellipse")
    assert ell.area == pytest.approx(0.4 * disc.area)
    leaf = fo.leaf_template("leaf")
    assert leaf.area == pytest.approx(polygon_area(leaf.xy[1:]))  # a fan of a simple polygon
    for t in (quad, disc, ell, leaf):
        # Length 1 along +x, counter-clockwise seen from +z (every triangle's area positive).
        assert np.ptp(t.xy[:, 0]) == pytest.approx(1.0)
        a, b, c = (t.xy[t.faces[:, j]] for j in range(3))
        e1, e2 = b - a, c - a
        assert np.all(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0)
        np.testing.assert_allclose(t.uv, t.xy + 0.5)
    with pytest.raises(ParameterError, match="leaf_shape"):
        fo.leaf_template("star")


def test02_textured_alpha_leaf(tmp_path):
    """A disc in the alpha channel gives a disc-like outline whose UVs sit on the image."""
    n = 64
    yy, xx = np.mgrid[0:n, 0:n]
    alpha = ((xx + 0.5 - 32) ** 2 + (yy + 0.5 - 32) ** 2 <= 24**2) * 255
    rgba = np.dstack([np.full((n, n), 40), np.full((n, n), 160), np.full((n, n), 30), alpha])
    Image.fromarray(rgba.astype(np.uint8), "RGBA").save(tmp_path / "leaf.png")
    t = fo.leaf_template(str(tmp_path / "leaf.png"))
    radius = np.linalg.norm(t.xy[1:] - t.xy[0], axis=1)
    np.testing.assert_allclose(radius, 24 / 64, atol=1.5 / 64)
    assert np.all((t.uv >= 0) & (t.uv <= 1))
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(tmp_path / "rgb.png")
    with pytest.raises(InputError, match="alpha"):
        fo.leaf_template(str(tmp_path / "rgb.png"))
    Image.fromarray(np.zeros((8, 8, 4), np.uint8), "RGBA").save(tmp_path / "empty.png")
    with pytest.raises(InputError, match="no leaf"):
        fo.leaf_template(str(tmp_path / "empty.png"))
    with pytest.raises(InputError, match="no such file"):
        fo.leaf_template(str(tmp_path / "none.png"))


def test03_mesh_layout_brute_force(tree):
    plant, hlps = tree
    leaves = fo.make_leaves(hlps, plant, leaf_size=0.2, shape="ellipse", placement="leaves")
    V, F, _, face_leaf = leaves.mesh()
    t = leaves.template
    assert V.dtype == np.float32 and F.dtype == np.uint32 and len(F) == len(leaves) * t.triangles
    for i in RNG.choice(len(leaves), 10, replace=False):
        side = np.cross(leaves.normals[i], leaves.axes[i])
        for j, (x, y) in enumerate(t.xy):
            v = leaves.centers[i] + leaves.sizes[i] * (x * leaves.axes[i] + y * side)
            np.testing.assert_allclose(V[i * len(t.xy) + j], v, atol=1e-5)
        faces = F[face_leaf == i]
        assert np.array_equal(faces, t.faces + i * len(t.xy))
        # Geometric normals of the leaf's triangles = the leaf's normal.
        p0, p1, p2 = (V[faces[:, k]].astype(np.float64) for k in range(3))
        n = np.cross(p1 - p0, p2 - p0)
        n /= np.linalg.norm(n, axis=1)[:, None]
        np.testing.assert_allclose(n, np.broadcast_to(leaves.normals[i], n.shape), atol=1e-4)
    np.testing.assert_array_equal(face_leaf, np.repeat(np.arange(len(leaves)), t.triangles))


def test04_leaf_size_sets_the_count_and_keeps_the_area(tree):
    plant, hlps = tree
    for placement, area in (("leaves", plant.total_area), ("surface", hlps.surface_area())):
        counts = []
        for s in (0.05, 0.1, 0.2, 0.4):
            leaves = fo.make_leaves(hlps, plant, leaf_size=s, placement=placement, shape="disc")
            counts.append(len(leaves))
            covered = len(leaves) * leaves.template.area * s**2
            assert covered == pytest.approx(area, rel=0.25 if len(leaves) < 10 else 0.02)
        assert counts == sorted(counts, reverse=True) and counts[0] > counts[-1]
    assert leaf_count(0.0, 0.1, fo.leaf_template("quad"), 1.0) == 0
    double = fo.make_leaves(hlps, plant, leaf_size=0.1, placement="leaves", coverage=2.0)
    single = fo.make_leaves(hlps, plant, leaf_size=0.1, placement="leaves")
    assert len(double) == pytest.approx(2 * len(single), abs=1)
    with pytest.raises(ParameterError, match="max_leaves"):
        fo.make_leaves(hlps, plant, leaf_size=0.001, placement="leaves", max_leaves=1000)


def test05_placements(tree):
    plant, hlps = tree
    few = fo.make_leaves(hlps, plant, leaf_size=0.3, placement="leaves", orientation="leaf")
    # Fewer primitives than leaves: a subset of the leaves, with their own frames.
    idx = [int(np.argmin(np.linalg.norm(plant.centers - c, axis=1))) for c in few.centers]
    np.testing.assert_allclose(few.centers, plant.centers[idx], atol=1e-12)
    # ... turned to face the outside of the HLP surface.
    sign = np.sign(np.sum(plant.normals[idx] * hlps.normal(few.centers), axis=1))
    np.testing.assert_allclose(few.normals, sign[:, None] * plant.normals[idx], atol=1e-12)
    assert len(set(idx)) == len(idx)
    many = fo.make_leaves(hlps, plant, leaf_size=0.02, placement="leaves", orientation="leaf")
    assert len(many) > len(plant)
    # Extra primitives stay within their leaf's extent.
    near = np.min(np.linalg.norm(many.centers[:, None] - plant.centers[None], axis=2), axis=1)
    assert near.max() <= 0.75 * plant.sizes.max()
    on = fo.make_leaves(hlps, plant, leaf_size=0.1, placement="surface")
    np.testing.assert_allclose(hlps.field(on.centers), hlps.iso, rtol=1e-4)
    inside = fo.make_leaves(hlps, plant, leaf_size=0.1, placement="volume")
    assert np.all(hlps.field(inside.centers) >= hlps.iso)
    assert len(on) == len(inside)
    a = fo.make_leaves(hlps, plant, leaf_size=0.1, seed=3)
    b = fo.make_leaves(hlps, plant, leaf_size=0.1, seed=3)
    np.testing.assert_array_equal(a.centers, b.centers)


def test06_orientation_rules(tree):
    plant, hlps = tree
    for orientation in ("hlp", "van_gogh", "random", "leaf"):
        leaves = fo.make_leaves(
            hlps, plant, leaf_size=0.1, placement="leaves", orientation=orientation, tilt=20.0
        )
        N, A = leaves.normals, leaves.axes
        np.testing.assert_allclose(np.linalg.norm(N, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(A, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.sum(N * A, axis=1), 0.0, atol=1e-12)
        n_hlp = hlps.normal(leaves.centers)
        assert np.all(np.sum(N * n_hlp, axis=1) >= 0)  # leaves face the outside
        if orientation == "hlp":
            angle = np.degrees(np.arccos(np.clip(np.sum(N * n_hlp, axis=1), -1, 1)))
            assert angle.max() <= 20.0 + 1e-6
        assert np.array_equal(leaves.hlp, hlps.dominant(leaves.centers))


def test07_van_gogh_long_axis_is_perpendicular_to_the_hlp_direction(tree):
    """The issue's rule: every leaf's long axis within 5 degrees of perpendicular to the
    direction from its HLP centre, checked on the emitted mesh itself."""
    plant, hlps = tree
    for placement in ("surface", "leaves", "volume"):
        leaves = fo.make_leaves(
            hlps, plant, leaf_size=0.08, shape="ellipse", placement=placement,
            orientation="van_gogh", tilt=30.0,
        )  # fmt: skip
        V, F, _, face_leaf = leaves.mesh()
        nv = len(leaves.template.xy)
        verts = V.reshape(len(leaves), nv, 3).astype(np.float64)
        # The ellipse's long axis: the direction between its two farthest rim vertices.
        rim = verts[:, 1:]
        d2 = np.sum((rim[:, :, None] - rim[:, None, :]) ** 2, axis=-1)
        i, j = np.unravel_index(np.argmax(d2.reshape(len(leaves), -1), axis=1), d2.shape[1:])
        long_axis = rim[np.arange(len(leaves)), i] - rim[np.arange(len(leaves)), j]
        long_axis /= np.linalg.norm(long_axis, axis=1, keepdims=True)
        centre = verts.mean(axis=1)
        # "Its HLP": the blob contributing most to the field at the leaf, brute force.
        contrib = [
            [
                w * np.exp(-0.5 * np.sum(((p - c) @ a.T / r) ** 2))
                for c, r, a, w in zip(
                    hlps.centers, hlps.radii, hlps.axes, hlps.weights, strict=True
                )
            ]
            for p in leaves.centers
        ]
        own = hlps.centers[np.argmax(contrib, axis=1)]
        d = centre - own
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        off = np.degrees(np.arcsin(np.clip(np.abs(np.sum(long_axis * d, axis=1)), 0, 1)))
        assert off.max() < 5.0, placement
        assert len(face_leaf) == len(F)


def test08_empty_and_single_leaf_inputs():
    empty_plant = fo.Plant.from_mesh(np.zeros((0, 3)), np.zeros((0, 3)))
    empty_hlps = fo.build_hlps(empty_plant)
    for placement in ("leaves", "surface", "volume"):
        leaves = fo.make_leaves(empty_hlps, empty_plant, leaf_size=0.1, placement=placement)
        assert len(leaves) == 0
        V, F, _, fl = leaves.mesh()
        assert V.shape == (0, 3) and F.shape == (0, 3) and fl.shape == (0,)
    one = fo.Plant.from_points([[0, 1, 0]], [[0, 0, 1]], sizes=0.2, areas=0.02)
    h1 = fo.build_hlps(one)
    for placement in ("leaves", "surface", "volume"):
        for orientation in ("hlp", "van_gogh", "random"):
            leaves = fo.make_leaves(h1, one, 0.05, placement=placement, orientation=orientation)
            assert len(leaves) >= 1 and np.all(np.isfinite(leaves.mesh()[0]))
    for bad, match in (
        ({"leaf_size": 0.0}, "leaf_size"),
        ({"leaf_size": float("nan")}, "leaf_size"),
        ({"coverage": -1.0}, "coverage"),
        ({"tilt": 100.0}, "tilt"),
        ({"placement": "air"}, "placement"),
        ({"orientation": "up"}, "orientation"),
        ({"placement": "surface", "orientation": "leaf"}, "orientation"),
    ):
        with pytest.raises(ParameterError, match=match):
            fo.make_leaves(h1, one, **{"leaf_size": 0.1, **bad})
    with pytest.raises(ParameterError, match="needs the plant"):
        fo.make_leaves(h1, None, 0.1, placement="leaves")
