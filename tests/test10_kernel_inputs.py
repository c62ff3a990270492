"""mi_npr.kernels: what goes in (layouts, dtypes, Dr.Jit tensors) and what comes out."""

from __future__ import annotations

import doctest

import drjit as dr
import numpy as np
import pytest
from drjit.llvm.ad import TensorXf, TensorXu

import mi_npr
from mi_npr import kernels as K
from mi_npr.kernels import chain, depth_lines, edges, morphology

RNG = np.random.default_rng(10)


def _calls():
    """One call per kernel on a 7x5 image: (name, function of one image argument)."""
    ids = RNG.integers(0, 3, (7, 5)).astype(np.uint32)
    n = RNG.normal(size=(7, 5, 3)).astype(np.float32)
    return {
        "normalize_depth": lambda a: K.normalize_depth(a),
        "depth_contours": lambda a: K.depth_contours(a, c=2.0, t=0.1),
        "remove_isolated": lambda a: K.remove_isolated(a),
        "selective_dilation": lambda a: K.selective_dilation(a),
        "id_edges": lambda a: K.id_edges(ids if a is None else a),
        "normal_edges": lambda a: K.normal_edges(n, ids if a is None else a, 30.0),
    }


def test01_public_api():
    """The names the issue gives, exactly."""
    assert mi_npr.kernels is K
    functions = "normalize_depth depth_contours remove_isolated selective_dilation id_edges "
    functions += "normal_edges lines leaf_edges"  # leaf_edges: foliage
    functions += " crease_edges widen_lines ink_density"  # line drawings
    assert set(K.__all__) == {"LINES_PARAMS", *functions.split()}
    params = "c t t0 dilation_size dilation_iterations remove_isolated id_edges crease_angle"
    params += " leaf_edges max_density line_width bright_fade"  # issues 8 (foliage), 19
    assert [p.name for p in K.LINES_PARAMS] == [*params.split(), "near", "far"]


@pytest.mark.parametrize("name", list(_calls()))
def test02_result_is_an_evaluated_tensor_of_the_input_shape(name):
    a = RNG.random((7, 5)).astype(np.float32)
    fn = _calls()[name]
    out = fn(None if name in ("id_edges", "normal_edges") else a)
    assert type(out) is mi_npr.mi.TensorXf and tuple(out.shape) == (7, 5)  # the variant's backend
    view = np.asarray(out)
    assert view.shape == (7, 5) and view.dtype == np.float32
    assert np.all(np.isfinite(view)) and view.min() >= 0 and view.max() <= 1


@pytest.mark.parametrize("name", ["normalize_depth", "depth_contours", "remove_isolated"])
def test03_dtypes_tensors_and_views_give_the_same_result(name):
    fn = _calls()[name]
    a = RNG.random((6, 9))
    ref = np.asarray(fn(a.astype(np.float32)))
    wide = np.zeros((6, 18))
    wide[:, ::2] = a  # a strided view
    for x in (a, wide[:, ::2], mi_npr.mi.TensorXf(a.astype(np.float32)), a.tolist()):
        np.testing.assert_array_equal(np.asarray(fn(x)), ref)


def test04_input_arrays_are_not_aliased():
    """Dr.Jit maps float32 numpy memory without a copy; results must not change with it."""
    a = RNG.random((5, 4)).astype(np.float32)
    out = K.selective_dilation(a)
    before = np.asarray(out).copy()
    a[:] = 0.0
    np.testing.assert_array_equal(np.asarray(out), before)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: K.normalize_depth(np.zeros((2, 3, 4))), "Z: expected a (H, W) array"),
        (lambda: K.normalize_depth(np.zeros(5)), "Z: expected a (H, W) array"),
        (lambda: K.normalize_depth(np.zeros((0, 3))), "Z: the image is empty"),
        (lambda: K.depth_contours(np.array([["a"]]), 1, 0), "D: expected numbers"),
        (lambda: K.depth_contours(TensorXf(np.zeros((2, 2, 2))), 1, 0), "D: expected a (H, W)"),
        (lambda: K.depth_contours(np.zeros((2, 2)), -1.0, 0), "c = -1.0: must be"),
        (lambda: K.depth_contours(np.zeros((2, 2)), np.inf, 0), "c = inf"),
        (lambda: K.depth_contours(np.zeros((2, 2)), 1, -0.5), "t = -0.5"),
        (lambda: K.depth_contours(np.zeros((2, 2)), True, 0), "c = True"),
        (lambda: K.remove_isolated(np.zeros((2, 2)), 1.5), "t0 = 1.5: must lie in [0, 1]"),
        (lambda: K.selective_dilation(np.zeros((2, 2)), 4), "size = 4: must be an odd integer"),
        (lambda: K.selective_dilation(np.zeros((2, 2)), 1), "size = 1: must be an odd integer"),
        (lambda: K.selective_dilation(np.zeros((2, 2)), 3.0), "size = 3.0"),
        (lambda: K.selective_dilation(np.zeros((2, 2)), 17), "size = 17: must be at most 15"),
        (lambda: K.selective_dilation(np.zeros((2, 2)), 3, -1), "iterations = -1"),
        (lambda: K.normalize_depth(np.zeros((2, 2)), near=2.0, far=1.0), "near must be less"),
        (lambda: K.normalize_depth(np.zeros((2, 2)), near=np.nan), "near = nan"),
        (lambda: K.id_edges(np.array([[1.5, 2.0]])), "object_id: object ids must be integers"),
        (lambda: K.id_edges(np.array([[np.nan, 2.0]])), "object_id: object ids must be integers"),
        (lambda: K.id_edges(np.array([[-1, 2]])), "object_id: object ids must be >= 0"),
        (lambda: K.normal_edges(np.zeros((2, 2)), np.zeros((2, 2), np.uint32), 30), "N: expected"),
        (
            lambda: K.normal_edges(np.zeros((2, 3, 3)), np.zeros((3, 2), np.uint32), 30),
            "object_id: shape (3, 2) differs from N's (2, 3)",
        ),
        (
            lambda: K.normal_edges(np.zeros((2, 2, 3)), np.zeros((2, 2), np.uint32), 180),
            "angle_deg = 180: must lie in [0, 180)",
        ),
    ],
)
def test05_bad_inputs_name_the_argument(call, message):
    with pytest.raises(mi_npr.ParameterError) as e:
        call()
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test06_ids_as_floats_and_dr_tensors():
    ids = RNG.integers(0, 4, (9, 7)).astype(np.uint32)
    ref = np.asarray(K.id_edges(ids))
    for x in (ids.astype(np.int64), ids.astype(np.float32), TensorXu(ids), TensorXf(ids)):
        np.testing.assert_array_equal(np.asarray(K.id_edges(x)), ref)
    ref_n = np.asarray(K.normal_edges(RNG.normal(size=(9, 7, 3)), ids, 20.0))
    assert ref_n.shape == (9, 7)


def test07_changing_parameters_reuses_the_compiled_kernels():
    d = RNG.random((16, 16)).astype(np.float32)
    K.depth_contours(d, 2.0, 0.1)
    dr.sync_thread()
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
        K.depth_contours(d, 3.5, 0.3)
        K.remove_isolated(d, 0.25)
        K.remove_isolated(d, 0.75)
        dr.sync_thread()
        history = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    # The second remove_isolated must hit the first one's kernel; the first may be new.
    assert history[-1]["cache_hit"] or history[-1]["hash"] == history[-2]["hash"]


@pytest.mark.parametrize("module", [depth_lines, morphology, edges, chain, K])
def test08_docstring_examples_run(module):
    result = doctest.testmod(module, extraglobs={"np": np, "mi_npr": mi_npr}, optionflags=0)
    assert result.failed == 0
