"""Visibility of strokes: T-junctions, glass, no stroke drawn twice.

References: the projected outlines and corners of test75 (pinhole model and tangent cone
written in the tests), and brute-force distances between sampled strokes.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from mi_npr.strokes import extract_strokes

from .test75_strokes_closed_form import load, project, seg_distance, sphere_outline

#: A wall far behind (a mesh rectangle, 2 x 2 scaled by 3) whose top border passes behind a
#: cube and a sphere.
WALL = (
    '<shape type="rectangle" id="wall"><transform name="to_world">'
    '<scale x="2.6" y="1.2"/><translate x="0" y="0.2" z="9"/></transform></shape>'
)
BOX = (
    '<shape type="cube" id="box"><transform name="to_world"><rotate y="1" angle="30"/>'
    '<rotate x="1" angle="25"/><scale value="0.45"/><translate x="-0.6" y="0.9" z="5"/>'
    "</transform></shape>"
)
BALL_C, BALL_R = np.array([0.9, 1.0, 5.5]), 0.5
BALL = (
    f'<shape type="sphere" id="ball"><point name="center" value="{", ".join(map(str, BALL_C))}"'
    f'/><float name="radius" value="{BALL_R}"/></shape>'
)


def polylines(st, pred=lambda s: True):
    return [
        np.concatenate([s.points, s.points[:1]]) if s.closed else s.points for s in st if pred(s)
    ]


def _near(p: np.ndarray, lines: list[np.ndarray]) -> float:
    """Distance of point p to the nearest polyline."""
    return min(float(seg_distance(p[None], q[:-1], q[1:])[0]) for q in lines if len(q) > 1)


def test01_t_junctions_end_the_strokes_behind(tmp_path):
    scene = load(tmp_path, WALL + BOX + BALL)
    st = extract_strokes(scene, scene.sensors()[0], max_qi=8)
    wall = [s for s in st if st.name_of(s.object_id[0]) == "wall"]
    top_y = project(np.array([[0.0, 1.4, 9.0]]))[0, 1]
    top = sorted(
        (s for s in wall if np.allclose(s.points[:, 1], top_y, atol=0.5)),
        key=lambda s: s.points[:, 0].min(),
    )
    # the wall's top border: hidden behind the box and the ball (qi 2: their near and far
    # sides), visible between and around them
    assert [s.qi for s in top] == [0, 2, 0, 2, 0], [(s.qi, s.points.tolist()) for s in top]
    assert all(s.kind == "border" for s in top)
    # every end where visibility changes lies on the occluder's outline
    box_sil = polylines(
        st, lambda s: s.kind == "silhouette" and st.name_of(s.object_id[0]) == "box"
    )
    ball_ref = sphere_outline(BALL_C, BALL_R)
    ball_ring = np.concatenate([ball_ref, ball_ref[:1]])
    errors = []
    for left, right in itertools.pairwise(top):
        a = left.points[np.argmax(left.points[:, 0])]
        b = right.points[np.argmin(right.points[:, 0])]
        assert np.allclose(a, b)  # the pieces meet
        on_ball = float(seg_distance(a[None], ball_ring[:-1], ball_ring[1:])[0])
        errors.append(min(_near(a, box_sil), on_ball))
    print(f"T-junction ends: max distance to the occluder's outline {max(errors):.2e} px")
    assert max(errors) < 0.05
    # the occluders' outlines run on through the junctions: one stroke each
    assert (
        len([s for s in st if s.kind == "silhouette" and st.name_of(s.object_id[0]) == "ball"]) == 1
    )


def longest_double(st) -> float:
    """The longest stretch (px) along which two strokes of one visibility state run within
    0.5 px of each other, sampled every 0.1 px along each."""
    lines = polylines(st)
    state = [(s.qi, s.through_glass) for s in st]
    worst = 0.0
    for i, a in enumerate(lines):
        seg = np.hypot(*np.diff(a, axis=0).T)
        samples = []
        for k in range(len(a) - 1):  # every 0.1 px along stroke i
            n = max(2, int(np.ceil(seg[k] / 0.1)) + 1)
            t = np.linspace(0, 1, n)[:, None]
            samples.append(a[k] + t * (a[k + 1] - a[k]))
        pts = np.concatenate(samples)
        step = np.hypot(*np.diff(pts, axis=0).T)
        for j, b in enumerate(lines):
            if i == j or len(b) < 2 or state[i] != state[j]:
                continue
            close = seg_distance(pts, b[:-1], b[1:]) < 0.5
            # the longest run of samples within 0.5 px of stroke j, in pixels
            run = best = 0.0
            for k in range(1, len(pts)):
                run = run + step[k - 1] if close[k] and close[k - 1] else 0.0
                best = max(best, run)
            worst = max(worst, best)
    return worst


def test02_no_stroke_is_drawn_twice(tmp_path):
    """Two strokes of one visibility state never run within 0.5 px of each other for more than
    2 px (a hidden line may cross a visible one at a small angle: that is the view, not a
    duplicate)."""
    scene = load(tmp_path, WALL + BOX + BALL)
    st = extract_strokes(scene, scene.sensors()[0], max_qi=8)
    assert len(polylines(st)) >= 10
    worst = longest_double(st)
    print(f"longest stretch of two strokes within 0.5 px: {worst:.2f} px")
    assert worst <= 2.0


GLASS = (
    '<shape type="cube" id="pane"><transform name="to_world"><scale x="1.2" y="1.6" z="0.05"/>'
    '<translate x="{x}" y="0" z="3"/></transform><bsdf type="dielectric"/></shape>'
)


def test03_a_sphere_behind_glass_keeps_its_strokes(tmp_path):
    c, r = np.array([-0.3, 0.0, 6.5]), 0.9
    ball = (
        f'<shape type="sphere" id="ball"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
        f'<float name="radius" value="{r}"/></shape>'
    )
    scene = load(tmp_path, GLASS.format(x=-0.2) + ball)
    st = extract_strokes(scene, scene.sensors()[0])
    balls = [s for s in st if st.name_of(s.object_id[0]) == "ball"]
    assert [(s.kind, s.closed, s.qi, s.through_glass) for s in balls] == [
        ("silhouette", True, 0, True)
    ]
    ref = sphere_outline(c, r)
    ring = np.concatenate([ref, ref[:1]])
    err = seg_distance(balls[0].points, ring[:-1], ring[1:]).max()
    print(f"sphere behind glass: max vertex error {err:.5f} px")
    assert err < 0.05
    # the pane's own edges: those of its front face seen directly, the others through it
    pane = [s for s in st if st.name_of(s.object_id[0]) == "pane"]
    assert pane and all(s.qi == 0 for s in pane)
    assert {s.through_glass for s in pane} == {False, True}


def test04_glass_over_half_a_sphere_splits_its_outline(tmp_path):
    c, r = np.array([0.0, 0.0, 6.5]), 0.9
    ball = (
        f'<shape type="sphere" id="ball"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
        f'<float name="radius" value="{r}"/></shape>'
    )
    scene = load(tmp_path, GLASS.format(x=-1.2) + ball)  # the pane covers x < 0 only
    st = extract_strokes(scene, scene.sensors()[0])
    balls = [s for s in st if st.name_of(s.object_id[0]) == "ball"]
    assert sorted(s.through_glass for s in balls) == [False, True]
    assert all(not s.closed and s.qi == 0 for s in balls)
    # the two pieces meet: they are one outline
    a, b = balls
    ends_a, ends_b = a.points[[0, -1]], b.points[[0, -1]]
    gaps = np.hypot(*(ends_a[:, None] - ends_b[None]).transpose(2, 0, 1))
    assert np.sort(gaps.min(1)).max() < 1.5


def test05_mesh_edges_behind_glass_keep_their_qi(tmp_path):
    box = (
        '<shape type="cube" id="box"><transform name="to_world"><rotate y="1" angle="35"/>'
        '<rotate x="1" angle="25"/><scale value="0.6"/><translate z="6"/></transform></shape>'
    )
    plain = load(tmp_path, box)
    behind = load(tmp_path, GLASS.format(x=0.2) + box)
    a = [s for s in extract_strokes(plain, plain.sensors()[0])]
    st = extract_strokes(behind, behind.sensors()[0])
    b = [s for s in st if st.name_of(s.object_id[0]) == "box"]
    key = lambda s: (s.kind, s.qi, np.round(s.points, 3).tobytes())  # noqa: E731
    assert sorted(map(key, a)) == sorted(map(key, b))  # same strokes, same QI
    assert all(s.through_glass for s in b)
    # the three back edges, hidden by the box itself (QI 1): two of them chained at the back
    # corner where they turn by less than chain_angle, so 2 or 3 strokes of 3 segments
    hidden = [s for s in b if s.qi == 1]
    assert {s.qi for s in b} == {0, 1} and 2 <= len(hidden) <= 3
    assert sum(len(s) - 1 for s in hidden) == 3


def test06_visibility_rays_reuse_their_compiled_kernel(tmp_path):
    """The QI loop is fed from numpy arrays; Dr.Jit compiles a different kernel for an
    unaligned buffer, so without aligned copies most calls compiled anew."""
    import drjit as dr

    from mi_npr.scene import object_table
    from mi_npr.strokes.visibility import quantitative_invisibility

    scene = load(tmp_path, BOX)
    table = object_table(scene)
    rng = np.random.default_rng(3)
    origin, ahead = np.array([0.3, 0.8, -0.5]), np.array([0.0, 0.0, 4.0])
    quantitative_invisibility(scene, table, origin, rng.random((301, 3)) + ahead)
    dr.sync_thread()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        for n in (257, 1000, 333):  # sizes whose numpy buffers land anywhere
            quantitative_invisibility(scene, table, origin, rng.random((n, 3)) + ahead)
        dr.sync_thread()
        history = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    assert history and all(k["cache_hit"] for k in history)


def test07_a_sphere_in_front_of_another_owns_their_shared_outline(tmp_path):
    near_c, near_r = np.array([0.3, 0.1, 5.0]), 0.8
    far_c, far_r = np.array([-0.6, -0.2, 7.0]), 1.2
    scene = load(
        tmp_path,
        "".join(
            f'<shape type="sphere" id="{n}"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
            f'<float name="radius" value="{r}"/></shape>'
            for n, c, r in (("near", near_c, near_r), ("far", far_c, far_r))
        ),
    )
    st = extract_strokes(scene, scene.sensors()[0])
    near = [s for s in st if st.name_of(s.object_id[0]) == "near"]
    far = [s for s in st if st.name_of(s.object_id[0]) == "far"]
    assert [(s.kind, s.closed, s.through_glass) for s in near] == [("silhouette", True, False)]
    assert [(s.kind, s.closed, s.through_glass) for s in far] == [("silhouette", False, False)]
    rings = {}
    for name, c, r in (("near", near_c, near_r), ("far", far_c, far_r)):
        ref = sphere_outline(c, r)
        rings[name] = np.concatenate([ref, ref[:1]])
    for s, name in ((near[0], "near"), (far[0], "far")):
        err = seg_distance(s.points, rings[name][:-1], rings[name][1:]).max()
        assert err < 0.05, (name, err)
    # the far outline stops where the near sphere covers it: its ends lie on the near outline
    ends = far[0].points[[0, -1]]
    assert seg_distance(ends, rings["near"][:-1], rings["near"][1:]).max() < 0.5
    # and none of the far stroke runs along the near outline
    inside = seg_distance(far[0].points, rings["near"][:-1], rings["near"][1:]) < 0.25
    assert inside.sum() <= 2


def test08_max_qi_leaves_out_what_lies_deeper(tmp_path):
    """Strokes behind more than ``max_qi`` surfaces are left out, the others are unchanged:
    the wall's top border passes behind the box and the ball (qi 2, each a closed solid)."""
    scene = load(tmp_path, WALL + BOX + BALL)
    full = extract_strokes(scene, scene.sensors()[0], max_qi=8)
    key = lambda s: (s.kind, s.qi, s.through_glass, np.round(s.points, 6).tobytes())  # noqa: E731
    assert {s.qi for s in full} == {0, 1, 2}
    for max_qi in (0, 1, 2):  # 0: the visible strokes alone
        cut = extract_strokes(scene, scene.sensors()[0], max_qi=max_qi)
        assert sorted(map(key, cut)) == sorted(key(s) for s in full if s.qi <= max_qi)
    # the drawing's default keeps an object's own back edges (qi 1), not what lies behind it
    from mi_npr.drawings import DRAWINGS

    assert DRAWINGS["strokes"].values({})["max_qi"] == 1


def _chains_by_walking(node0, node1, cls, dir0, dir1, max_turn, short):
    """Chaining by hand (the rules of :mod:`mi_npr.strokes.chain`): at each node, join ends of
    one class in pairs, the straightest first, unless the turn is too sharp between two pieces
    of at least ``short`` px; then walk the
    pieces one by one: open chains from the lower end piece's free end, then loops from their
    lowest piece."""
    n = len(cls)
    ends = {}
    for p in range(n):
        for side, node in ((0, node0[p]), (1, node1[p])):
            ends.setdefault((int(node), int(cls[p])), []).append((p, side))
    link = {}
    for group in ends.values():
        pairs = []
        for (p, a), (q, b) in itertools.combinations(group, 2):
            if p == q:
                continue
            u1 = (dir0 if a == 0 else dir1)[p]
            u2 = (dir0 if b == 0 else dir1)[q]
            l1, l2 = math.hypot(*u1), math.hypot(*u2)
            cos = 1.0 if l1 == 0 or l2 == 0 else -float(u1 @ u2) / (l1 * l2)
            sharp = cos <= math.cos(math.radians(max_turn))
            if max_turn < 180 and min(l1, l2) >= short and sharp:
                continue
            ea, eb = sorted((p + a * n, q + b * n))
            pairs.append((-cos, ea, eb))
        for _, ea, eb in sorted(pairs):
            x, y = (ea % n, ea // n), (eb % n, eb // n)
            if x not in link and y not in link:
                link[x], link[y] = y, x
    used = [False] * n
    out = []

    def walk(p, side):
        steps = []
        while True:
            used[p] = True
            steps.append((p, side == 1))
            nxt = link.get((p, 1 - side))
            if nxt is None:
                return steps, False
            if used[nxt[0]]:
                return steps, True
            p, side = nxt

    for p in range(n):
        if not used[p] and ((p, 0) not in link or (p, 1) not in link):
            out.append(walk(p, 0 if (p, 0) not in link else 1))
    for p in range(n):
        if not used[p]:
            out.append(walk(p, 0))
    return out


def test09_chaining_agrees_with_walking_by_hand():
    from mi_npr.strokes.chain import chain_pieces

    rng = np.random.default_rng(7)
    loops = 0
    for _ in range(400):
        n, nodes = int(rng.integers(0, 30)), int(rng.integers(1, 25))
        node0, node1 = rng.integers(0, nodes, n), rng.integers(0, nodes, n)
        cls = rng.integers(0, 2, n)
        dir0 = rng.normal(size=(n, 2))
        dir0[rng.random(n) < 0.1] = 0.0  # pieces of no length on the film
        dir1 = -dir0
        for max_turn, short in itertools.product((45.0, 120.0, 180.0), (0.0, 1.0)):
            ref = _chains_by_walking(node0, node1, cls, dir0, dir1, max_turn, short)
            assert chain_pieces(node0, node1, cls, dir0, dir1, max_turn, short) == ref
            loops += sum(closed for _, closed in ref)
    assert loops > 10  # closed loops were tested too


def test10_a_glass_sphere_has_its_own_outline(tmp_path):
    """A glass shape that is not a mesh: its outline is drawn (seen directly, not through
    glass) on the analytic outline, and the ball behind it keeps its strokes, through glass."""
    c, r = np.array([0.2, 0.1, 5.0]), 0.7
    glass = (
        f'<shape type="sphere" id="lens"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
        f'<float name="radius" value="{r}"/><bsdf type="dielectric"/></shape>'
    )
    scene = load(tmp_path, glass + BALL)
    st = extract_strokes(scene, scene.sensors()[0])
    lens = [s for s in st if st.name_of(s.object_id[0]) == "lens"]
    assert [(s.kind, s.qi, s.through_glass) for s in lens] == [("silhouette", 0, False)]
    ref = sphere_outline(c, r)
    ring = np.concatenate([ref, ref[:1]])
    err = seg_distance(lens[0].points, ring[:-1], ring[1:]).max()
    assert err < 0.05, err
    # the lens covers part of the ball: where it does, the ball's outline is seen through it
    balls = [s for s in st if st.name_of(s.object_id[0]) == "ball"]
    assert sorted({s.through_glass for s in balls}) == [False, True]
    # the lens is in front of the ball where they overlap, so its whole outline is drawn
    assert lens[0].closed


def test10_sub_pixel_zig_zag_is_one_stroke_a_corner_ends_it():
    """Pieces shorter than ``SHORT`` px never break a chain by turning (a tessellated
    silhouette's zig-zag), pieces longer than that do (a corner of the drawing)."""
    from mi_npr.strokes.chain import SHORT, chain_pieces

    assert SHORT == 1.0
    for size, expect in ((0.4, 1), (3.0, 10)):
        # ten pieces, each turning by 120 degrees from the last: a zig-zag along x
        angles = np.radians(np.where(np.arange(10) % 2 == 0, 60.0, -60.0))
        d = size * np.stack([np.cos(angles), np.sin(angles)], 1)
        node0, node1 = np.arange(10), np.arange(1, 11)
        chains = chain_pieces(node0, node1, np.zeros(10, int), d, -d, 60.0)
        assert len(chains) == expect, size
        assert sorted(p for steps, _ in chains for p, _ in steps) == list(range(10))


def test11_edges_and_rays_taken_in_small_batches_give_the_same_strokes(tmp_path, monkeypatch):
    """The extraction clips its edges :data:`EDGE_CHUNK` at a time, casts their samples in
    launches of whole edges of at most :data:`SAMPLES` samples (one edge alone when it has
    more) and its bisections' rays :data:`RAYS` a launch (memory bounds): batches of a few
    edges, samples and rays change nothing."""
    from mi_npr.strokes import extract, visibility

    scene = load(tmp_path, WALL + BOX + BALL)
    key = lambda s: (s.kind, s.qi, s.through_glass, np.round(s.points, 6).tobytes())  # noqa: E731
    whole = sorted(map(key, extract_strokes(scene, scene.sensors()[0], max_qi=2)))
    monkeypatch.setattr(extract, "EDGE_CHUNK", 5)
    monkeypatch.setattr(extract, "SAMPLES", 40)
    monkeypatch.setattr(visibility, "RAYS", 7)
    small = sorted(map(key, extract_strokes(scene, scene.sensors()[0], max_qi=2)))
    assert len(whole) > 5 and small == whole


def test12_extract_strokes_defaults_are_the_drawings():
    """``extract_strokes`` called without a parameter extracts what the ``strokes`` drawing
    does by default: its keyword defaults are the drawing's parameter table's."""
    import inspect

    from mi_npr.drawings import DRAWINGS

    drawing = DRAWINGS["strokes"].values({})
    sig = inspect.signature(extract_strokes).parameters
    for name in ("crease_angle", "chain_angle", "max_qi", "raytree_depth"):
        assert sig[name].default == drawing[name], name
    assert sig["max_qi"].default == 1


def _qi_by_brute_force(v, f, face_oid, glass_oids, origin, points, own, max_qi):
    """QI and through_glass of ``points`` by intersecting each eye segment with every
    triangle (Moller-Trumbore in float64), nearest first, as the module docstring counts."""
    from mi_npr.strokes.visibility import EPSILON

    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = b - a, c - a
    prim = np.arange(len(f)) - np.searchsorted(face_oid, face_oid)  # index within its object
    qi = np.zeros(len(points), np.int32)
    glass = np.zeros(len(points), bool)
    for k, p in enumerate(points):
        d = p - origin
        dist = np.linalg.norm(d)
        d = d / dist
        h = np.cross(d, e2)
        det = (e1 * h).sum(1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = origin - a
            u = (s * h).sum(1) / det
            q = np.cross(s, e1)
            w = (q * d).sum(1) / det
            t = (q * e2).sum(1) / det
        hit = (np.abs(det) > 1e-12) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 0)
        hit &= t < dist * (1 - EPSILON)
        for o0, p0 in own[k]:
            hit &= ~((face_oid == o0) & (prim == p0))
        for j in np.flatnonzero(hit)[np.argsort(t[hit])]:
            if qi[k] >= max_qi:
                break
            if face_oid[j] in glass_oids:
                glass[k] = True
            else:
                qi[k] += 1
    return qi, glass


def test13_a_scene_of_meshes_counts_as_the_brute_force_does(tmp_path, monkeypatch):
    """In a scene of meshes alone the QI loop runs on preliminary hits (no surface
    interaction): QI and through_glass of random points (in space, and on the faces, with
    those faces as their own) equal the brute force's over every triangle, and the loop
    over full surface interactions gives the same."""
    from mi_npr.scene import object_table
    from mi_npr.strokes import visibility as V
    from mi_npr.strokes.edges import mesh_arrays

    glass = (
        '<shape type="cube" id="pane"><bsdf type="dielectric"/><transform name="to_world">'
        '<scale x="0.7" y="0.5" z="0.05"/><translate x="0.1" y="0.6" z="3.5"/></transform>'
        "</shape>"
    )
    box2 = (
        BOX.replace('id="box"', 'id="box2"')
        .replace('x="-0.6"', 'x="0.3"')
        .replace('z="5"', 'z="6.5"')
    )
    scene = load(tmp_path, WALL + BOX + box2 + glass)
    table = object_table(scene)
    assert V.meshes_only(table)
    origin = np.array([0.3, 0.8, -0.5])  # test75's camera
    v, f, face_oid = mesh_arrays(table)
    v, f, face_oid = np.asarray(v, np.float64), np.asarray(f), np.asarray(face_oid)
    glass_oids = {table.id_of("pane")}
    rng = np.random.default_rng(3)
    space = rng.random((400, 3)) * [3.0, 2.0, 9.0] + [-1.5, -0.2, 1.0]
    tri = rng.integers(0, len(f), 300)
    bary = rng.dirichlet([1, 1, 1], 300)
    on = np.einsum("nk,nkj->nj", bary, v[f[tri]])
    first = np.searchsorted(face_oid, face_oid)
    points = np.concatenate([space, on])
    own = np.zeros((len(points), 2, 2), np.int64)
    own[len(space) :, 0, 0] = face_oid[tri]
    own[len(space) :, 0, 1] = tri - first[tri]
    for max_qi in (1, 8):
        ref = _qi_by_brute_force(v, f, face_oid, glass_oids, origin, points, own, max_qi)
        got = V.quantitative_invisibility(scene, table, origin, points, own, max_qi)
        monkeypatch.setattr(V, "meshes_only", lambda table: False)
        full = V.quantitative_invisibility(scene, table, origin, points, own, max_qi)
        monkeypatch.undo()
        assert ref[0].max() >= min(max_qi, 3) and ref[1].any()  # deep points, and glass
        for name, (q, g) in (("preliminary", got), ("surface interactions", full)):
            bad = np.flatnonzero((q != ref[0]) | (g != ref[1]))
            assert len(bad) == 0, (name, max_qi, bad, q[bad], ref[0][bad])


def _clip_by_loops(m, width, height, near, depth_row, a, b):
    """The frustum clip of one segment, written as loops (Liang-Barsky on the homogeneous
    coordinates): the interval (lo, hi) of ``a + s (b - a)`` with ``near <= depth``,
    ``0 <= X <= W``, ``0 <= Y <= W``."""
    with np.errstate(invalid="ignore"):  # an infinite end times a zero entry
        ha = [sum(a[k] * m[r][k] for k in range(3)) + m[r][3] for r in range(4)]
        hb = [sum(b[k] * m[r][k] for k in range(3)) + m[r][3] for r in range(4)]
    if not all(math.isfinite(x) for x in ha + hb):
        return None
    lo, hi = 0.0, 1.0
    bounds = [
        (ha[depth_row] - near, hb[depth_row] - near),
        (ha[0], hb[0]),
        (ha[3] - ha[0], hb[3] - hb[0]),
        (ha[1], hb[1]),
        (ha[3] - ha[1], hb[3] - hb[1]),
    ]
    for f0, f1 in bounds:
        d = f1 - f0
        if d > 0:
            lo = max(lo, -f0 / d)
        elif d < 0:
            hi = min(hi, -f0 / d)
        elif f0 < 0:
            return None
    return (lo, hi) if hi - lo > 1e-12 else None


def test14_the_frustum_clip_against_loops(tmp_path):
    """The extraction's clip (Dr.Jit, in double precision) against the same clip written as
    loops in the test, on random segments around a perspective and an orthographic camera:
    in front, behind, across the near plane and the frame's sides, along a bound, of zero
    length, with an end not finite; the same edges kept, in order, their clipped ends within
    1e-9, the ends the frustum did not cut marked whole, and the samples every half pixel (at
    least two); and, whatever the algorithm, the kept parts inside the frustum and the points
    just past a cut end outside it."""
    from mi_npr.strokes.edges import FeatureEdges, Projector
    from mi_npr.strokes.extract import SPACING, _clip

    rng = np.random.default_rng(5)
    ortho = (
        '<sensor type="orthographic"><transform name="to_world"><lookat origin="0, 0, -3" '
        'target="0, 0, 5" up="0, 1, 0"/><scale value="2"/></transform>'
        '<film type="hdrfilm"><integer name="width" value="61"/><integer name="height" '
        'value="37"/></film></sensor>'
    )
    for body in ("", ortho):
        scene = load(tmp_path, '<shape type="sphere"/>' + body)
        proj = Projector(scene.sensors()[len(scene.sensors()) - 1])
        assert proj.ortho == bool(body)
        n = 400
        a = rng.normal(0, 4, (n, 3)) + np.array([0.0, 0.0, 4.0])
        b = a + rng.normal(0, 3, (n, 3))
        b[:20] = a[:20]  # no length
        b[20:40, 2] = a[20:40, 2]  # along a depth bound
        a[40:60, 2] = proj.origin[2] + rng.uniform(-2, 0.005, 20)  # about the near plane
        a[60, 0], b[61, 1], a[62, 2] = np.nan, np.inf, -np.inf  # ends not finite: dropped
        z = np.zeros(n, np.int64)
        faces = np.zeros((n, 2, 2), np.int64)
        edges = FeatureEdges(a, b, z, z, z, z.astype(np.uint32), z.astype(np.uint32), faces)
        _, rows = _clip(proj, edges)
        want = []
        for i in range(n):
            got = _clip_by_loops(
                proj.matrix, proj.width, proj.height, proj.near, proj.depth_row, a[i], b[i]
            )
            if got is not None:
                want.append((i, *got))
        assert 20 < len(want) < n
        assert len(rows["A"]) == len(want)
        lo = np.array([w[1] for w in want])
        hi = np.array([w[2] for w in want])
        i = np.array([w[0] for w in want])
        np.testing.assert_allclose(rows["A"], a[i] + lo[:, None] * (b[i] - a[i]), atol=1e-9)
        np.testing.assert_allclose(rows["B"], a[i] + hi[:, None] * (b[i] - a[i]), atol=1e-9)
        assert rows["whole_a"].tolist() == (lo == 0).tolist()
        assert rows["whole_b"].tolist() == (hi == 1).tolist()
        xa, _ = proj.film(rows["A"])
        xb, _ = proj.film(rows["B"])
        length = np.hypot(*(xb - xa).T)
        np.testing.assert_allclose(rows["length"], length, rtol=1e-9, atol=1e-9)
        count = np.maximum(2, np.ceil(length / SPACING).astype(np.int64) + 1)
        assert np.abs(rows["count"] - count).max() <= 1  # (a length on a multiple of SPACING)
        assert (rows["count"] == count).mean() > 0.99
        # independently of the algorithm: the kept parts lie in the frustum (projected), and
        # just past a cut end a segment is outside it
        s = np.linspace(0.0, 1.0, 9)[:, None, None]
        inner = rows["A"][None] + s * (rows["B"] - rows["A"])[None]
        xy, depth = proj.film(inner.reshape(-1, 3))
        tol = 1e-6
        assert (depth >= proj.near - tol).all()
        assert ((xy >= -tol) & (xy <= np.array([proj.width, proj.height]) + tol)).all()
        for end, cut, step in ((lo, ~rows["whole_a"], -1e-6), (hi, ~rows["whole_b"], 1e-6)):
            past = a[i] + (end + step)[:, None] * (b[i] - a[i])
            pxy, pdepth = proj.film(past[cut])
            outside = (pdepth < proj.near) | (pxy < 0).any(1)
            outside |= (pxy > np.array([proj.width, proj.height])).any(1)
            assert outside.all()


def test15_launches_of_whole_edges():
    """The samples' launches: runs of whole edges of at most ``SAMPLES`` samples, an edge
    with more alone, every edge once, in order."""
    from mi_npr.strokes import extract

    rng = np.random.default_rng(2)
    for count in (np.array([3]), np.array([50, 2, 2]), rng.integers(2, 30, 200)):
        runs = extract._launch_bounds(count) if len(count) else []
        assert [e for e0, e1 in runs for e in range(e0, e1)] == list(range(len(count)))
        for e0, e1 in runs:
            assert count[e0:e1].sum() <= extract.SAMPLES or e1 - e0 == 1
    assert extract._launch_bounds(np.zeros(0, np.int64)) == []
    old = extract.SAMPLES
    try:
        extract.SAMPLES = 10
        assert extract._launch_bounds(np.array([4, 4, 4, 20, 1, 1])) == [
            (0, 2),
            (2, 3),
            (3, 4),
            (4, 6),
        ]
    finally:
        extract.SAMPLES = old


def test16_meshes_out_of_sight_give_no_stroke(tmp_path):
    """Meshes behind the camera, beside the frame, or cut by the near plane alone (every edge
    clipped away): no mesh stroke, no error; one edge in sight is enough for its strokes."""
    behind = (
        '<shape type="cube"><transform name="to_world"><scale value="0.3"/>'
        '<translate x="0.3" y="0.8" z="-3"/></transform></shape>'
    )
    aside = (
        '<shape type="cube"><transform name="to_world"><scale value="0.3"/>'
        '<translate x="40" y="0" z="5"/></transform></shape>'
    )
    scene = load(tmp_path, behind + aside)
    assert len(extract_strokes(scene, scene.sensors()[0], max_qi=2)) == 0
    scene = load(tmp_path, behind + aside + BOX)
    st = extract_strokes(scene, scene.sensors()[0], max_qi=2)
    assert len(st) > 0 and {st.name_of(int(s.object_id[0])) for s in st} == {"box"}
