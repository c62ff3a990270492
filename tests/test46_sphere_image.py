"""The quality-sphere picture (matplotlib, the ``plots`` extra), and best-view without it."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from mi_npr import cli
from mi_npr.camera import fibonacci_sphere
from mi_npr.viewpoint import plots_missing, sphere_image

from .test44_best_view_cli import BODY

# viridis at 0 and 1 (#440154, #fde725), written here rather than read from matplotlib.
PURPLE, YELLOW = np.array([68, 1, 84]), np.array([253, 231, 37])


def _pixel(img: np.ndarray, size: int, disc: int, u: float, v: float) -> np.ndarray:
    """The colour at (u, v) in [-1, 1]^2 of disc 0 (left) or 1, with 12-pixel margins and no
    title (8 pixels above the discs)."""
    x = 12 + disc * (size + 12) + (u + 1) / 2 * size
    y = 8 + (1 - v) / 2 * size
    return img[int(y), int(x)].astype(np.int64)


def test01_colours_follow_the_quality():
    d = fibonacci_sphere(400)
    size = 120
    img = sphere_image(d, d[:, 2], size=size)  # quality = z: the left disc faces +z
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[1] == 2 * size + 36
    near_front = _pixel(img, size, 0, 0.25, 0.3)
    near_back = _pixel(img, size, 1, 0.25, 0.3)
    assert np.abs(near_front - YELLOW).max() < 40, near_front
    assert np.abs(near_back - PURPLE).max() < 40, near_back
    # Near the rim (z about 0.2): neither end of the map.
    rim = _pixel(img, size, 0, 0.3, -0.93)
    assert min(np.abs(rim - YELLOW).max(), np.abs(rim - PURPLE).max()) > 60, rim
    # Outside the discs: white.
    assert (_pixel(img, size, 0, -0.97, 0.97) == 255).all()


def test02_marks_and_a_constant_quality():
    d = fibonacci_sphere(64)
    img = sphere_image(d, np.ones(len(d)), best=[0.2, 0.3, 1.0], evaluated=d[d[:, 2] > 0][:5])
    red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
    xs = np.nonzero(red)[1]
    assert len(xs) > 20 and xs.max() < 12 + 240  # the best view's ring, on the left disc only
    white = (img[8 : 8 + 240, 12 : 12 + 240] == 255).all(axis=-1)
    assert white.sum() > 0


def test03_without_matplotlib_best_view_skips_the_picture(
    write_scene, tmp_path, capsys, monkeypatch
):
    scene_path = write_scene(BODY, name="toy.xml", width=40, height=30, spp=1, origin="2, 3, -5")
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    assert "mi-npr[plots]" in plots_missing()
    with pytest.raises(ImportError, match=r"sphere_image: matplotlib is not installed"):
        sphere_image(fibonacci_sphere(8), np.zeros(8))
    out = tmp_path / "o"
    code = cli.main(
        ["best-view", str(scene_path), "--measure", "pb", "--depth", "1", "-o", str(out)]
    )
    err = capsys.readouterr().err
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["toy_best_view.png", "toy_best_view.xml"]
    note = [ln for ln in err.splitlines() if "note" in ln]
    assert len(note) == 1 and "quality sphere picture is skipped" in note[0]
    assert "Traceback" not in err
