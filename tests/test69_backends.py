"""The kernels run on the backend their inputs live on: a G-buffer rendered on a
GPU stays there. On LLVM this checks the rule with LLVM tensors of both flavours and mixed
inputs; the CUDA half runs where a CUDA device is present (the suite's GPU run) and compares
every kernel's CUDA result with its LLVM result bit for bit."""

from __future__ import annotations

import drjit as dr
import drjit.llvm as llvm_plain
import drjit.llvm.ad as llvm_ad
import numpy as np
import pytest

import mi_npr
from mi_npr import kernels as K
from mi_npr.kernels._stencil import backend

H, W = 9, 13


def _inputs() -> dict[str, np.ndarray]:
    """The same random frame on every call."""
    rng = np.random.default_rng(69)
    z = rng.uniform(1.0, 3.0, (H, W)).astype(np.float32)
    z[2:6, 3:9] = 1.2
    z[0, 0] = np.inf
    ids = np.zeros((H, W), np.uint32)
    ids[2:6, 3:9] = 2
    ids[6:, :4] = 5
    n = rng.normal(size=(H, W, 3)).astype(np.float32)
    lines = (rng.uniform(size=(H, W)) > 0.6).astype(np.float32)
    return {"Z": z, "ids": ids, "N": n, "lines": lines}


def _calls(T: object) -> dict[str, object]:
    """Every kernel, its inputs converted by ``T(name, array)``."""
    a = _inputs()
    d = np.asarray(K.normalize_depth(a["Z"]))
    gb = {
        "Z": T("Z", a["Z"]),
        "object_id.V": T("ids", a["ids"]),
        **{f"N.{c}": T("N", np.ascontiguousarray(a["N"][..., i])) for i, c in enumerate("XYZ")},
    }
    return {
        "normalize_depth": lambda: K.normalize_depth(T("Z", a["Z"])),
        "depth_contours": lambda: K.depth_contours(T("D", d), c=3.0, t=0.1),
        "remove_isolated": lambda: K.remove_isolated(T("lines", a["lines"])),
        "selective_dilation": lambda: K.selective_dilation(T("D", d), 3, 2),
        "id_edges": lambda: K.id_edges(T("ids", a["ids"]), 1, T("Z", a["Z"]), 0.01),
        "normal_edges": lambda: K.normal_edges(T("N", a["N"]), T("ids", a["ids"]), 30.0),
        "crease_edges": lambda: K.crease_edges(T("N", a["N"]), T("ids", a["ids"]), 120.0),
        "leaf_edges": lambda: K.leaf_edges(T("ids", a["ids"]), T("Z", a["Z"]), 1),
        "widen_lines": lambda: K.widen_lines(T("lines", a["lines"]), 3.0),
        "ink_density": lambda: K.ink_density(T("lines", a["lines"]), 5),
        "lines": lambda: K.lines(gb, max_density=0.3, line_width=2.0),
    }


def _tensor(module: object):
    """``T(name, array)`` making tensors of ``module`` (``TensorXu`` for ids)."""

    def T(name: str, a: np.ndarray) -> object:
        return (module.TensorXu if a.dtype == np.uint32 else module.TensorXf)(a)

    return T


def _numpy(name: str, a: np.ndarray) -> np.ndarray:
    return a


def test01_backend_rule():
    """First JIT input wins; numpy alone follows the active variant; plain and AD flavours of
    one backend are one backend (the AD module is used)."""
    mi_npr.set_variant("llvm_ad_rgb")
    assert backend(np.zeros(3)) is llvm_ad
    assert backend(np.zeros(3), llvm_plain.Float([1.0])) is llvm_ad
    assert backend(llvm_ad.TensorXf([1.0])) is llvm_ad


@pytest.mark.parametrize("flavour", ["plain", "ad"])
def test02_llvm_tensors_match_numpy(flavour):
    """LLVM tensors (Dr.Jit's plain and AD types) give the numpy inputs' result, as LLVM AD
    tensors."""
    mi_npr.set_variant("llvm_ad_rgb")  # numpy inputs run on LLVM too
    module = llvm_plain if flavour == "plain" else llvm_ad
    want = {k: np.asarray(f()) for k, f in _calls(_numpy).items()}
    for name, call in _calls(_tensor(module)).items():
        out = call()
        assert type(out) is llvm_ad.TensorXf, name
        np.testing.assert_array_equal(np.asarray(out), want[name], err_msg=name)


def test03_mixed_inputs():
    """numpy next to a tensor is brought to the tensor's backend; an (H, W, 3) tensor of normals
    is split on the device, as the numpy planes are."""
    mi_npr.set_variant("llvm_ad_rgb")
    a = _inputs()
    got = K.normal_edges(llvm_ad.TensorXf(a["N"]), a["ids"], 30.0)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(K.normal_edges(a["N"], a["ids"], 30)))
    got = K.leaf_edges(a["ids"], llvm_plain.TensorXf(a["Z"]), 2)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(K.leaf_edges(a["ids"], a["Z"], 2)))


def _cuda() -> object:
    if "cuda_ad_rgb" not in mi_npr.mi.variants():
        pytest.skip("no CUDA variant in this Mitsuba build")
    try:
        mi_npr.set_variant("cuda_ad_rgb")
    except mi_npr.ParameterError as e:
        pytest.skip(f"CUDA unavailable here: {e}")
    import drjit.cuda.ad as cuda_ad

    return cuda_ad


def test04_cuda_kernels_match_llvm():
    """On a CUDA device every kernel keeps CUDA inputs on the GPU (a ``drjit.cuda.ad`` result)
    and matches LLVM (the same float32 operations; ``ink_density`` divides, so 1 ulp)."""
    cuda_ad = _cuda()
    want = {k: np.asarray(f()) for k, f in _calls(_tensor(llvm_ad)).items()}
    for name, call in _calls(_tensor(cuda_ad)).items():
        out = call()
        assert type(out) is cuda_ad.TensorXf, name
        np.testing.assert_allclose(out.numpy(), want[name], rtol=1e-6, atol=0, err_msg=name)


def test05_cuda_variant_numpy_inputs():
    """With a ``cuda_*`` variant active, numpy inputs go to the GPU, and the whole chain on a
    rendered G-buffer runs there."""
    cuda_ad = _cuda()
    assert backend(np.zeros(3)) is cuda_ad
    out = K.depth_contours(np.asarray(K.normalize_depth(_inputs()["Z"])), c=3.0, t=0.1)
    assert dr.backend_v(out) == dr.JitBackend.CUDA
