"""The four line variants of the thesis's claim, and popping of real rendered frames."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mi_npr import ParameterError
from mi_npr import camera as C
from mi_npr import layers as L
from mi_npr import paths as P
from mi_npr.coherence import VARIANTS, line_variants, variant_lines

from .helpers import SCENES

SCENE3 = str(SCENES / "scene3.xml")


def _step(z_right: float) -> dict:
    """Z = 10 on the left half, ``z_right`` on the right: with the frame's range [10, 40]
    (far = 4 x near), eq. 5.1 gives ``c * (z_right - 10) / 30 - t`` on the near side."""
    Z = np.full((9, 12), 10.0, np.float32)
    Z[:, 6:] = z_right
    return {L.Z: Z}


@pytest.mark.parametrize(("z_right", "gray"), [(11.05, 0.4), (11.15, 0.533), (12.5, 1.0)])
def test01_gray_levels_and_their_threshold(z_right, gray):
    gb = _step(z_right)
    g = variant_lines(gb, "gray")
    bw = variant_lines(gb, "black/white")
    assert g.max() == pytest.approx(gray, abs=2e-3)
    assert set(np.unique(bw)) <= {0.0, 1.0}
    np.testing.assert_array_equal(bw, (g > 0.5).astype(np.float32))
    assert np.count_nonzero(g) == 9  # one column, the near side of the step


def test02_prefilter_variants_and_bad_names():
    gb = _step(12.5)
    pre = variant_lines(gb, "gray + pre-filter + eq. 5.2")
    assert pre.max() == pytest.approx(1.0) and np.all(pre[:, :4] == 0)
    with pytest.raises(ParameterError, match="line variant"):
        variant_lines(gb, "grey")
    assert len(VARIANTS) == 4


def test03_a_static_camera_does_not_pop_in_real_frames(tmp_path):
    cam = C.orbit(SCENE3, 1)[0]
    fr = P.render_frames(
        SCENE3, [cam, cam, cam], tmp_path, ["lines"], resolution=(48, 36), spp=1, variants=True
    )
    assert fr.coherence["overall"] == 0.0 and sum(fr.coherence["ink"]) > 0
    for v in line_variants(fr.gbuffers).values():
        assert v["overall"] == 0.0
    data = json.loads((tmp_path / "coherence.json").read_text())
    assert data["per_frame"] == [0.0, 0.0] and set(data["variants"]) == set(VARIANTS)


def test04_a_moving_camera_pops_a_little(tmp_path):
    cams = C.orbit(SCENE3, 4, 12.0)
    fr = P.render_frames(SCENE3, cams, tmp_path, ["lines"], resolution=(64, 48), spp=1)
    c = fr.coherence
    assert len(c["per_frame"]) == 3 and 0 < c["overall"] < 0.5
    np.testing.assert_allclose(np.add(c["appeared"], c["vanished"]), c["per_frame"])
