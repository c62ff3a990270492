"""--width/--height/--spp on any scene, `render --lines --contours --raytree` (one EXR
with every layer, the scene's own integrator as the beauty), no command overwriting another's
files, flags generated from the plugins' parameters, progress and per-scene lines."""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest

import mi_npr
from mi_npr import cli
from mi_npr import layers as L
from mi_npr.drawings import DRAWINGS
from mi_npr.io import read_exr
from mi_npr.pipeline import render_layers

from .public_style import fifty, ground, room


def _files(d) -> list[str]:
    return sorted(os.listdir(d))


def _digest(d) -> dict[str, str]:
    return {f: hashlib.sha1((d / f).read_bytes()).hexdigest() for f in _files(d)}


def test01_resized_sensor_rays_equal_a_loaded_one(tmp_path):
    """resize_sensor gives the rays of a sensor loaded at that size (pixel corners, centres)."""
    from mi_npr.raycast import film_grid, pixel_rays
    from mi_npr.session import resize_sensor

    mi = mi_npr.mi

    def sensor(w, h):
        return mi.load_dict(
            {
                "type": "perspective",
                "fov": 50,
                "to_world": mi.ScalarTransform4f().look_at([1, 2, 3], [0, 0, 0], [0, 1, 0]),
                "film": {"type": "hdrfilm", "width": w, "height": h},
            }
        )

    for w, h in ((1, 1), (7, 5), (33, 64)):
        got = resize_sensor(sensor(40, 30), (w, h), 3)
        ref = sensor(w, h)
        assert tuple(got.film().crop_size()) == (w, h) and got.sampler().sample_count() == 3
        x, y = film_grid(w, h, corners=True)
        a, b = pixel_rays(got, x, y), pixel_rays(ref, x, y)
        np.testing.assert_allclose(np.asarray(a.d), np.asarray(b.d), atol=1e-6)
        np.testing.assert_allclose(np.asarray(a.o), np.asarray(b.o), atol=1e-6)


def test02_size_flags_on_scenes_with_different_default_names(tmp_path):
    """res (room), resx/resy (ground), width (fifty): one --width/--height/--spp sizes all."""
    scenes = [room(tmp_path), ground(tmp_path), fifty(tmp_path)[0]]
    out = tmp_path / "out"
    args = ["render", *map(str, scenes), "-o", str(out), "--no-progress"]
    assert cli.main([*args, "--width", "24", "--height", "18", "--spp", "3"]) == 0
    for s in scenes:
        gb = read_exr(out / f"{s.stem}.exr")
        assert gb.shape == (18, 24) and gb.camera.resolution == (24, 18), s.stem
        assert gb.metadata["mi_npr/spp"] == "3"
    # --width alone keeps the film's aspect (ground: 48 x 32 -> 30 x 20)
    assert cli.main(["render", str(scenes[1]), "-o", str(out), "--width", "30"]) == 0
    assert read_exr(out / "ground.exr").shape == (20, 30)
    # -D keeps its meaning: the XML's own default names
    assert cli.main(["render", str(scenes[1]), "-o", str(out), "-D", "resx=20"]) == 0
    assert read_exr(out / "ground.exr").shape == (32, 20)
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(scenes[1]), "-o", str(out), "--width", "0"])
    assert e.value.code == 2


def test03_one_exr_with_every_layer_and_the_scenes_own_beauty(tmp_path):
    path = room(tmp_path)
    out = tmp_path / "out"
    cmd = ["render", str(path), "-o", str(out), "--lines", "--contours", "--raytree"]
    assert cli.main([*cmd, "--no-progress", "--seed", "2"]) == 0
    assert _files(out) == [
        "room.exr",
        "room.png",
        "room_contours.png",
        "room_contours.svg",
        "room_lines.png",
        "room_lines.svg",
        "room_raytree.png",
        "room_raytree.svg",
    ]
    gb = read_exr(out / "room.exr")
    for name in (*L.GBUFFER, L.LINES, L.CONTOUR, L.RAYTREE_HI, L.RAYTREE_LO, *L.EDGES, *L.RAW_RGB):
        assert name in gb, name
    assert gb.metadata["mi_npr/integrator"] == "npr_lines+npr_contours+npr_raytree"
    # the beauty is the scene's own path integrator (max_depth 3 kept), untouched by drawings:
    # the same image as mi-npr render without drawings
    plain = tmp_path / "plain"
    assert cli.main(["render", str(path), "-o", str(plain), "--no-progress", "--seed", "2"]) == 0
    ref = read_exr(plain / "room.exr")
    np.testing.assert_array_equal(gb.stack(L.RAW_RGB), ref.beauty)
    mi = mi_npr.mi
    scene = mi_npr.load_scene(path)
    direct = np.asarray(scene.integrator().render(scene, scene.sensors()[0], seed=2, spp=2))
    np.testing.assert_array_equal(ref.beauty, direct[..., :3])
    assert scene.integrator().class_name() == "PathIntegrator"
    # R G B: the beauty with the lines (composited where the lines layer has ink)
    ink = gb.numpy(L.LINES) > 0
    assert ink.any() and np.all(gb.beauty[~ink] == gb.stack(L.RAW_RGB)[~ink])
    assert mi is not None


def test04_no_command_overwrites_anothers_files(tmp_path):
    path = ground(tmp_path)
    out = tmp_path / "out"
    run = ["-o", str(out), "--no-progress"]
    assert cli.main(["render", str(path), *run]) == 0
    first = _digest(out)
    assert cli.main(["contours", str(path), *run]) == 0
    assert cli.main(["raytree", str(path), *run]) == 0
    after = _digest(out)
    assert {k: after[k] for k in first} == first  # render's files untouched
    assert sorted(set(after) - set(first)) == [
        "ground_contours.exr",
        "ground_contours.png",
        "ground_contours.svg",
        "ground_raytree.exr",
        "ground_raytree.png",
        "ground_raytree.svg",
    ]
    # the shorthand and render --contours draw the same picture under the same name
    shorthand = _digest(out)["ground_contours.png"]
    assert cli.main(["render", str(path), "--contours", *run]) == 0
    assert _digest(out)["ground_contours.png"] == shorthand
    assert read_exr(out / "ground_contours.exr").numpy(L.CONTOUR).any()


def test05_flags_are_the_plugins_parameters(tmp_path, capsys):
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    for command, layers in (
        ("render", DRAWINGS),
        ("contours", ["contours"]),
        ("raytree", ["raytree"]),
    ):
        flags = {o for a in sub[command]._actions for o in a.option_strings}
        for layer in layers:
            for p in DRAWINGS[layer].params:
                assert "--" + p.name.replace("_", "-") in flags, (command, p.name)
    for flag in ("--width", "--height", "--spp"):
        assert flag in {o for a in sub["best-view"]._actions for o in a.option_strings}
    # a drawing parameter no drawing of this render takes: one clear line
    path = ground(tmp_path)
    assert cli.main(["render", str(path), "-o", str(tmp_path / "o"), "--c", "30"]) == 1
    assert "--c: no drawing of this render takes it (add --lines)" in capsys.readouterr().err
    # values are checked like the XML's: a usage error naming the parameter
    with pytest.raises(SystemExit):
        cli.main(["render", str(path), "-o", str(tmp_path / "o"), "--lines", "--t0", "2"])
    assert "'t0' = 2.0" in capsys.readouterr().err


def test06_line_width_thickens_every_drawing(tmp_path):
    path = room(tmp_path)
    thin = render_layers(path, ["contours", "raytree"], resolution=(40, 40))
    wide = render_layers(path, ["contours", "raytree"], {"line_width": 3.0}, resolution=(40, 40))
    for name in ("contours", "raytree"):
        a = np.abs(thin.pictures[name] - thin.gbuffer.stack(L.RAW_RGB)).sum(-1) > 1e-6
        b = np.abs(wide.pictures[name] - wide.gbuffer.stack(L.RAW_RGB)).sum(-1) > 1e-6
        assert b.sum() > 2 * a.sum() and np.all(b[a]), name
    # the layers stay 1 px
    np.testing.assert_array_equal(thin.gbuffer[L.CONTOUR], wide.gbuffer[L.CONTOUR])
    out = tmp_path / "svg"
    mi_npr.io.write_layered_outputs(wide, out, "room")
    assert 'stroke-width="3"' in (out / "room_contours.svg").read_text()


def test07_progress_passes_and_per_scene_lines(tmp_path, monkeypatch, capsys):
    import importlib

    from mi_npr.batch import run_jobs

    R = importlib.import_module("mi_npr.render")

    path = ground(tmp_path)
    scene = mi_npr.load_scene(path)
    sensor, integ = scene.sensors()[0], scene.integrator()
    one = R.beauty_layers(scene, sensor, integ, 8, 0)
    monkeypatch.setattr(R, "PROGRESS_AFTER", 0.0)  # every render counts as long
    monkeypatch.setattr(R, "PASS_SECONDS", 1e-9)
    # not a terminal (pytest's stderr): no bar, one render, the same image
    quiet = R.beauty_layers(scene, sensor, integ, 8, 0, progress=True)
    np.testing.assert_array_equal(np.stack(list(quiet.values())), np.stack(list(one.values())))
    img = R._render_in_passes(scene, sensor, integ, 8, 0)  # the probe + 7 passes of 1 spp
    a, ref = np.asarray(img)[..., :3], np.stack(list(one.values()), -1)
    assert a.shape == ref.shape and abs(a.mean() - ref.mean()) < 0.1 * ref.mean()
    # per-scene lines: printed as each job ends, before the next starts
    seen = []

    def job(item):
        seen.append(capsys.readouterr().out)
        return []

    run_jobs(["a", "b"], job, progress=False, on_result=lambda r: (f"done {r.item}", False))
    assert seen[1] == "done a\n"


def test08_best_view_takes_the_size_flags(tmp_path):
    from PIL import Image

    path = ground(tmp_path)
    out = tmp_path / "view"
    args = ["best-view", str(path), "--measure", "pb", "--depth", "0", "--res", "24"]
    assert cli.main([*args, "-o", str(out), "--width", "40", "--height", "30", "--spp", "2"]) == 0
    assert Image.open(out / "ground_best_view.png").size == (40, 30)
    xml = (out / "ground_best_view.xml").read_text()
    assert 'name="width" value="40"' in xml and 'name="sample_count" value="2"' in xml


def test09_progress_keeps_its_probe(tmp_path, monkeypatch):
    """A long render's 1-spp time probe is its first sample: spp - 1 more are rendered, in
    passes whose seeds differ from the probe's, and the mean is weighted by sample counts."""
    import importlib

    R = importlib.import_module("mi_npr.render")
    M = importlib.import_module("mi_npr.memory")
    scene = mi_npr.load_scene(ground(tmp_path))
    sensor, integ = scene.sensors()[0], scene.integrator()
    calls = []

    class Spy:
        def render(self, *a, seed, spp, **k):
            calls.append((seed, spp))
            return integ.render(*a, seed=seed, spp=spp, **k)

    monkeypatch.setattr(R, "PROGRESS_AFTER", 0.0)
    monkeypatch.setattr(R, "PASS_SECONDS", 1e-9)
    img = np.asarray(R._render_in_passes(scene, sensor, Spy(), 5, 7))
    assert calls[0] == (7, 1) and sum(n for _, n in calls) == 5
    seeds = [s for s, _ in calls]
    assert len(set(seeds)) == len(seeds)
    # the same mean from the spy's own renders
    ref = sum(np.asarray(integ.render(scene, sensor, seed=s, spp=n)) * n for s, n in calls) / 5
    np.testing.assert_allclose(img, ref, rtol=1e-5, atol=1e-6)
    # memory passes larger than the samples left never ask for a render of 0 spp
    calls.clear()
    M.render_passes(Spy(), scene, sensor, 3, 0, passes=8, first=(integ.render(scene, sensor), 1))
    assert [n for _, n in calls] == [1, 1]


AOV_SCENE = """<scene version="3.0.0">
    <integrator type="aov">
        <string name="aovs" value="dd.y:depth,nn:sh_normal,Z:depth"/>
        {inner}
    </integrator>
    <sensor type="perspective">
        <transform name="to_world"><lookat origin="0, 0, -4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/>
            <rfilter type="box"/></film>
        <sampler type="stratified"><integer name="sample_count" value="1"/>
            <boolean name="jitter" value="false"/></sampler>
    </sensor>
    <shape type="sphere" id="ball"/>
    <emitter type="constant"/>
</scene>"""


@pytest.mark.parametrize("inner", ["", '<integrator type="path" name="image"/>'])
def test10_the_scene_integrators_own_channels_are_kept(tmp_path, inner):
    """Mitsuba's ``aov`` integrator as the scene's: its channels reach the EXR under its own
    names, its depth (the distance along the pixel-centre ray from the near clip plane: no
    jitter, box filter) agrees with mi-npr's exact ``P`` and ``Z`` where it hits, and the
    beauty is its nested image (or black without one) rather than its first AOVs."""
    path = tmp_path / "aov.xml"
    path.write_text(AOV_SCENE.format(inner=inner))
    assert cli.main(["render", str(path), "-o", str(tmp_path / "o"), "--lines"]) == 0
    gb = read_exr(tmp_path / "o" / "aov.exr")
    assert {"dd.y.T", "nn.X", "nn.Y", "nn.Z", "Z.T", "lines.V"} <= set(gb.names)
    hit = np.isfinite(gb.numpy(L.Z))
    assert hit.any() and not hit.all()
    distance = np.linalg.norm(gb.stack(list(L.P)) - [0.0, 0.0, -4.0], axis=-1)
    near = 0.01  # the sensor's near clip, where Mitsuba's rays start
    along = distance * (1.0 - near / gb.numpy(L.Z))  # from the near plane to the hit
    np.testing.assert_allclose(gb.numpy("dd.y.T")[hit], along[hit], rtol=1e-4)
    assert np.all(gb.numpy("dd.y.T")[~hit] == 0)
    normal = np.stack([gb.numpy(f"nn.{c}") for c in "XYZ"], -1)[hit]
    np.testing.assert_allclose(np.linalg.norm(normal, axis=-1), 1.0, atol=1e-4)
    beauty = gb.stack(L.RAW_RGB)
    if inner:
        assert beauty[hit].min() > 0 and np.allclose(
            beauty, gb.stack(["image.R", "image.G", "image.B"])
        )
    else:
        assert np.all(beauty == 0)
