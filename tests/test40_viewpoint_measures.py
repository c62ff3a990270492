"""Eqs. 1-3 as pure functions of per-polygon areas, and the angle defects of eq. 2 / Fig. 3."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr.meshes import box, merge, uv_sphere
from mi_npr.viewpoint import curvature, entropy, pb, vertex_curvature
from mi_npr.viewpoint.measures import Topology


def pb_loop(areas):
    """Eq. 1 written out: ceil(P/(P+1)) summed over polygons / n + sum P / r."""
    n = len(areas) - 1
    r = sum(areas)
    first = sum(math.ceil(p / (p + 1)) for p in areas[1:]) / n if n else 0.0
    return first + (sum(areas[1:]) / r if r else 0.0)


def entropy_loop(areas):
    """Eq. 3 written out, from i = 0 (background) to N_f, base-2 logarithm."""
    at = sum(areas)
    return -sum((a / at) * math.log2(a / at) for a in areas if a > 0) if at else 0.0


def curvature_loop(areas, faces, defect):
    """Eq. 2 written out: faces (n + 1 lists of vertex ids), defect per vertex."""
    visible = set()
    for i, a in enumerate(areas):
        if i and a > 0:
            visible.update(faces[i])
    r = sum(areas)
    return sum(abs(defect[v]) for v in visible) * (sum(areas[1:]) / r if r else 0.0)


def angle_sums_loop(V, F):
    """Angle sum at every welded position, one corner at a time (an oracle for the weld too)."""
    sums: dict[tuple, float] = {}
    for tri in F:
        for c in range(3):
            p, q, s = (np.asarray(V[tri[(c + k) % 3]], float) for k in range(3))
            a, b = q - p, s - p
            ang = math.acos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))
            key = tuple(np.float32(V[tri[c]]))
            sums[key] = sums.get(key, 0.0) + ang
    return sums


def test01_hand_values():
    a = np.array([60.0, 20.0, 20.0, 0.0])  # background, 3 polygons, one hidden
    assert pb(a) == pytest.approx(2 / 3 + 40 / 100)
    h = -(0.6 * math.log2(0.6) + 2 * 0.2 * math.log2(0.2))
    assert entropy(a) == pytest.approx(h)
    # Four equal faces and no background: log2(4) = 2 bits, the maximum for 4 faces.
    assert entropy(np.array([0.0, 1, 1, 1, 1])) == pytest.approx(2.0)


@pytest.mark.parametrize("seed", range(5))
def test02_batched_measures_equal_the_loops(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    areas = rng.integers(0, 50, size=(7, n + 1)).astype(float)
    areas[rng.random(areas.shape) < 0.4] = 0
    areas[0] = 0  # a viewpoint that has no area at all
    faces = [[-1, -1, -1]] + [list(rng.integers(-1, 12, size=3)) for _ in range(n)]
    defect = rng.normal(size=12)
    topo = Topology(np.asarray(faces, np.int64), np.abs(defect))
    got_pb, got_h, got_c = pb(areas), entropy(areas), curvature(areas, topo)
    for k, row in enumerate(areas):
        assert got_pb[k] == pytest.approx(pb_loop(list(row)))
        assert got_h[k] == pytest.approx(entropy_loop(list(row)))
        fl = [[v for v in f if v >= 0] for f in faces]
        assert got_c[k] == pytest.approx(curvature_loop(list(row), fl, defect))
    # Any leading shape is a batch.
    assert pb(areas.reshape(7, 1, n + 1)).shape == (7, 1)


def test03_nothing_seen_is_zero():
    for a in (np.array([100.0, 0, 0]), np.zeros(3), np.array([5.0])):
        assert pb(a) == 0 and entropy(a) == 0
        topo = Topology(np.full((len(a), 3), -1), np.zeros(0))
        assert curvature(a, topo) == 0
    # Only background (1x1 image) and a fully covered single polygon.
    assert entropy(np.array([1.0])) == 0
    assert pb(np.array([0.0, 1.0])) == pytest.approx(2.0)


def test04_bad_areas_are_errors():
    for bad in (np.array([np.nan, 1.0]), np.array([-1.0, 2.0]), np.array([np.inf, 0.0])):
        with pytest.raises(mi_npr.ParameterError):
            pb(bad)
    with pytest.raises(mi_npr.ParameterError):
        entropy(np.zeros(0))
    with pytest.raises(mi_npr.ParameterError, match="polygons"):
        curvature(np.ones(4), Topology(np.full((3, 3), -1), np.zeros(0)))


def _torus(n1=24, n2=12, R=1.0, r=0.35):
    u = 2 * np.pi * np.arange(n1) / n1
    v = 2 * np.pi * np.arange(n2) / n2
    uu, vv = np.meshgrid(u, v, indexing="ij")
    V = np.stack(
        [(R + r * np.cos(vv)) * np.cos(uu), r * np.sin(vv), (R + r * np.cos(vv)) * np.sin(uu)], -1
    ).reshape(-1, 3)
    F = []
    for i in range(n1):
        for j in range(n2):
            a, b = i * n2 + j, ((i + 1) % n1) * n2 + j
            c, d = ((i + 1) % n1) * n2 + (j + 1) % n2, i * n2 + (j + 1) % n2
            F += [(a, b, c), (a, c, d)]
    return V, np.asarray(F)


def test05_gauss_bonnet():
    # Closed convex meshes: the defects sum to 4 pi over all vertices.
    for V, F in (uv_sphere(36, 30), uv_sphere(5, 3), box((1.0, 2.0, 0.5))):
        defect, _ = vertex_curvature(V, F)
        assert defect.sum() == pytest.approx(4 * math.pi, abs=1e-9)
        assert np.all(defect > -1e-12)  # convex: no negative curvature
    # A torus: chi = 0. Two separate closed meshes in one: 8 pi.
    assert vertex_curvature(*_torus())[0].sum() == pytest.approx(0.0, abs=1e-9)
    both = merge(uv_sphere(8, 6), box(0.3, center=(3, 0, 0)))
    assert vertex_curvature(*both)[0].sum() == pytest.approx(8 * math.pi)
    # An open mesh (a disc-like patch: the upper half of a uv sphere): chi = 1, 2 pi.
    V, F = uv_sphere(12, 8)
    top = F[np.all(V[F][:, :, 1] > -1e-6, axis=1)]
    assert vertex_curvature(V, top)[0].sum() == pytest.approx(2 * math.pi, abs=1e-9)


def test06_mitsuba_cube_is_welded():
    """Mitsuba's cube has 24 vertices (4 per face): welded, 8 corners of pi / 2 each."""
    mi = mi_npr.mi
    cube = mi.load_dict({"type": "cube"})
    V = cube.vertex_positions_buffer().numpy().reshape(-1, 3)
    F = cube.faces_buffer().numpy().reshape(-1, 3)
    assert len(V) == 24
    defect, weld = vertex_curvature(V, F)
    assert len(defect) == 8 and weld.shape == (24,)
    np.testing.assert_allclose(defect, math.pi / 2, atol=1e-9)
    # The same per welded position as a corner-by-corner loop.
    sums = angle_sums_loop(V, F)
    for i, v in enumerate(V):
        assert defect[weld[i]] == pytest.approx(2 * math.pi - sums[tuple(np.float32(v))])


def test07_flat_and_degenerate():
    # A flat square of 2 triangles: corners pi/2 each (boundary rule), no interior vertex.
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(vertex_curvature(V, F)[0], math.pi / 2)
    # A flat interior vertex has no curvature; an unused vertex gets 0; no NaN from a
    # collapsed triangle.
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [5, 5, 5]], float)
    F = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [1, 1, 2]])
    d, weld = vertex_curvature(V, F)
    assert np.all(np.isfinite(d))
    assert d[weld[0]] == pytest.approx(0.0, abs=1e-12)
    assert d[weld[5]] == 0.0
    assert d[weld[3]] == pytest.approx(math.pi / 2)  # a corner of the square's border
    assert vertex_curvature(np.zeros((0, 3)), np.zeros((0, 3), int))[0].shape == (0,)
    with pytest.raises(mi_npr.ParameterError):
        vertex_curvature(V, np.array([[0, 1, 9]]))
