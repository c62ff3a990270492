"""Rays through pixel centres that slip between two triangles of one mesh (on their shared
edge) leave no speck: the seam rule of :mod:`mi_npr.render` (a cell whose 4-neighbours agree on
an object it misses, or sees only farther than they do, is re-cast a hair away), in the G-buffer,
the lines and the anti-aliased lines' sub-pixel grid; a real one-pixel object stays."""

from __future__ import annotations

import mitsuba as mi
import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.antialias import supersampled_gbuffer
from mi_npr.raycast import film_grid, pixel_rays
from mi_npr.render import channels
from mi_npr.scene import object_table

W, H = 24, 16


def _scene(extra: dict | None = None, integrator: str = "npr_gbuffer") -> mi.Scene:
    """A wall (a cube mesh, front face at z = 4) filling a 30-degree view from the origin: the
    diagonal of its front face runs through pixel centres."""
    d = {
        "type": "scene",
        "integrator": {"type": integrator},
        "sensor": {
            "type": "perspective",
            "fov": 30,
            "film": {"type": "hdrfilm", "width": W, "height": H},
        },
        "wall": {
            "type": "cube",
            "to_world": mi.ScalarTransform4f().translate([0.0, 0.0, 5.0]).scale([10, 10, 1]),
        },
    }
    d.update(extra or {})
    return mi.load_dict(d)


def test01_the_scene_has_seam_slips():
    """The reference: a plain cast of the same pixel-centre rays (the test's premise) slips
    through the front face's diagonal at some pixels and sees the back face at z = 6."""
    scene = _scene()
    sensor = scene.sensors()[0]
    raw = channels(scene, sensor, pixel_rays(sensor, *film_grid(W, H)), object_table(scene), False)
    z = np.asarray(raw[L.Z])
    if not np.isclose(z, 6.0).any() and mi.variant().startswith("cuda"):
        pytest.skip("OptiX's ray-triangle test is watertight here: no seam slip to reproduce")
    assert np.sum(np.isclose(z, 6.0)) > 0 and np.sum(np.isclose(z, 4.0)) > W * H / 2


def test02_no_speck_in_the_gbuffer_or_the_lines():
    gb = mi_npr.render(_scene(integrator="npr_lines"), spp=1)
    np.testing.assert_allclose(gb.numpy(L.Z), 4.0, rtol=1e-6)
    normal = gb.stack(list(L.N))
    np.testing.assert_allclose(normal, np.broadcast_to([0, 0, -1], normal.shape), atol=1e-6)
    assert np.all(gb.object_id == 1)
    assert not np.asarray(gb[L.LINES]).any()  # a flat wall: not one line pixel


@pytest.mark.parametrize("n", [2, 3])
def test03_no_speck_in_the_subpixel_grid(n):
    scene = _scene()
    big = supersampled_gbuffer(scene, scene.sensors()[0], n)
    assert big.shape == (H * n, W * n)
    np.testing.assert_allclose(big.numpy(L.Z), 4.0, rtol=1e-6)


def test04_a_real_one_pixel_object_stays():
    """A small sphere seen at one pixel centre only, in front of the wall: its neighbours all
    see the wall, but rays a hair away still see the sphere, so it is kept."""
    # pixel (5, 4): the centre ray's direction; a sphere of radius 0.01 on it at distance 3
    scene = _scene()
    sensor = scene.sensors()[0]
    ray = pixel_rays(sensor, mi.Float(5.5), mi.Float(4.5))
    o, d = np.asarray(ray.o).ravel(), np.asarray(ray.d).ravel()
    dot = {"type": "sphere", "center": (o + 3.0 * d).tolist(), "radius": 0.01}
    gb = mi_npr.render(_scene({"dot": dot}), spp=1)
    ids = gb.object_id
    dot_id = next(k for k, v in gb.objects.items() if v == "dot")
    assert ids[4, 5] == dot_id and np.sum(ids == dot_id) == 1
    assert np.isclose(gb.numpy(L.Z)[4, 5], 3.0 * d[2], rtol=1e-4)


def test05_a_slip_into_the_background_is_no_hole(tmp_path):
    """The wall's front face alone (its two triangles, nothing behind them): a slip is a miss,
    and the ID buffer would get background holes on the diagonal; there are none, in the
    contours either."""
    from mi_npr.meshes import write_ply

    params = mi.traverse(_scene().shapes()[0])
    v = np.asarray(params["vertex_positions"]).reshape(-1, 3)
    f = np.asarray(params["faces"]).reshape(-1, 3)
    front = f[np.all(np.isclose(v[f][:, :, 2], 4.0), axis=1)]  # the two triangles at z = 4
    assert len(front) == 2
    quad = write_ply(tmp_path / "front.ply", v, front.astype(np.int64))
    scene = _scene({"wall": {"type": "ply", "filename": str(quad)}})
    sensor = scene.sensors()[0]
    raw = channels(scene, sensor, pixel_rays(sensor, *film_grid(W, H)), object_table(scene), False)
    if not np.any(np.asarray(raw[L.OBJECT_ID]) == 0) and mi.variant().startswith("cuda"):
        pytest.skip("OptiX's ray-triangle test is watertight here: no seam slip to reproduce")
    assert np.any(np.asarray(raw[L.OBJECT_ID]) == 0)  # the premise: plain rays slip through
    r = mi_npr.render_layers(scene, ["contours"], spp=1)
    assert np.all(r.gbuffer.object_id == 1)
    assert not r.gbuffer.numpy(L.CONTOUR).any()  # the face fills the frame: no contour
    # ray-cast contours close the same seams: no hole contour either
    contours, _ = mi_npr.contours.trace_scene(scene)
    assert [(c.name, c.is_hole) for c in contours] == [("wall", False)]
