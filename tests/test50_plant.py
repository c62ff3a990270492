"""mi_npr.foliage.plant: leaves from meshes (components or triangles), point sets, PLY/OBJ files,
and what happens with empty, single-leaf and broken input."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import foliage as fo
from mi_npr.errors import InputError, ParameterError
from mi_npr.meshes import face_components, write_ply

RNG = np.random.default_rng(50)


def random_leaves(n: int, rng=RNG) -> tuple[np.ndarray, np.ndarray]:
    """``n`` separate leaves, each a random planar quad (2 triangles) or triangle."""
    Vs, Fs, off = [], [], 0
    for _ in range(n):
        c = rng.normal(size=3)
        u, v = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2].T
        if rng.random() < 0.5:
            pts = [c, c + 0.3 * u, c + 0.3 * u + 0.1 * v, c + 0.1 * v]
            f = [(0, 1, 2), (0, 2, 3)]
        else:
            pts = [c, c + 0.2 * u, c + 0.05 * v]
            f = [(0, 1, 2)]
        Vs += pts
        Fs += [tuple(off + i for i in t) for t in f]
        off += len(pts)
    return np.asarray(Vs), np.asarray(Fs)


def reference_components(F: np.ndarray, nv: int) -> np.ndarray:
    """Connected components of the vertex graph, per face: breadth-first search in plain Python."""
    nbrs: list[set[int]] = [set() for _ in range(nv)]
    for a, b, c in F.tolist():
        nbrs[a] |= {b, c}
        nbrs[b] |= {a, c}
        nbrs[c] |= {a, b}
    lab = [-1] * nv
    for s in range(nv):
        if lab[s] < 0:
            lab[s], todo = s, [s]
            while todo:
                for w in nbrs[todo.pop()]:
                    if lab[w] < 0:
                        lab[w] = s
                        todo.append(w)
    return np.array(lab)[F[:, 0]]


def same_partition(x: np.ndarray, y: np.ndarray) -> bool:
    pairs = set(zip(x.tolist(), y.tolist(), strict=True))
    return len(pairs) == len(set(x.tolist())) == len(set(y.tolist()))


def test01_components_match_a_graph_search():
    V, F = random_leaves(40)
    # Join some leaves by sharing vertices, as a twig would.
    F = np.concatenate([F, [[F[0, 0], F[5, 1], F[9, 2]]]])
    assert same_partition(face_components(F), reference_components(F, len(V)))
    # A long chain (a worst case for label propagation).
    n = 300
    chain = np.array([(i, i + 1, i + 2) for i in range(n)])
    assert len(set(face_components(chain).tolist())) == 1
    assert face_components(np.zeros((0, 3), np.int64)).shape == (0,)


def test02_leaf_records_brute_force():
    V, F = random_leaves(12)
    plant = fo.Plant.from_mesh(V, F)
    assert len(plant) == 12
    lab = reference_components(F, len(V))
    for leaf in np.unique(lab):
        faces = F[lab == leaf]
        p0, p1, p2 = (V[faces[:, j]] for j in range(3))
        cross = np.cross(p1 - p0, p2 - p0)
        area = 0.5 * np.linalg.norm(cross, axis=1).sum()
        centre = (0.5 * np.linalg.norm(cross, axis=1)[:, None] * (p0 + p1 + p2) / 3).sum(0) / area
        i = int(np.argmin(np.linalg.norm(plant.centers - centre, axis=1)))
        np.testing.assert_allclose(plant.centers[i], centre, atol=1e-9)
        np.testing.assert_allclose(plant.areas[i], area, rtol=1e-9)
        n = cross.sum(0) / np.linalg.norm(cross.sum(0))
        np.testing.assert_allclose(plant.normals[i], n, atol=1e-9)
        # The long axis lies in the plane; the size is the vertices' extent along it.
        assert abs(plant.axes[i] @ plant.normals[i]) < 1e-9
        verts = V[np.unique(faces)]
        extent = np.ptp((verts - centre) @ plant.axes[i])
        np.testing.assert_allclose(plant.sizes[i], extent, rtol=1e-9)
        assert plant.sizes[i] == pytest.approx(0.3 if len(faces) == 2 else 0.2, rel=0.05)


def test03_triangles_mode_and_degenerate_leaves():
    V, F = random_leaves(10)
    per_triangle = fo.Plant.from_mesh(V, F, leaves="triangles")
    assert len(per_triangle) == len(F)
    assert per_triangle.total_area == pytest.approx(fo.Plant.from_mesh(V, F).total_area)
    # A zero-area triangle has no normal: dropped.
    V2 = np.concatenate([V, [[0, 0, 0], [1, 0, 0], [2, 0, 0]]])
    F2 = np.concatenate([F, [[len(V), len(V) + 1, len(V) + 2]]])
    assert len(fo.Plant.from_mesh(V2, F2)) == 10
    with pytest.raises(ParameterError, match="leaves"):
        fo.Plant.from_mesh(V, F, leaves="petals")


def test04_empty_single_and_nan():
    empty = fo.Plant.from_mesh(np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(empty) == 0 and empty.total_area == 0.0
    one = fo.Plant.from_mesh(*random_leaves(1))
    assert len(one) == 1
    V, F = random_leaves(5)
    V[3, 1] = np.nan
    with pytest.raises(InputError, match=r"1 vertices have non-finite"):
        fo.Plant.from_mesh(V, F, name="bad.ply")
    with pytest.raises(InputError, match="non-finite"):
        fo.Plant.from_points([[0, 0, np.inf]], [[0, 0, 1]])
    with pytest.raises(InputError, match="zero normal"):
        fo.Plant.from_points([[0, 0, 0]], [[0, 0, 0]])
    with pytest.raises(InputError, match="does not exist"):
        fo.Plant.from_mesh(V[:2], F)


def test05_ply_round_trip_and_point_sets(tmp_path):
    plant = fo.procedural_tree(seed=5, n_leaves=50)
    back = fo.read_plant(plant.save(tmp_path / "p.ply"))
    for attr in ("centers", "normals", "axes", "sizes", "areas"):
        np.testing.assert_allclose(getattr(back, attr), getattr(plant, attr), atol=1e-6, rtol=1e-6)
    # A plain point set with normals (sizes estimated) and one without normals.
    P = RNG.normal(size=(20, 3))
    N = RNG.normal(size=(20, 3))
    normals = {"nx": N[:, 0], "ny": N[:, 1], "nz": N[:, 2]}
    write_ply(tmp_path / "pts.ply", P, np.zeros((0, 3)), normals)
    pts = fo.read_plant(tmp_path / "pts.ply")
    assert len(pts) == 20 and np.all(pts.sizes > 0)
    np.testing.assert_allclose(np.linalg.norm(pts.normals, axis=1), 1.0)
    write_ply(tmp_path / "bare.ply", P, np.zeros((0, 3)))
    with pytest.raises(InputError, match="needs normals"):
        fo.read_plant(tmp_path / "bare.ply")
    # A mesh file: leaves are components.
    V, F = random_leaves(7)
    write_ply(tmp_path / "mesh.ply", V, F)
    assert len(fo.read_plant(tmp_path / "mesh.ply")) == 7
    assert len(fo.read_plant(tmp_path / "mesh.ply", leaves="triangles")) == len(F)
    write_ply(tmp_path / "empty.ply", np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(fo.read_plant(tmp_path / "empty.ply")) == 0


def test06_obj_files(tmp_path):
    text = "\n".join(
        [
            "# two leaves: a quad (polygon face, v/vt/vn forms) and a triangle (negative indices)",
            "v 0 0 0",
            "v 1 0 0",
            "v 1 0.5 0",
            "v 0 0.5 0",
            "vt 0 0",
            "f 1/1 2/1 3/1 4/1",
            "v 3 0 0",
            "v 3 1 0",
            "v 3 0 1",
            "f -3 -2 -1",
        ]
    )
    (tmp_path / "leaves.obj").write_text(text)
    plant = fo.read_plant(tmp_path / "leaves.obj")
    assert len(plant) == 2
    assert sorted(plant.areas.round(6)) == [0.5, 0.5]
    (tmp_path / "pts.obj").write_text("v 0 0 0\nv 1 0 0\nvn 0 1 0\nvn 0 0 1\n")
    assert len(fo.read_plant(tmp_path / "pts.obj")) == 2
    for bad, why in (
        ("v 0 0 x\n", "could not convert"),
        ("v 0 0\n", "line 1: 'v' needs 3 coordinates"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "line 4: vertex 9 does not exist"),
    ):
        (tmp_path / "bad.obj").write_text(bad)
        with pytest.raises(InputError, match=rf"bad\.obj: malformed OBJ \(.*{why}"):
            fo.read_plant(tmp_path / "bad.obj")
    (tmp_path / "nan.obj").write_text("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match="non-finite"):
        fo.read_plant(tmp_path / "nan.obj")
    with pytest.raises(InputError, match="no such file"):
        fo.read_plant(tmp_path / "missing.obj")
    (tmp_path / "x.stl").write_text("solid")
    with pytest.raises(InputError, match="unknown plant format"):
        fo.read_plant(tmp_path / "x.stl")


def test07_procedural_is_deterministic():
    a = fo.procedural_tree(seed=3, n_leaves=200)
    b = fo.procedural_tree(seed=3, n_leaves=200)
    c = fo.procedural_tree(seed=4, n_leaves=200)
    for attr in ("centers", "normals", "axes", "sizes", "areas"):
        np.testing.assert_array_equal(getattr(a, attr), getattr(b, attr))
    np.testing.assert_array_equal(a.wood[0], b.wood[0])
    assert not np.array_equal(a.centers, c.centers)
    assert len(a) == 200 and len(fo.procedural_tree(n_leaves=0)) == 0
    np.testing.assert_allclose(np.linalg.norm(a.normals, axis=1), 1.0)
    np.testing.assert_allclose(np.sum(a.normals * a.axes, axis=1), 0.0, atol=1e-12)
    bush = fo.procedural_tree(seed=0, n_leaves=100, kind="bush")
    assert bush.bbox()[1][1] < a.bbox()[1][1]  # a bush is lower than a tree
    for bad in ({"kind": "fern"}, {"n_leaves": -1}, {"leaf_size": 0.0}):
        with pytest.raises(ParameterError):
            fo.procedural_tree(**bad)
    assert mi_npr.foliage is fo
