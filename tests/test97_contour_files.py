"""``mi_npr.io.write_contour_outputs`` from Python writes the files ``mi-npr contours`` writes:
given ``vectorize``'s outlines, byte for byte; without them, the SVG holds the pixel contours.

One render feeds both writers: two renders of a path-traced beauty may differ in the last bit
(the film's reconstruction filter splats samples with atomic additions, in thread order)."""

from __future__ import annotations

import filecmp

import mi_npr
from mi_npr import cli
from mi_npr.contours import vectorize
from mi_npr.pipeline import render_layers

from .helpers import SCENES

SCENE = SCENES / "scene1.xml"
SIZE = ("--width", "64", "--height", "48", "--spp", "1")


def test01_python_writes_the_commands_files(tmp_path):
    argv = ["contours", str(SCENE), "-o", str(tmp_path / "cli"), "--no-progress"]
    assert cli.main([*argv, *SIZE]) == 0
    names = sorted(f.name for f in (tmp_path / "cli").iterdir())
    # the command's job, on one render: what `mi-npr contours` writes ...
    r = render_layers(SCENE, ["contours"], scene_drawings=False, resolution=(64, 48), spp=1)
    command = mi_npr.io.write_layered_outputs(r, tmp_path / "cmd", "scene1", only="contours")
    assert sorted(f.name for f in command) == names
    # ... and what Python writes from the same render
    gb = r.drawing("contours")
    scene = mi_npr.load_scene(SCENE, width=64, height=48, spp=1)
    files = mi_npr.io.write_contour_outputs(
        gb, r.contours, tmp_path / "api", "scene1", paths=vectorize(gb, scene)
    )
    assert [f.name for f in files] == [
        "scene1_contours.exr",
        "scene1_contours.png",
        "scene1_contours.svg",
    ]
    for f in files:
        assert filecmp.cmp(f, tmp_path / "cmd" / f.name, shallow=False), f.name
    # Without the outlines: the same EXR and PNG, the pixel contours in the SVG.
    plain = mi_npr.io.write_contour_outputs(gb, r.contours, tmp_path / "px", "scene1")
    assert filecmp.cmp(plain[0], files[0], shallow=False)
    assert filecmp.cmp(plain[1], files[1], shallow=False)
    svg = plain[2].read_text()
    assert svg.count("<path") == len(r.contours) and svg != files[2].read_text()
