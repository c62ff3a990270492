"""The strokes' mesh topology: its edges grouped a range of half-edges at a time against one
pass over them all written here, its size per triangle, and a view's feature edges made a few
rows at a time against all at once."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mi_npr.scene import object_table
from mi_npr.strokes import KINDS
from mi_npr.strokes import edges as E

from .test75_strokes_closed_form import ORIGIN, load


def reference_edges(wid: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, ...]:
    """The welded edges of faces ``f`` from their definition, one half-edge at a time:
    half-edge ``h`` runs from corner ``h % 3`` of face ``h // 3`` to the next corner (none
    where both ends weld into one vertex); an edge is a pair of welded ends, its faces those
    of its half-edges in the order of ``h``; ``flip``: its first two half-edges run the same
    way."""
    groups: dict[tuple[int, int], list[tuple[int, bool]]] = {}
    for h in range(3 * len(f)):
        a, b = int(wid[f[h // 3, h % 3]]), int(wid[f[h // 3, (h % 3 + 1) % 3]])
        if a != b:
            groups.setdefault((min(a, b), max(a, b)), []).append((h // 3, a < b))
    keys = sorted(groups)
    first = [groups[k][0] for k in keys]
    second = [groups[k][1] if len(groups[k]) > 1 else groups[k][0] for k in keys]
    return (
        np.array(keys, np.int64).reshape(-1, 2),
        np.array([min(len(groups[k]), 3) for k in keys]),
        np.array([g[0] for g in first]),
        np.array([g[0] for g in second]),
        np.array([a[1] == b[1] for a, b in zip(first, second, strict=True)], bool),
    )


@pytest.mark.parametrize("half_edges", [5, 1 << 18])
def test01_edges_grouped_in_ranges_match_one_pass(monkeypatch, half_edges):
    """Random faces over vertices that weld in pairs and triples, some faces collapsed by the
    welding, edges of one to many faces: the same edges, counts, faces and flips whether the
    half-edges are sorted 5 at a time or all at once."""
    monkeypatch.setattr(E, "HALF_EDGES", half_edges)
    rng = np.random.default_rng(3)
    wid = rng.integers(0, 40, 70).astype(np.int32)
    wid = np.unique(wid, return_inverse=True)[1].astype(np.int32)  # ids 0..K-1
    f = rng.integers(0, 70, (300, 3)).astype(np.int32)
    got = E._group_edges(wid, f, int(wid.max()) + 1)
    want = reference_edges(wid, f)
    assert (want[1] == 1).any() and (want[1] == 3).any() and len(want[0]) > 50
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)


OBJ_GRID = 60  # a 60 x 60 grid of quads: 7200 triangles


def grid_obj(path) -> None:
    """A wavy sheet of OBJ_GRID^2 quads (two triangles each) across the view."""
    n = OBJ_GRID + 1
    x, y = np.meshgrid(np.linspace(-2, 2, n), np.linspace(-1.5, 1.5, n))
    z = 5.0 + 0.2 * np.sin(3 * x) * np.cos(2 * y)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.concatenate([np.stack([i, i + 1, i + n + 1], 1), np.stack([i, i + n + 1, i + n], 1)])
    lines = [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


SHEET_AND_BOX = (
    '<shape type="obj" id="sheet"><string name="filename" value="{}"/></shape>'
    '<shape type="cube" id="box"><transform name="to_world">'
    '<scale value="0.4"/><translate x="0.3" y="-0.2" z="5"/></transform></shape>'
)


def test02_topology_keeps_about_65_bytes_per_triangle(tmp_path):
    """What the topology keeps between views: per face its plane (28 bytes: the normal in
    single precision, the offset in double) and object (4), per edge (~1.5 a face) its ends,
    two faces, count and orientation (18), the welded vertices in single precision (~6 a
    face) and the intersection lines. Under 80 bytes a triangle (a copy of the triangle soup
    in double precision alone would add ~48)."""
    grid_obj(tmp_path / "sheet.obj")
    scene = load(tmp_path, SHEET_AND_BOX.format(tmp_path / "sheet.obj"))
    E._LAST[0] = None
    topo = E.topology(object_table(scene))
    n_faces = len(topo.face_oid)
    assert n_faces == 2 * OBJ_GRID**2 + 12
    assert len(topo.crossings[0]) > 0  # the box cuts the sheet
    arrays = [x for x in vars(topo).values() if isinstance(x, np.ndarray)]
    arrays += list(topo.crossings)
    size = sum(x.nbytes for x in arrays)
    assert size / n_faces < 80, size / n_faces


def test03_a_views_rows_made_a_few_at_a_time_are_all_of_them(tmp_path):
    """ViewEdges.take over slices of 7 rows (across the mesh edges and the intersection
    lines) gives every field of the rows taken at once, which are the edges of the view."""
    grid_obj(tmp_path / "sheet.obj")
    scene = load(tmp_path, SHEET_AND_BOX.format(tmp_path / "sheet.obj"))
    table = object_table(scene)
    view = E.view_edges(table, ORIGIN, 134.0)
    whole = E.feature_edges(table, ORIGIN, 134.0)
    kinds = {KINDS[k] for k in np.unique(whole.kind)}
    assert {"silhouette", "border", "intersection"} <= kinds
    assert len(view) == len(whole) and view.max_node() == whole.max_node()
    parts = [view.take(slice(c, c + 7)) for c in range(0, len(view), 7)]
    for key in whole.__dataclass_fields__:
        joined = np.concatenate([getattr(p, key) for p in parts])
        np.testing.assert_array_equal(joined, getattr(whole, key), err_msg=key)
        assert joined.dtype == getattr(whole, key).dtype, key


def test04_depth_behind_a_few_vertices_at_a_time_is_the_same(tmp_path, monkeypatch):
    """``depth_behind`` cast a block of 3 vertices at a time: the same values as one block
    for every vertex (the blocks' ends included)."""
    from mi_npr.strokes import extract as X

    scene = load(
        tmp_path,
        '<shape type="cube" id="box"><transform name="to_world"><scale value="0.8"/>'
        '<rotate y="1" angle="30"/></transform></shape>'
        '<shape type="sphere" id="ball"><point name="center" value="1.2, 0.3, -1.5"/>'
        '<float name="radius" value="0.6"/></shape>',
    )
    sensor = scene.sensors()[0]
    whole = X.extract_strokes(scene, sensor, resample=4.0)
    monkeypatch.setattr(X, "BESIDE_BLOCK", 3)
    blocks = X.extract_strokes(scene, sensor, resample=4.0)
    assert sum(len(s) for s in whole) > 10 and len(whole) == len(blocks)
    for a, b in zip(whole, blocks, strict=True):
        np.testing.assert_array_equal(a.depth_behind, b.depth_behind)
    assert any(np.isfinite(s.depth_behind).any() for s in whole)


def _strokes_key(st) -> list:
    return [(s.kind, s.qi, s.closed, s.points.round(6).tolist()) for s in st]


def test05_a_scene_seen_once_drops_its_topology(tmp_path):
    """``keep_topology=False`` gives the same strokes and leaves no topology kept for the
    scene (with ``True`` the next view reuses it: the same object). A render of a scene it
    loads itself keeps none; of a loaded scene, keeps it; with the strokes drawing and the
    lines' SVG, dropped once, the SVG's strokes those of the lines alone (at another crease
    angle the SVG extracts again: the strokes drawing keeps the topology for it)."""
    from mi_npr.pipeline import _lines_reuse_strokes, render_layers
    from mi_npr.strokes import extract as X

    grid_obj(tmp_path / "sheet.obj")
    scene = load(tmp_path, SHEET_AND_BOX.format(tmp_path / "sheet.obj"))
    sensor, table = scene.sensors()[0], object_table(scene)
    E._LAST[0] = None
    kept = X.extract_strokes(scene, sensor, table)
    topo = E.topology(table)
    assert E._LAST[0] is not None
    dropped = X.extract_strokes(scene, sensor, table, keep_topology=False)
    assert E._LAST[0] is None
    assert _strokes_key(kept) == _strokes_key(dropped) and len(kept) > 3
    assert E.topology(table) is not topo  # built again
    (tmp_path / "other").mkdir()
    E.forget_topology(object_table(load(tmp_path / "other", "")))  # another scene's: kept
    assert E._LAST[0] is not None

    xml = tmp_path / "scene.xml"
    lines = {"crease_angle": 100.0}
    E._LAST[0] = None
    alone = render_layers(str(xml), ["lines"], lines, spp=1)
    assert E._LAST[0] is None
    render_layers(scene, ["lines"], lines, spp=1)
    assert E._LAST[0] is not None
    E._LAST[0] = None
    calls = []
    original = X.forget_topology
    try:
        X.forget_topology = lambda t, view=None: (calls.append(len(t.shapes)), original(t, view))
        both = render_layers(str(xml), ["lines", "strokes"], lines, spp=1)
    finally:
        X.forget_topology = original
    assert calls == [len(table.shapes)] and E._LAST[0] is None  # dropped once, at the end
    assert both.vector_strokes is not None
    a, b = alone.strokes["lines"].strokes, both.strokes["lines"].strokes
    assert _strokes_key(a) == _strokes_key(b) and len(a) > 3
    c = {"crease_angle": 134.0}
    assert _lines_reuse_strokes({"lines": c, "strokes": c})
    assert _lines_reuse_strokes({"lines": {"crease_angle": 0.0}, "strokes": c})
    assert not _lines_reuse_strokes({"lines": {"crease_angle": 100.0}, "strokes": c})
    assert not _lines_reuse_strokes({"lines": c})


def _weld_reference(v: np.ndarray, tol: float) -> np.ndarray:
    """Welded ids from the definition: every pair closer than ``tol``, joined transitively,
    groups numbered in the order of their first vertex."""
    n = len(v)
    close = np.linalg.norm(v[:, None] - v[None], axis=2) < tol
    label = np.full(n, -1)
    k = 0
    for i in range(n):
        if label[i] >= 0:
            continue
        todo = [i]
        label[i] = k
        while todo:
            j = todo.pop()
            for m in np.flatnonzero(close[j] & (label < 0)):
                label[m] = k
                todo.append(m)
        k += 1
    return label


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test06_weld_against_every_pair(dtype):
    """``weld`` against all pairs' distances: exact duplicates, chains of near ones (joined
    transitively though their ends lie farther apart than the tolerance), lone points; one
    point, none; float32 and float64 positions."""
    rng = np.random.default_rng(11)
    base = rng.uniform(-1, 1, (60, 3))
    chain = base[0] + np.outer(np.arange(5), [0.6e-3, 0, 0])  # steps under 1e-3, ends 2.4e-3
    v = np.concatenate([base, base[rng.integers(0, 60, 40)], chain, base[:7] + 2e-4])
    v = v[rng.permutation(len(v))].astype(dtype)
    got = E.weld(v, 1e-3)
    want = _weld_reference(v.astype(np.float64), 1e-3)
    np.testing.assert_array_equal(got, want)
    assert got.max() + 1 < len(v) - 40
    np.testing.assert_array_equal(E.weld(v[:1], 1e-3), [0])
    assert len(E.weld(v[:0], 1e-3)) == 0


def test07_the_last_views_rows_without_the_planes(tmp_path):
    """A topology without its planes (:meth:`Topology.rows_only`) gives a view the same rows;
    the single-precision soup the same intersection segments as in double precision."""
    from mi_npr.strokes.intersect import intersections

    grid_obj(tmp_path / "sheet.obj")
    scene = load(tmp_path, SHEET_AND_BOX.format(tmp_path / "sheet.obj"))
    table = object_table(scene)
    view = E.view_edges(table, ORIGIN, 134.0)
    whole = view.take(slice(None))
    view.topo = view.topo.rows_only()
    assert len(view.topo.unit) == 0 and len(view.topo.offset) == 0
    slim = view.take(slice(None))
    for key in whole.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(slim, key), getattr(whole, key), err_msg=key)
    v, f, oid = E.mesh_arrays(table)
    assert v.dtype == np.float32
    single, double = intersections(v, f, oid), intersections(v.astype(np.float64), f, oid)
    assert len(single[0]) > 0
    for a, b in zip(single, double, strict=True):
        np.testing.assert_array_equal(a, b)


def test08_a_prefetched_first_stage_gives_the_same_topology(tmp_path):
    """``prefetch_topology`` runs the intersection search and the weld (or, ``whole``, the
    whole build) on another thread; the next ``topology`` of the same meshes goes on from them:
    every array the same as a build from scratch (with the pairs asked for by the prefetch).
    One under way refuses another; one of other meshes is dropped; none starts when the
    topology is kept already; a whole build with a crease angle has the edges' kinds at that
    angle. A render prefetches the whole build, or its first stage where the
    lines' SVG takes the strokes drawing's strokes, and draws the same strokes as the
    extraction alone."""
    from mi_npr.pipeline import render_layers
    from mi_npr.strokes import extract as X

    grid_obj(tmp_path / "sheet.obj")
    scene = load(tmp_path, SHEET_AND_BOX.format(tmp_path / "sheet.obj"))
    table = object_table(scene)
    cases = (None, np.array([[1, 2]]), np.zeros((0, 2), np.int64))
    for pairs, whole in itertools.product(cases, (False, True)):
        E._LAST[0] = None
        ref = E.Topology.of(table, pairs)
        assert E.prefetch_topology(table, pairs, whole=whole)
        assert not E.prefetch_topology(table, pairs)  # one at a time
        E.wait_for_topology()
        got = E.topology(table, np.array([[5, 6]]))  # the prefetch's pairs, not these
        assert E._EARLY[0] is None
        for key, value in vars(ref).items():
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(getattr(got, key), value, err_msg=key)
        for a, b in zip(got.crossings, ref.crossings, strict=True):
            np.testing.assert_array_equal(a, b)
        assert got.size == ref.size and (got.searched is None) == (pairs is None)
    # a whole build classifies the edges at the crease angle asked for: the same kinds
    E._LAST[0] = None
    assert E.prefetch_topology(table, whole=True, crease_angle=100.0)
    E.wait_for_topology()
    got = E.topology(table)
    assert list(got._kinds) == [100.0]
    np.testing.assert_array_equal(got._kinds[100.0], E.Topology.of(table).static_kinds(100.0))
    assert not E.prefetch_topology(table)  # kept already
    (tmp_path / "other").mkdir()
    other = object_table(load(tmp_path / "other", '<shape type="cube" id="c"/>'))
    E._LAST[0] = None
    assert E.prefetch_topology(other)
    E.topology(table)  # other meshes: the prefetch is waited for and dropped
    assert E._EARLY[0] is None and E._LAST[0][2].size == ref.size
    E._LAST[0] = None
    assert E.prefetch_topology(other)
    E.wait_for_topology()  # done, never taken: a prefetch of other meshes replaces it
    assert E.prefetch_topology(table) and E._EARLY[0][0] == E._mesh_key(table)[0]
    E.wait_for_topology()
    assert not E.prefetch_topology(table)  # its own, done: kept for the next topology()
    E.topology(table)

    called = []
    original = E.prefetch_topology
    try:
        E.prefetch_topology = lambda *a, **k: (
            called.append((k["whole"], k["crease_angle"])) or original(*a, **k)
        )
        import mi_npr.pipeline as P

        P.prefetch_topology = E.prefetch_topology
        E._LAST[0] = None
        render_layers(scene, ["strokes"], spp=1)  # the whole topology beside the beauty
        E._LAST[0] = None
        # the lines' SVG taking the strokes drawing's strokes: the first stage alone (the
        # rest would stay alive through the anti-aliased lines)
        render_layers(scene, ["lines", "strokes"], spp=1)
        E._LAST[0] = None
        r = render_layers(scene, ["lines"], {"crease_angle": 100.0}, spp=1)
    finally:
        E.prefetch_topology = original
        P.prefetch_topology = original
    # the edges' kinds at the crease angle of the strokes extracted first
    assert [w for w, _ in called] == [True, False, True] and E._EARLY[0] is None
    assert called[0][1] == 134.0 and called[2][1] == 100.0
    E._LAST[0] = None
    ids = r.gbuffer.numpy("object_id.V")
    from mi_npr.strokes.intersect import touching_pairs

    alone = X.extract_strokes(
        scene, scene.sensors()[0], table, crease_angle=100.0, max_qi=0, depth_behind=False,
        intersect=touching_pairs(ids),
    )  # fmt: skip
    drawn = r.strokes["lines"].strokes
    found = {tuple(map(tuple, s.points.round(6))) for s in alone}
    assert len(drawn) > 3 and all(tuple(map(tuple, s.points.round(6))) in found for s in drawn)
