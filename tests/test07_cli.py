"""The mi-npr command: outputs, several scenes, and one-line errors for bad input."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mi_npr import cli
from mi_npr.io import read_exr

from .helpers import SCENES, run_cli, scene_xml

BALL = (
    '<shape type="sphere" id="ball"><point name="center" x="0" y="0" z="4"/></shape>'
    '<emitter type="constant"/>'
)
NESTED = '<integrator type="npr_gbuffer"><integrator type="direct"/></integrator>'


@pytest.fixture
def ball(tmp_path) -> Path:
    p = tmp_path / "ball.xml"
    p.write_text(scene_xml(BALL, integrator=NESTED, spp=2))
    return p


def _files(d: Path) -> list[str]:
    return sorted(os.listdir(d)) if d.exists() else []


def test01_render_writes_exr_and_png(ball, tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["render", str(ball), "-o", str(out), "-D", "not_in_scene=1"]) == 1
    err = capsys.readouterr().err  # Mitsuba refuses unused defines; we name them, in one line
    assert "the scene uses no parameter named not_in_scene (a define it cannot use" in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert cli.main(["render", str(ball), "-o", str(out), "--spp", "3"]) == 0
    assert _files(out) == ["ball.exr", "ball.png"]
    gb = read_exr(out / "ball.exr")
    assert gb.metadata["mi_npr/spp"] == "3" and gb.objects == {1: "ball"}
    png = np.asarray(Image.open(out / "ball.png"))
    assert png.shape == (24, 32, 3) and png.dtype == np.uint8


def test02_several_scenes_one_failing(ball, tmp_path, capsys):
    broken = tmp_path / "broken.xml"
    broken.write_text("<scene version='3.0.0'><shape type='sphere'>")
    other = tmp_path / "other.xml"
    other.write_text(scene_xml(BALL, width=8, height=8))
    out = tmp_path / "out"
    code = cli.main(["render", str(ball), str(broken), str(other), "-o", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1
    assert _files(out) == ["ball.exr", "ball.png", "other.exr", "other.png"]
    assert f"{broken}" in err and "1 of 3 inputs failed" in err
    assert "Traceback" not in err


def test03_defines_fill_defaults(tmp_path, scenes):
    out = tmp_path / "o"
    code = cli.main(
        [
            "render",
            str(scenes / "scene2.xml"),
            "-o",
            str(out),
            "-D",
            "width=20",
            "-D",
            "height=10",
            "-D",
            "spp=2",
            "--no-progress",
        ]
    )
    assert code == 0
    gb = read_exr(out / "scene2.exr")
    assert gb.shape == (10, 20) and gb.metadata["mi_npr/spp"] == "2"


def test04_info(ball, tmp_path, capsys):
    out = tmp_path / "out"
    cli.main(["render", str(ball), "-o", str(out)])
    capsys.readouterr()
    assert cli.main(["info", str(out / "ball.exr")]) == 0
    text = capsys.readouterr().out
    assert "object_id.V" in text and "uint32" in text and "1: ball" in text and "fov 40" in text
    assert cli.main(["info", str(out / "ball.exr"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["objects"] == {"1": "ball"} and info["width"] == 32
    z = next(layer for layer in info["layers"] if layer["name"] == "Z")
    assert z["non_finite"] > 0  # the background's +inf


def test05_version():
    res = run_cli("--version")
    assert res.returncode == 0 and res.stdout.startswith("mi-npr 0.1.0 (mitsuba 3.9.1")


BAD_INPUTS = [
    # (name, scene text or None for a missing file, extra args, expected code, expected text)
    ("missing", None, [], 1, "no such file"),
    ("malformed", "<scene version='3.0.0'><shape type='sphere'>", [], 1, "malformed.xml"),
    (
        "unknown_param",
        scene_xml(
            BALL,
            integrator='<integrator type="npr_gbuffer"><float name="cc" value="2"/></integrator>',
        ),
        [],
        1,
        "npr_gbuffer: unknown parameter 'cc'",
    ),
    ("bad_define", scene_xml(BALL), ["-D", "width"], 2, "-D 'width': expected name=value"),
    ("bad_spp", scene_xml(BALL), ["--spp", "0"], 2, "argument --spp: '0': must be in 1..65536"),
]


@pytest.mark.parametrize(
    ("name", "text", "extra", "code", "expected"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS]
)
def test06_bad_input_is_one_line_no_traceback_no_file(tmp_path, name, text, extra, code, expected):
    scene = tmp_path / f"{name}.xml"
    if text is not None:
        scene.write_text(text)
    out = tmp_path / "out"
    res = run_cli("render", str(scene), "-o", str(out), *extra)
    assert res.returncode == code, res.stderr
    assert "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert expected in lines[-1]
    if code == 1:
        assert len(lines) == 1
    assert [f for f in _files(out) if not f.startswith(".")] == []
    assert not [f for f in _files(out) if f.startswith(".")]  # no temporary file either


def test07_unwritable_output_directory(ball, tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    code = cli.main(["render", str(ball), "-o", str(blocker / "out")])
    err = capsys.readouterr().err
    assert code == 1 and "cannot create output directory" in err and err.count("\n") == 1
    if os.geteuid() != 0:  # root writes anywhere: only an ordinary user sees this case
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        assert cli.main(["render", str(ball), "-o", str(ro)]) == 1
        assert "not writable" in capsys.readouterr().err


def test08_same_stem_twice_is_refused(ball, tmp_path, capsys):
    sub = tmp_path / "sub"
    sub.mkdir()
    (sub / "ball.xml").write_text(ball.read_text())
    code = cli.main(["render", str(ball), str(sub / "ball.xml"), "-o", str(tmp_path / "o")])
    assert code == 1 and "would both write outputs named 'ball'" in capsys.readouterr().err


def test09_info_on_a_non_exr(tmp_path, capsys):
    bad = tmp_path / "x.exr"
    bad.write_text("hello")
    assert cli.main(["info", str(bad)]) == 1
    assert "not a valid EXR (truncated?)" in capsys.readouterr().err


def test10_defines_reach_names_the_command_uses_itself(tmp_path):
    # -D seed=... fills the XML's $seed (a sampler seed here), not render()'s own seed argument.
    sampler = (
        '<sampler type="independent"><integer name="sample_count" value="1"/>'
        '<integer name="seed" value="$seed"/></sampler>'
    )
    text = scene_xml(BALL, integrator=NESTED).replace(
        '<sampler type="independent"><integer name="sample_count" value="1"/></sampler>', sampler
    )
    xml = tmp_path / "seeded.xml"
    xml.write_text(
        text.replace(
            '<scene version="3.0.0">', '<scene version="3.0.0">\n<default name="seed" value="0"/>'
        )
    )
    out = tmp_path / "o"
    images = []
    for seed in ("1", "1", "7"):
        assert cli.main(["render", str(xml), "-o", str(out), "-D", f"seed={seed}"]) == 0
        images.append(read_exr(out / "seeded.exr").beauty)
    np.testing.assert_array_equal(images[0], images[1])
    assert not np.array_equal(images[0], images[2])  # the define changed the sampler's seed


def test11_batch_errors_name_the_scene(ball, tmp_path, capsys):
    nosensor = tmp_path / "nosensor.xml"
    nosensor.write_text(f'<scene version="3.0.0">{BALL}</scene>')
    out = tmp_path / "o"
    assert cli.main(["render", str(nosensor), str(ball), "-o", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert f"{nosensor}: sensor 0: the scene has 0 sensor(s)" in err
    assert _files(out) == ["ball.exr", "ball.png"]
    scene2 = str(SCENES / "scene2.xml")
    for cmd in ("render", "contours", "raytree"):
        assert cli.main([cmd, scene2, "-o", str(out), "-D", "width=0", "--no-progress"]) == 1
        err = capsys.readouterr().err
        assert "film size 0x480: width and height must be at least 1 pixel" in err, err
        assert scene2 in err and err.count("\n") == 1


def test12_numpy_values_and_a_defines_mapping_fill_defaults():
    import mi_npr

    gb = mi_npr.render(SCENES / "scene2.xml", defines={"width": np.int64(8)}, height=np.int32(6))
    assert gb.shape == (6, 8)
    with pytest.raises(mi_npr.ParameterError, match="defines: expected a mapping"):
        mi_npr.render(SCENES / "scene2.xml", defines=["width=8"])


def test13_variant_errors_speak_the_command_line(ball, tmp_path, capsys):
    """A scene that needs a polarized variant says so and names one; a scalar variant is refused
    in the command line's words, before anything loads."""
    out = tmp_path / "o"
    pol = tmp_path / "pol.xml"
    pol.write_text(
        scene_xml('<shape type="sphere"><point name="center" x="0" y="0" z="3"/></shape>').replace(
            '<integrator type="npr_gbuffer"/>', '<integrator type="stokes"/>'
        )
    )
    assert cli.main(["render", str(pol), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "polarized mode" in err and "such as llvm_ad_spectral_polarized, with --variant" in err
    assert "\n" not in err
    # a polarized plugin whose file is missing: the file is the problem, not the variant
    gone = tmp_path / "gone.xml"
    gone.write_text(
        scene_xml(
            '<shape type="sphere"><point name="center" x="0" y="0" z="3"/>'
            '<bsdf type="measured_polarized"><string name="filename" value="gone.pbsdf"/>'
            '<float name="wavelength" value="550"/></bsdf></shape>'
        )
    )
    assert cli.main(["render", str(gone), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "gone.pbsdf" in err and "--variant" not in err, err
    assert cli.main(["--variant", "scalar_rgb", "render", str(ball), "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (
        "mi-npr: error: --variant scalar_rgb: mi-npr runs on Mitsuba's JIT variants only "
        "(llvm_*, cuda_*): use --variant llvm_ad_rgb"
    )
    assert not (out / "ball.exr").exists()


def test14_search_path_finds_the_files_a_scene_names(tmp_path, capsys, monkeypatch):
    """``-a PATH`` as Mitsuba's own command: a scene that names ``uv_sphere.ply`` without a
    folder renders when ``-a`` points at it, in a render and in a batch alike."""
    import shutil

    monkeypatch.delenv("MI_NPR_SEARCH_PATH", raising=False)
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    shutil.copy(SCENES / "meshes" / "uv_sphere.ply", meshes)
    xml = tmp_path / "scene" / "s.xml"
    xml.parent.mkdir()
    body = '<shape type="ply"><string name="filename" value="uv_sphere.ply"/>'
    body += '<transform name="to_world"><translate z="4"/></transform></shape>'
    xml.write_text(scene_xml(body))
    out = tmp_path / "out"
    assert cli.main(["render", str(xml), "-o", str(out), "--no-progress"]) == 1
    assert "uv_sphere.ply" in capsys.readouterr().err
    assert cli.main(["render", str(xml), "-o", str(out), "-a", str(meshes), "--no-progress"]) == 0
    gb = read_exr(out / "s.exr")
    assert list(gb.objects.values()) == ["uv_sphere"] and gb.object_id.any()
    argv = ["batch", str(xml), "-o", str(tmp_path / "b"), "--workers", "0", "--no-progress"]
    assert cli.main([*argv, "-a", f"{tmp_path / 'nowhere'}{os.pathsep}{meshes}"]) == 2
    assert "-a " + str(tmp_path / "nowhere") + ": not a folder" in capsys.readouterr().err
    assert cli.main([*argv, "-a", str(meshes)]) == 0
    monkeypatch.delenv("MI_NPR_SEARCH_PATH", raising=False)


def test15_empty_output_folder_and_empty_glob_are_refused(ball, tmp_path, capsys, monkeypatch):
    """``-o ''`` is no folder (it used to write into the current one); ``--only ''`` selects
    no object on purpose (it used to mean every object)."""
    monkeypatch.chdir(tmp_path)
    for command in (["render", str(ball)], ["batch", str(ball), "--workers", "0"]):
        assert cli.main([*command, "-o", "", "--no-progress"]) == 1
        err = capsys.readouterr().err.strip()
        assert (
            err == "mi-npr: error: output directory '': an empty name (give a folder, e.g. -o out)"
        )
    assert sorted(os.listdir(tmp_path)) == ["ball.xml"]  # nothing written here
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(ball), "-o", "out", "--contours", "--only", ""])
    assert e.value.code == 2
    assert "argument --only: an empty pattern" in capsys.readouterr().err
