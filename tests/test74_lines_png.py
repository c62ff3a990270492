"""Mi-npr render writes <stem>_lines.png (ink on paper) beside the beauty with lines;
--line-width, --line-aa, --line-color and --paper reach the drawing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import cli
from mi_npr import layers as L
from mi_npr.compose import lines_on_paper
from mi_npr.io import read_exr, to_rgb8

from .helpers import scene_xml
from .test18_npr_lines import BALL, lines_integrator


@pytest.fixture
def ball(tmp_path):
    scene = tmp_path / "ball.xml"
    scene.write_text(scene_xml(BALL, integrator=lines_integrator()))
    return scene


def test01_lines_png_is_black_ink_on_white(ball, tmp_path):
    out = tmp_path / "out"
    assert cli.main(["render", str(ball), "-o", str(out), "--no-progress"]) == 0
    gb = read_exr(out / "ball.exr")
    png = np.asarray(Image.open(out / "ball_lines.png"))
    assert png.shape == (*gb.shape, 3)
    ink = gb.numpy(L.LINES)
    assert np.all(png[ink == 0] == 255) and np.all(png[ink == 1] == 0)
    gray = png[(ink > 0) & (ink < 1)]
    assert len(gray) and np.all((gray > 0) & (gray < 255))  # anti-aliased by default
    np.testing.assert_array_equal(png, to_rgb8(np.repeat(1 - ink[..., None], 3, axis=-1)))
    assert json.loads(gb.metadata["mi_npr/lines"])["line_aa"] == 3


def test02_flags_reach_the_drawing(ball, tmp_path):
    out = tmp_path / "out"
    args = ["--line-width", "2", "--line-aa", "2", "--line-color", "1,0,0", "--paper", "0.5"]
    assert cli.main(["render", str(ball), "-o", str(out), "--no-progress", *args]) == 0
    gb = read_exr(out / "ball.exr")
    params = json.loads(gb.metadata["mi_npr/lines"])
    assert params["line_width"] == 2.0 and params["line_aa"] == 2
    png = np.asarray(Image.open(out / "ball_lines.png"))
    np.testing.assert_array_equal(png, to_rgb8(lines_on_paper(gb, (1, 0, 0), (0.5, 0.5, 0.5))))
    assert np.all(png[gb.numpy(L.LINES) == 1] == (255, 0, 0))
    beauty = np.asarray(Image.open(out / "ball.png"))
    assert np.all(beauty[gb.numpy(L.LINES) == 1] == (255, 0, 0))  # the composite's colour too
    # Wider than the default: more ink.
    assert cli.main(["render", str(ball), "-o", str(tmp_path / "d"), "--no-progress"]) == 0
    assert (
        gb.numpy(L.LINES).sum() > read_exr(tmp_path / "d" / "ball.exr").numpy(L.LINES).sum() * 1.5
    )


def test03_errors_are_one_line_and_write_nothing(tmp_path, capsys):
    plain = tmp_path / "plain.xml"
    plain.write_text(scene_xml(BALL))  # npr_gbuffer
    out = tmp_path / "out"
    assert cli.main(["render", str(plain), "-o", str(out), "--no-progress"]) == 0
    assert not (out / "plain_lines.png").exists()  # no lines layer, no drawing
    bad = tmp_path / "bad"
    assert cli.main(["render", str(plain), "-o", str(bad), "--no-progress", "--line-aa", "2"]) == 1
    err = capsys.readouterr().err
    assert (
        "--line-aa: no drawing of this render takes it (add --lines)" in err and str(plain) in err
    )
    assert len(err.strip().splitlines()) == 1 and not list(bad.glob("*"))
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(plain), "-o", str(bad), "--paper", "red"])
    assert e.value.code == 2 and "'red' is not a colour" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["render", str(plain), "-o", str(bad), "--line-width", "-1"])


def test04_drawing_needs_lines():
    gb = mi_npr.GBuffer({L.Z: np.ones((2, 2), np.float32)})
    with pytest.raises(mi_npr.ParameterError, match=r"no 'lines\.V' layer"):
        lines_on_paper(gb)


def test05_srgb_encoding_is_the_formula_bit_for_bit():
    """The PNG writers' encoding against IEC 61966-2-1 written out in float32 (NaN black, +inf
    white, -inf black, alpha stored linear)."""
    from mi_npr.io.png import linear_to_srgb, to_rgb8

    x = np.linspace(-0.01, 1.01, 2_000_001).astype(np.float32)
    x = np.concatenate([x, np.arange(0, 0x3F800001, 4099, dtype=np.uint32).view(np.float32)])
    x = np.concatenate([x, np.array([np.nan, np.inf, -np.inf, 3.0, -2.0], np.float32)])
    c = np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0)
    want = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    assert want.dtype == np.float32 and linear_to_srgb(x).tobytes() == want.tobytes()
    clean = np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0)
    c = np.clip(clean, 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    rgba = np.stack([x, x[::-1], x, x[::-1]], -1).reshape(-1, 4, 4)
    got = to_rgb8(rgba)
    alpha = np.clip(clean[::-1], 0.0, 1.0)
    for i, v in enumerate((srgb, srgb[::-1], srgb, alpha)):
        assert np.array_equal(got[..., i].reshape(-1), (v * 255.0 + 0.5).astype(np.uint8))
    assert np.array_equal(
        to_rgb8(x.reshape(1, -1), linear=False)[0], (c * 255.0 + 0.5).astype(np.uint8)
    )


def test06_over_is_the_mix_bit_for_bit():
    from mi_npr.compose import over

    rng = np.random.default_rng(0)
    rgb = rng.normal(size=(13, 17, 3)).astype(np.float32)
    a = rng.normal(0.5, 0.6, (13, 17)).astype(np.float32)
    a[::3, ::4], a[1::5, 2::3], a[2::4, ::5] = np.nan, 0.0, 1.0
    color = (0.25, 0.7, 1.5)
    k = np.clip(np.where(np.isnan(a), 0.0, a), 0.0, 1.0).astype(np.float32)[..., None]
    want = rgb * (np.float32(1) - k) + np.asarray(color, np.float32) * k
    got = over(rgb, a, color)
    assert got.dtype == np.float32 and got.tobytes() == want.tobytes()
    sheet = np.broadcast_to(np.float32(0.9), (13, 17, 3))
    assert over(sheet, a, color).tobytes() == (sheet * (1 - k) + np.float32(color) * k).tobytes()
