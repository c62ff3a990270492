"""The kernel benchmark's OpenCV anchor computes the chain it is timed against: CI never runs the
benchmarks, so a change of the chain's defaults would otherwise leave the anchor measuring
something else (``outputs agree`` in its report)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import mi_npr

from .helpers import ROOT

pytest.importorskip("cv2")


@pytest.fixture(scope="module")
def bench():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_kernels
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return bench_kernels


@pytest.mark.parametrize(("w", "h"), [(64, 48), (33, 17)])
def test01_opencv_anchor_equals_the_chain(bench, w, h):
    scene = mi_npr.load_scene(bench.SCENE, width=w, height=h, spp=1)
    gb = mi_npr.render_gbuffer(scene)
    ours = np.asarray(mi_npr.kernels.lines(gb, id_edges=True, crease_angle=0))
    anchor = bench.opencv_lines(gb.numpy("Z"), gb.numpy("object_id.V"))
    assert np.count_nonzero(ours) > 0.02 * w * h  # the scene has lines at this size
    # The benchmark's own criterion: gray levels within 1e-5 (eq. 5.1 multiplies a depth
    # difference by c = 40, so one float32 ulp of D moves a gray level by ~5e-6).
    np.testing.assert_allclose(ours, anchor, rtol=0, atol=1e-5)
