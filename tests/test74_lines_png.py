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
