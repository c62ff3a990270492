"""``mi-npr raytree``: EXR with every layer, overlay PNG, --max-depth, one-line errors."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mi_npr import cli
from mi_npr import layers as L
from mi_npr.io import read_exr, to_rgb8

from .helpers import run_cli, scene_xml
from .test34_npr_raytree_plugin import SCENE, raytree_integrator


@pytest.fixture
def glassy(tmp_path) -> Path:
    p = tmp_path / "glassy.xml"
    p.write_text(scene_xml(SCENE, integrator=raytree_integrator(), spp=2))
    return p


def _files(d: Path) -> list[str]:
    return sorted(os.listdir(d)) if d.exists() else []


def test01_writes_exr_and_overlay_png(glassy, tmp_path):
    out = tmp_path / "out"
    assert cli.main(["raytree", str(glassy), "-o", str(out), "--no-progress"]) == 0
    assert _files(out) == ["glassy.exr", "glassy_raytree.png", "glassy_raytree.svg"]
    gb = read_exr(out / "glassy.exr")
    for name in (L.RAYTREE_HI, L.RAYTREE_LO, *L.EDGES, *L.RAW_RGB, *L.GBUFFER):
        assert name in gb, name
    assert gb.numpy(L.RAYTREE_HI).dtype == np.uint32
    assert gb.metadata["mi_npr/integrator"] == "npr_raytree"
    png = np.asarray(Image.open(out / "glassy_raytree.png"))
    np.testing.assert_array_equal(png, to_rgb8(gb.beauty))
    real = gb.numpy(L.EDGES_REAL) > 0
    assert np.all(png[real] == [255, 0, 0])


def test02_max_depth_spp_and_defines(glassy, tmp_path):
    out = tmp_path / "out"
    args = ["raytree", str(glassy), "-o", str(out), "--max-depth", "1", "--spp", "3"]
    assert cli.main([*args, "-D", "unused=1"]) == 1  # Mitsuba refuses unused defines
    assert cli.main(args) == 0
    gb = read_exr(out / "glassy.exr")
    assert gb.metadata["mi_npr/raytree_max_depth"] == "1" and gb.metadata["mi_npr/spp"] == "3"
    assert not gb.numpy(L.EDGES_REFLECTION).any()


def test03_paper_scenes_with_defines(scenes, tmp_path):
    out = tmp_path / "o"
    args = [str(scenes / "scene1.xml"), str(scenes / "scene2.xml"), "-o", str(out)]
    sizes = ["-D", "width=24", "-D", "height=18", "-D", "spp=1", "--no-progress"]
    assert cli.main(["raytree", *args, *sizes]) == 0
    assert _files(out) == [
        "scene1.exr",
        "scene1_raytree.png",
        "scene1_raytree.svg",
        "scene2.exr",
        "scene2_raytree.png",
        "scene2_raytree.svg",
    ]
    one, two = read_exr(out / "scene1.exr"), read_exr(out / "scene2.exr")
    np.testing.assert_array_equal(one.numpy(L.EDGES_REAL), two.numpy(L.EDGES_REAL))


@pytest.mark.parametrize(
    ("extra", "code", "expected"),
    [
        (["--max-depth", "0"], 2, "argument --max-depth: '0': must be in 1..31"),
        (["--max-depth", "99"], 2, "argument --max-depth: '99': must be in 1..31"),
        (["-D", "width"], 2, "expected name=value"),
    ],
)
def test04_bad_arguments(glassy, tmp_path, extra, code, expected):
    out = tmp_path / "out"
    res = run_cli("raytree", str(glassy), "-o", str(out), *extra)
    assert res.returncode == code, res.stderr
    assert "Traceback" not in res.stderr and expected in res.stderr.splitlines()[-1]
    assert _files(out) == []


def test05_missing_scene_among_others(glassy, tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["raytree", str(tmp_path / "nope.xml"), str(glassy), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "no such file" in err and "1 of 2 inputs failed" in err
    assert _files(out) == ["glassy.exr", "glassy_raytree.png", "glassy_raytree.svg"]
