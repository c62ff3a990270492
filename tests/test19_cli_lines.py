"""mi-npr render with npr_lines: the lines layer in the EXR, the composited beauty in the PNG."""

from __future__ import annotations

import numpy as np
from PIL import Image

from mi_npr import cli
from mi_npr import layers as L
from mi_npr.io import read_exr, to_rgb8

from .helpers import run_cli, scene_xml
from .test18_npr_lines import BALL, lines_integrator


def test01_exr_has_lines_and_png_is_the_composited_beauty(tmp_path, capsys):
    scene = tmp_path / "ball.xml"
    color = '<rgb name="line_color" value="0, 0, 1"/>'
    scene.write_text(scene_xml(BALL, integrator=lines_integrator(color), spp=2))
    out = tmp_path / "out"
    assert cli.main(["render", str(scene), "-o", str(out), "--no-progress"]) == 0
    gb = read_exr(out / "ball.exr")
    assert gb.numpy(L.LINES).dtype == np.float32 and gb.numpy(L.LINES).max() == 1.0
    assert set(L.RAW_RGB) <= set(gb.names) and gb.metadata["mi_npr/integrator"] == "npr_lines"
    png = np.asarray(Image.open(out / "ball.png"))
    np.testing.assert_array_equal(png, to_rgb8(gb.beauty))  # R G B: with the lines
    drawn = gb.numpy(L.LINES) == 1.0
    assert np.all(png[drawn] == (0, 0, 255))
    raw = to_rgb8(gb.stack(L.RAW_RGB))
    assert not np.array_equal(png, raw) and np.array_equal(
        png[~(gb.numpy(L.LINES) > 0)], raw[~(gb.numpy(L.LINES) > 0)]
    )
    assert cli.main(["info", str(out / "ball.exr")]) == 0
    info = capsys.readouterr().out
    assert "gray-level line image" in info and "beauty red before lines" in info


def test02_paper_scene_with_define(tmp_path, scenes):
    out = tmp_path / "o"
    args = ["-D", "width=48", "-D", "height=36", "-D", "spp=1", "-D", "integrator=npr_lines"]
    proc = run_cli("render", str(scenes / "scene3.xml"), "-o", str(out), "--no-progress", *args)
    assert proc.returncode == 0, proc.stderr
    gb = read_exr(out / "scene3.exr")
    assert gb.numpy(L.LINES).any() and gb.shape == (36, 48)
    assert gb.metadata["mi_npr/integrator"] == "npr_lines"


def test03_bad_parameter_is_one_line(tmp_path, capsys):
    scene = tmp_path / "bad.xml"
    bad = '<integer name="dilation_size" value="4"/>'
    scene.write_text(scene_xml(BALL, integrator=lines_integrator(bad)))
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "o"), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "dilation_size" in err and str(scene) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
