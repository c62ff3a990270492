"""Anti-aliased lines from a supersampled G-buffer equal the box-filtered lines of the
same camera rendered on a film N times larger, normalised by each line's coverage peak
(:func:`ref_full_ink`, written from the definition in :mod:`mi_npr.antialias`)."""

from __future__ import annotations

import mitsuba as mi
import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr import layers as L
from mi_npr.antialias import (
    antialiased_lines,
    box_filter,
    chain_reach,
    full_ink_filter,
    strips,
    supersampled_gbuffer,
)
from mi_npr.kernels.depth_lines import finite_range

from .helpers import scene_xml

BODY = (
    '<shape type="sphere" id="ball"><point name="center" x="-0.6" y="0.1" z="5"/>'
    '<float name="radius" value="0.8"/></shape>'
    '<shape type="cube" id="box"><transform name="to_world"><scale value="0.6"/>'
    '<rotate y="1" angle="35"/><rotate x="1" angle="25"/><translate x="0.9" y="-0.2" z="5.5"/>'
    "</transform></shape>"
    '<shape type="rectangle" id="wall"><transform name="to_world">'
    '<scale value="30"/><translate z="12"/></transform></shape>'
)


def _scene(tmp_path, w, h):
    p = tmp_path / f"s{w}x{h}.xml"
    p.write_text(scene_xml(BODY, width=w, height=h, integrator='<integrator type="npr_gbuffer"/>'))
    return mi_npr.load_scene(p)


def ref_box(a, n):
    h, w = a.shape[0] // n, a.shape[1] // n
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            out[y, x] = a[y * n : (y + 1) * n, x * n : (x + 1) * n].astype(np.float64).mean()
    return out


def ref_full_ink(a, n):
    """Each film pixel's block mean ``b`` times ``g / m``, at most ``top`` (the block's largest
    sub-pixel): ``m`` and ``g`` the largest ``b`` and ``top`` over the 3 pixels of the pixel's
    row or column (the one whose ``b`` rises more from its least to its largest value, the row
    on a tie; pixels beyond the border repeat it); 0 where ``m`` is 0."""
    b = ref_box(a, n)
    h, w = b.shape
    top = a.reshape(h, n, w, n).max(axis=(1, 3)).astype(np.float64)
    out = np.zeros((h, w))
    for y in range(h):
        for x in range(w):
            best = None
            for dy, dx in ((0, 1), (1, 0)):
                cells = [
                    (min(max(y + k * dy, 0), h - 1), min(max(x + k * dx, 0), w - 1))
                    for k in (-1, 0, 1)
                ]
                vals = [b[c] for c in cells]
                rise = max(vals) - min(vals)
                if best is None or rise > best[0]:
                    best = (rise, max(vals), max(top[c] for c in cells))
            _, m, g = best
            out[y, x] = 0.0 if m == 0 else min(b[y, x] * g / m, top[y, x])
    return out


def test01_box_filter_matches_reference():
    a = np.random.default_rng(73).random((12, 18)).astype(np.float32)
    for n in (1, 2, 3, 6):
        np.testing.assert_allclose(box_filter(a, n), ref_box(a, n), atol=1e-7)
    with pytest.raises(mi_npr.ParameterError, match="not a multiple of 4"):
        box_filter(a, 4)


def _film_range(gb):
    """The film's nearest and farthest finite depth, as 1-lane arrays (``depth_range``)."""
    z = gb.numpy(L.Z)
    z = z[np.isfinite(z)]
    return mi.Float(float(z.min())), mi.Float(float(z.max()))


@pytest.mark.parametrize("n", [2, 4])
@pytest.mark.parametrize("params", [{}, {"line_width": 1.5, "t": 0.5}])
def test02_supersampled_equals_box_filtered_large_film(tmp_path, n, params):
    """n x n rays per pixel = the pixel centres of a film n times larger (exact for powers of
    two), so the AA lines are the large film's lines, line_width scaled by n, box-filtered and
    normalised."""
    w, h = 24, 16
    scene = _scene(tmp_path, w, h)
    gb = mi_npr.render(scene)
    sensor = scene.sensors()[0]
    big = mi_npr.render(_scene(tmp_path, w * n, h * n))
    sup = supersampled_gbuffer(scene, sensor, n)
    for name in (L.Z, L.OBJECT_ID, *L.N):
        np.testing.assert_array_equal(sup.numpy(name), big.numpy(name), err_msg=name)
    width = params.get("line_width", 1.0)
    frame = _film_range(gb)  # the depths normalised over the film's range, not the big one's
    big_lines = K.lines(big, depth_range=frame, **{**params, "line_width": width * n})
    expected = ref_full_ink(np.asarray(big_lines), n)
    got = np.asarray(antialiased_lines(scene, sensor, gb, n, **params))
    assert got.shape == (h, w) and got.dtype == np.float32
    np.testing.assert_allclose(got, expected, atol=1e-6)
    assert 0 < got[got > 0].min() < 1  # gray levels


def test03_three_by_three_matches_up_to_rounding(tmp_path):
    """n = 3: sub-pixel positions (j + 0.5) / 3 round differently from the large film's, which
    may move a ray by an ulp; the images agree but for rare pixels."""
    w, h, n = 24, 16, 3
    scene = _scene(tmp_path, w, h)
    big = mi_npr.render(_scene(tmp_path, w * n, h * n))
    gb = mi_npr.render(scene)
    lines = K.lines(big, line_width=float(n), depth_range=_film_range(gb))
    expected = ref_full_ink(np.asarray(lines), n)
    got = antialiased_lines(scene, scene.sensors()[0], gb, n)
    assert np.mean(np.abs(got - expected) > 1e-6) < 0.02


def test04_one_ray_is_the_pixel_centre_chain(tmp_path):
    scene = _scene(tmp_path, 20, 14)
    gb = mi_npr.render(scene)
    got = antialiased_lines(scene, scene.sensors()[0], gb, 1, crease_angle=100.0)
    np.testing.assert_array_equal(got, np.asarray(K.lines(gb, crease_angle=100.0)))


def test05_plugin_and_bad_values(write_scene):
    lines = '<integrator type="npr_lines"><integer name="line_aa" value="2"/></integrator>'
    scene = mi_npr.load_scene(write_scene(BODY, integrator=lines))
    gb = mi_npr.render(scene)
    expected = antialiased_lines(scene, scene.sensors()[0], gb, 2)
    np.testing.assert_array_equal(gb.numpy(L.LINES), expected)
    sensor = scene.sensors()[0]
    with pytest.raises(mi_npr.ParameterError, match=r"line_aa = 9: must be an integer in \[1, 8\]"):
        antialiased_lines(scene, sensor, gb, 9)
    with pytest.raises(mi_npr.ParameterError, match="line_width = 8 with line_aa = 2"):
        antialiased_lines(scene, sensor, gb, 2, line_width=8.0)
    with pytest.raises(mi_npr.ParameterError, match="unknown parameter 'cc'"):
        antialiased_lines(scene, sensor, gb, 2, cc=1.0)


@pytest.mark.parametrize("n", [1, 2, 3])
def test06_full_ink_filter_matches_reference(n):
    """Random images (sparse ink, gray levels), one pixel, odd sizes, no ink at all."""
    rng = np.random.default_rng(74 + n)
    cases = [rng.random((7 * n, 9 * n)) * (rng.random((7 * n, 9 * n)) < 0.2)]
    cases += [rng.random((n, n)), rng.random((5 * n, 1 * n)), np.zeros((3 * n, 4 * n))]
    for a in cases:
        a = a.astype(np.float32)
        got = np.asarray(full_ink_filter(a, n))
        assert got.shape == (a.shape[0] // n, a.shape[1] // n) and got.dtype == np.float32
        np.testing.assert_allclose(got, ref_full_ink(a, n), atol=1e-5)
    with pytest.raises(mi_npr.ParameterError, match="full_ink_filter: shape"):
        full_ink_filter(np.zeros((4, 6), np.float32), 4)


def test07_full_ink_filter_hand_made():
    """A 3-sub-pixel band a third into pixel 1 (n = 3): box 2/3 + 1/3, filtered 1 + 1/2; gray
    0.4 keeps its gray; a gray line beside a black one is never darker than its sub-pixels."""
    a = np.zeros((3, 12), np.float32)
    a[:, 4:7] = 1.0
    np.testing.assert_allclose(np.asarray(full_ink_filter(a, 3)), [[0, 1, 0.5, 0]], atol=1e-6)
    np.testing.assert_allclose(
        np.asarray(full_ink_filter(0.4 * a, 3)), [[0, 0.4, 0.2, 0]], atol=1e-6
    )
    a[:, 9] = 1.0  # one black sub-pixel column in pixel 3 ...
    a[:, 4:7] = 0.4  # ... beside the gray band
    got = np.asarray(full_ink_filter(a, 3))[0]
    assert got[1] <= 0.4 + 1e-6 and got[2] <= 0.4 + 1e-6 and got[3] == pytest.approx(1.0)


def test08_full_ink_filter_is_differentiable():
    """d(weighted sum of the filtered image) / d(sub-pixel ink) from ``dr.backward`` agrees with
    central differences of the float64 reference (random inks: no ties, smooth there)."""
    dr, mi = mi_npr.dr, mi_npr.mi
    n, rng = 3, np.random.default_rng(8)
    a = (rng.random((4 * n, 5 * n)) * (rng.random((4 * n, 5 * n)) < 0.5)).astype(np.float32)
    weights = rng.random((4, 5))
    x = mi.TensorXf(a)
    dr.enable_grad(x)
    loss = dr.sum((full_ink_filter(x, n) * mi.TensorXf(weights.astype(np.float32))).array)
    dr.backward(loss)
    grad = np.asarray(dr.grad(x))
    eps = 1e-4
    for y, xx in zip(*np.nonzero(a)[:2], strict=True):
        up, down = a.astype(np.float64), a.astype(np.float64)
        up[y, xx] += eps
        down[y, xx] -= eps
        fd = ((ref_full_ink(up, n) - ref_full_ink(down, n)) * weights).sum() / (2 * eps)
        assert grad[y, xx] == pytest.approx(fd, abs=2e-3), (y, xx)


STRIP_PARAMS = [
    {},
    {"dilation_iterations": 2, "max_density": 0.3, "line_width": 2.0, "crease_angle": 100.0},
    {"near": 3.0, "far": 20.0},
    {"line_width": 0.5, "t": 0.3},
]


@pytest.mark.parametrize("n", [2, 3])
def test09_strips_draw_the_whole_film(tmp_path, n):
    """Drawn in strips of film rows (down to one row a strip: every strip border cuts through
    the sphere's and the cube's outlines), the lines are those of the whole supersampled film,
    bit for bit: odd sizes, dilation, density thinning, wide and thin lines, given depth range."""
    w, h = 23, 17
    scene = _scene(tmp_path, w, h)
    sensor, gb = scene.sensors()[0], mi_npr.render(scene)
    for params in STRIP_PARAMS:
        whole = np.asarray(antialiased_lines(scene, sensor, gb, n, **params))
        assert whole.max() > 0
        for budget in (1, w * n * n * 9):
            got = antialiased_lines(scene, sensor, gb, n, strip_samples=budget, **params)
            np.testing.assert_array_equal(np.asarray(got), whole, err_msg=f"{params} {budget}")
    with pytest.raises(mi_npr.ParameterError, match="strip_samples = 0"):
        antialiased_lines(scene, sensor, gb, n, strip_samples=0)


def test10_strips_cover_every_row_once():
    """Every row in exactly one core; a core's window reaches ``halo`` rows beyond it, or the
    film's border; windows of one height."""
    for h in (1, 2, 7, 10, 31):
        for core in (1, 2, 3, 8, 40):
            for halo in (0, 1, 2, 5):
                parts = strips(h, core, halo)
                rows = [y for r0, r1, _, _ in parts for y in range(r0, r1)]
                assert rows == list(range(h))
                assert len({s1 - s0 for *_, s0, s1 in parts}) == 1
                for r0, r1, s0, s1 in parts:
                    assert 0 <= s0 <= r0 < r1 <= s1 <= h and r1 - r0 <= core
                    assert s0 == 0 or r0 - s0 >= halo
                    assert s1 == h or s1 - r1 >= halo


@pytest.mark.parametrize("params", [*STRIP_PARAMS[:2], {"dilation_size": 5, "line_width": 7.0}])
def test11_chain_reach_bounds_what_the_chain_reads(params):
    """The chain on rows s0..s1 of a random G-buffer (blocky depth, ids and normals), with the
    whole frame's depth range, equals the chain on the whole image at every row farther than
    chain_reach from a cut."""
    rng = np.random.default_rng(11)
    h, w = 60, 30
    blocks = rng.random((h // 4 + 1, w // 5 + 1))
    Z = (2 + 3 * np.kron(blocks, np.ones((4, 5)))[:h, :w]).astype(np.float32)
    Z[rng.random((h, w)) < 0.05] = np.inf
    ids = (np.kron(blocks > 0.5, np.ones((4, 5)))[:h, :w] + 1).astype(np.uint32)
    N = rng.normal(size=(3, h, w)).astype(np.float32)
    gb = {L.Z: Z, L.OBJECT_ID: ids, **{k: N[i] for i, k in enumerate(L.N)}}
    whole = np.asarray(K.lines(gb, **params))
    frame = finite_range(mi_npr.mi.Float(Z.ravel()))
    r = chain_reach(params)
    assert r <= 15
    for s0, s1 in ((0, 30), (20, 60), (12, 48)):
        part = {k: v[s0:s1] for k, v in gb.items()}
        got = np.asarray(K.lines(part, depth_range=frame, **params))
        lo = s0 + (r if s0 > 0 else 0)
        hi = s1 - (r if s1 < h else 0)
        np.testing.assert_array_equal(got[lo - s0 : hi - s0], whole[lo:hi], err_msg=(s0, s1))
