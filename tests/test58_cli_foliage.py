"""mi-npr foliage: a plant file (or a procedural one) becomes a ready scene that mi-npr render
renders; bad plants and flags are one-line errors."""

from __future__ import annotations

import os

import numpy as np
import pytest

from mi_npr import cli
from mi_npr import foliage as fo
from mi_npr import layers as L
from mi_npr.io import read_exr
from mi_npr.meshes import write_ply

from .helpers import run_cli


def test01_procedural_plant_to_rendered_exr(tmp_path):
    """As a user runs it, in fresh interpreters: foliage, then render with defines."""
    scene = tmp_path / "scene" / "tree.xml"
    r = run_cli(
        "foliage", "procedural:tree", "--style", "van_gogh", "-o", str(scene),
        "--leaf-size", "0.3", "--abstraction", "0.7", "--hlps", "4", "--seed", "2",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "tree.xml" in r.stdout and "1500 leaves" in r.stdout
    assert sorted(os.listdir(scene.parent)) == [
        "tree.xml", "tree_hlps.json", "tree_plant.ply", "tree_wood.ply"
    ]  # fmt: skip
    text = scene.read_text()
    assert '<default name="leaf_size" value="0.3"/>' in text
    assert '<default name="abstraction" value="0.7"/>' in text
    assert len(fo.HLPSet.load(scene.parent / "tree_hlps.json")) == 4
    out = tmp_path / "out"
    r = run_cli(
        "render", str(scene), "-o", str(out),
        "-D", "width=48", "-D", "height=40", "-D", "spp=2", "-D", "leaf_size=0.4",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    gb = read_exr(out / "tree.exr")
    assert gb.shape == (40, 48)
    assert {L.LINES, L.LEAF_ID, *L.RAW_RGB} <= set(gb.names)
    assert gb.numpy(L.LINES).max() == 1.0 and gb.numpy(L.LEAF_ID).max() > 10
    assert set(gb.objects.values()) == {"leaves", "wood"}


def test02_mesh_plant_file(tmp_path, capsys):
    plant = fo.procedural_tree(seed=4, n_leaves=120)
    leaves = fo.make_leaves(None, plant, 0.1, placement="leaves", orientation="leaf")
    V, F, _, _ = leaves.mesh()
    write_ply(tmp_path / "plant.ply", V, F)
    out = tmp_path / "p.xml"
    code = cli.main(
        ["foliage", str(tmp_path / "plant.ply"), "--style", "small_leaves", "-o", str(out)]
    )
    assert code == 0
    n = len(leaves)
    assert f"({n} leaves)" in capsys.readouterr().out
    assert not (tmp_path / "p_wood.ply").exists()  # a plant file holds leaves only
    back = fo.read_plant(tmp_path / "p_plant.ply")
    assert len(back) == n
    np.testing.assert_allclose(back.areas, 0.01, rtol=1e-4)  # 0.1 x 0.1 quads
    # --leaves triangles: every triangle is a leaf.
    assert (
        cli.main(
            [
                "foliage",
                str(tmp_path / "plant.ply"),
                "--style",
                "small_leaves",
                "-o",
                str(out),
                "--leaves",
                "triangles",
            ]
        )
        == 0
    )
    assert len(fo.read_plant(tmp_path / "p_plant.ply")) == 2 * n
    # The plant's own file is never overwritten by the scene's assets.
    plant_file = tmp_path / "p_plant.ply"
    code = cli.main(["foliage", str(plant_file), "--style", "van_gogh", "-o", str(out)])
    assert code == 1 and "would overwrite the input plant" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("setup", "args", "code", "message"),
    [
        ("empty", [], 1, "the plant has no leaves"),
        ("nan", [], 1, "non-finite"),
        ("missing", [], 1, "no such file"),
        ("ok", ["--abstraction", "2"], 2, "argument --abstraction: '2': must be a finite number"),
        ("ok", ["--leaf-size", "-1"], 2, "argument --leaf-size: '-1': must be a finite number"),
        ("ok", ["--style", "cubist"], 2, "invalid choice: 'cubist'"),
        ("ok", ["--hlps", "0"], 2, "argument --hlps: '0': must be in 1..1024"),
        ("bush", [], 0, ""),
        ("fern", [], 1, "kind = 'fern'"),
    ],
)
def test03_errors_are_one_line(tmp_path, capsys, setup, args, code, message):
    inputs = {
        "empty": tmp_path / "empty.ply",
        "nan": tmp_path / "nan.ply",
        "missing": tmp_path / "missing.ply",
        "ok": tmp_path / "ok.ply",
        "bush": "procedural:bush",
        "fern": "procedural:fern",
    }
    write_ply(inputs["empty"], np.zeros((0, 3)), np.zeros((0, 3)))
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    write_ply(inputs["ok"], V, np.array([[0, 1, 2]]))
    V[1, 0] = np.nan
    write_ply(inputs["nan"], V, np.array([[0, 1, 2]]))
    argv = ["foliage", str(inputs[setup]), "-o", str(tmp_path / "s.xml")]
    if "--style" not in args:
        argv += ["--style", "van_gogh"]
    with pytest.raises(SystemExit) if code == 2 else _nothing() as exc:
        got = cli.main(argv + args)
    err = capsys.readouterr().err
    if code == 2:
        assert exc.value.code == 2
    else:
        assert got == code
    assert message in err and "Traceback" not in err
    if code:
        assert len(err.strip().splitlines()) == 1 or code == 2
        assert not (tmp_path / "s.xml").exists()


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def test04_file_names_that_xml_or_mitsuba_would_misread(tmp_path, capsys):
    # & < > " are escaped in the scene's attributes; a '$' (a Mitsuba parameter) is refused
    # before anything is written.
    odd = tmp_path / 'a&b <"c">.xml'
    assert (
        cli.main(["foliage", "procedural:bush", "--style", "childrens_book", "-o", str(odd)]) == 0
    )
    capsys.readouterr()
    out = tmp_path / "out"
    args = ["render", str(odd), "-o", str(out), "-D", "width=24", "-D", "height=24", "-D", "spp=1"]
    assert cli.main([*args, "--no-progress"]) == 0
    assert read_exr(out / 'a&b <"c">.exr').numpy(L.LEAF_ID).max() > 0
    dollar = tmp_path / "d" / "tree$v1.xml"
    assert cli.main(["foliage", "procedural:bush", "--style", "van_gogh", "-o", str(dollar)]) == 1
    assert "a '$' in a file name cannot be used" in capsys.readouterr().err
    assert not dollar.parent.exists() or not os.listdir(dollar.parent)


def test05_two_leaf_plant_renders(tmp_path, capsys):
    # One leaf per HLP cluster: the blobs keep a leaf's size, so the scene has leaves to draw.
    plant = tmp_path / "p2.ply"
    fo.procedural_tree(seed=0, n_leaves=2).save(plant)
    scene = tmp_path / "s" / "two.xml"
    assert cli.main(["foliage", str(plant), "--style", "childrens_book", "-o", str(scene)]) == 0
    out = tmp_path / "o"
    args = ["render", str(scene), "-o", str(out), "-D", "width=24", "-D", "height=24"]
    assert cli.main([*args, "-D", "spp=1", "--no-progress"]) == 0, capsys.readouterr().err
