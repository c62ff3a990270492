"""Property-based tests (hypothesis) for the kernels, the tracer and the writers on
random shapes, sizes, dtypes and non-finite values, against the brute-force references of the
earlier tests. Small ``max_examples`` keep them fast."""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from PIL import Image

import mi_npr
from mi_npr import kernels as K
from mi_npr.contours import contour_mask, trace
from mi_npr.io import read_exr, write_exr, write_png, write_svg

from .test11_normalize_depth import ref_normalize
from .test12_depth_contours import ref_contours
from .test13_remove_isolated import ref_remove_isolated
from .test14_selective_dilation import ref_selective_dilation
from .test16_lines_chain import ref_lines
from .test20_contour_trace import brute_contour_pixels

FAST = settings(
    max_examples=20,
    deadline=None,
    derandomize=True,  # the same examples on every run: CI stays reproducible
    suppress_health_check=[
        HealthCheck.function_scoped_fixture,
        HealthCheck.too_slow,
        HealthCheck.filter_too_much,  # arrays of few distinct levels: hypothesis retries a lot
    ],
)
SHAPES = hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=9)
FLOATS = st.sampled_from([np.float16, np.float32, np.float64])


def depth_images(finite_only=False):
    """Depth in a few levels (so steps and ties happen) with NaN and +-inf sprinkled in."""
    levels = st.sampled_from([0.5, 1.0, 2.0, 2.5, 7.0, 1e3])
    if not finite_only:
        levels = levels | st.sampled_from([math.nan, math.inf, -math.inf])
    return st.tuples(SHAPES, FLOATS).flatmap(lambda sd: hnp.arrays(sd[1], sd[0], elements=levels))


def unit_images():
    return st.tuples(SHAPES, FLOATS).flatmap(
        lambda sd: hnp.arrays(
            sd[1],
            sd[0],
            elements=st.sampled_from([0.0, 0.25, 0.5, 0.75, 1.0, 2.0, -1.0, math.nan, math.inf]),
        )
    )


@FAST
@given(depth_images())
def test01_normalize_depth(Z):
    got = np.asarray(K.normalize_depth(Z))
    assert got.shape == Z.shape and np.all(np.isfinite(got)) and got.min() >= 0 and got.max() <= 1
    np.testing.assert_allclose(got, ref_normalize(Z.astype(np.float32)), atol=1e-6)


@FAST
@given(unit_images(), st.sampled_from([(1.0, 0.0), (8.0, 1.5), (40.0, 1.0)]))
def test02_depth_contours(D, ct):
    got = np.asarray(K.depth_contours(D, *ct))
    assert np.all(np.isfinite(got)) and got.min() >= 0 and got.max() <= 1
    np.testing.assert_allclose(got, ref_contours(D.astype(np.float32), *ct), atol=1e-5)


@FAST
@given(unit_images(), st.sampled_from([0.0, 0.5, 1.0]))
def test03_remove_isolated(P, t0):
    got = np.asarray(K.remove_isolated(P, t0))
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, ref_remove_isolated(P.astype(np.float32), t0), atol=1e-6)


@FAST
@given(unit_images(), st.sampled_from([3, 5]), st.integers(0, 2))
def test04_selective_dilation_exact(D, n, it):
    got = np.asarray(K.selective_dilation(D, n, it))
    np.testing.assert_array_equal(got, ref_selective_dilation(D.astype(np.float32), n, it))


@FAST
@given(depth_images())
def test05_lines_chain(Z):
    gb = {"Z": Z}
    got = np.asarray(K.lines(gb))
    assert np.all(np.isfinite(got)) and got.min() >= 0 and got.max() <= 1
    np.testing.assert_allclose(got, ref_lines({"Z": Z.astype(np.float32)}), atol=1e-5)


ID_DTYPES = st.sampled_from([np.uint8, np.uint16, np.int32, np.uint32, np.float32])


@FAST
@given(
    st.tuples(SHAPES, ID_DTYPES).flatmap(
        lambda sd: hnp.arrays(sd[1], sd[0], elements=st.sampled_from([0, 1, 2, 3]))
    )
)
def test06_tracer(ids):
    border = trace(ids)
    mask = np.zeros(ids.shape, bool)
    for c in border:
        mask[c.ys, c.xs] = True
        if len(c) > 1:  # 8-connected chains
            assert (np.abs(np.diff(c.points, axis=0)).max(axis=1) == 1).all()
    assert np.array_equal(mask, brute_contour_pixels(ids.astype(np.int64)))
    assert np.array_equal(mask, contour_mask(ids))
    walks = trace(ids, method="code_direction")
    assert len(walks) == len(border)
    for b, w in zip(border, walks, strict=True):
        if w.closed:  # closed means the whole piece
            assert set(map(tuple, b.points.tolist())) <= set(map(tuple, w.points.tolist()))


@FAST
@given(
    st.tuples(
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=7),
        st.sampled_from([None, 3, 4]),
        st.sampled_from([np.float16, np.float32, np.float64, np.uint8]),
    ).flatmap(
        lambda a: hnp.arrays(
            a[2],
            a[0] if a[1] is None else (*a[0], a[1]),
            elements=st.sampled_from([0, 1, 0.5, 2.0, -1.0, math.nan, math.inf])
            if a[2] != np.uint8
            else st.integers(0, 255),
        )
    )
)
def test07_write_png(tmp_path_factory, image):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "invalid value encountered in cast"
        path = write_png(tmp_path_factory.mktemp("png") / "a.png", image)
    with Image.open(path) as im:
        assert (im.height, im.width) == image.shape[:2]
        px = np.asarray(im)
    if image.dtype != np.uint8:
        nan = np.isnan(image.astype(np.float64))
        assert np.all(px[nan] == 0)  # NaN is black


@FAST
@given(
    st.tuples(SHAPES, st.sampled_from([np.float16, np.float32])).flatmap(
        lambda sd: hnp.arrays(sd[1], sd[0], elements=st.floats(width=16, allow_subnormal=False))
    )
)
def test08_exr_round_trip_is_bit_exact(tmp_path_factory, Z):
    gb = mi_npr.GBuffer({"Z": Z.astype(np.float32)})
    back = read_exr(write_exr(tmp_path_factory.mktemp("exr") / "a.exr", gb))
    np.testing.assert_array_equal(
        back.numpy("Z").view(np.uint32), Z.astype(np.float32).view(np.uint32)
    )


@FAST
@given(
    st.tuples(SHAPES, ID_DTYPES).flatmap(
        lambda sd: hnp.arrays(sd[1], sd[0], elements=st.sampled_from([0, 1, 2]))
    ),
    st.text(max_size=8),
)
def test09_write_svg_is_valid_xml(tmp_path_factory, ids, name):
    objects = {1: name, 2: name + "\x1b<&>"}
    cs = trace(ids, objects=objects)
    h, w = ids.shape
    path = write_svg(tmp_path_factory.mktemp("svg") / "a.svg", cs, w, h, title=name)
    root = ET.parse(path).getroot()
    assert root.get("width") == str(w) and root.get("height") == str(h)
