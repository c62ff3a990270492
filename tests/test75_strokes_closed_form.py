"""Strokes against closed forms: a sphere's projected outline and a cube's projected corners.

The references are written here from the pinhole model of Mitsuba's ``perspective`` sensor
(:func:`mi_npr.raycast.pinhole_rays`'s docstring: pixel ``(x, y)`` looks along ``f + (1 - 2x/W)
tan(fov/2) left + (1 - 2y/H) tan(fov/2) H/W up``), inverted, and from the sphere's tangent
cone: nothing of mi_npr's projection or of the strokes' code.
"""

from __future__ import annotations

import itertools
import math

import mitsuba as mi
import numpy as np
import pytest

import mi_npr
from mi_npr.strokes import extract_strokes

from .helpers import scene_xml

W, H, FOV = 96, 72, 40.0
ORIGIN, TARGET, UP = np.array([0.3, 0.8, -0.5]), np.array([0.0, 0.0, 5.0]), np.array([0, 1, 0])


def project(p: np.ndarray) -> np.ndarray:
    """Film positions (N, 2) of world points (N, 3) (module docstring)."""
    f = (TARGET - ORIGIN) / np.linalg.norm(TARGET - ORIGIN)
    left = np.cross(UP, f)
    left /= np.linalg.norm(left)
    up = np.cross(f, left)
    v = np.asarray(p, np.float64) - ORIGIN
    z = v @ f
    tx = math.tan(math.radians(FOV) / 2)
    ty = tx * H / W
    x = W / 2 * (1 - (v @ left) / z / tx)
    y = H / 2 * (1 - (v @ up) / z / ty)
    return np.stack([x, y], -1)


def load(tmp_path, body: str) -> mi.Scene:
    path = tmp_path / "scene.xml"
    path.write_text(
        scene_xml(
            body,
            width=W,
            height=H,
            fov=FOV,
            origin=", ".join(map(str, ORIGIN)),
            target=", ".join(map(str, TARGET)),
        )
    )
    return mi_npr.load_scene(path)


def seg_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point p (N, 2) to the nearest of the segments a -> b (M, 2)."""
    ab = b - a
    ll = np.maximum((ab**2).sum(1), 1e-300)
    t = np.clip(((p[:, None, :] - a[None]) * ab[None]).sum(-1) / ll[None], 0, 1)
    q = a[None] + t[..., None] * ab[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(-1)).min(1)


def sphere_outline(c: np.ndarray, r: float, n: int = 20000) -> np.ndarray:
    """The projected outline of a sphere: the circle where the tangent cone from the camera
    touches it, sampled densely and projected."""
    v = c - ORIGIN
    L = np.linalg.norm(v)
    q = ORIGIN + v * (1 - r**2 / L**2)
    rho = r * math.sqrt(L**2 - r**2) / L
    e1 = np.cross(v, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(v / L, e1)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = q + rho * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)
    return project(pts)


def test01_sphere_silhouette_is_one_closed_stroke_on_the_analytic_outline(tmp_path):
    c, r = np.array([0.4, -0.3, 5.0]), 1.1
    scene = load(
        tmp_path,
        f'<shape type="sphere" id="ball"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
        f'<float name="radius" value="{r}"/></shape>',
    )
    st = extract_strokes(scene, scene.sensors()[0])
    assert [(s.kind, s.closed, s.qi, st.name_of(s.object_id[0])) for s in st] == [
        ("silhouette", True, 0, "ball")
    ]
    s = st[0]
    ref = sphere_outline(c, r)
    ring = np.concatenate([ref, ref[:1]])
    vert = seg_distance(s.points, ring[:-1], ring[1:])
    p = np.concatenate([s.points, s.points[:1]])
    mid = seg_distance(0.5 * (p[1:] + p[:-1]), ring[:-1], ring[1:])
    print(f"sphere: max vertex error {vert.max():.5f} px, max chord error {mid.max():.5f} px")
    assert vert.max() < 0.05 and mid.max() < 0.05
    # the whole outline, not a piece of it: same length within 0.5 %
    ref_len = np.hypot(*np.diff(ring, axis=0).T).sum()
    assert abs(s.length() - ref_len) < 0.005 * ref_len
    # per-vertex attributes: on the sphere, at its depth
    assert np.allclose(np.linalg.norm(s.position - c, axis=1), r, atol=1e-3)
    f = (TARGET - ORIGIN) / np.linalg.norm(TARGET - ORIGIN)
    assert np.allclose(s.depth, (s.position - ORIGIN) @ f, atol=1e-4)
    # beside the limb: the background, at +inf
    assert np.all(np.isinf(s.depth_behind))


#: The cube's pose: rotate 35 deg about y, then 25 deg about x, scale 0.9, translate.
CUBE = '<shape type="cube" id="box"><transform name="to_world">{}</transform></shape>'
POSE = (
    '<rotate y="1" angle="35"/><rotate x="1" angle="25"/><scale value="0.9"/>'
    '<translate x="0.2" y="-0.1" z="5"/>'
)


def cube_geometry() -> tuple[np.ndarray, list[tuple[int, int]], dict]:
    """Corners (8, 3), edges (index pairs) and, per edge, its two face normals."""
    T = (
        mi.ScalarTransform4f()
        .translate([0.2, -0.1, 5])
        .scale(0.9)
        .rotate([1, 0, 0], 25)
        .rotate([0, 1, 0], 35)
    )
    m = np.asarray(T.matrix, np.float64)
    corners_local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    corners = corners_local @ m[:3, :3].T + m[:3, 3]
    edges, faces = [], {}
    for i in range(8):
        for j in range(i + 1, 8):
            diff = corners_local[i] != corners_local[j]
            if diff.sum() == 1:
                edges.append((i, j))
                fixed = np.flatnonzero(~diff)
                normals = []
                for k in fixed:
                    n = np.zeros(3)
                    n[k] = corners_local[i][k]
                    normals.append(m[:3, :3] @ n)
                faces[(i, j)] = normals
    return corners, edges, faces


def test02_cube_strokes_end_on_the_projected_corners(tmp_path):
    scene = load(tmp_path, CUBE.format(POSE))
    st = extract_strokes(scene, scene.sensors()[0])
    corners, edges, faces = cube_geometry()
    px = project(corners)
    worst = 0.0
    covered: dict[tuple[int, int], list] = {}
    for s in st:
        d = np.hypot(*(s.points[:, None, :] - px[None]).transpose(2, 0, 1))
        nearest = d.argmin(1)
        worst = max(worst, float(d.min(1).max()))
        # every segment of a stroke is one whole cube edge
        seg = list(itertools.pairwise(nearest))
        if s.closed:
            seg.append((nearest[-1], nearest[0]))
        for a, b in seg:
            key = (min(a, b), max(a, b))
            assert key in faces, f"segment {key} is no cube edge"
            covered.setdefault(key, []).append(s)
    print(f"cube: max corner error {worst:.2e} px")
    assert worst < 0.05
    assert sorted(covered) == sorted(edges)  # all 12 edges...
    assert all(len(v) == 1 for v in covered.values())  # ...each drawn once
    for key, (s,) in covered.items():
        front = [float(n @ (corners[key[0]] - ORIGIN)) < 0 for n in faces[key]]
        if sum(front) == 1:
            assert (s.kind, s.qi) == ("silhouette", 0), key
        else:
            hidden = not any(front)
            assert s.kind == "crease" and s.qi == (1 if hidden else 0), key
    assert sum(1 for v in covered.values() if v[0].qi == 1) == 3  # a generic view: 3 hidden


@pytest.mark.parametrize("chain_angle", [0.0, 180.0])
def test03_chain_angle_joins_or_splits_the_outline(tmp_path, chain_angle):
    scene = load(tmp_path, CUBE.format(POSE))
    st = extract_strokes(scene, scene.sensors()[0], chain_angle=chain_angle)
    sil = st.of_kind("silhouette")
    if chain_angle == 0:  # every corner breaks: one stroke per silhouette edge
        assert len(sil) == 6 and all(len(s) == 2 for s in sil)
    else:  # the hexagonal outline of a cube is one closed stroke
        assert len(sil) == 1 and sil[0].closed and len(sil[0]) == 6


def test04_moved_vertices_are_seen_by_the_next_extraction(tmp_path):
    """The meshes' topology is kept between extractions of one scene; vertex positions
    updated through ``mi.traverse`` must not be answered from it: after the cube is shrunk
    in place about its centre, its strokes end on the shrunk cube's projected corners."""
    scene = load(tmp_path, CUBE.format(POSE))
    extract_strokes(scene, scene.sensors()[0])
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("vertex_positions"))
    v = np.asarray(params[key].numpy(), np.float64).reshape(-1, 3)
    centre = np.array([0.2, -0.1, 5.0])
    params[key] = mi.Float(((v - centre) * 0.5 + centre).astype(np.float32).reshape(-1))
    params.update()
    st = extract_strokes(scene, scene.sensors()[0])
    corners, _, _ = cube_geometry()
    px = project((corners - centre) * 0.5 + centre)
    pts = np.concatenate([s.points for s in st])
    d = np.hypot(*(pts[:, None, :] - px[None]).transpose(2, 0, 1))
    assert d.min(1).max() < 0.05  # every vertex on a corner of the shrunk cube...
    assert len(set(d.argmin(1).tolist())) == 8  # ...and every corner reached


def test05_a_thin_lens_draws_the_pinhole_at_its_lens_centre(tmp_path):
    """A thin-lens camera (a wide aperture, focused elsewhere) has the strokes of the pinhole at
    its lens centre, where the G-buffer's pixel rays pass: the cube's visible corners on their
    projections, the same strokes as the perspective camera's."""
    path = tmp_path / "scene.xml"
    load(tmp_path, CUBE.format(POSE))  # writes scene.xml with the perspective camera
    text = path.read_text()
    lens = (
        '<sensor type="thinlens"><float name="aperture_radius" value="0.3"/>'
        '<float name="focus_distance" value="2.0"/>'
    )
    path.write_text(text.replace('<sensor type="perspective">', lens, 1))
    assert 'type="thinlens"' in path.read_text()
    thin = mi_npr.load_scene(path)
    assert thin.sensors()[0].class_name() == "ThinLensCamera"
    pin = load(tmp_path, CUBE.format(POSE))
    a = extract_strokes(thin, thin.sensors()[0])
    b = extract_strokes(pin, pin.sensors()[0])
    assert [(s.kind, s.qi, len(s)) for s in a] == [(s.kind, s.qi, len(s)) for s in b]
    for s, t in zip(a, b, strict=True):
        np.testing.assert_allclose(s.points, t.points, atol=1e-4)
    corners = project(cube_geometry()[0])
    ends = np.concatenate([s.points for s in a if s.qi == 0])
    assert np.hypot(*(ends[:, None] - corners[None]).transpose(2, 0, 1)).min(1).max() < 0.05


def test06_an_orthographic_cube_ends_on_its_projected_corners(tmp_path):
    """An orthographic camera (``to_world``: a scale of 2.5 then the look-at): its rays are
    parallel, so the cube's visible edges end on the corners' parallel projections (film
    ``x = (1 - c_x) / 2 W``, ``y = (1 - (W / H) c_y) / 2 H`` of camera-space ``c``, Mitsuba's
    ``orthographic``), each edge once, the three facing away hidden (QI 1), silhouettes where
    one face turns away from the view axis, and each vertex's depth its distance along it."""
    import re

    scale = 2.5
    load(tmp_path, CUBE.format(POSE))
    path = tmp_path / "scene.xml"
    text = re.sub(
        r'<sensor type="perspective">\s*<float name="fov" value="[^"]*"/>',
        '<sensor type="orthographic">',
        path.read_text(),
    )
    text = text.replace("<lookat", f'<scale x="{scale}" y="{scale}"/><lookat', 1)
    path.write_text(text)
    scene = mi_npr.load_scene(path)
    assert scene.sensors()[0].class_name() == "OrthographicCamera"
    st = extract_strokes(scene, scene.sensors()[0])
    f = (TARGET - ORIGIN) / np.linalg.norm(TARGET - ORIGIN)
    left = np.cross(UP, f)
    left /= np.linalg.norm(left)
    up = np.cross(f, left)

    def film(p: np.ndarray) -> np.ndarray:
        v = np.asarray(p, np.float64) - ORIGIN
        cx, cy = v @ left / scale, v @ up / scale
        return np.stack([(1 - cx) / 2 * W, (1 - (W / H) * cy) / 2 * H], -1)

    corners, edges, faces = cube_geometry()
    px = film(corners)
    covered: dict[tuple[int, int], list] = {}
    for s in st:
        d = np.hypot(*(s.points[:, None, :] - px[None]).transpose(2, 0, 1))
        assert d.min(1).max() < 0.05  # every vertex on a projected corner
        np.testing.assert_allclose(s.depth, (s.position - ORIGIN) @ f, atol=1e-5)
        near = d.argmin(1)
        seg = list(itertools.pairwise(near)) + ([(near[-1], near[0])] if s.closed else [])
        for a, b in seg:
            covered.setdefault((min(a, b), max(a, b)), []).append(s)
    assert sorted(covered) == sorted(edges)
    assert all(len(v) == 1 for v in covered.values())
    for key, (s,) in covered.items():
        front = [float(n @ f) < 0 for n in faces[key]]
        if sum(front) == 1:
            assert (s.kind, s.qi) == ("silhouette", 0), key
        else:
            assert s.kind == "crease" and s.qi == (0 if any(front) else 1), key
    assert sum(1 for v in covered.values() if v[0].qi == 1) == 3
