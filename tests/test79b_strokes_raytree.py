"""Reflection, refraction and shadow strokes (ray-tree edge classes traced) against closed forms.

References, written here: a planar mirror shows a sphere as the sphere mirrored across its
plane (so the reflection's outline is that sphere's projected outline); a point light's shadow
of a sphere on a floor is the tangent cone from the light cut by the floor's plane, projected.
Both through test75's pinhole model, nothing of mi_npr's projection.
"""

from __future__ import annotations

import math

import numpy as np

from mi_npr.camera.sensor import projection_of
from mi_npr.scene import object_table
from mi_npr.strokes.raytree import raytree_strokes

from .test75_strokes_closed_form import load, project, seg_distance, sphere_outline

#: A vertex is a pixel centre of the marked band: within half a diagonal of the change.
HALF_DIAGONAL = math.sqrt(2) / 2


def ball(c, r, extra=""):
    return (
        f'<shape type="sphere" id="ball"><point name="center" value="{c[0]}, {c[1]}, {c[2]}"/>'
        f'<float name="radius" value="{r}"/>{extra}</shape>'
    )


def strokes(scene, depth=2):
    sensor = scene.sensors()[0]
    return raytree_strokes(scene, sensor, object_table(scene), projection_of(sensor), depth)


def ring(points):
    return np.concatenate([points, points[:1]])


def test01_a_mirror_shows_the_mirrored_sphere(tmp_path):
    c, r, x_mirror = np.array([0.1, 0.0, 6.0]), 0.4, 0.9
    mirror = (
        '<shape type="rectangle" id="mirror"><bsdf type="conductor"/><transform name="to_world">'
        f'<scale x="4.5" y="2"/><rotate y="1" angle="-90"/><translate x="{x_mirror}" y="0" '
        'z="4.75"/></transform></shape>'
    )
    st = strokes(load(tmp_path, ball(c, r) + mirror))
    virtual = c.copy()
    virtual[0] = 2 * x_mirror - c[0]
    ref = ring(sphere_outline(virtual, r))
    assert [(s.kind, s.closed, s.qi, s.through_glass) for s in st] == [
        ("reflection", True, 0, False)
    ]
    err = seg_distance(st[0].points, ref[:-1], ref[1:]).max()
    assert err <= HALF_DIAGONAL, err
    # the stroke goes all the way round: every part of the analytic outline has a vertex near
    dense = ref[::50]
    back = seg_distance(dense, ring(st[0].points)[:-1], ring(st[0].points)[1:]).max()
    assert back <= 1.0, back
    # its vertices lie on the mirror (the surface the reflection is seen on)
    names = object_table(load(tmp_path, ball(c, r) + mirror)).names
    assert {names[int(i)] for i in st[0].object_id} == {"mirror"}
    assert np.allclose(st[0].position[:, 0], x_mirror, atol=1e-3)


def shadow_outline(c, r, light, floor_y, n=4000):
    """The shadow of a sphere on the plane y = floor_y from a point light, and the sphere's
    terminator (where the light's tangent cone touches it: its own shadow), projected."""
    v = c - light
    L = np.linalg.norm(v)
    q = light + v * (1 - r**2 / L**2)
    rho = r * math.sqrt(L**2 - r**2) / L
    e1 = np.cross(v, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(v / L, e1)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    tangent = q + rho * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)
    d = tangent - light
    t = (floor_y - light[1]) / d[:, 1]
    return project(light + t[:, None] * d), project(tangent)


def test02_a_point_light_casts_the_analytic_shadow(tmp_path):
    c, r, light, floor_y = np.array([0.3, -0.3, 5.0]), 0.35, np.array([0.8, 2.5, 4.0]), -1.0
    body = (
        ball(c, r)
        + '<shape type="rectangle" id="floor"><transform name="to_world"><scale value="8"/>'
        f'<rotate x="1" angle="-90"/><translate y="{floor_y}" z="5"/></transform></shape>'
        f'<emitter type="point"><point name="position" value="{light[0]}, {light[1]}, '
        f'{light[2]}"/></emitter>'
    )
    st = strokes(load(tmp_path, body), depth=1)
    shadows = [s for s in st if s.kind == "shadow"]
    assert shadows and all(s.qi == 0 for s in shadows)
    cast, terminator = (ring(p) for p in shadow_outline(c, r, light, floor_y))
    on_floor = [s for s in shadows if np.allclose(s.position[:, 1], floor_y, atol=1e-3)]
    on_ball = [s for s in shadows if s not in on_floor]
    # the cast shadow: one closed stroke on the floor, on the analytic curve
    assert [s.closed for s in on_floor] == [True]
    err = seg_distance(on_floor[0].points, cast[:-1], cast[1:]).max()
    assert err <= HALF_DIAGONAL, err
    # the ball's own shadow line: on its terminator
    assert on_ball
    for s in on_ball:
        assert np.allclose(np.linalg.norm(s.position - c, axis=1), r, atol=1e-3)
        err = seg_distance(s.points, terminator[:-1], terminator[1:]).max()
        assert err <= HALF_DIAGONAL, err


def test03_nothing_to_reflect_gives_no_strokes(tmp_path):
    assert strokes(load(tmp_path, ball(np.array([0.0, 0.0, 6.0]), 0.5))) == []
