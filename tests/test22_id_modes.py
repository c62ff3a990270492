"""id_mode: shape, primitive and component ids, on numpy layers and on cast rays."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.contours import id_map, mode_ids, trace
from mi_npr.meshes import box, face_components, merge, uv_sphere, weld, write_ply
from mi_npr.raycast import pixel_rays

from .helpers import SCENES


def union_find_components(F: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Oracle (plain Python, independent of scipy): faces joined through shared positions by a
    union-find over the faces, numbered by lowest face."""
    parent = list(range(len(F)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner: dict[tuple, int] = {}  # position -> first face that uses it
    for f, tri in enumerate(F):
        for v in tri:
            key = tuple(V[v].tolist())
            if key in owner:
                parent[root(f)] = root(owner[key])
            else:
                owner[key] = f
    order: dict[int, int] = {}
    return np.array([order.setdefault(root(f), len(order)) for f in range(len(F))])


@pytest.mark.parametrize("seed", range(5))
def test01_components_match_union_find(seed):
    rng = np.random.default_rng(seed)
    parts = [uv_sphere(int(rng.integers(3, 9)), int(rng.integers(2, 6))) for _ in range(3)]
    parts += [box(0.2, center=rng.uniform(-1, 1, 3)) for _ in range(int(rng.integers(0, 3)))]
    V, F = merge(*parts)
    F = F[rng.permutation(len(F))]
    np.testing.assert_array_equal(face_components(F, V), union_find_components(F, V))
    # Duplicated seam vertices (same position, new index) do not split a component.
    dup = np.concatenate([V, V])
    F2 = F.copy()
    flip = rng.random(F.shape) < 0.5
    F2[flip] += len(V)
    np.testing.assert_array_equal(face_components(F2, dup), face_components(F, V))
    assert face_components(F2).max() > face_components(F, V).max()  # unwelded: split


def test02_weld():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0.5]], np.float32)
    w = weld(V)
    assert w[0] == w[2] and len(set(w.tolist())) == 3
    assert face_components(np.zeros((0, 3))).shape == (0,)


def _fig9(**kw):
    return mi_npr.load_scene(SCENES / "fig9_sphere_cube.xml", **kw)


def test03_fig9_tables():
    scene = _fig9(width=16, height=12, spp=1)
    shape = id_map(scene, "shape")
    assert shape.names == {1: "floor", 2: "sphere_mesh"}
    comp = id_map(scene, "component")
    assert comp.names == {1: "floor", 2: "sphere_mesh#0", 3: "sphere_mesh#1"}
    prim = id_map(scene, "primitive")
    assert len(prim.names) == 2 + 2100
    assert prim.names[1] == "floor/0" and prim.names[3] == "sphere_mesh/0"
    assert prim.names[2102] == "sphere_mesh/2099"
    assert len(comp.boxes) == 2 + 2  # two shapes, two components
    cube = comp.boxes[-1]
    np.testing.assert_allclose(cube, [[-0.2, 0.8, -0.2], [0.2, 1.2, 0.2]], atol=1e-6)
    with pytest.raises(mi_npr.ParameterError, match="id_mode"):
        id_map(scene, "triangle")


@pytest.mark.parametrize("mode", ["shape", "primitive", "component"])
def test04_layers_and_rays_agree(mode):
    """apply() on the G-buffer layers equals lookup() on the same pixel-centre rays."""
    scene = _fig9(width=48, height=36, spp=1)
    gb = mi_npr.render(scene)
    ids = id_map(scene, mode)
    mi, dr = mi_npr.mi, mi_npr.dr
    h, w = gb.shape
    idx = np.arange(w * h)
    ray = pixel_rays(scene.sensors()[0], mi.Float(idx % w + 0.5), mi.Float(idx // w + 0.5))
    got = ids.lookup(scene.ray_intersect_preliminary(ray, coherent=True)).numpy().reshape(h, w)
    np.testing.assert_array_equal(got, ids.apply(gb.numpy("object_id.V"), gb.numpy("prim_id.V")))
    assert set(np.unique(got)) <= {0, *ids.names}
    if mode == "primitive":
        sphere = gb.numpy("object_id.V") == gb.find_object("sphere_mesh")
        np.testing.assert_array_equal(got[sphere], gb.numpy("prim_id.V")[sphere] + 3)
    dr.eval()


def test05_component_separates_the_cube(tmp_path, write_scene):
    """From inside the sphere the cube is hit directly: one object by shape, two by component."""
    V, F = merge(uv_sphere(24, 16, 2.0), box(0.6, center=(0, 0, 0)))
    write_ply(tmp_path / "m.ply", V, F)
    path = write_scene(
        f'<shape type="ply" id="mesh"><string name="filename" value="{tmp_path / "m.ply"}"/>'
        "</shape>",
        width=40,
        height=30,
        origin="0, 0, -1.5",
        target="0, 0, 0",
        fov=60,
    )
    scene = mi_npr.load_scene(path)
    gb = mi_npr.render(scene)
    ids, names = mode_ids(gb, scene, "shape")
    by_shape = trace(ids, objects=names)
    ids, names = mode_ids(gb, scene, "component")
    by_comp = trace(ids, objects=names)
    assert {c.name for c in by_shape} == {"mesh"}
    assert not any(c.is_hole for c in by_shape)  # the cube is part of the same object
    names = {c.name for c in by_comp}
    assert names == {"mesh#0", "mesh#1"}
    assert any(c.is_hole and c.name == "mesh#0" for c in by_comp)  # the sphere around the cube
    cube = [c for c in by_comp if c.name == "mesh#1"]
    assert len(cube) == 1 and not cube[0].is_hole


def test06_mode_ids_without_scene():
    gb = mi_npr.GBuffer(
        {"object_id.V": np.array([[0, 1]], np.uint32), "prim_id.V": np.zeros((1, 2), np.uint32)},
        objects={1: "a"},
    )
    ids, names = mode_ids(gb)
    assert names == {1: "a"} and ids.tolist() == [[0, 1]]
    with pytest.raises(mi_npr.ParameterError, match="needs the scene"):
        mode_ids(gb, None, "component")
