"""The popping measure (reprojection through P and the cameras, occlusion by depth)."""

from __future__ import annotations

import mitsuba as mi
import numpy as np
import pytest

from mi_npr import GBuffer, ParameterError
from mi_npr import layers as L
from mi_npr.coherence import popping, reproject
from mi_npr.gbuffer import Projection
from mi_npr.projection import project

W, H, FOV = 48, 32, 50.0
DX = 0.2  # camera B = camera A moved by DX along world x


def _sensor(origin):
    return mi.load_dict(
        {
            "type": "perspective",
            "fov": FOV,
            "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=origin, target=[origin[0], origin[1], origin[2] + 1], up=[0, 1, 0]
            ),
            "film": {"type": "hdrfilm", "width": W, "height": H},
        }
    )


def _rays(sensor):
    """Mitsuba's own rays through the pixel centres: origins and directions (H, W, 3) (the
    origins lie on the near clip plane, not at the camera's centre)."""
    j, i = np.mgrid[0:H, 0:W]
    uv = mi.Point2f(((i + 0.5) / W).ravel().astype(np.float32), ((j + 0.5) / H).ravel())
    ray, _ = sensor.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))
    d = np.stack([np.asarray(ray.d[k], np.float64) for k in range(3)], -1).reshape(H, W, 3)
    o = np.stack([np.asarray(ray.o[k], np.float64) for k in range(3)], -1).reshape(H, W, 3)
    return o, d


def _step_scene(origin):
    """The flat plane z = 4 with a nearer step z = 2 over world x > 0, seen from ``origin``:
    the G-buffer layers (P, Z) and the camera, intersected in numpy."""
    s = _sensor(origin)
    o, d = _rays(s)
    t_near = (2.0 - o[..., 2]) / d[..., 2]
    near = o[..., 0] + t_near * d[..., 0] > 0
    t = np.where(near, t_near, (4.0 - o[..., 2]) / d[..., 2])
    Pw = o + t[..., None] * d
    layers = {n: Pw[..., k].astype(np.float32) for k, n in enumerate(L.P)}
    layers[L.Z] = (Pw[..., 2] - origin[2]).astype(np.float32)  # the camera looks along +z
    M = np.asarray(s.world_transform().matrix, np.float64).reshape(4, 4)
    return layers, Projection(M, (W, H), FOV), near


def _frame(layers, cam, ink):
    return GBuffer({**layers, L.LINES: ink.astype(np.float32)}, camera=cam)


def test01_project_matches_mitsuba_rays():
    la, cam, _ = _step_scene([0.0, 0.0, 0.0])
    P = np.stack([la[n] for n in L.P], -1).astype(np.float64)
    x, y, depth = project(cam, P)
    j, i = np.mgrid[0:H, 0:W]
    np.testing.assert_allclose(x, i + 0.5, atol=2e-3)
    np.testing.assert_allclose(y, j + 0.5, atol=2e-3)
    np.testing.assert_allclose(depth, la[L.Z], rtol=1e-5)
    # behind the camera: no pixel
    bx, by, bd = project(cam, np.array([[0.0, 0.0, -1.0]]))
    assert np.isnan(bx[0]) and np.isnan(by[0]) and bd[0] < 0


def test02_translation_of_a_step_reprojects_analytically():
    la, _, _ = _step_scene([0.0, 0.0, 0.0])
    lb, cam_b, near_b = _step_scene([DX, 0.0, 0.0])
    # expected: the column where B's ray slope x/z equals the point's, from Mitsuba's rays of B
    _ob, db = _rays(_sensor([DX, 0.0, 0.0]))
    slope_b = db[0, :, 0] / db[0, :, 2]  # linear in the column; Mitsuba's +x is to the left
    cols = np.arange(W) + 0.5
    P = np.stack([la[n] for n in L.P], -1).astype(np.float64)
    s = (P[..., 0] - DX) / P[..., 2]
    order = np.argsort(slope_b)
    step = (cols[-1] - cols[0]) / (slope_b[-1] - slope_b[0])
    x_expected = cols[0] + (s - slope_b[0]) * step  # the straight line through the centres
    x, _, _depth = project(cam_b, P)
    np.testing.assert_allclose(x, x_expected, atol=2e-3)
    assert np.all(np.diff(slope_b[order]) > 0)
    # the shift is DX * f / z pixels: twice as large on the near step as on the far plane
    f = W / (2 * np.tan(np.radians(FOV) / 2))
    _j, i = np.mgrid[0:H, 0:W]
    shift = np.abs(x - (i + 0.5))
    near_a = P[..., 2] < 3
    np.testing.assert_allclose(shift[near_a], DX * f / 2, atol=2e-3)
    np.testing.assert_allclose(shift[~near_a], DX * f / 4, atol=2e-3)
    # occlusion: far points with -DX < x <= 0 hide behind the step as seen from B
    hidden = (~near_a) & (P[..., 0] > -DX)
    inside = (x >= 0) & (x < W)
    col, _row, _, kept = reproject(_frame(la, None, np.zeros((H, W))), cam_b, lb[L.Z], radius=0)
    # away from the step's edge in B (a pixel either side), kept = in view and not hidden
    edge_cols = np.flatnonzero(np.diff(near_b[0].astype(int)) != 0)
    clear = np.all(np.abs(x[..., None] - (edge_cols + 1)) > 1.5, axis=-1)
    assert clear.sum() > W * H / 2 and (hidden & clear).sum() > 10
    np.testing.assert_array_equal(kept[clear], (inside & ~hidden)[clear])
    np.testing.assert_array_equal(col[kept], np.floor(x[kept]).astype(int))


def test03_static_camera_has_no_popping():
    la, cam, _near = _step_scene([0.0, 0.0, 0.0])
    rng = np.random.default_rng(3)
    ink = rng.random((H, W)) * (rng.random((H, W)) < 0.2)
    fr = _frame(la, cam, ink)
    for radius in (0, 1, 2):
        r = popping([fr, fr, fr], radius=radius)
        assert r["overall"] == 0.0 and r["per_frame"] == [0.0, 0.0]
        assert r["ink"][0] == pytest.approx(2 * ink.sum(), rel=1e-5)


def test04_lines_moving_with_the_surface_do_not_pop_and_vanishing_ones_do():
    la, cam_a, near_a = _step_scene([0.0, 0.0, 0.0])
    lb, cam_b, near_b = _step_scene([DX, 0.0, 0.0])

    def edge_ink(near):  # the near side of the step: where eq. 5.1 inks
        e = np.zeros((H, W))
        cols = np.flatnonzero(np.diff(near[0].astype(int)) != 0)
        for c in cols:
            e[:, c if near[0, c] else c + 1] = 1.0
        return e

    ink_a, ink_b = edge_ink(near_a), edge_ink(near_b)
    assert ink_a.sum() == H and ink_b.sum() == H  # one column each, at different columns
    assert not np.array_equal(ink_a, ink_b)
    a, b = _frame(la, cam_a, ink_a), _frame(lb, cam_b, ink_b)
    assert popping([a, b], radius=1)["overall"] < 0.05
    gone = popping([a, _frame(lb, cam_b, np.zeros((H, W)))], radius=1)
    assert gone["overall"] == pytest.approx(1.0) and gone["vanished"][0] == pytest.approx(1.0)
    new = popping([_frame(la, cam_a, np.zeros((H, W))), b], radius=1)
    assert new["appeared"][0] == pytest.approx(1.0)
    # half the line fading to gray: half of those rows' ink vanishes, except the gray row next
    # to the full one (the 3x3 window sees the full row); the pair holds H + 0.75 H of ink
    half = ink_b.copy()
    half[: H // 2] *= 0.5
    r = popping([a, _frame(lb, cam_b, half)], radius=1)
    assert r["overall"] == pytest.approx((H / 2 - 1) * 0.5 / (1.75 * H), rel=1e-6)
    r0 = popping([a, _frame(lb, cam_b, half)], radius=0)
    assert r0["overall"] == pytest.approx(H / 2 * 0.5 / (1.75 * H), rel=1e-6)


def test05_no_ink_no_popping_and_bad_arguments():
    la, cam, _ = _step_scene([0.0, 0.0, 0.0])
    fr = _frame(la, cam, np.zeros((H, W)))
    assert popping([fr, fr])["overall"] == 0.0
    assert popping([fr])["per_frame"] == []
    with pytest.raises(ParameterError, match="radius"):
        popping([fr, fr], radius=-1)
    with pytest.raises(ParameterError, match="contour"):
        popping([fr, fr], layer=L.CONTOUR)
    with pytest.raises(ParameterError, match="camera"):
        popping([GBuffer(dict(fr.layers)), fr])
