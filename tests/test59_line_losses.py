"""The line losses of mi_npr.ad: the Gaussian blur against scipy, gradients against finite
differences, a gradient far from the target's lines (where plain L2 has none), and the target
drawings read from PNG and SVG."""

from __future__ import annotations

import re

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest
from PIL import Image
from scipy.ndimage import distance_transform_edt, gaussian_filter

from mi_npr import ParameterError
from mi_npr.ad import blur, blurred_l2, chamfer, read_drawing
from mi_npr.errors import InputError


def _line(h: int, w: int, x: float) -> np.ndarray:
    """A vertical anti-aliased line of width 1 at column ``x`` (its left edge)."""
    img = np.zeros((h, w), np.float32)
    i = int(np.floor(x))
    f = x - i
    img[:, i] = 1.0 - f
    if i + 1 < w:
        img[:, i + 1] = f
    return img


@pytest.mark.parametrize(("shape", "sigma"), [((1, 1), 1.0), ((7, 5), 0.7), ((16, 23), 2.5)])
def test01_blur_is_scipys_gaussian(shape, sigma):
    rng = np.random.default_rng(3)
    img = rng.random(shape).astype(np.float32)
    got = np.asarray(blur(img, sigma))
    ref = gaussian_filter(img.astype(np.float64), sigma, mode="nearest", truncate=3.0)
    # scipy truncates at int(3 sigma + 0.5) taps, this blur at ceil(3 sigma): compare where both
    # windows agree, i.e. for sigmas whose 3 sigma is a whole number of pixels, else loosely
    tol = 1e-5 if float(3 * sigma).is_integer() else 2e-3
    np.testing.assert_allclose(got, ref, atol=tol)
    assert np.array_equal(np.asarray(blur(img, 0.0)), img)
    with pytest.raises(ParameterError, match="sigma"):
        blur(img, -1.0)
    with pytest.raises(ParameterError, match="sigma"):
        blur(img, float("nan"))


def test02_losses_vanish_on_the_target_and_reject_other_sizes():
    t = _line(12, 20, 6.0)
    assert float(blurred_l2(t, t)[0]) == pytest.approx(0.0, abs=1e-12)
    assert float(chamfer(t, t)[0]) == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(ParameterError, match="the drawing is 21x12, the render 20x12"):
        blurred_l2(t, np.zeros((12, 21)))
    with pytest.raises(ParameterError, match="no line"):
        chamfer(t, np.zeros_like(t))


def test03_gradients_match_finite_differences_far_from_the_target():
    """The line is 8 px from the target's: plain L2 has no gradient for its position there,
    the blurred L2 and the chamfer loss do, and they agree with finite differences."""
    h, w, target = 10, 32, _line(10, 32, 20.0)

    def losses(x: float) -> tuple[float, float, float]:
        r = _line(h, w, x)
        plain = float(np.mean((r - target) ** 2))
        return plain, float(blurred_l2(r, target)[0]), float(chamfer(r, target)[0])

    x0, e = 12.3, 1e-2
    fd = [(a - b) / (2 * e) for a, b in zip(losses(x0 + e), losses(x0 - e), strict=True)]
    # the premise: plain L2's slope here knows nothing of the target (it is mean(r^2)'s)
    alone = (np.mean(_line(h, w, x0 + e) ** 2) - np.mean(_line(h, w, x0 - e) ** 2)) / (2 * e)
    assert fd[0] == pytest.approx(alone, rel=1e-4)
    assert fd[1] < 0 and fd[2] < 0  # both pull the line towards the target (x grows)

    # the same through Dr.Jit's AD: x -> the anti-aliased line image -> the loss
    for k, loss in ((1, blurred_l2), (2, chamfer)):
        x = mi.Float(x0)
        dr.enable_grad(x)
        col = dr.arange(mi.Float, w)
        cover = dr.clip(1.0 - dr.abs(col - x), 0.0, 1.0)  # _line: a box of width 1 at x
        img = mi.TensorXf(dr.gather(mi.Float, cover, dr.arange(mi.UInt32, h * w) % w), (h, w))
        value = loss(img, target)
        dr.backward(value)
        assert float(dr.grad(x)[0]) == pytest.approx(fd[k], rel=2e-2), loss.__name__


def test04_chamfer_is_the_mean_distance_to_the_lines():
    rng = np.random.default_rng(5)
    target = (rng.random((9, 13)) > 0.9).astype(np.float32)
    target[4, 6] = 1.0
    r = rng.random((9, 13)).astype(np.float32)
    d = distance_transform_edt(target <= 0.5)
    assert float(chamfer(r, target)[0]) == pytest.approx((r * d).sum() / r.sum(), rel=1e-5)


def test05_drawings_from_png_and_svg(tmp_path):
    ink = np.zeros((6, 9), np.float32)
    ink[2, 1:8] = 1.0
    rgb = np.repeat(((1.0 - ink) * 255).astype(np.uint8)[..., None], 3, axis=2)
    Image.fromarray(rgb).save(tmp_path / "d.png")
    np.testing.assert_allclose(read_drawing(tmp_path / "d.png"), ink, atol=1e-6)
    rgba = np.zeros((6, 9, 4), np.uint8)  # black but transparent: paper
    Image.fromarray(rgba).save(tmp_path / "t.png")
    assert not read_drawing(tmp_path / "t.png").any()
    svg = tmp_path / "d.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="9" height="6">'
        '<path d="M 1.5 2.5 L 7.5 2.5" stroke-width="1"/></svg>'
    )
    got = read_drawing(svg)
    assert got.shape == (6, 9) and got[2, 2:7].min() == 1.0 and got[4].max() == 0.0
    for bad, text in (("x.png", b"not an image"), ("x.svg", b"<svg")):
        (tmp_path / bad).write_bytes(text)
        with pytest.raises(InputError, match=re.escape(bad)):
            read_drawing(tmp_path / bad)
    with pytest.raises(InputError, match=r"missing\.png"):
        read_drawing(tmp_path / "missing.png")


def _clipped_blur_matrix(length: int, sigma: float) -> np.ndarray:
    """The 1-D blur as a dense matrix: row p sums w_k x[clip(p + k)], built tap by tap."""
    r = max(1, int(np.ceil(3.0 * sigma)))
    k = np.arange(-r, r + 1)
    w = np.exp(-0.5 * (k / sigma) ** 2)
    w /= w.sum()
    m = np.zeros((length, length))
    for p in range(length):
        for kk, ww in zip(k, w, strict=True):
            m[p, min(max(p + kk, 0), length - 1)] += ww
    return m


@pytest.mark.parametrize(
    ("shape", "sigma"), [((1, 7), 1.0), ((3, 2), 2.0), ((5, 40), 8.0), ((33, 17), 1.3)]
)
def test06_blur_backward_is_the_transpose_of_the_clipped_blur(shape, sigma):
    """The blur's hand-written backward pass (gathers, the taps clipped onto a border pixel
    summed there) is A^T g for the dense matrix A of the blur, also where the image is shorter
    than the filter's radius."""
    h, w = shape
    rng = np.random.default_rng(11)
    x = mi.Float(rng.random(h * w).astype(np.float32))
    g = rng.random((h, w)).astype(np.float32)
    dr.enable_grad(x)
    out = blur(mi.TensorXf(x, shape=shape), sigma)
    dr.backward(dr.sum(out.array * mi.Float(g.ravel())))
    A, B = _clipped_blur_matrix(h, sigma), _clipped_blur_matrix(w, sigma)
    ref = A.T @ g.astype(np.float64) @ B
    np.testing.assert_allclose(np.asarray(dr.grad(x)).reshape(h, w), ref, atol=1e-6)
    # and forward mode is A dx
    dx = rng.random((h, w)).astype(np.float32)
    x2 = mi.Float(np.asarray(dr.detach(x)))
    dr.enable_grad(x2)
    dr.set_grad(x2, mi.Float(dx.ravel()))
    out2 = blur(mi.TensorXf(x2, shape=shape), sigma)
    dr.forward_to(out2.array)
    got = np.asarray(dr.grad(out2.array)).reshape(h, w)
    np.testing.assert_allclose(got, A @ dx.astype(np.float64) @ B.T, atol=1e-6)
