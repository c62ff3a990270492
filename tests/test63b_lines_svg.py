"""Thin masks traced into chains (against a brute-force walker written here), and
``<stem>_lines.svg`` made of the scene's strokes: a cube's lines end on its projected corners
(closed form), each edge once, and every line pixel the strokes do not explain is traced.

The cube's references (pinhole projection, corners, faces) are written here from Mitsuba's
``perspective`` sensor model, as in ``test75_strokes_closed_form.py``: nothing of mi_npr's
projection or of the strokes' code.
"""

from __future__ import annotations

import itertools
import re
import xml.etree.ElementTree as ET
from collections import Counter

import numpy as np
import pytest

import mi_npr
from mi_npr import layers as L
from mi_npr.contours import trace_strokes
from mi_npr.io import write_layered_outputs
from mi_npr.pipeline import render_layers

from .helpers import scene_xml
from .test75_strokes_closed_form import CUBE as CUBE_XML
from .test75_strokes_closed_form import FOV, ORIGIN, POSE, TARGET, H, W, cube_geometry, project

SVG = "{http://www.w3.org/2000/svg}"
INK = "{http://www.inkscape.org/namespaces/inkscape}"


# ------------------------------------------------------------------ references for the tracer


def seg_dist(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of points ``p`` (N, 2) to a polyline (brute force over its segments)."""
    poly = np.asarray(poly, np.float64)
    if len(poly) == 1:
        return np.hypot(*(p - poly[0]).T)
    a, b = poly[:-1], poly[1:]
    d = b - a
    ll = np.maximum((d**2).sum(1), 1e-300)
    t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(-1) / ll[None], 0, 1)
    q = a[None] + t[..., None] * d[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(-1)).min(axis=1)


def brute_neighbours(m: np.ndarray, x: int, y: int) -> list[tuple[int, int]]:
    """8-neighbours of (x, y) in ``m``; a diagonal one only when neither pixel that would
    bridge it with 4-steps is set."""
    h, w = m.shape
    out = []
    for dx, dy in itertools.product((-1, 0, 1), repeat=2):
        u, v = x + dx, y + dy
        if (dx, dy) == (0, 0) or not (0 <= u < w and 0 <= v < h and m[v, u]):
            continue
        if dx and dy and (m[y, u] or m[v, x]):
            continue
        out.append((u, v))
    return out


def pixel_run(path: np.ndarray) -> list[tuple[int, int]]:
    """The pixels of a traced path, in order: each segment is a straight run of equal
    8-neighbour steps between pixel centres (what Douglas-Peucker at tolerance 0 leaves out)."""
    q = np.rint(np.asarray(path) - 0.5).astype(int)
    out = [tuple(int(v) for v in q[0])]
    for a, b in itertools.pairwise(q):
        n = int(np.abs(b - a).max())
        step = (b - a) // n
        assert np.array_equal(a + n * step, b), "a segment that is no straight pixel run"
        out += [tuple(int(v) for v in a + k * step) for k in range(1, n + 1)]
    return out


def expanded_edges(path: np.ndarray) -> frozenset:
    """The pixel edges of a traced path (a lone pixel: the set holding only ``(p, p)``)."""
    q = pixel_run(path)
    if len(q) == 1:
        return frozenset([frozenset((q[0], q[0]))])
    return frozenset(frozenset(e) for e in itertools.pairwise(q))


def drawn(points: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The pixels a polyline passes through, sampled every 0.01 px."""
    m = np.zeros(shape, bool)
    for a, b in itertools.pairwise(points):
        t = np.linspace(0, 1, int(np.hypot(*(b - a)) * 100) + 2)[:, None]
        p = np.floor(a + t * (b - a)).astype(int)
        m[p[:, 1], p[:, 0]] = True
    return m


# ------------------------------------------------------------------------------- the tracer


def check_chains(m: np.ndarray, lines: list[np.ndarray]) -> None:
    """The definition of the chains (module docstring of :mod:`mi_npr.contours.vector`),
    checked on the paths traced from ``m`` at tolerance 0: they use the mask's neighbour edges,
    each once, and visit every pixel; the edges left out join pixels that keep two edges or more;
    no kept edge joins two pixels of three or more; a path runs on through pixels of two edges
    and straight through crossings, and ends elsewhere (or closes on itself)."""
    ys, xs = np.nonzero(m)
    pixels = {(int(x), int(y)) for x, y in zip(xs, ys, strict=True)}
    graph = {frozenset((p, q)) for p in pixels for q in brute_neighbours(m, *p)}
    chains = [expanded_edges(p) for p in lines]
    kept = [e for c in chains for e in c if len(e) == 2]
    assert len(kept) == len(set(kept)) and set(kept) <= graph
    assert {p for c in chains for e in c for p in e} == pixels
    deg = Counter(p for e in kept for p in e)
    assert all(deg[p] >= 2 for e in graph - set(kept) for p in e)
    assert not [e for e in kept if min(deg[p] for p in e) >= 3]

    def crossing(p):
        arms = [q for e in kept if p in e for q in e if q != p]
        return len(arms) == 4 and all((2 * p[0] - q[0], 2 * p[1] - q[1]) in arms for q in arms)

    for path in lines:
        q = pixel_run(path)
        closed = len(q) > 2 and q[0] == q[-1]
        if not closed:  # a path ends where no walk goes on
            assert all(deg[p] != 2 and not crossing(p) for p in {q[0], q[-1]} if deg[p])
        for a, b, c in zip(q, q[1:], q[2:], strict=False):  # and goes on where one does
            assert deg[b] == 2 or (
                crossing(b) and np.array_equal(np.subtract(b, a), np.subtract(c, b))
            )


@pytest.mark.parametrize("seed", range(6))
def test01_chains_against_their_definition(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        h, w = (int(v) for v in rng.integers(1, 16, 2))
        m = rng.random((h, w)) < rng.uniform(0.05, 0.7)
        check_chains(m, trace_strokes(m, 0.0))
        # and simplified: every mask pixel within 0.25 px, every vertex a mask pixel's centre
        simple = trace_strokes(m)
        ys, xs = np.nonzero(m)
        if len(xs):
            c = np.stack([xs + 0.5, ys + 0.5], 1)
            assert np.min([seg_dist(c, p) for p in simple], axis=0).max() <= 0.25 + 1e-9
            v = np.concatenate(simple) - 0.5
            assert np.allclose(v, np.rint(v)) and m[v[:, 1].astype(int), v[:, 0].astype(int)].all()


def test01b_thin_masks_are_walked_between_ends_and_junctions():
    """Where no two junction pixels touch, the chains are those of a plain walk: a cross is two
    lines through its centre, a T three paths."""
    cross = np.zeros((9, 9), bool)
    cross[4, 1:8] = cross[1:8, 4] = True
    got = sorted(p.tolist() for p in trace_strokes(cross))
    assert got == [[[1.5, 4.5], [7.5, 4.5]], [[4.5, 1.5], [4.5, 7.5]]]
    band = np.zeros((8, 34), bool)
    band[3:5, 2:32] = True  # two pixels wide: its rungs go, its two rows make one ring
    (ring,) = trace_strokes(band)
    assert {tuple(p) for p in ring} == {(2.5, 3.5), (31.5, 3.5), (31.5, 4.5), (2.5, 4.5)}
    assert np.array_equal(ring[0], ring[-1])


def test02_a_drawn_polyline_comes_back_within_a_pixel():
    x = np.linspace(3.2, 88.7, 60)
    curve = np.stack([x, 30 + 12 * np.sin(x / 9.0)], 1)
    m = drawn(curve, (60, 96))
    (path,) = trace_strokes(m)
    samples = np.concatenate([np.linspace(a, b, 20) for a, b in itertools.pairwise(curve)])
    assert seg_dist(path, curve).max() < 1.0  # every vertex near the curve
    assert seg_dist(samples, path).max() < 1.0  # and the whole curve near the path
    ends = {tuple(np.floor(p).astype(int)) for p in path[[0, -1]]}
    assert ends == {tuple(np.floor(curve[0]).astype(int)), tuple(np.floor(curve[-1]).astype(int))}
    # a coarser tolerance drops the stairs: within 1 px still, a fraction of the vertices
    (coarse,) = trace_strokes(m, 0.7)
    assert seg_dist(samples, coarse).max() < 1.0 and seg_dist(coarse, curve).max() < 1.0
    assert len(coarse) < m.sum() / 4


def test03_a_ring_is_one_closed_path():
    a = np.linspace(0, 2 * np.pi, 400)
    circle = np.stack([20.3 + 13.1 * np.cos(a), 17.6 + 13.1 * np.sin(a)], 1)
    m = drawn(circle, (36, 42))
    (path,) = trace_strokes(m)
    assert np.array_equal(path[0], path[-1]) and len(path) > 4
    r = np.hypot(path[:, 0] - 20.3, path[:, 1] - 17.6)
    assert np.abs(r - 13.1).max() < 1.0
    assert seg_dist(circle, path).max() < 1.0


def test04_a_t_is_three_paths_ending_at_the_junction():
    m = np.zeros((14, 18), bool)
    m[5, 1:16] = True
    m[6:13, 8] = True
    lines = trace_strokes(m)
    assert len(lines) == 3
    junction = (8.5, 5.5)
    ends = []
    for p in lines:
        a, b = tuple(p[0]), tuple(p[-1])
        assert junction in (a, b)
        ends.append(b if a == junction else a)
        assert len(p) == 2  # straight arms: two vertices each
    assert sorted(ends) == sorted([(1.5, 5.5), (15.5, 5.5), (8.5, 12.5)])


def test05_small_empty_and_border_masks():
    assert trace_strokes(np.zeros((0, 0), bool)) == []
    assert trace_strokes(np.zeros((3, 4), bool)) == []
    (one,) = trace_strokes(np.ones((1, 1), bool))
    assert one.tolist() == [[0.5, 0.5]]
    frame = np.ones((5, 7), bool)
    frame[1:-1, 1:-1] = False
    (ring,) = trace_strokes(frame)
    corners = {(0.5, 0.5), (6.5, 0.5), (6.5, 4.5), (0.5, 4.5)}
    assert np.array_equal(ring[0], ring[-1]) and {tuple(p) for p in ring} == corners
    row = np.zeros((3, 9), bool)
    row[-1] = True
    assert [p.tolist() for p in trace_strokes(row)] == [[[0.5, 2.5], [8.5, 2.5]]]
    with pytest.raises(mi_npr.errors.ParameterError, match="stroke mask"):
        trace_strokes(np.zeros(4, bool))


# ---------------------------------------------------------------- lines.svg from the strokes

CUBE = CUBE_XML.format(POSE)


def cube() -> tuple[np.ndarray, dict[tuple[int, int], list[bool]]]:
    """The corners (8, 3) and, per edge, whether each of its two faces faces the camera."""
    corners, _, faces = cube_geometry()
    front = {e: [float(n @ (corners[e[0]] - ORIGIN)) < 0 for n in ns] for e, ns in faces.items()}
    return corners, front


def lines_svg(tmp_path, body: str, **params) -> tuple[ET.Element, mi_npr.GBuffer]:
    xml = tmp_path / "scene.xml"
    origin, target = ", ".join(map(str, ORIGIN)), ", ".join(map(str, TARGET))
    xml.write_text(scene_xml(body, W, H, FOV, origin=origin, target=target))
    r = render_layers(xml, ["lines"], params, spp=1)
    write_layered_outputs(r, tmp_path, "scene", svg_image="none")
    return ET.parse(tmp_path / "scene_lines.svg").getroot(), r.gbuffer


def paths_of(el: ET.Element) -> list[np.ndarray]:
    out = []
    for p in el.iter(f"{SVG}path"):
        nums = [float(v) for v in re.sub("[MLZ]", " ", p.get("d")).split()]
        out.append(np.reshape(nums, (-1, 2)))
    return out


@pytest.mark.parametrize("crease_angle", [134.0, 0.0])
def test06_a_cubes_lines_end_on_its_projected_corners(tmp_path, crease_angle):
    root, _ = lines_svg(tmp_path, CUBE, crease_angle=crease_angle, line_width=2.5)
    (layer,) = [g for g in root.findall(f"{SVG}g") if g.get(f"{INK}label") == "lines"]
    kinds = [g.get("data-kind") for g in layer.findall(f"{SVG}g")]
    assert kinds == (["silhouette", "crease"] if crease_angle else ["silhouette"])
    assert layer.find(f"{SVG}g[@id='traced']") is None  # the strokes explain every line pixel
    corners, edges = cube()
    px = project(corners)
    drawn_edges = []
    for path in paths_of(layer):
        d = np.hypot(*(path[:, None, :] - px[None]).transpose(2, 0, 1))
        assert d.min(1).max() < 0.05  # every vertex on a projected corner
        at = d.argmin(1)
        drawn_edges += [(min(a, b), max(a, b)) for a, b in itertools.pairwise(at)]
    for p in layer.iter(f"{SVG}path"):
        assert p.get("stroke-width") == "2.5" and p.get("stroke") == "#000000"
        assert p.get("class") == "visible"
    assert all(e in edges for e in drawn_edges)  # straight paths along cube edges
    assert len(drawn_edges) == len(set(drawn_edges))  # none twice
    outline = {e for e, front in edges.items() if sum(front) == 1}
    creases = {e for e, front in edges.items() if all(front)}
    assert set(drawn_edges) == (outline | creases if crease_angle else outline)


def test07_every_line_pixel_is_a_stroke_or_traced(tmp_path):
    """A sphere (an outline from the image) on a box (mesh strokes) with leaf-free lines: every
    pixel of ``lines.V > 0.5`` lies near a stroke or on a traced path."""
    body = CUBE + (
        '<shape type="sphere"><point name="center" value="-0.9, 0.2, 4"/>'
        '<float name="radius" value="0.5"/></shape>'
    )
    root, gb = lines_svg(tmp_path, body, line_width=1.0)
    (layer,) = [g for g in root.findall(f"{SVG}g") if g.get(f"{INK}label") == "lines"]
    strokes = [p for g in layer.findall(f"{SVG}g[@data-kind]") for p in paths_of(g)]
    traced_layer = layer.find(f"{SVG}g[@id='traced']")
    traced = paths_of(traced_layer) if traced_layer is not None else []
    mask = gb.numpy(L.LINES) > 0.5
    ys, xs = np.nonzero(mask)
    c = np.stack([xs + 0.5, ys + 0.5], 1)
    near = np.min([seg_dist(c, p) for p in strokes], axis=0) <= 0.5 + 2.0 + 0.85
    if traced:
        near |= np.min([seg_dist(c, p) for p in traced], axis=0) <= 0.25 + 1e-9
    assert near.all()
    assert len(strokes) >= 4  # the sphere's outline and the box's


def _ortho(tmp_path):
    xml = tmp_path / "ortho.xml"
    xml.write_text(
        re.sub(r'type="perspective">\s*<float name="fov" value="[^"]*"/>', 'type="orthographic">',
               scene_xml(CUBE, W, H, origin="0, 0, 0", target="0, 0, 1"))
    )  # fmt: skip
    assert "orthographic" in xml.read_text()
    return xml


def test08_an_orthographic_cameras_lines_are_strokes(tmp_path):
    """An orthographic camera gets object-space strokes too: every line pixel lies near one,
    nothing is left to trace."""
    r = render_layers(_ortho(tmp_path), ["lines"], spp=1)
    write_layered_outputs(r, tmp_path, "o", svg_image="none")
    root = ET.parse(tmp_path / "o_lines.svg").getroot()
    (layer,) = [g for g in root.findall(f"{SVG}g") if g.get(f"{INK}label") == "lines"]
    strokes = [p for g in layer.findall(f"{SVG}g[@data-kind]") for p in paths_of(g)]
    assert strokes and layer.find(f"{SVG}g[@id='traced']") is None
    mask = r.gbuffer.numpy(L.LINES) > 0.5
    ys, xs = np.nonzero(mask)
    c = np.stack([xs + 0.5, ys + 0.5], 1)
    assert np.min([seg_dist(c, p) for p in strokes], axis=0).max() <= 0.5 + 2.0 + 0.85


def test09_a_camera_the_strokes_refuse_traces_every_line_pixel(tmp_path, monkeypatch):
    """Where the strokes refuse the camera (a ParameterError from the extraction, as for a
    sensor that is no camera), every line pixel is traced instead."""
    import mi_npr.pipeline as P

    def refuse(*args, **kwargs):
        raise mi_npr.ParameterError("strokes: the radiancemeter camera is not supported")

    monkeypatch.setattr(P, "extract_strokes", refuse)
    r = render_layers(_ortho(tmp_path), ["lines"], spp=1)
    write_layered_outputs(r, tmp_path, "o", svg_image="none")
    root = ET.parse(tmp_path / "o_lines.svg").getroot()
    mask = r.gbuffer.numpy(L.LINES) > 0.5
    assert mask.any()
    traced = paths_of(root.find(f".//{SVG}g[@id='traced']"))
    ys, xs = np.nonzero(mask)
    c = np.stack([xs + 0.5, ys + 0.5], 1)
    assert np.min([seg_dist(c, p) for p in traced], axis=0).max() <= 0.25 + 1e-9
