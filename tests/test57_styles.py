"""The four styles as presets and as scenes (thesis Fig. 4.8): defaults, the lines layer with
the leaf outlines, flat colours, no lines in bright areas, and the scene writer."""

from __future__ import annotations

import os

import numpy as np
import pytest

import mi_npr
from mi_npr import cli
from mi_npr import foliage as fo
from mi_npr import layers as L
from mi_npr.errors import ParameterError
from mi_npr.foliage import styles as S
from mi_npr.scene import declared_defaults

from .helpers import SCENES, sun_only

STYLES = ("small_leaves", "large_leaves", "van_gogh", "childrens_book")
DEFAULTS = {"abstraction", "leaf_size", "width", "height", "spp", "integrator", "beauty"}


def test01_presets():
    assert tuple(S.STYLES) == STYLES
    sub = next(a for a in cli.build_parser()._actions if a.dest == "command").choices["foliage"]
    assert tuple(next(a for a in sub._actions if a.dest == "style").choices) == STYLES
    for name in STYLES:
        st = S.style(name)
        fo.leaf_template(st.leaf_shape)
        assert st.placement in fo.PLACEMENTS and st.orientation in fo.ORIENTATIONS
        assert 0 <= st.abstraction <= 1 and st.leaf_size > 0
        mi_npr.kernels.lines(
            {
                L.Z: np.ones((2, 2)),
                L.LEAF_ID: np.ones((2, 2), np.uint32),
                **{c: np.zeros((2, 2)) for c in L.RGB},
            },
            **st.lines,
        )
    assert S.style("van_gogh").orientation == "van_gogh"
    assert S.style("childrens_book").bands > 0 and S.style("large_leaves").lines["bright_fade"] > 0
    with pytest.raises(ParameterError, match="small_leaves, large_leaves"):
        S.style("cubist")


@pytest.mark.parametrize("name", STYLES)
def test02_style_scene_renders_leaf_outlines(name, tmp_path):
    path = SCENES / f"foliage_{name}.xml"
    assert DEFAULTS <= declared_defaults(path)
    gb = mi_npr.render(path, width=64, height=64, spp=2)
    assert gb.metadata["mi_npr/integrator"] == "npr_lines"
    leaf, ink = gb.numpy(L.LEAF_ID), gb.numpy(L.LINES)
    assert leaf.max() > 20  # many leaves in view
    # Lines are full strength, except large_leaves' where the beauty is bright (bright_fade).
    fade = np.ones(leaf.shape)
    if "bright_fade" in S.style(name).lines:
        Y = gb.stack(L.RAW_RGB) @ np.array([0.2126, 0.7152, 0.0722])
        fade = np.clip(2 - Y / S.style(name).lines["bright_fade"], 0, 1)
    # Every boundary between two leaves (or a leaf and anything else) carries a line pixel;
    # anti-aliased, it is inked at least by half where the line crosses it.
    for a, b, ia, ib, min_fade in (
        (leaf[:, 1:], leaf[:, :-1], ink[:, 1:], ink[:, :-1], np.minimum(fade[:, 1:], fade[:, :-1])),
        (leaf[1:], leaf[:-1], ink[1:], ink[:-1], np.minimum(fade[1:], fade[:-1])),
    ):
        boundary = a != b
        drawn = np.maximum(ia, ib)[boundary]
        assert np.all(drawn >= 0.5 * min_fade[boundary] - 1e-6)
    out = mi_npr.io.write_outputs(gb, tmp_path, name)
    back = mi_npr.io.read_exr(out[0])
    np.testing.assert_array_equal(back.numpy(L.LINES), ink)
    np.testing.assert_array_equal(back.numpy(L.LEAF_ID), leaf)


def test03_large_leaves_has_no_lines_in_bright_areas():
    gb = mi_npr.render(SCENES / "foliage_large_leaves.xml", width=64, height=64, spp=4)
    Y = gb.stack(L.RAW_RGB) @ np.array([0.2126, 0.7152, 0.0722])
    fade = S.style("large_leaves").lines["bright_fade"]
    assert np.all(gb.numpy(L.LINES)[Y >= 2 * fade] == 0)
    dark = (Y < fade) & (gb.numpy(L.LEAF_ID) > 0)
    assert gb.numpy(L.LINES)[dark].max() == 1.0


def test04_childrens_book_is_flat(tmp_path):
    """Flat colours: with its sun alone, every leaf pixel is one of the bands' tones (0, 1/3,
    2/3 or all of the full Lambert value), and all of them show."""
    text = (SCENES / "foliage_childrens_book.xml").read_text()
    assert '<integer name="bands" value="3"/>' in text
    gb = mi_npr.render(sun_only("childrens_book", tmp_path), width=64, height=64, spp=1)
    green = gb.stack(L.RAW_RGB)[gb.numpy(L.LEAF_ID) > 0][:, 1]
    full = S.style("childrens_book").leaf_color[1] / np.pi * 2.6
    tones = green / full * 3
    np.testing.assert_allclose(tones, np.round(tones), atol=1e-3)
    assert set(np.round(tones).astype(int).tolist()) == {0, 1, 2, 3}


def test05_write_foliage_scene(tmp_path):
    plant = fo.procedural_tree(seed=9, n_leaves=200)
    written = S.write_foliage_scene(
        tmp_path / "scenes" / "t.xml", plant, "van_gogh", leaf_size=0.3, abstraction=0.25, k=2
    )
    names = sorted(p.name for p in written)
    assert names == ["t.xml", "t_hlps.json", "t_plant.ply", "t_wood.ply"]
    assert sorted(os.listdir(tmp_path / "scenes")) == names  # no temporary files left
    xml = tmp_path / "scenes" / "t.xml"
    text = xml.read_text()
    assert '<default name="leaf_size" value="0.3"/>' in text
    assert '<default name="abstraction" value="0.25"/>' in text
    assert len(fo.HLPSet.load(tmp_path / "scenes" / "t_hlps.json")) == 2
    # Relative paths: the scene renders from any working directory.
    cwd = os.getcwd()
    try:
        os.chdir(tmp_path)
        gb = mi_npr.render(str(xml), width=40, height=30, spp=1, leaf_size=0.5)
    finally:
        os.chdir(cwd)
    assert gb.shape == (30, 40) and (gb.numpy(L.LEAF_ID) > 0).any()
    # The camera frames the whole plant: nothing touches the image border.
    assert not gb.object_id[[0, -1]].any() and not gb.object_id[:, [0, -1]].any()
    empty = fo.Plant.from_mesh(np.zeros((0, 3)), np.zeros((0, 3)))
    bad = [
        ((tmp_path / "e.xml", empty, "van_gogh"), {}, "no leaves"),
        ((tmp_path / "x.xml", plant, "pointillist"), {}, "style"),
        ((tmp_path / "x.xml", plant, "van_gogh"), {"abstraction": 2.0}, "abstraction"),
        ((tmp_path / "x.xml", plant, "van_gogh"), {"leaf_size": -1.0}, "leaf_size"),
        ((tmp_path / "x.txt", plant, "van_gogh"), {}, r"\.xml"),
    ]
    for args, kw, match in bad:
        with pytest.raises(ParameterError, match=match):
            S.write_foliage_scene(*args, **kw)
    assert not (tmp_path / "x.xml").exists() and not (tmp_path / "e.xml").exists()
