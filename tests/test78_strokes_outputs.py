"""The ``strokes`` drawing end to end: ``mi-npr render --strokes`` (in-process), its three
files, the ``strokes.V`` layer, the ``npr_strokes`` plugin, and bad flags.

References: the files are read back with the standard library (``json``, ``xml.etree``), and
checked against the strokes the library returns for the same scene and against each other
(the SVG's paths are the JSON's drawn strokes; the PNG is the layer's ink on white).
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import mitsuba as mi
import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import cli
from mi_npr import layers as L
from mi_npr.io import read_exr
from mi_npr.pipeline import render_layers

from .helpers import scene_xml

SVG = "{http://www.w3.org/2000/svg}"
INK = "{http://www.inkscape.org/namespaces/inkscape}"

BODY = (
    '<shape type="cube" id="box"><transform name="to_world"><rotate y="1" angle="35"/>'
    '<rotate x="1" angle="25"/><scale value="0.7"/><translate x="-0.6" z="5"/></transform>'
    "</shape>"
    '<shape type="sphere" id="ball"><point name="center" x="0.9" y="0.2" z="5.5"/>'
    '<float name="radius" value="0.7"/></shape>'
    '<shape type="rectangle" id="floor"><transform name="to_world"><rotate x="1" angle="-90"/>'
    '<scale value="4"/><translate y="-0.8" z="6"/></transform></shape>'
)


def scene(tmp_path, integrator='<integrator type="path"/>'):
    path = tmp_path / "three.xml"
    path.write_text(
        scene_xml(
            BODY,
            width=64,
            height=48,
            origin="0, 0.6, 0",
            target="0, 0, 5",
            spp=2,
            integrator=integrator,
        )
    )
    return path


def test01_render_writes_svg_json_and_png(tmp_path):
    path, out = scene(tmp_path), tmp_path / "out"
    argv = ["render", str(path), "--strokes", "-o", str(out), "--width", "64", "--height", "48"]
    assert cli.main([*argv, "--spp", "2"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "three.exr",
        "three.png",
        "three_strokes.json",
        "three_strokes.png",
        "three_strokes.svg",
    ]
    doc = json.loads((out / "three_strokes.json").read_text())
    assert doc["format"] == "mi-npr-strokes" and (doc["width"], doc["height"]) == (64, 48)
    assert doc["style"]["name"] == "technical"
    strokes = doc["strokes"]
    kinds = {s["kind"] for s in strokes}
    assert {"silhouette", "crease", "border"} <= kinds <= set(doc["kinds"])
    assert {s["object"] for s in strokes} == {"box", "ball", "floor"}
    for s in strokes:
        n = len(s["points"])
        assert n >= 2
        for key in ("position", "depth", "depth_behind", "object_ids", "prims", "width", "opacity"):
            assert len(s[key]) == n, key
        assert s["visible"] == (s["qi"] == 0)
    assert any(s["qi"] > 0 for s in strokes)  # the cube's back edges, dashed
    # the SVG: one path per drawn stroke, in a layer per kind and a group per object
    root = ET.parse(out / "three_strokes.svg").getroot()
    assert root.get("viewBox") == "0 0 64 48"
    layers = [g for g in root.iter(f"{SVG}g") if g.get(f"{INK}groupmode") == "layer"]
    assert layers[0].get("id") == "strokes"
    assert {g.get("id") for g in layers[1:]} == kinds
    paths = list(root.iter(f"{SVG}path"))
    assert sorted(int(p.get("data-stroke")) for p in paths) == [
        s["id"] for s in strokes if s["drawn"]
    ]
    hidden = [p for p in paths if p.get("class") == "hidden"]
    assert hidden and all(p.get("stroke-dasharray") == "4 3" for p in hidden)
    assert not list(root.iter(f"{SVG}image"))  # no raster image unless asked
    # the layer and the PNG: the same ink
    gb = read_exr(out / "three.exr")
    cov = gb.numpy(L.STROKES)
    assert cov.shape == (48, 64) and cov.min() >= 0 and cov.max() <= 1 and cov.max() > 0.9
    png = np.asarray(Image.open(out / "three_strokes.png").convert("L"), np.float64) / 255
    assert png.shape == (48, 64)
    assert np.all(png[cov > 0.999] < 0.01) and np.all(png[cov == 0] > 0.99)


def test02_the_picture_and_the_layer_agree_with_the_library(tmp_path):
    path = scene(tmp_path)
    r = render_layers(path, ["strokes"], {"style": "illustration"}, resolution=(64, 48), spp=2)
    done = r.vector_strokes
    assert done.style.name == "illustration" and not done.style.hidden
    np.testing.assert_array_equal(r.gbuffer.numpy(L.STROKES), done.alpha)
    raw = r.gbuffer.stack(L.RAW_RGB)
    expected = raw * (1 - done.alpha[..., None]) + done.ink
    np.testing.assert_allclose(r.pictures["strokes"], expected, atol=1e-6)
    np.testing.assert_array_equal(r.gbuffer.beauty, raw)  # R G B untouched by a picture
    # every stroke's points lie in the frame
    for s in done.strokes:
        assert np.all((s.points >= -1e-6) & (s.points <= [64 + 1e-6, 48 + 1e-6]))


def test03_thesis_style_svg_has_varying_opacity(tmp_path):
    path, out = scene(tmp_path), tmp_path / "out"
    argv = ["render", str(path), "--strokes", "--style", "thesis", "-o", str(out)]
    assert cli.main([*argv, "--width", "64", "--height", "48", "--spp", "1"]) == 0
    doc = json.loads((out / "three_strokes.json").read_text())
    assert doc["style"]["gray"] and not any(s["drawn"] for s in doc["strokes"] if s["qi"])
    op = np.concatenate([s["opacity"] for s in doc["strokes"] if s["drawn"]])
    assert op.min() == 0.0 and op.max() == 1.0
    root = ET.parse(out / "three_strokes.svg").getroot()
    levels = {float(p.get("stroke-opacity", 1)) for p in root.iter(f"{SVG}path")}
    assert all(0 < a <= 1 for a in levels)


def test04_the_plugin(tmp_path):
    path = scene(
        tmp_path,
        '<integrator type="npr_strokes"><string name="style" value="illustration"/>'
        '<float name="crease_angle" value="120"/></integrator>',
    )
    loaded = mi_npr.load_scene(path)
    integ = loaded.integrator()
    assert integ.aov_names() == [L.STROKES, *L.GBUFFER_AOVS, *L.RAW_RGB]
    img = np.asarray(mi.render(loaded))
    assert img.shape == (48, 64, 3 + len(integ.aov_names()))
    gb = mi_npr.render(path)
    assert gb.metadata["mi_npr/integrator"] == "npr_strokes"
    np.testing.assert_allclose(img[..., 3], gb.numpy(L.STROKES), atol=1e-6)
    # the XML's values are the drawing's: render picks them up
    r = render_layers(path, resolution=(64, 48), spp=1)
    assert r.vector_strokes.style.name == "illustration"
    assert r.vector_strokes.strokes.params["crease_angle"] == 120


@pytest.mark.parametrize(
    ("flag", "value", "name"),
    [("--style", "watercolour", "style"), ("--dash", "0,0", "dash"), ("--max-qi", "-1", "max_qi")],
)
def test05_bad_flags_are_usage_errors(tmp_path, capsys, flag, value, name):
    path = scene(tmp_path)
    with pytest.raises(SystemExit) as e:
        cli.main(["render", str(path), "--strokes", flag, value, "-o", str(tmp_path / "o")])
    assert e.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]  # after argparse's usage
    assert last.startswith("mi-npr render: error:") and f"'{name}'" in last
    assert not (tmp_path / "o").exists()


def test06_a_bad_xml_value_names_the_parameter(tmp_path):
    path = scene(
        tmp_path, '<integrator type="npr_strokes"><string name="style" value="oil"/></integrator>'
    )
    with pytest.raises(Exception, match="parameter 'style'"):
        mi_npr.load_scene(path)


def test07_docstring_examples_run():
    import doctest

    import mi_npr.strokes

    assert doctest.testmod(mi_npr.strokes, optionflags=0).failed == 0


def _hand_made(rng, n_strokes=40):
    """Strokes of 1 to 7 vertices with non-finite depths, positions and film points here and
    there, some without ``depth_behind``, hidden and visible, open and closed."""
    from mi_npr.strokes import KINDS, Stroke, Strokes

    strokes = []
    for i in range(n_strokes):
        n = int(rng.integers(1, 8))
        s = Stroke(
            kind=KINDS[i % 5],
            points=rng.uniform(-2, 66, (n, 2)),
            position=rng.normal(size=(n, 3)),
            depth=rng.uniform(1, 9, n),
            object_id=np.full(n, 1 + i % 3),
            prim=rng.integers(0, 99, n),
            qi=int(i % 4 == 3),
            closed=bool(i % 3 == 0),
            depth_behind=None if i % 5 == 4 else rng.uniform(1, 12, n),
        )
        if i % 6 == 1:
            s.depth[0], s.points[-1, 1], s.position[0, 2] = np.inf, np.nan, -np.inf
            if s.depth_behind is not None:
                s.depth_behind[-1] = np.inf
        strokes.append(s)
    return Strokes(strokes, 64, 48, {1: "a", 2: "b"}, depth_range=(1.5, 8.0))


def _expected(a):
    """``a`` (an array or None) as JSON values: floats, ``None`` where not finite."""
    if a is None:
        return None
    a = np.asarray(a, np.float64)
    if a.ndim > 1:
        return [_expected(row) for row in a]
    return [float(v) if math.isfinite(v) else None for v in a]


@pytest.mark.parametrize("block", [None, 1, 3])
@pytest.mark.parametrize("preset", ["technical", "illustration", "thesis"])
def test08_json_holds_each_strokes_numbers_with_null_where_not_finite(preset, block, monkeypatch):
    """Each stroke's numbers as the stroke holds them; ``block``: the rows made a few strokes
    at a time (the memory bound of a large drawing), the same text."""
    from mi_npr.io import strokes as S
    from mi_npr.io.strokes import stroke_json
    from mi_npr.strokes.drawing import StrokeDrawing
    from mi_npr.strokes.style import style_of

    st = _hand_made(np.random.default_rng(1))
    style = style_of(preset)
    drawing = StrokeDrawing(st, style, np.zeros((48, 64)), None)
    text = stroke_json(drawing)
    if block is not None:
        monkeypatch.setattr(S, "JSON_BLOCK", block)
        assert stroke_json(drawing) == text
    doc = json.loads(text)
    assert len(doc["strokes"]) == len(st)
    for i, (row, s) in enumerate(zip(doc["strokes"], st, strict=True)):
        assert (row["id"], row["object_id"], row["qi"]) == (i, int(s.object_id[0]), s.qi)
        for key, field in (("points", "points"), ("position", "position"), ("depth", "depth")):
            assert row[key] == _expected(getattr(s, field)), (i, key)
        assert row["depth_behind"] == _expected(s.depth_behind)
        assert row["object_ids"] == [int(v) for v in s.object_id]
        assert row["prims"] == [int(v) for v in s.prim]
        # the style's numbers for this stroke alone
        assert row["width"] == _expected(style.widths(s, st.depth_range))
        assert row["opacity"] == _expected(style.opacity(s, st.depth_range))


@pytest.mark.parametrize("preset", ["technical", "illustration", "thesis"])
def test09_style_arrays_are_each_strokes_own(preset):
    from mi_npr.io.svg import style_arrays
    from mi_npr.strokes.style import style_of

    st = _hand_made(np.random.default_rng(2))
    style = style_of(preset, depth_falloff=0.5)
    widths, opacity, ends = style_arrays(st.strokes, style, st.depth_range)
    starts = [0, *ends[:-1].tolist()]
    for s, a, b in zip(st.strokes, starts, ends.tolist(), strict=True):
        # bit for bit: the SVG's and the JSON's numbers are those of one stroke at a time
        assert widths[a:b].tobytes() == style.widths(s, st.depth_range).tobytes()
        assert opacity[a:b].tobytes() == style.opacity(s, st.depth_range).tobytes()
