"""Ray-cast contours on Dr.Jit: batched mesh components (cached), the guard's boxes, and ids and
contours equal to buffer mode's on the paper's scenes in every id_mode."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.contours import trace, trace_scene
from mi_npr.contours.idmode import id_map
from mi_npr.contours.parts import clear_cache, components, mesh_parts, weld_keys
from mi_npr.contours.refine import (
    MACRO,
    BufferCaster,
    RayCaster,
    pixel_rects,
    rect_pixels,
    run,
)
from mi_npr.meshes import box, face_components, merge, uv_sphere, write_ply

from .helpers import SCENES


# ----------------------------------------------------------------------------- components
def _random_mesh(rng, parts):
    """Boxes and spheres merged into one mesh, some vertices duplicated (seams), shuffled."""
    meshes = []
    for _ in range(parts):
        c = rng.uniform(-3, 3, 3)
        if rng.random() < 0.5:
            meshes.append(box(float(rng.uniform(0.1, 1)), c))
        else:
            V, F = uv_sphere(8, 6, float(rng.uniform(0.1, 1)))
            meshes.append((V + c.astype(np.float32), F))
    V, F = merge(*meshes)
    F = np.asarray(F, np.int64)
    dup = rng.random(len(F) * 3) < 0.2  # split corners onto duplicate vertices
    extra = F.reshape(-1)[dup]
    F.reshape(-1)[dup] = len(V) + np.arange(len(extra))
    V = np.concatenate([V, V[extra]])
    perm = rng.permutation(len(F))
    return F[perm], V


def _reference_boxes(F, V, labels):
    lo = np.full((labels.max() + 1, 3), np.inf)
    hi = np.full((labels.max() + 1, 3), -np.inf)
    for j in range(3):
        np.minimum.at(lo, labels, V[F[:, j]])
        np.maximum.at(hi, labels, V[F[:, j]])
    return np.stack([lo, hi], axis=1)


def test01_components_of_many_meshes_equal_one_by_one():
    rng = np.random.default_rng(3)
    meshes = [_random_mesh(rng, int(rng.integers(1, 5))) for _ in range(7)]
    meshes.append(meshes[0])  # the same positions again: welded within a mesh only
    meshes.append((np.zeros((0, 3), np.int64), np.zeros((0, 3), np.float32)))
    got = components(meshes)
    for (F, V), parts in zip(meshes, got, strict=True):
        if len(F) == 0:
            assert parts.count == 0 and parts.labels.shape == (0,)
            continue
        ref = face_components(F, V)
        np.testing.assert_array_equal(parts.labels, ref)
        np.testing.assert_array_equal(parts.boxes, _reference_boxes(F, V, ref))
    assert components([]) == []


def test02_weld_compares_values():
    V = np.array([[0, 0, 0], [-0.0, 0, 0], [np.nan, 0, 0], [np.nan, 0, 0], [1, 2, 3], [1, 2, 3]])
    np.testing.assert_array_equal(weld_keys(V, np.zeros(6, np.int64)), [0, 0, 2, 3, 1, 1])
    # the same position in two groups stays two vertices
    w = weld_keys(np.zeros((2, 3)), np.array([0, 1]))
    assert w[0] != w[1]
    assert weld_keys(np.zeros((0, 3)), np.zeros(0)).shape == (0,)


def _mesh_scene(tmp_path, meshes):
    d = {
        "type": "scene",
        "sensor": {
            "type": "perspective",
            "fov": 45,
            "to_world": mi_npr.mi.ScalarTransform4f().look_at(
                origin=[0, 0, -9], target=[0, 0, 0], up=[0, 1, 0]
            ),
            "film": {"type": "hdrfilm", "width": 64, "height": 48},
        },
    }
    for i, (F, V) in enumerate(meshes):
        path = write_ply(tmp_path / f"m{i}.ply", V, F)
        d[f"m{i}"] = {"type": "ply", "filename": str(path)}
    return mi_npr.mi.load_dict(d, optimize=False)


def test03_parts_are_cached_per_mesh_and_checked(tmp_path):
    rng = np.random.default_rng(5)
    scene = _mesh_scene(tmp_path, [_random_mesh(rng, 3), _random_mesh(rng, 2)])
    clear_cache()
    shapes = list(scene.shapes())
    first = mesh_parts(shapes)
    again = mesh_parts(shapes)
    assert all(a is b for a, b in zip(first, again, strict=True))  # from the cache
    # An edited mesh (moved vertices: another bounding box) is recomputed.
    params = mi_npr.mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("vertex_positions"))
    params[key] = params[key] * 2.0
    params.update()
    moved = mesh_parts(shapes)
    changed = [a is not b for a, b in zip(first, moved, strict=True)]
    assert sum(changed) == 1
    i = changed.index(True)
    np.testing.assert_allclose(moved[i].boxes, first[i].boxes * 2.0, rtol=1e-6)


def _brute_guard_pixels(caster):
    """Every shape's and every component's box projected (no skipping), as pixel indices."""
    boxes = caster.id_map.boxes
    uv, front = caster._project(boxes)
    g = caster.grid
    lo, hi, small, _ = pixel_rects(uv[front], g.width, g.height, MACRO)
    return set(g.index(*rect_pixels(lo[small], hi[small])).tolist())


def test04_guard_skips_only_covered_components(tmp_path):
    """The guard projects a mesh's component boxes only where the mesh's own box is not
    already guarded or off the image; the pixels it casts are those of all the boxes."""
    rng = np.random.default_rng(11)
    far = [_random_mesh(rng, 3) for _ in range(2)]  # small on screen: covered by their box
    near = []
    for _ in range(3):
        F, V = _random_mesh(rng, 4)
        near.append((F, V * np.float32(0.6) + np.float32([0, 0, -5])))  # large on screen
    tiny = [(F, V * np.float32(0.05)) for F, V in far]
    scene = _mesh_scene(tmp_path, far + near + tiny)
    session = mi_npr.session.SceneSession.open(scene)
    caster = RayCaster(scene, session.sensor, id_map(scene, "shape"))
    boxes = caster.guard_boxes(MACRO)
    g = caster.grid
    lo, hi, small, _ = pixel_rects(boxes, g.width, g.height, MACRO)
    got = set(g.index(*rect_pixels(lo[small], hi[small])).tolist())
    assert got == _brute_guard_pixels(caster)
    assert len(boxes) < len(caster.id_map.boxes)  # something was skipped


def test05_rect_pixels():
    x, y = rect_pixels(np.array([[1, 2], [0, 0]]), np.array([[2, 4], [0, 0]]))
    ref = [(xx, yy) for yy in range(2, 5) for xx in range(1, 3)] + [(0, 0)]
    assert sorted(zip(x.tolist(), y.tolist(), strict=True)) == sorted(ref)
    x, y = rect_pixels(np.zeros((0, 2)), np.zeros((0, 2)))
    assert len(x) == len(y) == 0


# ----------------------------------------------------------------------------- same as before
def _buffer(scene, id_mode):
    gb = mi_npr.render(scene)
    ids, names = mi_npr.contours.mode_ids(gb, scene, id_mode)
    return np.asarray(ids, np.uint32), names


@pytest.mark.parametrize("id_mode", ["shape", "primitive", "component"])
@pytest.mark.parametrize("name", ["scene1", "scene2", "scene3", "scene4"])
def test06_ids_and_contours_equal_buffer_mode(name, id_mode):
    """At 160x120: every pixel trace_scene cast has the G-buffer's id, and its contours are
    buffer mode's, in both tracing methods."""
    scene = mi_npr.load_scene(SCENES / f"{name}.xml", width=160, height=120, spp=1)
    ids, names = _buffer(scene, id_mode)
    session = mi_npr.session.SceneSession.open(scene)
    caster = RayCaster(scene, session.sensor, id_map(scene, id_mode, session.objects))
    got, stats = run(caster, names)
    g = caster.grid
    cast = np.asarray(stats.cast)
    inner = np.asarray(g.ids).reshape(g.height + 2, g.stride)[1:-1, 1:-1]
    np.testing.assert_array_equal(inner[cast], ids[cast])
    ref = trace(ids, objects=names)
    assert got == ref
    for method in ("border", "code_direction"):
        again, _ = trace_scene(scene, id_mode=id_mode, method=method)
        assert again == trace(ids, objects=names, method=method)


# ----------------------------------------------------------------------------- the numpy reference
def _reference_cast(ids, boxes=None, macro=MACRO):
    """The numpy bookkeeping trace_scene had before it moved to Dr.Jit (steps 1-3 on an id
    buffer): the pixels it cast, the batches and the following rounds."""
    h, w = ids.shape
    s = w + 2
    pid = np.full((h + 2, s), 0xFFFFFFFF, np.uint32)
    pid[1:-1, 1:-1] = ids
    pid = pid.reshape(-1)
    known = np.ones((h + 2, s), bool)
    known[1:-1, 1:-1] = False
    known = known.reshape(-1)
    count = {"launches": 0, "rounds": 0}

    def index(x, y):
        return (np.asarray(y, np.int64) + 1) * s + np.asarray(x, np.int64) + 1

    def cast(idx):
        idx = np.unique(np.asarray(idx, np.int64).reshape(-1))
        idx = idx[~known[idx]]
        known[idx] = True
        count["launches"] += len(idx) > 0
        return idx

    def points(n):
        return np.unique(np.r_[np.arange(0, n, macro), n - 1])

    def halves(a0, a1, split, *rest):
        out = [[] for _ in range(2 + len(rest))]
        for i in range(len(a0)):
            mid = (a0[i] + a1[i]) // 2
            for lo, hi in ((a0[i], mid), (mid, a1[i])) if split[i] else ((a0[i], a1[i]),):
                for k, v in enumerate((lo, hi, *(r[i] for r in rest))):
                    out[k].append(v)
        return [np.asarray(o, np.int64) for o in out]

    xs, ys = points(w), points(h)
    gx, gy = np.meshgrid(xs, ys)
    done = [cast(index(gx, gy))]
    x0, x1 = (xs[:-1], xs[1:]) if len(xs) > 1 else (xs, xs)
    y0, y1 = (ys[:-1], ys[1:]) if len(ys) > 1 else (ys, ys)
    bx0, by0 = (a.ravel() for a in np.meshgrid(x0, y0))
    bx1, by1 = (a.ravel() for a in np.meshgrid(x1, y1))
    while len(bx0):
        c = [pid[index(x, y)] for x, y in ((bx0, by0), (bx1, by0), (bx0, by1), (bx1, by1))]
        differ = (c[0] != c[1]) | (c[0] != c[2]) | (c[0] != c[3])
        sx, sy = (bx1 - bx0) > 1, (by1 - by0) > 1
        keep = differ & (sx | sy)
        bx0, bx1, by0, by1, sx, sy = (a[keep] for a in (bx0, bx1, by0, by1, sx, sy))
        bx0, bx1, by0, by1, sy = halves(bx0, bx1, sx, by0, by1, sy)
        by0, by1, bx0, bx1 = halves(by0, by1, sy.astype(bool), bx0, bx1)
        if len(bx0) == 0:
            break
        done.append(cast(index(np.r_[bx0, bx1, bx0, bx1], np.r_[by0, by0, by1, by1])))
    if boxes is not None and len(boxes):
        lo, hi, small, _ = pixel_rects(boxes, w, h, macro)
        box = [np.zeros(0, np.int64)]  # one batch for all boxes
        for (a, b), (c_, d) in zip(lo[small].astype(int), hi[small].astype(int), strict=True):
            yy, xx = np.mgrid[b : d + 1, a : c_ + 1]
            box.append(index(xx, yy).ravel())
        done.append(cast(np.concatenate(box)))
    new = np.concatenate(done)
    off = np.array([1, s, -1, -s])
    while len(new):
        need = []
        for p in new:
            for d in range(4):
                q = p + off[d]
                if not known[q] or pid[q] == pid[p]:
                    continue
                cracks = [(p, d)] if pid[p] != 0 else []
                if pid[q] not in (0, 0xFFFFFFFF):
                    cracks.append((q, (d + 2) & 3))
                for cp, cs in cracks:
                    t = off[(cs + 1) & 3]
                    need += [cp + t, cp + t + off[cs], cp - t, cp - t + off[cs]]
        new = cast(need)
        count["rounds"] += 1
    return known.reshape(h + 2, s)[1:-1, 1:-1], count


@pytest.mark.parametrize("seed", range(5))
def test07_same_pixels_as_the_numpy_bookkeeping(seed):
    """Without a scene (an id buffer): the same pixels cast, batches and rounds as before."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(1, 60, 2))
    yy, xx = np.mgrid[0:h, 0:w]
    ids = np.zeros((h, w), np.uint32)
    for k in range(1, 6):
        cy, cx, r = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(0.5, 15)
        ids[(yy - cy) ** 2 + (xx - cx) ** 2 < r * r] = k
    caster = BufferCaster(ids)
    got, stats = run(caster, None, guard=False)
    cast, count = _reference_cast(ids)
    np.testing.assert_array_equal(stats.cast, cast)
    assert stats.rays_cast == cast.sum()
    assert (stats.launches, stats.rounds) == (count["launches"], count["rounds"])
    assert got == [c for c in trace(ids) if cast[c.points[0][1], c.points[0][0]]]


@pytest.mark.parametrize("name", ["scene1", "scene3"])
def test08_scene_same_pixels_as_the_numpy_bookkeeping(name):
    scene = mi_npr.load_scene(SCENES / f"{name}.xml", width=120, height=90, spp=1)
    ids, names = _buffer(scene, "shape")
    session = mi_npr.session.SceneSession.open(scene)
    caster = RayCaster(scene, session.sensor, id_map(scene, "shape", session.objects))
    boxes = caster.guard_boxes(MACRO)
    _, stats = run(caster, names)
    cast, count = _reference_cast(ids, boxes)
    np.testing.assert_array_equal(stats.cast, cast)
    assert (stats.launches, stats.rounds) == (count["launches"], count["rounds"])
