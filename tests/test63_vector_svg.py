"""Vector contours worth opening in an illustration program: vertices on a sphere's analytic
outline, Douglas-Peucker within 0.25 px, no contour along the image frame, Inkscape layers, the
beauty embedded once / linked / left out, strokes from thin masks, and the SVG against the PNG
overlay it accompanies."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from PIL import Image

import mi_npr
from mi_npr import layers as L
from mi_npr.contours import trace, trace_strokes, vectorize
from mi_npr.contours.vector import douglas_peucker

from .helpers import SCENES, run_cli, scene_xml

SVG = "{http://www.w3.org/2000/svg}"
INK = "{http://www.inkscape.org/namespaces/inkscape}"
W, H, FOV = 96, 72, 40.0
C, R = np.array([0.35, -0.1, 6.0]), 1.0


def seg_dist(p: np.ndarray, poly: np.ndarray, closed: bool) -> np.ndarray:
    """Distance of points ``p`` (N, 2) to a polyline (brute force over its segments)."""
    if len(poly) == 1:
        return np.hypot(*(p - poly[0]).T)
    a = poly if not closed else np.concatenate([poly, poly[:1]])
    s0, s1 = a[:-1], a[1:]
    d = s1 - s0
    L2 = np.maximum((d**2).sum(1), 1e-300)
    t = np.clip(((p[:, None, :] - s0[None]) * d[None]).sum(-1) / L2[None], 0, 1)
    q = s0[None] + t[..., None] * d[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(-1)).min(axis=1)


def outline_error_px(pts: np.ndarray) -> np.ndarray:
    """Pixel distance of image points to the analytic outline of the sphere (C, R) seen by a
    pinhole at the origin looking down +z (image +x = world -x, image +y = world -y, horizontal
    fov FOV): g = dist(C, ray) - R, divided by |grad g| in pixels."""
    tx = math.tan(math.radians(FOV) / 2)
    ty = tx * H / W

    def g(u, v):
        d = np.stack([-(2 * u / W - 1) * tx, -(2 * v / H - 1) * ty, np.ones_like(u)], -1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        along = d @ C
        return np.sqrt(np.maximum(C @ C - along**2, 0)) - R

    u, v = pts[:, 0], pts[:, 1]
    e = 1e-4
    gu = (g(u + e, v) - g(u - e, v)) / (2 * e)
    gv = (g(u, v + e) - g(u, v - e)) / (2 * e)
    return np.abs(g(u, v)) / np.hypot(gu, gv)


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    d = tmp_path_factory.mktemp("vec")
    body = f'<shape type="sphere" id="ball"><point name="center" x="{C[0]}" y="{C[1]}" '
    body += f'z="{C[2]}"/><float name="radius" value="{R}"/></shape>'
    xml = d / "sphere.xml"
    xml.write_text(scene_xml(body, width=W, height=H, fov=FOV))
    scene = mi_npr.load_scene(xml)
    return scene, mi_npr.render(scene), xml


def test01_vertices_lie_on_the_analytic_outline(sphere):
    scene, gb, _ = sphere
    paths = vectorize(gb, scene)
    assert len(paths) == 1 and paths[0].closed and paths[0].name == "ball"
    err = outline_error_px(paths[0].points)
    assert err.max() < 0.05, err.max()
    # pixel centres (the old paths) are up to half a pixel off; this is what was gained
    centres = trace(gb)[0].points + 0.5
    assert outline_error_px(centres.astype(float)).max() > 0.3
    # and without rays, crack midpoints: still sub-pixel but not on the outline
    mid = vectorize(gb)[0].points
    assert outline_error_px(mid).max() > 0.1


def test02_simplified_within_a_quarter_pixel(sphere):
    scene, gb, _ = sphere
    dense = vectorize(gb, scene, tolerance=0)[0]
    simple = vectorize(gb, scene)[0]
    assert len(simple) < len(dense) / 3
    assert seg_dist(dense.points, simple.points, closed=True).max() <= 0.25 + 1e-9
    # every kept vertex is one of the outline points
    d = np.abs(simple.points[:, None, :] - dense.points[None]).sum(-1).min(axis=1)
    assert d.max() < 1e-12


@pytest.mark.parametrize("closed", [False, True])
def test03_douglas_peucker_against_its_definition(closed):
    rng = np.random.default_rng(2)
    for n in (1, 2, 3, 17, 200):
        p = np.cumsum(rng.normal(size=(n, 2)), axis=0)
        for tol in (0.0, 0.25, 2.0):
            q = douglas_peucker(p, tol, closed)
            assert seg_dist(p, q, closed and len(q) > 2).max() <= tol + 1e-9
            if not closed:
                assert np.array_equal(q[0], p[0]) and np.array_equal(q[-1], p[-1])
            assert all((np.abs(p - v).sum(1) == 0).any() for v in q)


def test04_the_frame_is_never_a_contour(tmp_path):
    body = '<shape type="sphere" id="big"><point name="center" x="-1.6" y="0" z="4"/></shape>'
    body += '<shape type="rectangle" id="wall"><transform name="to_world"><scale value="20"/>'
    body += '<translate z="9"/></transform></shape>'
    xml = tmp_path / "edge.xml"
    xml.write_text(scene_xml(body, width=40, height=30))
    scene = mi_npr.load_scene(xml)
    gb = mi_npr.render(scene)
    assert np.all(gb.numpy(L.OBJECT_ID) > 0)  # the wall fills what the sphere leaves
    paths = vectorize(gb, scene)
    # the sphere is cut by the right edge: open paths; the wall fills the frame: no path of its
    # own along the border, only the part it shares with the sphere
    assert paths and all(not p.closed for p in paths)
    for p in paths:
        x, y = p.points[:, 0], p.points[:, 1]
        assert np.all((x > 0.49) & (x < 39.51) & (y > 0.49) & (y < 29.51))
        ends = p.points[[0, -1]]
        assert np.all(
            np.minimum.reduce([ends[:, 0], 40 - ends[:, 0], ends[:, 1], 30 - ends[:, 1]]) < 1.0
        )
        # no segment runs along a border pixel line
        a, b = p.points[:-1], p.points[1:]
        for k, lim in ((0, 0.5), (0, 39.5), (1, 0.5), (1, 29.5)):
            along = (np.abs(a[:, k] - lim) < 1e-6) & (np.abs(b[:, k] - lim) < 1e-6)
            assert not np.any(along & (np.abs(a[:, 1 - k] - b[:, 1 - k]) > 1.5))


def _layers(root):
    return [g for g in root.findall(f"{SVG}g") if g.get(f"{INK}groupmode") == "layer"]


@pytest.mark.parametrize("mode", ["embed", "link", "none"])
def test05_cli_svg_image_modes_layers_and_the_png_overlay(sphere, tmp_path, mode):
    _, _, xml = sphere
    out = tmp_path / mode
    r = run_cli("contours", str(xml), "-o", str(out), "--svg-image", mode, "--no-progress")
    assert r.returncode == 0, r.stderr
    text = (out / "sphere_contours.svg").read_text()
    root = ET.fromstring(text)
    labels = [g.get(f"{INK}label") for g in _layers(root)]
    images = root.findall(f".//{SVG}image")
    xlink = "{http://www.w3.org/1999/xlink}href"  # what Inkscape 1.2 reads
    if mode == "embed":
        assert labels == ["beauty", "contours"] and text.count("base64,") == 1
        assert images[0].get(xlink).startswith("data:image/png;base64,")
    elif mode == "link":
        assert labels == ["beauty", "contours"] and images[0].get(xlink) == "sphere_beauty.png"
        assert images[0].get("href") == "sphere_beauty.png"
        assert Image.open(out / "sphere_beauty.png").size == (W, H)
    else:
        assert labels == ["contours"] and not images
    group = root.find(f"{SVG}g[@id='contours']/{SVG}g")
    assert group.get(f"{INK}label") == "ball" and group.get("data-object-id") == "1"
    # the SVG's paths against the PNG overlay drawn beside it
    png = np.asarray(Image.open(out / "sphere_contours.png"))
    red = np.all(png == [255, 0, 0], axis=-1)
    gb = mi_npr.io.read_exr(out / "sphere_contours.exr")
    on = gb.numpy(L.CONTOUR) != 0
    assert np.array_equal(red & on, on)  # every contour pixel is drawn red
    d = group.find(f"{SVG}path").get("d")
    nums = [float(v) for v in d.replace("M", " ").replace("L", " ").replace("Z", " ").split()]
    poly = np.reshape(nums, (-1, 2))
    ys, xs = np.nonzero(on)
    centres = np.stack([xs + 0.5, ys + 0.5], 1)
    assert seg_dist(centres, poly, closed=True).max() < 1.0  # the path follows the red pixels
    near = np.hypot(*(poly[:, None, :] - centres[None]).transpose(2, 0, 1)).min(axis=1)
    # every vertex sits between a red pixel's centre and a 4-neighbour's: within 1 px of it,
    # one coordinate on the pixel-centre grid
    assert near.max() <= 1.0 + 1e-6
    frac = np.abs((poly - 0.5) - np.round(poly - 0.5))
    assert np.all(frac.min(axis=1) < 1e-9)


def test06_scene1_svg_without_image_is_small():
    gb, _, paths, strokes = mi_npr.render_vector_contours(
        SCENES / "scene1.xml", spp=1, width=640, height=480
    )
    text = mi_npr.io.svg_document(paths, gb.width, gb.height, strokes=strokes)
    assert len(text.encode()) <= 60_000, len(text.encode())
    root = ET.fromstring(text)
    names = {g.get(f"{INK}label") for g in root.findall(f"{SVG}g[@id='contours']/{SVG}g")}
    assert names == set(gb.objects.values())


@pytest.mark.parametrize(
    "mask",
    [
        np.zeros((5, 4), bool),
        np.ones((1, 1), bool),
        np.eye(7, dtype=bool),  # a diagonal
        np.pad(np.ones((1, 9), bool), 2),  # a horizontal line
        np.array([[1, 0, 0], [1, 0, 0], [1, 1, 1]], bool),  # an L
        np.pad(np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], bool), 1),  # a cross
        np.pad(np.pad(np.zeros((3, 3), bool), 1, constant_values=True), 1),  # a ring
    ],
)
def test07_strokes_cover_the_mask(mask):
    lines = trace_strokes(mask)
    ys, xs = np.nonzero(mask)
    centres = np.stack([xs + 0.5, ys + 0.5], 1)
    if not len(centres):
        assert lines == []
        return
    dist = np.min([seg_dist(centres, ln, False) for ln in lines], axis=0)
    assert dist.max() <= 0.25 + 1e-9
    for ln in lines:
        ix = (ln - 0.5).astype(int)
        assert np.allclose(ln - 0.5, ix) and mask[ix[:, 1], ix[:, 0]].all()


def test08_lines_and_edges_become_stroke_layers():
    gb = mi_npr.render(SCENES / "scene4.xml", width=64, height=48, spp=1, integrator="npr_lines")
    strokes = mi_npr.contours.stroke_layers(gb)
    assert list(strokes) == ["lines"]
    mask = gb.numpy(L.LINES) > 0.5
    lines, rgb = strokes["lines"]
    assert rgb == (0.0, 0.0, 0.0) and mask.any()
    ys, xs = np.nonzero(mask)
    dist = np.min([seg_dist(np.stack([xs + 0.5, ys + 0.5], 1), ln, False) for ln in lines], 0)
    assert dist.max() <= 0.25 + 1e-9
    text = mi_npr.io.svg_document([], 64, 48, strokes=strokes)
    assert [g.get(f"{INK}label") for g in _layers(ET.fromstring(text))] == ["lines"]


def test09_raytree_svg_has_one_layer_per_edge_class(tmp_path):
    r = run_cli(
        "raytree", "scene1", "-o", str(tmp_path), "-D", "width=48", "-D", "height=36",
        "--spp", "1", "--no-progress",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    root = ET.parse(tmp_path / "scene1_raytree.svg").getroot()
    layers = {g.get(f"{INK}label"): g for g in _layers(root)}
    assert list(layers) == [
        "beauty",
        "edges_real",
        "edges_reflection",
        "edges_refraction",
        "edges_shadow",
    ]
    gb = mi_npr.io.read_exr(tmp_path / "scene1_raytree.exr")
    for name in L.EDGES:
        mask = gb.numpy(name) > 0.5
        polys = []
        for p in layers[name.split(".")[0]].findall(f"{SVG}path"):
            d = p.get("d").replace("M", " ").replace("L", " ").replace("Z", " ")
            polys.append(np.reshape([float(v) for v in d.split()], (-1, 2)))
        ys, xs = np.nonzero(mask)
        assert len(polys) > 0 or not mask.any()
        if mask.any():
            c = np.stack([xs + 0.5, ys + 0.5], 1)
            assert np.min([seg_dist(c, q, False) for q in polys], axis=0).max() <= 0.25 + 0.01
            v = (np.concatenate(polys) - 0.5).round().astype(int)
            assert mask[v[:, 1], v[:, 0]].all()


@pytest.mark.parametrize("value", ["a", 'say "hi"', "it's", "<&>", "tab\there\nnew\rline", "ünï"])
def test10_quoteattr_round_trips_through_an_xml_parser(value):
    """The attribute quoting the SVG and sensor XML writers use (no xml.sax import)."""
    import xml.etree.ElementTree as ET

    from mi_npr.io.text import quoteattr

    assert ET.fromstring(f"<g id={quoteattr(value)}/>").get("id") == value


def _number(v: float, digits: int) -> str:
    """The SVG's number rule, one number at a time: ``digits`` decimals, trailing zeros and a
    bare point dropped, ``-0`` written ``0``."""
    t = f"{v:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if t == "-0" else t


@pytest.mark.parametrize("digits", [1, 2, 3])
def test11_path_numbers_follow_the_rule_one_by_one(digits):
    from mi_npr.io.svg import _polyline

    rng = np.random.default_rng(digits)
    edge = [0.0, -0.0, -1e-4, -0.0005, 0.0005, 0.0015, 2.675, 10.0, 100.5, -10.1, 1e6, 1e20]
    edge += [0.995, 9.99951, -9.99951, math.nan, math.inf, -math.inf, 5e-324, 123.456]
    for trial in range(400):
        n = int(rng.integers(1, 9))
        if trial % 2:
            pts = rng.choice(edge, (n, 2))
        else:
            pts = rng.normal(size=(n, 2)) * 10.0 ** rng.integers(-4, 4)
        for closed in (False, True):
            words = [_number(v, digits) for v in pts.reshape(-1)]
            pairs = [" ".join(words[i : i + 2]) for i in range(0, len(words), 2)]
            want = "M " + pairs[0] + (" L " + " ".join(pairs[1:]) if n > 1 else "")
            assert _polyline(pts, closed, digits) == want + (" Z" if closed else "")
    assert _polyline(np.zeros((0, 2)), True, digits) == ""


@pytest.mark.parametrize("radius", [0.0, 1.0, math.sqrt(2), 2.0, 2.5, 3.0, 4.9, 31.99, 32.0, 40.0])
def test12_near_is_the_distance_transforms_threshold(radius):
    from scipy.ndimage import distance_transform_edt

    from mi_npr.contours.vector import _dilate_disk

    rng = np.random.default_rng(int(radius * 100))
    for h, w, p in [(1, 1, 1.0), (1, 9, 0.2), (23, 2, 0.1), (31, 37, 0.02), (40, 45, 0.3)]:
        on = rng.random((h, w)) < p
        on[rng.integers(h), rng.integers(w)] = True
        assert np.array_equal(_dilate_disk(on, radius), distance_transform_edt(~on) <= radius)


def test13_near_polylines_of_a_line_by_brute_force():
    from mi_npr.contours.vector import near_polylines

    h, w, radius = 20, 30, 2.5
    lines = [np.array([[3.2, 5.5], [20.7, 5.5]]), np.array([[25.5, 17.9]]), np.zeros((0, 2))]
    near = near_polylines((h, w), lines, radius)
    # the pixels the polylines pass through: row 5 from x = 3 to 20, and pixel (25, 17)
    on = [(5, x) for x in range(3, 21)] + [(17, 25)]
    for y in range(h):
        for x in range(w):
            d = min(math.hypot(x - ox, y - oy) for oy, ox in on)
            assert near[y, x] == (d <= radius), (y, x)
    assert not near_polylines((h, w), [np.array([[-5.0, -5.0], [-1.0, -2.0]])], radius).any()


def test13b_near_polylines_in_blocks_of_segments(monkeypatch):
    """Random polylines (some leaving the image) sampled a few segments at a time mark the
    same pixels as all at once."""
    import mi_npr.contours.vector as V

    rng = np.random.default_rng(8)
    lines = [rng.random((int(rng.integers(1, 9)), 2)) * [50, 30] - 3 for _ in range(40)]
    whole = V.near_polylines((30, 50), lines, 1.5)
    for block in (1, 3, 7):
        monkeypatch.setattr(V, "NEAR_BLOCK", block)
        assert np.array_equal(V.near_polylines((30, 50), lines, 1.5), whole)
    assert whole.any() and not whole.all()


def test14_strokes_move_with_their_mask():
    """Tracing does not depend on where the mask lies in the image: shifted by whole pixels in a
    larger image, the same polylines, shifted, in the same order (and none for an empty mask)."""
    rng = np.random.default_rng(5)
    assert trace_strokes(np.zeros((30, 40), bool)) == []
    for _ in range(30):
        small = rng.random((int(rng.integers(1, 12)), int(rng.integers(1, 12)))) < 0.45
        small[0, 0] = small[-1, -1] = True  # it spans its own box
        dy, dx = (int(v) for v in rng.integers(0, 20, 2))
        big = np.zeros((small.shape[0] + 25, small.shape[1] + 31), bool)
        big[dy : dy + small.shape[0], dx : dx + small.shape[1]] = small
        want = [p + np.array([dx, dy]) for p in trace_strokes(small)]
        got = trace_strokes(big)
        assert len(got) == len(want)
        assert all(np.array_equal(g, v) for g, v in zip(got, want, strict=True))
