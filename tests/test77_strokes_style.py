"""Stroke styles and their raster: widths, opacity (eq. 5.1), dashes, anti-aliased coverage,
and one-line errors for bad styles.

References: the formulas of :mod:`mi_npr.strokes.style`'s docstring evaluated by hand on
hand-made strokes; for the raster, the ink of a straight horizontal line, whose every pixel
column holds exactly the line's width (a box filter over a band of width ``w``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import mi_npr
from mi_npr.drawings import DRAWINGS
from mi_npr.errors import ParameterError
from mi_npr.strokes import Stroke, Strokes, extract_strokes, raster
from mi_npr.strokes.raster import dash_pieces, rasterize
from mi_npr.strokes.style import STYLES, make_style, style_of

from .test75_strokes_closed_form import CUBE, POSE, load, seg_distance


def line(x0, x1, y, depth=(2.0, 2.0), qi=0, kind="silhouette", n=2, behind=None) -> Stroke:
    """A straight horizontal stroke of ``n`` vertices."""
    x = np.linspace(x0, x1, n)
    d = np.linspace(*depth, n)
    return Stroke(
        kind=kind,
        points=np.stack([x, np.full(n, y)], 1),
        position=np.zeros((n, 3)),
        depth=d,
        object_id=np.ones(n),
        prim=np.zeros(n),
        qi=qi,
        depth_behind=None if behind is None else np.full(n, behind),
    )


def sheet(*strokes: Stroke, w=40, h=24, depth_range=(1.0, 3.0)) -> Strokes:
    return Strokes(list(strokes), w, h, {1: "thing"}, depth_range)


@pytest.mark.parametrize(("width", "y"), [(1.0, 10.0), (1.0, 10.3), (2.0, 10.0), (3.0, 9.75)])
def test01_each_column_of_a_line_holds_its_width(width, y):
    style = make_style(width=width)
    alpha, ink = rasterize(sheet(line(4.0, 36.0, y)), style)
    assert alpha.shape == (24, 40) and alpha.dtype == np.float32
    assert alpha.min() >= 0 and alpha.max() <= 1
    cols = alpha[:, 8:32].sum(0)
    np.testing.assert_allclose(cols, width, atol=1e-5)
    np.testing.assert_array_equal(ink, 0.0)  # black ink, premultiplied


def test02_technical_is_uniform_with_dashed_hidden_lines(tmp_path):
    scene = load(tmp_path, CUBE.format(POSE))
    st = extract_strokes(scene, scene.sensors()[0])
    tech = style_of("technical")
    assert all(np.all(tech.widths(s, st.depth_range) == 1.0) for s in st)
    assert all(tech.drawn(s) for s in st)
    assert {tech.dashes(s) for s in st if s.qi > 0} == {(4.0, 3.0)}
    assert {tech.dashes(s) for s in st if s.qi == 0} == {()}
    # a long hidden line inks 4 px of every 7
    hidden = line(0.0, 700.0, 10.5, qi=1)
    on = sum(
        np.hypot(*np.diff(p, axis=0).T).sum()
        for p, _ in dash_pieces(hidden.points, np.zeros((2, 1)), tech.dashes(hidden))
    )
    assert abs(on - 400.0) < 1e-9


def test03_illustration_widths_follow_depth_and_taper():
    style = style_of("illustration")
    s = line(0.0, 100.0, 5.0, depth=(1.0, 3.0), n=11)  # vertices every 10 px, D = 0 .. 1
    w = style.widths(s, (1.0, 3.0))
    D = np.linspace(0, 1, 11)
    dist_to_end = np.minimum(np.arange(11) * 10.0, 100 - np.arange(11) * 10.0)
    x = np.clip(dist_to_end / 8.0, 0, 1)
    taper = 0.15 + 0.85 * (3 * x**2 - 2 * x**3)
    np.testing.assert_allclose(w, 2.4 * (1 - 0.6 * D) * taper)
    crease = line(0.0, 100.0, 5.0, kind="crease", n=3)
    assert style.widths(crease, (1.0, 3.0))[1] == pytest.approx(2.4 * 0.55 * (1 - 0.6 * 0.5))
    assert not style.drawn(line(0, 10, 5, qi=1))  # no hidden lines


def test04_thesis_opacity_is_the_gray_level_of_eq_5_1():
    style = style_of("thesis")
    rng = (1.0, 3.0)
    # a line at depth 1.5 (D = 0.25): background behind it (D = 1), a surface at depth 1.55
    # (D = 0.275) and one at 1.52 (D = 0.26)
    for behind, expected in ((math.inf, 1.0), (1.55, 0.0), (1.56, 0.2), (1.52, 0.0)):
        s = line(0, 10, 5, depth=(1.5, 1.5), behind=behind)
        d0, di = 0.25, 1.0 if math.isinf(behind) else (behind - 1.0) / 2.0
        assert expected == pytest.approx(min(1, max(0, (di - d0) * 40 - 1)))
        np.testing.assert_allclose(style.opacity(s, rng), expected, atol=1e-9)
    # on a cube against the background: silhouettes opaque, creases (no depth step) gone
    assert style_of("technical").opacity(line(0, 10, 5), rng).tolist() == [1.0, 1.0]


def test05_thesis_on_a_cube(tmp_path):
    """In front of a far wall (depth range 4 to 25), the silhouette is opaque (the wall is
    far behind it); a crease (no depth step, faces sloping by less than 1/40 of the range
    within a pixel) vanishes, except within a pixel of the silhouette (near its ends), where
    the wall lies beside it (as eq. 5.1 sees the corner pixels)."""
    wall = (
        '<shape type="rectangle"><transform name="to_world"><scale value="40"/>'
        '<translate z="25"/></transform></shape>'
    )
    scene = load(tmp_path, CUBE.format(POSE) + wall)
    st = extract_strokes(scene, scene.sensors()[0], resample=2.0)
    style = style_of("thesis")
    sil = [s.points for s in st if s.kind == "silhouette"]
    for s in st:
        assert np.hypot(*np.diff(s.points, axis=0).T).max() <= 2.0 + 1e-9
        if s.qi or st.name_of(s.object_id[0]) != "box":
            continue
        o = style.opacity(s, st.depth_range)
        if s.kind == "silhouette":
            assert np.all(o == 1.0), s.points
        else:
            away = np.min([seg_distance(s.points, q[:-1], q[1:]) for q in sil], axis=0) > 1.2
            assert away.sum() >= 3 and np.all(o[away] == 0.0), (s.points, o)


BAD = {
    "style": lambda: style_of("watercolour"),
    "width": lambda: make_style(width=-1.0),
    "width ": lambda: make_style(width=math.nan),
    "dash": lambda: make_style(dash="0,0"),
    "dash ": lambda: make_style(dash=(0.0, 0.0)),
    "dash  ": lambda: make_style(dash="4,x"),
    "kind_width": lambda: make_style(kind_width={"silhouette": -2.0}),
    "colors": lambda: make_style(colors={"outline": (0, 0, 0)}),
    "taper_min": lambda: make_style(taper_min=2.0),
    "max_qi": lambda: DRAWINGS["strokes"].values({"max_qi": -1}),
    "line_width": lambda: DRAWINGS["strokes"].values({"line_width": -1.0}),
    "crease_angle": lambda: DRAWINGS["strokes"].values({"crease_angle": 200.0}),
    "chain_angle": lambda: DRAWINGS["strokes"].values({"chain_angle": math.nan}),
    "style   ": lambda: DRAWINGS["strokes"].values({"style": "watercolour"}),
    "dash   ": lambda: DRAWINGS["strokes"].values({"dash": "0, 0, 0"}),
}


@pytest.mark.parametrize("name", list(BAD))
def test06_bad_parameters_are_one_line_errors_naming_them(name):
    with pytest.raises(ParameterError) as e:
        BAD[name]()
    text = str(e.value)
    assert name.strip() in text and "\n" not in text, text


def test07_presets_are_valid_and_named():
    assert set(STYLES) == {"technical", "illustration", "thesis"}
    for name in STYLES:
        s = style_of(name)
        assert s.name == name and s.to_dict()["name"] == name
    assert style_of("illustration", hidden=True, width=3.0).hidden
    assert mi_npr.strokes.style.style_of("thesis").gray


def _raster_by_hand(strokes: Strokes, style) -> tuple[np.ndarray, np.ndarray]:
    """The raster's rules (:mod:`mi_npr.strokes.raster`) pixel by pixel: per stroke, per
    "on" piece, per segment and per pixel centre the capsule coverage; the largest per stroke
    and pixel; strokes laid over each other in order."""
    h, w = strokes.height, strokes.width
    alpha, ink = np.zeros((h, w)), np.zeros((h, w, 3))
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    for s in strokes:
        if not style.drawn(s):
            continue
        vals = np.stack(
            [style.widths(s, strokes.depth_range), style.opacity(s, strokes.depth_range)], -1
        )
        cov = np.zeros((h, w))
        for p, v in dash_pieces(s.points, vals, style.dashes(s), s.closed):
            if len(p) == 1:
                p, v = np.concatenate([p, p]), np.concatenate([v, v])
            for k in range(len(p) - 1):
                a, ab = p[k], p[k + 1] - p[k]
                ll = float(ab @ ab)
                t = (
                    np.zeros_like(xs)
                    if ll == 0
                    else ((xs - a[0]) * ab[0] + (ys - a[1]) * ab[1]) / ll
                )
                t = np.clip(t, 0, 1)
                d = np.hypot(xs - a[0] - t * ab[0], ys - a[1] - t * ab[1])
                r = (v[k, 0] + t * (v[k + 1, 0] - v[k, 0])) / 2
                o = v[k, 1] + t * (v[k + 1, 1] - v[k, 1])
                cov = np.maximum(cov, np.clip(r + 0.5 - d, 0, np.minimum(1, 2 * r)) * o)
        cov = np.minimum(cov, 1.0)
        alpha = alpha * (1 - cov) + cov
        ink = ink * (1 - cov)[..., None] + np.asarray(style.kind_color(s)) * cov[..., None]
    return alpha, ink


@pytest.mark.parametrize("small", [False, True])
def test10_the_raster_agrees_with_the_rules_pixel_by_pixel(small, monkeypatch):
    """Against the rules stroke by stroke (some strokes off the image); ``small``: in blocks of
    3 strokes and batches of 64 pixel tests (the memory bounds of a large drawing), the same
    raster."""
    if small:
        monkeypatch.setattr(raster, "BLOCK", 3)
        monkeypatch.setattr(raster, "CHUNK", 64)
    rng = np.random.default_rng(11)
    styles = [
        style_of("technical"),
        style_of("thesis", hidden=True),
        make_style(width=2.5, taper=6.0, depth_falloff=0.5, dash=(3.0,), hidden_width=0.6),
        make_style(
            colors={"crease": (1.0, 0.2, 0.0)}, hidden_color=(0.0, 0.0, 1.0), dash="2,1,0.5"
        ),
    ]
    for _ in range(12):
        strokes = []
        for _ in range(int(rng.integers(1, 12))):
            n = int(rng.integers(1, 7))
            pts = rng.random((n, 2)) * [44.0, 28.0] - 2.0
            if rng.random() < 0.2:  # off the image: segments that test no pixel
                pts[:, 0] -= 100.0
            strokes.append(
                Stroke(
                    kind=str(rng.choice(["silhouette", "crease", "border"])),
                    points=pts,
                    position=np.zeros((n, 3)),
                    depth=1.0 + 2.0 * rng.random(n),
                    object_id=np.ones(n),
                    prim=np.zeros(n),
                    qi=int(rng.integers(0, 3)),
                    closed=bool(rng.random() < 0.3),
                    depth_behind=1.0 + 4.0 * rng.random(n),
                )
            )
        st = sheet(*strokes)
        for style in styles:
            alpha, ink = rasterize(st, style)
            ref_alpha, ref_ink = _raster_by_hand(st, style)
            np.testing.assert_allclose(alpha, ref_alpha, atol=1e-6)
            np.testing.assert_allclose(ink, ref_ink, atol=1e-6)
