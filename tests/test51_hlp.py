"""mi_npr.foliage.hlp: the summed-blob field, its closed-form gradient and normal (numpy and
Dr.Jit), JSON, clustering, and the implicit surface's area and samples."""

from __future__ import annotations

import dataclasses
import json
import math

import drjit as dr
import numpy as np
import pytest
from scipy import stats

import mi_npr
from mi_npr import foliage as fo
from mi_npr.errors import InputError, ParameterError
from mi_npr.foliage.hlp import clusters_for_radius, field_normal, kmeans

mi = mi_npr.mi
RNG = np.random.default_rng(51)


def random_hlps(k: int, rng=RNG) -> fo.HLPSet:
    axes = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(k)])
    return fo.HLPSet(
        rng.normal(size=(k, 3)), rng.uniform(0.3, 1.0, (k, 3)), axes, rng.uniform(0.5, 2.0, k)
    )


def field_brute(h: fo.HLPSet, p: np.ndarray) -> float:
    """The documented field, one blob at a time: sum_i w_i exp(-q_i / 2)."""
    total = 0.0
    for c, r, a, w in zip(h.centers, h.radii, h.axes, h.weights, strict=True):
        q = sum(((p - c) @ a[j] / r[j]) ** 2 for j in range(3))
        total += w * math.exp(-q / 2)
    return total


def fd_normal(h: fo.HLPSet, p: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    g = np.array(
        [(field_brute(h, p + eps * e) - field_brute(h, p - eps * e)) / (2 * eps) for e in np.eye(3)]
    )
    return -g / np.linalg.norm(g)


def test01_field_and_gradient_match_the_definition():
    h = random_hlps(5)
    P = RNG.normal(size=(30, 3))
    np.testing.assert_allclose(h.field(P), [field_brute(h, p) for p in P], rtol=1e-12)
    eps = 1e-6
    fd = np.stack(
        [(h.field(P + eps * e) - h.field(P - eps * e)) / (2 * eps) for e in np.eye(3)], axis=1
    )
    np.testing.assert_allclose(h.gradient(P), fd, atol=1e-7)
    n = h.normal(P)
    np.testing.assert_allclose(n, -fd / np.linalg.norm(fd, axis=1, keepdims=True), atol=1e-6)
    # A lone blob of weight 1: its ellipsoid is the iso-surface, and the normal is the ellipsoid's.
    one = fo.HLPSet([[1, 2, 3]], [[2, 1, 0.5]], [np.eye(3)], [1.0])
    on = np.array([[1 + 2 * np.cos(0.3), 2 + np.sin(0.3), 3.0], [1, 2, 3.5]])
    np.testing.assert_allclose(one.field(on), fo.ISO)
    grad_q = (on - [1, 2, 3]) / np.array([4, 1, 0.25])
    np.testing.assert_allclose(one.normal(on), grad_q / np.linalg.norm(grad_q, axis=1)[:, None])
    assert np.all(one.normal([[1, 2, 3]]) == 0)  # the centre: no gradient, no normal
    assert one.dominant(on).tolist() == [0, 0]


def test02_normal_far_away_and_empty():
    """Far from every blob F underflows, but the normal stays defined (shifted exponents)."""
    h = random_hlps(3)
    far = np.array([[40.0, 0, 0], [0, -60, 0]])
    assert np.all(h.field(far) == 0)
    n = h.normal(far)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    # Brute force in log space: the blob with the largest exponent dominates there.
    lw = np.log(h.weights)[None] - 0.5 * np.einsum(
        "nki,kij,nkj->nk", far[:, None] - h.centers, h.metrics(), far[:, None] - h.centers
    )
    best = np.argmax(lw, axis=1)
    m = np.einsum("nij,nj->ni", h.metrics()[best], far - h.centers[best])
    np.testing.assert_allclose(n, m / np.linalg.norm(m, axis=1, keepdims=True), atol=1e-6)
    empty = fo.HLPSet(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0))
    assert len(empty) == 0 and empty.field(far).tolist() == [0, 0]
    assert empty.surface_area() == 0 and empty.dominant(far).tolist() == [-1, -1]


def test03_dr_jit_normal_matches_numpy():
    h = random_hlps(7)
    P = np.concatenate([RNG.normal(size=(200, 3)), [[30.0, 0, 0], [np.nan, 0, 0]]])
    p = mi.Point3f(P[:, 0].astype(np.float32), P[:, 1].astype(np.float32), P[:, 2])
    n = np.asarray(dr.ravel(field_normal(mi.Float(h.packed()), len(h), p))).reshape(-1, 3)
    ref = h.normal(P.astype(np.float32).astype(np.float64))
    np.testing.assert_allclose(n[:-1], ref[:-1], atol=2e-5)
    assert np.all(n[-1] == 0)  # NaN in, no normal out


def test04_validation_and_json(tmp_path):
    h = random_hlps(4)
    back = fo.HLPSet.load(h.save(tmp_path / "h.json"))
    for attr in ("centers", "radii", "axes", "weights"):
        np.testing.assert_array_equal(getattr(back, attr), getattr(h, attr))
    assert back.iso == h.iso
    d = json.loads((tmp_path / "h.json").read_text())
    assert d["format"] == "mi-npr/hlps" and len(d["hlps"]) == 4
    # Edit and save: a user moves a blob.
    moved = dataclasses.replace(h, centers=h.centers + np.array([0, 1, 0]))
    assert fo.HLPSet.load(moved.save(tmp_path / "m.json")).centers[0, 1] == h.centers[0, 1] + 1
    # Axes that are not orthonormal are made so; degenerate ones are errors.
    skew = fo.HLPSet([[0, 0, 0]], [[1, 1, 1]], [[[2, 0, 0], [0.1, 1, 0], [0, 0, 3]]], [1])
    np.testing.assert_allclose(skew.axes[0] @ skew.axes[0].T, np.eye(3), atol=1e-12)
    bad_cases = [
        ("radii", {"radii": [[1, 0, 1]]}),
        ("NaN", {"centers": [[np.nan, 0, 0]]}),
        ("independent", {"axes": [[[1, 0, 0], [1, 0, 0], [0, 0, 1]]]}),
    ]
    base = {"centers": [[0, 0, 0]], "radii": [[1, 1, 1]], "axes": [np.eye(3)], "weights": [1.0]}
    for what, change in bad_cases:
        with pytest.raises(ParameterError, match=what):
            fo.HLPSet(**{**base, **change})
    for text, what in (
        ("{", "not JSON"),
        ('{"format": "x"}', "not an HLP file"),
        ('{"format": "mi-npr/hlps", "hlps": [{"center": [0, 0]}]}', "malformed"),
        ('{"format": "mi-npr/hlps", "hlps": [{"center": [0,0,0], "radii": [1,1,-1], '
         '"axes": [[1,0,0],[0,1,0],[0,0,1]]}]}', "radii"),
    ):  # fmt: skip
        (tmp_path / "bad.json").write_text(text)
        with pytest.raises(InputError, match=what):
            fo.HLPSet.load(tmp_path / "bad.json")
    with pytest.raises(InputError, match="no such file"):
        fo.HLPSet.load(tmp_path / "none.json")


def test05_kmeans_and_cluster_count():
    blobs = np.concatenate([RNG.normal(c, 0.1, (50, 3)) for c in ([0, 0, 0], [3, 0, 0], [0, 3, 0])])
    C, lab = kmeans(blobs, 3, seed=1)
    assert sorted(np.bincount(lab).tolist()) == [50, 50, 50]
    np.testing.assert_allclose(
        C[np.argsort(C[:, 0] + 2 * C[:, 1])], [[0, 0, 0], [3, 0, 0], [0, 3, 0]], atol=0.05
    )
    # Every point is assigned to its nearest centre (Lloyd's fixed point).
    d = np.linalg.norm(blobs[:, None] - C[None], axis=2)
    assert np.array_equal(lab, np.argmin(d, axis=1))
    C2, lab2 = kmeans(blobs, 3, seed=1)
    assert np.array_equal(C, C2) and np.array_equal(lab, lab2)
    # Coincident points: empty clusters are dropped.
    C3, lab3 = kmeans(np.zeros((10, 3)), 4)
    assert len(C3) == 1 and np.all(lab3 == 0)
    # Cells of side 2r holding points, brute force.
    r = 0.4
    ref = {tuple(np.floor((p - blobs.min(0)) / (2 * r)).astype(int)) for p in blobs}
    assert clusters_for_radius(blobs, r) == len(ref)
    with pytest.raises(ParameterError, match="radius"):
        clusters_for_radius(blobs, 0.0)


def test06_build_hlps():
    plant = fo.procedural_tree(seed=2, n_leaves=400)
    h = fo.build_hlps(plant, k=6, seed=0)
    assert len(h) == 6
    # The common radius scale puts 90 % of the leaf centres inside the surface.
    assert np.mean(h.field(plant.centers) >= h.iso) == pytest.approx(0.9, abs=0.01)
    h2 = fo.build_hlps(plant, k=6, seed=0)
    np.testing.assert_array_equal(h.centers, h2.centers)
    assert len(fo.build_hlps(plant)) == clusters_for_radius(
        plant.centers, fo.hlp.default_radius(plant)
    )
    assert len(fo.build_hlps(plant, radius=10.0)) == 1
    empty = fo.Plant.from_mesh(np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(fo.build_hlps(empty)) == 0
    one = fo.Plant.from_points([[1, 2, 3]], [[0, 1, 0]], sizes=0.2)
    h1 = fo.build_hlps(one, k=5)
    assert len(h1) == 1 and np.all(h1.radii > 0) and h1.field([[1, 2, 3]])[0] >= h1.iso
    for bad in ({"k": 0}, {"k": 2.5}, {"inside": 0.0}):
        with pytest.raises(ParameterError):
            fo.build_hlps(plant, **bad)


def test07_surface_area_and_samples_of_known_shapes():
    """A lone sphere (area 4 pi r^2, Archimedes: z uniform on the surface), an ellipsoid, and two
    far-apart spheres (areas add)."""
    r = 0.7
    sphere = fo.HLPSet([[0, 0, 0]], [[r, r, r]], [np.eye(3)], [1.0])
    assert sphere.surface_area() == pytest.approx(4 * np.pi * r**2, rel=0.03)
    P = sphere.sample_surface(3000, np.random.default_rng(1))
    assert P.shape == (3000, 3)
    np.testing.assert_allclose(np.linalg.norm(P, axis=1), r, rtol=1e-6)
    assert stats.kstest(P[:, 2], stats.uniform(-r, 2 * r).cdf).pvalue > 0.01
    Q = sphere.sample_volume(3000, np.random.default_rng(0))
    assert np.all(np.linalg.norm(Q, axis=1) <= r + 1e-9)
    assert stats.kstest((np.linalg.norm(Q, axis=1) / r) ** 3, "uniform").pvalue > 0.01
    a, b, c = 1.0, 0.5, 0.3
    ell = fo.HLPSet([[0, 0, 0]], [[a, b, c]], [np.eye(3)], [1.0])
    p = 1.6075
    thomsen = 4 * np.pi * (((a * b) ** p + (a * c) ** p + (b * c) ** p) / 3) ** (1 / p)
    assert ell.surface_area() == pytest.approx(thomsen, rel=0.03)
    two = fo.HLPSet([[0, 0, 0], [50, 0, 0]], [[r, r, r]] * 2, [np.eye(3)] * 2, [1.0, 1.0])
    assert two.surface_area() == pytest.approx(8 * np.pi * r**2, rel=0.03)
    S = two.sample_surface(2000, np.random.default_rng(1))
    assert abs(np.mean(S[:, 0] > 25) - 0.5) < 0.05
    np.testing.assert_allclose(two.field(S), two.iso, rtol=1e-6)


def test08_one_leaf_per_cluster_keeps_leaf_sized_blobs():
    # Each leaf alone in its cluster is inside its blob at any scale: the radius fit must not
    # shrink such blobs towards nothing (they would hold no leaf primitive).
    for plant, k in (
        (fo.procedural_tree(seed=0, n_leaves=2), None),
        (fo.procedural_tree(seed=0, n_leaves=12), 12),
    ):
        h = fo.build_hlps(plant, k=k)
        assert h.radii.min() >= np.mean(plant.sizes) * (1 - 1e-12)
        assert h.surface_area() > 0
        assert len(fo.make_leaves(h, leaf_size=0.05, seed=0)) > 0


def test09_surface_area_travels_with_the_json(tmp_path):
    r = 0.7
    sphere = fo.HLPSet([[0, 0, 0]], [[r, r, r]], [np.eye(3)], [1.0])
    path = sphere.save(tmp_path / "s.json")
    d = json.loads(path.read_text())
    assert d["surface_area"] == {"value": sphere.surface_area(), "geometry": sphere.digest()}
    fo.hlp._AREAS.clear()
    d["surface_area"]["value"] = 123.0  # trusted for the blobs it was saved with
    path.write_text(json.dumps(d))
    assert fo.HLPSet.load(path).surface_area() == 123.0
    fo.hlp._AREAS.clear()
    d["hlps"][0]["radii"] = [1.0, 1.0, 1.0]  # edited by hand: the stored value no longer counts
    path.write_text(json.dumps(d))
    assert fo.HLPSet.load(path).surface_area() == pytest.approx(4 * np.pi, rel=0.03)
    fo.hlp._AREAS.clear()
    d["surface_area"]["value"] = -1.0
    path.write_text(json.dumps(d))
    with pytest.raises(InputError, match=r"surface_area = .*-1\.0"):
        fo.HLPSet.load(path)
    fo.hlp._AREAS.clear()
