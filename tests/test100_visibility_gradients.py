"""Visibility gradients of :func:`mi_npr.ad.soft_lines`: d(ink)/d(parameter) from ``dr.backward``
agrees with a central finite difference of the same function when silhouettes, occlusion
boundaries and creases move (the pixel-centre G-buffer's gradient is zero there).

References: central finite differences over a step of many sub-samples (the primal moves in
steps of ``1 / n`` pixel, so the step must span several); the closed-form outline of a sphere
(its image radius ``f r / sqrt(d^2 - r^2)`` shrinks as it moves away); Mitsuba's own
``perspective`` sensor for the camera's rays."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr.ad import Pinhole, soft_lines

mi, dr = mi_npr.mi, mi_npr.dr

W, H = 64, 48
N, SIGMA = 8, 1.0  # 8 x 8 samples a pixel, a filter of 1 px: smooth to a step of ~0.1 px

pytestmark = pytest.mark.skipif(
    not str(mi.variant()).startswith(("llvm_ad", "cuda_ad")), reason="needs an AD variant"
)


def _ramp() -> mi.Float:
    """Pixel weights that make a sideways motion change the loss (a plain sum is symmetric)."""
    yy, xx = np.mgrid[0:H, 0:W]
    return mi.Float((1.0 + np.sin(xx / 7.0) * np.cos(yy / 5.0) + xx / W).ravel().astype(np.float32))


def _check(f, eps: float) -> tuple[float, float]:
    """``(gradient, central finite difference)`` of ``f(v) -> loss`` at 0."""
    v = mi.Float(0.0)
    dr.enable_grad(v)
    loss = f(v)
    dr.backward(loss)
    grad = float(dr.grad(v)[0])
    fd = (float(f(mi.Float(eps))[0]) - float(f(mi.Float(-eps))[0])) / (2 * eps)
    return grad, fd


def test01_sphere_moving_away_shrinks_its_outline():
    scene = mi.load_dict({"type": "scene", "ball": {"type": "sphere", "radius": 1.0}})
    params = mi.traverse(scene)
    cam = Pinhole.look_at([0, 0, -5], [0, 0, 0], [0, 1, 0], 40.0)

    def ink(v):
        params["ball.to_world"] = mi.Transform4f().translate(mi.Vector3f(0.0, 0.0, v))
        params.update()
        return dr.sum(soft_lines(scene, cam, (W, H), n=N, sigma=SIGMA, depth_scale=1.0).array)

    grad, fd = _check(ink, 0.2)
    assert grad < -10.0  # the outline shrinks: less ink
    assert grad == pytest.approx(fd, rel=0.05)

    # The id feature alone is the silhouette's ink: proportional to the outline's length, so
    # d(ink)/dd / ink = d(rho)/dd / rho = -d / (d^2 - r^2) for the closed-form radius rho.
    def outline(v):
        params["ball.to_world"] = mi.Transform4f().translate(mi.Vector3f(0.0, 0.0, v))
        params.update()
        img = soft_lines(scene, cam, (W, H), n=N, sigma=SIGMA, depth_weight=0, normal_weight=0)
        return dr.sum(img.array)

    g, _ = _check(outline, 0.2)
    total = float(outline(mi.Float(0.0))[0])
    assert g / total == pytest.approx(-5.0 / (25.0 - 1.0), rel=0.05)
    params["ball.to_world"] = mi.Transform4f()
    params.update()


def _two_objects() -> mi.Scene:
    box = mi.ScalarTransform4f().translate([-0.5, -0.3, 1.5]).rotate([0, 1, 0], 30)
    return mi.load_dict(
        {
            "type": "scene",
            "ball": {"type": "sphere", "center": [0.3, 0.2, 0.0], "radius": 0.8},
            "box": {"type": "cube", "to_world": box.rotate([1, 0, 0], 20)},
        }
    )


@pytest.mark.parametrize(
    "motion",
    ["camera_forward", "camera_sideways", "camera_rotation", "fov", "box_scale", "box_shift"],
)
def test02_camera_and_object_motion_match_finite_differences(motion):
    """A sphere in front of a box: silhouettes, the occlusion boundary between them, the box's
    creases and its ID edges move."""
    scene = _two_objects()
    params = mi.traverse(scene)
    V0 = mi.Float(params["box.vertex_positions"])
    c = mi.Point3f(-0.5, -0.3, 1.5)
    weights = _ramp()

    def loss(v):
        o = mi.Point3f(0.0, 0.0, -6.0)
        target, fov = mi.Point3f(0.0), mi.Float(40.0)
        P = dr.unravel(mi.Point3f, V0)
        if motion == "camera_forward":
            o = mi.Point3f(0.0, 0.0, -6.0 + v)
        elif motion == "camera_sideways":
            o = mi.Point3f(v, 0.0, -6.0)
        elif motion == "camera_rotation":
            target = mi.Point3f(0.0, v, 0.0)  # a pitch of v / 6 radians
        elif motion == "fov":
            fov = 40.0 + 10.0 * v
        elif motion == "box_scale":
            P = c + (P - c) * (1.0 + v)
        elif motion == "box_shift":
            P = P + mi.Vector3f(v, 0.0, 0.0)
        params["box.vertex_positions"] = dr.ravel(P)
        params.update()
        cam = Pinhole.look_at(o, target, mi.Vector3f(0, 1, 0), fov)
        img = soft_lines(scene, cam, (W, H), n=N, sigma=SIGMA, depth_scale=5.0)
        return dr.sum(img.array * weights)

    grad, fd = _check(loss, 0.1)
    assert abs(fd) > 20.0  # the motion changes the drawing
    assert grad == pytest.approx(fd, rel=0.05)


def test03_pinhole_rays_are_mitsubas_perspective_rays():
    sensor = mi.load_dict(
        {
            "type": "perspective",
            "fov": 50.0,
            "to_world": mi.ScalarTransform4f().look_at([1, 2, -4], [0, 0.5, 0], [0, 1, 0]),
            "film": {"type": "hdrfilm", "width": 40, "height": 30},
        }
    )
    xs = mi.Float([0.5, 10.0, 39.5, 20.0, 3.25])
    ys = mi.Float([0.5, 29.5, 7.0, 15.0, 22.75])
    ref, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(xs / 40.0, ys / 30.0), mi.Point2f(0.5))
    cam = Pinhole.of_sensor(sensor)
    ours = cam.rays(xs, ys, (40, 30))
    np.testing.assert_allclose(np.asarray(ours.d), np.asarray(ref.d), atol=1e-5)
    # Mitsuba starts its rays at the near clip plane, on the same lines
    off = np.asarray(ref.o - ours.o)
    along = np.asarray(ours.d) * np.linalg.norm(off, axis=0)
    np.testing.assert_allclose(off, along, atol=1e-4)
    same = Pinhole.look_at([1, 2, -4], [0, 0.5, 0], [0, 1, 0], 50.0).rays(xs, ys, (40, 30))
    np.testing.assert_allclose(np.asarray(same.d), np.asarray(ref.d), atol=1e-5)
    # project() inverts rays()
    px, py = cam.project(ours.o + 3.0 * ours.d, (40, 30))
    np.testing.assert_allclose(np.asarray(px), np.asarray(xs), atol=1e-3)
    np.testing.assert_allclose(np.asarray(py), np.asarray(ys), atol=1e-3)


def test04_empty_scene_has_no_ink_and_bad_settings_are_named():
    scene = mi.load_dict({"type": "scene"})
    cam = Pinhole.look_at([0, 0, -5], [0, 0, 0], [0, 1, 0], 40.0)
    img = np.asarray(soft_lines(scene, cam, (9, 7), n=2))
    assert img.shape == (7, 9) and not img.any()
    with pytest.raises(mi_npr.ParameterError, match="sigma"):
        soft_lines(scene, cam, (9, 7), sigma=0.0)
    with pytest.raises(mi_npr.ParameterError, match="size"):
        soft_lines(scene, cam)


def test05_the_filters_backward_pass_is_its_transpose():
    """The prefilter's hand-written backward pass (gathers, not scatters) is the adjoint of its
    forward pass: <g, F(dv)> = <F^T(g), dv> for random g, dv, F linear."""
    from mi_npr.ad.visibility import _separable, _taps

    rng = np.random.default_rng(0)
    n, R, w, h = 3, 2, 7, 5
    rows, cols = (h + 2 * R) * n, (w + 2 * R) * n
    taps = _taps(n, R, 0.6)
    v = mi.Float(rng.random(rows * cols).astype(np.float32))
    dv = rng.random(rows * cols).astype(np.float32)
    g = rng.random(w * h).astype(np.float32)
    dr.enable_grad(v)
    dr.set_grad(v, mi.Float(dv))
    out = _separable(v, rows, cols, taps, n, R, (w, h))
    dr.forward_to(out)
    lhs = float(np.dot(g, np.asarray(dr.grad(out))))
    v2 = mi.Float(np.asarray(dr.detach(v)))
    dr.enable_grad(v2)
    out2 = _separable(v2, rows, cols, taps, n, R, (w, h))
    dr.backward(dr.sum(out2 * mi.Float(g)))
    rhs = float(np.dot(np.asarray(dr.grad(v2)), dv))
    assert lhs == pytest.approx(rhs, rel=1e-5)
    # and the forward pass is the sum it says, by a numpy loop
    a = np.asarray(dr.detach(v)).reshape(rows, cols)
    ks = {k: wt for k, wt in taps}
    ref = np.zeros((h, w))
    for j in range(h):
        for i in range(w):
            for ky, wy in ks.items():
                for kx, wx in ks.items():
                    ref[j, i] += wy * wx * a[(j + R) * n + ky, (i + R) * n + kx]
    np.testing.assert_allclose(np.asarray(dr.detach(out)).reshape(h, w), ref, rtol=1e-5)


def test06_camera_gradients_agree_in_forward_and_reverse_mode():
    """Every custom pass (the camera's broadcast to the samples and its summed adjoint, the
    boundary flux, the prefilter) is linear: d(loss)/d(camera value) from ``dr.backward`` equals
    the tangent ``dr.forward`` pushes through the same function, for each of the camera's
    values."""
    scene = _two_objects()
    weights = _ramp()
    names = ["origin.x", "origin.y", "origin.z", "target.y", "fov"]

    def loss(vs):
        o = mi.Point3f(vs[0], vs[1], -6.0 + vs[2])
        cam = Pinhole.look_at(o, mi.Point3f(0.0, vs[3], 0.0), mi.Vector3f(0, 1, 0), 40.0 + vs[4])
        img = soft_lines(scene, cam, (W, H), n=2, sigma=SIGMA, depth_scale=5.0)
        return dr.sum(img.array * weights)

    vs = [mi.Float(0.0) for _ in names]
    dr.enable_grad(vs)
    dr.backward(loss(vs))
    reverse = [float(dr.grad(v)[0]) for v in vs]
    for i, name in enumerate(names):
        v = [mi.Float(0.0) for _ in names]
        dr.enable_grad(v[i])
        dr.set_grad(v[i], 1.0)
        out = loss(v)
        dr.forward_to(out)
        tangent = float(dr.grad(out)[0])
        assert abs(tangent) > 1.0, name  # the value moves the drawing
        assert reverse[i] == pytest.approx(tangent, rel=1e-3), name


@pytest.mark.parametrize("motion", ["sphere_away", "sphere_sideways", "camera_sideways"])
def test07_a_unit_sphere_with_the_default_depth_scale_converges_to_the_fine_grid(motion):
    """A sphere of radius 1 five units away, the depth scale its bounding-box diagonal (its
    inverse depth then steps by ~0.7 at the outline). Brute-force reference: central finite
    differences on a grid twice as fine (16 x 16 samples a pixel). Where the features are
    Lipschitz up to the outline the gradient's error is O(h): the gradient at 8 x 8 samples is
    within 3% of the reference and within 1.5% of its own value at 16 x 16. (An error that
    shrinks as h^(1/2) instead, from a feature whose depth grows as the square root of the
    distance to the outline, was 7% between the two grids and 10% from the reference.)"""
    scene = mi.load_dict({"type": "scene", "ball": {"type": "sphere", "radius": 1.0}})
    params = mi.traverse(scene)
    weights = _ramp()

    def loss(v, n):
        o = mi.Point3f(0.0, 0.0, -5.0)
        shift = mi.Vector3f(0.0)
        if motion == "sphere_away":
            shift = mi.Vector3f(0.0, 0.0, v)
        elif motion == "sphere_sideways":
            shift = mi.Vector3f(v, 0.0, 0.0)
        else:
            o = o + mi.Vector3f(v, 0.3 * v, 0.0)
        params["ball.to_world"] = mi.Transform4f().translate(shift)
        params.update()
        target = o + mi.Vector3f(0.0, 0.0, 5.0)
        cam = Pinhole.look_at(o, target, mi.Vector3f(0, 1, 0), 40.0)
        return dr.sum(soft_lines(scene, cam, (W, H), n=n, sigma=SIGMA).array * weights)

    grads = {}
    for n in (8, 16):
        v = mi.Float(0.0)
        dr.enable_grad(v)
        dr.backward(loss(v, n))
        grads[n] = float(dr.grad(v)[0])
    eps = 0.05
    fine = (float(loss(mi.Float(eps), 16)[0]) - float(loss(mi.Float(-eps), 16)[0])) / (2 * eps)
    params["ball.to_world"] = mi.Transform4f()
    params.update()
    assert abs(fine) > 50.0  # the motion changes the drawing
    assert grads[8] == pytest.approx(fine, rel=0.03)
    assert grads[8] == pytest.approx(grads[16], rel=0.015)


#: (feature, motion) pairs whose finite difference is stable (the same within 5% over steps of
#: 0.1 and 0.05): the ID feature alone (ID edges and apparent contours), with depth (a slab in
#: front of a wall: depth contours), with normals (a box's creases).
KIND_CASES = [
    ("id", "camera_rotation"),
    ("id", "shift"),
    ("id", "scale"),
    ("depth", "scale"),
    ("normal", "camera_rotation"),
    ("normal", "shift"),
    ("normal", "scale"),
]


@pytest.mark.parametrize(("kind", "motion"), KIND_CASES)
def test08_each_line_kind_matches_finite_differences(kind, motion):
    """One feature at a time beside the ID feature (which is always on), for camera and
    object motions: the gradient within 5% of a central finite difference that is stable."""
    T = mi.ScalarTransform4f
    pose = T().translate([0.2, 0.1, 0.5]).rotate([0, 1, 0], 30).rotate([1, 0, 0], 20)
    d = {"type": "scene", "obj": {"type": "cube", "to_world": pose.scale(0.6)}}
    if kind == "depth":
        d["obj"]["to_world"] = pose.scale([0.7, 0.5, 0.3])
        d["wall"] = {"type": "cube", "to_world": T().translate([0.2, 0, 3]).scale([1.6, 1.6, 0.3])}
    weights = {"id": (0.0, 0.0), "depth": (1.0, 0.0), "normal": (0.0, 0.5)}[kind]
    scene = mi.load_dict(d)
    params = mi.traverse(scene)
    V0 = mi.Float(params["obj.vertex_positions"])
    c = mi.Point3f(0.2, 0.1, 0.5)
    ramp = _ramp()

    def loss(v):
        o, target = mi.Point3f(0.0, 0.0, -6.0), mi.Point3f(0.0)
        P = dr.unravel(mi.Point3f, V0)
        if motion == "camera_sideways":
            o = mi.Point3f(v, 0.0, -6.0)
        elif motion == "camera_rotation":
            target = mi.Point3f(v, 0.0, 0.0)  # a yaw of v / 6 radians
        elif motion == "shift":
            P = P + mi.Vector3f(v, 0.0, 0.0)
        else:
            P = c + (P - c) * (1.0 + v)
        params["obj.vertex_positions"] = dr.ravel(P)
        params.update()
        cam = Pinhole.look_at(o, target, mi.Vector3f(0, 1, 0), mi.Float(40.0))
        img = soft_lines(
            scene,
            cam,
            (W, H),
            n=N,
            sigma=SIGMA,
            depth_scale=5.0,
            depth_weight=weights[0],
            normal_weight=weights[1],
        )
        return dr.sum(img.array * ramp)

    grad, fd = _check(loss, 0.05)
    _, fd_wide = _check(loss, 0.1)
    assert abs(fd) > 5.0  # the motion changes the drawing
    assert fd_wide == pytest.approx(fd, rel=0.05)  # the reference is stable
    assert grad == pytest.approx(fd, rel=0.05)
