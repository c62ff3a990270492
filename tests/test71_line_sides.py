"""Every kind of line 1 px wide, one side of every edge (ID edges, creases, depth
steps), crease angles in degrees against analytic dihedral angles, and brute-force references
of the 1-px ID and crease edges."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr import layers as L

RNG = np.random.default_rng(71)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (33, 24)]
CROSS = ((-1, 0), (0, -1), (0, 1), (1, 0))


def _neighbours(h, w, y, x):
    for dy, dx in CROSS:
        yield min(max(y + dy, 0), h - 1), min(max(x + dx, 0), w - 1)


def _owns(z0, z1, step, key_wins):
    """The side rule written from the docstring: the near side of a step, else the key."""
    with np.errstate(invalid="ignore"):
        dz = np.float32(z1) - np.float32(z0)
    if np.isnan(dz):
        return False
    return bool(dz > step or (abs(dz) <= step and key_wins))


def _depth(Z, shape):
    if Z is None:
        return np.zeros(shape, np.float32)
    Z = np.asarray(Z, np.float32)
    return np.where(np.isnan(Z), np.float32(np.inf), Z)


def ref_id_edges_1px(ids, Z=None, step=0.0):
    h, w = ids.shape
    z = _depth(Z, ids.shape)
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            for q in _neighbours(h, w, y, x):
                if ids[q] != ids[y, x] and _owns(z[y, x], z[q], step, ids[y, x] > ids[q]):
                    out[y, x] = 1.0
    return out


def _unit(v):
    v = np.asarray(v, np.float64)
    n = math.sqrt(float(v @ v))
    return v / n if n > 0 and math.isfinite(n) else None


def ref_crease_edges(N, ids, crease_angle, Z=None, step=0.0, view=(0.0, 0.0, 1.0)):
    h, w = ids.shape
    z = _depth(Z, ids.shape)
    v = np.asarray(view, np.float64) / np.linalg.norm(view)
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            u0 = _unit(N[y, x])
            if ids[y, x] == 0 or u0 is None or crease_angle == 0:
                continue
            for q in _neighbours(h, w, y, x):
                u1 = _unit(N[q])
                if ids[q] != ids[y, x] or u1 is None or np.array_equal(N[q], N[y, x]):
                    continue
                turn = math.degrees(math.acos(min(max(float(u0 @ u1), -1.0), 1.0)))
                if not 180.0 - turn < crease_angle:
                    continue
                f0, f1 = -float(u0 @ v), -float(u1 @ v)
                key = f0 > f1 or (f0 == f1 and tuple(u0) > tuple(u1))
                if _owns(z[y, x], z[q], step, key):
                    out[y, x] = 1.0
    return out


def normals_from_angles(theta_deg, shape):
    """(H, W, 3) unit normals with azimuth ``theta_deg`` (degrees) around the y axis, facing a
    camera that looks along +z at theta = 0: ``(sin theta, 0, -cos theta)``."""
    t = np.radians(np.asarray(theta_deg, np.float64))
    n = np.stack([np.sin(t), np.zeros_like(t), -np.cos(t)], axis=-1)
    return np.broadcast_to(n, (*shape, 3)).astype(np.float32)


def gbuffer(Z, ids, N):
    return {L.Z: Z, L.OBJECT_ID: ids, **{k: N[..., i] for i, k in enumerate(L.N)}}


# ------------------------------------------------------------------ kernels vs references


@pytest.mark.parametrize("shape", SIZES)
def test01_id_edges_1px_match_reference(shape):
    ids = RNG.integers(0, 4, shape).astype(np.uint32)
    Z = RNG.uniform(1, 3, shape).astype(np.float32)
    Z[RNG.random(shape) < 0.1] = np.nan
    for z, step in ((None, 0.0), (Z, 0.0), (Z, 0.5), (Z, np.inf)):
        got = np.asarray(K.id_edges(ids, 1, Z=z, step=step))
        np.testing.assert_array_equal(got, ref_id_edges_1px(ids, z, np.float32(step)))


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("angle", [0.0, 30.0, 90.0, 134.0, 180.0])
def test02_crease_edges_match_reference(shape, angle):
    N = RNG.normal(size=(*shape, 3)).astype(np.float32)
    N[RNG.random(shape) < 0.05] = 0.0
    ids = RNG.integers(0, 3, shape).astype(np.uint32)
    Z = RNG.uniform(1, 3, shape).astype(np.float32)
    view = (0.3, -0.2, 0.9)
    for z, step in ((None, 0.0), (Z, 0.2)):
        got = np.asarray(K.crease_edges(N, ids, angle, Z=z, step=step, view=view))
        np.testing.assert_array_equal(got, ref_crease_edges(N, ids, angle, z, step, view))


def test03_bad_arguments_name_the_argument():
    ids = np.ones((3, 3), np.uint32)
    N = np.zeros((3, 3, 3), np.float32)
    with pytest.raises(mi_npr.ParameterError, match=r"crease_angle = 181"):
        K.crease_edges(N, ids, 181)
    with pytest.raises(mi_npr.ParameterError, match=r"view = "):
        K.crease_edges(N, ids, 90.0, view=(0, 0, 0))
    with pytest.raises(mi_npr.ParameterError, match=r"step = nan"):
        K.id_edges(ids, 1, step=float("nan"))
    with pytest.raises(mi_npr.ParameterError, match=r"width = 3"):
        K.id_edges(ids, 3)
    with pytest.raises(mi_npr.ParameterError, match=r"Z: shape"):
        K.id_edges(ids, 1, Z=np.ones((2, 3)))
    with pytest.raises(mi_npr.ParameterError, match=r"parameter 'crease_angle' = -1\.0"):
        K.lines({L.Z: np.ones((3, 3))}, crease_angle=-1.0)


# ------------------------------------------------------------------ crease angle, analytic


@pytest.mark.parametrize("dihedral", [30.0, 60.0, 90.0, 120.0, 133.0, 135.0, 150.0, 178.0])
def test04_crease_angle_is_the_dihedral_angle_in_degrees(dihedral):
    """Two planar faces whose normals turn by ``180 - dihedral``: a crease exactly when the
    crease angle exceeds the dihedral angle (Freestyle's definition)."""
    half = (180.0 - dihedral) / 2
    theta = np.where(np.arange(8) < 4, -half, half)[None, :].repeat(5, 0)
    N = normals_from_angles(theta, (5, 8))
    ids = np.ones((5, 8), np.uint32)
    for crease_angle, drawn in ((dihedral + 0.5, True), (dihedral - 0.5, False)):
        e = np.asarray(K.crease_edges(N, ids, crease_angle))
        assert e.any() == drawn, (dihedral, crease_angle)
        if drawn:  # 1 px: one column of the two along the crease
            assert e.sum() == 5 and np.all(e[:, 3] + e[:, 4] == 1)


def test05_default_crease_angle_is_freestyles():
    assert {p.name: p.default for p in K.LINES_PARAMS}["crease_angle"] == 134.0


# ------------------------------------------------------------------ 1 px for every kind


def _one_per_row(e):
    return np.all(e.sum(axis=1) == 1)


def test06_box_crease_is_one_pixel_wide_also_on_a_diagonal():
    """A box's vertical edge seen at an angle, the crease running diagonally across the image,
    on faces whose depth slopes differ: exactly one pixel per row, on the face turned more
    towards the camera (the nearer-pixel rule would flip along the edge)."""
    h, w = 24, 24
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    left = xx < yy  # face A below the diagonal
    a, b = normals_from_angles(-20.0, (h, w)), normals_from_angles(70.0, (h, w))
    N = np.where(left[..., None], a, b)
    Z = np.where(left, 5 + 0.02 * xx - 0.03 * yy, 5 - 0.04 * xx + 0.05 * yy).astype(np.float32)
    ids = np.ones((h, w), np.uint32)
    e = np.asarray(K.crease_edges(N, ids, 134.0, Z=Z, step=1.0))
    assert e.sum() > 0
    assert np.all(e[~left] == 0)  # face A (theta -20) faces the camera more: it gets the ink
    rows = e[1:-1].sum(axis=1)
    assert np.all(rows == 1), rows
    full = np.asarray(K.lines(gbuffer(Z, ids, N), id_edges=False, c=0.0))
    np.testing.assert_array_equal(full, e)  # the chain draws the same single pixels


def test07_two_touching_objects_one_pixel():
    """Two objects side by side at (nearly) the same depth: depth sees no step, the ID edge is
    one pixel, on the larger id, whatever the diagonal."""
    h, w = 20, 30
    yy, xx = np.mgrid[0:h, 0:w]
    ids = np.where(xx * 2 < yy + 20, 3, 7).astype(np.uint32)
    Z = np.full((h, w), 6.0, np.float32)
    N = normals_from_angles(0.0, (h, w))
    ink = np.asarray(K.lines(gbuffer(Z, ids, N)))
    assert np.all(ink[ids == 3] == 0)
    assert _one_per_row(ink)
    np.testing.assert_array_equal(ink, ref_id_edges_1px(ids))


def test08_depth_step_one_pixel_for_every_kind():
    """A box in front of a far wall: eq. 5.1, the ID edge and the box's crease to its side face
    all mark the same boundary; together they stay on eq. 5.1's near-side pixels."""
    h, w = 16, 20
    Z = np.full((h, w), 10.0, np.float32)
    ids = np.ones((h, w), np.uint32)
    N = normals_from_angles(0.0, (h, w)).copy()
    Z[4:12, 5:15], ids[4:12, 5:15] = 4.0, 2
    N[4:12, 12:15] = normals_from_angles(80.0, (8, 3))  # a side face of the box, a crease
    gb = gbuffer(Z, ids, N)
    depth_only = np.asarray(K.lines(gb, id_edges=False, crease_angle=0.0, far=11.0))
    ids_only = np.asarray(K.lines(gb, c=0.0, crease_angle=0.0))
    all_kinds = np.asarray(K.lines(gb, far=11.0))
    ring = np.zeros((h, w), bool)
    ring[4:12, 5:15] = True
    ring[5:11, 6:14] = False
    np.testing.assert_array_equal(depth_only > 0, ring)  # eq. 5.1: the near side, 1 px
    np.testing.assert_array_equal(ids_only > 0, ring)  # ID edges: the same pixels
    crease = np.zeros((h, w), bool)
    crease[5:11, 11] = True  # the front face (facing the camera) inks the crease
    np.testing.assert_array_equal(all_kinds > 0, ring | crease)


def test09_no_layers_no_edges_unless_asked():
    z_only = {L.Z: np.ones((4, 4))}
    assert not np.asarray(K.lines(z_only)).any()
    with pytest.raises(mi_npr.ParameterError, match=r"no 'N\.X' layer"):
        K.lines({**z_only, L.OBJECT_ID: np.ones((4, 4), np.uint32)}, crease_angle=100.0)


def test10_crease_side_follows_the_gbuffers_camera():
    """The crease goes to the face turned towards the camera: the G-buffer's camera axis decides
    (a camera turned around, looking along -z, sees the other face as the front one)."""
    h, w = 6, 8
    theta = np.where(np.arange(w) < 4, 10.0, 60.0)[None, :].repeat(h, 0)
    N = normals_from_angles(theta, (h, w))
    layers = gbuffer(np.full((h, w), 5.0, np.float32), np.ones((h, w), np.uint32), N)
    front = mi_npr.Projection(np.eye(4), (w, h), 40.0)
    back = mi_npr.Projection(np.diag([-1.0, 1.0, -1.0, 1.0]), (w, h), 40.0)
    a = np.asarray(K.lines(mi_npr.GBuffer(layers, camera=front), id_edges=False))
    b = np.asarray(K.lines(mi_npr.GBuffer(layers, camera=back), id_edges=False))
    assert np.all(a[:, 3] == 1) and a.sum() == h  # theta 10 faces +z more: column 3
    assert np.all(b[:, 4] == 1) and b.sum() == h  # seen from behind: the other face, column 4
    np.testing.assert_array_equal(a, np.asarray(K.lines(layers, id_edges=False)))  # +z default
