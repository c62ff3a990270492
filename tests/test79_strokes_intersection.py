"""Intersection lines between meshes, against a closed form: a box poking out of a cube's face
cuts it along a square.

Configuration (before a common rotation and translation): the cube ``[-1, 1]^3`` and the box
``[0.5, 2] x [-0.5, 0.5] x [-0.5, 0.5]``; the box leaves the cube through its face ``x = 1``
along the square ``x = 1, |y| = 0.5 or |z| = 0.5``, of perimeter 4. The square's corners are
placed by Mitsuba's own transform and projected with test75's pinhole model.
"""

from __future__ import annotations

import math

import mitsuba as mi
import numpy as np

from mi_npr.strokes import extract_strokes
from mi_npr.strokes.intersect import segments

from .test75_strokes_closed_form import load, project, seg_distance

COMMON = '<rotate y="1" angle="30"/><rotate x="1" angle="20"/><translate z="6"/>'
BOXES = (
    f'<shape type="cube" id="cube"><transform name="to_world">{COMMON}</transform></shape>'
    '<shape type="cube" id="peg"><transform name="to_world"><scale x="0.75" y="0.5" z="0.5"/>'
    f'<translate x="1.25"/>{COMMON}</transform></shape>'
)


def common() -> np.ndarray:
    m = mi.ScalarTransform4f().translate([0, 0, 6]).rotate([1, 0, 0], 20).rotate([0, 1, 0], 30)
    return np.asarray(m.matrix, np.float64)


def test01_two_triangles_cut_along_the_closed_form_segment():
    # the triangle in z = 0 and one standing across it: they meet on x = 0.25, y in [0, 0.5]
    t1 = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    t2 = np.array([[[0.25, -1.0, -1.0], [0.25, 0.5, -1.0], [0.25, 0.5, 2.0]]])
    ok, p, q = segments(t1, t2)
    assert ok.tolist() == [True]
    ends = sorted([tuple(np.round(p[0], 12)), tuple(np.round(q[0], 12))])
    # t2 spans y <= 0.5 at z = 0 (its edge from (y=-1, z=-1) to (y=0.5, z=2) crosses z = 0 at
    # y = 0); t1 spans y in [0, 0.75] at x = 0.25: the overlap is y in [0, 0.5]
    np.testing.assert_allclose(ends, [(0.25, 0.0, 0.0), (0.25, 0.5, 0.0)], atol=1e-12)
    # apart, parallel, coplanar or only touching with a vertex: nothing
    touching = np.array([[[0.2, 0.2, 0.0], [0.2, 0.2, 1.0], [0.3, 0.2, 1.0]]])
    up, shift = np.array([0.0, 0.0, 1.0]), np.array([0.1, 0.1, 0.0])
    for other in (t2 + 5 * up, t1 + up, t1 + shift, touching):
        assert not segments(t1, other)[0].any()


def test02_a_box_poking_out_of_a_cube_cuts_a_square(tmp_path):
    scene = load(tmp_path, BOXES)
    st = extract_strokes(scene, scene.sensors()[0])
    cut = st.of_kind("intersection")
    assert cut
    m = common()
    local = np.array([[1, -0.5, -0.5], [1, 0.5, -0.5], [1, 0.5, 0.5], [1, -0.5, 0.5]], float)
    square = local @ m[:3, :3].T + m[:3, 3]
    px = project(square)
    ring = np.concatenate([px, px[:1]])
    # on the square in 3-D: back in the configuration's frame, x = 1 and on the square's rim
    for s in cut:
        back = (s.position - m[:3, 3]) @ m[:3, :3]  # m's rotation is orthonormal
        np.testing.assert_allclose(back[:, 0], 1.0, atol=1e-5)
        rim = np.maximum(np.abs(back[:, 1]), np.abs(back[:, 2]))
        np.testing.assert_allclose(rim, 0.5, atol=1e-5)
    # on the projected square, covering it once
    err = max(seg_distance(s.points, ring[:-1], ring[1:]).max() for s in cut)
    print(f"intersection: max distance to the projected square {err:.2e} px")
    assert err < 0.05
    total = sum(s.length() for s in cut)
    perimeter = np.hypot(*np.diff(ring, axis=0).T).sum()
    assert abs(total - perimeter) < 0.05
    # the square's far side is behind the peg: some of it hidden, some visible
    assert {s.qi > 0 for s in cut} == {False, True}


def _soup(rng: np.random.Generator, objects: int, per: int) -> tuple[np.ndarray, ...]:
    """Random triangles in ``objects`` objects, faces of one object contiguous: small ones
    crowded into a unit cube, a few long or flat ones across it (the grid's hard case), and
    some that share a plane or a corner with another object's (the tie rules)."""
    tris, oid = [], []
    for o in range(objects):
        centre = rng.uniform(0, 1, 3)
        t = centre + rng.normal(0, 0.08, (per, 3, 3))
        t[:2] = rng.uniform(-0.2, 1.2, (2, 3, 3))  # long thin triangles across the cube
        t[2] = [[-0.1, 0.5, -0.1], [1.1, 0.5, -0.1], [0.5, 0.5, 1.1]]  # a plane y = 0.5
        t[3] = t[2] + [0.0, 0.0, 0.01]  # coplanar with the one above (and every object's)
        t[4, 0] = rng.uniform(0, 1, 3) * [1, 0, 1] + [0, 0.5, 0]  # a corner on that plane
        tris.append(t)
        oid += [o] * per
    t = np.concatenate(tris)
    v = t.reshape(-1, 3)
    f = np.arange(len(v)).reshape(-1, 3).astype(np.int32)
    return v, f, np.array(oid, np.int32), t


def test03_the_search_finds_what_every_pair_gives():
    """The grid search (:func:`intersections`) against the pair test on every pair of
    triangles of different objects: the same segments, on the same faces."""
    from mi_npr.strokes.intersect import intersections

    rng = np.random.default_rng(7)
    for objects, per in ((2, 40), (5, 30), (9, 25)):
        v, f, oid, t = _soup(rng, objects, per)
        i, j = np.triu_indices(len(f), 1)
        i, j = i[oid[i] != oid[j]], j[oid[i] != oid[j]]
        ok, p, q = segments(t[i], t[j])
        want = {(a, b): (pa, qa) for a, b, pa, qa in zip(i[ok], j[ok], p[ok], q[ok], strict=True)}
        gp, gq, ga, gb = intersections(v, f, oid)
        got = {(a, b): (pa, qa) for a, b, pa, qa in zip(ga, gb, gp, gq, strict=True)}
        assert len(got) == len(ga) == len(want) > 0
        assert got.keys() == want.keys()
        for k, (pa, qa) in want.items():
            np.testing.assert_array_equal(got[k][0], pa)
            np.testing.assert_array_equal(got[k][1], qa)


def test04_no_pair_without_a_crossing():
    """Objects apart, one object alone, no faces: no segment."""
    from mi_npr.strokes.intersect import intersections

    rng = np.random.default_rng(3)
    v, f, oid, _ = _soup(rng, 1, 30)
    assert len(intersections(v, f, oid)[0]) == 0
    far = np.concatenate([v, v + 10.0])
    f2 = np.concatenate([f, f + len(v)])
    assert len(intersections(far, f2, np.r_[oid, oid + 1])[0]) == 0
    assert len(intersections(v, f[:0], oid[:0])[0]) == 0


def test05_without_depth_behind_the_same_strokes(tmp_path):
    """``depth_behind=False`` (the lines drawing's strokes) skips only the rays beside each
    vertex: the same strokes, with ``depth_behind`` left unset."""
    scene = load(tmp_path, BOXES)
    sensor = scene.sensors()[0]
    full = extract_strokes(scene, sensor)
    lean = extract_strokes(scene, sensor, depth_behind=False)
    assert len(full) == len(lean) > 4
    for a, b in zip(full, lean, strict=True):
        assert (a.kind, a.qi, a.closed) == (b.kind, b.qi, b.closed)
        np.testing.assert_array_equal(a.points, b.points)
        assert a.depth_behind is not None and b.depth_behind is None


def _circle(centre: np.ndarray, normal: np.ndarray, r: float, n: int = 20000) -> np.ndarray:
    normal = normal / np.linalg.norm(normal)
    e1 = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    t = np.linspace(0, 2 * np.pi, n)[:, None]
    return centre + r * (np.cos(t) * e1 + np.sin(t) * e2)


def _inner(strokes, field: str) -> np.ndarray:
    """``field`` of the strokes' vertices but the ends of open ones: where a stroke meets an
    outline of another kind it ends on that outline's first vertex (no gap between them)."""
    return np.concatenate(
        [getattr(s, field)[slice(None) if s.closed else slice(1, -1)] for s in strokes]
    )


def _on_curve(strokes, curve_px: np.ndarray) -> tuple[float, float]:
    """The largest film distance (px) to a densely sampled curve of the strokes' inner
    vertices, and of their ends."""
    ends = np.concatenate([s.points[[0, -1]] for s in strokes])
    inner = _inner(strokes, "points")
    far = [float(seg_distance(x, curve_px[:-1], curve_px[1:]).max()) for x in (inner, ends)]
    return far[0], far[1]


def test06_two_spheres_cut_along_their_circle_drawn_once(tmp_path):
    """Shapes that are not meshes meet along an intersection stroke too (from their outlines:
    the two sides at one depth), on the analytic circle of the two spheres, drawn once (by
    the smaller object id's outline)."""
    a, ra = np.array([-0.4, 0.0, 5.0]), 0.8
    b, rb = np.array([0.5, 0.1, 5.2]), 0.7
    body = "".join(
        f'<shape type="sphere" id="{name}"><point name="center" value="{", ".join(map(str, c))}"/>'
        f'<float name="radius" value="{r}"/></shape>'
        for name, c, r in (("a", a, ra), ("b", b, rb))
    )
    scene = load(tmp_path, body)
    cut = extract_strokes(scene, scene.sensors()[0]).of_kind("intersection")
    assert cut and len({int(s.object_id[0]) for s in cut}) == 1  # drawn once
    p = _inner(cut, "position")
    assert len(p) >= 4
    np.testing.assert_allclose(np.linalg.norm(p - a, axis=1), ra, atol=2e-3)
    np.testing.assert_allclose(np.linalg.norm(p - b, axis=1), rb, atol=2e-3)
    # the circle: in the plane 2 p.(b - a) = ra^2 - rb^2 + |b|^2 - |a|^2, about the line a-b
    d = np.linalg.norm(b - a)
    x = (d * d + ra * ra - rb * rb) / (2 * d)
    ring = project(_circle(a + x * (b - a) / d, b - a, math.sqrt(ra * ra - x * x)))
    inner, ends = _on_curve(cut, ring)
    assert inner < 0.05 and ends < 1.0
    assert sum(s.length() for s in cut) > 10.0


def test07_a_sphere_sunk_into_a_mesh_cuts_its_top_face(tmp_path):
    """A sphere (not a mesh) half sunk into a box (a mesh): the intersection stroke lies on
    the circle where the box's top plane cuts the sphere."""
    c, r, top = np.array([0.0, 0.0, 5.0]), 0.8, -0.4
    body = (
        '<shape type="sphere"><point name="center" value="0, 0, 5"/>'
        f'<float name="radius" value="{r}"/></shape>'
        '<shape type="cube" id="box"><transform name="to_world"><scale x="2" y="0.5" z="2"/>'
        f'<translate y="{top - 0.5}" z="5"/></transform></shape>'
    )
    scene = load(tmp_path, body)
    cut = extract_strokes(scene, scene.sensors()[0]).of_kind("intersection")
    assert cut
    p = _inner(cut, "position")
    assert len(p) >= 4
    np.testing.assert_allclose(p[:, 1], top, atol=2e-3)
    np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), r, atol=2e-3)
    ring = project(
        _circle(
            c + np.array([0.0, top, 0.0]), np.array([0.0, 1.0, 0.0]), math.sqrt(r * r - top * top)
        )
    )
    inner, ends = _on_curve(cut, ring)
    assert inner < 0.05 and ends < 1.0
    assert sum(s.length() for s in cut) > 20.0


def test08_a_search_of_some_pairs_is_the_full_search_of_those_pairs():
    """``intersections(..., pairs)``: exactly the segments of the full search whose faces'
    objects are one of the pairs asked for (either order; a pair of one object, or with an id
    that has no faces, asks for nothing)."""
    from mi_npr.strokes.intersect import intersections

    rng = np.random.default_rng(5)
    v, f, oid, _ = _soup(rng, 7, 25)
    full = intersections(v, f, oid)
    key = oid[full[2]] * 100 + oid[full[3]]
    assert len(np.unique(key)) > 6
    for asked in ([[1, 2]], [[4, 0], [2, 5], [3, 3], [6, 99]], np.zeros((0, 2)), [[6, 1]]):
        a = np.sort(np.asarray(asked, np.int64).reshape(-1, 2), axis=1)
        rows = np.isin(key, a[:, 0] * 100 + a[:, 1])
        got = intersections(v, f, oid, np.asarray(asked))
        for x, y in zip(got, full, strict=True):
            np.testing.assert_array_equal(x, y[rows])


def test09_touching_pairs_against_every_pixel_pair():
    """The pairs of ids side by side or corner to corner, against a loop over every pixel and
    its 8 neighbours; background (0) touches nothing; 1x1, one row, one column."""
    from mi_npr.strokes.intersect import touching_pairs

    rng = np.random.default_rng(2)
    images = [np.zeros((1, 1), np.uint32), np.array([[3, 0, 4, 4, 1]], np.uint32)]
    images += [np.array([[2], [2], [5]], np.uint32), np.zeros((4, 6), np.uint32)]
    images += [rng.integers(0, 6, (h, w)).astype(np.uint32) for h, w in ((7, 5), (9, 12))]
    for ids in images:
        want = set()
        h, w = ids.shape
        for y in range(h):
            for x in range(w):
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        yy, xx = y + dy, x + dx
                        if 0 <= yy < h and 0 <= xx < w:
                            a, b = int(ids[y, x]), int(ids[yy, xx])
                            if a and b and a != b:
                                want.add((min(a, b), max(a, b)))
        got = touching_pairs(ids)
        assert got.shape == (len(want), 2)
        assert [tuple(p) for p in got.tolist()] == sorted(want)


THREE = (
    '<shape type="cube" id="a"><transform name="to_world">'
    f'<scale value="0.8"/>{COMMON}</transform></shape>'
    '<shape type="cube" id="b"><transform name="to_world"><scale x="0.9" y="0.3" z="0.3"/>'
    f'<translate x="0.9"/>{COMMON}</transform></shape>'
    '<shape type="cube" id="c"><transform name="to_world"><scale x="0.3" y="0.9" z="0.3"/>'
    f'<translate x="0.6" y="0.5"/>{COMMON}</transform></shape>'
)


def test10_pairs_searched_on_demand_give_the_same_lines_in_any_order(tmp_path):
    """Three boxes cutting each other: a view asking for some pairs gets the segments and
    end nodes of those pairs in the full search, whatever the topology searched before; a
    view asking for every pair after partial searches gets the full search's rows."""
    from mi_npr.scene import object_table
    from mi_npr.strokes import edges as E

    table = object_table(load(tmp_path, THREE))
    ids = {n: k for k, n in table.names.items()}
    ab, bc, ac = ([ids[x], ids[y]] for x, y in ("ab", "bc", "ac"))
    origin = np.array([0.0, 0.0, 0.0])

    def rows(view):
        edges = view.take(slice(len(view.edge), len(view)))
        return edges.a, edges.b, edges.va, edges.vb, edges.faces

    def fresh(pairs):
        E._LAST[0] = None
        return rows(E.view_edges(table, origin, intersect=pairs))

    full = fresh(True)
    pair_of = {tuple(sorted(r)) for r in full[4][:, :, 0].tolist()}
    assert pair_of == {tuple(sorted(p)) for p in (ab, bc, ac)}  # each pair cuts
    for asked in ([ab], [bc, ac], [ac, ab, bc]):
        want = fresh(np.array(asked))
        assert len(want[0]) > 0
        for before in ([bc], [ab, ac], True):
            E._LAST[0] = None
            E.view_edges(table, origin, intersect=np.array(before) if before is not True else True)
            got = rows(E.view_edges(table, origin, intersect=np.array(asked)))
            for x, y in zip(got, want, strict=True):
                np.testing.assert_array_equal(x, y)
    E._LAST[0] = None
    E.view_edges(table, origin, intersect=np.array([bc]))
    for x, y in zip(rows(E.view_edges(table, origin)), full, strict=True):
        np.testing.assert_array_equal(x, y)
    assert len(rows(E.view_edges(table, origin, intersect=False))[0]) == 0


def test11_the_lines_drawing_finds_the_visible_intersection_lines(tmp_path):
    """The lines drawing's strokes look only at the meshes whose pixels touch: its
    intersection strokes are the visible ones of a full extraction."""
    import mi_npr
    from mi_npr import pipeline

    scene_path = tmp_path / "scene.xml"
    load(tmp_path, THREE)  # writes scene.xml
    out = pipeline.render_layers(scene_path, ("lines",), {}, spp=1)
    layer = out.strokes[next(k for k in out.strokes if "lines" in k)]
    got = [s for s in layer.strokes if s.kind == "intersection"]
    scene = mi_npr.load_scene(scene_path)
    full = extract_strokes(scene, scene.sensors()[0], max_qi=0)
    want = [s for s in full if s.kind == "intersection" and s.qi == 0]
    assert len(want) >= 2
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a.points, b.points, atol=1e-9)
