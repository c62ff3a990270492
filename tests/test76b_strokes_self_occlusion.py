"""Self-occlusion outlines of shapes that are not meshes: an outline in front of the same object.

References: test75's pinhole model (:func:`project`) and tangent cone (:func:`sphere_outline`),
a rim circle and a disk written here in closed form, test76's brute-force check for strokes
drawn twice, and the ``lines`` drawing's eq. 5.1 (its ink image) for which depth steps exist.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mi_npr.strokes import extract_strokes

from .test75_strokes_closed_form import load, project, seg_distance, sphere_outline
from .test76_strokes_visibility import longest_double, polylines

#: An open tube (Mitsuba's ``cylinder`` has no caps) whose top faces the camera at about 55
#: degrees: its rim is seen whole, the front half of it in front of the tube's inner wall.
AXIS = np.array([0.0, math.cos(math.radians(26)), -math.sin(math.radians(26))])
TOP, RADIUS, LENGTH = np.array([0.0, 0.35, 2.6]), 0.6, 1.0


def tube(flip: bool) -> str:
    bottom = TOP - LENGTH * AXIS
    return (
        f'<shape type="cylinder" id="tube"><point name="p0" value="{", ".join(map(str, bottom))}"/>'
        f'<point name="p1" value="{", ".join(map(str, TOP))}"/>'
        f'<float name="radius" value="{RADIUS}"/>'
        f'<boolean name="flip_normals" value="{str(flip).lower()}"/></shape>'
    )


def circle(centre: np.ndarray, normal: np.ndarray, r: float, t: np.ndarray) -> np.ndarray:
    """Points (N, 3) of the circle of radius ``r`` about ``centre`` in the plane of ``normal``
    at angles ``t`` (N,) from the direction of x projected into that plane."""
    e1 = np.array([1.0, 0.0, 0.0]) - normal[0] * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return centre + r * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)


def ring(points: np.ndarray) -> np.ndarray:
    return np.concatenate([points, points[:1]])


@pytest.mark.parametrize("flip", [False, True])
def test01_the_rim_of_an_open_cylinder_is_drawn_on_its_projected_circle(tmp_path, flip):
    """The tube's top rim, seen from above at an angle, its normals out or in: its back half
    against the background (an id outline), its front half in front of the tube's inner wall
    (the same object on both sides). Every vertex lies within 0.01 px of the projected circle
    (measured: 4e-5 px), every chord within 0.05 px (Douglas-Peucker's 0.02 px and the
    curvature), and nothing is drawn twice."""
    scene = load(tmp_path, tube(flip))
    st = extract_strokes(scene, scene.sensors()[0])
    t = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    rim3 = circle(TOP, AXIS, RADIUS, t)
    rim = ring(project(rim3))
    near = [seg_distance(s.points, rim[:-1], rim[1:]).max() < 0.5 for s in st]
    on_rim = [s for s, n in zip(st, near, strict=True) if n]
    assert on_rim and {s.kind for s in on_rim} <= {"border", "silhouette"}
    pts = np.concatenate([s.points for s in on_rim])
    vert = seg_distance(pts, rim[:-1], rim[1:])
    mid = np.concatenate([0.5 * (p[1:] + p[:-1]) for p in polylines(on_rim)])
    chord = seg_distance(mid, rim[:-1], rim[1:])
    print(f"rim: max vertex error {vert.max():.5f} px, max chord error {chord.max():.5f} px")
    assert vert.max() < 0.01 and chord.max() < 0.05
    # the vertices' 3-D positions: the near side, seen a probe's distance (a few hundredths of
    # a pixel) inside the rim: on the tube's wall, just below the rim
    pos = np.concatenate([s.position for s in on_rim])
    height = (pos - TOP) @ AXIS
    off_radius = np.abs(np.linalg.norm(pos - TOP - height[:, None] * AXIS, axis=1) - RADIUS)
    print(f"rim: 3-D positions {-height.min():.4f} below the rim at most")
    assert off_radius.max() < 1e-4 and np.all(height < 1e-6) and height.min() > -0.01

    # the whole rim is visible: every point of it is on a stroke, except where it runs
    # between the pixel centres and the side outline, within a pixel of it (next to the
    # points where the rim touches the side outlines)
    samples = rim[:-1][::10]
    covered = seg_distance(samples, *_segments(polylines(st))) < 0.05
    sides = [p for n, p in zip(near, polylines(st), strict=True) if not n]
    beside = seg_distance(samples, *_segments(sides)) < 1.0
    assert np.all(covered | beside)
    gap = np.hypot(*np.diff(samples, axis=0).T)[~covered[:-1]].sum()
    print(f"rim: {gap:.2f} px of its {np.hypot(*np.diff(rim, axis=0).T).sum():.1f} px not drawn")
    assert gap < 8.0

    # its front half, in front of the inner wall: a border with the tube behind it
    front = [s for s in on_rim if np.all(np.isfinite(s.depth_behind))]
    assert front and {s.kind for s in front} <= {"border", "silhouette"}
    assert sum(s.length() for s in front if s.kind == "border") > 20.0
    assert np.all(np.concatenate([s.object_id for s in on_rim]) == st[0].object_id[0])

    worst = longest_double(st)
    print(f"longest stretch of two strokes within 0.5 px: {worst:.2f} px")
    assert worst <= 2.0


def _segments(lines: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The segments (a, b) of polylines, all in two arrays (M, 2)."""
    lines = [p for p in lines if len(p) > 1]
    return np.concatenate([p[:-1] for p in lines]), np.concatenate([p[1:] for p in lines])


#: One object of three shapes (a shape group): a small sphere in front of a large one, and a
#: disk in front of the large one (scaled by 0.4, turned 30 degrees about x).
NEAR_C, NEAR_R = np.array([0.35, 0.15, 4.0]), 0.45
FAR_C, FAR_R = np.array([-0.3, -0.1, 5.5]), 0.9
DISK_C, DISK_R, DISK_N = np.array([-0.55, -0.6, 4.2]), 0.4, np.array([0, -0.5, math.sqrt(0.75)])
GROUP = (
    '<shape type="shapegroup" id="group">'
    + "".join(
        f'<shape type="sphere"><point name="center" value="{", ".join(map(str, c))}"/>'
        f'<float name="radius" value="{r}"/></shape>'
        for c, r in ((NEAR_C, NEAR_R), (FAR_C, FAR_R))
    )
    + '<shape type="disk"><transform name="to_world"><scale value="0.4"/>'
    f'<rotate x="1" angle="30"/><translate value="{", ".join(map(str, DISK_C))}"/>'
    '</transform></shape></shape><shape type="instance" id="both"><ref id="group"/></shape>'
)


def test02_shapes_of_one_object_in_front_of_each_other(tmp_path):
    """In one object, a sphere's limb in front of another sphere is a silhouette and a disk's
    rim in front of it a border, each on its closed-form outline; the outlines against the
    background continue them, and nothing is drawn twice."""
    scene = load(tmp_path, GROUP)
    st = extract_strokes(scene, scene.sensors()[0])
    t = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    near = ring(sphere_outline(NEAR_C, NEAR_R))
    far = ring(sphere_outline(FAR_C, FAR_R))
    disk = ring(project(circle(DISK_C, DISK_N, DISK_R, t)))

    def on(s, *refs):  # distance of each vertex of stroke s to the nearest of refs
        return np.min([seg_distance(s.points, r[:-1], r[1:]) for r in refs], axis=0)

    err = max(on(s, near, far, disk).max() for s in st)
    print(f"one object: max vertex error {err:.5f} px")
    assert err < 0.01  # every vertex on one of the three outlines
    assert {s.kind for s in st} == {"silhouette", "border"}
    # kinds by vertex (an open stroke's ends may be where the next kind begins)
    body = lambda d, s: d if s.closed else d[1:-1]  # noqa: E731
    assert all(np.all(body(on(s, near, far), s) < 0.01) for s in st if s.kind == "silhouette")
    assert all(np.all(body(on(s, disk), s) < 0.01) for s in st if s.kind == "border")
    # the outlines in front of the large sphere, which lies 1 px beside them (but at their
    # ends, where they reach the background)
    for ref, least in ((near, 40.0), (disk, 20.0)):
        front = [s for s in st if body(np.isinf(s.depth_behind), s).sum() == 0]
        assert sum(s.length() for s in front if on(s, ref).max() < 0.01) > least
    # the small sphere's and the disk's outlines are drawn whole, but next to where they
    # cross the large sphere's outline (where one kind of outline ends and the other begins)
    for ref in (near, disk):
        samples = ref[:-1][::20]
        covered = seg_distance(samples, *_segments(polylines(st))) < 0.05
        junction = seg_distance(samples, far[:-1], far[1:]) < 1.5
        assert np.all(covered | junction)
    worst = longest_double(st)
    print(f"longest stretch of two strokes within 0.5 px: {worst:.2f} px")
    assert worst <= 2.0


def test03_depth_steps_are_the_lines_drawings():
    """The steps the self-occlusion outlines start from: 4-neighbours of one id (not 0) whose
    depths, normalised as the ``lines`` drawing's (nearest finite ``Z`` -> 0, the larger of the
    farthest and 4x the nearest -> 1), differ by more than eq. 5.1's ``t / c``, near pixel
    first; every near pixel is inked by the drawing's eq. 5.1."""
    from mi_npr.kernels import lines
    from mi_npr.kernels.chain import LINES_PARAMS
    from mi_npr.strokes.outlines import step_cracks

    p = {q.name: q.default for q in LINES_PARAMS}
    rng = np.random.default_rng(5)
    for h, w in ((1, 1), (1, 7), (9, 5), (30, 40)):
        z = rng.uniform(2.0, 9.0, (h, w)).astype(np.float32)
        z[rng.random((h, w)) < 0.2] = np.inf  # the background
        ids = rng.integers(0, 3, (h, w)).astype(np.uint32)
        near, far = step_cracks(ids, z)
        lo = z[np.isfinite(z)].min()
        span = max(z[np.isfinite(z)].max(), 4 * lo) - lo
        D = np.where(np.isfinite(z), (z.astype(np.float64) - lo) / span, 2.0)
        ref = set()
        for y in range(h):
            for x in range(w):
                for dx, dy in ((1, 0), (0, 1), (-1, 0), (0, -1)):
                    u, v = x + dx, y + dy
                    if 0 <= u < w and 0 <= v < h and ids[y, x] == ids[v, u] != 0:
                        if D[v, u] - D[y, x] > p["t"] / p["c"]:
                            ref.add(((x, y), (u, v)))
        got = {(tuple(a), tuple(b)) for a, b in zip(near.tolist(), far.tolist(), strict=True)}
        assert got == ref
        ink = np.asarray(
            lines({"Z": z}, dilation_iterations=0, remove_isolated=False, crease_angle=0.0)
        )
        assert all(ink[y, x] > 0 for (x, y), _ in got)
    assert len(ref) > 20  # the last image has steps


LONE_BALL = '<shape type="sphere" id="ball"><float name="radius" value="1"/></shape>'
#: The same sphere as the one shape of an instance: an instance may group several shapes, so
#: its depth steps are located, and refused as a smooth surface's.
GROUPED_BALL = (
    '<shape type="shapegroup" id="g"><shape type="sphere"><float name="radius" value="1"/>'
    '</shape></shape><shape type="instance" id="ball"><ref id="g"/></shape>'
)


@pytest.mark.parametrize("body", [LONE_BALL, GROUPED_BALL], ids=["sphere", "instance"])
def test04_a_sphere_close_to_the_camera_gains_no_stroke(tmp_path, body):
    """A sphere filling most of a wide view: between the pixels next to its limb the depth
    steps as much as the ``lines`` drawing's depth lines do, but the surface is smooth there,
    so its outline stays one closed silhouette. A lone sphere is never looked at for steps
    (it cannot hide a part of itself); as an instance's shape, its steps are refused."""
    import mi_npr
    from mi_npr.scene import object_table
    from mi_npr.strokes.outlines import can_self_occlude, step_cracks

    from .helpers import scene_xml

    path = tmp_path / "ball.xml"
    path.write_text(scene_xml(body, width=160, height=120, fov=90.0, origin="0, 0, -2"))
    scene = mi_npr.load_scene(path)
    st = extract_strokes(scene, scene.sensors()[0])
    assert [(s.kind, s.closed) for s in st] == [("silhouette", True)]
    assert can_self_occlude(object_table(scene))[1] == (body is GROUPED_BALL)
    # the steps were there: the depth of the pixel-centre hits, 0 where they miss
    gb = mi_npr.render(path, width=160, height=120, spp=1)
    z = gb.numpy("Z")
    ids = (np.isfinite(z)).astype(np.uint32)
    assert len(step_cracks(ids, z)[0]) > 20


def test05_a_rim_seen_at_a_fine_resolution_is_one_stroke(tmp_path):
    """At 960 x 720 the intersections of rays grazing a tube's rim flip between its two sides
    within about 0.002 px of it, and the rim passes through pixel centres where it is level:
    its front half, in front of the inner wall, is still one border, with a silhouette at
    each end (where the wall inside the rim turns away) joined to it."""
    import mi_npr

    from .helpers import scene_xml

    path = tmp_path / "tube.xml"
    body = (
        '<shape type="cylinder" id="tube"><point name="p0" value="0, 0, 0"/>'
        '<point name="p1" value="0, 1, 0"/><float name="radius" value="0.5"/></shape>'
    )
    kw = dict(width=960, height=720, fov=30.0, origin="0.3, 3.0, -5.2", target="0, 0.5, 0")
    path.write_text(scene_xml(body, **kw))
    scene = mi_npr.load_scene(path)
    st = extract_strokes(scene, scene.sensors()[0])
    front = [s for s in st if np.isfinite(s.depth_behind).mean() > 0.5]  # the tube behind
    assert sorted(s.kind for s in front) == ["border", "silhouette", "silhouette"]
    (rim,) = (s for s in front if s.kind == "border")
    assert rim.length() > 250.0
    ends = np.concatenate([s.points[[0, -1]] for s in front if s.kind == "silhouette"])
    for p in rim.points[[0, -1]]:
        assert np.hypot(*(ends - p).T).min() < 1e-9


@pytest.mark.parametrize("size", [(960, 720), (1280, 960)])
def test06_a_cylinders_sides_are_one_stroke_each(tmp_path, size):
    """Rays grazing a cylinder's side flip between hit and miss within a band that, in pixels,
    widens with the resolution: the vertices there are probed again farther out, so each side
    is one silhouette along the whole tube, on the projected tangent line (the vertical
    generator whose normal is perpendicular to the view ray)."""
    import mi_npr
    from mi_npr.strokes.edges import Projector

    from .helpers import scene_xml

    path = tmp_path / "tube.xml"
    body = (
        '<shape type="cylinder" id="tube"><point name="p0" value="0, 0, 0"/>'
        '<point name="p1" value="0, 1, 0"/><float name="radius" value="0.5"/></shape>'
    )
    eye = np.array([0.3, 3.0, -5.2])
    kw = dict(width=size[0], height=size[1], fov=30.0, origin="0.3, 3.0, -5.2", target="0, 0.5, 0")
    path.write_text(scene_xml(body, **kw))
    scene = mi_npr.load_scene(path)
    sensor = scene.sensors()[0]
    st = extract_strokes(scene, sensor)
    # the tangent generators: x^2 + z^2 = r^2 with (p - eye) . p = 0 in the xz plane
    d, r = math.hypot(eye[0], eye[2]), 0.5
    base, spread = math.atan2(eye[2], eye[0]), math.acos(r / d)
    proj = Projector(sensor)
    sides = []
    for phi in (base - spread, base + spread):
        ends = np.array([[r * math.cos(phi), y, r * math.sin(phi)] for y in (0.0, 1.0)])
        sides.append(proj.film(ends)[0])
    long = [s for s in st if s.kind == "silhouette" and s.length() > 0.2 * size[1]]
    assert len(long) == 2
    for s, side in zip(
        sorted(long, key=lambda s: s.points[:, 0].mean()),
        sorted(sides, key=lambda a: a[:, 0].mean()),
        strict=True,
    ):
        top, bottom = side[:, 1].min(), side[:, 1].max()
        # it runs on round the rims' ends, where their inner walls graze: beyond the side
        assert s.points[:, 1].min() < top + 1.0 and s.points[:, 1].max() > bottom - 1.0
        t = np.linspace(0.0, 1.0, 64)[:, None]
        dense = np.concatenate([a + t * (b - a) for a, b in itertools.pairwise(s.points)])
        along = dense[(dense[:, 1] > top + 5.0) & (dense[:, 1] < bottom - 5.0)]
        assert len(along) > 32
        err = seg_distance(along, side[:1], side[1:]).max()
        assert err < 0.05, err
