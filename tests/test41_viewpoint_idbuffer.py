"""Batched ID buffers: per-polygon areas of many viewpoints in one launch, against a per-view loop
of ordinary Mitsuba sensors rendered through mi-npr's G-buffer pass."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.camera import view_frame
from mi_npr.meshes import uv_sphere, write_ply
from mi_npr.viewpoint import areas, polygons

MIXED = (
    '<shape type="ply" id="ball"><string name="filename" value="{ply}"/></shape>'
    '<shape type="cube" id="box"><transform name="to_world"><scale value="0.4"/>'
    '<translate x="1.3" y="0.2" z="0.3"/></transform></shape>'
    '<shape type="sphere" id="analytic"><point name="center" x="-1.2" y="0.4" z="-0.5"/>'
    '<float name="radius" value="0.45"/></shape>'
    '<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>'
    '<scale value="2.2"/><translate y="-1.1"/></transform></shape>'
)

INSTANCED = (
    '<shape type="shapegroup" id="pair">'
    '<shape type="ply" id="pair_ball"><string name="filename" value="{ply}"/>'
    '<transform name="to_world"><scale value="0.35"/><translate x="-0.4"/></transform></shape>'
    '<shape type="cube" id="pair_box"><transform name="to_world"><scale value="0.25"/>'
    '<translate x="0.45"/></transform></shape>'
    '<shape type="sphere" id="pair_dot"><point name="center" x="0" y="0.5" z="0"/>'
    '<float name="radius" value="0.12"/></shape>'
    "</shape>"
    '<shape type="instance" id="inst_a"><ref id="pair"/>'
    '<transform name="to_world"><translate y="0.6"/></transform></shape>'
    '<shape type="instance" id="inst_b"><ref id="pair"/>'
    '<transform name="to_world"><rotate y="1" angle="30"/><scale value="1.3"/>'
    '<translate y="-0.6"/></transform></shape>'
)

# The same objects written out without instancing (children in the group's order).
EXPANDED = (
    '<shape type="ply" id="a1"><string name="filename" value="{ply}"/>'
    '<transform name="to_world"><scale value="0.35"/><translate x="-0.4"/>'
    '<translate y="0.6"/></transform></shape>'
    '<shape type="cube" id="a2"><transform name="to_world"><scale value="0.25"/>'
    '<translate x="0.45"/><translate y="0.6"/></transform></shape>'
    '<shape type="sphere" id="a3"><float name="radius" value="0.12"/><transform name="to_world">'
    '<translate y="0.5"/><translate y="0.6"/></transform></shape>'
    '<shape type="ply" id="b1"><string name="filename" value="{ply}"/>'
    '<transform name="to_world"><scale value="0.35"/><translate x="-0.4"/>'
    '<rotate y="1" angle="30"/><scale value="1.3"/><translate y="-0.6"/></transform></shape>'
    '<shape type="cube" id="b2"><transform name="to_world"><scale value="0.25"/>'
    '<translate x="0.45"/><rotate y="1" angle="30"/><scale value="1.3"/>'
    '<translate y="-0.6"/></transform></shape>'
    '<shape type="sphere" id="b3"><float name="radius" value="0.12"/><transform name="to_world">'
    '<translate y="0.5"/><rotate y="1" angle="30"/><scale value="1.3"/>'
    '<translate y="-0.6"/></transform></shape>'
)


@pytest.fixture
def ply(tmp_path):
    return write_ply(tmp_path / "ball.ply", *uv_sphere(10, 7, 0.8))


def _scene(write_scene, body, name="scene.xml"):
    return mi_npr.load_scene(write_scene(body, name=name))


def brute_numbering(scene):
    """Polygon numbering from the object table alone: objects by id, mesh triangles in order,
    one polygon per non-mesh shape (no instances here)."""
    table = mi_npr.object_table(scene)
    base, n = {}, 0
    for oid in sorted(table.shapes):
        s = table.shapes[oid]
        base[oid] = n
        n += s.face_count() if s.is_mesh() else 1
    return table, base, n


def gbuffer_areas(scene, gb):
    """Per-polygon pixel counts of a G-buffer's object_id / prim_id, numbered by hand."""
    table, base, n = brute_numbering(scene)
    oid, prim = gb.numpy("object_id.V").ravel(), gb.numpy("prim_id.V").ravel()
    poly = np.zeros(oid.shape, np.int64)
    for k, s in table.shapes.items():
        sel = oid == k
        poly[sel] = base[k] + (prim[sel] if s.is_mesh() else 0) + 1
    return np.bincount(poly, minlength=n + 1)


def brute_areas(scene, origin, target, up, fov, w, h):
    """One Mitsuba sensor per viewpoint, mi-npr's exact G-buffer pass, numpy counting."""
    mi = mi_npr.mi
    sensor = mi.load_dict(
        {
            "type": "perspective",
            "fov": fov,
            "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=origin, target=target, up=up),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}},
        }
    )
    gb = mi_npr.render_gbuffer(scene, sensor)
    return gbuffer_areas(scene, gb), gb


def test01_numbering(write_scene, ply):
    scene = _scene(write_scene, MIXED.format(ply=ply))
    P = polygons(scene)
    table, base, n = brute_numbering(scene)
    assert P.n == n == 10 * 2 * 6 + 12 + 1 + 2  # uv sphere, cube, analytic sphere, rectangle
    assert [int(P.base[k]) for k in sorted(base)] == [base[k] for k in sorted(base)]
    assert P.table.names == table.names


@pytest.mark.parametrize(("w", "h", "fov"), [(33, 21, 40.0), (16, 16, 75.0), (1, 1, 30.0)])
def test02_batched_areas_equal_a_loop_of_sensors(write_scene, ply, w, h, fov):
    scene = _scene(write_scene, MIXED.format(ply=ply))
    rng = np.random.default_rng(w)
    dirs = rng.normal(size=(9, 3))
    dirs[0] = (0, 1, 0)  # straight down: the frame's fallback up vector
    dirs[1] = (0, -1e-4, 1)
    origins = 4.5 * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    target = np.array([0.1, -0.2, 0.05])
    got = areas(scene, origins, target, fov, (w, h))
    assert got.shape == (9, 10 * 2 * 6 + 12 + 1 + 2 + 1) and got.dtype == np.uint32
    assert np.all(got.sum(axis=1) == w * h)
    _, _, ups = view_frame(origins, target)
    below = 0
    for v, o in enumerate(origins):
        ref, _ = brute_areas(scene, o, target, ups[v], fov, w, h)
        if o[1] < -1.1:  # the one-sided (diffuse) floor at y = -1.1 seen from below: background
            ref[0] += ref[-2:].sum()
            ref[-2:] = 0
            below += 1
        np.testing.assert_array_equal(got[v], ref)
    assert below > 0  # the back-face rule is exercised


def test03_instances_count_like_their_expanded_copies(write_scene, ply):
    inst = _scene(write_scene, INSTANCED.format(ply=ply), "inst.xml")
    flat = _scene(write_scene, EXPANDED.format(ply=ply), "flat.xml")
    Pi, Pf = polygons(inst), polygons(flat)
    per_child = [120, 12, 1]
    assert Pi.n == Pf.n == 2 * sum(per_child)
    assert list(Pi.span[1:]) == [sum(per_child)] * 2
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(6, 3))
    origins = 3.5 * dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    a_i = areas(inst, origins, (0, 0, 0), 50.0, (40, 30), polys=Pi)
    a_f = areas(flat, origins, (0, 0, 0), 50.0, (40, 30), polys=Pf)
    # Same background, same area per object (instance = its 3 expanded shapes), and polygon by
    # polygon when the group's children are matched to the expanded shapes.
    np.testing.assert_array_equal(a_i[:, 0], a_f[:, 0])
    for k, name in enumerate(("inst_a", "inst_b")):
        oid = Pi.table.id_of(name)
        lo = int(Pi.base[oid]) + 1
        got = a_i[:, lo : lo + sum(per_child)]
        parts = [p for p in Pi.parts if p.object_id == oid]
        ref = []
        for p in parts:
            flat_name = ("a" if k == 0 else "b") + {"pair_ball": "1", "pair_box": "2"}.get(
                p.shape.id(), "3"
            )
            fid = Pf.table.id_of(flat_name)
            fl = int(Pf.base[fid]) + 1
            ref.append(a_f[:, fl : fl + p.count])
        order = np.argsort([p.offset for p in parts])
        ref = np.concatenate([ref[i] for i in order], axis=1)
        diff = np.abs(got.astype(np.int64) - ref).sum()
        assert diff <= 2 * len(origins), diff  # transforms composed in another order: ~1 px
        assert got.sum() > 0


def test04_instance_topology_uses_world_space(write_scene, ply):
    inst = _scene(write_scene, INSTANCED.format(ply=ply), "inst.xml")
    topo = polygons(inst).topology()
    # Per instance: a closed uv sphere (4 pi), a closed cube (4 pi), an analytic sphere (none).
    assert topo.vertex_term.sum() == pytest.approx(2 * 8 * np.pi)
    assert topo.polygon_vertices.shape == (2 * 133 + 1, 3)
    assert np.all(topo.polygon_vertices[0] == -1)
    sphere_rows = [p for p in polygons(inst).parts if not p.shape.is_mesh()]
    for p in sphere_rows:
        assert np.all(topo.polygon_vertices[p.offset + 1] == -1)


def test05_views_that_see_nothing(write_scene, ply):
    scene = _scene(write_scene, MIXED.format(ply=ply))
    # Looking away from everything, and from far beyond the far side of an empty direction.
    got = areas(scene, [[0, 0, 50]], [0, 0, 100], 30.0, (8, 6))
    assert got[0, 0] == 48 and got[0, 1:].sum() == 0
    empty = mi_npr.mi.load_dict({"type": "scene"})
    got = areas(empty, [[0, 0, -3]], [0, 0, 0], 30.0, (5, 3))
    assert got.shape == (1, 1) and got[0, 0] == 15


def test06_batches_split_like_one(write_scene, ply, monkeypatch):
    from mi_npr.viewpoint import idbuffer

    scene = _scene(write_scene, MIXED.format(ply=ply))
    origins = 4 * np.eye(3)
    one = areas(scene, origins, (0, 0, 0), 40.0, (24, 24))
    monkeypatch.setattr(idbuffer, "MAX_RAYS", 24 * 24)  # one view per launch
    np.testing.assert_array_equal(areas(scene, origins, (0, 0, 0), 40.0, (24, 24)), one)


def test07_bad_input(write_scene, ply):
    scene = _scene(write_scene, MIXED.format(ply=ply))
    with pytest.raises(mi_npr.ParameterError, match="fov"):
        areas(scene, [[0, 0, 4]], (0, 0, 0), 180.0, (4, 4))
    with pytest.raises(mi_npr.ParameterError, match="coincide"):
        areas(scene, [[0, 0, 0]], (0, 0, 0), 40.0, (4, 4))
    with pytest.raises(mi_npr.ParameterError, match="finite"):
        areas(scene, [[np.nan, 0, 4]], (0, 0, 0), 40.0, (4, 4))
    mi_npr.set_variant("scalar_rgb")
    xml = write_scene(MIXED.format(ply=ply), name="s.xml", integrator='<integrator type="path"/>')
    scalar = mi_npr.load_scene(xml)
    with pytest.raises(mi_npr.ParameterError, match="JIT variant"):
        areas(scalar, [[0, 0, 4]], (0, 0, 0), 40.0, (4, 4))
    with pytest.raises(mi_npr.ParameterError, match="JIT variant"):
        mi_npr.viewpoint.quality(scalar, [0, 0, 4])


def test08_view_frame_is_orthonormal_and_never_degenerate():
    rng = np.random.default_rng(0)
    o = np.concatenate([rng.normal(size=(50, 3)), np.eye(3), -np.eye(3), [[1e-9, 1, 0]]])
    f, left, up = view_frame(o, np.zeros(3))
    for a, b in ((f, left), (f, up), (left, up)):
        np.testing.assert_allclose((a * b).sum(-1), 0, atol=1e-12)
    for a in (f, left, up):
        np.testing.assert_allclose(np.linalg.norm(a, axis=-1), 1)
    np.testing.assert_allclose(f, -o / np.linalg.norm(o, axis=-1, keepdims=True))
    # Away from the poles, "up" leans towards +y like a lookat with up = (0, 1, 0).
    side = np.abs(f[:, 1]) < 0.9
    assert np.all(up[side, 1] > 0)


def test09_unresolved_instance_groups_still_count(write_scene, ply, monkeypatch):
    """If the group of an instance cannot be found, the instance keeps its area, indexed by
    primitive, and adds no topology."""
    from mi_npr.viewpoint import idbuffer

    inst = _scene(write_scene, INSTANCED.format(ply=ply), "inst.xml")
    good = polygons(inst)
    monkeypatch.setattr(idbuffer, "_group_children", lambda scene: {})
    blind = polygons(inst)
    assert blind.n == good.n and list(blind.span) == list(good.span)
    origins = 3.0 * np.eye(3)
    a_good = areas(inst, origins, (0, 0, 0), 50.0, (24, 24), polys=good)
    a_blind = areas(inst, origins, (0, 0, 0), 50.0, (24, 24), polys=blind)
    # Blind, the children's BSDFs are unknown, so no hit is a back face. Closed shapes seen from
    # outside show none either, except where rounding at a grazing silhouette pixel turns the
    # normal away (none on LLVM; one pixel on CUDA).
    back = a_good[:, 0].astype(int) - a_blind[:, 0]
    assert np.all((back >= 0) & (back <= 1)), back
    seen = [a[:, 1:].sum(1).astype(int) for a in (a_good, a_blind)]
    np.testing.assert_array_equal(seen[1] - seen[0], back)
    for oid in (1, 2):
        lo, hi = int(good.base[oid]) + 1, int(good.base[oid] + good.span[oid]) + 1
        assert np.all(
            np.abs(a_good[:, lo:hi].sum(1).astype(int) - a_blind[:, lo:hi].sum(1)) <= back
        )
    assert np.all(blind.topology().polygon_vertices == -1)
