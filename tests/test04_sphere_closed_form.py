"""The G-buffer of one sphere against closed-form ray casting through each pixel centre."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr


def analytic_sphere(width, height, fov, origin, target, center, radius):
    """Mask, depth Z, position, normal and |distance-to-outline| (pixels) per pixel centre."""
    o, t, c = (np.asarray(v, np.float64) for v in (origin, target, center))
    fwd = (t - o) / np.linalg.norm(t - o)
    left = np.cross([0.0, 1.0, 0.0], fwd)
    left /= np.linalg.norm(left)
    up = np.cross(fwd, left)
    tx = np.tan(np.radians(fov) / 2)
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    cx = (1 - 2 * u)[None, :, None] * tx
    cy = (1 - 2 * v)[:, None, None] * tx * height / width
    d = cx * left + cy * up + fwd
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    oc = c - o
    b = d @ oc
    miss_dist = np.sqrt(np.maximum(oc @ oc - b**2, 0.0))  # ray's closest approach to c
    disc = b**2 - (oc @ oc - radius**2)
    mask = disc > 0
    tt = np.where(mask, b - np.sqrt(np.maximum(disc, 0)), 0.0)
    P = o + tt[..., None] * d
    Z = np.where(mask, (P - o) @ fwd, np.inf)
    N = (P - c) / radius
    pixel = 2 * tx * np.linalg.norm(oc) / width  # world size of one pixel at the sphere
    outline = np.abs(miss_dist - radius) / pixel
    return mask, Z, np.where(mask[..., None], P, 0), np.where(mask[..., None], N, 0), outline


CASES = [
    dict(
        width=64,
        height=48,
        fov=40,
        origin=(0, 0, 0),
        target=(0, 0, 1),
        center=(0.4, -0.3, 5.0),
        radius=1.2,
    ),
    dict(
        width=33,
        height=17,
        fov=65,
        origin=(1, 2, -3),
        target=(0.2, 0.1, 1.5),
        center=(0.0, 0.0, 2.0),
        radius=0.9,
    ),
    dict(
        width=1,
        height=1,
        fov=30,
        origin=(0, 0, 0),
        target=(0, 0, 1),
        center=(0.0, 0.0, 3.0),
        radius=0.5,
    ),
]


def _sphere_scene(write_scene, case):
    c = case["center"]
    body = (
        f'<shape type="sphere" id="ball"><point name="center" x="{c[0]}" y="{c[1]}" '
        f'z="{c[2]}"/><float name="radius" value="{case["radius"]}"/></shape>'
    )
    return write_scene(
        body,
        width=case["width"],
        height=case["height"],
        fov=case["fov"],
        origin=", ".join(map(str, case["origin"])),
        target=", ".join(map(str, case["target"])),
    )


@pytest.mark.parametrize("case", CASES)
def test01_ids_and_depth_match_closed_form(write_scene, case):
    path = _sphere_scene(write_scene, case)
    gb = mi_npr.render(path)
    mask, Z, P, N, outline = analytic_sphere(**case)
    ids = gb.numpy("object_id.V")
    assert gb.objects == {1: "ball"}
    wrong = (ids == 1) != mask
    assert not np.any(wrong & (outline > 1e-4)), "id differs away from the outline"
    both = mask & (ids == 1)
    np.testing.assert_allclose(gb.numpy("Z")[both], Z[both], rtol=1e-4)
    assert np.all(np.isposinf(gb.numpy("Z")[ids == 0]))
    for i, name in enumerate(mi_npr.layers.P):
        np.testing.assert_allclose(gb.numpy(name)[both], P[both][:, i], atol=1e-4 * Z[both].max())
        assert np.all(gb.numpy(name)[ids == 0] == 0)
    for i, name in enumerate(mi_npr.layers.N):
        np.testing.assert_allclose(gb.numpy(name)[both], N[both][:, i], atol=2e-3)
        assert np.all(gb.numpy(name)[ids == 0] == 0)


def test02_pixel_centre_rays_equal_scene_ray_intersect(write_scene):
    """The same pixel-centre rays cast by hand with scene.ray_intersect give the same layers."""
    mi, dr = mi_npr.mi, mi_npr.dr  # the variant is set: the JIT types are the current ones
    case = CASES[1]
    scene = mi_npr.load_scene(_sphere_scene(write_scene, case))
    gb = mi_npr.render(scene)
    sensor = scene.sensors()[0]
    w, h = case["width"], case["height"]
    ys, xs = np.mgrid[0:h, 0:w]
    pos = mi.Point2f(mi.Float((xs.ravel() + 0.5) / w), mi.Float((ys.ravel() + 0.5) / h))
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5))
    si = scene.ray_intersect(ray)
    T = sensor.world_transform()
    depth = dr.dot(si.p - T @ mi.Point3f(0, 0, 0), dr.normalize(T @ mi.Vector3f(0, 0, 1)))
    depth = np.where(si.is_valid().numpy(), depth.numpy(), np.inf).reshape(h, w)
    np.testing.assert_allclose(gb.numpy("Z"), depth, rtol=1e-5)
    hit = si.is_valid().numpy().reshape(h, w)
    np.testing.assert_array_equal(gb.numpy("object_id.V"), hit.astype(np.uint32))
    # Z is along the view axis, not along the ray: t * cos(angle) + the near-clip offset.
    cos = dr.dot(ray.d, dr.normalize(T @ mi.Vector3f(0, 0, 1))).numpy().reshape(h, w)
    t = si.t.numpy().reshape(h, w)
    np.testing.assert_allclose(gb.numpy("Z")[hit], (t * cos)[hit] + sensor.near_clip(), rtol=1e-5)


def test03_scalar_variant_gets_one_line_error(write_scene):
    """JIT variants only, as Mitsuba's own Python integrators: a scalar variant can be active,
    but mi-npr's functions and plugins say so in one line."""
    case = dict(CASES[0], width=12, height=9)
    path = _sphere_scene(write_scene, case)
    mi_npr.set_variant("scalar_rgb")
    for call in (
        lambda: mi_npr.render(path),
        lambda: mi_npr.contours.trace_scene(path),
        lambda: mi_npr.object_table(mi_npr.load_scene(path)),
    ):
        with pytest.raises(mi_npr.NprError, match="JIT variant") as e:
            call()
        assert "scalar_rgb" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.skipif("cuda_ad_rgb" not in mi_npr.mi.variants(), reason="no CUDA variant")
def test04_cuda_variant_matches_llvm(write_scene):
    case = CASES[0]
    path = _sphere_scene(write_scene, case)
    mi_npr.set_variant("llvm_ad_rgb")
    llvm = mi_npr.render(path)
    try:
        mi_npr.set_variant("cuda_ad_rgb")
    except mi_npr.ParameterError as e:
        pytest.skip(f"CUDA unavailable here: {e}")
    cuda = mi_npr.render(path)
    np.testing.assert_array_equal(cuda.numpy("object_id.V"), llvm.numpy("object_id.V"))
    np.testing.assert_allclose(cuda.numpy("Z"), llvm.numpy("Z"), rtol=1e-5)
