"""lines(gbuffer, **params): the thesis's chain, against the composition of the kernels and of
the brute-force references of tests 11-15."""

from __future__ import annotations

import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr import layers as L

from .test11_normalize_depth import ref_normalize
from .test12_depth_contours import ref_contours
from .test13_remove_isolated import ref_remove_isolated
from .test14_selective_dilation import ref_selective_dilation
from .test71_line_sides import ref_crease_edges, ref_id_edges_1px

RNG = np.random.default_rng(16)
SIZES = [(1, 1), (1, 9), (9, 1), (7, 5), (64, 48)]
DEFAULTS = {p.name: p.default for p in K.LINES_PARAMS}


def ref_chain_depth(Z, near=None, far=None):
    """The chain's depth: test 11's normalisation, except that with ``far`` unset
    the far bound is at least ``4 * near`` (a step counts against at least the depth where it
    happens) and the background reads 2, a full step from every finite pixel."""
    Z = np.asarray(Z, dtype=np.float64)
    finite = np.isfinite(Z)
    if far is None and finite.any():
        n = Z[finite].min() if near is None else near
        far = max(Z[finite].max(), n + 3.0 * max(n, 0.0))
        if near is not None:
            far = max(far, near)
        if far <= n:
            far = None  # a flat frame: test 11's step
    D = ref_normalize(Z, near, far)
    D[~finite] = 2.0
    return D.astype(np.float32)


def ref_lines(gb, **params):
    """The chain written with the references: normalise -> selective dilation -> eq. 5.1 ->
    eq. 5.2 -> max with 1-px ID and crease edges (sides by the dilated depth, step t / c)."""
    p = {**DEFAULTS, **params}
    D = ref_chain_depth(gb[L.Z], p["near"], p["far"])
    D = ref_selective_dilation(D, p["dilation_size"], p["dilation_iterations"], top=2.0)
    ink = ref_contours(D.astype(np.float32), p["c"], p["t"], top=2.0)
    if p["remove_isolated"]:
        ink = ref_remove_isolated(ink, p["t0"])
    step = np.float32(p["t"] / p["c"]) if p["c"] > 0 else np.inf
    # Like the chain: defaults skip what the G-buffer has no layers for.
    if p["id_edges"] and L.OBJECT_ID in gb:
        ink = np.maximum(ink, ref_id_edges_1px(gb[L.OBJECT_ID], D, step))
    if p["crease_angle"] > 0 and L.OBJECT_ID in gb and L.N[0] in gb:
        n = np.stack([gb[k] for k in L.N], axis=-1)
        ink = np.maximum(ink, ref_crease_edges(n, gb[L.OBJECT_ID], p["crease_angle"], D, step))
    return ink


def kernel_lines(gb, **params):
    """The same chain from the public kernels, one call each (for a G-buffer without background
    and with ``far`` given, where the chain's depth is :func:`normalize_depth`'s)."""
    p = {**DEFAULTS, **params}
    D = K.normalize_depth(gb[L.Z], p["near"], p["far"])
    if p["dilation_iterations"]:
        D = K.selective_dilation(D, p["dilation_size"], p["dilation_iterations"])
    ink = K.depth_contours(D, p["c"], p["t"])
    if p["remove_isolated"]:
        ink = K.remove_isolated(ink, p["t0"])
    ink = np.asarray(ink)
    step = p["t"] / p["c"] if p["c"] > 0 else np.inf
    if p["id_edges"]:
        e = K.id_edges(gb[L.OBJECT_ID], 1, Z=D, step=step)
        ink = np.maximum(ink, np.asarray(e))
    if p["crease_angle"] > 0:
        n = np.stack([gb[k] for k in L.N], axis=-1)
        e = K.crease_edges(n, gb[L.OBJECT_ID], p["crease_angle"], Z=D, step=step)
        ink = np.maximum(ink, np.asarray(e))
    return ink


def blocks(shape):
    """A G-buffer of a few boxes at different depths in front of a slanted wall and background."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    Z = 8.0 + 0.05 * xx + 0.03 * yy
    ids = np.ones(shape, np.uint32)
    for k in range(2, 6):
        y0, x0 = RNG.integers(0, h), RNG.integers(0, w)
        y1, x1 = y0 + RNG.integers(1, h // 2 + 2), x0 + RNG.integers(1, w // 2 + 2)
        Z[y0:y1, x0:x1] = RNG.uniform(2.0, 7.0)
        ids[y0:y1, x0:x1] = k
    sky = RNG.random(shape) < 0.05
    Z[sky], ids[sky] = np.inf, 0
    n = RNG.normal(size=(*shape, 3)).astype(np.float32)
    return {L.Z: Z, L.OBJECT_ID: ids, **{k: n[..., i] for i, k in enumerate(L.N)}}


CASES = [
    {},  # ID edges and creases at 134 degrees by default
    {"dilation_iterations": 0, "remove_isolated": False},
    {"c": 5.0, "t": 0.5, "t0": 0.2, "dilation_size": 5, "dilation_iterations": 2},
    {"id_edges": False, "crease_angle": 0.0},
    {"crease_angle": 140.0, "near": 1.0, "far": 20.0, "id_edges": False},
    {"id_edges": True, "crease_angle": 170.0, "remove_isolated": False, "far": 9.0, "c": 0.0},
]


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("params", CASES)
def test01_chain_is_the_composition_of_the_kernels(shape, params):
    gb = blocks(shape)
    gb[L.Z] = np.where(np.isfinite(gb[L.Z]), gb[L.Z], 30.0)  # a far wall, no background
    params = {**params, "far": params.get("far", 40.0)}
    np.testing.assert_array_equal(np.asarray(K.lines(gb, **params)), kernel_lines(gb, **params))


@pytest.mark.parametrize("shape", SIZES)
@pytest.mark.parametrize("params", CASES)
def test02_chain_matches_the_references(shape, params):
    gb = blocks(shape)
    # 1e-5: eq. 5.1 multiplies float32 rounding of the normalised depth by c = 40.
    np.testing.assert_allclose(
        np.asarray(K.lines(gb, **params)), ref_lines(gb, **params), atol=1e-5
    )


@pytest.mark.parametrize("shape", SIZES)
def test03_no_edges_no_lines(shape):
    for Z in (np.full(shape, 3.0), np.full(shape, np.inf)):
        gb = {L.Z: Z, L.OBJECT_ID: np.ones(shape, np.uint32)}
        assert not np.asarray(K.lines(gb, id_edges=True)).any()


def test04_accepts_a_gbuffer_and_nan_never_spreads():
    gb = blocks((32, 24))
    gb[L.Z][3, 4] = np.nan
    gbuf = mi_npr.GBuffer(gb)
    out = np.asarray(K.lines(gbuf, id_edges=True, crease_angle=150.0))
    assert out.shape == (32, 24) and np.all(np.isfinite(out))
    np.testing.assert_allclose(out, ref_lines(gb, id_edges=True, crease_angle=150.0), atol=1e-5)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"c": -1.0}, "lines: parameter 'c' = -1.0: must be a finite number >= 0"),
        ({"t": float("nan")}, "parameter 't' = nan"),
        ({"t0": 1.5}, "parameter 't0' = 1.5: must lie in [0, 1]"),
        ({"dilation_size": 4}, "parameter 'dilation_size' = 4: must be an odd integer >= 3"),
        ({"dilation_size": 1}, "parameter 'dilation_size' = 1"),
        ({"dilation_iterations": -2}, "parameter 'dilation_iterations' = -2"),
        ({"crease_angle": -5.0}, "parameter 'crease_angle' = -5.0: must lie in [0, 180]"),
        ({"line_width": 0.0}, "parameter 'line_width' = 0.0: must lie in (0, 15]"),
        ({"max_density": 1.5}, "parameter 'max_density' = 1.5: must lie in (0, 1]"),
        ({"near": 5.0, "far": 1.0}, "lines: near = 5.0, far = 1.0: near must be less than far"),
        ({"cc": 1.0}, "lines: unknown parameter 'cc'"),
        ({"remove_isolated": "maybe"}, "parameter 'remove_isolated' = 'maybe'"),
        ({"dilation_size": float("inf")}, "parameter 'dilation_size' = inf: expected an integer"),
        ({"dilation_iterations": float("nan")}, "'dilation_iterations' = nan: expected an int"),
        ({"c": 1e39}, "parameter 'c' = 1e+39: must be a finite number (float32)"),
        ({"far": 1e39}, "far"),
    ],
)
def test05_bad_parameters_name_the_parameter(params, message):
    with pytest.raises(mi_npr.ParameterError) as e:
        K.lines(blocks((4, 5)), **params)
    assert message in str(e.value)


def test06_missing_or_mismatched_layers():
    with pytest.raises(mi_npr.ParameterError, match="no 'Z' layer"):
        K.lines({L.OBJECT_ID: np.zeros((3, 3), np.uint32)})
    z_only = {L.Z: np.ones((3, 3))}
    assert K.lines(z_only).shape == (3, 3)  # depth alone is enough by default
    with pytest.raises(mi_npr.ParameterError, match=r"no 'object_id\.V' layer"):
        K.lines(z_only, id_edges=True)
    with pytest.raises(mi_npr.ParameterError, match=r"no 'N\.X' layer"):
        K.lines({**z_only, L.OBJECT_ID: np.zeros((3, 3), np.uint32)}, crease_angle=160.0)
    with pytest.raises(mi_npr.ParameterError, match=r"object_id\.V: shape"):
        K.lines({L.Z: np.ones((3, 4)), L.OBJECT_ID: np.zeros((4, 3), np.uint32)}, id_edges=True)


def test07_numpy_scalars_are_the_values_they_hold():
    Z = blocks((9, 11))
    plain = np.asarray(K.lines(Z, c=40.0, dilation_size=3, remove_isolated=True, t0=0.5))
    numpy = K.lines(
        Z, c=np.float32(40), dilation_size=np.int64(3), remove_isolated=np.True_, t0=np.float64(0.5)
    )
    np.testing.assert_array_equal(np.asarray(numpy), plain)


def test08_huge_finite_values_never_make_nan():
    c = float(np.finfo(np.float32).max)  # the largest accepted gain
    Z = blocks((9, 11))
    assert np.isfinite(np.asarray(K.lines(Z, c=c))).all()
    D = np.asarray(K.normalize_depth(np.array([[-3e38, 0.0, 3e38]], np.float32)))
    np.testing.assert_array_equal(D, [[0.0, 0.5, 1.0]])
    D = np.asarray(K.normalize_depth(np.array([[-3e38, 0.0, 3e38]]), near=-3e38, far=3e38))
    np.testing.assert_array_equal(D, [[0.0, 0.5, 1.0]])
